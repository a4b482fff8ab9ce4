// `penumbra probe` under a square lamp behind a half-plane blocker: the printed irradiance
// against the closed form of the rectangle that stays visible, within the issue's tolerance
// (1% of the largest value everywhere, 1% relative where the value is at least a tenth of it).

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <sstream>

#include "cli_support.h"
#include "closed_forms.h"

namespace penumbra {
namespace {

namespace fs = std::filesystem;

using test::rectangleFormFactor;

TEST(ProbeCli, HalfPlaneBlockerUnderASquareLampMatchesTheClosedForm) {
    const fs::path dir =
        fs::temp_directory_path() / ("penumbra_cli_probe_" + std::to_string(::getpid()));
    fs::remove_all(dir);
    fs::create_directories(dir);
    // A 1 m lamp 1 m up facing down (emission 2, 3, 4) and a black blocker at 0.6 m covering
    // x ≥ −0.1; no surface reflects, so the irradiance is the direct light alone.
    test::writeFile(dir / "scene.json", R"({
  "format": "penumbra-scene/1",
  "settings": {"patch_size": 0.5, "element_size": 0.25},
  "materials": {"lamp": {"reflectance": [0, 0, 0], "emission": [2, 3, 4]},
                "black": {"reflectance": [0, 0, 0]}},
  "objects": [
    {"id": "lamp", "shape": {"type": "quad", "size": [1, 1]}, "material": "lamp",
     "transform": {"translate": [0, 1, 0], "rotate_deg": [180, 0, 0]}},
    {"id": "blocker", "shape": {"type": "quad", "size": [4, 4]}, "material": "black",
     "transform": {"translate": [1.9, 0.6, 0], "rotate_deg": [180, 0, 0]}}
  ]
})");
    std::ostringstream points;
    std::vector<double> xs;
    for (int i = 0; i <= 60; ++i) {
        const double px = -1.2 + 2.0 * i / 60;
        xs.push_back(px);
        points << px << " 0 0.15 0 1 0\n";
    }
    test::writeFile(dir / "points.txt", points.str());
    const std::string run = std::string("timeout 120 '") + PENUMBRA_EXE + "' probe '" +
                            (dir / "scene.json").string() + "' --points '" +
                            (dir / "points.txt").string() + "' > '" + (dir / "out.txt").string() +
                            "' 2> '" + (dir / "err.txt").string() + "'";
    ASSERT_EQ(test::runShell(run), 0) << test::readFile(dir / "err.txt");
    std::istringstream out(test::readFile(dir / "out.txt"));
    std::vector<double> measured, truth;
    double largest = 0;
    for (double px : xs) {
        double r, g, b;
        ASSERT_TRUE(out >> r >> g >> b);
        // The blocker's edge x = −0.1 at height 0.6, seen from (px, 0), meets the lamp's plane
        // at x = px + (−0.1 − px) / 0.6; the lamp is visible on the smaller-x side of it.
        const double edge = px + (-0.1 - px) / 0.6;
        const double f = rectangleFormFactor(-0.5 - px, std::min(0.5, edge) - px, -0.65, 0.35, 1.0);
        measured.push_back(g);
        truth.push_back(3 * f);
        largest = std::max(largest, 3 * f);
        EXPECT_NEAR(r / 2, b / 4, 1e-6 * largest);  // one form factor times each channel
    }
    ASSERT_GT(largest, 0);
    for (std::size_t i = 0; i < xs.size(); ++i) {
        EXPECT_NEAR(measured[i], truth[i], 0.01 * largest) << "x = " << xs[i];
        if (truth[i] >= 0.1 * largest) {
            EXPECT_NEAR(measured[i], truth[i], 0.01 * truth[i]) << "x = " << xs[i];
        }
    }
    fs::remove_all(dir);
}

}  // namespace
}  // namespace penumbra
