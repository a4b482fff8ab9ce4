// Ray-traced point-to-patch form factors (formFactorToPatch) against independent truths:
//  - reciprocity A_i F_ij = A_j F_ji, each side an area integral over a fine grid of points of
//    one patch, and the patch-to-patch closed forms of Howell's catalogue (C-11 parallel
//    coaxial rectangles, C-14 perpendicular rectangles sharing an edge);
//  - visibility: a fully blocking occluder (0), a half-blocking one (the closed-form F of the
//    unblocked half), occluders that cannot block (unchanged), `ignoreObject`;
//  - the unoccluded part equals the sum of Lambert form factors of the patch's element polygons;
//  - reproducible sample patterns keyed by (seed, receiverKey, patch).
//
// Index: helpers and closed forms · unoccluded part · reciprocity · visibility · determinism

#include "core/random.h"
#include "solver/form_factor.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <memory>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "solver/discretization.h"
#include "solver/ray_tracer.h"
#include "test_scenes.h"

namespace penumbra {
namespace {

std::string str(const Vec3& v) {
    std::ostringstream s;
    s.precision(9);
    s << "(" << v.x << ", " << v.y << ", " << v.z << ")";
    return s.str();
}

bool sameBits(double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0; }

// ---------------------------------------------------------------------------------------------
// Closed forms

/// Howell B-3: differential area parallel to an a × b rectangle at distance c, its normal
/// through one corner; odd in a and b, so corner terms superpose for any foot point.
double cornerRectangle(double a, double b, double c) {
    double A = a / c, B = b / c;
    double sa = std::sqrt(1 + A * A), sb = std::sqrt(1 + B * B);
    return (A / sa * std::atan(B / sa) + B / sb * std::atan(A / sb)) / (2 * M_PI);
}
double parallelRectangle(double x0, double x1, double y0, double y1, double c) {
    return cornerRectangle(x1, y1, c) - cornerRectangle(x0, y1, c) - cornerRectangle(x1, y0, c) +
           cornerRectangle(x0, y0, c);
}

/// Howell C-11: between identical, parallel, directly opposed a × b rectangles at distance c.
double coaxialRectangles(double a, double b, double c) {
    double X = a / c, Y = b / c;
    double x1 = std::sqrt(1 + X * X), y1 = std::sqrt(1 + Y * Y);
    return 2 / (M_PI * X * Y) *
           (std::log(std::sqrt((1 + X * X) * (1 + Y * Y) / (1 + X * X + Y * Y))) +
            X * y1 * std::atan(X / y1) + Y * x1 * std::atan(Y / x1) - X * std::atan(X) -
            Y * std::atan(Y));
}

/// Howell C-14: from a w × l rectangle to an h × l rectangle at right angles, sharing the
/// edge of length l.
double perpendicularRectangles(double w, double h, double l) {
    double W = w / l, H = h / l, W2 = W * W, H2 = H * H, s = std::sqrt(W2 + H2);
    double logTerm = std::log((1 + W2) * (1 + H2) / (1 + W2 + H2)) +
                     W2 * std::log(W2 * (1 + W2 + H2) / ((1 + W2) * (W2 + H2))) +
                     H2 * std::log(H2 * (1 + H2 + W2) / ((1 + H2) * (H2 + W2)));
    return (W * std::atan(1 / W) + H * std::atan(1 / H) - s * std::atan(1 / s) + 0.25 * logTerm) /
           (M_PI * W);
}

// ---------------------------------------------------------------------------------------------
// Scene helpers

/// Area integral over quad object `from` (one patch, index `fromPatch`) of the point-to-patch
/// form factor to patch `toPatch`: A_from F_from→to, midpoint rule on a grid × grid lattice.
double areaTimesFormFactor(const Discretization& disc, const RayTracer& tracer,
                           const SceneObject& from, int toPatch, int grid) {
    const std::vector<Vec3> c = test::quadCorners(from);
    const Vec3 n = glm::normalize(glm::cross(c[1] - c[0], c[2] - c[1]));
    const Vec3 du = c[1] - c[0], dv = c[3] - c[0];
    const double area = glm::length(glm::cross(du, dv));
    double sum = 0;
    for (int j = 0; j < grid; ++j)
        for (int i = 0; i < grid; ++i) {
            Vec3 x = c[0] + (i + 0.5) / grid * du + (j + 0.5) / grid * dv;
            PointToPatch ff = formFactorToPatch(disc, tracer, x, n, toPatch,
                                                static_cast<std::uint64_t>(j * grid + i), 1, 16);
            sum += ff.visible;
        }
    return sum * area / (grid * grid);
}

/// A sphere "sphere" of material "white".
SceneObject whiteSphere(double radius, int segments, const Vec3& centre) {
    SceneObject sphere;
    sphere.id = "sphere";
    sphere.shape.type = ShapeType::Sphere;
    sphere.shape.radius = radius;
    sphere.shape.segments = segments;
    sphere.material = "white";
    sphere.transform.translate = centre;
    return sphere;
}

/// The patch of object `object`; the scenes here make every object a single patch.
int onlyPatchOf(const Discretization& disc, int object) {
    int found = -1;
    for (int p = 0; p < static_cast<int>(disc.patches().size()); ++p)
        if (disc.patches()[p].object == object) {
            EXPECT_EQ(found, -1) << "object " << object << " has several patches";
            found = p;
        }
    return found;
}

struct PairCase {
    const char* what;
    SceneObject a, b;
    double closedForm = -1;  ///< F_a→b when known in closed form, else < 0
};

void checkReciprocity(const PairCase& pc) {
    Scene scene = test::emptyScene(10.0, 0.25);
    test::addMaterial(scene, "white", Rgb(0.5));
    scene.objects = {pc.a, pc.b};
    Discretization disc(scene);
    RayTracer tracer(disc);
    const int pa = onlyPatchOf(disc, 0), pb = onlyPatchOf(disc, 1);
    const int grid = 80;
    const double aFab = areaTimesFormFactor(disc, tracer, pc.a, pb, grid);
    const double bFba = areaTimesFormFactor(disc, tracer, pc.b, pa, grid);
    const double areaA = disc.patches()[pa].area;
    ASSERT_GT(aFab, 0) << pc.what;
    EXPECT_NEAR(aFab, bFba, 0.02 * std::max(aFab, bFba))
        << pc.what << ": A_a F_ab = " << aFab << " but A_b F_ba = " << bFba;
    ::testing::Test::RecordProperty(std::string("reciprocity_") + pc.what,
                                    std::to_string(aFab / bFba - 1));
    if (pc.closedForm >= 0) {
        EXPECT_NEAR(aFab / areaA, pc.closedForm, 0.01 * pc.closedForm)
            << pc.what << ": F_ab integrated = " << aFab / areaA
            << ", Howell closed form = " << pc.closedForm;
    }
}

// ---------------------------------------------------------------------------------------------
// Unoccluded part

TEST(FormFactor, UnoccludedIsSumOfElementPolygonFormFactors) {
    // The header's contract: the unoccluded value is the exact form factor of the patch's
    // element polygons, i.e. of the surface the patch really covers.
    Scene scene = test::emptyScene(0.5, 0.2);
    test::addMaterial(scene, "white", Rgb(0.5));
    SceneObject quad = test::makeQuad("quad", 1.2, 0.7, "white", {0, 0, 0}, {10, 20, 30});
    SceneObject box;
    box.id = "box";
    box.shape.type = ShapeType::Box;
    box.shape.size = Vec3(0.6, 0.9, 0.4);
    box.material = "white";
    box.transform.translate = Vec3(3, 0, 0);
    SceneObject cyl;
    cyl.id = "cylinder";
    cyl.shape.type = ShapeType::Cylinder;
    cyl.shape.radius = 0.5;
    cyl.shape.height = 0.6;
    cyl.shape.segments = 24;
    cyl.material = "white";
    cyl.transform.translate = Vec3(-3, 0, 0);
    scene.objects = {quad, box, cyl, whiteSphere(0.4, 16, Vec3(0, 0, 3))};
    Discretization disc(scene);
    RayTracer tracer(disc);

    int checked = 0;
    for (int p = 0; p < static_cast<int>(disc.patches().size()); ++p) {
        const Patch& P = disc.patches()[p];
        // Points in front of the patch: near, off to the side, far.
        const Vec3 side = glm::normalize(glm::cross(P.normal, Vec3(0.3, 0.5, 0.7)));
        const Vec3 points[] = {P.centroid + 0.05 * P.normal,
                               P.centroid + 0.3 * P.normal + 0.2 * side,
                               P.centroid + 2.0 * P.normal - 0.5 * side};
        for (const Vec3& x : points) {
            const Vec3 n = glm::normalize(P.centroid - x);
            double expected = 0;
            for (int e : P.elements) expected += polygonFormFactor(x, n, disc.elementPolygon(e));
            const PointToPatch ff = formFactorToPatch(disc, tracer, x, n, p, 3, 1, 16);
            EXPECT_NEAR(ff.unoccluded, expected, 1e-3 * expected + 1e-9)
                << disc.objects()[P.object].id << " patch " << p
                << ": unoccluded = " << ff.unoccluded << ", Σ over its " << P.elements.size()
                << " element polygons = " << expected << " at x = " << str(x) << "; "
                << P.toString();
            ++checked;
        }
    }
    EXPECT_GT(checked, 30);
}

// ---------------------------------------------------------------------------------------------
// Reciprocity

TEST(FormFactor, ReciprocityParallelPatches) {
    // Coaxial unit squares one apart (Howell C-11: 0.1998), then unequal offset ones.
    checkReciprocity({"coaxial unit squares", test::makeQuad("a", 1, 1, "white", {0, 0, 0}),
                      test::makeQuad("b", 1, 1, "white", {0, 1, 0}, {180, 0, 0}),
                      coaxialRectangles(1, 1, 1)});
    checkReciprocity({"offset unequal parallel", test::makeQuad("a", 1, 0.5, "white", {0, 0, 0}),
                      test::makeQuad("b", 0.6, 0.8, "white", {0.4, 0.7, 0.2}, {180, 0, 0})});
}

TEST(FormFactor, ReciprocityPerpendicularPatches) {
    // Floor 1 (x, from the edge) × 1 (z) and a wall 0.8 high sharing the edge x = 0.5
    // (Howell C-14), then a perpendicular pair with a gap and no shared edge.
    checkReciprocity({"perpendicular, shared edge",
                      test::makeQuad("floor", 1, 1, "white", {0, 0, 0}),
                      test::makeQuad("wall", 0.8, 1, "white", {0.5, 0.4, 0}, {0, 0, 90}),
                      perpendicularRectangles(1, 0.8, 1)});
    checkReciprocity({"perpendicular with a gap",
                      test::makeQuad("floor", 1, 0.7, "white", {0, 0, 0}),
                      test::makeQuad("wall", 0.6, 0.5, "white", {0.8, 0.5, 0.3}, {0, 0, 90})});
}

TEST(FormFactor, ReciprocityTiltedPatches) {
    checkReciprocity({"tilted 30 degrees", test::makeQuad("a", 1, 1, "white", {0, 0, 0}),
                      test::makeQuad("b", 0.7, 0.5, "white", {0.3, 0.8, -0.2}, {150, 20, 0})});
    checkReciprocity({"tilted 70 degrees, general",
                      test::makeQuad("a", 0.8, 1.1, "white", {0, 0, 0}, {10, 0, -15}),
                      test::makeQuad("b", 0.9, 0.4, "white", {-0.6, 0.6, 0.3}, {0, 40, -110})});
}

// ---------------------------------------------------------------------------------------------
// Visibility

/// A 1 × 1 emitter facing down at height 0.5 over the receiver point at the origin (normal +Y),
/// one patch, plus the given occluders.
struct OcclusionScene {
    Scene scene;
    std::unique_ptr<Discretization> disc;
    std::unique_ptr<RayTracer> tracer;
    int lampPatch = -1;
    explicit OcclusionScene(const std::vector<SceneObject>& occluders) {
        scene = test::emptyScene(2.0, 0.125);
        test::addMaterial(scene, "lamp", Rgb(0.0), Rgb(1.0));
        test::addMaterial(scene, "black", Rgb(0.0));
        scene.objects.push_back(test::makeQuad("lamp", 1, 1, "lamp", {0, 0.5, 0}, {180, 0, 0}));
        for (const SceneObject& o : occluders) scene.objects.push_back(o);
        disc = std::make_unique<Discretization>(scene);
        tracer = std::make_unique<RayTracer>(*disc);
        lampPatch = onlyPatchOf(*disc, 0);
    }
    PointToPatch at(std::uint64_t key, std::uint64_t seed = 1, int maxRays = 100,
                    int ignore = -1) const {
        return formFactorToPatch(*disc, *tracer, Vec3(0.0), Vec3(0, 1, 0), lampPatch, key, seed,
                                 maxRays, ignore);
    }
};

const double kLampF = parallelRectangle(-0.5, 0.5, -0.5, 0.5, 0.5);  // ≈ 0.554

/// Covers the whole cone from the origin to the lamp (half-width 0.25 at height 0.25).
SceneObject fullBlocker() { return test::makeQuad("blocker", 0.8, 0.8, "black", {0, 0.25, 0}); }
/// Covers exactly the x < 0 half of the lamp as seen from the origin.
SceneObject halfBlocker() { return test::makeQuad("half", 0.4, 0.8, "black", {-0.2, 0.25, 0}); }

TEST(FormFactor, VisibilityRayCountIsBoundedAndMonotone) {
    int previous = 0;
    for (double f = 0; f <= 1.0; f += 1e-3) {
        int n = visibilityRayCount(f, 64);
        EXPECT_GE(n, 1);
        EXPECT_LE(n, 64);
        EXPECT_GE(n, previous) << "ray count decreased at F = " << f;
        previous = n;
    }
    EXPECT_EQ(visibilityRayCount(0.9, 1), 1);
    EXPECT_EQ(visibilityRayCount(0.9, 0), 1);
    EXPECT_EQ(visibilityRayCount(0.0, 64), 1);
    EXPECT_EQ(visibilityRayCount(1e-9, 64), 1) << "a distant pair gets one ray";
    EXPECT_EQ(visibilityRayCount(0.9, 64), 64) << "a close pair gets maxRays";
}

TEST(FormFactor, UnblockedLampMatchesClosedFormAndIsFullyVisible) {
    OcclusionScene s({});
    for (std::uint64_t key = 0; key < 64; ++key) {
        PointToPatch ff = s.at(key);
        ASSERT_NEAR(ff.unoccluded, kLampF, 1e-9 * kLampF)
            << "unoccluded = " << ff.unoccluded << ", Howell B-3 = " << kLampF;
        ASSERT_NEAR(ff.visible, ff.unoccluded, 1e-12)
            << "key " << key << ": nothing blocks, yet visible = " << ff.visible
            << " and unoccluded = " << ff.unoccluded;
    }
}

TEST(FormFactor, OccludersOutsideTheSegmentDoNotBlock) {
    // A quad above the lamp and one below the receiver point: neither crosses a shadow ray.
    OcclusionScene s({test::makeQuad("above", 2, 2, "black", {0, 0.8, 0}),
                      test::makeQuad("below", 2, 2, "black", {0, -0.2, 0})});
    for (std::uint64_t key = 0; key < 16; ++key) {
        PointToPatch ff = s.at(key);
        EXPECT_NEAR(ff.visible, kLampF, 1e-9)
            << "key " << key << ": visible = " << ff.visible << ", closed form = " << kLampF;
    }
}

TEST(FormFactor, FullyBlockedLampIsInvisibleUnlessTheBlockerIsIgnored) {
    OcclusionScene s({fullBlocker()});
    const int blocker = 1, lamp = 0;
    for (std::uint64_t key = 0; key < 16; ++key) {
        PointToPatch ff = s.at(key);
        EXPECT_NEAR(ff.unoccluded, kLampF, 1e-9) << "unoccluded ignores occluders";
        EXPECT_EQ(ff.visible, 0.0) << "key " << key << ": the blocker covers the whole cone, "
                                   << "visible = " << ff.visible;
        EXPECT_GT(ff.rays, 0);
        // ignoreObject makes the blocker transparent: the unoccluded value comes back.
        PointToPatch ignored = s.at(key, 1, 100, blocker);
        EXPECT_NEAR(ignored.visible, kLampF, 1e-9)
            << "key " << key << ": blocker ignored, visible = " << ignored.visible
            << ", closed form = " << kLampF;
        // Ignoring another object (the lamp itself) leaves the blocker in place.
        EXPECT_EQ(s.at(key, 1, 100, lamp).visible, 0.0);
    }
}

TEST(FormFactor, HalfBlockedLampIsHalfVisible) {
    // Truth: by symmetry, and in closed form, the visible half is the x > 0 rectangle.
    const double truth = parallelRectangle(0, 0.5, -0.5, 0.5, 0.5);
    ASSERT_NEAR(truth, 0.5 * kLampF, 1e-12);
    OcclusionScene s({halfBlocker()});
    // visibilityRayCount gives ceil(sqrt(F / 1e-4)) capped by maxRays: 75 rays for F ≈ 0.55.
    // A single estimate with N independent rays has a relative standard deviation of about
    // 1/sqrt(N) ≈ 12%, so check each estimate at 4σ, the mean over 64 independent patterns
    // (σ ≈ 1.4%) at 5%, and that the spread is no worse than independent rays.
    const int keys = 64;
    double sum = 0, sumSq = 0;
    for (std::uint64_t key = 0; key < keys; ++key) {
        PointToPatch ff = s.at(key);
        ASSERT_EQ(ff.rays, visibilityRayCount(ff.unoccluded, 100));
        ASSERT_GE(ff.rays, 64) << "geometry chosen so the pair gets many rays";
        const double ratio = ff.visible / truth;
        const double sigma = 1 / std::sqrt(double(ff.rays));
        EXPECT_NEAR(ratio, 1.0, 4 * sigma)
            << "key " << key << ": visible = " << ff.visible << ", closed-form half = " << truth
            << " (" << ff.rays << " rays)";
        sum += ratio;
        sumSq += (ratio - 1) * (ratio - 1);
    }
    const double mean = sum / keys, rms = std::sqrt(sumSq / keys);
    const int rays = s.at(0).rays;
    EXPECT_NEAR(mean, 1.0, 0.05) << "mean visible / closed-form half over " << keys
                                 << " patterns = " << mean;
    EXPECT_LE(rms, 1.25 / std::sqrt(double(rays)))
        << "rms relative error " << rms << " exceeds that of " << rays << " independent rays";
    ::testing::Test::RecordProperty("mean_ratio", std::to_string(mean));
    ::testing::Test::RecordProperty("rms_relative_error", std::to_string(rms));
}

/// The visible form factor from (x, n) to patch p by quadrature: every element polygon fanned
/// into triangles, each cut into grid² congruent pieces whose centroids carry the point kernel
/// cos·cos/(π r²) times one occlusion ray. Independent of formFactorToPatch's sampling.
double quadratureFormFactor(const Discretization& disc, const RayTracer& tracer, const Vec3& x,
                            const Vec3& n, int p, int grid, bool withVisibility) {
    const double eps = tracer.epsilon();
    double sum = 0;
    for (int e : disc.patches()[p].elements) {
        const std::vector<Vec3> poly = disc.elementPolygon(e);
        const Vec3 ny = disc.elements()[e].normal;
        for (std::size_t t = 1; t + 1 < poly.size(); ++t) {
            const Vec3 a = poly[0], du = (poly[t] - a) / double(grid),
                       dv = (poly[t + 1] - a) / double(grid);
            const double piece = 0.5 * glm::length(glm::cross(du, dv));
            auto add = [&](const Vec3& y) {
                const Vec3 d = y - x;
                const double r2 = glm::dot(d, d);
                const double cx = glm::dot(n, d), cy = -glm::dot(ny, d);
                if (cx <= 0 || cy <= 0) return;
                if (withVisibility && tracer.occluded(x + n * eps, y + ny * eps)) return;
                sum += cx * cy / (M_PI * r2 * r2) * piece;
            };
            for (int i = 0; i < grid; ++i)
                for (int j = 0; i + j < grid; ++j) {
                    const Vec3 c = a + double(i) * du + double(j) * dv;
                    add(c + (du + dv) / 3.0);  // the piece pointing up
                    if (i + j + 2 <= grid) add(c + (2.0 * du + 2.0 * dv) / 3.0);  // and down
                }
        }
    }
    return sum;
}

TEST(FormFactor, CurvedPatchesBehindABlockerMatchQuadrature) {
    // A sphere's patches are curved: no outline, so the estimate samples its element polygons
    // (the general path, not the parallelogram one). Half of the sphere is hidden from the
    // receiver by a blocker whose edge runs under its middle, so patches are fully seen, fully
    // hidden and partly hidden. Per patch the mean over 256 sample patterns must match the
    // quadrature with visibility within 4 standard errors, and the unoccluded part the
    // quadrature without it.
    Scene scene = test::emptyScene(0.3, 0.12);
    test::addMaterial(scene, "white", Rgb(0.5));
    scene.objects = {whiteSphere(0.4, 16, Vec3(0, 1.2, 0)),
                     test::makeQuad("half", 0.6, 1.2, "white", {-0.3, 0.5, 0})};
    Discretization disc(scene);
    RayTracer tracer(disc);
    const Vec3 x(0.0), n(0, 1, 0);
    int partial = 0, checked = 0;
    for (int p = 0; p < static_cast<int>(disc.patches().size()); ++p) {
        const Patch& P = disc.patches()[p];
        if (P.object != 0) continue;
        ASSERT_TRUE(P.outline.empty()) << "sphere patches are curved";
        const double unoccluded = quadratureFormFactor(disc, tracer, x, n, p, 24, false);
        if (unoccluded < 2e-3) continue;
        const double visible = quadratureFormFactor(disc, tracer, x, n, p, 96, true);
        double sum = 0, sumSq = 0;
        const int keys = 256;
        for (int key = 0; key < keys; ++key) {
            const PointToPatch ff = formFactorToPatch(disc, tracer, x, n, p, key, 1, 16);
            ASSERT_NEAR(ff.unoccluded, unoccluded, 2e-3 * unoccluded)
                << "patch " << p << ": exact unoccluded against the quadrature";
            sum += ff.visible;
            sumSq += ff.visible * ff.visible;
        }
        // The mean at 4 standard errors of the patterns' spread.
        const double mean = sum / keys;
        const double error = std::sqrt(std::max(0.0, sumSq / keys - mean * mean) / keys);
        EXPECT_NEAR(mean, visible, 4 * error + 1e-4 * unoccluded)
            << "patch " << p << ": mean estimate " << mean << " ± " << error << ", quadrature "
            << visible << " of unoccluded " << unoccluded;
        partial += visible > 0.1 * unoccluded && visible < 0.9 * unoccluded ? 1 : 0;
        ++checked;
    }
    EXPECT_GE(partial, 2) << "the blocker's edge should cut some patches";
    EXPECT_GE(checked, 6);
}

TEST(FormFactor, HalfBlockedLampIsEvenlySampledAlongBothSides) {
    // The pattern must spread a pair's samples evenly along both sides of a parallelogram
    // lamp, not only along the stratified one: the blocker's edge runs along each side in
    // turn, at the solver's 16 rays per pair and at 32. Independent rays give an rms relative
    // error of 1/sqrt(N) here (half visible); the pattern must do better by half.
    const double truth = 0.5 * kLampF;
    const SceneObject blockers[] = {halfBlocker(),
                                    test::makeQuad("half-z", 0.8, 0.4, "black", {0, 0.25, -0.2})};
    for (const SceneObject& blocker : blockers) {
        OcclusionScene s({blocker});
        for (int maxRays : {16, 32}) {
            const int keys = 128;
            double sum = 0, sumSq = 0;
            for (std::uint64_t key = 0; key < keys; ++key) {
                const PointToPatch ff = s.at(key, 1, maxRays);
                ASSERT_EQ(ff.rays, maxRays);
                const double ratio = ff.visible / truth;
                sum += ratio;
                sumSq += (ratio - 1) * (ratio - 1);
            }
            const double mean = sum / keys, rms = std::sqrt(sumSq / keys);
            EXPECT_NEAR(mean, 1.0, 0.05) << blocker.id << ", " << maxRays << " rays";
            EXPECT_LE(rms, 0.5 / std::sqrt(double(maxRays)))
                << blocker.id << ", " << maxRays << " rays: rms relative error " << rms
                << " against " << 1 / std::sqrt(double(maxRays)) << " for independent rays";
            ::testing::Test::RecordProperty(blocker.id + "_" + std::to_string(maxRays),
                                            std::to_string(rms));
        }
    }
}

TEST(FormFactor, PatchPartlyBelowTheHorizonIsStillSeen) {
    // The receiver is 0.01 under the lamp near its +x edge, its normal tipped 80° toward +x:
    // only the strip x > 0.448 of the lamp is above its horizon, but that strip is close and
    // carries a large form factor. Nothing occludes, so visible must equal unoccluded for every
    // sample pattern.
    OcclusionScene s({});
    const Vec3 x(0.45, 0.49, 0.0);
    const double a = 80 * M_PI / 180;
    const Vec3 n(std::sin(a), std::cos(a), 0);
    int failures = 0;
    for (std::uint64_t key = 0; key < 64; ++key) {
        PointToPatch ff = formFactorToPatch(*s.disc, *s.tracer, x, n, s.lampPatch, key, 1, 16);
        ASSERT_GT(ff.unoccluded, 0.1);
        if (std::abs(ff.visible - ff.unoccluded) > 1e-9 * ff.unoccluded) ++failures;
        EXPECT_NEAR(ff.visible, ff.unoccluded, 1e-9 * ff.unoccluded)
            << "key " << key << ": nothing occludes, yet visible = " << ff.visible
            << " and unoccluded = " << ff.unoccluded << " (" << ff.rays << " rays)";
    }
    ::testing::Test::RecordProperty("patterns_losing_the_patch", std::to_string(failures));
}

// ---------------------------------------------------------------------------------------------
// Change of form factor between two worlds (redistribution)

TEST(FormFactor, ChangeEqualsTheDifferenceOfTheTwoWorldsSampleForSample) {
    // Lamp, a half blocker that stays, and a moved blocker (two versions: before, after)
    // that partly overlaps it. formFactorChange traces only samples meeting the changed
    // versions; it must equal F(after) − F(before) evaluated separately with the same
    // pair-seeded samples, for every pattern and receiver point.
    OcclusionScene s({halfBlocker(), test::makeQuad("old", 0.3, 0.3, "black", {0.05, 0.3, 0.1}),
                      test::makeQuad("new", 0.3, 0.3, "black", {0.1, 0.2, -0.1})});
    const int oldVersion = 2, newVersion = 3;
    std::vector<std::uint8_t> before{1, 1, 1, 0}, after{1, 1, 0, 1};
    Visibility vb, va;
    vb.world = &before;
    va.world = &after;
    RayTracer::SubsetHandle changed(*s.tracer, {oldVersion, newVersion});
    int nonzero = 0;
    for (std::uint64_t key = 0; key < 48; ++key) {
        const Vec3 x(0.02 * double(key % 7) - 0.06, 0.0, 0.015 * double(key % 5) - 0.03);
        const PointToPatch b =
            formFactorToPatch(*s.disc, *s.tracer, x, Vec3(0, 1, 0), s.lampPatch, key, 1, 100, vb);
        const PointToPatch a =
            formFactorToPatch(*s.disc, *s.tracer, x, Vec3(0, 1, 0), s.lampPatch, key, 1, 100, va);
        const PointToPatch d = formFactorChange(*s.disc, *s.tracer, x, Vec3(0, 1, 0), s.lampPatch,
                                                key, 1, 100, vb, va, changed.visibility());
        ASSERT_EQ(d.unoccluded, a.unoccluded);
        EXPECT_NEAR(d.visible, a.visible - b.visible, 1e-12)
            << "key " << key << ": change " << d.visible << ", F(after) " << a.visible
            << " − F(before) " << b.visible;
        // One ray per sample against the changed objects, two more for those meeting one.
        EXPECT_GE(d.rays, a.rays);
        EXPECT_LE(d.rays, 3 * a.rays);
        EXPECT_EQ((d.rays - a.rays) % 2, 0);
        if (a.visible != b.visible) ++nonzero;
    }
    EXPECT_GT(nonzero, 24) << "the moved blocker changes most of these pairs";
}

TEST(FormFactor, ChangeWithTheChangedObjectsInOneWorldTracesOnlyTheOther) {
    // An addition (every changed object after the edit, none before) and a removal (the
    // reverse): a sample meeting a changed object is blocked in the world holding it, so only
    // the other world is traced. The change must equal the evaluation that traces both worlds
    // bit for bit, and F(after) − F(before) evaluated separately, with one ray fewer per
    // sample that meets the changed object.
    OcclusionScene s({halfBlocker(), test::makeQuad("box", 0.3, 0.3, "black", {0.1, 0.2, -0.1})});
    const std::vector<std::uint8_t> without{1, 1, 0}, with{1, 1, 1};
    RayTracer::SubsetHandle changed(*s.tracer, {2});
    int meeting = 0;
    for (const bool added : {true, false}) {
        Visibility vb, va;
        vb.world = added ? &without : &with;
        va.world = added ? &with : &without;
        const ChangedObjectsIn where = added ? ChangedObjectsIn::After : ChangedObjectsIn::Before;
        for (std::uint64_t key = 0; key < 48; ++key) {
            const Vec3 x(0.02 * double(key % 7) - 0.06, 0.0, 0.015 * double(key % 5) - 0.03);
            const Vec3 n(0, 1, 0);
            const PointToPatch b =
                formFactorToPatch(*s.disc, *s.tracer, x, n, s.lampPatch, key, 1, 100, vb);
            const PointToPatch a =
                formFactorToPatch(*s.disc, *s.tracer, x, n, s.lampPatch, key, 1, 100, va);
            const PointToPatch both = formFactorChange(*s.disc, *s.tracer, x, n, s.lampPatch, key,
                                                       1, 100, vb, va, changed.visibility());
            const PointToPatch one = formFactorChange(*s.disc, *s.tracer, x, n, s.lampPatch, key, 1,
                                                      100, vb, va, changed.visibility(), where);
            EXPECT_TRUE(sameBits(one.visible, both.visible))
                << (added ? "addition" : "removal") << ", key " << key << ": one world "
                << one.visible << ", both worlds " << both.visible;
            EXPECT_NEAR(one.visible, a.visible - b.visible, 1e-12)
                << "key " << key << ": F(after) " << a.visible << " − F(before) " << b.visible;
            // Both: 1 + 2 rays per meeting sample; one world: 1 + 1.
            const int met = (both.rays - a.rays) / 2;
            EXPECT_EQ(one.rays, a.rays + met) << "key " << key;
            meeting += met > 0 ? 1 : 0;
        }
    }
    EXPECT_GT(meeting, 48) << "the box should meet samples of most pairs";
}

TEST(FormFactor, ChangeOutsideTheConeCostsOneCheapRayPerSampleAndIsZero) {
    OcclusionScene s({halfBlocker(), test::makeQuad("far", 0.3, 0.3, "black", {3, 0.3, 3})});
    std::vector<std::uint8_t> before{1, 1, 0}, after{1, 1, 1};
    Visibility vb, va;
    vb.world = &before;
    va.world = &after;
    RayTracer::SubsetHandle changed(*s.tracer, {2});
    for (std::uint64_t key = 0; key < 16; ++key) {
        const PointToPatch d =
            formFactorChange(*s.disc, *s.tracer, Vec3(0.0), Vec3(0, 1, 0), s.lampPatch, key, 1, 100,
                             vb, va, changed.visibility());
        EXPECT_EQ(d.visible, 0.0);
        EXPECT_EQ(d.rays, visibilityRayCount(d.unoccluded, 100));
    }
}

// ---------------------------------------------------------------------------------------------
// Determinism

TEST(FormFactor, SamplePatternIsKeyedBySeedAndReceiver) {
    OcclusionScene s({halfBlocker()});
    std::set<double> bySeed, byKey;
    for (std::uint64_t seed = 1; seed <= 16; ++seed) {
        PointToPatch a = s.at(42, seed), b = s.at(42, seed);
        EXPECT_TRUE(sameBits(a.visible, b.visible) && sameBits(a.unoccluded, b.unoccluded) &&
                    a.rays == b.rays)
            << "seed " << seed << ": " << a.visible << " then " << b.visible;
        bySeed.insert(a.visible);
        byKey.insert(s.at(seed, 7).visible);
    }
    // A partly occluded pair: different patterns give different visible estimates.
    EXPECT_GE(bySeed.size(), 12u) << "only " << bySeed.size()
                                  << " distinct estimates from 16 seeds";
    EXPECT_GE(byKey.size(), 12u) << "only " << byKey.size() << " distinct estimates from 16 keys";
    // Evaluation order does not matter: another pair in between leaves the pattern unchanged.
    PointToPatch first = s.at(5, 3);
    s.at(6, 9);
    formFactorToPatch(*s.disc, *s.tracer, Vec3(0.1, 0, 0.1), Vec3(0, 1, 0), s.lampPatch, 5, 3, 100);
    EXPECT_TRUE(sameBits(first.visible, s.at(5, 3).visible));
}

}  // namespace
}  // namespace penumbra

namespace penumbra {
namespace {

/// The lit test room with a half-metre box blocker (the last object) below its centre.
Scene litRoomWithABlocker() {
    Scene scene = test::makeLitRoom("white");
    SceneObject box;
    box.id = "blocker";
    box.shape.type = ShapeType::Box;
    box.shape.size = Vec3(0.5);
    box.material = "white";
    box.transform.translate = Vec3(0.0, -0.3, 0.0);
    scene.objects.push_back(box);
    return scene;
}

TEST(RayTracerPackets, PacketsAnswerAsSingleRays) {
    // A packet of segments from one point (the solver's visibility samples of one pair) is
    // blocked exactly where the single-ray query says so, in the current scene and with an
    // object ignored.
    Scene scene = litRoomWithABlocker();
    Discretization disc(scene);
    RayTracer tracer(disc);
    const auto& el = disc.elements();
    int blockedCount = 0, total = 0;
    for (int trial = 0; trial < 256; ++trial) {
        const Element& a = el[hashPair(7, trial) % el.size()];
        const Vec3 from = a.centroid + a.normal * 1e-4;
        Vec3 to[16];
        const int count = 1 + static_cast<int>(hashPair(8, trial) % 16);  // packets of 4, 8, 16
        for (int i = 0; i < count; ++i) {
            const Element& b = el[hashPair(trial, i) % el.size()];
            to[i] = b.centroid + b.normal * 1e-4;
        }
        for (const Visibility& v :
             {Visibility{}, Visibility{static_cast<int>(scene.objects.size()) - 1}}) {
            bool blocked[16];
            tracer.occludedPacket(from, to, count, blocked, v);
            for (int i = 0; i < count; ++i) {
                EXPECT_EQ(blocked[i], tracer.occluded(from, to[i], v))
                    << "trial " << trial << " ray " << i;
                blockedCount += blocked[i] ? 1 : 0;
                ++total;
            }
        }
    }
    // Both answers occur, so the comparison means something.
    EXPECT_GT(blockedCount, total / 10);
    EXPECT_LT(blockedCount, total - total / 10);
}

TEST(RayTracerPackets, FirstHitsAnswerAsSingleFirstHits) {
    // The grouped closest-hit query of the stochastic batches gives, ray for ray, what
    // firstHit gives: element, patch, area, side and distance, misses and back faces
    // included, in the current scene and with an object ignored.
    Scene scene = litRoomWithABlocker();
    Discretization disc(scene);
    RayTracer tracer(disc);
    const auto& el = disc.elements();
    std::vector<Vec3> origins, dirs;
    for (int i = 0; i < 301; ++i) {  // not a multiple of any group size
        const Element& a = el[hashPair(11, i) % el.size()];
        // Every third ray starts far outside, so some escape and some meet backs.
        const double far = i % 3 == 0 ? 10.0 : 1e-4;
        origins.push_back(a.centroid + a.normal * far);
        Vec3 d(std::sin(0.37 * i) + 0.1, std::cos(1.3 * i), std::sin(2.1 * i + 0.5));
        dirs.push_back(glm::normalize(d));
    }
    int misses = 0, backs = 0;
    for (const Visibility& v :
         {Visibility{}, Visibility{static_cast<int>(scene.objects.size()) - 1}}) {
        std::vector<RayTracer::FirstHit> grouped(origins.size());
        tracer.firstHits(origins.data(), dirs.data(), static_cast<int>(origins.size()),
                         grouped.data(), v);
        for (std::size_t i = 0; i < origins.size(); ++i) {
            const RayTracer::FirstHit one = tracer.firstHit(origins[i], dirs[i], v);
            EXPECT_EQ(grouped[i].element, one.element) << "ray " << i;
            EXPECT_EQ(grouped[i].patch, one.patch) << "ray " << i;
            EXPECT_EQ(grouped[i].backFace, one.backFace) << "ray " << i;
            EXPECT_EQ(grouped[i].t, one.t) << "ray " << i;
            EXPECT_EQ(grouped[i].area, one.area) << "ray " << i;
            misses += one.element < 0 ? 1 : 0;
            backs += one.element >= 0 && one.backFace ? 1 : 0;
        }
    }
    EXPECT_GT(misses, 0);
    EXPECT_GT(backs, 0);
}

// ---------------------------------------------------------------------------------------------
// Batched receivers: the same numbers as one pair at a time

/// Uniform numbers in [0, 1) from a counter (SplitMix64), for reproducible random cases.
struct Uniform {
    std::uint64_t state;
    double operator()() { return static_cast<double>(splitmix64(state++) >> 11) * 0x1.0p-53; }
};

TEST(FormFactorBatch, ContourLanesEqualTheContourSumPointByPoint) {
    // Random convex polygons of 3 to 20 vertices (beyond the scalar sum's 16-edge chunks),
    // seen from random points with random normals: each lane's sum has the scalar sum's bits.
    Uniform u{11};
    int checked = 0;
    for (int trial = 0; trial < 200; ++trial) {
        const std::size_t m = 3 + static_cast<std::size_t>(u() * 18);
        std::vector<Vec3> poly(m);
        const Vec3 c(u() * 4 - 2, u() * 4 - 2, u() * 4 - 2);
        const double r = 0.1 + u() * 2;
        for (std::size_t k = 0; k < m; ++k) {
            const double a = 2 * M_PI * static_cast<double>(k) / static_cast<double>(m);
            poly[k] = c + Vec3(r * std::cos(a), 0.3 * u(), r * std::sin(a));
        }
        Vec3 xs[kContourLanes], ns[kContourLanes];
        for (int l = 0; l < kContourLanes; ++l) {
            xs[l] = Vec3(u() * 6 - 3, u() * 6 - 3, u() * 6 - 3);
            ns[l] = glm::normalize(Vec3(u() - 0.5, u() - 0.5, u() - 0.5));
        }
        if (trial % 10 == 0) xs[1] = poly[0];  // an edge through the point adds nothing
        double sums[kContourLanes];
        integrateContourLanes(xs, ns, poly.data(), m, sums);
        for (int l = 0; l < kContourLanes; ++l) {
            const double one = integrateContour(xs[l], ns[l], poly.data(), m);
            EXPECT_TRUE(sameBits(sums[l], one))
                << "trial " << trial << ", lane " << l << ", " << m << " vertices: " << sums[l]
                << " in lanes, " << one << " alone";
            ++checked;
        }
    }
    EXPECT_EQ(checked, 200 * kContourLanes);
}

TEST(FormFactorBatch, ReceiversTogetherEqualEachPairAlone) {
    // Every patch of a room with a blocking box and a sphere (planar outlines and curved
    // patches), from every element centre and from random points with random normals: in
    // front, behind, with the horizon cutting the patch, in batches of every length up to 9
    // (the lanes' padding): the same unoccluded and visible form factors bit for bit, and
    // the same rays.
    Scene scene = litRoomWithABlocker();
    scene.objects.push_back(whiteSphere(0.2, 12, Vec3(0.5, 0.3, -0.4)));
    Discretization disc(scene);
    RayTracer tracer(disc);
    std::vector<Receiver> receivers;
    for (std::size_t e = 0; e < disc.elements().size(); ++e) {
        const Element& el = disc.elements()[e];
        receivers.push_back({el.centroid, el.normal, e});
    }
    Uniform u{5};
    for (int k = 0; k < 300; ++k)
        receivers.push_back({Vec3(u() * 1.4 - 0.7, u() * 1.4 - 0.7, u() * 1.4 - 0.7),
                             glm::normalize(Vec3(u() - 0.5, u() - 0.5, u() - 0.5)),
                             1000000u + static_cast<std::uint64_t>(k)});
    int planar = 0, curved = 0, whole = 0, clipped = 0, behind = 0, occluded = 0;
    std::vector<PointToPatch> together(receivers.size());
    for (int p = 0; p < static_cast<int>(disc.patches().size()); ++p) {
        const Patch& P = disc.patches()[p];
        (P.outline.empty() ? curved : planar) += 1;
        const int batch = 1 + p % 9;
        for (std::size_t i = 0; i < receivers.size(); i += batch) {
            const int m = static_cast<int>(std::min<std::size_t>(batch, receivers.size() - i));
            formFactorsToPatch(disc, tracer, p, &receivers[i], m, 7, 16, {}, &together[i]);
        }
        for (std::size_t i = 0; i < receivers.size(); ++i) {
            const Receiver& r = receivers[i];
            const PointToPatch alone = formFactorToPatch(disc, tracer, r.x, r.n, p, r.key, 7, 16);
            const PointToPatch& t = together[i];
            ASSERT_TRUE(sameBits(t.unoccluded, alone.unoccluded) &&
                        sameBits(t.visible, alone.visible) && t.rays == alone.rays)
                << "patch " << p << ", receiver " << i << " at " << str(r.x) << ": together ("
                << t.unoccluded << ", " << t.visible << ", " << t.rays << " rays), alone ("
                << alone.unoccluded << ", " << alone.visible << ", " << alone.rays << " rays)";
            if (P.outline.empty()) continue;
            if (!(alone.unoccluded > 0)) {
                ++behind;
                continue;
            }
            bool below = false;
            for (const Vec3& v : P.outline) below = below || glm::dot(v - r.x, r.n) < 0;
            (below ? clipped : whole) += 1;
            if (alone.visible < alone.unoccluded) ++occluded;
        }
    }
    // The cases the batch treats apart all occur.
    EXPECT_GT(planar, 0);
    EXPECT_GT(curved, 0);
    EXPECT_GT(whole, 100);
    EXPECT_GT(clipped, 100);
    EXPECT_GT(behind, 100);
    EXPECT_GT(occluded, 10);
}

}  // namespace
}  // namespace penumbra
