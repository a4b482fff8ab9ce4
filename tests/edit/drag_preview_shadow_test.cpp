// The drag preview's shadow in the reflected light (SolverOptions::previewShadowRayBudget):
// while cube-room's table top is dragged, the floor under it holds the indirect light of a
// converged solution with the table there, in every buffer the solver publishes.

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include "edit/edit_command.h"
#include "edit/edit_session.h"
#include "solver/discretization.h"
#include "solver/progressive_solver.h"

namespace penumbra {
namespace {

const std::string kScene = std::string(PENUMBRA_SOURCE_DIR) + "/scenes/cube-room.json";

void run(EditSession& s, const std::string& command) {
    s.apply(parseEditCommand(command, {}, &s.scene()));
}

std::string moveTableTop(double x) {
    char command[160];
    std::snprintf(
        command, sizeof command,
        R"({"op":"transform","id":"table-top","transform":{"translate":[%g,0.725,-0.2]}})", x);
    return command;
}

/// Per element the indirect irradiance the display shows: H − H_emission, plus while an
/// object is dragged the preview buffer's reflected part (T − T_emission)/ρ.
std::vector<double> indirectLuminance(const EditSession& s) {
    const ProgressiveSolver& solver = s.solver();
    const Discretization& disc = s.discretization();
    const bool preview = solver.previewObject() >= 0;
    std::vector<double> y(disc.elements().size());
    for (std::size_t e = 0; e < y.size(); ++e) {
        Rgb h = solver.irradiance()[e] - solver.irradianceFromEmission()[e];
        if (preview) {
            const Rgb rho = disc.elementMaterial(static_cast<int>(e)).reflectance;
            const Rgb t = solver.previewRadiosity()[e] - solver.previewRadiosityFromEmission()[e];
            for (int c = 0; c < 3; ++c)
                if (rho[c] > 0) h[c] += t[c] / rho[c];
        }
        y[e] = luminance(h);
    }
    return y;
}

/// The floor's elements around and under the table (the table top stands at z = -0.2).
std::vector<int> floorUnderTable(const Discretization& disc) {
    std::vector<int> floor;
    for (std::size_t e = 0; e < disc.elements().size(); ++e) {
        const Element& el = disc.elements()[e];
        if (disc.objects()[el.object].id == "floor" && std::abs(el.centroid.x) < 1.0 &&
            std::abs(el.centroid.z + 0.2) < 0.7)
            floor.push_back(static_cast<int>(e));
    }
    return floor;
}

struct FloorReading {
    double meanRatio = 0;  ///< the floor's summed indirect luminance over the reference's
    double rms = 0;        ///< relative RMS over the floor's elements
};

FloorReading compareFloor(const std::vector<int>& floor, const std::vector<double>& value,
                          const std::vector<double>& reference) {
    double sum = 0, sum0 = 0, num = 0, den = 0;
    for (int e : floor) {
        sum += value[e];
        sum0 += reference[e];
        num += (value[e] - reference[e]) * (value[e] - reference[e]);
        den += reference[e] * reference[e];
    }
    return {sum / sum0, std::sqrt(num / den)};
}

/// Drags the table top through three positions, a few shots each as the editor's solver
/// thread gives a drag step, and returns the floor's worst reading over every shot of every
/// position against the converged solution of the table moved there.
FloorReading worstWhileDragging(const SolverOptions& options) {
    auto session = EditSession::open(kScene, options);
    session->converge(1e-3);
    const std::vector<int> floor = floorUnderTable(session->discretization());
    run(*session, R"({"op":"select","id":"table-top"})");
    for (int k = 0; k < 30; ++k) session->solve(1);
    FloorReading worst{1.0, 0.0};
    for (int step = 1; step <= 3; ++step) {
        const double x = 0.05 * step;
        auto reference = EditSession::open(kScene, options);
        run(*reference, moveTableTop(x));
        reference->converge(1e-4);
        const std::vector<double> truth = indirectLuminance(*reference);
        run(*session, moveTableTop(x));
        for (int shot = 0; shot < 8; ++shot) {
            session->solve(1);
            const FloorReading r = compareFloor(floor, indirectLuminance(*session), truth);
            if (std::abs(r.meanRatio - 1) > std::abs(worst.meanRatio - 1))
                worst.meanRatio = r.meanRatio;
            worst.rms = std::max(worst.rms, r.rms);
        }
    }
    return worst;
}

TEST(DragPreviewShadow, TheFloorUnderADraggedTableLosesTheReflectedLightItBlocks) {
    // With the gather (and the shadow carried from position to position) every buffer, from
    // the first shot after a move, darkens the floor under the table as the converged
    // solution does; shots alone leave it about a quarter too bright, since the hundreds of
    // weak shooters whose light the table blocks never shoot within a drag step.
    const SolverOptions gathered = interactiveSolverOptions();
    ASSERT_GT(gathered.previewShadowRayBudget, 0);
    const FloorReading with = worstWhileDragging(gathered);
    EXPECT_NEAR(with.meanRatio, 1.0, 0.08);
    EXPECT_LT(with.rms, 0.12);

    SolverOptions shotsOnly = gathered;
    shotsOnly.previewShadowRayBudget = 0;
    const FloorReading without = worstWhileDragging(shotsOnly);
    std::printf(
        "floor under the table, worst over the drag: gathered %.3f of converged (RMS %.3f), "
        "shots only %.3f (RMS %.3f)\n",
        with.meanRatio, with.rms, without.meanRatio, without.rms);
    EXPECT_GT(without.meanRatio, 1.15) << "the scene no longer shows what the gather is for";
}

TEST(DragPreviewShadow, TheCarriedShadowMovesWithTheObject) {
    // A long drag step: right after the move, before any shot at the new position, the floor
    // holds the shadow gathered at the last position moved with the table top, closer to the
    // converged solution with the table there than the same shadow left where it was.
    const SolverOptions options = interactiveSolverOptions();
    auto session = EditSession::open(kScene, options);
    session->converge(1e-3);
    const std::vector<int> floor = floorUnderTable(session->discretization());
    run(*session, R"({"op":"select","id":"table-top"})");
    for (int k = 0; k < 30; ++k) session->solve(1);
    const std::vector<double> gathered = indirectLuminance(*session);

    constexpr double kStep = 0.35;
    auto reference = EditSession::open(kScene, options);
    run(*reference, moveTableTop(kStep));
    reference->converge(1e-4);
    const std::vector<double> truth = indirectLuminance(*reference);
    run(*session, moveTableTop(kStep));
    const FloorReading moved = compareFloor(floor, indirectLuminance(*session), truth);
    const FloorReading left = compareFloor(floor, gathered, truth);
    // The gather's own error, at the position it was gathered at.
    auto still = EditSession::open(kScene, options);
    still->converge(1e-4);
    const FloorReading own = compareFloor(floor, gathered, indirectLuminance(*still));
    std::printf(
        "floor right after a %.2f m step: moved RMS %.3f (%.3f of converged), left "
        "RMS %.3f (%.3f); the gather where it was gathered RMS %.3f\n",
        kStep, moved.rms, moved.meanRatio, left.rms, left.meanRatio, own.rms);
    EXPECT_LT(moved.rms, 0.8 * left.rms);
    EXPECT_LT(moved.rms, 1.5 * own.rms);
    EXPECT_NEAR(moved.meanRatio, 1.0, 0.1);
}

}  // namespace
}  // namespace penumbra
