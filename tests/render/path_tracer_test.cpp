// The path tracer against closed forms: the furnace (a closed room whose every surface emits
// E and reflects ρ has radiance E / (π (1 − ρ)) everywhere) and one bounce of direct light
// (a grey floor under a lamp in a black world shows ρ/π times the exact direct irradiance).

#include "render/path_tracer.h"

#include <gtest/gtest.h>

#include "render/camera_rays.h"
#include "render/hifi/exact_irradiance.h"
#include "solver/discretization.h"
#include "solver/progressive_solver.h"
#include "solver/ray_tracer.h"
#include "test_scenes.h"

namespace penumbra {
namespace {

Camera lookingAt(Vec3 position, Vec3 target) {
    Camera c;
    c.position = position;
    c.lookAt = target;
    c.up = Vec3(0, 1, 0);
    c.fovDeg = 60;
    return c;
}

TEST(PathTracer, FurnaceRoomHasTheClosedFormRadianceEverywhere) {
    Scene scene;
    test::addMaterial(scene, "glow", Rgb(0.5, 0.25, 0.0), Rgb(1.0, 2.0, 3.0));
    test::addClosedRoom(scene, 2.0, "glow");
    Discretization disc(scene);
    RayTracer tracer(disc);
    const CameraRays rays(lookingAt({0.2, 0.1, 0.3}, {0, -0.3, -1}), 12, 12);
    PathTraceOptions options;
    options.samplesPerPixel = 256;
    options.rouletteDepth = 40;  // E / (1 − ρ) needs long paths; roulette adds only noise
    const PathTraceResult r = pathTrace(disc, tracer, rays, options);
    const Rgb truth = Rgb(1.0, 2.0, 3.0) / (M_PI * (Rgb(1.0) - Rgb(0.5, 0.25, 0.0)));
    Rgb mean(0.0);
    for (const Rgb& p : r.image.pixels) mean += p;
    mean /= static_cast<double>(r.image.pixels.size());
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(mean[c], truth[c], 0.01 * truth[c]) << c;
    // Every pixel sees an emitter: the mask leaves them all out.
    for (std::uint8_t m : r.emitterMask) EXPECT_EQ(m, 1);
}

TEST(PathTracer, OneBounceOfDirectLightIsReflectanceOverPiTimesTheExactIrradiance) {
    Scene scene;
    test::addMaterial(scene, "grey", Rgb(0.6));
    test::addMaterial(scene, "lamp", Rgb(0.0), Rgb(10.0));
    test::addMaterial(scene, "black", Rgb(0.0));
    scene.objects.push_back(test::makeQuad("floor", 4, 4, "grey", {0, 0, 0}));
    scene.objects.push_back(test::makeQuad("lamp", 0.6, 0.6, "lamp", {0, 1, 0}, {180, 0, 0}));
    // A black blocker casting a penumbra across the view.
    scene.objects.push_back(test::makeQuad("card", 0.5, 0.8, "black", {0.3, 0.5, 0}, {180, 0, 0}));
    Discretization disc(scene);
    RayTracer tracer(disc);
    const int size = 10;
    const CameraRays rays(lookingAt({0, 2.2, 1.2}, {0, 0, 0}), size, size);
    ExactIrradiance exact(disc);
    // At floor points seen through a coarse view (some in the card's penumbra):
    int compared = 0;
    for (int y = 1; y < size; y += 3)
        for (int x = 1; x < size; x += 3) {
            const Vec3 dir = rays.rayDirection(x + 0.5, y + 0.5);
            const RayTracer::FirstHit hit = tracer.firstHit(rays.origin(), dir);
            if (hit.element < 0 || disc.elements()[hit.element].object != 0) continue;
            const Vec3 point = rays.origin() + double(hit.t) * dir;
            // A 1 × 1 image from a pinhole right above the point looking straight at it:
            // every path starts at that point.
            const Vec3 eye = point + Vec3(0, 1e-3, 0);
            const CameraRays one(lookingAt(eye, point), 1, 1);
            PathTraceOptions many;
            many.samplesPerPixel = 40000;
            many.seed = 7 + x + 100 * y;
            const double traced = pathTrace(disc, tracer, one, many).image.at(0, 0).x;
            const double truth = 0.6 / M_PI * exact.direct(point, Vec3(0, 1, 0)).x;
            EXPECT_NEAR(traced, truth, 0.02 * truth + 1e-4) << x << ", " << y;
            ++compared;
        }
    EXPECT_GE(compared, 4);
}

TEST(PathTracer, RelativeRmseLeavesMaskedPixelsOut) {
    Image a(2, 1), b(2, 1);
    a.at(0, 0) = Rgb(1.0);
    b.at(0, 0) = Rgb(2.0);
    a.at(1, 0) = Rgb(100.0);
    b.at(1, 0) = Rgb(0.0);
    EXPECT_NEAR(relativeRmse(a, b, {0, 1}), 0.5, 1e-15);
    EXPECT_GT(relativeRmse(a, b), 1.0);
}

}  // namespace
}  // namespace penumbra

namespace penumbra {
namespace {

TEST(PathTracer, AgreesWithAConvergedRadiosityGatherInAClosedRoom) {
    // A grey room lit by a small lamp: the path tracer's radiance at floor points against
    // ρ/π times the exact gather from the converged radiosity solution (direct light exact,
    // indirect light from constant elements: a few per cent of discretization error).
    Scene scene;
    test::addMaterial(scene, "grey", Rgb(0.6));
    test::addMaterial(scene, "lamp", Rgb(0.0), Rgb(20.0));
    test::addClosedRoom(scene, 2.0, "grey");
    scene.objects.push_back(test::makeQuad("lamp", 0.5, 0.5, "lamp", {0, 0.99, 0}, {180, 0, 0}));
    scene.settings.patchSize = 0.25;
    scene.settings.elementSize = 0.125;
    Discretization disc(scene);
    RayTracer tracer(disc);
    ProgressiveSolver solver(disc, tracer, SolverOptions{});
    solver.converge(1e-5, 1000000);
    ExactIrradiance exact(disc);
    exact.setReflected(reflectedRadiosity(disc, solver));
    for (Vec3 point : {Vec3(0.1, -1, 0.2), Vec3(-0.6, -1, 0.5)}) {
        const CameraRays one(lookingAt(point + Vec3(0, 1e-3, 0), point), 1, 1);
        PathTraceOptions many;
        many.samplesPerPixel = 40000;
        const double traced = pathTrace(disc, tracer, one, many).image.at(0, 0).x;
        const double gathered = 0.6 / M_PI * exact.irradiance(point, Vec3(0, 1, 0)).x;
        EXPECT_NEAR(traced, gathered, 0.03 * gathered);
    }
}

}  // namespace
}  // namespace penumbra
