// The settling estimate (ProgressiveSolver::computeSettling; docs/solver.md "Settling")
// against the truth: on a bundled edit log, the from-scratch references `replay --reference`
// computes say how much each element's radiosity still has to change after each line. The
// estimate must bound that change for at least 95% of the elements, and while the light is
// still settling its RMS (George et al. eq. 7) must be within a factor of two of the true RMS
// error. Once a deterministic solve has converged it is negligible.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <memory>
#include <string>

#include "edit/edit_session.h"
#include "edit/replay.h"
#include "solver/discretization.h"
#include "solver/progressive_solver.h"
#include "solver/ray_tracer.h"
#include "test_scenes.h"

namespace penumbra {
namespace {

constexpr double kEps = 1e-5;

/// A converged lit room (deterministic shots).
struct Lit {
    Scene scene = test::makeLitRoom("white");
    std::unique_ptr<Discretization> disc = std::make_unique<Discretization>(scene);
    std::unique_ptr<RayTracer> tracer = std::make_unique<RayTracer>(*disc);
    std::unique_ptr<ProgressiveSolver> solver =
        std::make_unique<ProgressiveSolver>(*disc, *tracer, SolverOptions{});

    Lit() { solver->converge(kEps, 1000000); }
};

/// The lit room three shots into its solve: most of its light still to come.
struct BarelySolved {
    Scene scene = test::makeLitRoom("white");
    Discretization disc{scene};
    RayTracer tracer{disc};
    ProgressiveSolver solver{disc, tracer, SolverOptions{}};

    BarelySolved() { solver.step(3); }
};

TEST(Settling, BoundsTheChangeOnTheBundledAddCubeLog) {
    ReplayOptions options;
    options.scenePath = std::string(PENUMBRA_SOURCE_DIR) + "/scenes/cube-room.json";
    options.logPath = std::string(PENUMBRA_SOURCE_DIR) + "/scenes/logs/cube-room-add-cube.jsonl";
    options.reference = true;
    const nlohmann::json report = runReplay(options);
    ASSERT_EQ(report["edits"].size(), 2u);
    for (const nlohmann::json& edit : report["edits"]) {
        const std::string what = "line " + edit["line"].dump() + " (" +
                                 edit["op"].get<std::string>() + "): " + edit.dump();
        EXPECT_GE(edit["estimate_coverage"].get<double>(), 0.95) << what;
        const double estimated = edit["error_estimate"].get<double>();
        const double truth = edit["error_rms"].get<double>();
        // Settling (the add, nothing shot yet): the RMS within a factor of two. Converged: the
        // truth is the two solves' sampling noise, which the estimate's change part leaves out.
        if (truth > 0.005) {
            EXPECT_LE(estimated, 2 * truth) << what;
            EXPECT_GE(estimated, 0.5 * truth) << what;
        } else {
            EXPECT_LT(estimated, 0.005) << what;
        }
    }
}

TEST(Settling, IsNegligibleOnceConverged) {
    Lit lit;
    const SettlingEstimate estimate = lit.solver->computeSettling();
    EXPECT_LT(estimate.relativeRms, 1e-3);
    for (double n : estimate.noise) EXPECT_EQ(n, 0.0) << "deterministic shots have no noise";
}

TEST(Settling, AgainstTheReflectedLightTheLampsDoNotDiluteIt) {
    // A barely started solve of the lit room: the change against the reflected light alone
    // (recomputed here from the solver's radiosity and the materials' emission) is the
    // walls' relative change, several times eq. 7's, whose denominator the lamp dominates.
    BarelySolved lit;
    const Discretization& disc = lit.disc;
    const ProgressiveSolver& solver = lit.solver;
    const SettlingEstimate estimate = solver.computeSettling();
    double num = 0, den = 0;
    for (std::size_t e = 0; e < disc.elements().size(); ++e) {
        if (!disc.elementAlive(static_cast<int>(e))) continue;
        const double area = disc.elements()[e].area;
        const double reflected =
            luminance(solver.radiosity()[e] - disc.elementMaterial(static_cast<int>(e)).emission);
        num += estimate.change[e] * estimate.change[e] * area;
        den += reflected * reflected * area;
    }
    ASSERT_GT(den, 0);
    EXPECT_NEAR(estimate.reflectedRms, std::sqrt(num / den), 1e-12 * estimate.reflectedRms);
    EXPECT_GT(estimate.reflectedRms, 3 * estimate.relativeRms);
    EXPECT_GT(estimate.reflectedRms, 0.05) << "three shots leave most of the light to come";
}

TEST(Settling, BoundsTheLossOfARemovedLampAndItsReflections) {
    // cube-room with a second lamp, converged, then the lamp removed with nothing shot yet:
    // every element loses the lamp's direct light and its reflections, a pure loss with no
    // gain to cancel it. The bound must hold for 95% of the elements and the RMS be within a
    // factor of two of the truth.
    const std::filesystem::path log =
        std::filesystem::temp_directory_path() / "penumbra-settling-remove-lamp.jsonl";
    {
        std::ofstream out(log);
        out << R"({"op":"add","object":{"id":"lamp2","shape":{"type":"sphere","radius":0.1,)"
               R"("segments":12},"material":"lamp","transform":{"translate":[-1.2,2.2,1.0]}}})"
            << "\n"
            << R"({"op":"converge","threshold":0.01})"
            << "\n"
            << R"({"op":"remove","id":"lamp2"})"
            << "\n";
    }
    ReplayOptions options;
    options.scenePath = std::string(PENUMBRA_SOURCE_DIR) + "/scenes/cube-room.json";
    options.logPath = log.string();
    options.reference = true;
    const nlohmann::json report = runReplay(options);
    std::filesystem::remove(log);
    ASSERT_EQ(report["edits"].size(), 3u);
    const nlohmann::json& removed = report["edits"][2];
    const double estimated = removed["error_estimate"].get<double>();
    const double truth = removed["error_rms"].get<double>();
    ASSERT_GT(truth, 0.005) << "the removal must leave light to settle: " << removed.dump();
    EXPECT_LE(estimated, 2 * truth) << removed.dump();
    EXPECT_GE(estimated, 0.5 * truth) << removed.dump();
    EXPECT_GE(removed["estimate_coverage"].get<double>(), 0.95) << removed.dump();
}

TEST(Settling, BoundsTheSamplingNoiseOfSmallElements) {
    // cube-room with a finely tessellated ball on the table (4,096 small triangles, as a
    // scanned mesh's), solved with a coarse stochastic tail (a tenth of the interactive rays,
    // everything below 1% of the emitted power on rays): most of the ball's indirect light
    // arrives in a few dozen hits per element, and the session's redistribution batches add
    // hits of their own, negative ones included. A cube is added next to the ball and the
    // light converged; after both lines the bound must hold for 95% of the elements against
    // a from-scratch solve. The noise of an element that drew few hits is as large as its
    // patch's pooled hits say, not as small as its own.
    const std::filesystem::path dir =
        std::filesystem::temp_directory_path() / "penumbra-settling-small-elements";
    std::filesystem::create_directories(dir);
    {
        std::ifstream in(std::string(PENUMBRA_SOURCE_DIR) + "/scenes/cube-room.json");
        nlohmann::json scene = nlohmann::json::parse(in);
        scene["objects"].push_back(nlohmann::json::parse(
            R"({"id":"ball","shape":{"type":"sphere","radius":0.2,"segments":64},)"
            R"("material":"wall","transform":{"translate":[-0.4,0.95,-0.2]}})"));
        std::ofstream(dir / "ball-room.json") << scene.dump();
        std::ofstream(dir / "add-cube.jsonl")
            << R"({"op":"add","object":{"id":"cube","shape":{"type":"box","size":[0.35,0.35,0.35]},)"
               R"("material":"wall","transform":{"translate":[0.15,0.925,-0.25],)"
               R"("rotate_deg":[0,30,0]}}})"
            << "\n"
            << R"({"op":"converge","threshold":0.001})"
            << "\n";
    }
    ReplayOptions options;
    options.scenePath = (dir / "ball-room.json").string();
    options.logPath = (dir / "add-cube.jsonl").string();
    options.reference = true;
    options.solver.raysPerEmittedPower = 1e6;
    options.solver.stochasticBelow = 1e-2;
    const nlohmann::json report = runReplay(options);
    std::filesystem::remove_all(dir);
    ASSERT_EQ(report["edits"].size(), 2u);
    for (const nlohmann::json& edit : report["edits"])
        EXPECT_GE(edit["estimate_coverage"].get<double>(), 0.95)
            << "line " << edit["line"] << ": " << edit.dump();
}

TEST(SettlingSummary, ReadsAsTheFullPassOnTheRobotRoomLog) {
    // robot-room (46,000 elements, over the full-pass limit): after each of the log's lines, the
    // stratified sample's eq. 7 and reflected RMS against the full pass over every element.
#if defined(__SANITIZE_ADDRESS__)
    GTEST_SKIP() << "a robot-room replay takes minutes under the sanitizers";
#endif
    ReplayOptions options;
    options.scenePath = std::string(PENUMBRA_SOURCE_DIR) + "/scenes/robot-room-empty.json";
    options.logPath = std::string(PENUMBRA_SOURCE_DIR) + "/scenes/logs/robot-room-add-robot.jsonl";
    int compared = 0;
    options.afterEdit = [&](EditSession& session, const EditEvent&, nlohmann::json& entry) {
        const ProgressiveSolver& solver = session.solver();
        std::size_t alive = 0;
        for (std::size_t e = 0; e < session.discretization().elements().size(); ++e)
            alive += session.discretization().elementAlive(static_cast<int>(e)) ? 1 : 0;
        ASSERT_GT(alive, ProgressiveSolver::kSettlingSummaryFullBelow) << "not sampled";
        const SettlingEstimate summary = solver.computeSettlingSummary();
        const SettlingEstimate full = solver.computeSettling();
        EXPECT_TRUE(summary.change.empty());
        EXPECT_DOUBLE_EQ(entry["error_estimate"].get<double>(), summary.relativeRms)
            << "replay reports the summary";
        const std::string what = "line " + entry["line"].dump();
        EXPECT_NEAR(summary.relativeRms, full.relativeRms, 0.03 * full.relativeRms) << what;
        EXPECT_NEAR(summary.reflectedRms, full.reflectedRms, 0.03 * full.reflectedRms) << what;
        EXPECT_GT(full.relativeRms, 0.0) << what;
        ++compared;
    };
    runReplay(options);
    EXPECT_EQ(compared, 7);
}

TEST(SettlingSummary, IsTheFullPassOnASmallScene) {
    // Under the limit the summary is the full pass's sums, exactly.
    BarelySolved lit;
    const SettlingEstimate summary = lit.solver.computeSettlingSummary();
    const SettlingEstimate full = lit.solver.computeSettling();
    EXPECT_GT(full.relativeRms, 0.0);
    EXPECT_EQ(summary.relativeRms, full.relativeRms);
    EXPECT_EQ(summary.reflectedRms, full.reflectedRms);
}

}  // namespace
}  // namespace penumbra
