// The interpolants' far field is smooth (issue 46, point 2): in a closed room of one
// reflectance and one emission (the furnace) the interpolant image is flat at the closed form
// E / (1 − ρ) / π, and in the Cornell box the relative error over any 32 × 32 pixel window of a
// flat face, against the exact gather of the same solution at every pixel (every reflecting
// patch through its visible part, no rays), stays within a per cent.

#include <gtest/gtest.h>
#include <tbb/parallel_for.h>

#include <cmath>

#include "edit/scene_io.h"
#include "render/camera_rays.h"
#include "render/exact_irradiance.h"
#include "render/hifi_mesh.h"
#include "render/path_tracer.h"
#include "solver/discretization.h"
#include "solver/progressive_solver.h"
#include "solver/ray_tracer.h"
#include "test_scenes.h"

namespace penumbra {
namespace {

Camera lookingAt(const Vec3& position, const Vec3& target, double fovDeg) {
    Camera c;
    c.position = position;
    c.lookAt = target;
    c.up = Vec3(0, 1, 0);
    c.fovDeg = fovDeg;
    return c;
}

/// Interpolants of a converged solution as the command line builds them (the far field's
/// rays), with the far field pooled (`pool` true: the default) or each sample's own.
HifiMesh buildInterpolants(const Discretization& disc, const RayTracer& tracer,
                           const ProgressiveSolver& solver, bool pool) {
    ExactIrradiance exact(disc, ExactIrradianceOptions::forInterpolants(256), &tracer);
    exact.setReflected(reflectedRadiosity(disc, solver));
    HifiOptions options;
    if (!pool) options.farFieldPoolRadius = 0;
    HifiMesh mesh;
    mesh.build(disc, exact, options);
    return mesh;
}

TEST(HifiFarField, TheFurnaceRoomIsFlatAtTheClosedForm) {
    Scene scene = test::emptyScene(0.25, 0.0625);
    test::addMaterial(scene, "glow", Rgb(0.5), Rgb(1.0));
    test::addClosedRoom(scene, 1.0, "glow");
    Discretization disc(scene);
    RayTracer tracer(disc);
    ProgressiveSolver solver(disc, tracer, SolverOptions{});
    solver.converge(1e-5, 1000000);
    const HifiMesh mesh = buildInterpolants(disc, tracer, solver, true);
    // Into a corner, so the view holds three walls and their edges.
    const CameraRays rays(lookingAt({0.3, 0.2, 0.35}, {-0.5, -0.5, -0.5}, 80), 64, 64);
    const Image image = renderInterpolants(disc, tracer, mesh, rays, 1);
    const double truth = 1.0 / (1 - 0.5) / M_PI;
    double worst = 0;
    for (const Rgb& p : image.pixels) worst = std::max(worst, std::abs(p.x - truth) / truth);
    EXPECT_LT(worst, 0.005) << "radiance off E / (1 − ρ) / π = " << truth << " by " << 100 * worst
                            << "% at worst";
}

TEST(HifiFarField, CornellWindowsOfFlatFacesFollowTheExactGather) {
    Scene scene = loadScene(std::string(PENUMBRA_SOURCE_DIR) + "/scenes/cornell-box.json");
    Discretization disc(scene);
    RayTracer tracer(disc);
    ProgressiveSolver solver(disc, tracer, SolverOptions{});
    solver.converge(1e-3, 1000000);
    // The back wall above the boxes, filling the view.
    const CameraRays rays(lookingAt({0, 1.15, 0.2}, {0, 1.15, -0.75}, 30), 64, 64);
    // The reference: every reflecting patch gathered through its visible part (near ones
    // element by element) at each pixel's point, with the same solution's light.
    ExactIrradiance exact(disc, {}, &tracer);
    exact.setReflected(reflectedRadiosity(disc, solver));
    Image reference(rays.width(), rays.height());
    tbb::parallel_for(0, rays.height(), [&](int y) {
        for (int x = 0; x < rays.width(); ++x) {
            const Vec3 dir = rays.rayDirection(x + 0.5, y + 0.5);
            const RayTracer::FirstHit hit = tracer.firstHit(rays.origin(), dir);
            if (hit.element < 0 || hit.backFace) continue;
            const Material& m = disc.elementMaterial(hit.element);
            const Vec3 p = rays.origin() + double(hit.t) * dir;
            reference.at(x, y) =
                (m.emission +
                 m.reflectance * exact.irradiance(p, disc.elements()[hit.element].normal)) /
                M_PI;
        }
    });
    const std::vector<std::uint64_t> faces = flatFaceKeys(disc, tracer, rays);
    // Each sample's own rays, then the far field pooled over neighbouring samples (the default).
    WindowErrors own, pooled;
    for (bool pool : {false, true}) {
        const Image image = renderInterpolants(
            disc, tracer, buildInterpolants(disc, tracer, solver, pool), rays, 1);
        (pool ? pooled : own) = flatWindowErrors(image, reference, faces, 32, 4);
    }
    ASSERT_GT(pooled.windows, 10) << pooled.toString();
    EXPECT_LE(pooled.maxStd, 0.01) << "pooled " << pooled.toString();
    // The pooling is what makes it smooth: the samples' own rays leave twice the blotches.
    EXPECT_LT(2 * pooled.maxStd, own.maxStd)
        << "pooled " << pooled.toString() << ", own " << own.toString();
}

}  // namespace
}  // namespace penumbra
