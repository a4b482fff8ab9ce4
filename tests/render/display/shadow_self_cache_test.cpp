// The edge finder's reuse across receiver moves (Bala et al. 2003 §6.5 "moving objects"): each
// (light, blocker) pair keeps what its blocker does to its own events (hidden by the blocker
// alone, or the blocker's crossings) and each event keeps its near receivers. Real meshes
// (cow, dino, bull) under a square area light with slats between them and the light; the
// slats and the meshes move in turn, and after every move the incremental result must equal a
// fresh finder's and the exhaustive reference's (every receiver intersected whole).
#include <gtest/gtest.h>

#include <filesystem>
#include <glm/gtc/matrix_transform.hpp>
#include <memory>
#include <string>
#include <vector>

#include "edit/io/mesh_io.h"
#include "render/display/edge_finder.h"
#include "shadow_test_support.h"

using namespace penumbra;

namespace {

/// A floor of n×n quads, size×size, at y = 0, facing up.
std::shared_ptr<const EdgeMesh> floorMesh(double size, int n) {
    std::vector<Vec3> p;
    std::vector<std::vector<int>> f;
    for (int i = 0; i <= n; ++i)
        for (int j = 0; j <= n; ++j)
            p.push_back({size * (double(j) / n - 0.5), 0, size * (double(i) / n - 0.5)});
    for (int i = 0; i < n; ++i)
        for (int j = 0; j < n; ++j) {
            int a = i * (n + 1) + j;
            f.push_back({a, a + n + 1, a + n + 2, a + 1});  // counter-clockwise seen from +y
        }
    return std::make_shared<const EdgeMesh>(p, f);
}

/// A closed box of half extents h, centred at the origin, faces outward.
std::shared_ptr<const EdgeMesh> boxMesh(const Vec3& h) {
    std::vector<Vec3> p;
    for (int i = 0; i < 8; ++i)
        p.push_back({(i & 1) ? h.x : -h.x, (i & 2) ? h.y : -h.y, (i & 4) ? h.z : -h.z});
    std::vector<std::vector<int>> f = {{0, 4, 6, 2}, {1, 3, 7, 5}, {0, 1, 5, 4},
                                       {2, 6, 7, 3}, {0, 2, 3, 1}, {4, 5, 7, 6}};
    return std::make_shared<const EdgeMesh>(p, f, 85.0, true);
}

Mat4 translation(const Vec3& t) { return glm::translate(Mat4(1.0), t); }

/// A mesh file scaled to `height` and standing on the floor at `at` (x, z).
Mat4 standing(const EdgeMesh& mesh, double height, const Vec3& at) {
    const Box3& b = mesh.bounds();
    double s = height / (b.hi.y - b.lo.y);
    Vec3 base(0.5 * (b.lo.x + b.hi.x), b.lo.y, 0.5 * (b.lo.z + b.hi.z));
    return glm::translate(Mat4(1.0), at) * glm::scale(Mat4(1.0), Vec3(s)) *
           glm::translate(Mat4(1.0), -base);
}

struct Field {
    std::vector<std::shared_ptr<const EdgeMesh>> meshes;
    std::vector<Mat4> transforms;
    Light light;
    void addTo(EdgeFinder& finder) const {
        for (std::size_t i = 0; i < meshes.size(); ++i) finder.addObject(meshes[i], transforms[i]);
        finder.addLight(light);
    }
};

}  // namespace

TEST(ShadowSelfCache, ReceiverMovesEqualFreshAndExhaustive) {
    const std::string dir = std::string(PENUMBRA_SOURCE_DIR) + "/scenes/meshes/cgal/";
    for (const char* f : {"cow.off", "dino.off", "bull.off"})
        if (!std::filesystem::exists(dir + f)) GTEST_SKIP() << dir + f << " absent";
    Field field;
    field.meshes.push_back(floorMesh(4, 16));
    field.transforms.push_back(Mat4(1.0));
    const std::vector<Vec3> at = {{-0.8, 0, -0.3}, {0.1, 0, 0.4}, {0.9, 0, -0.2}};
    int k = 0;
    for (const char* f : {"cow.off", "dino.off", "bull.off"}) {
        auto mesh = std::make_shared<const EdgeMesh>(EdgeMesh::fromTriMesh(loadMeshFile(dir + f)));
        field.transforms.push_back(standing(*mesh, 0.7, at[k++]));
        field.meshes.push_back(mesh);
    }
    const int firstSlat = static_cast<int>(field.meshes.size());
    for (double z : {-0.35, 0.0, 0.35}) {
        field.meshes.push_back(boxMesh({1.2, 0.02, 0.06}));
        field.transforms.push_back(translation({0, 1.4, z}));
    }
    const Vec3 c(0.1, 2.2, 0.05);
    field.light.polygon = {c + Vec3(-0.3, 0, -0.3), c + Vec3(0.3, 0, -0.3), c + Vec3(0.3, 0, 0.3),
                           c + Vec3(-0.3, 0, 0.3)};

    EdgeFinderOptions exhaustive;
    exhaustive.exhaustiveShadows = true;
    EdgeFinder fast, ref(exhaustive);
    field.addTo(fast);
    field.addTo(ref);
    std::vector<WorldEdge> a = fast.findShadowEdges(), b = ref.findShadowEdges();
    ASSERT_GT(a.size(), 200u);
    EXPECT_GT(test::expectSameShadowLines(a, b, 1e-6, "initial"), 100);
    // The meshes hide some of their own events whole (convex silhouettes behind a fold).
    EXPECT_GT(fast.stats().eventsSelfHidden, 0) << fast.stats().toString();

    // Moves: slats slide (sometimes out of every event and back), a slat is removed and
    // restored, a mesh moves (its own pair is rebuilt, the others reuse their blockers). Moves
    // 1–2: slat 1 enters the shadow of slat 0 (behind what decided the events slat 0 hides, so
    // they stay as they are), then slat 0 leaves and slat 1 hides them: their near receivers
    // must follow slat 1's earlier move.
    struct Move {
        int object;
        Vec3 to;
        int alive = -1;  ///< 0 remove, 1 restore, -1 leave
    };
    const std::vector<Move> moves = {
        {firstSlat, {0.1, 1.4, -0.2}},
        {firstSlat + 1, {0.1, 1.1, -0.19}},
        {firstSlat, {0.0, 1.4, -3.0}},
        {firstSlat + 2, {0.2, 1.35, 0.3}, 0},
        {firstSlat, {0.05, 1.45, -0.3}},
        {firstSlat + 2, {0.2, 1.35, 0.3}, 1},
        {2, {0.15, 0, 0.5}},
        {firstSlat + 1, {-0.3, 1.5, 0.05}},
        {firstSlat + 1, {0.0, 1.4, 0.0}},
    };
    long long reused = 0;
    for (std::size_t m = 0; m < moves.size(); ++m) {
        const Move& mv = moves[m];
        Mat4 t = mv.object < firstSlat ? standing(*field.meshes[mv.object], 0.7, mv.to)
                                       : translation(mv.to);
        field.transforms[mv.object] = t;
        fast.resetStats();
        for (EdgeFinder* f : {&fast, &ref}) {
            f->notifyObjectMoved(mv.object, t);
            if (mv.alive >= 0) f->setObjectAlive(mv.object, mv.alive == 1);
        }
        a = fast.findShadowEdges();
        b = ref.findShadowEdges();
        reused += fast.stats().selfReused;
        const std::string what = "move " + std::to_string(m);
        test::expectSameShadowLines(a, b, 1e-6, (what + " vs exhaustive").c_str());
        // A fresh finder on the same positions.
        EdgeFinder fresh;
        field.addTo(fresh);
        for (std::size_t p = 0; p <= m; ++p)
            if (moves[p].alive >= 0) fresh.setObjectAlive(moves[p].object, moves[p].alive == 1);
        std::vector<WorldEdge> scratch = fresh.findShadowEdges();
        test::expectSameShadowLines(a, scratch, 1e-6, (what + " vs fresh").c_str());
        // Only the moved slat's own pair has its events rebuilt.
        if (mv.object >= firstSlat) {
            EXPECT_LE(fast.stats().eventRecomputations, 1);
        }
        std::printf("[ measure  ] %s: %s; fresh %s\n", what.c_str(),
                    fast.stats().toString().c_str(), fresh.stats().toString().c_str());
    }
    // Receiver moves recomputed events with the blockers' own crossings kept.
    EXPECT_GT(reused, 0);
}
