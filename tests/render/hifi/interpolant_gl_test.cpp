// The interpolants' offscreen GL passes against the Embree pass: the same triangle and the
// same barycentric coordinates at every pixel both see inside a triangle, so the same image,
// on an OSMesa context and on an EGL context, with no DISPLAY.

#include "render/hifi/interpolant_gl.h"

#include <gtest/gtest.h>

#include <cstdlib>

#include "render/camera_rays.h"
#include "render/gl/offscreen_context.h"
#include "render/hifi/exact_irradiance.h"
#include "render/hifi/hifi_mesh.h"
#include "render/path_tracer.h"
#include "solver/discretization.h"
#include "solver/progressive_solver.h"
#include "solver/ray_tracer.h"
#include "test_scenes.h"

namespace penumbra {
namespace {

struct LitCardScene {
    Scene scene;
    std::unique_ptr<Discretization> disc;
    std::unique_ptr<RayTracer> tracer;
    HifiMesh mesh;
    LitCardScene() {
        test::addMaterial(scene, "lamp", Rgb(0.0), Rgb(10.0));
        test::addMaterial(scene, "grey", Rgb(0.5));
        test::addMaterial(scene, "red", Rgb(0.6, 0.1, 0.1));
        scene.objects.push_back(test::makeQuad("floor", 2, 2, "grey", {0, 0, 0}));
        scene.objects.push_back(test::makeQuad("lamp", 0.4, 0.4, "lamp", {0, 1, 0}, {180, 0, 0}));
        scene.objects.push_back(
            test::makeQuad("card", 0.6, 0.6, "red", {0.45, 0.5, 0.1}, {180, 0, 0}));
        scene.settings.patchSize = 0.5;
        scene.settings.elementSize = 0.25;
        disc = std::make_unique<Discretization>(scene);
        tracer = std::make_unique<RayTracer>(*disc);
        ProgressiveSolver solver(*disc, *tracer, SolverOptions{});
        solver.converge(1e-4, 100000);
        ExactIrradiance exact(*disc);
        exact.setReflected(reflectedRadiosity(*disc, solver));
        mesh.build(*disc, exact);
    }
};

void expectSameAsEmbree(OffscreenContext::Backend backend) {
    ::unsetenv("DISPLAY");
    static LitCardScene s;
    OffscreenContext context(backend);
    EXPECT_FALSE(context.renderer().empty());
    InterpolantGlRenderer renderer;
    renderer.upload(s.mesh);
    Camera camera;
    camera.position = Vec3(0.3, 1.4, 1.6);
    camera.lookAt = Vec3(0, 0.1, 0);
    camera.fovDeg = 50;
    const CameraRays rays(camera, 64, 48);
    const Image gl = renderer.render(*s.disc, s.mesh, rays, 1);
    const Image embree = renderInterpolants(*s.disc, *s.tracer, s.mesh, rays, 1);
    // Pixel by pixel where the Embree pass finds the same triangle strictly inside.
    int compared = 0, agreeing = 0;
    for (int y = 0; y < rays.height(); ++y)
        for (int x = 0; x < rays.width(); ++x) {
            const Vec3 dir = rays.rayDirection(x + 0.5, y + 0.5);
            const RayTracer::FirstHit hit = s.tracer->firstHit(rays.origin(), dir);
            if (hit.element < 0 || hit.backFace) {
                EXPECT_EQ(renderer.ids()[y * rays.width() + x], 0u) << x << ", " << y;
                continue;
            }
            double sb = 0, tb = 0;
            const int tri = s.mesh.locate(hit.element, rays.origin() + double(hit.t) * dir, sb, tb);
            if (sb < 1e-3 || tb < 1e-3 || sb + tb > 1 - 1e-3) continue;  // near an edge
            ++compared;
            const std::size_t i = static_cast<std::size_t>(y) * rays.width() + x;
            if (renderer.ids()[i] != static_cast<std::uint32_t>(tri + 1)) continue;
            ++agreeing;
            EXPECT_NEAR(renderer.barycentrics()[2 * i], sb, 2e-4);
            EXPECT_NEAR(renderer.barycentrics()[2 * i + 1], tb, 2e-4);
            EXPECT_NEAR(gl.at(x, y).x, embree.at(x, y).x, 1e-3 * embree.at(x, y).x + 1e-9);
        }
    EXPECT_GT(compared, 1000);
    EXPECT_GE(agreeing, compared * 99 / 100);
    EXPECT_LT(relativeRmse(gl, embree), 0.02);
}

TEST(InterpolantGl, OsMesaPassMatchesTheEmbreePass) {
    expectSameAsEmbree(OffscreenContext::Backend::OsMesa);
}

TEST(InterpolantGl, EglPassMatchesTheEmbreePass) {
    expectSameAsEmbree(OffscreenContext::Backend::Egl);
}

}  // namespace
}  // namespace penumbra
