// Furnace: a closed box, every surface reflectance ρ and emission E, converges to
// B = E/(1 − ρ) everywhere (the geometric series of interreflection with Σ_j F_ij = 1).
#include <gtest/gtest.h>

#include "solver/discretization.h"
#include "solver/progressive_solver.h"
#include "solver/ray_tracer.h"
#include "test_scenes.h"

namespace penumbra {
namespace {

void runFurnace(Rgb rho, Rgb emission, double patchSize, double elementSize,
                SolverOptions options = {}, double tolerance = 5e-3) {
    Scene scene;
    scene.settings.patchSize = patchSize;
    scene.settings.elementSize = elementSize;
    test::addMaterial(scene, "glow", rho, emission);
    test::addClosedRoom(scene, 2.0, "glow");
    Discretization disc(scene);
    RayTracer tracer(disc);
    ProgressiveSolver solver(disc, tracer, options);
    solver.converge(1e-6, 200000);
    ASSERT_LT(solver.unshotFraction(), 1e-6);
    const Rgb expected = emission / (1.0 - rho);
    double worst = 0;
    for (std::size_t e = 0; e < disc.elements().size(); ++e) {
        const Rgb& b = solver.radiosity()[e];
        for (int c = 0; c < 3; ++c) {
            double rel = std::abs(b[c] - expected[c]) / expected[c];
            worst = std::max(worst, rel);
            ASSERT_LT(rel, tolerance) << "element " << e << " channel " << c << ": B = " << b[c]
                                      << ", expected E/(1-rho) = " << expected[c] << "; "
                                      << disc.elements()[e].toString();
        }
    }
    ::testing::Test::RecordProperty("worst_relative_error", std::to_string(worst));
}

TEST(Furnace, GreyBoxConvergesToGeometricSeries) { runFurnace(Rgb(0.5), Rgb(1.0), 0.5, 0.25); }

TEST(Furnace, ColouredHighAlbedoBox) {
    runFurnace(Rgb(0.8, 0.6, 0.3), Rgb(2.0, 1.0, 0.5), 1.0, 0.25);
}

TEST(Furnace, StochasticShootingConvergesToo) {
    // Every shot below half the emitted power goes Monte Carlo: unbiased, so the furnace
    // still holds within the noise of ~4e6 rays spread over 96 elements (~1% per element).
    SolverOptions options;
    options.stochasticBelow = 0.5;
    options.raysPerEmittedPower = 2e6;
    runFurnace(Rgb(0.5), Rgb(1.0), 0.5, 0.25, options, 0.03);
}

}  // namespace
}  // namespace penumbra
