// EdgeFinder over a Discretization: world-space silhouettes of transformed objects against a
// world-space brute force, forward-facing sharp edges, moves without rebuilding trees.
#include "render/display/edge_finder.h"

#include <gtest/gtest.h>

#include <random>
#include <set>

#include "test_scenes.h"

using namespace penumbra;

namespace {

Vec3 apply(const Mat4& m, const Vec3& p) { return Vec3(m * glm::dvec4(p, 1.0)); }

Scene primitives() {
    Scene s;
    s.settings.patchSize = 0.5;
    s.settings.elementSize = 0.1;
    test::addMaterial(s, "white", Rgb(0.5));
    SceneObject box;
    box.id = "box";
    box.shape.type = ShapeType::Box;
    box.shape.size = Vec3(0.6, 0.4, 0.5);
    box.material = "white";
    box.transform.translate = Vec3(0.5, 0.3, -0.2);
    box.transform.rotateDeg = Vec3(10, 30, 5);
    s.objects.push_back(box);
    SceneObject sphere;
    sphere.id = "sphere";
    sphere.shape.type = ShapeType::Sphere;
    sphere.shape.radius = 0.3;
    sphere.shape.segments = 24;
    sphere.material = "white";
    sphere.transform.translate = Vec3(-0.5, 0.4, 0.1);
    sphere.transform.scale = Vec3(1.0, 1.5, 0.8);  // non-uniform: eq. 1 is affine invariant
    s.objects.push_back(sphere);
    s.objects.push_back(test::makeQuad("floor", 3, 3, "white", {0, 0, 0}));
    return s;
}

/// Eq. 1 in world space on the transformed polygons (Newell normals of world vertices).
bool worldSilhouette(const EdgeMesh& mesh, const Mat4& m, int edge, const Vec3& eye) {
    const MeshEdge& e = mesh.edges()[edge];
    if (e.boundary()) return true;
    auto front = [&](int f) {
        Vec3 n(0.0);
        int b = mesh.faceStart()[f], c = mesh.faceStart()[f + 1] - b;
        std::vector<Vec3> w;
        for (int i = 0; i < c; ++i)
            w.push_back(apply(m, mesh.positions()[mesh.faceVertices()[b + i]]));
        for (int i = 0; i < c; ++i) n += glm::cross(w[i], w[(i + 1) % c]);
        return glm::dot(n, eye - w[0]) > 0;
    };
    return front(e.f0) != front(e.f1);
}

}  // namespace

TEST(EdgeFinder, WorldSilhouettesOfTransformedObjectsEqualBruteForce) {
    Scene scene = primitives();
    Discretization disc(scene);
    EdgeFinder finder(disc);
    ASSERT_EQ(finder.objectCount(), 3);
    std::mt19937 rng(5);
    std::uniform_real_distribution<double> u(-2, 2);
    for (int i = 0; i < 20; ++i) {
        Vec3 eye(u(rng), std::abs(u(rng)) + 0.05, u(rng));
        std::set<std::pair<int, int>> got, expected;
        for (const WorldEdge& w : finder.findSilhouettes(eye)) {
            EXPECT_EQ(w.kind, EdgeKind::Silhouette);
            got.insert({w.object, w.edge});
            const EdgeMesh& mesh = finder.tree(w.object).mesh();
            const MeshEdge& e = mesh.edges()[w.edge];
            Mat4 m = scene.objects[w.object].transform.worldFromObject();
            EXPECT_LT(glm::length(w.a - apply(m, mesh.positions()[e.v0])), 1e-12);
        }
        for (int o = 0; o < 3; ++o) {
            const EdgeMesh& mesh = finder.tree(o).mesh();
            Mat4 m = scene.objects[o].transform.worldFromObject();
            for (int e = 0; e < static_cast<int>(mesh.edges().size()); ++e)
                if (worldSilhouette(mesh, m, e, eye)) expected.insert({o, e});
        }
        EXPECT_EQ(got, expected) << "eye " << i;
    }
}

TEST(EdgeFinder, SharpEdgesFacingTheEye) {
    Scene scene = primitives();
    Discretization disc(scene);
    EdgeFinder finder(disc);
    std::vector<WorldEdge> all = finder.findSharpEdges();
    // Box: 12 edges of sharp segments; the floor's boundary; the sphere none.
    int box = 0, sphere = 0, floor = 0;
    for (const WorldEdge& w : all) (w.object == 0 ? box : w.object == 1 ? sphere : floor)++;
    EXPECT_GT(box, 0);
    EXPECT_EQ(sphere, 0);
    EXPECT_EQ(floor, 4 * 30);
    // From far along the box's +x side only edges touching a visible face remain: fewer.
    Vec3 eye = apply(scene.objects[0].transform.worldFromObject(), Vec3(50, 0, 0));
    std::vector<WorldEdge> facing = finder.findSharpEdges(eye);
    int boxFacing = 0;
    for (const WorldEdge& w : facing) boxFacing += w.object == 0;
    EXPECT_GT(boxFacing, 0);
    EXPECT_LT(boxFacing, box);
    // Exactly the 4 edges around the +x face (plus none else): their total length.
    double length = 0;
    for (const WorldEdge& w : facing)
        if (w.object == 0) length += glm::length(w.b - w.a);
    EXPECT_NEAR(length, 2 * (0.4 + 0.5), 1e-9);
}

TEST(EdgeFinder, MovedObjectKeepsItsTreeAndMovesItsEdges) {
    Scene scene = primitives();
    Discretization disc(scene);
    EdgeFinder finder(disc);
    const EdgeTree* before = &finder.tree(0);
    Vec3 eye(0.3, 2.0, 1.5);
    std::vector<WorldEdge> a = finder.findSilhouettes(eye);
    Transform t = scene.objects[0].transform;
    Vec3 by(0.2, 0.0, -0.1);
    t.translate += by;
    finder.notifyObjectMoved(0, t.worldFromObject());
    EXPECT_EQ(&finder.tree(0), before);
    // Moving eye and object together leaves the object's silhouettes in place, shifted.
    std::vector<WorldEdge> b = finder.findSilhouettes(eye + by);
    std::vector<WorldEdge> boxA, boxB;
    for (const WorldEdge& w : a)
        if (w.object == 0) boxA.push_back(w);
    for (const WorldEdge& w : b)
        if (w.object == 0) boxB.push_back(w);
    ASSERT_EQ(boxA.size(), boxB.size());
    for (std::size_t i = 0; i < boxA.size(); ++i) {
        EXPECT_EQ(boxA[i].edge, boxB[i].edge);
        EXPECT_LT(glm::length(boxA[i].a + by - boxB[i].a), 1e-9);
    }
    // A new version of the object in the discretization shares the tree.
    Discretization& d = disc;
    SceneObject moved = scene.objects[0];
    moved.transform = t;
    int version = d.addObject(scene, moved);
    d.setAlive(0, false);
    finder.syncWith(d);
    EXPECT_EQ(&finder.tree(version), before);
    std::size_t ofVersion = 0, ofDead = 0;
    for (const WorldEdge& w : finder.findSilhouettes(eye + by)) {
        ofVersion += w.object == version;
        ofDead += w.object == 0;
    }
    EXPECT_EQ(ofVersion, boxB.size());
    EXPECT_EQ(ofDead, 0u);
}

namespace {

/// a and b equal field by field, positions bit for bit.
::testing::AssertionResult sameEdges(const std::vector<WorldEdge>& a,
                                     const std::vector<WorldEdge>& b) {
    if (a.size() != b.size())
        return ::testing::AssertionFailure() << a.size() << " vs " << b.size() << " edges";
    for (std::size_t k = 0; k < a.size(); ++k) {
        const WorldEdge &x = a[k], &y = b[k];
        if (x.a != y.a || x.b != y.b || x.kind != y.kind || x.object != y.object ||
            x.edge != y.edge || x.light != y.light || x.blocker != y.blocker)
            return ::testing::AssertionFailure()
                   << "edge " << k << ": " << x.toString() << " vs " << y.toString();
    }
    return ::testing::AssertionSuccess();
}

std::vector<WorldEdge> concatenated(const std::vector<std::vector<WorldEdge>>& lists) {
    std::vector<WorldEdge> out;
    for (const auto& list : lists) out.insert(out.end(), list.begin(), list.end());
    return out;
}

}  // namespace

TEST(EdgeFinder, PerObjectParallelSilhouettesAndSharpEdgesEqualTheSerialLists) {
    // Many objects (copies of the primitives, moved), one of them not alive.
    Scene scene = primitives();
    const std::size_t base = scene.objects.size();
    for (int copy = 1; copy < 6; ++copy)
        for (std::size_t o = 0; o < base; ++o) {
            SceneObject obj = scene.objects[o];
            obj.id.append("-").append(std::to_string(copy));
            obj.transform.translate += Vec3(0.7 * copy, 0.1 * copy, -0.4 * copy);
            obj.transform.rotateDeg += Vec3(7.0 * copy, 11.0 * copy, 0.0);
            scene.objects.push_back(obj);
        }
    Discretization disc(scene);
    EdgeFinder finder(disc);
    ASSERT_EQ(finder.objectCount(), static_cast<int>(scene.objects.size()));
    finder.setObjectAlive(4, false);
    std::mt19937 rng(8);
    std::uniform_real_distribution<double> u(-3, 3);
    // Lists reused across calls (stale content from a previous eye and an oversized list).
    std::vector<std::vector<WorldEdge>> silParallel(40), silSerial, sharpParallel, sharpSerial;
    silParallel[3].resize(7);
    int silhouettes = 0, sharp = 0;
    for (int i = 0; i < 12; ++i) {
        const Vec3 eye(u(rng), std::abs(u(rng)) + 0.05, u(rng));
        finder.findSilhouettes(eye, silParallel);
        finder.findSilhouettes(eye, silSerial, false);
        finder.findSharpEdges(eye, sharpParallel);
        finder.findSharpEdges(eye, sharpSerial, false);
        ASSERT_EQ(silParallel.size(), scene.objects.size());
        EXPECT_TRUE(silParallel[4].empty() && sharpParallel[4].empty()) << "not alive";
        for (std::size_t o = 0; o < silParallel.size(); ++o)
            for (const WorldEdge& w : silParallel[o]) EXPECT_EQ(w.object, static_cast<int>(o));
        const std::vector<WorldEdge> reference = finder.findSilhouettes(eye);
        EXPECT_TRUE(sameEdges(concatenated(silParallel), reference)) << "eye " << i;
        EXPECT_TRUE(sameEdges(concatenated(silSerial), reference)) << "eye " << i;
        const std::vector<WorldEdge> sharpReference = finder.findSharpEdges(eye);
        EXPECT_TRUE(sameEdges(concatenated(sharpParallel), sharpReference)) << "eye " << i;
        EXPECT_TRUE(sameEdges(concatenated(sharpSerial), sharpReference)) << "eye " << i;
        silhouettes += static_cast<int>(reference.size());
        sharp += static_cast<int>(sharpReference.size());
    }
    EXPECT_GT(silhouettes, 1000);
    EXPECT_GT(sharp, 100);
}
