// The high-fidelity mesh: the quadratic interpolant reproduces every quadratic exactly (§2.2),
// the constrained Delaunay triangulation keeps every constraint segment as a union of its
// edges, the shadow events of a blocker under a square lamp cut the receiver where the
// penumbra's closed-form boundary lies, a box resting on a floor leaves its outline as contact
// lines, and the interpolants of a blocker over a plane are closer to the exact irradiance
// than the solution's constant elements.

#include "render/hifi/hifi_mesh.h"

#include <gtest/gtest.h>
#include <tbb/global_control.h>

#include <atomic>
#include <cmath>
#include <random>

#include "edit/edit_session.h"
#include "render/camera_rays.h"
#include "render/hifi/cdt.h"
#include "render/hifi/exact_irradiance.h"
#include "solver/discretization.h"
#include "solver/progressive_solver.h"
#include "solver/ray_tracer.h"
#include "test_scenes.h"

namespace penumbra {
namespace {

TEST(QuadraticInterpolant, ReproducesAnyQuadraticExactly) {
    std::mt19937 rng(5);
    std::uniform_real_distribution<double> u(-3, 3);
    for (int trial = 0; trial < 20; ++trial) {
        double k[6];
        for (double& c : k) c = u(rng);
        auto f = [&](double s, double t) {
            return k[0] * s * s + k[1] * s * t + k[2] * s + k[3] * t * t + k[4] * t + k[5];
        };
        const double at[6][2] = {{0, 0}, {0.5, 0}, {1, 0}, {0.5, 0.5}, {0, 1}, {0, 0.5}};
        std::array<Rgb, 6> r;
        for (int i = 0; i < 6; ++i) r[i] = Rgb(f(at[i][0], at[i][1]), 2 * f(at[i][0], at[i][1]), 0);
        const QuadraticInterpolant q = QuadraticInterpolant::fromSamples(r);
        for (int i = 0; i <= 10; ++i)
            for (int j = 0; j + i <= 10; ++j) {
                const double s = i / 10.0, t = j / 10.0;
                EXPECT_NEAR(q(s, t).x, f(s, t), 1e-12);
                EXPECT_NEAR(q(s, t).y, 2 * f(s, t), 1e-12);
            }
    }
}

TEST(QuadraticInterpolant, IrradianceIsTheQuadraticClampedAtZero) {
    // Bright corners, dark midpoints: the quadratic through them dips below 0 inside.
    const std::array<Rgb, 6> r = {Rgb(1.0), Rgb(0.0), Rgb(1.0), Rgb(0.0), Rgb(1.0), Rgb(0.0)};
    const QuadraticInterpolant q = QuadraticInterpolant::fromSamples(r);
    int negative = 0;
    for (int i = 0; i <= 20; ++i)
        for (int j = 0; j + i <= 20; ++j) {
            const double s = i / 20.0, t = j / 20.0;
            const double raw = q(s, t).x;
            if (raw < 0) ++negative;
            EXPECT_EQ(q.irradiance(s, t).x, std::max(raw, 0.0)) << s << ", " << t;
        }
    EXPECT_GT(negative, 0) << "the samples were meant to make the quadratic dip below 0";
}

/// Whether segment a–b is covered by triangle edges of `tri` lying on it.
bool coveredByEdges(const Triangulation2& tri, glm::dvec2 a, glm::dvec2 b) {
    const glm::dvec2 d = b - a;
    const double len2 = glm::dot(d, d);
    std::vector<std::pair<double, double>> spans;
    for (const auto& t : tri.triangles)
        for (int k = 0; k < 3; ++k) {
            const glm::dvec2 p = tri.points[t[k]], q = tri.points[t[(k + 1) % 3]];
            auto off = [&](glm::dvec2 x) {
                return std::abs(d.x * (x.y - a.y) - d.y * (x.x - a.x)) / std::sqrt(len2);
            };
            if (off(p) > 1e-9 || off(q) > 1e-9) continue;
            double sp = glm::dot(p - a, d) / len2, sq = glm::dot(q - a, d) / len2;
            if (sp > sq) std::swap(sp, sq);
            spans.emplace_back(sp, sq);
        }
    std::sort(spans.begin(), spans.end());
    double reached = 0;
    for (auto [s0, s1] : spans)
        if (s0 <= reached + 1e-9) reached = std::max(reached, s1);
    return reached >= 1 - 1e-9;
}

TEST(ConstrainedTriangulation, EveryConstraintSegmentIsAUnionOfEdges) {
    const std::vector<glm::dvec2> square = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};
    std::vector<std::pair<glm::dvec2, glm::dvec2>> segs = {{{0.1, 0.2}, {0.9, 0.7}},
                                                           {{0.2, 0.9}, {0.8, 0.1}},
                                                           {{0.0, 0.5}, {1.0, 0.5}},
                                                           {{0.3, 0.3}, {0.35, 0.31}}};
    const Triangulation2 tri = triangulateConstrained(square, segs);
    for (const auto& [a, b] : segs) EXPECT_TRUE(coveredByEdges(tri, a, b));
    for (std::size_t i = 0; i < square.size(); ++i)
        EXPECT_TRUE(coveredByEdges(tri, square[i], square[(i + 1) % square.size()]));
    // The triangles tile the square.
    double area = 0;
    for (const auto& t : tri.triangles) {
        const glm::dvec2 p = tri.points[t[0]], q = tri.points[t[1]], r = tri.points[t[2]];
        area += 0.5 * std::abs((q.x - p.x) * (r.y - p.y) - (q.y - p.y) * (r.x - p.x));
    }
    EXPECT_NEAR(area, 1.0, 1e-12);
}

/// A 1 m lamp 1 m above a grey 2 m floor, a black card at 0.5 m over part of it.
struct CardScene {
    Scene scene;
    std::unique_ptr<Discretization> disc;
    std::unique_ptr<RayTracer> tracer;
    CardScene(double elementSize, bool withCard = true) {
        test::addMaterial(scene, "lamp", Rgb(0.0), Rgb(10.0));
        test::addMaterial(scene, "grey", Rgb(0.5));
        test::addMaterial(scene, "black", Rgb(0.0));
        scene.objects.push_back(test::makeQuad("floor", 2, 2, "grey", {0, 0, 0}));
        scene.objects.push_back(test::makeQuad("lamp", 0.4, 0.4, "lamp", {0, 1, 0}, {180, 0, 0}));
        if (withCard)
            scene.objects.push_back(
                test::makeQuad("card", 0.6, 0.6, "black", {0.45, 0.5, 0.1}, {180, 0, 0}));
        scene.settings.patchSize = 0.5;
        scene.settings.elementSize = elementSize;
        disc = std::make_unique<Discretization>(scene);
        tracer = std::make_unique<RayTracer>(*disc);
    }
};

/// The exact irradiance (no far field's rays) of `disc`'s solution converged to 1e-4: what most
/// of these tests build the interpolants from.
ExactIrradiance solvedExact(Discretization& disc, RayTracer& tracer) {
    ProgressiveSolver solver(disc, tracer, SolverOptions{});
    solver.converge(1e-4, 100000);
    ExactIrradiance exact(disc);
    exact.setReflected(reflectedRadiosity(disc, solver));
    return exact;
}

TEST(HifiMesh, ShadowEventsLieOnTheCardsPenumbraBoundaries) {
    // The card's edge x = 0.15 at height 0.5 with lamp edges x = ±0.2 at height 1: its VE/EV
    // events meet the floor at x = 0.15 + (0.15 ∓ 0.2) · 0.5 / 0.5, i.e. x = 0.1 and x = 0.35.
    CardScene s(0.25);
    int onBoundary = 0, total = 0;
    for (std::size_t e = 0; e < s.disc->elements().size(); ++e) {
        if (s.disc->elements()[e].object != 0) continue;
        for (const Discontinuity& d : shadowDiscontinuities(*s.disc, static_cast<int>(e))) {
            ++total;
            EXPECT_GT(d.weight, 0);
            const bool alongX = std::abs(d.a.x - d.b.x) < 1e-9;
            if (alongX && (std::abs(d.a.x - 0.1) < 1e-9 || std::abs(d.a.x - 0.35) < 1e-9))
                ++onBoundary;
            EXPECT_NEAR(d.a.y, 0.0, 1e-12);
        }
    }
    EXPECT_GT(total, 0);
    EXPECT_GT(onBoundary, 0);
}

TEST(HifiMesh, TheWedgeIndexFindsWhatTestingEveryWedgeFinds) {
    // The card scene with a tessellated sphere and a turned box among the blockers and a wall
    // beside them: on every element, the wedges found through the bounding-volume hierarchy
    // cut the same segments, with the same weights and in the same order, as every wedge
    // tested in turn.
    Scene scene;
    scene.materials = {{"grey", {}}, {"lamp", {}}, {"black", {}}};
    scene.materials[0].material.reflectance = Rgb(0.5);
    scene.materials[1].material.emission = Rgb(10.0);
    scene.objects.push_back(test::makeQuad("floor", 2, 2, "grey", {0, 0, 0}));
    scene.objects.push_back(test::makeQuad("wall", 2, 1, "grey", {0, 0.5, -1}, {90, 0, 0}));
    scene.objects.push_back(test::makeQuad("lamp", 0.4, 0.4, "lamp", {0, 1, 0}, {180, 0, 0}));
    scene.objects.push_back(
        test::makeQuad("card", 0.3, 0.3, "black", {0.45, 0.5, 0.1}, {180, 0, 0}));
    SceneObject ball;
    ball.id = "ball";
    ball.material = "grey";
    ball.shape.type = ShapeType::Sphere;
    ball.shape.radius = 0.12;
    ball.shape.segments = 12;
    ball.transform.translate = {-0.4, 0.3, 0.2};
    scene.objects.push_back(ball);
    SceneObject box;
    box.id = "box";
    box.material = "grey";
    box.shape.type = ShapeType::Box;
    box.shape.size = {0.2, 0.3, 0.2};
    box.transform.translate = {0.1, 0.15, -0.5};
    box.transform.rotateDeg = {0, 30, 0};
    scene.objects.push_back(box);
    scene.settings.patchSize = 0.5;
    scene.settings.elementSize = 0.125;
    const Discretization disc(scene);
    int cut = 0, uncut = 0;
    for (std::size_t e = 0; e < disc.elements().size(); ++e) {
        const int ei = static_cast<int>(e);
        const std::vector<Discontinuity> indexed = shadowDiscontinuities(disc, ei);
        const std::vector<Discontinuity> every =
            shadowDiscontinuities(disc, ei, WedgeSearch::Every);
        ASSERT_EQ(indexed.size(), every.size()) << "element " << e;
        for (std::size_t k = 0; k < every.size(); ++k) {
            EXPECT_EQ(indexed[k].a, every[k].a) << "element " << e;
            EXPECT_EQ(indexed[k].b, every[k].b) << "element " << e;
            EXPECT_EQ(indexed[k].weight, every[k].weight) << "element " << e;
        }
        (every.empty() ? uncut : cut) += 1;
    }
    EXPECT_GT(cut, 20) << "the blockers cast events on many elements";
    EXPECT_GT(uncut, 20);
}

/// A 2 m floor (patches 0.5 m, elements 0.25 m) with a 0.4 m box resting on it off the
/// floor's element grid: footprint x ∈ [−0.1, 0.3], z ∈ [−0.16, 0.24]; with a lamp to its
/// side when `lit`.
Scene boxOnFloor(bool lit) {
    Scene scene;
    test::addMaterial(scene, "grey", Rgb(0.5));
    scene.objects.push_back(test::makeQuad("floor", 2, 2, "grey", {0, 0, 0}));
    if (lit) {
        test::addMaterial(scene, "lamp", Rgb(0.0), Rgb(10.0));
        scene.objects.push_back(
            test::makeQuad("lamp", 0.5, 0.5, "lamp", {-0.6, 1.2, 0}, {180, 0, 0}));
    }
    SceneObject box;
    box.id = "box";
    box.shape.type = ShapeType::Box;
    box.shape.size = Vec3(0.4, 0.4, 0.4);
    box.material = "grey";
    box.transform.translate = Vec3(0.1, 0.2, 0.04);
    scene.objects.push_back(box);
    scene.settings.patchSize = 0.5;
    scene.settings.elementSize = 0.25;
    return scene;
}

TEST(HifiMesh, ABoxOnTheFloorLeavesItsOutlineAsContactLines) {
    const Scene scene = boxOnFloor(false);
    Discretization disc(scene);
    double length = 0;
    for (std::size_t e = 0; e < disc.elements().size(); ++e) {
        if (disc.elements()[e].object != 0) continue;
        for (const Discontinuity& d : contactLines(disc, static_cast<int>(e), 0.25)) {
            // On the box's outline x ∈ {−0.1, 0.3} or z ∈ {−0.16, 0.24}.
            const bool onX = std::abs(d.a.x - d.b.x) < 1e-9 &&
                             (std::abs(d.a.x + 0.1) < 1e-9 || std::abs(d.a.x - 0.3) < 1e-9);
            const bool onZ = std::abs(d.a.z - d.b.z) < 1e-9 &&
                             (std::abs(d.a.z + 0.16) < 1e-9 || std::abs(d.a.z - 0.24) < 1e-9);
            EXPECT_TRUE(onX || onZ) << d.a.x << " " << d.a.z << " → " << d.b.x << " " << d.b.z;
            if (onX || onZ) length += glm::length(d.b - d.a);
        }
    }
    // The outline once (the bottom edges of the welded box; the grid lines inside its flat
    // bottom face are no creases): 4 × 0.4 m.
    EXPECT_NEAR(length, 1.6, 1e-9);
}

TEST(HifiMesh, SharesSamplesWhereIrradianceIsContinuousAndSplitsThemAtContacts) {
    const Scene scene = boxOnFloor(true);
    Discretization disc(scene);
    RayTracer tracer(disc);
    const ExactIrradiance exact = solvedExact(disc, tracer);
    HifiMesh mesh;
    mesh.build(disc, exact);
    // Without sharing every triangle would take six samples of its own.
    EXPECT_LT(mesh.stats().samples, 4 * mesh.stats().triangles);

    // The floor triangles' values at each of their corners, grouped by corner.
    auto onOutline = [](const Vec3& v) {
        const bool inX = v.x > -0.1 - 1e-9 && v.x < 0.3 + 1e-9;
        const bool inZ = v.z > -0.16 - 1e-9 && v.z < 0.24 + 1e-9;
        return (inZ && (std::abs(v.x + 0.1) < 1e-9 || std::abs(v.x - 0.3) < 1e-9)) ||
               (inX && (std::abs(v.z + 0.16) < 1e-9 || std::abs(v.z - 0.24) < 1e-9));
    };
    auto underBox = [](const Vec3& c) {
        return c.x > -0.1 && c.x < 0.3 && c.z > -0.16 && c.z < 0.24;
    };
    struct Corner {
        Vec3 at;
        double value;
        bool inside;  // its triangle lies under the box
    };
    std::vector<Corner> corners;
    for (const HifiTriangle& t : mesh.triangles()) {
        if (disc.elements()[t.element].object != 0) continue;
        const Vec3 centre = (t.p[0] + t.p[1] + t.p[2]) / 3.0;
        const double at[3] = {t.irradiance(0, 0).x, t.irradiance(1, 0).x, t.irradiance(0, 1).x};
        for (int k = 0; k < 3; ++k) corners.push_back({t.p[k], at[k], underBox(centre)});
    }
    int shared = 0, outline = 0;
    double brightest = 0;
    for (const Corner& c : corners) brightest = std::max(brightest, c.value);
    for (std::size_t i = 0; i < corners.size(); ++i)
        for (std::size_t j = i + 1; j < corners.size(); ++j) {
            const Corner &a = corners[i], &b = corners[j];
            if (glm::length(a.at - b.at) > 1e-9) continue;
            if (!onOutline(a.at)) {
                // Off the contact irradiance is continuous: one sample serves both (equal up
                // to the rounding of the coefficients; a sample of each side's own, moved a
                // hair towards its triangle, would differ far more).
                EXPECT_NEAR(a.value, b.value, 1e-12 * brightest) << a.at.x << " " << a.at.z;
                ++shared;
            } else if (a.inside != b.inside) {
                // On it each side keeps its own limit: dark under the box.
                const Corner& in = a.inside ? a : b;
                EXPECT_LT(in.value, 1e-3 * brightest) << in.at.x << " " << in.at.z;
                ++outline;
            }
        }
    EXPECT_GT(shared, 0);
    EXPECT_GT(outline, 0);
}

TEST(HifiMesh, TrianglesInsideAnotherObjectAreDropped) {
    const Scene scene = boxOnFloor(true);
    Discretization disc(scene);
    RayTracer tracer(disc);
    ProgressiveSolver solver(disc, tracer, SolverOptions{});
    solver.converge(1e-4, 100000);
    auto floorTrianglesUnderTheBox = [&](const HifiMesh& mesh) {
        int under = 0;
        for (const HifiTriangle& t : mesh.triangles()) {
            const Vec3 c = (t.p[0] + t.p[1] + t.p[2]) / 3.0;
            if (disc.elements()[t.element].object == 0 && c.x > -0.1 && c.x < 0.3 && c.z > -0.16 &&
                c.z < 0.24)
                ++under;
        }
        return under;
    };
    // Without a tracer nothing is dropped; with one, the floor under the box goes and the
    // floor around it stays.
    ExactIrradiance plain(disc);
    plain.setReflected(reflectedRadiosity(disc, solver));
    HifiMesh all;
    all.build(disc, plain);
    EXPECT_GT(floorTrianglesUnderTheBox(all), 0);
    EXPECT_EQ(all.stats().coveredTriangles, 0);
    ExactIrradiance traced(disc, {}, &tracer);
    traced.setReflected(reflectedRadiosity(disc, solver));
    HifiMesh culled;
    culled.build(disc, traced);
    EXPECT_EQ(floorTrianglesUnderTheBox(culled), 0);
    EXPECT_GT(culled.stats().coveredTriangles, 0);
    EXPECT_EQ(culled.triangles().size() + floorTrianglesUnderTheBox(all), all.triangles().size());
}

/// A 2 m floor under a square lamp, with a 0.6 m box of a two-sided material floating 0.1 m
/// above the floor (a closed solid, as Blender's exporter writes every box); with `buried`, a
/// 0.2 m box turned 20° about y inside it, touching nothing.
Scene boxInsideABox(bool buried) {
    Scene scene;
    test::addMaterial(scene, "grey", Rgb(0.5));
    test::addMaterial(scene, "lamp", Rgb(0.0), Rgb(10.0));
    test::addMaterial(scene, "painted", Rgb(0.6));
    scene.materials.back().material.twoSided = true;
    scene.objects.push_back(test::makeQuad("floor", 2, 2, "grey", {0, 0, 0}));
    scene.objects.push_back(
        test::makeQuad("lamp", 0.5, 0.5, "lamp", {-0.3, 1.5, 0.1}, {180, 0, 0}));
    auto box = [](const std::string& id, double size, Vec3 at, double turnDeg) {
        SceneObject o;
        o.id = id;
        o.shape.type = ShapeType::Box;
        o.shape.size = Vec3(size);
        o.material = "painted";
        o.transform.translate = at;
        o.transform.rotateDeg = Vec3(0, turnDeg, 0);
        return o;
    };
    scene.objects.push_back(box("outer", 0.6, {0.1, 0.4, 0}, 0));
    if (buried) scene.objects.push_back(box("inner", 0.2, {0.15, 0.45, 0.05}, 20));
    scene.settings.patchSize = 0.2;
    scene.settings.elementSize = 0.1;
    return scene;
}

TEST(HifiMesh, AnObjectBuriedInsideAClosedOneAddsNoSegmentsTrianglesOrSamples) {
    // Direct light only, so both builds sample the same function wherever they sample; one
    // thread, so no sample is taken twice by two threads reaching it at once.
    const tbb::global_control oneThread(tbb::global_control::max_allowed_parallelism, 1);
    auto build = [](const Discretization& disc, const RayTracer& tracer) {
        ExactIrradiance exact(disc, {}, &tracer);
        HifiMesh mesh;
        mesh.build(disc, exact);
        return mesh;
    };
    const Scene without = boxInsideABox(false), with = boxInsideABox(true);
    Discretization discWithout(without), discWith(with);
    RayTracer tracerWithout(discWithout), tracerWith(discWith);
    const HifiMesh a = build(discWithout, tracerWithout);
    const HifiMesh b = build(discWith, tracerWith);
    // Every element of the inner box is buried: no triangles.
    const auto [first, count] = discWith.elementRange(3);
    ASSERT_GT(count, 0);
    for (int e = first; e < first + count; ++e)
        EXPECT_EQ(b.first(e + 1) - b.first(e), 0) << "inner element " << e;
    EXPECT_EQ(b.stats().buriedElements, count) << b.toString();
    EXPECT_EQ(a.stats().buriedElements, 0) << a.toString();
    // Its edges cast no shadow events and nothing else changes: the same segments, triangles
    // and samples as without it.
    EXPECT_EQ(b.stats().shadowSegments, a.stats().shadowSegments);
    EXPECT_EQ(b.stats().contactSegments, a.stats().contactSegments);
    EXPECT_EQ(b.stats().triangles, a.stats().triangles);
    EXPECT_EQ(b.stats().samples, a.stats().samples);
    EXPECT_GT(a.stats().shadowSegments, 0) << "the outer box shadows the floor";
}

TEST(HifiMesh, NoTriangleLiesInsideAnInterpenetratingClosedObject) {
    // Two boxes of a two-sided material, the second pushed halfway through the first's side.
    Scene scene;
    test::addMaterial(scene, "grey", Rgb(0.5));
    test::addMaterial(scene, "lamp", Rgb(0.0), Rgb(10.0));
    test::addMaterial(scene, "fabric", Rgb(0.4));
    scene.materials.back().material.twoSided = true;
    scene.objects.push_back(test::makeQuad("floor", 2, 2, "grey", {0, 0, 0}));
    scene.objects.push_back(test::makeQuad("lamp", 0.5, 0.5, "lamp", {0, 1.5, 0}, {180, 0, 0}));
    SceneObject seat;
    seat.id = "seat";
    seat.shape.type = ShapeType::Box;
    seat.shape.size = Vec3(0.8, 0.3, 0.5);
    seat.material = "fabric";
    seat.transform.translate = Vec3(0, 0.25, 0);
    SceneObject arm = seat;
    arm.id = "arm";
    arm.shape.size = Vec3(0.2, 0.5, 0.6);
    arm.transform.translate = Vec3(0.4, 0.35, 0);
    scene.objects.push_back(seat);
    scene.objects.push_back(arm);
    scene.settings.patchSize = 0.2;
    scene.settings.elementSize = 0.05;
    Discretization disc(scene);
    RayTracer tracer(disc);
    ExactIrradiance exact(disc, {}, &tracer);
    HifiMesh mesh;
    mesh.build(disc, exact);
    // Strictly inside a box (centre c, half size h), with a margin.
    auto inside = [](const Vec3& p, const Vec3& c, const Vec3& h) {
        const Vec3 d = glm::abs(p - c);
        return d.x < h.x - 1e-6 && d.y < h.y - 1e-6 && d.z < h.z - 1e-6;
    };
    int seatTriangles = 0, armTriangles = 0;
    for (const HifiTriangle& t : mesh.triangles()) {
        const Vec3 centre = (t.p[0] + t.p[1] + t.p[2]) / 3.0;
        const int object = disc.elements()[t.element].object;
        if (object == 2) {
            ++seatTriangles;
            EXPECT_FALSE(inside(centre, arm.transform.translate, 0.5 * arm.shape.size))
                << "seat triangle inside the arm at " << centre.x << " " << centre.y << " "
                << centre.z;
        } else if (object == 3) {
            ++armTriangles;
            EXPECT_FALSE(inside(centre, seat.transform.translate, 0.5 * seat.shape.size))
                << "arm triangle inside the seat at " << centre.x << " " << centre.y << " "
                << centre.z;
        }
    }
    EXPECT_GT(seatTriangles, 0);
    EXPECT_GT(armTriangles, 0);
    // The seat's end inside the arm is whole elements (buried), its border partly inside
    // (covered triangles).
    EXPECT_GT(mesh.stats().buriedElements, 0) << mesh.toString();
    EXPECT_GT(mesh.stats().coveredTriangles, 0) << mesh.toString();
    // Where they cross, on grid lines of each other's faces too, are contact lines.
    EXPECT_GT(mesh.stats().contactSegments, 0) << mesh.toString();
}

TEST(HifiMesh, TheSegmentAndTriangleCapsHoldOnEveryElement) {
    const Scene scene = boxOnFloor(true);
    Discretization disc(scene);
    RayTracer tracer(disc);
    ExactIrradiance exact(disc, {}, &tracer);
    auto mostTriangles = [&](const HifiMesh& mesh) {
        int most = 0;
        for (std::size_t e = 0; e < disc.elements().size(); ++e)
            most = std::max(most,
                            mesh.first(static_cast<int>(e) + 1) - mesh.first(static_cast<int>(e)));
        return most;
    };
    HifiOptions loose;
    loose.maxSegments = 1000;
    loose.maxTriangles = 1000;
    HifiMesh free;
    free.build(disc, exact, loose);
    HifiOptions tight;
    tight.maxSegments = 2;
    tight.maxTriangles = 8;
    HifiMesh capped;
    capped.build(disc, exact, tight);
    EXPECT_GT(mostTriangles(free), tight.maxTriangles) << "the caps have work to do";
    EXPECT_EQ(free.stats().cappedElements, 0);
    EXPECT_LE(mostTriangles(capped), tight.maxTriangles) << capped.toString();
    EXPECT_GT(capped.stats().cappedElements, 0);
    // Segments: at most two per element, so at most twice the meshed elements.
    EXPECT_LE(capped.stats().shadowSegments + capped.stats().contactSegments,
              2 * capped.stats().meshedElements);
    // The default cap holds too.
    HifiMesh standard;
    standard.build(disc, exact);
    EXPECT_LE(mostTriangles(standard), HifiOptions{}.maxTriangles);
}

TEST(HifiMesh, InterpolantsFollowTheExactIrradianceCloserThanConstantElements) {
    CardScene s(0.25);
    ProgressiveSolver solver(*s.disc, *s.tracer, SolverOptions{});
    solver.converge(1e-6, 100000);
    ExactIrradiance exact(*s.disc);
    exact.setReflected(reflectedRadiosity(*s.disc, solver));
    HifiMesh mesh;
    mesh.build(*s.disc, exact);
    EXPECT_GT(mesh.stats().meshedElements, 0);
    // Floor points on a fine grid: the interpolant's radiosity and the element's constant one
    // against ρ × the exact irradiance there.
    double errHifi = 0, errConst = 0, norm = 0;
    for (int i = 0; i < 60; ++i)
        for (int k = 0; k < 60; ++k) {
            const Vec3 x(-0.95 + 1.9 * (i + 0.5) / 60, 0, -0.95 + 1.9 * (k + 0.5) / 60);
            const RayTracer::FirstHit hit = s.tracer->firstHit(x + Vec3(0, 0.1, 0), Vec3(0, -1, 0));
            ASSERT_GE(hit.element, 0);
            double sb = 0, tb = 0;
            const int tri = mesh.locate(hit.element, x, sb, tb);
            ASSERT_GE(tri, 0);
            const double truth = 0.5 * exact.irradiance(x, Vec3(0, 1, 0)).x;
            const double hifi = mesh.radiosity(*s.disc, tri, sb, tb).x;
            const double constant = solver.radiosity()[hit.element].x;
            errHifi += (hifi - truth) * (hifi - truth);
            errConst += (constant - truth) * (constant - truth);
            norm += truth * truth;
        }
    const double relHifi = std::sqrt(errHifi / norm), relConst = std::sqrt(errConst / norm);
    EXPECT_LT(relHifi, 0.02);
    EXPECT_LT(relHifi, 0.3 * relConst);
}

TEST(HifiMesh, AFaceSmallerThanTheFinestRefinementIsSampledOnceAtItsCentroid) {
    // A tessellated ball 2 cm across above the card scene's floor: its faces (a few millimetres)
    // are smaller than refinement's finest triangle on the 0.1 m floor elements, so each is one
    // sample at its centroid, its triangles' interpolants that constant; the floor's are not.
    Scene scene;
    test::addMaterial(scene, "lamp", Rgb(0.0), Rgb(10.0));
    test::addMaterial(scene, "grey", Rgb(0.5));
    scene.objects.push_back(test::makeQuad("floor", 2, 2, "grey", {0, 0, 0}));
    scene.objects.push_back(test::makeQuad("lamp", 0.4, 0.4, "lamp", {0, 1, 0}, {180, 0, 0}));
    SceneObject ball;
    ball.id = "ball";
    ball.shape.type = ShapeType::Sphere;
    ball.shape.radius = 0.01;
    ball.shape.segments = 12;
    ball.material = "grey";
    ball.transform.translate = Vec3(-0.5, 0.3, -0.5);
    scene.objects.push_back(ball);
    scene.settings.patchSize = 0.5;
    scene.settings.elementSize = 0.1;
    Discretization disc(scene);
    RayTracer tracer(disc);
    const ExactIrradiance exact = solvedExact(disc, tracer);
    HifiMesh mesh;
    mesh.build(disc, exact);
    int ballElements = 0;
    for (std::size_t e = 0; e < disc.elements().size(); ++e) {
        const Element& el = disc.elements()[e];
        if (el.object != 2) continue;
        ++ballElements;
        const int first = mesh.first(static_cast<int>(e)),
                  last = mesh.first(static_cast<int>(e) + 1);
        ASSERT_GT(last, first) << "ball element " << e << " has no triangles";
        const Rgb truth = exact.irradiance(el.centroid, el.normal);
        for (int t = first; t < last; ++t) {
            const QuadraticInterpolant& q = mesh.triangles()[t].irradiance;
            for (int k = 0; k < 5; ++k)
                EXPECT_NEAR(glm::length(q.c[k]), 0.0, 1e-12)
                    << "element " << e << " coefficient " << k;
            EXPECT_NEAR(q.c[5].x, truth.x, 1e-9 * (1 + truth.x)) << "element " << e;
        }
    }
    EXPECT_GT(ballElements, 50);
    EXPECT_EQ(mesh.stats().singleSampleElements, ballElements);
}

TEST(HifiMesh, ACancelledBuildStopsEarlyAndSaysSo) {
    CardScene s(0.25);
    const ExactIrradiance exact = solvedExact(*s.disc, *s.tracer);
    HifiMesh whole;
    whole.build(*s.disc, exact);
    EXPECT_FALSE(whole.stats().cancelled);
    // Cancelled after a few elements: those may finish, the rest are not sampled.
    std::atomic<int> polls{0};
    HifiOptions options;
    options.cancelled = [&] { return ++polls > 4; };
    HifiMesh part;
    part.build(*s.disc, exact, options);
    EXPECT_TRUE(part.stats().cancelled);
    EXPECT_LT(part.stats().triangles, whole.stats().triangles / 2);
    EXPECT_LT(part.stats().samples, whole.stats().samples / 2);
}

TEST(HifiMesh, AnUpdateAfterAMoveRemeshesWhatChangedAsAFullBuildWouldAndKeepsTheRest) {
    EditSession session(boxOnFloor(true), SolverOptions{});
    session.converge(1e-4);
    const Discretization& disc = session.discretization();
    ExactIrradiance before(disc, {}, &session.tracer());
    before.setReflected(reflectedRadiosity(disc, session.solver()));
    HifiMesh mesh;
    mesh.build(disc, before);
    const HifiMesh old = mesh;
    const std::vector<Rgb> lightBefore = session.solver().radiosity();

    // The box slides 0.3 m away from the lamp: its shadow and contact lines move with it.
    const EditEvent event = session.apply(MoveCommand{"box", Vec3(0.3, 0, 0)});
    session.converge(1e-4);
    ExactIrradiance after(disc, {}, &session.tracer());
    after.setReflected(reflectedRadiosity(disc, session.solver()));
    const std::vector<std::uint8_t> remesh =
        hifiRemeshElements(disc, lightBefore, session.solver().radiosity(), event.changed());
    mesh.update(disc, after, remesh);
    HifiMesh full;
    full.build(disc, after);

    // Some floor elements are re-meshed (the old and new shadow, the contacts), not all.
    int flaggedFloor = 0, floor = 0;
    for (std::size_t e = 0; e < disc.elements().size(); ++e)
        if (disc.elementAlive(int(e)) && disc.elements()[e].object == 0)
            ++floor, flaggedFloor += remesh[e];
    EXPECT_GT(flaggedFloor, 0);
    EXPECT_LT(flaggedFloor, floor);
    EXPECT_LT(mesh.stats().remeshed, full.stats().remeshed);
    // Elements past the old solution's are new (the box's moved version): always meshed.
    const int built = int(lightBefore.size());
    int newElements = 0;
    // Each alive element: kept as it was when unflagged, as a full build makes it otherwise.
    for (int e = 0; e < int(disc.elements().size()); ++e) {
        if (!disc.elementAlive(e)) {
            EXPECT_EQ(mesh.first(e), mesh.first(e + 1)) << "dead element " << e;
            continue;
        }
        const bool kept = e < built && !remesh[e];
        const HifiMesh& expected = kept ? old : full;
        if (e >= built) {
            ++newElements;
            EXPECT_TRUE(remesh[e]);
        }
        ASSERT_EQ(mesh.first(e + 1) - mesh.first(e), expected.first(e + 1) - expected.first(e))
            << "element " << e << (kept ? " kept" : " re-meshed");
        for (int k = 0; k < mesh.first(e + 1) - mesh.first(e); ++k) {
            const HifiTriangle& a = mesh.triangles()[mesh.first(e) + k];
            const HifiTriangle& b = expected.triangles()[expected.first(e) + k];
            for (int v = 0; v < 3; ++v) EXPECT_EQ(a.p[v], b.p[v]) << "element " << e;
            for (int c = 0; c < 6; ++c)
                EXPECT_NEAR(glm::length(a.irradiance.c[c] - b.irradiance.c[c]), 0.0,
                            1e-9 * (1 + glm::length(b.irradiance.c[c])))
                    << "element " << e;
        }
    }
    EXPECT_GT(newElements, 0);  // the box's new version
    // And the unflagged elements were near enough: the floor's radiosity from the update is
    // within 1% (RMS, relative) of the full build's.
    double diff = 0, norm = 0;
    for (int i = 0; i < 40; ++i)
        for (int k = 0; k < 40; ++k) {
            const Vec3 x(-0.975 + 1.95 * (i + 0.5) / 40, 0, -0.975 + 1.95 * (k + 0.5) / 40);
            const RayTracer::FirstHit hit =
                session.tracer().firstHit(x + Vec3(0, 0.01, 0), Vec3(0, -1, 0));
            if (hit.element < 0 || disc.elements()[hit.element].object != 0) continue;
            double s1 = 0, t1 = 0, s2 = 0, t2 = 0;
            const int a = mesh.locate(hit.element, x, s1, t1);
            const int b = full.locate(hit.element, x, s2, t2);
            if (a < 0 || b < 0) continue;
            const double ya = luminance(mesh.radiosity(disc, a, s1, t1));
            const double yb = luminance(full.radiosity(disc, b, s2, t2));
            diff += (ya - yb) * (ya - yb);
            norm += yb * yb;
        }
    EXPECT_LT(std::sqrt(diff / norm), 0.01);
}

TEST(HifiMesh, RendersWithoutADisplay) {
    // The per-pixel pass needs no window system: it runs with DISPLAY unset.
    ::unsetenv("DISPLAY");
    CardScene s(0.25);
    const ExactIrradiance exact = solvedExact(*s.disc, *s.tracer);
    HifiMesh mesh;
    mesh.build(*s.disc, exact);
    Camera camera;
    camera.position = Vec3(0, 1.5, 1.5);
    camera.lookAt = Vec3(0, 0, 0);
    const Image image = renderInterpolants(*s.disc, *s.tracer, mesh, CameraRays(camera, 32, 32));
    double lit = 0;
    for (const Rgb& p : image.pixels) lit += p.x > 0;
    EXPECT_GT(lit, 100);
}

}  // namespace
}  // namespace penumbra
