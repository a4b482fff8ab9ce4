// The point shader (Bala et al. 2003 §3): per-sample direct lighting from area lights with
// stratified shadow rays, the radiosity solution's indirect part, asynchronous workers and the
// light–blocker–receiver triples. Truths: Howell's closed form for a differential area under a
// parallel rectangle (written out here), exact half-occlusion by symmetry, the solver's own
// element irradiance, and synchronous shading of the same requests.
//
// Index: scenes and closed forms · direct lighting · indirect part · determinism · threading

#include "render/display/point_shader.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <glm/gtc/constants.hpp>
#include <map>
#include <sstream>
#include <thread>
#include <vector>

#include "point_shader_test_access.h"
#include "render/camera_rays.h"
#include "solver/discretization.h"
#include "solver/progressive_solver.h"
#include "solver/ray_tracer.h"
#include "test_scenes.h"

namespace penumbra {
namespace {

const double kPi = glm::pi<double>();

std::string str(const Vec3& v) {
    std::ostringstream s;
    s.precision(9);
    s << "(" << v.x << ", " << v.y << ", " << v.z << ")";
    return s.str();
}

// ---------------------------------------------------------------------------------------------
// Scenes and closed forms

/// Howell's catalogue B-3: differential area parallel to a rectangle a × b at distance c, one
/// corner of the rectangle straight above the point. Odd in a and in b, so signed sides
/// superpose.
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

/// A 4 m floor (normal +Y, object 0) under a downward-facing square lamp of side `lampSide`
/// centred at (0, height, 0) (object 1); patch size 0.25 m so the lamp is several patches.
Scene lampOverFloor(double lampSide, double height, Rgb emission) {
    Scene scene = test::emptyScene(0.25, 0.25);
    test::addMaterial(scene, "grey", Rgb(0.5, 0.4, 0.3));
    test::addMaterial(scene, "lamp", Rgb(0.0), emission);
    scene.objects.push_back(test::makeQuad("floor", 4, 4, "grey", {0, 0, 0}));
    scene.objects.push_back(
        test::makeQuad("lamp", lampSide, lampSide, "lamp", {0, height, 0}, {180, 0, 0}));
    return scene;
}

Camera cameraAt(Vec3 position, Vec3 lookAt, double fovDeg = 40) {
    Camera camera;
    camera.name = "test";
    camera.position = position;
    camera.lookAt = lookAt;
    camera.up = Vec3(0, 0, -1);
    camera.fovDeg = fovDeg;
    return camera;
}

PointShaderOptions syncOptions(std::uint64_t seed = 7) {
    PointShaderOptions o;
    o.seed = seed;
    o.threads = 0;
    return o;
}

// ---------------------------------------------------------------------------------------------
// Direct lighting

TEST(PointShader, UnoccludedSquareEmitterMatchesHowellClosedForm) {
    const Rgb emission(10.0, 8.0, 6.0);
    const double side = 1.0, height = 1.0;
    const Scene scene = lampOverFloor(side, height, emission);
    const Discretization disc(scene);
    const RayTracer tracer(disc);
    const PointShader shader(disc, tracer, SolverOptions{}, syncOptions());

    // Many floor points, inside, under the edge of, and far outside the lamp's footprint.
    int checked = 0;
    for (double px = -1.9; px <= 1.9; px += 0.23) {
        for (double pz = -1.9; pz <= 1.9; pz += 0.31) {
            const Vec3 x(px, 0, pz);
            const double f =
                rectangleFormFactor(px, pz, -side / 2, side / 2, -side / 2, side / 2, height);
            const Rgb h = shader.directIrradiance(x, Vec3(0, 1, 0), 0, checked);
            for (int c = 0; c < 3; ++c)
                EXPECT_NEAR(h[c], emission[c] * f, 1e-3 * emission[c] * f)
                    << "floor point " << str(x) << " channel " << c << ": shader " << h[c]
                    << ", Howell " << emission[c] * f;
            ++checked;
        }
    }
    EXPECT_GT(checked, 200);

    // Through the whole shading path: a camera looking down at the floor sees ρ·E·F/π.
    const CameraRays rays(cameraAt(Vec3(0, 0.8, 0), Vec3(0, 0, 0), 90), 16, 16);
    for (int j = 0; j < 16; j += 3) {
        for (int i = 0; i < 16; i += 3) {
            // Off the element grid lines: RayTracer's scenes are not built with
            // RTC_SCENE_FLAG_ROBUST, so rays exactly through shared edges can slip through.
            const glm::dvec2 px(i + 0.37, j + 0.41);
            ShadeRequest r{px, rays.origin(), rays.rayDirection(px.x, px.y), 3};
            const ShadedPoint p = shader.shade(r);
            ASSERT_EQ(p.object, 0) << p.toString();
            EXPECT_NEAR(p.position.y, 0, 1e-5) << p.toString();
            const double f =
                rectangleFormFactor(p.position.x, p.position.z, -0.5, 0.5, -0.5, 0.5, height);
            const Rgb expected = Rgb(0.5, 0.4, 0.3) * emission * f / kPi;
            EXPECT_NEAR(glm::length(p.radiance - expected), 0, 2e-3 * glm::length(expected))
                << p.toString() << " expected " << str(expected);
        }
    }
}

/// A 0.2 m lamp at height 1 over the origin; a large blocker at height 0.5 covering x < 0
/// hides exactly the lamp's x < 0 half from the origin (rays to (x_l, 1) cross y = 0.5 at
/// x_l/2).
Scene halfBlockedScene() {
    Scene scene = lampOverFloor(0.2, 1.0, Rgb(20.0));
    test::addMaterial(scene, "white", Rgb(0.5));
    scene.objects.push_back(test::makeQuad("blocker", 2.0, 3.0, "white", {-1.0, 0.5, 0}));
    return scene;
}

TEST(PointShader, HalfBlockedSmallEmitterGivesHalfAndRecordsTheTriple) {
    const Scene scene = halfBlockedScene();
    const Discretization disc(scene);
    const RayTracer tracer(disc);
    const PointShader shader(disc, tracer, SolverOptions{}, syncOptions());
    const double f = rectangleFormFactor(0, 0, -0.1, 0.1, -0.1, 0.1, 1.0);

    // Each estimate is near half (s × s strata: the shadow boundary crosses one column of s,
    // so at most about half a column, 1/(2s) ≤ 1/6, is misjudged); the mean over many
    // independent patterns is half within 1%.
    const int n = 400;
    double sum = 0;
    for (int k = 0; k < n; ++k) {
        const Rgb h = shader.directIrradiance(Vec3(0), Vec3(0, 1, 0), 0, 1000 + k);
        EXPECT_NEAR(h.x / (20 * f), 0.5, 0.2) << "pattern " << k;
        sum += h.x;
    }
    EXPECT_NEAR(sum / n / (20 * f), 0.5, 0.01) << "mean over " << n << " patterns";

    // A fully unblocked point is exact; a fully blocked one is zero up to the area estimate's
    // stratified noise.
    const Vec3 open(0.6, 0, 0), shut(-0.6, 0, 0);
    EXPECT_NEAR(shader.directIrradiance(open, Vec3(0, 1, 0), 0, 1).x,
                20 * rectangleFormFactor(0.6, 0, -0.1, 0.1, -0.1, 0.1, 1.0), 1e-9);
    const double fShut = rectangleFormFactor(-0.6, 0, -0.1, 0.1, -0.1, 0.1, 1.0);
    EXPECT_NEAR(shader.directIrradiance(shut, Vec3(0, 1, 0), 0, 1).x, 0, 0.02 * 20 * fShut);

    const auto triples = shader.shadowTriples();
    ASSERT_EQ(triples.size(), 1u);
    EXPECT_EQ(triples[0], (ShadowTriple{1, 2, 0})) << triples[0].toString();
}

// ---------------------------------------------------------------------------------------------
// Indirect part

TEST(PointShader, DirectPlusIndirectAtCentroidsReproducesSolverIrradiance) {
    const Scene scene = test::makeLitRoom("red");
    Discretization disc(scene);
    RayTracer tracer(disc);
    SolverOptions options;  // deterministic shots
    ProgressiveSolver solver(disc, tracer, options);
    solver.converge(1e-3, 100000);
    PointShader shader(disc, tracer, options, syncOptions());
    shader.updateSolution(solver);

    // The direct part is a subset of what the solver gathered: same pair-seeded form factors,
    // so H_e − H_direct(e) is never negative (beyond rounding).
    const auto& H = solver.irradiance();
    const auto direct = shader.elementDirect();
    const auto indirect = shader.elementIndirect();
    int lit = 0;
    for (std::size_t e = 0; e < H.size(); ++e) {
        for (int c = 0; c < 3; ++c)
            EXPECT_GE(indirect[e][c], -1e-9 * (1 + H[e][c]))
                << "element " << e << " channel " << c << ": H " << H[e][c] << ", direct "
                << direct[e][c];
        if (luminance(direct[e]) > 0.5 * luminance(H[e])) ++lit;
    }
    EXPECT_GT(lit, 10) << "the lamp lights elements directly";

    // Shading at element centroids: per-sample direct + indirect ≈ H_e. With the element's own
    // indirect value the decomposition is exact up to the direct estimates' shadow noise
    // (checked per element: the solver saw the slab's penumbra through 16 rays per pair); with the
    // per-vertex blend the display uses, the indirect part is smoothed across elements (checked in
    // aggregate: the ceiling just above the lamp, which the lamp hides, is smeared toward its lit
    // neighbours as in the Gouraud display). Errors are relative to max(H_e, mean H / 4) so nearly
    // unlit elements do not dominate.
    double meanH = 0;
    for (const Rgb& h : H) meanH += luminance(h) / H.size();
    std::vector<double> relative;
    double worstExact = 0;
    for (std::size_t e = 0; e < disc.elements().size(); ++e) {
        const Element& el = disc.elements()[e];
        if (disc.elementMaterial(static_cast<int>(e)).isEmitter()) continue;
        const RayHit hit = tracer.intersect(el.centroid + 1e-3 * el.normal, -el.normal);
        ASSERT_EQ(hit.element, static_cast<int>(e)) << el.toString();
        Rgb d(0.0);
        const int patterns = 8;
        for (int k = 0; k < patterns; ++k)
            d += shader.directIrradiance(hit.position, el.normal, el.object, e * 31 + k);
        d /= double(patterns);
        const double scale = std::max(luminance(H[e]), 0.25 * meanH);
        const double exact = std::abs(luminance(d + indirect[e]) - luminance(H[e])) / scale;
        EXPECT_LT(exact, 0.1) << el.toString() << ": direct " << str(d) << " + indirect "
                              << str(indirect[e]) << ", solver " << str(H[e]);
        worstExact = std::max(worstExact, exact);
        const Rgb blended = d + shader.indirectIrradiance(hit.element, hit.weights);
        relative.push_back(std::abs(luminance(blended) - luminance(H[e])) / scale);
    }
    std::sort(relative.begin(), relative.end());
    double mean = 0;
    for (double r : relative) mean += r;
    mean /= relative.size();
    const double p90 = relative[relative.size() * 9 / 10];
    EXPECT_LT(mean, 0.03) << "mean relative error over " << relative.size() << " elements";
    EXPECT_LT(p90, 0.06) << "90th percentile relative error";
    std::printf(
        "centroids: exact decomposition worst %.4f; blended mean %.4f, p90 %.4f, max %.4f\n",
        worstExact, mean, p90, relative.back());
}

TEST(PointShader, IncrementalDirectRefreshEqualsFullRecomputation) {
    // Move the slab of the lit room (remove its version, add a moved one), refresh only what
    // the change can reach, and compare with a from-scratch shader over the edited scene.
    Scene scene = test::makeLitRoom("white");
    Discretization disc(scene);
    RayTracer tracer(disc);
    PointShader shader(disc, tracer, SolverOptions{}, syncOptions());
    const int slab = scene.findObject("slab");
    SceneObject moved = scene.objects[slab];
    moved.transform.translate += Vec3(-0.5, 0.3, 0.2);
    const auto original = shader.elementDirect();
    {
        PointShader::Pause pause(shader);
        disc.setAlive(slab, false);
        tracer.updateAlive(slab);
        const int added = disc.addObject(scene, moved);
        tracer.addObject(added);
        PointShaderTestAccess::refreshDirect(shader, {slab, added});
    }
    const auto incremental = shader.elementDirect();
    const PointShader fresh(disc, tracer, SolverOptions{}, syncOptions());
    const auto full = fresh.elementDirect();
    ASSERT_EQ(incremental.size(), full.size());
    int changed = 0;
    for (std::size_t e = 0; e < full.size(); ++e) {
        EXPECT_EQ(incremental[e], full[e]) << disc.elements()[e].toString();
        if (e < original.size() && disc.elementAlive(static_cast<int>(e)))
            changed += glm::length(full[e] - original[e]) > 1e-6 * glm::length(original[e]);
    }
    EXPECT_GT(changed, 10) << "the slab's shadow moved across the floor";
}

// ---------------------------------------------------------------------------------------------
// Determinism

std::vector<ShadeRequest> gridRequests(const Camera& camera, int w, int h, std::uint64_t frame) {
    const CameraRays rays(camera, w, h);
    std::vector<ShadeRequest> out;
    for (int j = 0; j < h; ++j)
        for (int i = 0; i < w; ++i) {
            glm::dvec2 p(i + 0.25 + 0.5 * ((i * 7 + j * 3) % 5) / 5.0, j + 0.5);
            out.push_back({p, rays.origin(), rays.rayDirection(p.x, p.y), frame});
        }
    return out;
}

TEST(PointShader, FixedSeedIsDeterministicAndSeedsChangeThePenumbra) {
    const Scene scene = halfBlockedScene();
    const Discretization disc(scene);
    const RayTracer tracer(disc);
    const PointShader a(disc, tracer, SolverOptions{}, syncOptions(5));
    const PointShader b(disc, tracer, SolverOptions{}, syncOptions(5));
    const PointShader c(disc, tracer, SolverOptions{}, syncOptions(6));
    int differ = 0;
    for (const ShadeRequest& r :
         gridRequests(cameraAt(Vec3(0, 0.3, 0), Vec3(0, 0, 0), 60), 24, 24, 9)) {
        const ShadedPoint pa = a.shade(r), pb = b.shade(r), pc = c.shade(r);
        EXPECT_EQ(pa.radiance, pb.radiance) << r.toString();
        EXPECT_EQ(pa.position, pb.position) << r.toString();
        if (pa.radiance != pc.radiance) ++differ;
    }
    EXPECT_GT(differ, 0) << "another seed gives another penumbra sample pattern";
}

// ---------------------------------------------------------------------------------------------
// Threading

TEST(PointShader, AsynchronousWorkersEqualSynchronousShading) {
    const Scene scene = test::makeLitRoom("white");
    Discretization disc(scene);
    RayTracer tracer(disc);
    SolverOptions options;
    ProgressiveSolver solver(disc, tracer, options);
    solver.step(20);

    PointShaderOptions asyncOptions = syncOptions(11);
    asyncOptions.threads = 2;
    asyncOptions.batchSize = 16;
    PointShader async(disc, tracer, options, asyncOptions);
    PointShader sync(disc, tracer, options, syncOptions(11));
    async.updateSolution(solver);
    sync.updateSolution(solver);

    const Camera camera = [] {
        Camera c;
        c.position = Vec3(0, 0, 1.4);
        c.lookAt = Vec3(0, -0.5, 0);
        c.fovDeg = 80;
        return c;
    }();
    std::vector<ShadeRequest> requests;
    for (std::uint64_t frame = 0; frame < 3; ++frame) {
        auto part = gridRequests(camera, 32, 24, frame);
        requests.insert(requests.end(), part.begin(), part.end());
    }
    // Submit in pieces, pausing once in the middle, and collect everything.
    const std::size_t half = requests.size() / 2;
    {
        PointShader::Pause pause(async);
        async.submit({requests.begin(), requests.begin() + half});
        std::this_thread::sleep_for(std::chrono::milliseconds(20));
        EXPECT_EQ(async.pendingCount(), half) << "paused workers take nothing";
        EXPECT_TRUE(async.takeResults().empty());
    }
    async.submit({requests.begin() + half, requests.end()});
    async.waitIdle();
    EXPECT_EQ(async.pendingCount(), 0u);
    std::vector<ShadedPoint> results = async.takeResults();
    ASSERT_EQ(results.size(), requests.size());

    auto keyOf = [](const glm::dvec2& p, std::uint64_t frame) {
        return std::tuple(frame, p.y, p.x);
    };
    std::map<std::tuple<std::uint64_t, double, double>, ShadedPoint> byKey;
    for (const ShadedPoint& p : results) byKey[keyOf(p.pixel, p.frame)] = p;
    ASSERT_EQ(byKey.size(), requests.size()) << "every request answered once";
    int hits = 0;
    for (const ShadeRequest& r : requests) {
        const ShadedPoint s = sync.shade(r);
        const ShadedPoint& p = byKey.at(keyOf(r.pixel, r.frame));
        EXPECT_EQ(p.radiance, s.radiance) << p.toString() << " vs " << s.toString();
        EXPECT_EQ(p.position, s.position) << p.toString();
        EXPECT_EQ(p.element, s.element) << p.toString();
        hits += p.hit();
    }
    EXPECT_EQ(hits, static_cast<int>(requests.size())) << "a closed room: every ray hits";

    // Both found the slab's shadow on the floor: (lamp, slab, floor).
    const int floor = scene.findObject("floor"), lamp = scene.findObject("lamp"),
              slab = scene.findObject("slab");
    auto has = [&](const std::vector<ShadowTriple>& ts) {
        return std::find(ts.begin(), ts.end(), ShadowTriple{lamp, slab, floor}) != ts.end();
    };
    const auto asyncTriples = async.shadowTriples();
    EXPECT_TRUE(has(asyncTriples)) << async.toString();
    auto fresh = async.takeNewShadowTriples();
    EXPECT_EQ(fresh.size(), asyncTriples.size()) << "each triple reported as new once";
    EXPECT_TRUE(async.takeNewShadowTriples().empty());
    EXPECT_TRUE(has(sync.shadowTriples())) << sync.toString();
}

TEST(PointShader, CancelPendingDropsQueuedWork) {
    const Scene scene = halfBlockedScene();
    const Discretization disc(scene);
    const RayTracer tracer(disc);
    PointShaderOptions options = syncOptions();
    options.threads = 1;
    PointShader shader(disc, tracer, SolverOptions{}, options);
    const auto requests = gridRequests(cameraAt(Vec3(0, 0.3, 0), Vec3(0, 0, 0), 60), 40, 40, 1);
    {
        PointShader::Pause pause(shader);
        shader.submit(requests);
        EXPECT_EQ(shader.pendingCount(), requests.size());
        shader.cancelPending();
        EXPECT_EQ(shader.pendingCount(), 0u);
    }
    shader.waitIdle();
    EXPECT_TRUE(shader.takeResults().empty());
}

}  // namespace
}  // namespace penumbra
