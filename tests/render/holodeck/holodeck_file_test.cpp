// The holodeck file: round trips, fragment reuse and the optimizer, the repair of torn tails,
// damaged records and superblocks, and SIGKILL at random moments of a writer (fork, kill,
// reopen): every committed beam is present, nothing torn is kept.

#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <thread>

#include "core/input_error.h"
#include "core/random.h"
#include "render/holodeck/holo_file.h"

namespace penumbra {
namespace {

namespace fs = std::filesystem;

class HoloFileTest : public ::testing::Test {
protected:
    void SetUp() override {
        mDir = fs::temp_directory_path() /
               ("penumbra_holo_file_test_" + std::to_string(::getpid()) + "_" +
                ::testing::UnitTest::GetInstance()->current_test_info()->name());
        fs::remove_all(mDir);
        fs::create_directories(mDir);
    }
    void TearDown() override { fs::remove_all(mDir); }
    std::string path(const std::string& name = "scene.hdk") const { return (mDir / name).string(); }
    fs::path mDir;
};

std::vector<HoloSection> oneSection() { return {HoloSection(Vec3(0.0), Vec3(4, 3, 2), {6, 5, 4})}; }

/// `count` samples whose bytes are a function of (seed, index): what a beam should hold.
std::vector<HoloSample> samples(std::uint64_t seed, std::size_t count) {
    std::vector<HoloSample> out(count);
    for (std::size_t i = 0; i < count; ++i) {
        const std::uint64_t r = splitmix64(hashPair(seed, i));
        for (int k = 0; k < 4; ++k) out[i].rgbe[k] = std::uint8_t(r >> (8 * k));
        out[i].entry[0] = std::uint8_t(r >> 32);
        out[i].entry[1] = std::uint8_t(r >> 40);
        out[i].exit[0] = std::uint8_t(r >> 44);
        out[i].exit[1] = std::uint8_t(r >> 52);
        out[i].distance = static_cast<std::uint16_t>(r >> 48);
    }
    return out;
}

bool same(const std::vector<HoloSample>& a, const std::vector<HoloSample>& b) {
    return a.size() == b.size() &&
           (a.empty() || std::memcmp(a.data(), b.data(), a.size() * sizeof(HoloSample)) == 0);
}

TEST_F(HoloFileTest, BeamsRoundTripThroughReopening) {
    std::map<std::pair<int, std::int64_t>, std::vector<HoloSample>> written;
    const std::vector<HoloSection> sections = {
        oneSection()[0], HoloSection(Vec3(5, 0, 0), Vec3(1.0), {4, 4, 4}, SectionKind::Exterior)};
    {
        HoloFile file(path(), sections);
        for (int i = 0; i < 200; ++i) {
            const int s = i % 2;
            const std::int64_t beam = (i * 7919) % sections[s].beamCount();
            written[{s, beam}] = samples(i, 1 + i % 23);
            file.writeBeam(s, beam, written[{s, beam}]);
        }
        file.commit();
    }
    HoloFile file(path(), {});
    ASSERT_EQ(file.sections().size(), 2u);
    EXPECT_EQ(file.sections()[1].kind(), SectionKind::Exterior);
    EXPECT_EQ(file.sections()[0].grid(), sections[0].grid());
    std::int64_t total = 0;
    for (const auto& [key, expected] : written) {
        EXPECT_TRUE(same(file.readBeam(key.first, key.second), expected))
            << "section " << key.first << " beam " << key.second;
        total += std::int64_t(expected.size());
    }
    const HoloFileInfo info = file.info();
    EXPECT_EQ(info.beams, std::int64_t(written.size()));
    EXPECT_EQ(info.samples, total);
    EXPECT_EQ(info.recovered, 0);
    EXPECT_EQ(info.truncated, 0);
}

TEST_F(HoloFileTest, RewrittenBeamsReuseFreedFragmentsAndTheOptimizerCollates) {
    HoloFile file(path(), oneSection());
    // A beam grown step by step leaves its old records behind; they are reused once free.
    std::vector<std::int64_t> sizes;
    for (int round = 0; round < 40; ++round) {
        for (std::int64_t beam = 0; beam < 50; ++beam)
            file.writeBeam(0, beam, samples(beam, std::size_t(5 + (round * beam) % 17)));
        file.commit();
        sizes.push_back(file.info().bytes);
    }
    // A commit keeps both a rewritten beam's old and new records until it lands, so the file
    // holds about twice its live records: bounded, and not growing round after round.
    const HoloFileInfo last = file.info();
    EXPECT_LE(last.bytes, 3 * (last.bytes - last.freeBytes)) << "freed fragments not reused";
    EXPECT_LE(sizes.back(), sizes[20] * 5 / 4) << "the file keeps growing";
    const HoloFileInfo before = file.info();
    EXPECT_GT(before.fragments, 0);
    HoloFile::optimize(path());
    HoloFile optimized = HoloFile::openReadOnly(path());
    const HoloFileInfo after = optimized.info();
    EXPECT_EQ(after.samples, before.samples);
    EXPECT_EQ(after.fragments, 0);
    EXPECT_LT(after.bytes, before.bytes);
    for (std::int64_t beam = 0; beam < 50; ++beam)
        EXPECT_TRUE(
            same(optimized.readBeam(0, beam), samples(beam, std::size_t(5 + (39 * beam) % 17))))
            << "beam " << beam;
}

TEST_F(HoloFileTest, UncommittedAppendsAreRecoveredAndATornTailIsCut) {
    {
        HoloFile file(path(), oneSection());
        file.writeBeam(0, 10, samples(1, 8));
        file.commit();
        // Written, never committed: appended after the commit, so found on reopening.
        file.writeBeam(0, 11, samples(2, 9));
        file.writeBeam(0, 10, samples(3, 12));
    }
    // A record cut short, as by a kill in the middle of a write.
    {
        std::ofstream out(path(), std::ios::binary | std::ios::app);
        const char partial[30] = {'B', 'E', 'A', 'M', 1, 2, 3};
        out.write(partial, sizeof partial);
    }
    HoloFile file(path(), {});
    const HoloFileInfo info = file.info();
    EXPECT_EQ(info.recovered, 2);
    EXPECT_EQ(info.truncated, 30);
    EXPECT_EQ(std::int64_t(fs::file_size(path())), info.bytes) << "the torn record stays";
    EXPECT_TRUE(same(file.readBeam(0, 10), samples(3, 12)));
    EXPECT_TRUE(same(file.readBeam(0, 11), samples(2, 9)));
}

TEST_F(HoloFileTest, DamagedFilesAreRefusedOrRepairedBeamByBeam) {
    // Not a holodeck file, and a damaged header: one InputError naming the file.
    { std::ofstream(path("text.hdk")) << "hello"; }
    try {
        HoloFile::openReadOnly(path("text.hdk"));
        FAIL() << "a text file opened as a holodeck";
    } catch (const InputError& e) {
        EXPECT_NE(std::string(e.what()).find("text.hdk"), std::string::npos) << e.what();
        EXPECT_NE(std::string(e.what()).find("not a holodeck file"), std::string::npos);
    }
    std::uint64_t beamOffset = 0;
    {
        HoloFile file(path(), oneSection());
        file.writeBeam(0, 3, samples(3, 10));
        file.commit();
        file.writeBeam(0, 4, samples(4, 10));
        file.commit();
        beamOffset = 16 + 64 + 8 + 80;  // the first record after the slots: beam 3
    }
    // A flipped byte inside beam 3's samples: that beam is dropped, beam 4 survives.
    {
        std::fstream f(path(), std::ios::binary | std::ios::in | std::ios::out);
        f.seekp(std::streamoff(beamOffset + 30));
        f.put('\x5a');
    }
    {
        HoloFile file(path(), {});
        EXPECT_TRUE(file.readBeam(0, 3).empty());
        EXPECT_TRUE(same(file.readBeam(0, 4), samples(4, 10)));
    }
    // A damaged header checksum.
    {
        std::fstream f(path(), std::ios::binary | std::ios::in | std::ios::out);
        f.seekp(20);
        f.put('\x7f');
    }
    EXPECT_THROW(HoloFile::openReadOnly(path()), InputError);
}

TEST_F(HoloFileTest, ATornSuperblockFallsBackToThePreviousCommit) {
    {
        HoloFile file(path(), oneSection());
        file.writeBeam(0, 1, samples(1, 5));
        file.commit();  // sequence 1: slot 1
        file.writeBeam(0, 2, samples(2, 5));
        file.commit();  // sequence 2: slot 0
    }
    // Slot 0 (the newest) torn: its checksum no longer matches.
    {
        std::fstream f(path(), std::ios::binary | std::ios::in | std::ios::out);
        f.seekp(16 + 64 + 8 + 3);
        f.put('\x11');
    }
    HoloFile file(path(), {});
    EXPECT_TRUE(same(file.readBeam(0, 1), samples(1, 5)));
    // Beam 2's record lies after commit 1's end: recovered as an appended record.
    EXPECT_TRUE(same(file.readBeam(0, 2), samples(2, 5)));
}

/// What the writer child does at step i: beam, and the samples appended to it.
struct Step {
    std::int64_t beam;
    std::size_t added;
};
Step stepOf(std::uint64_t seed, int i) {
    const std::uint64_t r = splitmix64(hashPair(seed, std::uint64_t(i)));
    return {std::int64_t(r % 97), std::size_t(1 + (r >> 32) % 40)};
}

/// The beams' contents after steps 0..last: each beam's samples are samples(seed ^ beam, n).
std::map<std::int64_t, std::size_t> contentAfter(std::uint64_t seed, int last) {
    std::map<std::int64_t, std::size_t> sizes;
    for (int i = 0; i <= last; ++i) {
        const Step s = stepOf(seed, i);
        sizes[s.beam] += s.added;
    }
    return sizes;
}

[[noreturn]] void writerChild(const std::string& file, std::uint64_t seed, int ackFd) {
    HoloFile holo(file, oneSection());
    const int opened = -1;  // the file exists: the parent's clock starts
    if (::write(ackFd, &opened, sizeof opened) != sizeof opened) _exit(3);
    std::map<std::int64_t, std::size_t> sizes;
    for (int i = 0; i < 1000000; ++i) {
        const Step s = stepOf(seed, i);
        sizes[s.beam] += s.added;
        holo.writeBeam(0, s.beam, samples(seed ^ std::uint64_t(s.beam), sizes[s.beam]));
        if (i % 7 == 6) {
            holo.commit();
            // Acknowledged: every step up to i is durable.
            if (::write(ackFd, &i, sizeof i) != sizeof i) _exit(3);
        }
    }
    _exit(0);
}

TEST_F(HoloFileTest, SurvivesSigkillAtRandomMoments) {
    SplitMix rng(2026);
    int trials = 0, killedMidWrite = 0;
    for (int trial = 0; trial < 25; ++trial) {
        const std::string file = path("trial" + std::to_string(trial) + ".hdk");
        const std::uint64_t seed = 1000 + std::uint64_t(trial);
        int fds[2];
        ASSERT_EQ(::pipe(fds), 0);
        const pid_t pid = ::fork();
        ASSERT_GE(pid, 0);
        if (pid == 0) {
            ::close(fds[0]);
            writerChild(file, seed, fds[1]);
        }
        ::close(fds[1]);
        int acked = -1, i = 0;
        ASSERT_EQ(::read(fds[0], &i, sizeof i), ssize_t(sizeof i)) << "trial " << trial;
        std::this_thread::sleep_for(std::chrono::microseconds(1000 + int(rng.next() * 40000)));
        ::kill(pid, SIGKILL);
        int status = 0;
        ::waitpid(pid, &status, 0);
        ASSERT_TRUE(WIFSIGNALED(status)) << "trial " << trial << ": the writer ended on its own";
        while (::read(fds[0], &i, sizeof i) == sizeof i) acked = i;
        ::close(fds[0]);
        ++trials;
        // Reopened (and repaired): every acknowledged step is present; each beam holds what
        // the writer wrote at some step since (records only grow), never a torn mix.
        HoloFile holo(file, {});
        const auto sure = contentAfter(seed, acked);
        const auto later = contentAfter(seed, acked + 5000);
        for (std::int64_t beam = 0; beam < 97; ++beam) {
            const std::vector<HoloSample> got = holo.readBeam(0, beam);
            const std::size_t need = sure.count(beam) ? sure.at(beam) : 0;
            const std::size_t most = later.count(beam) ? later.at(beam) : 0;
            ASSERT_GE(got.size(), need) << "trial " << trial << " beam " << beam << ": lost "
                                        << "acknowledged samples (acked step " << acked << ")";
            ASSERT_LE(got.size(), most) << "trial " << trial << " beam " << beam;
            EXPECT_TRUE(same(got, samples(seed ^ std::uint64_t(beam), got.size())))
                << "trial " << trial << " beam " << beam << ": contents differ";
        }
        if (holo.info().truncated > 0 || holo.info().recovered > 0) ++killedMidWrite;
        // A second opening finds the repaired file as it was left: nothing more to repair.
        HoloFile again(file, {});
        EXPECT_EQ(again.info().truncated, 0) << "trial " << trial;
        EXPECT_EQ(again.info().recovered, 0) << "trial " << trial;
    }
    EXPECT_EQ(trials, 25);
    EXPECT_GT(killedMidWrite, 0) << "no kill fell between commits";
}

}  // namespace
}  // namespace penumbra
