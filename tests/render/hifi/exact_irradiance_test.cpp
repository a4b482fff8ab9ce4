// Exact point irradiance (Hardt & Teller §5, backprojection): the visible part of a source
// against closed forms that need no clipping — an unoccluded rectangle, a rectangle behind a
// half-plane blocker (what stays visible is again a rectangle), a blocker covering the source —
// and the polygon subtraction against areas computed by hand.

#include "render/hifi/exact_irradiance.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "closed_forms.h"
#include "solver/discretization.h"
#include "solver/form_factor.h"
#include "solver/progressive_solver.h"
#include "solver/ray_tracer.h"
#include "test_scenes.h"

namespace penumbra {
namespace {

using test::rectangleFormFactor;

TEST(PolygonSet2, SubtractingASquareFromTheMiddleLeavesTheFrame) {
    PolygonSet2 set({{0, 0}, {4, 0}, {4, 4}, {0, 4}});
    set.subtract({{1, 1}, {1, 3}, {3, 3}, {3, 1}});  // clockwise: either winding
    EXPECT_NEAR(set.area(), 16.0 - 4.0, 1e-12);
    for (const auto& piece : set.pieces()) {
        // Every piece convex and counter-clockwise.
        for (std::size_t i = 0; i < piece.size(); ++i) {
            const Vec2 a = piece[(i + 1) % piece.size()] - piece[i];
            const Vec2 b = piece[(i + 2) % piece.size()] - piece[(i + 1) % piece.size()];
            EXPECT_GE(a.x * b.y - a.y * b.x, -1e-12);
        }
    }
}

TEST(PolygonSet2, OverlappingSubtractionsRemoveTheUnionOnce) {
    PolygonSet2 set({{0, 0}, {4, 0}, {4, 4}, {0, 4}});
    set.subtract({{-1, -1}, {2, -1}, {2, 2}, {-1, 2}});  // 2×2 of the square
    set.subtract({{1, 1}, {3, 1}, {3, 3}, {1, 3}});      // overlaps it by 1×1
    set.subtract({{0, 0}, {1, 0}, {0, 1}});              // inside what is gone already
    EXPECT_NEAR(set.area(), 16.0 - (4.0 + 4.0 - 1.0), 1e-12);
    set.subtract({{-10, -10}, {10, -10}, {10, 10}, {-10, 10}});
    EXPECT_TRUE(set.empty());
}

TEST(PolygonSet2, DisjointSubtractionKeepsEverything) {
    PolygonSet2 set({{0, 0}, {1, 0}, {1, 1}, {0, 1}});
    set.subtract({{2, 0}, {3, 0}, {3, 1}});
    set.subtract({{1, 0}, {2, 0}, {2, 1}, {1, 1}});  // shares an edge only
    EXPECT_NEAR(set.area(), 1.0, 1e-15);
    EXPECT_EQ(set.pieces().size(), 1u);
}

TEST(PolygonSet2, RepeatedVerticesAndZeroAreaPolygonsAreHandled) {
    // Clipping a blocker at a pyramid's edge can repeat a vertex or leave a sliver of no area.
    PolygonSet2 set({{0, 0}, {1, 0}, {1, 1}, {0, 1}});
    set.subtract({{0, 1}, {0, 1}, {0, 0.5}, {0, 0.5}});  // a segment on the boundary
    EXPECT_NEAR(set.area(), 1.0, 1e-15);
    set.subtract({{0, 1}, {0, 1}, {0, 0}, {1, 0}, {1, 1}, {1, 1}});  // the square, repeated
    EXPECT_TRUE(set.empty());
}

/// A downward-facing 1 × 1 lamp at height 1 over the origin and, when `blockerHeight` > 0, a
/// black 40 × 40 quad at that height covering x ≥ edgeX: a half-plane for every point below.
struct HalfPlaneScene {
    Scene scene;
    std::unique_ptr<Discretization> disc;
    HalfPlaneScene(double blockerHeight, double edgeX) {
        test::addMaterial(scene, "lamp", Rgb(0.0), Rgb(1.0, 2.0, 3.0));
        test::addMaterial(scene, "black", Rgb(0.0));
        scene.objects.push_back(test::makeQuad("lamp", 1, 1, "lamp", {0, 1, 0}, {180, 0, 0}));
        if (blockerHeight > 0)
            scene.objects.push_back(test::makeQuad("blocker", 40, 40, "black",
                                                   {edgeX + 20, blockerHeight, 0}, {180, 0, 0}));
        scene.settings.patchSize = 50;  // one patch each: the lamp is one emitter polygon
        scene.settings.elementSize = 50;
        disc = std::make_unique<Discretization>(scene);
    }
};

/// The lamp's outline, counter-clockwise seen from below (its front).
const std::vector<Vec3> kLamp = {{-0.5, 1, -0.5}, {0.5, 1, -0.5}, {0.5, 1, 0.5}, {-0.5, 1, 0.5}};

TEST(ExactIrradiance, UnoccludedRectangleMatchesTheClosedForm) {
    HalfPlaneScene s(0, 0);
    ExactIrradiance exact(*s.disc);
    ASSERT_EQ(exact.emitterCount(), 1u);
    for (double px : {-1.3, -0.5, 0.0, 0.2, 0.9})
        for (double pz : {-0.7, 0.0, 0.4}) {
            const Vec3 x(px, 0, pz), n(0, 1, 0);
            const double truth = rectangleFormFactor(-0.5 - px, 0.5 - px, -0.5 - pz, 0.5 - pz, 1);
            EXPECT_NEAR(exact.visibleFormFactor(x, n, kLamp), truth, 1e-9 * truth);
            const Rgb h = exact.direct(x, n);
            EXPECT_NEAR(h.x, truth, 1e-9 * truth);
            EXPECT_NEAR(h.z, 3 * truth, 3e-9 * truth);
        }
}

TEST(ExactIrradiance, HalfPlaneBlockerMatchesTheClosedFormEverywhere) {
    // Blocker at height 0.5 covering x ≥ 0: from a point at x = px the lamp stays visible for
    // world x < −px (the blocker's edge seen from the point, carried to twice its height).
    HalfPlaneScene s(0.5, 0.0);
    ExactIrradiance exact(*s.disc);
    double largest = 0;
    std::vector<std::pair<double, double>> values;  // (computed, truth)
    for (int i = 0; i <= 80; ++i) {
        const double px = -1.0 + 2.0 * i / 80;
        for (double pz : {0.0, 0.35}) {
            const double visibleEnd = std::min(0.5, -px);
            const double truth =
                rectangleFormFactor(-0.5 - px, visibleEnd - px, -0.5 - pz, 0.5 - pz, 1.0);
            const double f = exact.direct(Vec3(px, 0, pz), Vec3(0, 1, 0)).x;
            values.emplace_back(f, truth);
            largest = std::max(largest, truth);
        }
    }
    ASSERT_GT(largest, 0.1);
    int penumbra = 0;
    for (auto [f, truth] : values) {
        EXPECT_NEAR(f, truth, 1e-9 * largest);
        if (truth > 0.01 * largest && truth < 0.99 * largest) ++penumbra;
    }
    EXPECT_GT(penumbra, 20);  // the sweep crosses the penumbra, not just umbra and full light
}

TEST(ExactIrradiance, ALampOfManyPatchesIsOneSourceWithTheSameLight) {
    // The 1 × 1 lamp split into 4 × 4 patches, over the half-plane blocker: one convex
    // emitter, whose light matches the closed form as the one-patch lamp's does.
    HalfPlaneScene s(0.5, 0.0);
    Scene split = s.scene;
    split.settings.patchSize = 0.25;
    split.settings.elementSize = 0.25;
    Discretization disc(split);
    int lampPatches = 0;
    for (const Patch& p : disc.patches()) lampPatches += p.object == 0;
    ASSERT_EQ(lampPatches, 16);
    ExactIrradiance exact(disc);
    EXPECT_EQ(exact.emitterCount(), 1u);
    for (double px : {-0.8, -0.3, 0.0, 0.25, 0.6})
        for (double pz : {0.0, 0.35}) {
            const double truth =
                rectangleFormFactor(-0.5 - px, std::min(0.5, -px) - px, -0.5 - pz, 0.5 - pz, 1.0);
            EXPECT_NEAR(exact.direct(Vec3(px, 0, pz), Vec3(0, 1, 0)).x, truth, 1e-9)
                << px << " " << pz;
        }
}

TEST(ExactIrradiance, ALampBoxStaysInPiecesWithTheSameLight) {
    // An emitting 1 m cube over the origin: its faces are not in one plane, so they stay
    // separate sources; from right below, only its bottom face (at height 1) is seen.
    Scene scene;
    test::addMaterial(scene, "lamp", Rgb(0.0), Rgb(1.0));
    SceneObject cube;
    cube.id = "cube";
    cube.shape.type = ShapeType::Box;
    cube.shape.size = Vec3(1.0);
    cube.material = "lamp";
    cube.transform.translate = Vec3(0, 1.5, 0);
    scene.objects.push_back(cube);
    scene.settings.patchSize = 50;
    scene.settings.elementSize = 50;
    Discretization disc(scene);
    ExactIrradiance exact(disc);
    EXPECT_GE(exact.emitterCount(), 6u);
    for (double px : {-0.3, 0.0, 0.2}) {
        const double truth = rectangleFormFactor(-0.5 - px, 0.5 - px, -0.5, 0.5, 1.0);
        EXPECT_NEAR(exact.direct(Vec3(px, 0, 0), Vec3(0, 1, 0)).x, truth, 1e-9 * truth);
    }
}

TEST(ExactIrradiance, TiltedPointAndTiltedBlockerAgreeWithAFinelyGriddedSource) {
    // No closed form: the same visible part integrated as many small unblocked squares whose
    // centre's visibility is known by a ray-free test (the blocker is one half-plane, so a
    // source point is visible when the segment to it stays on one side).
    HalfPlaneScene s(0.6, -0.1);
    ExactIrradiance exact(*s.disc);
    const Vec3 x(0.2, 0.05, -0.3), n = glm::normalize(Vec3(0.3, 1.0, 0.2));
    const double f = exact.visibleFormFactor(x, n, kLamp);
    const int grid = 1600;
    double sum = 0;
    for (int i = 0; i < grid; ++i)
        for (int k = 0; k < grid; ++k) {
            const double a = -0.5 + (i + 0.5) / grid, b = -0.5 + (k + 0.5) / grid;
            const Vec3 q(a, 1, b);
            // The segment x → q crosses y = 0.6 at one point; blocked when there x ≥ −0.1.
            const double t = (0.6 - x.y) / (q.y - x.y);
            if (x.x + t * (q.x - x.x) >= -0.1) continue;
            const Vec3 d = q - x;
            const double r2 = glm::dot(d, d);
            const double cosX = glm::dot(n, d) / std::sqrt(r2);
            const double cosQ = d.y / std::sqrt(r2);  // lamp faces −y
            if (cosX > 0) sum += cosX * cosQ / (M_PI * r2) / (double(grid) * grid);
        }
    ASSERT_GT(f, 0.01);
    EXPECT_NEAR(f, sum, 2e-3 * f);
}

TEST(ExactIrradiance, BlockerCoveringTheSourceLeavesNothing) {
    HalfPlaneScene s(0.5, -10.0);  // covers every x ≥ −10
    ExactIrradiance exact(*s.disc);
    for (double px : {-0.4, 0.0, 0.7}) {
        EXPECT_EQ(exact.visibleFormFactor(Vec3(px, 0, 0), Vec3(0, 1, 0), kLamp), 0.0);
        EXPECT_EQ(exact.visiblePart(Vec3(px, 0, 0), kLamp).size(), 0u);
    }
    // Above the blocker the lamp is in full view again.
    const Vec3 x(0.1, 0.7, 0.2);
    EXPECT_NEAR(exact.visibleFormFactor(x, Vec3(0, 1, 0), kLamp),
                rectangleFormFactor(-0.6, 0.4, -0.7, 0.3, 0.3), 1e-9);
}

TEST(ExactIrradiance, GatherMatchesAHemisphereOfRaysOverTheSameElements) {
    // A closed grey room with a lamp and a box on the floor, converged. Gathered element by
    // element, the exact irradiance integrates the same piecewise-constant radiosity as a
    // brute-force hemisphere of cosine-distributed Embree rays, each reading the radiosity of
    // the element it hits: they differ only by the rays' noise, at points in the open and
    // next to the box.
    Scene scene;
    test::addMaterial(scene, "grey", Rgb(0.5));
    test::addMaterial(scene, "lamp", Rgb(0.0), Rgb(20.0));
    test::addClosedRoom(scene, 2.0, "grey");
    scene.objects.push_back(test::makeQuad("lamp", 0.5, 0.5, "lamp", {0, 0.99, 0}, {180, 0, 0}));
    SceneObject box;
    box.id = "box";
    box.shape.type = ShapeType::Box;
    box.shape.size = Vec3(0.5, 0.5, 0.5);
    box.material = "grey";
    box.transform.translate = Vec3(0.3, -0.75, 0.1);
    scene.objects.push_back(box);
    scene.settings.patchSize = 0.5;
    scene.settings.elementSize = 0.25;
    Discretization disc(scene);
    RayTracer tracer(disc);
    ProgressiveSolver solver(disc, tracer, SolverOptions{});
    solver.converge(1e-4, 100000);

    std::vector<Rgb> reflected(disc.elements().size());
    for (std::size_t e = 0; e < reflected.size(); ++e)
        reflected[e] = solver.radiosity()[e] - disc.elementMaterial(int(e)).emission;
    ExactIrradianceOptions exactOptions;
    exactOptions.nearRadii = 1e9;  // every source element by element
    ExactIrradiance exact(disc, exactOptions);
    exact.setReflected(reflected);
    // The far field by rays (near patches exact): the same light, less the rays' noise.
    ExactIrradianceOptions hybridOptions;
    hybridOptions.farRays = 1024;
    ExactIrradiance hybrid(disc, hybridOptions, &tracer);
    hybrid.setReflected(reflected);
    const int grid = 600;  // 360,000 stratified rays
    for (Vec3 x : {Vec3(-0.5, -1, -0.5), Vec3(0.0, -1, 0.1), Vec3(0.3, -1, -0.3)}) {
        const Vec3 n(0, 1, 0);
        double sum = 0;
        for (int i = 0; i < grid; ++i)
            for (int k = 0; k < grid; ++k) {
                // Cosine-distributed direction (Malley): a uniform disc point lifted.
                const double r = std::sqrt((i + 0.5) / grid), phi = 2 * M_PI * (k + 0.5) / grid;
                const Vec3 d(r * std::cos(phi), std::sqrt(std::max(0.0, 1 - r * r)),
                             r * std::sin(phi));
                const RayTracer::FirstHit hit = tracer.firstHit(x + 1e-6 * n, d);
                if (hit.element < 0 || hit.backFace) continue;
                sum += solver.radiosity()[hit.element].x;
            }
        const double byRays = sum / (double(grid) * grid);  // E = ∫ (B/π) cos dω
        const Rgb total = exact.irradiance(x, n);
        EXPECT_NEAR(total.x, byRays, 0.003 * byRays) << x.x << " " << x.z;
        EXPECT_GT(exact.indirect(x, n).x, 0.05 * total.x);
        EXPECT_NEAR(hybrid.irradiance(x, n).x, byRays, 0.01 * byRays) << x.x << " " << x.z;
        // The parts add up to the irradiance; without rays there is no far field.
        const ExactIrradiance::Parts parts = hybrid.irradianceParts(x, n);
        EXPECT_NEAR(parts.total().x, hybrid.irradiance(x, n).x, 1e-12 * byRays);
        EXPECT_GT(parts.farField.x, 0.0);
        EXPECT_EQ(exact.irradianceParts(x, n).farField.x, 0.0);
        EXPECT_NEAR(exact.irradianceParts(x, n).gathered.x, total.x, 1e-12 * byRays);
    }
}

TEST(ExactIrradiance, TheNearFieldHoldsEveryElementWithinItsNearBallAndNoOther) {
    // Elements of very different sizes (a room of 0.5 m elements, a finely tessellated ball):
    // with the far field by rays, the gathered part at a point is the direct light and,
    // element by element, every source element whose near ball (nearElementRadii of its own
    // radius about its centroid) holds the point, found through the element grid. Summed
    // here by testing every element of the scene.
    Scene scene;
    test::addMaterial(scene, "grey", Rgb(0.5));
    test::addMaterial(scene, "lamp", Rgb(0.0), Rgb(20.0));
    test::addClosedRoom(scene, 2.0, "grey");
    scene.objects.push_back(test::makeQuad("lamp", 0.5, 0.5, "lamp", {0, 0.99, 0}, {180, 0, 0}));
    SceneObject ball;
    ball.id = "ball";
    ball.shape.type = ShapeType::Sphere;
    ball.shape.radius = 0.3;
    ball.shape.segments = 48;
    ball.material = "grey";
    ball.transform.translate = Vec3(0.2, -0.69, 0.1);
    scene.objects.push_back(ball);
    scene.settings.patchSize = 0.5;
    scene.settings.elementSize = 0.5;
    Discretization disc(scene);
    RayTracer tracer(disc);
    std::vector<Rgb> reflected(disc.elements().size());
    for (std::size_t e = 0; e < reflected.size(); ++e)
        reflected[e] = Rgb(0.1 + 0.01 * double(e % 17), 0.2, 0.3);
    ExactIrradianceOptions options;
    options.farRays = 16;
    ExactIrradiance hybrid(disc, options, &tracer);
    hybrid.setReflected(reflected);
    const ExactIrradiance direct(disc, ExactIrradianceOptions{});
    std::vector<std::pair<Vec3, Vec3>> points = {{Vec3(0.2, -1, 0.45), Vec3(0, 1, 0)},
                                                 {Vec3(-0.7, -1, -0.7), Vec3(0, 1, 0)},
                                                 {Vec3(0.9, -0.2, 0.3), Vec3(0, 0, 1)}};
    // Points on the ball, where its own small elements are near.
    for (int k = 0; k < 6; ++k) {
        const double a = 0.9 * k;
        const Vec3 n = glm::normalize(Vec3(std::cos(a), -0.3 + 0.2 * k, std::sin(a)));
        points.push_back({ball.transform.translate + 0.3 * n, n});
    }
    int nearTotal = 0;
    for (const auto& [x, n] : points) {
        Rgb expected = direct.direct(x, n);
        int near = 0;
        for (std::size_t e = 0; e < disc.elements().size(); ++e) {
            const std::vector<Vec3> poly = disc.elementPolygon(static_cast<int>(e));
            const Vec3 c = disc.elements()[e].centroid;
            double radius = 0;
            for (const Vec3& p : poly) radius = std::max(radius, glm::length(p - c));
            if (glm::length(x - c) > options.nearElementRadii * radius) continue;
            ++near;
            expected += reflected[e] * direct.visibleFormFactor(x, n, poly);
        }
        nearTotal += near;
        const Rgb gathered = hybrid.irradianceParts(x, n, false).gathered;
        for (int c = 0; c < 3; ++c)
            EXPECT_NEAR(gathered[c], expected[c], 1e-9 * expected[c]) << x.x << " " << x.y;
    }
    EXPECT_GT(nearTotal, 3 * static_cast<int>(points.size())) << "near elements were tested";
}

TEST(LeafReflectedRadiosity, EachElementTakesTheSolveInWhichItShootsOnItsOwn) {
    // A grey room lit from a lamp low on one wall, a tilted box of 0.6 m on the floor, a ball
    // of 8 segments and a two-sided triangle mesh in the air. Patches of 0.5 m split the box's
    // sides into 4 × 4 elements of 0.15 m and the ball into 9 × 4, where patches of one
    // element (0.25 m) would split them into 3 × 3 and 10 × 6, and group the mesh's back sheet
    // in another order: the leaf solve's value of each element is its own in a from-scratch
    // solve of the same elements, each its own shooter (checked here: one element a patch, and
    // each element of the scene's found in it by object, centroid and facing). Then elements
    // adaptive subdivision made (a box element split, one piece split again) take the value of
    // the element they lie in.
    Scene scene;
    test::addMaterial(scene, "grey", Rgb(0.5, 0.6, 0.7));
    test::addMaterial(scene, "lamp", Rgb(0.0), Rgb(20.0));
    test::addClosedRoom(scene, 2.0, "grey");
    scene.objects.push_back(
        test::makeQuad("lamp", 0.5, 0.5, "lamp", {-0.99, -0.5, 0.3}, {0, 0, -90}));
    SceneObject box;
    box.id = "box";
    box.shape.type = ShapeType::Box;
    box.shape.size = Vec3(0.6, 0.6, 0.6);
    box.material = "grey";
    box.transform.translate = Vec3(0.2, -0.7, 0.1);
    box.transform.rotateDeg = Vec3(0, 20, 0);
    scene.objects.push_back(box);
    SceneObject ball;
    ball.id = "ball";
    ball.shape.type = ShapeType::Sphere;
    ball.shape.radius = 0.2;
    ball.shape.segments = 8;
    ball.material = "grey";
    ball.transform.translate = Vec3(-0.4, 0.3, -0.3);
    scene.objects.push_back(ball);
    test::addMaterial(scene, "sheet", Rgb(0.7, 0.6, 0.5));
    scene.materials.back().material.twoSided = true;
    SceneObject sheet;
    sheet.id = "sheet";
    sheet.shape.type = ShapeType::Mesh;
    sheet.shape.mesh.positions = {{0.6, 0.2, -0.6}, {0.9, 0.2, 0.2}, {0.7, 0.8, -0.2}};
    sheet.shape.mesh.triangles = {{0, 1, 2}};
    sheet.material = "sheet";
    scene.objects.push_back(sheet);
    scene.settings.patchSize = 0.5;
    scene.settings.elementSize = 0.25;
    Discretization disc(scene);
    const int boxObject = static_cast<int>(disc.objects().size()) - 3, ballObject = boxObject + 1;
    auto elementsOf = [&](const Discretization& d, int object) {
        int n = 0;
        for (const Element& el : d.elements()) n += el.object == object;
        return n;
    };
    Scene elementPatches = scene;
    elementPatches.settings.patchSize = scene.settings.elementSize;
    const Discretization byElements(elementPatches);
    ASSERT_EQ(elementsOf(disc, boxObject), 6 * 16);
    ASSERT_EQ(elementsOf(byElements, boxObject), 6 * 9);
    ASSERT_EQ(elementsOf(disc, ballObject), 9 * 4);
    ASSERT_EQ(elementsOf(byElements, ballObject), 10 * 6);

    const double eps = 1e-6;
    const std::vector<Rgb> leaf = leafReflectedRadiosity(scene, disc, SolverOptions{}, eps, 100000);

    // The reference: the scene's elements, one a patch (the mesh's faces, smaller than an
    // element, several), solved from scratch.
    Discretization refDisc(scene, PatchGrouping::Elements);
    for (const Patch& p : refDisc.patches()) {
        if (p.object != boxObject + 2) {
            ASSERT_EQ(p.elements.size(), 1u) << p.toString();
        }
    }
    ASSERT_EQ(refDisc.elements().size(), disc.elements().size());
    std::vector<int> same(disc.elements().size(), -1);
    for (std::size_t e = 0; e < disc.elements().size(); ++e) {
        const Element& a = disc.elements()[e];
        for (std::size_t r = 0; r < refDisc.elements().size(); ++r) {
            const Element& b = refDisc.elements()[r];
            if (a.object == b.object && glm::length(a.centroid - b.centroid) < 1e-12 &&
                glm::dot(a.normal, b.normal) > 0) {
                ASSERT_LT(same[e], 0) << a.toString();
                same[e] = static_cast<int>(r);
            }
        }
        ASSERT_GE(same[e], 0) << a.toString();
    }
    RayTracer refTracer(refDisc);
    SolverOptions refOptions;
    refOptions.placeReceivers = true;
    ProgressiveSolver refSolver(refDisc, refTracer, refOptions);
    refSolver.converge(eps, 100000);
    const std::vector<Rgb> ref = reflectedRadiosity(refDisc, refSolver);
    double largest = 0;
    for (const Rgb& b : ref) largest = std::max(largest, b.x);
    for (std::size_t e = 0; e < disc.elements().size(); ++e)
        for (int c = 0; c < 3; ++c)
            ASSERT_NEAR(leaf[e][c], ref[same[e]][c], 1e-9 * largest)
                << "element " << e << " " << disc.elements()[e].toString() << " channel " << c;

    // A side of the box: one element split into four, one piece into four again.
    int side = -1;
    for (std::size_t e = 0; e < disc.elements().size() && side < 0; ++e)
        if (disc.elements()[e].object == boxObject && std::abs(disc.elements()[e].normal.y) < 0.5)
            side = static_cast<int>(e);
    ASSERT_GE(side, 0);
    const Rgb whole = leaf[side];
    std::vector<int> pieces = disc.subdivideElement(side);
    const std::vector<int> finer = disc.subdivideElement(pieces[1]);
    pieces.insert(pieces.end(), finer.begin() + 1, finer.end());
    ASSERT_EQ(pieces.size(), 7u);
    const std::vector<Rgb> split =
        leafReflectedRadiosity(scene, disc, SolverOptions{}, eps, 100000);
    for (int e : pieces)
        for (int c = 0; c < 3; ++c)
            EXPECT_NEAR(split[e][c], whole[c], 1e-9 * largest)
                << "piece " << e << " " << disc.elements()[e].toString() << " channel " << c;
}

}  // namespace
}  // namespace penumbra
