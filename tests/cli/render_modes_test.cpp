// The real `penumbra render` with the interactive display modes (DESIGN.md "Command line"):
// every mode writes a PNG of the requested size; --frames writes one file per frame; --overlay
// edges writes the EPI's pixel classes; --log replays one line per frame; the report carries
// "frames" with total_ms, reconstruct_ms, new_sample_fraction and rmse; --overlay settling
// tints where the light may still change and nothing once it settled; bad values exit 2 with
// one line on stderr.

#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>

#include "cli/cli_support.h"
#include "render/image.h"

namespace {

using penumbra::test::readFile;
using penumbra::test::runShell;
using penumbra::test::writeFile;

namespace fs = std::filesystem;
using nlohmann::json;

struct RunResult {
    int exitStatus = -1;
    std::string err;
};

class RenderModesCli : public ::testing::Test {
protected:
    void SetUp() override {
        const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
        mDir = fs::temp_directory_path() /
               (std::string("penumbra_render_") + info->name() + "_" + std::to_string(::getpid()));
        fs::remove_all(mDir);
        fs::create_directories(mDir);
    }
    void TearDown() override {
        if (!HasFailure()) fs::remove_all(mDir);
    }
    /// Runs `penumbra render cornell-box.json ARGS` (small, loosely converged) from the source
    /// directory, stderr captured.
    RunResult render(const std::string& args) const {
        const fs::path err = mDir / "stderr.txt";
        const std::string command = "cd '" + std::string(PENUMBRA_SOURCE_DIR) + "' && '" +
                                    PENUMBRA_EXE +
                                    "' render scenes/cornell-box.json --converge 0.05 --width 48 "
                                    "--height 40 " +
                                    args + " 2> '" + err.string() + "'";
        RunResult run;
        run.exitStatus = runShell(command);
        run.err = readFile(err);
        return run;
    }
    std::string path(const std::string& name) const { return (mDir / name).string(); }
    void expectPng(const std::string& name, int width = 48, int height = 40) const {
        ASSERT_TRUE(fs::exists(path(name))) << name << " was not written";
        penumbra::Image image = penumbra::readPng(path(name));
        EXPECT_EQ(image.width, width) << name;
        EXPECT_EQ(image.height, height) << name;
        double sum = 0;
        for (const auto& p : image.pixels) sum += p.x + p.y + p.z;
        EXPECT_GT(sum, 0) << name << " is black";
    }
    fs::path mDir;
};

TEST_F(RenderModesCli, EveryModeWritesAnImageOfTheRequestedSize) {
    for (const char* mode : {"epi", "cache", "reference", "gouraud"}) {
        const std::string out = std::string(mode) + ".png";
        RunResult run = render(std::string("--mode ") + mode + " --out '" + path(out) + "'");
        ASSERT_EQ(run.exitStatus, 0) << mode << ": " << run.err;
        expectPng(out);
    }
}

TEST_F(RenderModesCli, FramesOverlayAndReport) {
    RunResult run = render("--mode epi --frames 3 --overlay edges --out '" + path("orbit.png") +
                           "' --report '" + path("report.json") + "'");
    ASSERT_EQ(run.exitStatus, 0) << run.err;
    expectPng("orbit.png");
    for (const char* frame : {"orbit-0000.png", "orbit-0001.png", "orbit-0002.png"})
        expectPng(frame);
    EXPECT_FALSE(fs::exists(path("orbit-0003.png")));
    expectPng("orbit-edges.png");

    const json report = json::parse(readFile(path("report.json")));
    for (const char* key : {"shots", "rays", "seconds", "unshot_fraction", "elements", "patches"})
        EXPECT_TRUE(report.contains(key)) << key;
    ASSERT_TRUE(report.contains("frames"));
    ASSERT_EQ(report["frames"].size(), 3u);
    for (const json& f : report["frames"]) {
        // Every figure of render/display/display_report.h's displayFrameJson.
        for (const char* key :
             {"frame", "total_ms", "reconstruct_ms", "new_sample_fraction", "find_edges_ms",
              "silhouette_ms", "shadow_ms", "project_ms", "rasterize_ms", "points_ms",
              "reachability_ms", "interpolate_ms", "anti_alias_ms", "complex_filter_ms",
              "smooth_ms", "fill_ms", "hide_ms", "shadow_drop_ms", "request_ms", "shade_ms",
              "new_samples",
              "requested_samples", "visible_points", "silhouette_edges", "sharp_edges",
              "shadow_edges", "screen_edges", "empty_pixels", "simple_pixels", "complex_pixels",
              "unsampled_pixels", "unfilled_pixels", "dropped_shadowed"}) {
            ASSERT_TRUE(f.contains(key)) << key << " missing in " << f.dump();
            EXPECT_GE(f[key].get<double>(), 0.0) << key;
        }
        EXPECT_LE(f["reconstruct_ms"].get<double>(), f["total_ms"].get<double>());
    }
    // Frame 0 shows the warm-up (25% of the pixels); later frames 2% new samples each.
    EXPECT_NEAR(report["frames"][0]["new_sample_fraction"].get<double>(), 0.25, 0.03);
    EXPECT_NEAR(report["frames"][2]["new_sample_fraction"].get<double>(), 0.02, 0.01);
    ASSERT_TRUE(report["frames"][2].contains("rmse")) << "the last frame is compared";
    const double rmse = report["frames"][2]["rmse"].get<double>();
    EXPECT_GT(rmse, 0.0);
    EXPECT_LT(rmse, 0.2);
}

TEST_F(RenderModesCli, LogReplaysOneLinePerFrame) {
    std::ofstream(path("edits.jsonl"))
        << R"({"op":"move","id":"short-box","by":[-0.2,0,0.1]})"
        << "\n"
        << R"({"op":"material","id":"tall-box","material":{"reflectance":[0.7,0.2,0.2]}})"
        << "\n";
    RunResult run =
        render("--mode cache --log '" + path("edits.jsonl") + "' --out '" + path("log.png") +
               "' --report '" + path("report.json") + "' --sample-fraction 0.03");
    ASSERT_EQ(run.exitStatus, 0) << run.err;
    for (const char* frame : {"log-0000.png", "log-0001.png", "log-0002.png"}) expectPng(frame);
    const json report = json::parse(readFile(path("report.json")));
    ASSERT_EQ(report["frames"].size(), 3u) << "one frame before the log, one per line";
    EXPECT_FALSE(report["frames"][0].contains("edit"));
    EXPECT_EQ(report["frames"][1]["edit"]["op"], "move");
    EXPECT_EQ(report["frames"][2]["edit"]["op"], "material");
    EXPECT_NEAR(report["frames"][2]["new_sample_fraction"].get<double>(), 0.03, 0.01);
}

TEST_F(RenderModesCli, TheInterpolantsNeedNoSolveOfTheSceneButTheLeafSolve) {
    // The picture gathers from the leaf solve (every element shoots), which starts from
    // nothing: without --subdivide the scene's own solve is skipped, and the picture is the one
    // made after it (--subdivide 10 runs it and subdivides nothing). The report's solve figures
    // are the leaf solve's.
    auto interpolants = [&](const std::string& name, const std::string& args) {
        RunResult run =
            render("--mode interpolant --gather-rays 16 --samples 1 " + args + " --out '" +
                   path(name + ".exr") + "' --report '" + path(name + ".json") + "'");
        EXPECT_EQ(run.exitStatus, 0) << name << ": " << run.err;
        return json::parse(readFile(path(name + ".json")));
    };
    const json leafOnly = interpolants("leaf", "");
    const json solvedFirst = interpolants("solved", "--subdivide 10");
    ASSERT_EQ(solvedFirst["subdivisions"].get<int>(), 0);
    EXPECT_GT(leafOnly["shots"].get<int>(), 0);
    EXPECT_GT(leafOnly["rays"].get<double>(), 0);
    EXPECT_LT(leafOnly["unshot_fraction"].get<double>(), 0.05);
    const penumbra::Image a = penumbra::readExr(path("leaf.exr"));
    const penumbra::Image b = penumbra::readExr(path("solved.exr"));
    ASSERT_EQ(a.pixels.size(), b.pixels.size());
    for (std::size_t i = 0; i < a.pixels.size(); ++i)
        for (int c = 0; c < 3; ++c)
            ASSERT_NEAR(a.pixels[i][c], b.pixels[i][c], 1e-5 * (1 + b.pixels[i][c]))
                << "pixel " << i << " channel " << c;
}

TEST_F(RenderModesCli, SettlingOverlayTintsUnsettledLightAndLeavesSettledLightAlone) {
    // The same Gouraud picture with and without the overlay, at a loose and a tight
    // convergence. The heat colour is (255, g, 0) blended over the picture, so wherever the
    // overlay changed a pixel, red went up or stayed and blue went down or stayed.
    auto picture = [&](const std::string& converge, bool overlay, const std::string& name) {
        const fs::path err = mDir / "stderr.txt";
        const std::string command =
            "cd '" + std::string(PENUMBRA_SOURCE_DIR) + "' && '" + PENUMBRA_EXE +
            "' render scenes/cornell-box.json --mode gouraud --width 48 --height 40 --converge " +
            converge +
            (overlay ? " --overlay settling --report '" + path(name + ".json") + "'" : "") +
            " --out '" + path(name + ".png") + "' 2> '" + err.string() + "'";
        EXPECT_EQ(runShell(command), 0) << readFile(err);
        return penumbra::readPng(path(name + ".png"));
    };
    const penumbra::Image loosePlain = picture("0.3", false, "loose-plain");
    const penumbra::Image looseHeat = picture("0.3", true, "loose-heat");
    const json loose = json::parse(readFile(path("loose-heat.json")));
    EXPECT_GT(loose["error_estimate"].get<double>(), 0.01);
    EXPECT_FALSE(loose["settled"].get<bool>());
    ASSERT_EQ(loosePlain.pixels.size(), looseHeat.pixels.size());
    std::size_t tinted = 0;
    for (std::size_t i = 0; i < loosePlain.pixels.size(); ++i) {
        const auto& a = loosePlain.pixels[i];
        const auto& b = looseHeat.pixels[i];
        if (a == b) continue;
        ++tinted;
        EXPECT_GE(b.x, a.x - 1e-3) << "pixel " << i;
        EXPECT_LE(b.z, a.z + 1e-3) << "pixel " << i;
    }
    EXPECT_GT(tinted, loosePlain.pixels.size() / 4) << "most of a barely solved box is unsettled";

    const penumbra::Image tightPlain = picture("1e-4", false, "tight-plain");
    const penumbra::Image tightHeat = picture("1e-4", true, "tight-heat");
    const json tight = json::parse(readFile(path("tight-heat.json")));
    EXPECT_LT(tight["error_estimate"].get<double>(), 0.01);
    EXPECT_TRUE(tight["settled"].get<bool>());
    EXPECT_EQ(tightPlain.pixels, tightHeat.pixels) << "a settled picture carries no heat";
}

TEST_F(RenderModesCli, BadValuesExitTwoWithOneLine) {
    for (const std::string& args :
         {std::string("--mode sketch"), std::string("--mode epi --overlay normals"),
          std::string("--mode epi --overlay settling"),
          std::string("--mode epi --sample-fraction 2"),
          std::string("--mode epi --log '") + path("missing.jsonl") + "'"}) {
        RunResult run = render(args + " --out '" + path("bad.png") + "'");
        EXPECT_EQ(run.exitStatus, 2) << args << ": " << run.err;
        EXPECT_EQ(std::count(run.err.begin(), run.err.end(), '\n'), 1) << args << ": " << run.err;
        EXPECT_EQ(run.err.rfind("penumbra: ", 0), 0u) << run.err;
        EXPECT_FALSE(fs::exists(path("bad.png"))) << args;
    }
    RunResult run = render("--mode sketch --out '" + path("bad.png") + "'");
    EXPECT_NE(run.err.find("sketch"), std::string::npos) << run.err;
}

}  // namespace
