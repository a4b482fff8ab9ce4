// `penumbra holodeck fill` and `info`: a batch fill and a camera's fill of a bundled scene add
// exactly the samples asked for to one file that keeps its sections between runs; `info`
// reports what `fill` wrote; a file that is not a holodeck is one error line and exit 2.

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <nlohmann/json.hpp>

#include "cli_support.h"

namespace penumbra {
namespace {

namespace fs = std::filesystem;

class HolodeckCli : public ::testing::Test {
protected:
    void SetUp() override {
        mDir = fs::temp_directory_path() / ("penumbra_cli_holodeck_" + std::to_string(::getpid()));
        fs::remove_all(mDir);
        fs::create_directories(mDir);
    }
    void TearDown() override { fs::remove_all(mDir); }
    /// Runs penumbra with `args`; its exit status, stdout in out.txt and stderr in err.txt.
    int run(const std::string& args) const {
        return test::runShell(std::string("timeout 300 '") + PENUMBRA_EXE + "' " + args + " > '" +
                              (mDir / "out.txt").string() + "' 2> '" + (mDir / "err.txt").string() +
                              "'");
    }
    nlohmann::json out() const { return nlohmann::json::parse(test::readFile(mDir / "out.txt")); }
    std::string err() const { return test::readFile(mDir / "err.txt"); }
    fs::path mDir;
};

TEST_F(HolodeckCli, FillAddsTheSamplesAskedForAndInfoReportsThem) {
    const std::string scene = std::string(PENUMBRA_SOURCE_DIR) + "/scenes/cube-room.json";
    const std::string file = (mDir / "cube-room.hdk").string();
    ASSERT_EQ(run("holodeck fill '" + scene + "' --holodeck '" + file + "' --samples 20000"), 0)
        << err();
    const nlohmann::json filled = out();
    EXPECT_EQ(filled["samples_added"].get<std::int64_t>(), 20000);
    EXPECT_EQ(filled["samples"].get<std::int64_t>(), 20000);
    ASSERT_EQ(filled["sections"].size(), 1u);
    const std::int64_t sectionBeams = filled["sections"][0]["beams"].get<std::int64_t>();
    EXPECT_GE(sectionBeams, 50000);
    EXPECT_LE(sectionBeams, 500000);

    // A camera's view adds to the same file, whose section stays as it was made.
    ASSERT_EQ(run("holodeck fill '" + scene + "' --holodeck '" + file +
                  "' --camera default --width 64 --height 48 --samples 3000"),
              0)
        << err();
    EXPECT_EQ(out()["samples_added"].get<std::int64_t>(), 3000);
    EXPECT_EQ(out()["samples"].get<std::int64_t>(), 23000);
    EXPECT_EQ(out()["sections"][0]["beams"].get<std::int64_t>(), sectionBeams);

    ASSERT_EQ(run("holodeck info '" + file + "'"), 0) << err();
    const nlohmann::json info = out();
    EXPECT_EQ(info["samples"].get<std::int64_t>(), 23000);
    EXPECT_GT(info["beams"].get<std::int64_t>(), 1000);
    EXPECT_EQ(info["bytes"].get<std::int64_t>(), std::int64_t(fs::file_size(file)));
}

TEST_F(HolodeckCli, RenderStoresItsPointsAndTheNextRenderStartsFromThem) {
    const std::string scene = std::string(PENUMBRA_SOURCE_DIR) + "/scenes/cube-room.json";
    const std::string file = (mDir / "view.hdk").string();
    const std::string render = "render '" + scene +
                               "' --mode epi --width 160 --height 120 --holodeck '" + file +
                               "' --out '" + (mDir / "view.png").string() + "' --report '" +
                               (mDir / "report.json").string() + "'";
    auto report = [&] { return nlohmann::json::parse(test::readFile(mDir / "report.json")); };
    // First visit: nothing to read; the shaded points go into a new holodeck.
    ASSERT_EQ(run(render), 0) << err();
    const nlohmann::json first = report();
    EXPECT_EQ(first["holodeck_samples"].get<std::int64_t>(), 0);
    const std::int64_t stored = first["holodeck_stored"].get<std::int64_t>();
    EXPECT_GT(stored, 160 * 120 / 5);
    const double firstError = first["frames"][0]["rmse"].get<double>();
    // Second visit: the first frame starts from them (most of them: a point is taken when the
    // eye sees it), and its error is as small as the first visit's.
    ASSERT_EQ(run(render), 0) << err();
    const nlohmann::json second = report();
    EXPECT_GT(second["holodeck_samples"].get<std::int64_t>(), stored * 9 / 10);
    EXPECT_GT(second["frames"][0]["holodeck_ms"].get<double>(), 0);
    EXPECT_LE(second["frames"][0]["rmse"].get<double>(), firstError * 1.1)
        << "first visit " << firstError;
    // A mode without the display has no use for a holodeck: one error line, exit 2.
    EXPECT_EQ(run("render '" + scene + "' --mode gouraud --holodeck '" + file + "' --out '" +
                  (mDir / "g.png").string() + "'"),
              2);
    EXPECT_NE(err().find("--holodeck"), std::string::npos) << err();
}

TEST_F(HolodeckCli, AFilledViewReopensWithAPointInNearlyEveryPixel) {
    // A view filled with a sample per pixel (its pixel rays) gives the reopened first frame
    // nearly every pixel at once, and a smaller error than the display's own first frame.
    const std::string scene = std::string(PENUMBRA_SOURCE_DIR) + "/scenes/cube-room.json";
    const std::string file = (mDir / "filled.hdk").string();
    const int w = 160, h = 120;
    ASSERT_EQ(run("holodeck fill '" + scene + "' --holodeck '" + file + "' --camera default" +
                  " --width 160 --height 120 --samples " + std::to_string(w * h)),
              0)
        << err();
    EXPECT_EQ(out()["samples_added"].get<std::int64_t>(), w * h);
    const std::string render = "render '" + scene + "' --mode epi --width 160 --height 120" +
                               " --out '" + (mDir / "view.png").string() + "' --report '" +
                               (mDir / "report.json").string() + "'";
    ASSERT_EQ(run(render), 0) << err();
    const nlohmann::json without = nlohmann::json::parse(test::readFile(mDir / "report.json"));
    ASSERT_EQ(run(render + " --holodeck '" + file + "'"), 0) << err();
    const nlohmann::json with = nlohmann::json::parse(test::readFile(mDir / "report.json"));
    EXPECT_GT(with["holodeck_samples"].get<std::int64_t>(), w * h * 9 / 10);
    EXPECT_GT(with["frames"][0]["visible_points"].get<std::int64_t>(), w * h * 85 / 100);
    EXPECT_LT(with["frames"][0]["rmse"].get<double>(), without["frames"][0]["rmse"].get<double>());
}

TEST_F(HolodeckCli, ReplayForgetsWhatEachEditChangedAndKeepsTheRest) {
    const std::string scene = std::string(PENUMBRA_SOURCE_DIR) + "/scenes/cube-room.json";
    const std::string log =
        std::string(PENUMBRA_SOURCE_DIR) + "/scenes/logs/cube-room-add-cube.jsonl";
    const std::string file = (mDir / "replay.hdk").string();
    ASSERT_EQ(run("holodeck fill '" + scene + "' --holodeck '" + file + "' --samples 50000"), 0)
        << err();
    ASSERT_EQ(run("replay '" + scene + "' '" + log + "' --holodeck '" + file + "' --report '" +
                  (mDir / "replay.json").string() + "'"),
              0)
        << err();
    const nlohmann::json report = nlohmann::json::parse(test::readFile(mDir / "replay.json"));
    std::int64_t dropped = 0;
    for (const auto& edit : report["edits"]) {
        ASSERT_TRUE(edit.contains("beams_invalidated")) << edit.dump();
        EXPECT_LE(edit["beams_invalidated"].get<std::int64_t>(),
                  edit["samples_invalidated"].get<std::int64_t>());
        dropped += edit["samples_invalidated"].get<std::int64_t>();
    }
    // Adding a cube shadows part of the room and hides what is behind it: some samples go,
    // most of the room keeps its light and its samples.
    EXPECT_GT(dropped, 0);
    EXPECT_LT(dropped, 50000 / 2);
    ASSERT_EQ(run("holodeck info '" + file + "'"), 0) << err();
    EXPECT_EQ(out()["samples"].get<std::int64_t>(), 50000 - dropped);
}

TEST_F(HolodeckCli, ANonHolodeckFileIsOneErrorLineAndExitTwo) {
    const fs::path bad = mDir / "notes.hdk";
    test::writeFile(bad, "these are notes, not samples\n");
    EXPECT_EQ(run("holodeck info '" + bad.string() + "'"), 2);
    const std::string message = err();
    EXPECT_EQ(std::count(message.begin(), message.end(), '\n'), 1) << message;
    EXPECT_NE(message.find(bad.string()), std::string::npos) << message;
    EXPECT_NE(message.find("not a holodeck file"), std::string::npos) << message;
    EXPECT_EQ(run("holodeck info '" + (mDir / "missing.hdk").string() + "'"), 2);
}

}  // namespace
}  // namespace penumbra
