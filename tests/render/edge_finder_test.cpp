// EdgeFinder over a Discretization: world-space silhouettes of transformed objects against a
// world-space brute force, forward-facing sharp edges, moves without rebuilding trees.
#include "render/edge_finder.h"

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
