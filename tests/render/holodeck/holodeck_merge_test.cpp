// Merging holodeck parts (render/holodeck/holo_merge.h): the ranks' shares cover every request
// once with balanced desired totals and sample counts summing to the total; a part seeded from
// the target continues its beams; HoloFile::writeBeams, which the merge writes with, is
// writeBeam for each; parts holding a beam as prefixes of one sequence merge into the longest,
// with no sample twice; a part that disagrees, has other sections or is the target is refused
// with the target's bytes untouched.

#include <gtest/gtest.h>
#include <unistd.h>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>

#include "core/input_error.h"
#include "core/random.h"
#include "render/holodeck/holo_merge.h"

namespace penumbra {
namespace {

namespace fs = std::filesystem;

class HoloMergeTest : public ::testing::Test {
protected:
    void SetUp() override {
        mDir = fs::temp_directory_path() /
               ("penumbra_holo_merge_test_" + std::to_string(::getpid()) + "_" +
                ::testing::UnitTest::GetInstance()->current_test_info()->name());
        fs::remove_all(mDir);
        fs::create_directories(mDir);
    }
    void TearDown() override { fs::remove_all(mDir); }
    std::string path(const std::string& name) const { return (mDir / name).string(); }
    fs::path mDir;
};

std::vector<HoloSection> oneSection() { return {HoloSection(Vec3(0.0), Vec3(4, 3, 2), {6, 5, 4})}; }

/// The first `count` samples of one sequence per (seed, beam), as a fill with one seed makes.
std::vector<HoloSample> sequence(std::uint64_t seed, std::int64_t beam, std::size_t count) {
    std::vector<HoloSample> out(count);
    for (std::size_t i = 0; i < count; ++i) {
        const std::uint64_t r = splitmix64(hashPair(hashPair(seed, std::uint64_t(beam)), i));
        for (int k = 0; k < 4; ++k) out[i].rgbe[std::size_t(k)] = std::uint8_t(r >> (8 * k));
        out[i].entry[0] = std::uint8_t(r >> 32);
        out[i].entry[1] = std::uint8_t(r >> 40);
        out[i].exit[0] = std::uint8_t(r >> 48);
        out[i].exit[1] = std::uint8_t(r >> 56);
        out[i].distance = std::uint16_t(i);
    }
    return out;
}

bool same(const std::vector<HoloSample>& a, const std::vector<HoloSample>& b) {
    return a.size() == b.size() &&
           (a.empty() || std::memcmp(a.data(), b.data(), a.size() * sizeof(HoloSample)) == 0);
}

std::string bytesOf(const std::string& file) {
    std::ifstream in(file, std::ios::binary);
    std::stringstream s;
    s << in.rdbuf();
    return s.str();
}

TEST(HoloShare, EveryRequestOnceBalancedAndTheSamplesSumToTheTotal) {
    std::vector<BeamRequest> requests;
    for (std::int64_t b = 0; b < 1000; ++b)
        requests.push_back({0, b, 1.0 + double(splitmix64(std::uint64_t(b)) % 100) / 10.0});
    double total = 0;
    for (const BeamRequest& r : requests) total += r.desired;
    for (const int ranks : {1, 2, 3, 7}) {
        std::set<std::int64_t> seen;
        std::int64_t samples = 0;
        for (int k = 0; k < ranks; ++k) {
            const RankShare share = shareRequests(requests, 100001, ranks, k);
            double desired = 0;
            for (const BeamRequest& r : share.requests) {
                EXPECT_TRUE(seen.insert(r.beam).second) << "beam " << r.beam << " twice";
                desired += r.desired;
            }
            // Within one request (at most 10.9 desired) of an even split.
            EXPECT_NEAR(desired, total / ranks, 11.0) << ranks << " ranks, rank " << k;
            EXPECT_NEAR(double(share.samples), 100001.0 * desired / total, 1.0);
            samples += share.samples;
        }
        EXPECT_EQ(seen.size(), requests.size()) << ranks << " ranks";
        EXPECT_EQ(samples, 100001) << ranks << " ranks";
    }
}

TEST_F(HoloMergeTest, APartSeededFromTheTargetContinuesItsBeams) {
    {
        HoloFile target(path("t.hdk"), oneSection());
        target.writeBeam(0, 5, sequence(1, 5, 4));
        target.writeBeam(0, 9, sequence(1, 9, 2));
        target.commit();
    }
    HoloFile base = HoloFile::openReadOnly(path("t.hdk"));
    HoloFile part(path("p.hdk"), base.sections());
    // Beam 9 is not this part's: it is not copied.
    EXPECT_EQ(seedPart(base, part, {{0, 5, 10.0}, {0, 7, 10.0}}), 4);
    EXPECT_TRUE(same(part.readBeam(0, 5), sequence(1, 5, 4)));
    EXPECT_EQ(part.sampleCount(0, 7), 0u);
    EXPECT_EQ(part.sampleCount(0, 9), 0u);
}

TEST_F(HoloMergeTest, WriteBeamsIsWriteBeamForEachInOneExtent) {
    {
        HoloFile file(path("w.hdk"), oneSection());
        file.writeBeam(0, 1, sequence(1, 1, 3));
        file.writeBeam(0, 2, sequence(1, 2, 3));
        file.commit();
        // Beam 1 replaced, beam 2 emptied, beam 3 written twice (the later wins), beam 4 new.
        file.writeBeams({{0, 1, sequence(1, 1, 6)},
                         {0, 2, {}},
                         {0, 3, sequence(1, 3, 2)},
                         {0, 4, sequence(1, 4, 5)},
                         {0, 3, sequence(1, 3, 4)}});
        EXPECT_THROW(file.writeBeams({{0, 5, sequence(1, 5, 1)}, {0, -1, sequence(1, 0, 1)}}),
                     std::invalid_argument);
        EXPECT_EQ(file.sampleCount(0, 5), 0u) << "a refused batch wrote a beam";
        file.commit();
    }
    HoloFile file = HoloFile::openReadOnly(path("w.hdk"));
    EXPECT_TRUE(same(file.readBeam(0, 1), sequence(1, 1, 6)));
    EXPECT_EQ(file.sampleCount(0, 2), 0u);
    EXPECT_TRUE(same(file.readBeam(0, 3), sequence(1, 3, 4)));
    EXPECT_TRUE(same(file.readBeam(0, 4), sequence(1, 4, 5)));
    EXPECT_EQ(file.info().samples, 6 + 4 + 5);
}

TEST_F(HoloMergeTest, OverlappingPartsMergeIntoTheLongestWithNoSampleTwice) {
    {
        HoloFile target(path("t.hdk"), oneSection());
        target.writeBeam(0, 1, sequence(1, 1, 5));  // a part continues it
        target.writeBeam(0, 2, sequence(1, 2, 8));  // longer than a part's
        target.commit();
        HoloFile a(path("a.hdk"), oneSection());
        a.writeBeam(0, 1, sequence(1, 1, 9));
        a.writeBeam(0, 2, sequence(1, 2, 3));
        a.writeBeam(0, 3, sequence(1, 3, 6));  // b holds it too, longer
        a.commit();
        HoloFile b(path("b.hdk"), oneSection());
        b.writeBeam(0, 3, sequence(1, 3, 10));
        b.writeBeam(0, 4, sequence(1, 4, 7));
        b.commit();
    }
    HoloFile target(path("t.hdk"), {});
    const HoloMergeStats stats = mergeHoloParts(target, {path("a.hdk"), path("b.hdk")});
    EXPECT_EQ(stats.parts, 2);
    EXPECT_EQ(stats.beams, 3);                        // 1 from a, 3 and 4 from b
    EXPECT_EQ(stats.samplesAdded, (9 - 5) + 10 + 7);  // beam 2 keeps the target's 8
    EXPECT_EQ(stats.samplesShared, 5 + 3 + 6);        // held already, or by both parts
    HoloFile m = HoloFile::openReadOnly(path("t.hdk"));
    EXPECT_TRUE(same(m.readBeam(0, 1), sequence(1, 1, 9)));
    EXPECT_TRUE(same(m.readBeam(0, 2), sequence(1, 2, 8)));
    EXPECT_TRUE(same(m.readBeam(0, 3), sequence(1, 3, 10)));
    EXPECT_TRUE(same(m.readBeam(0, 4), sequence(1, 4, 7)));
    EXPECT_EQ(m.info().samples, 9 + 8 + 10 + 7);
    // Merging the same parts again changes nothing (a killed merge is completed this way).
    HoloFile again(path("t.hdk"), {});
    const HoloMergeStats second = mergeHoloParts(again, {path("a.hdk"), path("b.hdk")});
    EXPECT_EQ(second.beams, 0);
    EXPECT_EQ(second.samplesAdded, 0);
    EXPECT_EQ(again.info().samples, 9 + 8 + 10 + 7);
}

TEST_F(HoloMergeTest, ADisagreeingPartIsRefusedAndTheTargetKeepsItsBytes) {
    {
        HoloFile target(path("t.hdk"), oneSection());
        target.writeBeam(0, 1, sequence(1, 1, 5));
        target.commit();
        HoloFile good(path("good.hdk"), oneSection());
        good.writeBeam(0, 6, sequence(1, 6, 4));
        good.commit();
        // Another seed: beam 1's samples are not a continuation of the target's.
        HoloFile other(path("other.hdk"), oneSection());
        other.writeBeam(0, 1, sequence(2, 1, 7));
        other.commit();
        HoloFile shape(path("shape.hdk"), {HoloSection(Vec3(0.0), Vec3(4, 3, 2), {6, 5, 5})});
        shape.commit();
    }
    const std::string before = bytesOf(path("t.hdk"));
    auto refused = [&](const std::vector<std::string>& parts, const std::string& words) {
        HoloFile target(path("t.hdk"), {});
        try {
            mergeHoloParts(target, parts);
            ADD_FAILURE() << "merged " << parts.back();
        } catch (const InputError& e) {
            EXPECT_NE(std::string(e.what()).find(words), std::string::npos) << e.what();
            EXPECT_EQ(e.file(), parts.back()) << e.what();
        }
    };
    refused({path("good.hdk"), path("other.hdk")}, "disagree");
    refused({path("shape.hdk")}, "sections");
    refused({path("t.hdk")}, "target itself");
    EXPECT_EQ(bytesOf(path("t.hdk")), before) << "a refused merge wrote to the target";
}

}  // namespace
}  // namespace penumbra
