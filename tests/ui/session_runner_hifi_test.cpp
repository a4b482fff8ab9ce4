// SessionRunner in the interpolant mode (Hardt & Teller 1996): Gouraud while the lighting
// moves, then, once it is still, the interpolants of exactly that lighting, built in the
// background; an edit outdates them and they come back for the new lighting. The reference
// is an independent build: a fresh session converged the same way, its own ExactIrradiance
// and HifiMesh, drawn by renderInterpolants.

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <thread>

#include "render/camera_rays.h"
#include "render/gouraud_renderer.h"
#include "render/hifi/exact_irradiance.h"
#include "render/hifi/hifi_mesh.h"
#include "render/path_tracer.h"
#include "runner_test_support.h"
#include "test_scenes.h"
#include "ui/session_runner.h"

namespace penumbra {
namespace {

constexpr int kSize = 64;

ViewRequest view() {
    ViewRequest v;
    v.camera = test::litRoomTopCamera();
    v.width = v.height = kSize;
    v.mode = ViewMode::Interpolant;
    return v;
}

using test::pumpUntil;
using test::waitUntil;

/// Relative RMSE over all pixels (path_tracer.h's measure, nothing masked).
double relativeDifference(const Image& a, const Image& b) { return relativeRmse(a, b); }

/// The interpolants of `scene` converged to 1e-3 as the runner converges it, drawn from
/// the test view, and the Gouraud image of the same lighting.
std::pair<Image, Image> independentImages(const Scene& scene) {
    EditSession session(scene, SolverOptions{});
    while (!session.solver().converged(1e-3) && session.solve(1) > 0) {
    }
    const Discretization& disc = session.discretization();
    ExactIrradiance exact(disc, ExactIrradianceOptions::forInterpolants(256), &session.tracer());
    exact.setReflected(reflectedRadiosity(disc, session.solver()));
    HifiMesh mesh;
    mesh.build(disc, exact);
    const CameraRays rays(test::litRoomTopCamera(), kSize, kSize);
    Image hifi = renderInterpolants(disc, session.tracer(), mesh, rays);
    Image gouraud = renderGouraud(disc, session.tracer(), session.solver().displayRadiosity(),
                                  test::litRoomTopCamera(), kSize, kSize);
    return {std::move(hifi), std::move(gouraud)};
}

TEST(SessionRunnerInterpolant, ShowsTheInterpolantsOnceTheLightingIsStillAndAgainAfterAnEdit) {
    SessionRunnerOptions options;
    options.threaded = false;
    options.solveBudgetMs = 1;  // a few shots per pump: the lighting moves for a while
    const Scene scene = test::makeLitRoom("red");
    SessionRunner runner(std::make_unique<EditSession>(scene, SolverOptions{}), options);
    runner.setView(view());
    // While the solver shoots: Gouraud, saying why.
    runner.pump();
    ASSERT_TRUE(runner.image());
    EXPECT_EQ(runner.image()->mode, ViewMode::Gouraud);
    EXPECT_NE(runner.image()->note.find("interpolants"), std::string::npos);

    auto shown = pumpUntil(runner, 60,
                           [](const ViewportImage& i) { return i.mode == ViewMode::Interpolant; });
    ASSERT_TRUE(shown && shown->mode == ViewMode::Interpolant);
    EXPECT_FALSE(shown->reduced);
    auto [hifi, gouraud] = independentImages(scene);
    const double toHifi = relativeDifference(shown->render.radiance, hifi);
    const double hifiToGouraud = relativeDifference(gouraud, hifi);
    EXPECT_LT(toHifi, 1e-6);
    EXPECT_GT(hifiToGouraud, 10 * toHifi);
    EXPECT_TRUE(runner.takeMessages().empty());

    // An edit: Gouraud of the new lighting until it is still, then its interpolants.
    TransformCommand t;
    t.id = "slab";
    t.translate = test::kLitRoomSlabDragTarget;
    runner.submit(t);
    runner.pump();
    EXPECT_EQ(runner.image()->mode, ViewMode::Gouraud);
    EXPECT_GT(runner.image()->stateSerial, shown->stateSerial);
    auto after = pumpUntil(runner, 60,
                           [](const ViewportImage& i) { return i.mode == ViewMode::Interpolant; });
    ASSERT_TRUE(after && after->mode == ViewMode::Interpolant);
    Scene moved = scene;
    for (SceneObject& o : moved.objects)
        if (o.id == "slab") o.transform.translate = test::kLitRoomSlabDragTarget;
    auto [movedHifi, movedGouraud] = independentImages(moved);
    (void)movedGouraud;
    // Only what the edit changed was re-meshed (HifiMesh::update): fewer elements than all.
    int triangles = 0, meshed = 0, elements = 0;
    ASSERT_EQ(std::sscanf(after->note.c_str(), "interpolants: %d triangles, %d of %d elements",
                          &triangles, &meshed, &elements),
              3)
        << after->note;
    EXPECT_GT(meshed, 0) << after->note;
    EXPECT_LT(meshed, elements) << after->note;
    // Redistribution reaches the lighting of a fresh solve only to the convergence threshold,
    // and the elements kept carry their light to the update's 1%.
    EXPECT_LT(relativeDifference(after->render.radiance, movedHifi), 0.015);
    EXPECT_GT(relativeDifference(after->render.radiance, hifi), 0.05);
}

TEST(SessionRunnerInterpolant, ThreadedRunnerBuildsInTheBackgroundAndFollowsAnEdit) {
    SessionRunnerOptions options;
    options.solveBudgetMs = 5;
    SessionRunner runner(std::make_unique<EditSession>(test::makeLitRoom("red"), SolverOptions{}),
                         options);
    runner.setView(view());
    auto first = waitUntil(runner, 60,
                           [](const ViewportImage& i) { return i.mode == ViewMode::Interpolant; });
    ASSERT_TRUE(first && first->mode == ViewMode::Interpolant);
    TransformCommand t;
    t.id = "slab";
    t.translate = test::kLitRoomSlabDragTarget;
    runner.submit(t);
    auto second = waitUntil(runner, 60, [&](const ViewportImage& i) {
        return i.mode == ViewMode::Interpolant && i.stateSerial > first->stateSerial;
    });
    ASSERT_TRUE(second && second->mode == ViewMode::Interpolant);
    EXPECT_GT(relativeDifference(second->render.radiance, first->render.radiance), 0.05);
    EXPECT_TRUE(runner.takeMessages().empty());
}

}  // namespace
}  // namespace penumbra
