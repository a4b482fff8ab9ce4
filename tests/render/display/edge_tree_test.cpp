// Edge tree (Bala et al. 2003 §6.4) against brute force over every edge (eq. 1), sharp
// edges (§6.2) of boxes and spheres, and the silhouette time on ~1M triangles.
#include "render/display/edge_tree.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <map>
#include <random>
#include <set>

#include "edit/io/mesh_io.h"
#include "solver/discretization.h"

using namespace penumbra;

namespace {

std::string meshPath(const std::string& name) {
    return std::string(PENUMBRA_SOURCE_DIR) + "/scenes/meshes/cgal/" + name;
}

using VertexPair = std::pair<int, int>;
VertexPair sortedPair(int a, int b) { return {std::min(a, b), std::max(a, b)}; }

/// Independent brute force: adjacency from the triangle list itself, eq. 1 with unnormalised
/// cross-product normals and V from the face's first vertex. Boundary edges are silhouettes;
/// non-manifold edges (3+ faces) are listed in `skip`.
struct BruteForce {
    std::map<VertexPair, std::vector<int>> faces;
    const TriMesh& mesh;
    explicit BruteForce(const TriMesh& m) : mesh(m) {
        for (int t = 0; t < static_cast<int>(m.triangles.size()); ++t)
            for (int k = 0; k < 3; ++k)
                faces[sortedPair(m.triangles[t][k], m.triangles[t][(k + 1) % 3])].push_back(t);
    }
    bool front(int t, const Vec3& eye) const {
        const auto& tri = mesh.triangles[t];
        const Vec3 &a = mesh.positions[tri[0]], &b = mesh.positions[tri[1]],
                   &c = mesh.positions[tri[2]];
        return glm::dot(glm::cross(b - a, c - a), eye - a) > 0;
    }
    std::set<VertexPair> silhouettes(const Vec3& eye, std::set<VertexPair>* skip) const {
        std::set<VertexPair> out;
        for (const auto& [pair, fs] : faces) {
            if (fs.size() == 1)
                out.insert(pair);
            else if (fs.size() == 2) {
                if (front(fs[0], eye) != front(fs[1], eye)) out.insert(pair);
            } else if (skip)
                skip->insert(pair);
        }
        return out;
    }
};

std::set<VertexPair> asPairs(const EdgeMesh& mesh, const std::vector<int>& ids,
                             const std::set<VertexPair>& skip) {
    std::set<VertexPair> out;
    for (int id : ids) {
        const MeshEdge& e = mesh.edges()[id];
        VertexPair p = sortedPair(mesh.sourceVertex()[e.v0], mesh.sourceVertex()[e.v1]);
        if (!skip.count(p)) out.insert(p);
    }
    return out;
}

/// Random eye points: half inside the bounds, half up to two diagonals outside.
std::vector<Vec3> randomEyes(const Box3& b, int count, unsigned seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> u(0, 1);
    Vec3 size = b.hi - b.lo;
    double diag = glm::length(size);
    std::vector<Vec3> eyes;
    for (int i = 0; i < count; ++i) {
        if (i % 2 == 0) {
            eyes.push_back(b.lo + Vec3(u(rng), u(rng), u(rng)) * size);
        } else {
            Vec3 d(u(rng) - 0.5, u(rng) - 0.5, u(rng) - 0.5);
            eyes.push_back(b.centre() + glm::normalize(d) * diag * (0.6 + 1.5 * u(rng)));
        }
    }
    return eyes;
}

void checkAgainstBruteForce(const std::string& file) {
    std::string path = meshPath(file);
    if (!std::filesystem::exists(path)) GTEST_SKIP() << path << " absent (scripts/setup.sh)";
    TriMesh tri = loadMeshFile(path);
    auto mesh = std::make_shared<EdgeMesh>(EdgeMesh::fromTriMesh(tri));
    EdgeTree tree(mesh);
    BruteForce brute(tri);
    int eyeIndex = 0;
    for (const Vec3& eye : randomEyes(mesh->bounds(), 24, 7)) {
        std::set<VertexPair> skip;
        std::set<VertexPair> expected = brute.silhouettes(eye, &skip);
        std::vector<int> ids;
        tree.findSilhouettes(eye, ids);
        // With end points: the same ids in the same order, each with its edge's two input
        // vertices (looked up through the triangle file's own positions).
        std::vector<int> idsWithEnds;
        std::vector<Vec3> ends;
        tree.findSilhouettes(eye, idsWithEnds, ends);
        EXPECT_EQ(idsWithEnds, ids);
        ASSERT_EQ(ends.size(), 2 * idsWithEnds.size());
        for (std::size_t k = 0; k < idsWithEnds.size(); ++k) {
            const MeshEdge& e = mesh->edges()[idsWithEnds[k]];
            ASSERT_EQ(ends[2 * k], tri.positions[mesh->sourceVertex()[e.v0]]) << "edge " << k;
            ASSERT_EQ(ends[2 * k + 1], tri.positions[mesh->sourceVertex()[e.v1]]) << "edge " << k;
        }
        std::set<VertexPair> got = asPairs(*mesh, ids, skip);
        EXPECT_EQ(ids.size(), std::set<int>(ids.begin(), ids.end()).size()) << "duplicates";
        EXPECT_EQ(got, expected) << file << " eye " << eyeIndex << " (" << eye.x << ' ' << eye.y
                                 << ' ' << eye.z << "): tree " << got.size() << " vs brute "
                                 << expected.size() << "; " << tree.toString();
        EXPECT_GT(expected.size(), 0u);
        // The tree's own brute force (EdgeMesh::isSilhouette) agrees too.
        std::vector<int> all;
        for (int e = 0; e < static_cast<int>(mesh->edges().size()); ++e)
            if (mesh->isSilhouette(e, eye)) all.push_back(e);
        std::sort(all.begin(), all.end());
        std::sort(ids.begin(), ids.end());
        EXPECT_EQ(ids, all);
        ++eyeIndex;
    }
}

/// The one material of these scenes.
const std::string kMaterial = "m";

SceneObject primitive(ShapeType type, Vec3 size, double radius = 0.5, int segments = 24) {
    SceneObject o;
    o.id = "p";
    o.shape.type = type;
    o.shape.size = size;
    o.shape.radius = radius;
    o.shape.segments = segments;
    o.material = kMaterial;
    return o;
}

Scene sceneWith(const SceneObject& object) {
    Scene s;
    s.settings.patchSize = 0.25;
    s.settings.elementSize = 0.1;
    s.materials.push_back({"m", Material{}});
    s.objects.push_back(object);
    return s;
}

}  // namespace

TEST(EdgeTree, ArmadilloSilhouettesEqualBruteForce) { checkAgainstBruteForce("armadillo.off"); }
TEST(EdgeTree, BunnySilhouettesEqualBruteForce) { checkAgainstBruteForce("bunny00.off"); }

TEST(EdgeTree, PolygonCandidatesContainEverySilhouetteFromItsVertices) {
    std::string path = meshPath("bunny00.off");
    if (!std::filesystem::exists(path)) GTEST_SKIP() << path << " absent";
    auto mesh = std::make_shared<EdgeMesh>(EdgeMesh::fromTriMesh(loadMeshFile(path)));
    EdgeTree tree(mesh);
    Box3 b = mesh->bounds();
    double s = glm::length(b.hi - b.lo);
    Vec3 c = b.centre() + Vec3(0.3, 1.2, 0.4) * s;
    std::vector<Vec3> quad = {c + Vec3(-0.1, 0, -0.1) * s, c + Vec3(0.1, 0, -0.1) * s,
                              c + Vec3(0.1, 0, 0.1) * s, c + Vec3(-0.1, 0, 0.1) * s};
    std::vector<int> cand;
    tree.findSilhouetteCandidates(quad, cand);
    std::set<int> candidates(cand.begin(), cand.end());
    // Brute force: every edge that is a silhouette from some light vertex must be a candidate,
    // and every candidate has mixed face orientations over the vertices.
    int fromVertices = 0;
    for (int e = 0; e < static_cast<int>(mesh->edges().size()); ++e) {
        bool any = false;
        for (const Vec3& v : quad) any = any || mesh->isSilhouette(e, v);
        if (any) {
            ++fromVertices;
            EXPECT_TRUE(candidates.count(e)) << "edge " << e;
        }
    }
    EXPECT_GE(candidates.size(), static_cast<std::size_t>(fromVertices));
    EXPECT_LT(candidates.size(), mesh->edges().size() / 4) << "candidates are a small part";
}

TEST(EdgeMesh, BoxSharpEdgesAreItsTwelveEdges) {
    // A gridded box from the Discretization: sides welded, sharp segments cover the 12 edges.
    Vec3 size(1.0, 0.6, 0.8);
    Discretization disc(sceneWith(primitive(ShapeType::Box, size)));
    EdgeMesh mesh = EdgeMesh::fromElementMesh(disc.objects()[0].mesh);
    EXPECT_TRUE(mesh.closed()) << mesh.toString();
    Vec3 h = size / 2.0;
    std::map<std::tuple<int, int, int>, double> covered;  // line -> total sharp length
    for (int id : mesh.sharpEdges()) {
        const MeshEdge& e = mesh.edges()[id];
        Vec3 a = mesh.positions()[e.v0], b = mesh.positions()[e.v1];
        // On a box edge: two coordinates at ±h, the third varying.
        int sx = std::abs(std::abs(a.x) - h.x) < 1e-9 && std::abs(std::abs(b.x) - h.x) < 1e-9 &&
                         a.x == b.x
                     ? (a.x > 0 ? 1 : -1)
                     : 0;
        int sy = std::abs(std::abs(a.y) - h.y) < 1e-9 && std::abs(std::abs(b.y) - h.y) < 1e-9 &&
                         a.y == b.y
                     ? (a.y > 0 ? 1 : -1)
                     : 0;
        int sz = std::abs(std::abs(a.z) - h.z) < 1e-9 && std::abs(std::abs(b.z) - h.z) < 1e-9 &&
                         a.z == b.z
                     ? (a.z > 0 ? 1 : -1)
                     : 0;
        int fixed = (sx != 0) + (sy != 0) + (sz != 0);
        ASSERT_EQ(fixed, 2) << "sharp edge off the box edges: (" << a.x << ' ' << a.y << ' ' << a.z
                            << ") - (" << b.x << ' ' << b.y << ' ' << b.z << ")";
        covered[{sx, sy, sz}] += glm::length(b - a);
    }
    ASSERT_EQ(covered.size(), 12u);
    for (const auto& [line, length] : covered) {
        auto [sx, sy, sz] = line;
        double expected = sx == 0 ? size.x : sy == 0 ? size.y : size.z;
        EXPECT_NEAR(length, expected, 1e-9);
    }
    // A 12-triangle box: exactly 12 sharp edges, the face diagonals are flat.
    TriMesh box;
    for (int i = 0; i < 8; ++i)
        box.positions.push_back({(i & 1) ? 1.0 : -1.0, (i & 2) ? 1.0 : -1.0, (i & 4) ? 1.0 : -1.0});
    box.triangles = {{0, 2, 3}, {0, 3, 1}, {4, 5, 7}, {4, 7, 6}, {0, 1, 5}, {0, 5, 4},
                     {2, 6, 7}, {2, 7, 3}, {0, 4, 6}, {0, 6, 2}, {1, 3, 7}, {1, 7, 5}};
    EdgeMesh simple = EdgeMesh::fromTriMesh(box);
    EXPECT_EQ(simple.edges().size(), 18u);
    EXPECT_EQ(simple.sharpEdges().size(), 12u) << simple.toString();
    EXPECT_TRUE(simple.closed());
}

TEST(EdgeMesh, SphereHasNoSharpEdgesAt85Degrees) {
    Discretization disc(sceneWith(primitive(ShapeType::Sphere, Vec3(1.0), 0.5, 24)));
    EdgeMesh mesh = EdgeMesh::fromElementMesh(disc.objects()[0].mesh);
    EXPECT_TRUE(mesh.closed()) << mesh.toString();
    EXPECT_EQ(mesh.sharpEdges().size(), 0u) << mesh.toString();
    // At a 3° cutoff the ~11° steps of the gridded sphere are sharp.
    EdgeMesh strict = EdgeMesh::fromElementMesh(disc.objects()[0].mesh, 3.0);
    EXPECT_GT(strict.sharpEdges().size(), 0u);
    // A cylinder's rims are sharp (90°), its sides are not.
    Discretization cyl(sceneWith(primitive(ShapeType::Cylinder, Vec3(1.0), 0.3, 24)));
    EdgeMesh cm = EdgeMesh::fromElementMesh(cyl.objects()[0].mesh);
    EXPECT_TRUE(cm.closed()) << cm.toString();
    for (int id : cm.sharpEdges()) {
        const MeshEdge& e = cm.edges()[id];
        EXPECT_NEAR(std::abs(cm.positions()[e.v0].y), 0.5, 1e-9);
        EXPECT_NEAR(std::abs(cm.positions()[e.v1].y), 0.5, 1e-9);
    }
    EXPECT_EQ(cm.sharpEdges().size(), 48u);
}

TEST(EdgeTree, ManyArmadillosSilhouettesEqualBruteForce) {
    // Four randomly rotated copies of the armadillo (≈ 200k triangles): the tree's
    // silhouettes equal a brute force over every edge. The timings printed are for reading
    // only; the 1M-triangle figure is `penumbra bench display`'s (armadillo-field).
    std::string path = meshPath("armadillo.off");
    if (!std::filesystem::exists(path)) GTEST_SKIP() << path << " absent";
    TriMesh one = loadMeshFile(path);
    Box3 b;
    for (const Vec3& p : one.positions) b.extend(p);
    double s = glm::length(b.hi - b.lo);
    TriMesh many;
    std::mt19937 rng(3);
    std::uniform_real_distribution<double> u(0, 1);
    for (int copy = 0; copy < 4; ++copy) {
        Transform t;
        t.rotateDeg = Vec3(360 * u(rng), 360 * u(rng), 360 * u(rng));
        t.translate = Vec3((copy % 5) * s, (copy / 5) * s, 0.0);
        Mat4 m = t.worldFromObject();
        int base = static_cast<int>(many.positions.size());
        for (const Vec3& p : one.positions)
            many.positions.push_back(Vec3(m * glm::dvec4(p - b.centre(), 1.0)));
        for (auto tri : one.triangles)
            many.triangles.push_back({tri[0] + base, tri[1] + base, tri[2] + base});
    }
    auto t0 = std::chrono::steady_clock::now();
    auto mesh = std::make_shared<EdgeMesh>(EdgeMesh::fromTriMesh(many));
    auto t1 = std::chrono::steady_clock::now();
    EdgeTree tree(mesh);
    auto t2 = std::chrono::steady_clock::now();
    Box3 all = mesh->bounds();
    Vec3 centre = all.centre();
    double diag = glm::length(all.hi - all.lo);
    std::vector<double> ms;
    std::vector<int> ids;
    EdgeTreeStats stats;
    for (int i = 0; i < 8; ++i) {
        double a = i * 0.7;
        Vec3 eye = centre + Vec3(std::cos(a), 0.3, std::sin(a)) * diag;
        ids.clear();
        auto q0 = std::chrono::steady_clock::now();
        tree.findSilhouettes(eye, ids, &stats);
        auto q1 = std::chrono::steady_clock::now();
        ms.push_back(std::chrono::duration<double, std::milli>(q1 - q0).count());
        if (i == 0) {
            std::size_t brute = 0;
            for (int e = 0; e < static_cast<int>(mesh->edges().size()); ++e)
                brute += mesh->isSilhouette(e, eye);
            EXPECT_EQ(ids.size(), brute);
        }
    }
    std::sort(ms.begin(), ms.end());
    double bruteMs = 0;
    {
        auto q0 = std::chrono::steady_clock::now();
        std::size_t n = 0;
        Vec3 eye = centre + Vec3(1, 0.3, 0) * diag;
        for (int e = 0; e < static_cast<int>(mesh->edges().size()); ++e)
            n += mesh->isSilhouette(e, eye);
        auto q1 = std::chrono::steady_clock::now();
        bruteMs = std::chrono::duration<double, std::milli>(q1 - q0).count();
        EXPECT_GT(n, 0u);
    }
    std::printf(
        "[ measure  ] %zu triangles, %zu edges: mesh %.0f ms, tree %.0f ms (%d nodes); "
        "silhouettes median %.2f ms (min %.2f, max %.2f), %zu edges, %.0f nodes and %.0f edge "
        "tests per query; brute force %.1f ms\n",
        many.triangles.size(), mesh->edges().size(),
        std::chrono::duration<double, std::milli>(t1 - t0).count(),
        std::chrono::duration<double, std::milli>(t2 - t1).count(), tree.nodeCount(), ms[4],
        ms.front(), ms.back(), ids.size(), stats.nodesVisited / 8.0, stats.edgesTested / 8.0,
        bruteMs);
    RecordProperty("silhouette_ms_median", std::to_string(ms[4]));
}
