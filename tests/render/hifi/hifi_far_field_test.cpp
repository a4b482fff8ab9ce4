// The interpolants' far field is smooth (issue 46, point 2): in a closed room of one
// reflectance and one emission (the furnace) the interpolant image is flat at the closed form
// E / (1 − ρ) / π, with the far field pooled over neighbouring samples and with each sample's
// own; and in the Cornell box the relative error over any 32 × 32 pixel window of a face lit
// mostly by reflected light (the back wall, the short box's front face, the ceiling), against
// the exact gather of the same solution at every pixel (every reflecting patch through its
// visible part, no rays), stays within a per cent. PENUMBRA_TEST_IMAGES=DIR writes the Cornell
// views' images there (VIEW-reference.exr, VIEW-interpolants.exr).

#include <gtest/gtest.h>
#include <tbb/parallel_for.h>

#include <cmath>
#include <cstdlib>

#include "edit/io/scene_io.h"
#include "render/camera_rays.h"
#include "render/hifi/exact_irradiance.h"
#include "render/hifi/hifi_mesh.h"
#include "render/image.h"
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
/// rays), with the far field pooled (`pool` true: the default) or each sample's own, and taken
/// from the elements' base triangles off them (`fromBase` true: the default) or cast at every
/// sample.
HifiMesh buildInterpolants(const Discretization& disc, const RayTracer& tracer,
                           const ProgressiveSolver& solver, bool pool, bool fromBase = true) {
    ExactIrradiance exact(disc, ExactIrradianceOptions::forInterpolants(256), &tracer);
    exact.setReflected(reflectedRadiosity(disc, solver));
    HifiOptions options;
    if (!pool) options.farFieldPoolRadius = 0;
    options.farFieldFromBase = fromBase;
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
    // Into a corner, so the view holds three walls and their edges.
    const CameraRays rays(lookingAt({0.3, 0.2, 0.35}, {-0.5, -0.5, -0.5}, 80), 64, 64);
    const double truth = 1.0 / (1 - 0.5) / M_PI;
    // The far field pooled over neighbouring samples (the build's default), and each sample's
    // own: the far field's rays alone keep it flat.
    for (bool pool : {true, false}) {
        const HifiMesh mesh = buildInterpolants(disc, tracer, solver, pool);
        const Image image = renderInterpolants(disc, tracer, mesh, rays, 1);
        double worst = 0;
        for (const Rgb& p : image.pixels) worst = std::max(worst, std::abs(p.x - truth) / truth);
        EXPECT_LT(worst, 0.005) << (pool ? "pooled" : "own")
                                << " far field: radiance off E / (1 − ρ) / π = " << truth << " by "
                                << 100 * worst << "% at worst";
    }
}

/// The exact gather of `solver`'s solution at each pixel's point (every reflecting patch
/// through its visible part, near ones element by element; no rays): a smooth reference.
Image exactGather(const Discretization& disc, const RayTracer& tracer,
                  const ProgressiveSolver& solver, const CameraRays& rays) {
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
    return reference;
}

struct CornellView {
    const char* name;
    Camera camera;
};

/// The bundled Cornell box, converged.
struct ConvergedCornell {
    Scene scene = loadScene(std::string(PENUMBRA_SOURCE_DIR) + "/scenes/cornell-box.json");
    Discretization disc{scene};
    RayTracer tracer{disc};
    ProgressiveSolver solver{disc, tracer, SolverOptions{}};

    ConvergedCornell() { solver.converge(1e-3, 1000000); }
};

TEST(HifiFarField, CornellWindowsOfFlatFacesFollowTheExactGather) {
    ConvergedCornell cornell;
    const Discretization& disc = cornell.disc;
    const RayTracer& tracer = cornell.tracer;
    const ProgressiveSolver& solver = cornell.solver;
    // Faces lit mostly by reflected light, where the far field's noise shows most, each filling
    // its view: the back wall above the boxes; the short box's front face (normal
    // (−0.29, 0, 0.96)) above its lower third, where the floor's contact bends the light faster
    // than the quadratics follow; the ceiling beside the lamp.
    const CornellView views[] = {
        {"back-wall", lookingAt({0, 1.15, 0.2}, {0, 1.15, -0.75}, 30)},
        {"short-box", lookingAt({0.005, 0.26, 1.216}, {0.239, 0.26, 0.451}, 18)},
        {"ceiling", lookingAt({-0.35, 0.9, 0.6}, {-0.45, 1.5, 0.1}, 30)},
    };
    const HifiMesh mesh = buildInterpolants(disc, tracer, solver, true);
    for (const CornellView& view : views) {
        const CameraRays rays(view.camera, 64, 64);
        const Image reference = exactGather(disc, tracer, solver, rays);
        const Image image = renderInterpolants(disc, tracer, mesh, rays, 1);
        if (const char* dir = std::getenv("PENUMBRA_TEST_IMAGES")) {
            writeExr(reference, std::string(dir) + "/" + view.name + "-reference.exr");
            writeExr(image, std::string(dir) + "/" + view.name + "-interpolants.exr");
        }
        const WindowErrors w =
            flatWindowErrors(image, reference, flatFaceKeys(disc, tracer, rays), 32, 4);
        RecordProperty(view.name, w.toString());
        ASSERT_GT(w.windows, 10) << view.name << ": " << w.toString();
        EXPECT_LE(w.maxStd, 0.01) << view.name << ": " << w.toString();
    }
}

TEST(HifiFarField, FarFieldFromBaseTrianglesFollowsTheExactGather) {
    ConvergedCornell cornell;
    const Discretization& disc = cornell.disc;
    const RayTracer& tracer = cornell.tracer;
    const ProgressiveSolver& solver = cornell.solver;
    // The floor between the boxes and their shadows: elements split by shadow discontinuities
    // and refined, whose samples off the base triangles take the far field from them.
    const CameraRays rays(lookingAt({0.0, 0.9, 0.9}, {0.0, 0.0, -0.1}, 50), 64, 64);
    const Image reference = exactGather(disc, tracer, solver, rays);
    const std::vector<std::uint64_t> faces = flatFaceKeys(disc, tracer, rays);
    const HifiMesh own = buildInterpolants(disc, tracer, solver, true, false);
    const HifiMesh derived = buildInterpolants(disc, tracer, solver, true, true);
    EXPECT_EQ(own.stats().derivedFarFields, 0);
    EXPECT_GT(derived.stats().derivedFarFields, derived.stats().samples / 10) << derived.toString();
    // The rays the derived samples do not cast go to refining their base samples, within the
    // same budget: fewer in all.
    EXPECT_LT(derived.stats().farRays, own.stats().farRays)
        << "own rays " << own.stats().farRays << ", derived " << derived.stats().farRays;
    // Against the exact gather (no rays): as close as every sample's own rays, and as smooth
    // (the floor's open parts between the boxes are narrow in this view: 16 × 16 windows).
    const Image ownImage = renderInterpolants(disc, tracer, own, rays, 1);
    const Image image = renderInterpolants(disc, tracer, derived, rays, 1);
    const double ownError = relativeRmse(ownImage, reference);
    const double derivedError = relativeRmse(image, reference);
    EXPECT_LE(derivedError, ownError * 1.1 + 0.001)
        << "relative RMSE against the exact gather: own rays " << ownError << ", from the base "
        << derivedError;
    const WindowErrors ownWindows = flatWindowErrors(ownImage, reference, faces, 16, 4);
    const WindowErrors w = flatWindowErrors(image, reference, faces, 16, 4);
    RecordProperty("own", ownWindows.toString());
    RecordProperty("derived", w.toString());
    ASSERT_GT(w.windows, 10) << w.toString();
    EXPECT_LE(w.meanStd, ownWindows.meanStd * 1.1 + 0.0005)
        << "own rays " << ownWindows.toString() << ", from the base " << w.toString();
    EXPECT_LE(w.maxStd, ownWindows.maxStd * 1.1 + 0.001)
        << "own rays " << ownWindows.toString() << ", from the base " << w.toString();
}

}  // namespace
}  // namespace penumbra
