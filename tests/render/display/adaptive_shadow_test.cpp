// Adaptive shadow sampling in the point shader (PointShaderOptions::shadowRefine) and the
// display's converged reference (InteractiveDisplay::renderConvergedReference). Truths: the
// plain estimator bit for bit where the decision rays agree; the analytic penumbra of a square
// occluder parallel to a square lamp (the occluder's shadow on the lamp seen from a floor point
// is a rectangle, its form factor Howell's closed form, written out here); a brute-force
// 16×16-samples-per-pixel render with the plain shader.
//
// Index: scene and closed forms · adaptive shadow sampling · converged reference

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <glm/gtc/constants.hpp>
#include <vector>

#include "render/camera_rays.h"
#include "render/display/interactive_display.h"
#include "render/display/point_shader.h"
#include "solver/discretization.h"
#include "solver/ray_tracer.h"
#include "test_scenes.h"

namespace penumbra {
namespace {

const double kPi = glm::pi<double>();

// ---------------------------------------------------------------------------------------------
// Scene and closed forms

/// Howell's catalogue B-3: differential area parallel to a rectangle a × b at distance c, one
/// corner straight above the point; odd in a and b, so signed rectangles superpose.
double cornerFormFactor(double a, double b, double c) {
    double A = a / c, B = b / c;
    double sa = std::sqrt(1 + A * A), sb = std::sqrt(1 + B * B);
    return (A / sa * std::atan(B / sa) + B / sb * std::atan(A / sb)) / (2 * kPi);
}

/// Form factor from (px, 0, pz), normal +Y, to the rectangle [x0, x1] × [z0, z1] at height c.
double rectangleFormFactor(double px, double pz, double x0, double x1, double z0, double z1,
                           double c) {
    return cornerFormFactor(x1 - px, z1 - pz, c) - cornerFormFactor(x0 - px, z1 - pz, c) -
           cornerFormFactor(x1 - px, z0 - pz, c) + cornerFormFactor(x0 - px, z0 - pz, c);
}

constexpr double kLampHalf = 0.2, kLampHeight = 1.0;
constexpr double kOccluderHalf = 0.2, kOccluderHeight = 0.5, kOccluderX = 0.25;
constexpr double kEmission = 20.0;

/// A 4 m floor (object 0, normal +Y) under a downward-facing 0.4 m square lamp at height 1
/// (object 1) and a 0.4 m square occluder at height 0.5 centred at x = 0.25 (object 2).
Scene penumbraScene() {
    Scene scene = test::emptyScene(0.25, 0.25);
    test::addMaterial(scene, "grey", Rgb(0.5));
    test::addMaterial(scene, "lamp", Rgb(0.0), Rgb(kEmission));
    scene.objects.push_back(test::makeQuad("floor", 4, 4, "grey", {0, 0, 0}));
    scene.objects.push_back(test::makeQuad("lamp", 2 * kLampHalf, 2 * kLampHalf, "lamp",
                                           {0, kLampHeight, 0}, {180, 0, 0}));
    scene.objects.push_back(test::makeQuad("occluder", 2 * kOccluderHalf, 2 * kOccluderHalf, "grey",
                                           {kOccluderX, kOccluderHeight, 0}));
    return scene;
}

/// Exact direct irradiance at floor point (px, 0, pz): the lamp's form factor less that of the
/// part of the lamp the occluder hides, the occluder projected from the point onto the lamp's
/// plane (scale kLampHeight / kOccluderHeight about the point) clipped to the lamp.
double exactIrradiance(double px, double pz) {
    const double k = kLampHeight / kOccluderHeight;
    auto project = [&](double p, double o) { return p + (o - p) * k; };
    const double x0 = std::max(-kLampHalf, project(px, kOccluderX - kOccluderHalf));
    const double x1 = std::min(kLampHalf, project(px, kOccluderX + kOccluderHalf));
    const double z0 = std::max(-kLampHalf, project(pz, -kOccluderHalf));
    const double z1 = std::min(kLampHalf, project(pz, kOccluderHalf));
    const double whole =
        rectangleFormFactor(px, pz, -kLampHalf, kLampHalf, -kLampHalf, kLampHalf, kLampHeight);
    const double hidden =
        x1 > x0 && z1 > z0 ? rectangleFormFactor(px, pz, x0, x1, z0, z1, kLampHeight) : 0.0;
    return kEmission * (whole - hidden);
}

PointShaderOptions shaderOptions(int refine, bool clamp = true) {
    PointShaderOptions o;
    o.seed = 11;
    o.threads = 0;
    o.shadowRefine = refine;
    o.shadowMaxRefinedPerAxis = 16;
    o.shadowDecisionPerAxis = 4;
    o.clampNegative = clamp;
    return o;
}

struct MeanAndVariance {
    double mean = 0, variance = 0;
    double standardError(int n) const { return std::sqrt(variance / n); }
};

MeanAndVariance statistics(const std::vector<double>& v) {
    MeanAndVariance s;
    for (double x : v) s.mean += x / v.size();
    for (double x : v) s.variance += (x - s.mean) * (x - s.mean) / (v.size() - 1);
    return s;
}

// ---------------------------------------------------------------------------------------------
// Adaptive shadow sampling

TEST(PointShader, AdaptiveShadowSamplingEqualsPlainWhereDecisionRaysAgree) {
    const Scene scene = penumbraScene();
    const Discretization disc(scene);
    const RayTracer tracer(disc);
    const PointShader plain(disc, tracer, SolverOptions{}, shaderOptions(0));
    const PointShader adaptive(disc, tracer, SolverOptions{}, shaderOptions(4));
    const Vec3 up(0, 1, 0);
    // Fully lit and fully shadowed (umbra: the projected occluder covers the lamp for px in
    // [0.3, 0.7], |pz| ≤ 0.2) floor points: every decision agrees, so bit for bit the plain
    // estimate.
    for (const Vec3 x : {Vec3(-1.2, 0, 0.3), Vec3(1.5, 0, -0.7), Vec3(0.5, 0, 0.0),
                         Vec3(0.4, 0, 0.1), Vec3(0.62, 0, -0.15)}) {
        for (std::uint64_t key = 0; key < 50; ++key) {
            const Rgb a = adaptive.directIrradiance(x, up, 0, key);
            const Rgb p = plain.directIrradiance(x, up, 0, key);
            ASSERT_TRUE(a == p) << "point (" << x.x << ", " << x.z << ") key " << key
                                << ": adaptive " << a.x << ", plain " << p.x;
        }
    }
    // Whole shading path: a camera over the umbra and the lit floor far away.
    for (double px : {0.45, 1.4}) {
        const Vec3 origin(px, 0.3, 0.05);
        for (int k = 0; k < 20; ++k) {
            ShadeRequest r{glm::dvec2(0.5 + k, 0.5), origin,
                           glm::normalize(Vec3(0.01 * (k - 10), -1, 0.005 * k)), 3};
            const ShadedPoint a = adaptive.shade(r), p = plain.shade(r);
            ASSERT_EQ(a.object, 0) << a.toString();
            ASSERT_TRUE(a.radiance == p.radiance) << a.toString() << " vs " << p.toString();
        }
    }
    // In the penumbra the decision disagrees and the finer set takes over.
    int differ = 0;
    for (std::uint64_t key = 0; key < 50; ++key)
        differ += adaptive.directIrradiance(Vec3(0, 0, 0), up, 0, key) !=
                  plain.directIrradiance(Vec3(0, 0, 0), up, 0, key);
    EXPECT_GT(differ, 40) << "penumbra estimates that used the refined set";
}

TEST(PointShader, AdaptiveShadowSamplingIsUnbiasedAndLessNoisyInAPenumbra) {
    const Scene scene = penumbraScene();
    const Discretization disc(scene);
    const RayTracer tracer(disc);
    const PointShader plain(disc, tracer, SolverOptions{}, shaderOptions(0, false));
    const PointShader adaptive(disc, tracer, SolverOptions{}, shaderOptions(4, false));
    const Vec3 up(0, 1, 0);
    const int n = 600;
    // Points across the penumbra: a quarter of the lamp hidden (one whole column of the 4×4
    // strata), seven eighths, a corner, and a thin 5% strip (the decision then agrees about
    // 40% of the time, so both of the adaptive estimator's branches take part).
    struct Case {
        double px, pz;
    };
    for (const Case c : {Case{0.0, 0.0}, Case{0.25, 0.0}, Case{0.05, 0.3}, Case{-0.08, 0.0}}) {
        const double exact = exactIrradiance(c.px, c.pz);
        std::vector<double> a, p;
        for (int k = 0; k < n; ++k) {
            a.push_back(adaptive.directIrradiance(Vec3(c.px, 0, c.pz), up, 0, 5000 + k).x);
            p.push_back(plain.directIrradiance(Vec3(c.px, 0, c.pz), up, 0, 5000 + k).x);
        }
        const MeanAndVariance sa = statistics(a), sp = statistics(p);
        EXPECT_NEAR(sa.mean, exact, 4 * sa.standardError(n) + 1e-9 * exact)
            << "adaptive at (" << c.px << ", " << c.pz << "): mean " << sa.mean << " ± "
            << sa.standardError(n) << ", exact " << exact;
        EXPECT_NEAR(sp.mean, exact, 4 * sp.standardError(n) + 1e-9 * exact)
            << "plain at (" << c.px << ", " << c.pz << "): mean " << sp.mean << " ± "
            << sp.standardError(n) << ", exact " << exact;
        EXPECT_LT(sa.variance, 0.5 * sp.variance)
            << "at (" << c.px << ", " << c.pz << "): adaptive variance " << sa.variance
            << ", plain " << sp.variance;
        std::printf(
            "penumbra (%.2f, %.2f): exact %.5f, adaptive %.5f ± %.5f (sd %.5f), plain "
            "%.5f ± %.5f (sd %.5f)\n",
            c.px, c.pz, exact, sa.mean, sa.standardError(n), std::sqrt(sa.variance), sp.mean,
            sp.standardError(n), std::sqrt(sp.variance));
    }
}

// ---------------------------------------------------------------------------------------------
// Converged reference

constexpr int kRefSize = 20;

/// A camera under the occluder looking straight down on the floor's umbra and penumbrae.
CameraRays referenceCamera() {
    Camera camera;
    camera.name = "test";
    camera.position = Vec3(0.2, 0.45, 0.05);
    camera.lookAt = Vec3(0.2, 0, 0.05);
    camera.up = Vec3(0, 0, -1);
    camera.fovDeg = 90;
    return CameraRays(camera, kRefSize, kRefSize);
}

TEST(ConvergedReference, AgreesWithBruteForceAndAcrossSeeds) {
    const Scene scene = penumbraScene();
    const Discretization disc(scene);
    const RayTracer tracer(disc);
    InteractiveDisplayOptions options;
    options.width = options.height = kRefSize;
    // The brute force: the plain shader, unclamped (unbiased), 16×16 samples per pixel.
    options.shader.clampNegative = false;
    const InteractiveDisplay display(disc, tracer, SolverOptions{}, options);
    const CameraRays camera = referenceCamera();
    const Image brute = display.renderReference(camera, 16);

    ConvergedReferenceOptions ref;
    ref.useEpiEdges = false;  // no frame rendered: edges from the samples' spread only
    const Image a = display.renderConvergedReference(camera, ref);
    const std::size_t edgePixels = display.lastReferenceEdgePixels();
    ref.seed = 2;
    const Image b = display.renderConvergedReference(camera, ref);
    const Image plain = display.renderReference(camera, 2);

    const double errA = displayRmse(a, brute), errSeeds = displayRmse(a, b);
    const double errPlain = displayRmse(plain, brute);
    std::printf(
        "converged reference: vs brute force %.5f, seeds %.5f, plain 2x2 vs brute %.5f, "
        "%zu edge pixels of %d\n",
        errA, errSeeds, errPlain, edgePixels, kRefSize * kRefSize);
    EXPECT_GT(edgePixels, 20u) << "the penumbrae are edge pixels";
    EXPECT_LT(edgePixels, static_cast<std::size_t>(kRefSize * kRefSize)) << "not every pixel";
    EXPECT_LT(errA, 0.01) << "converged reference vs brute force";
    EXPECT_LT(errSeeds, 0.01) << "two seeds";
    EXPECT_LT(errA, errPlain) << "the converged reference is closer than the plain 2x2 one";
    // The reference has no regular sub-pixel grid and its own seed: it is not the brute force.
    EXPECT_GT(errA, 0.0);
    EXPECT_GT(errSeeds, 0.0);
}

}  // namespace
}  // namespace penumbra
