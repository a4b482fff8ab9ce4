// `mpirun -np 2 penumbra holodeck fill` and `penumbra holodeck merge` (docs/holodeck.md,
// "Scale-out"): two ranks' batch fill adds exactly the samples asked for to one file, continuing
// the beams it held, with every beam's samples the sequence its ray indices give (no sample
// twice) and equal to an independent one-process fill's; the part files are gone. A failing rank
// ends the job with one error line and exit 2, and leaves the target as it was. merge keeps the
// longest of agreeing holdings and refuses disagreeing ones.
//
// Open MPI refuses to run as root (CI does) unless told to; the tests tell it. The sanitizer
// build runs them without leak detection (tests/CMakeLists.txt says why).

#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <nlohmann/json.hpp>

#include "cli_support.h"
#include "render/holodeck/holo_file.h"
#include "render/holodeck/holo_server.h"

namespace penumbra {
namespace {

namespace fs = std::filesystem;

class HolodeckMpi : public ::testing::Test {
protected:
    void SetUp() override {
        mDir =
            fs::temp_directory_path() / ("penumbra_cli_holodeck_mpi_" + std::to_string(::getpid()));
        fs::remove_all(mDir);
        fs::create_directories(mDir);
        ::setenv("OMPI_ALLOW_RUN_AS_ROOT", "1", 1);
        ::setenv("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1", 1);
    }
    void TearDown() override { fs::remove_all(mDir); }
    /// Runs `prefix` penumbra `args`; its exit status, stdout in out.txt and stderr in err.txt.
    int run(const std::string& args, const std::string& prefix = "") const {
        return test::runShell("timeout 120 " + prefix + " '" + std::string(PENUMBRA_EXE) + "' " +
                              args + " > '" + (mDir / "out.txt").string() + "' 2> '" +
                              (mDir / "err.txt").string() + "'");
    }
    /// The same under `mpirun -np ranks` (no binding: every rank may use every core).
    int runRanks(int ranks, const std::string& args) const {
        return run(args, "mpirun -np " + std::to_string(ranks) + " --oversubscribe --bind-to none");
    }
    nlohmann::json out() const { return nlohmann::json::parse(test::readFile(mDir / "out.txt")); }
    std::string err() const { return test::readFile(mDir / "err.txt"); }
    std::string path(const std::string& name) const { return (mDir / name).string(); }
    fs::path mDir;
};

const std::string kScene = std::string(PENUMBRA_SOURCE_DIR) + "/scenes/cube-room.json";

/// Every beam's samples lie on the rays of indices 0, 1, 2, … of its sequence (so none is
/// there twice); returns the samples checked.
std::int64_t expectIndexedSequences(const std::string& file) {
    HoloFile holo = HoloFile::openReadOnly(file);
    const HoloServer rays(holo, nullptr);
    std::int64_t checked = 0;
    for (const auto& [section, beam] : holo.storedBeams()) {
        const std::vector<HoloSample> samples = holo.readBeam(section, beam);
        for (std::size_t i = 0; i < samples.size(); ++i, ++checked) {
            const auto [entry, exit] = rays.sampleRay(section, beam, i);
            const HoloSample& s = samples[i];
            EXPECT_TRUE(s.entry[0] == encodeCellPosition(entry.u) &&
                        s.entry[1] == encodeCellPosition(entry.v) &&
                        s.exit[0] == encodeCellPosition(exit.u) &&
                        s.exit[1] == encodeCellPosition(exit.v))
                << file << ": beam " << beam << " sample " << i << " is not ray " << i;
        }
    }
    return checked;
}

/// cube-room with a coarse section (4 × 4 × 4 cells, 7,680 beams), so that a small fill gives
/// every beam several samples.
std::string coarseScene(const fs::path& dir) {
    nlohmann::json scene = nlohmann::json::parse(test::readFile(kScene));
    scene["settings"]["holodeck"] = {
        {{"min", {-2.2, 0.05, -2.2}}, {"max", {2.2, 2.75, 2.2}}, {"grid", {4, 4, 4}}}};
    const std::string path = (dir / "coarse-room.json").string();
    test::writeFile(path, scene.dump());
    return path;
}

TEST_F(HolodeckMpi, TwoRanksFillAsOneProcessWouldWithNoSampleTwice) {
    const std::string fill = "holodeck fill '" + coarseScene(mDir) + "' --holodeck ";
    // The target holds samples already; the two ranks continue its beams.
    ASSERT_EQ(run(fill + "'" + path("ranks.hdk") + "' --samples 5000"), 0) << err();
    ASSERT_EQ(runRanks(2, fill + "'" + path("ranks.hdk") + "' --samples 25000"), 0) << err();
    const nlohmann::json report = out();
    EXPECT_EQ(report["ranks"].get<int>(), 2);
    EXPECT_EQ(report["samples_added"].get<std::int64_t>(), 25000);
    EXPECT_EQ(report["samples"].get<std::int64_t>(), 30000);
    EXPECT_EQ(report["sections"][0]["beams"].get<std::int64_t>(), 7680);
    EXPECT_FALSE(fs::exists(path("ranks.rank0.hdk")));
    EXPECT_FALSE(fs::exists(path("ranks.rank1.hdk")));
    EXPECT_EQ(expectIndexedSequences(path("ranks.hdk")), 30000);

    // An independent one-process fill: where both hold a beam's sample, it is the same ten bytes
    // (position, distance and colour).
    ASSERT_EQ(run(fill + "'" + path("one.hdk") + "' --samples 30000"), 0) << err();
    HoloFile ranks = HoloFile::openReadOnly(path("ranks.hdk"));
    HoloFile one = HoloFile::openReadOnly(path("one.hdk"));
    // The same beams but for a few of the smallest, whose first sample comes last.
    EXPECT_NEAR(double(ranks.storedBeams().size()), double(one.storedBeams().size()), 77.0);
    std::int64_t compared = 0;
    for (const auto& [section, beam] : one.storedBeams()) {
        const std::vector<HoloSample> a = ranks.readBeam(section, beam);
        const std::vector<HoloSample> b = one.readBeam(section, beam);
        const std::size_t n = std::min(a.size(), b.size());
        if (n == 0) continue;
        EXPECT_EQ(std::memcmp(a.data(), b.data(), n * sizeof(HoloSample)), 0)
            << "beam " << beam << ": the ranks' samples differ from one process's";
        compared += std::int64_t(n);
    }
    EXPECT_GT(compared, 27000);
}

TEST_F(HolodeckMpi, ABatchFillOfTheDefaultLayoutAddsTheTotalOverTheRanks) {
    ASSERT_EQ(runRanks(2, "holodeck fill '" + kScene + "' --holodeck '" + path("batch.hdk") +
                              "' --samples 20000"),
              0)
        << err();
    EXPECT_EQ(out()["samples"].get<std::int64_t>(), 20000);
    EXPECT_EQ(out()["samples_added"].get<std::int64_t>(), 20000);
    EXPECT_EQ(expectIndexedSequences(path("batch.hdk")), 20000);
    EXPECT_FALSE(fs::exists(path("batch.rank1.hdk")));
    // A camera's view is filled by one process.
    EXPECT_EQ(runRanks(2, "holodeck fill '" + kScene + "' --holodeck '" + path("batch.hdk") +
                              "' --camera default --samples 100"),
              2);
    EXPECT_NE(err().find("--camera"), std::string::npos) << err();
}

TEST_F(HolodeckMpi, AFailingRankEndsTheJobWithOneErrorLineAndExitTwo) {
    // Every rank fails: one line, not one per rank.
    EXPECT_EQ(runRanks(2, "holodeck fill '" + path("missing.json") + "' --samples 100"), 2);
    std::size_t lines = 0;
    for (std::size_t at = err().find("penumbra: "); at != std::string::npos;
         at = err().find("penumbra: ", at + 1))
        ++lines;
    EXPECT_EQ(lines, 1u) << err();
    EXPECT_NE(err().find("missing.json"), std::string::npos) << err();

    // Rank 1 alone fails (its part's path is a directory): the others do not wait for it, the
    // target keeps what it had, and no part is left.
    ASSERT_EQ(
        run("holodeck fill '" + kScene + "' --holodeck '" + path("t.hdk") + "' --samples 500"), 0)
        << err();
    fs::create_directories(path("t.rank1.hdk") + "/in-the-way");
    EXPECT_EQ(runRanks(2, "holodeck fill '" + kScene + "' --holodeck '" + path("t.hdk") +
                              "' --samples 1000"),
              2);
    EXPECT_NE(err().find("t.rank1.hdk"), std::string::npos) << err();
    EXPECT_FALSE(fs::exists(path("t.rank0.hdk")));
    ASSERT_EQ(run("holodeck info '" + path("t.hdk") + "'"), 0) << err();
    EXPECT_EQ(out()["samples"].get<std::int64_t>(), 500);
}

TEST_F(HolodeckMpi, MergeKeepsTheLongestOfAgreeingPartsAndRefusesOthers) {
    const std::string fill = "holodeck fill '" + coarseScene(mDir) + "' --holodeck ";
    // The first 1000 samples of a fill are the first of a longer one: the parts agree.
    ASSERT_EQ(run(fill + "'" + path("p1.hdk") + "' --samples 1000"), 0) << err();
    ASSERT_EQ(run(fill + "'" + path("p2.hdk") + "' --samples 3000"), 0) << err();
    ASSERT_EQ(run("holodeck merge '" + path("out.hdk") + "' '" + path("p1.hdk") + "' '" +
                  path("p2.hdk") + "'"),
              0)
        << err();
    EXPECT_EQ(out()["samples"].get<std::int64_t>(), 3000);
    EXPECT_EQ(out()["samples_added"].get<std::int64_t>(), 3000);
    EXPECT_EQ(out()["samples_shared"].get<std::int64_t>(), 1000);
    EXPECT_EQ(out()["parts"].get<int>(), 2);

    // Another shading seed: the same rays, other colours; refused, the target unchanged.
    ASSERT_EQ(run(fill + "'" + path("p3.hdk") + "' --samples 500 --seed 2"), 0) << err();
    EXPECT_EQ(run("holodeck merge '" + path("out.hdk") + "' '" + path("p3.hdk") + "'"), 2);
    EXPECT_NE(err().find("disagree"), std::string::npos) << err();
    ASSERT_EQ(run("holodeck info '" + path("out.hdk") + "'"), 0) << err();
    EXPECT_EQ(out()["samples"].get<std::int64_t>(), 3000);
    // A refused merge into a new file leaves no file.
    EXPECT_EQ(run("holodeck merge '" + path("new.hdk") + "' '" + path("p2.hdk") + "' '" +
                  path("p3.hdk") + "'"),
              2);
    EXPECT_FALSE(fs::exists(path("new.hdk")));
}

}  // namespace
}  // namespace penumbra
