// Shadow events and shadow edges (Bala et al. 2003 §6.3–6.5, appendix A): point-light events
// against brute-force silhouettes, analytic shadow lines of a square blocker over a plane for
// point and square area lights, incremental recomputation after a move.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <ctime>
#include <filesystem>
#include <random>
#include <set>

#include "edit/io/mesh_io.h"
#include "edit/io/scene_io.h"
#include "render/display/edge_finder.h"
#include "render/display/shadow_events.h"
#include "shadow_test_support.h"
#include "test_scenes.h"

using namespace penumbra;
using test::distanceToSegment;
using test::expectSameShadowLines;

namespace {

Vec3 apply(const Mat4& m, const Vec3& p) { return Vec3(m * glm::dvec4(p, 1.0)); }

/// Floor 4×4 at y = 0, facing up; square blockers facing up at height 0.5.
Scene blockerScene(const std::vector<Vec3>& blockerCentres, double blockerSize = 0.4) {
    Scene s;
    s.settings.patchSize = 0.5;
    s.settings.elementSize = 0.1;
    test::addMaterial(s, "white", Rgb(0.5));
    s.objects.push_back(test::makeQuad("floor", 4, 4, "white", {0, 0, 0}));
    int i = 0;
    for (const Vec3& c : blockerCentres)
        s.objects.push_back(
            test::makeQuad("blocker" + std::to_string(i++), blockerSize, blockerSize, "white", c));
    return s;
}

/// Total length of the union of [lo, hi] intervals that lies inside [from, to].
double coveredLength(std::vector<std::pair<double, double>> iv, double from, double to) {
    std::sort(iv.begin(), iv.end());
    double covered = 0, reach = from;
    for (auto [lo, hi] : iv) {
        lo = std::max(lo, reach);
        hi = std::min(hi, to);
        if (hi > lo) {
            covered += hi - lo;
            reach = hi;
        }
    }
    return covered;
}

}  // namespace

TEST(ShadowEvents, PointLightEventsAreSilhouettesFromTheLight) {
    std::string path = std::string(PENUMBRA_SOURCE_DIR) + "/scenes/meshes/cgal/bunny00.off";
    if (!std::filesystem::exists(path)) GTEST_SKIP() << path << " absent";
    TriMesh tri = loadMeshFile(path);
    auto mesh = std::make_shared<EdgeMesh>(EdgeMesh::fromTriMesh(tri));
    EdgeTree tree(mesh);
    Transform t;
    t.translate = Vec3(1.0, 0.3, -2.0);
    t.rotateDeg = Vec3(20, 35, -10);
    t.scale = Vec3(3.0, 3.0, 3.0);
    Mat4 M = t.worldFromObject();
    // Brute force in world space on the transformed triangles (eq. 1, cross-product normals).
    std::vector<Vec3> world;
    for (const Vec3& p : mesh->positions()) world.push_back(apply(M, p));
    Box3 wb = mesh->bounds().transformed(M);
    std::mt19937 rng(11);
    std::uniform_real_distribution<double> u(-1, 1);
    for (int i = 0; i < 20; ++i) {
        Vec3 light = wb.centre() + Vec3(u(rng), u(rng), u(rng)) * (i % 2 ? 0.5 : 2.0) *
                                       glm::length(wb.hi - wb.lo);
        std::set<int> expected;
        for (int e = 0; e < static_cast<int>(mesh->edges().size()); ++e) {
            const MeshEdge& me = mesh->edges()[e];
            if (me.boundary()) {
                expected.insert(e);
                continue;
            }
            auto front = [&](int f) {
                int b = mesh->faceStart()[f];
                const Vec3& a = world[mesh->faceVertices()[b]];
                Vec3 n = glm::cross(world[mesh->faceVertices()[b + 1]] - a,
                                    world[mesh->faceVertices()[b + 2]] - a);
                return glm::dot(n, light - a) > 0;
            };
            if (front(me.f0) != front(me.f1)) expected.insert(e);
        }
        std::vector<ShadowEvent> events;
        findShadowEvents(tree, M, glm::inverse(M), Light{{light}, -1}, events);
        std::set<int> got;
        for (const ShadowEvent& ev : events) {
            EXPECT_EQ(ev.kind, ShadowKind::Hard);
            got.insert(ev.blockerFeature);
            // World-space event geometry: the light and the edge's world endpoints.
            const MeshEdge& me = mesh->edges()[ev.blockerFeature];
            EXPECT_NEAR(glm::length(ev.q0 - world[me.v0]), 0, 1e-9);
            EXPECT_NEAR(glm::length(ev.p0 - light), 0, 1e-9);
        }
        EXPECT_EQ(got.size(), events.size());
        EXPECT_EQ(got, expected) << "light " << i << ": events " << got.size() << " vs brute "
                                 << expected.size();
    }
}

TEST(ShadowEdges, PointLightSquareShadowIsTheProjectedSquare) {
    Scene scene = blockerScene({{0, 0.5, 0}});
    Discretization disc(scene);
    EdgeFinder finder(disc);
    ASSERT_EQ(finder.lightCount(), 0);
    Vec3 L(0.13, 1.5, 0.07);
    finder.addLight(Light{{L}, -1});
    std::vector<WorldEdge> edges = finder.findShadowEdges();
    ASSERT_FALSE(edges.empty()) << finder.toString();
    // Analytic: the blocker's corners projected from the light onto y = 0.
    std::vector<Vec3> corners = test::quadCorners(scene.objects[1]);
    std::vector<Vec3> proj;
    for (const Vec3& c : corners) proj.push_back(L + (c - L) * (L.y / (L.y - c.y)));
    std::vector<double> covered(4, 0.0);
    for (const WorldEdge& e : edges) {
        EXPECT_EQ(e.kind, EdgeKind::Shadow);
        EXPECT_EQ(e.shadow, ShadowKind::Hard);
        EXPECT_EQ(e.penumbraA, 0.0) << "a point light casts no penumbra";
        EXPECT_EQ(e.penumbraB, 0.0);
        EXPECT_EQ(e.blocker, 1) << e.toString();
        EXPECT_EQ(e.object, 0) << e.toString();
        int side = -1;
        for (int k = 0; k < 4; ++k)
            if (distanceToSegment(e.a, proj[k], proj[(k + 1) % 4]) < 1e-9 &&
                distanceToSegment(e.b, proj[k], proj[(k + 1) % 4]) < 1e-9)
                side = k;
        ASSERT_GE(side, 0) << "off the projected square: " << e.toString();
        covered[side] += glm::length(e.b - e.a);
    }
    for (int k = 0; k < 4; ++k)
        EXPECT_NEAR(covered[k], glm::length(proj[(k + 1) % 4] - proj[k]), 1e-9) << "side " << k;
}

TEST(ShadowEdges, AreaLightUmbraAndPenumbraLines) {
    // Square light (half-size Lh, centre c at height h) over a square blocker (half-size B at
    // height b) over the floor: every line is the projection of a blocker edge through a
    // light corner. Light x = lx projects blocker edge x = ±B to x = s·(±B) + (1 − s)·lx,
    // s = h / (h − b); umbra lines come from the far light side, penumbra from the near side.
    // The light is a rectangle (half-sizes Lx, Lz), so a penumbra width measured along the
    // edge instead of across it would show.
    const double B = 0.2, b = 0.5, Lx = 0.3, Lz = 0.15, h = 1.5;
    const Vec3 c(0.05, h, -0.03);
    Scene scene = blockerScene({{0, b, 0}}, 2 * B);
    Discretization disc(scene);
    EdgeFinder finder(disc);
    Light light;
    light.polygon = {c + Vec3(-Lx, 0, -Lz), c + Vec3(-Lx, 0, Lz), c + Vec3(Lx, 0, Lz),
                     c + Vec3(Lx, 0, -Lz)};  // counter-clockwise seen from below
    finder.addLight(light);
    std::vector<WorldEdge> edges = finder.findShadowEdges();
    ASSERT_FALSE(edges.empty());
    const double s = h / (h - b);
    auto line = [&](double edge, double lightCoord) { return s * edge + (1 - s) * lightCoord; };
    // Per axis (0: x, 2: z): umbra lines at ±, penumbra lines at ±.
    struct Lines {
        double umbLo, umbHi, penLo, penHi;
    };
    Lines lx{line(-B, c.x - Lx), line(B, c.x + Lx), line(-B, c.x + Lx), line(B, c.x - Lx)};
    Lines lz{line(-B, c.z - Lz), line(B, c.z + Lz), line(-B, c.z + Lz), line(B, c.z - Lz)};
    ASSERT_LT(lx.umbLo, lx.umbHi);
    // Segments found on each analytic line, as intervals of the other coordinate.
    std::map<std::pair<int, int>, std::vector<std::pair<double, double>>> onLine;
    int umbra = 0, penumbra = 0;
    for (const WorldEdge& e : edges) {
        ASSERT_EQ(e.kind, EdgeKind::Shadow);
        ASSERT_NE(e.shadow, ShadowKind::Hard);
        EXPECT_EQ(e.object, 0) << e.toString();
        EXPECT_NEAR(e.a.y, 0, 1e-12);
        bool isUmbra = e.shadow == ShadowKind::Umbra;
        (isUmbra ? umbra : penumbra)++;
        // The penumbra between each umbra line and its penumbra line is (s − 1)·2L wide on
        // the floor, L the light's half-size across the line (similar triangles through the
        // blocker edge). The estimate is the light's extent across the event plane, shorter
        // by the cosine of the plane's tilt from the vertical: at most atan(0.55 / 1) = 28.8°
        // here (blocker edge at ±0.2 to light corners 0.35 across, 1 m above it), cos ≥ 0.876.
        const bool alongZ = std::abs(e.a.x - e.b.x) < 1e-9;  // a line x = const: across is x
        const double width = (s - 1) * 2 * (alongZ ? Lx : Lz);
        for (double w : {e.penumbraA, e.penumbraB}) {
            EXPECT_LE(w, width + 1e-9) << e.toString();
            EXPECT_GE(w, width * 0.85) << e.toString();
        }
        int found = -1;
        for (int axis : {0, 2}) {
            const Lines& l = axis == 0 ? lx : lz;
            double lo = isUmbra ? l.umbLo : l.penLo, hi = isUmbra ? l.umbHi : l.penHi;
            for (int which = 0; which < 2; ++which) {
                double v = which ? hi : lo;
                if (std::abs(e.a[axis] - v) < 1e-9 && std::abs(e.b[axis] - v) < 1e-9) {
                    found = axis * 2 + which;
                    int other = axis == 0 ? 2 : 0;
                    onLine[{isUmbra, found}].push_back(
                        {std::min(e.a[other], e.b[other]), std::max(e.a[other], e.b[other])});
                }
            }
        }
        ASSERT_GE(found, 0) << "not on an analytic " << shadowKindName(e.shadow)
                            << " line: " << e.toString();
    }
    EXPECT_GT(umbra, 0);
    EXPECT_GT(penumbra, 0);
    // Each side of the umbra square and of the penumbra square is covered.
    for (int isUmbra : {0, 1})
        for (int axis : {0, 2})
            for (int which : {0, 1}) {
                const Lines& other = axis == 0 ? lz : lx;
                double from = isUmbra ? other.umbLo : other.penLo;
                double to = isUmbra ? other.umbHi : other.penHi;
                double got = coveredLength(onLine[{isUmbra, axis * 2 + which}], from, to);
                EXPECT_NEAR(got, to - from, 1e-9)
                    << (isUmbra ? "umbra" : "penumbra") << " side axis " << axis << " " << which;
            }
}

TEST(ShadowEdges, MovingABlockerRecomputesOnlyItsShadows) {
    Scene scene = blockerScene({{-0.6, 0.5, 0}, {0.6, 0.5, 0}});
    Discretization disc(scene);
    EdgeFinder finder(disc);
    Vec3 P(0.05, 1.5, 0.02);
    Light area;
    area.polygon = {P + Vec3(-0.2, 0.1, -0.2), P + Vec3(-0.2, 0.1, 0.2), P + Vec3(0.2, 0.1, 0.2),
                    P + Vec3(0.2, 0.1, -0.2)};
    finder.addLight(Light{{P}, -1});
    finder.addLight(area);
    finder.findShadowEdges();
    EXPECT_EQ(finder.stats().pairRecomputations, 2 * 3) << finder.stats().toString();
    finder.resetStats();
    // Nothing moved: nothing recomputed.
    finder.findShadowEdges();
    EXPECT_EQ(finder.stats().pairRecomputations, 0);

    // Move blocker 1 (object 1).
    Scene moved = scene;
    moved.objects[1].transform.translate = Vec3(-0.7, 0.45, 0.1);
    finder.notifyObjectMoved(1, moved.objects[1].transform.worldFromObject());
    std::vector<WorldEdge> incremental = finder.findShadowEdges();
    EXPECT_EQ(finder.stats().eventRecomputations, 2) << finder.stats().toString();
    EXPECT_EQ(finder.stats().pairRecomputations, 2) << finder.stats().toString();

    // From scratch on the moved scene.
    Discretization disc2(moved);
    EdgeFinder scratch(disc2);
    scratch.addLight(Light{{P}, -1});
    scratch.addLight(area);
    // Into a reused list, longer than needed and full of other edges: the same edges.
    std::vector<WorldEdge> reused(incremental.size() + 17);
    for (WorldEdge& e : reused) e.a = Vec3(9, 9, 9), e.blocker = 99;
    scratch.findShadowEdges(reused);
    std::vector<WorldEdge> fresh = scratch.findShadowEdges();
    ASSERT_EQ(reused.size(), fresh.size());
    for (std::size_t i = 0; i < fresh.size(); ++i)
        ASSERT_TRUE(reused[i].a == fresh[i].a && reused[i].b == fresh[i].b &&
                    reused[i].blocker == fresh[i].blocker && reused[i].edge == fresh[i].edge &&
                    reused[i].object == fresh[i].object && reused[i].light == fresh[i].light)
            << i;
    ASSERT_EQ(incremental.size(), fresh.size());
    for (std::size_t i = 0; i < fresh.size(); ++i) {
        EXPECT_LT(glm::length(incremental[i].a - fresh[i].a), 1e-9) << fresh[i].toString();
        EXPECT_LT(glm::length(incremental[i].b - fresh[i].b), 1e-9) << fresh[i].toString();
        EXPECT_EQ(incremental[i].blocker, fresh[i].blocker);
        EXPECT_EQ(incremental[i].object, fresh[i].object);
        EXPECT_EQ(incremental[i].shadow, fresh[i].shadow);
    }
    // Blocker 1's shadow moved with it; blocker 2's edges are the same objects as before.
    int b1 = 0, b2 = 0;
    for (const WorldEdge& e : fresh) (e.blocker == 1 ? b1 : b2) += e.blocker >= 1;
    EXPECT_GT(b1, 0);
    EXPECT_GT(b2, 0);

    // Moving blocker 1 over blocker 2 makes it a receiver of blocker 2's events... and back:
    // a receiver that touches a pair's events makes the pair stale.
    finder.resetStats();
    Transform above;
    above.translate = Vec3(0.6, 0.2, 0.0);
    finder.notifyObjectMoved(1, above.worldFromObject());
    finder.findShadowEdges();
    // Its own two pairs, plus the pairs of blocker 2 whose events it now touches.
    EXPECT_GT(finder.stats().pairRecomputations, 2);
}

TEST(ShadowEdges, RobotRoomUpdateAfterAMove) {
    std::string path = std::string(PENUMBRA_SOURCE_DIR) + "/scenes/robot-room.json";
    if (!std::filesystem::exists(std::string(PENUMBRA_SOURCE_DIR) + "/scenes/meshes/cgal/cow.off"))
        GTEST_SKIP() << "meshes absent (scripts/setup.sh)";
    Scene scene = loadScene(path);
    auto t0 = std::chrono::steady_clock::now();
    Discretization disc(scene);
    auto t1 = std::chrono::steady_clock::now();
    EdgeFinder finder(disc);
    auto t2 = std::chrono::steady_clock::now();
    ASSERT_EQ(finder.lightCount(), 3) << finder.toString();
    for (int l = 0; l < 3; ++l) EXPECT_EQ(finder.light(l).polygon.size(), 4u);
    // Wall time and processor time of all threads (the machine may be shared).
    std::clock_t c2 = std::clock();
    std::vector<WorldEdge> all = finder.findShadowEdges();
    auto t3 = std::chrono::steady_clock::now();
    std::clock_t c3 = std::clock();
    EXPECT_GT(all.size(), 0u);
    auto ms = [](auto a, auto b) {
        return std::chrono::duration<double, std::milli>(b - a).count();
    };
    auto cpuMs = [](std::clock_t a, std::clock_t b) { return 1000.0 * (b - a) / CLOCKS_PER_SEC; };
    std::printf(
        "[ measure  ] robot-room: discretization %.0f ms, edge finder %.0f ms, all shadow "
        "edges %.0f ms, cpu %.0f ms (%zu edges, %s)\n",
        ms(t0, t1), ms(t1, t2), ms(t2, t3), cpuMs(c2, c3), all.size(),
        finder.stats().toString().c_str());
    for (const char* id : {"robot-body", "bull", "cow", "elephant", "dino"}) {
        int o = scene.findObject(id);
        ASSERT_GE(o, 0);
        Transform t = scene.objects[o].transform;
        t.translate += Vec3(0.15, 0, 0.1);
        finder.resetStats();
        auto a = std::chrono::steady_clock::now();
        std::clock_t ca = std::clock();
        finder.notifyObjectMoved(o, t.worldFromObject());
        std::vector<WorldEdge> after = finder.findShadowEdges();
        auto b = std::chrono::steady_clock::now();
        std::clock_t cb = std::clock();
        std::printf("[ measure  ] move %s: shadow update %.1f ms, cpu %.1f ms (%zu edges, %s)\n",
                    id, ms(a, b), cpuMs(ca, cb), after.size(), finder.stats().toString().c_str());
        EXPECT_LT(finder.stats().pairRecomputations, 3 * 19);
    }
    auto s0 = std::chrono::steady_clock::now();
    std::vector<WorldEdge> sil = finder.findSilhouettes(scene.cameras[0].position);
    auto s1 = std::chrono::steady_clock::now();
    std::printf("[ measure  ] robot-room silhouettes from the camera: %.2f ms (%zu edges)\n",
                ms(s0, s1), sil.size());
}

TEST(ShadowEvents, ConcaveEdgesOfSealedBlockersAreHiddenByTheBlocker) {
    // findShadowEvents(cullHidden) drops VE events at concave edges of sealed blockers: the
    // blocker itself must hide every one of them (the exhaustive 1D clipping against its own
    // faces, every u, leaves no shadow edge).
    for (const char* file : {"cow.off", "bunny00.off"}) {
        std::string path = std::string(PENUMBRA_SOURCE_DIR) + "/scenes/meshes/cgal/" + file;
        if (!std::filesystem::exists(path)) GTEST_SKIP() << path << " absent";
        auto mesh = std::make_shared<EdgeMesh>(EdgeMesh::fromTriMesh(loadMeshFile(path)));
        ASSERT_TRUE(mesh->sealed()) << mesh->toString();
        EdgeTree tree(mesh);
        ReceiverTree self(mesh);
        Box3 b = mesh->bounds();
        double size = glm::length(b.hi - b.lo);
        Vec3 c = b.centre() + Vec3(0.2, 1.5, -0.3) * size;
        Light light;
        light.polygon = {c + Vec3(-0.2, 0, -0.15) * size, c + Vec3(-0.2, 0, 0.15) * size,
                         c + Vec3(0.2, 0, 0.15) * size, c + Vec3(0.2, 0, -0.15) * size};
        Mat4 id(1.0);
        std::vector<ShadowEvent> all, culled;
        findShadowEvents(tree, id, id, light, all);
        findShadowEvents(tree, id, id, light, culled, nullptr, true);
        auto keyOf = [](const ShadowEvent& e) {
            return std::make_tuple(e.vertexEdge, e.lightFeature, e.blockerFeature);
        };
        std::set<std::tuple<bool, int, int>> kept;
        for (const ShadowEvent& e : culled) kept.insert(keyOf(e));
        int dropped = 0;
        for (const ShadowEvent& e : all) {
            if (kept.count(keyOf(e))) continue;
            ++dropped;
            ASSERT_TRUE(e.vertexEdge) << e.toString();
            ASSERT_TRUE(isConcaveEdge(*mesh, e.blockerFeature)) << e.toString();
            ReceiverCrossings rc;
            rc.receiver = 0;
            rc.worldFromObject = &id;
            self.intersect(e, true, rc.crossings);
            std::vector<EventEdge> found;
            clipEvent({rc}, found);
            double length = 0;
            for (const EventEdge& f : found) length += glm::length(f.b - f.a);
            EXPECT_LT(length, 1e-9 * size)
                << file << ": dropped event casts " << found.size() << " edges: " << e.toString();
        }
        EXPECT_GT(dropped, 0) << file;
        EXPECT_EQ(all.size(), culled.size() + dropped);
        std::printf("[ measure  ] %s: %zu events, %d concave VE events dropped\n", file, all.size(),
                    dropped);
    }
}

TEST(ShadowEdges, FrontToBackEqualsExhaustiveClippingInRobotRoom) {
    // The accelerated finder (front-to-back receivers, early outs, self-hidden events dropped)
    // against the exhaustive one (every receiver meeting an event intersected whole), on a part
    // of robot-room with real meshes, before and after moves.
    std::string path = std::string(PENUMBRA_SOURCE_DIR) + "/scenes/robot-room.json";
    if (!std::filesystem::exists(std::string(PENUMBRA_SOURCE_DIR) + "/scenes/meshes/cgal/cow.off"))
        GTEST_SKIP() << "meshes absent (scripts/setup.sh)";
    Scene scene = loadScene(path);
    Discretization disc(scene);
    EdgeFinderOptions exhaustive;
    exhaustive.exhaustiveShadows = true;
    EdgeFinder fast(disc), ref(disc, exhaustive);
    const std::set<std::string> keep = {"floor",          "back",       "left",       "cow",
                                        "elephant",       "robot-base", "robot-body", "robot-head",
                                        "robot-arm-left", "lamp-1"};
    auto restrict = [&](EdgeFinder& f) {
        for (int o = 0; o < static_cast<int>(scene.objects.size()); ++o)
            f.setObjectAlive(o, keep.count(scene.objects[o].id) > 0);
        for (int l = 0; l < f.lightCount(); ++l)
            f.setLightAlive(l, scene.objects[f.light(l).object].id == "lamp-1");
    };
    restrict(fast);
    restrict(ref);
    std::vector<WorldEdge> a = fast.findShadowEdges(), b = ref.findShadowEdges();
    ASSERT_GT(a.size(), 100u);
    EXPECT_GT(expectSameShadowLines(a, b, 1e-6, "initial"), 100);
    EXPECT_LT(fast.stats().receiverNodes, ref.stats().receiverNodes);
    for (const char* id : {"robot-body", "cow"}) {
        int o = scene.findObject(id);
        Transform t = scene.objects[o].transform;
        t.translate += Vec3(0.2, 0, 0.15);
        fast.notifyObjectMoved(o, t.worldFromObject());
        ref.notifyObjectMoved(o, t.worldFromObject());
        a = fast.findShadowEdges();
        b = ref.findShadowEdges();
        expectSameShadowLines(a, b, 1e-6, id);
    }
    // The incremental result equals a fresh finder's on the moved scene.
    EdgeFinder fresh(disc);
    restrict(fresh);
    for (const char* id : {"robot-body", "cow"}) {
        int o = scene.findObject(id);
        Transform t = scene.objects[o].transform;
        t.translate += Vec3(0.2, 0, 0.15);
        fresh.notifyObjectMoved(o, t.worldFromObject());
    }
    expectSameShadowLines(a, fresh.findShadowEdges(), 1e-6, "incremental vs fresh");
}

namespace {

/// EventCoverage::threshold from its definition, from scratch: every piece end, 0 and 1 cut
/// u into elementary intervals; each interval inside [0, 1] and at least 1e-12 long takes the
/// smallest sMax of the pieces covering it (infinite if none; a NaN sMax covers nothing); the
/// threshold is the largest. `shortest` 0 counts every interval (no gap ignored).
double coverageThresholdBruteForce(const std::vector<std::array<double, 3>>& pieces,
                                   double shortest = 1e-12) {
    std::vector<double> ends{0.0, 1.0};
    std::vector<std::array<double, 3>> kept;
    double length = 0;
    for (const auto& p : pieces) {
        if (!(p[1] - p[0] >= 1e-12)) continue;
        kept.push_back(p);
        length += p[1] - p[0];
        ends.push_back(p[0]);
        ends.push_back(p[1]);
    }
    if (length < 1 - 1e-9) return HUGE_VAL;  // cannot cover [0, 1]; never computed
    std::sort(ends.begin(), ends.end());
    ends.erase(std::unique(ends.begin(), ends.end()), ends.end());
    double t = -HUGE_VAL;
    for (std::size_t i = 0; i + 1 < ends.size(); ++i) {
        const double a = ends[i], b = ends[i + 1];
        if (b <= 0 || a >= 1 || b - a < shortest) continue;
        double best = HUGE_VAL;
        for (const auto& p : kept)
            if (p[0] <= a && p[1] >= b) best = std::min(best, p[2]);
        t = std::max(t, best);
    }
    return t;
}

}  // namespace

TEST(EventCoverage, ThresholdEqualsTheEnvelopeFromScratchAsPiecesArrive) {
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> unit(0.0, 1.0);
    EventCoverage coverage;
    int finite = 0, checked = 0, gapsThatMattered = 0;
    for (int trial = 0; trial < 300; ++trial) {
        coverage.reset(1 + 1e-7);
        std::vector<std::array<double, 3>> pieces;
        const int count = 1 + trial % 40;
        // A few shared ends, so pieces meet exactly; some pieces reach beyond [0, 1]; some
        // gaps are shorter than 1e-12 (ignored); some pieces are empty.
        std::vector<double> grid;
        for (int k = 0; k < 6; ++k) grid.push_back(unit(rng) * 1.2 - 0.1);
        for (int k = 0; k < count; ++k) {
            double u0 = unit(rng) < 0.3 ? grid[rng() % grid.size()] : unit(rng) * 1.2 - 0.1;
            if (unit(rng) < 0.15 && !pieces.empty()) u0 = pieces.back()[1] + 4e-13;  // tiny gap
            double u1 = unit(rng) < 0.3 ? grid[rng() % grid.size()] : u0 + unit(rng) * 0.6;
            if (unit(rng) < 0.1) u1 = u0 + 5e-13;  // too short: ignored
            double s = unit(rng) < 0.2 ? 1.0 : 0.5 + 3 * unit(rng);
            if (unit(rng) < 0.03) s = std::nan("");  // covers nothing
            pieces.push_back({u0, u1, s});
            coverage.add(u0, u1, s);
            const double expected = coverageThresholdBruteForce(pieces);
            // bound() is stale between its recomputations, never below the threshold.
            EXPECT_GE(coverage.bound(), expected);
            if (k % 3 == 0 || k + 1 == count) {
                EXPECT_EQ(coverage.threshold(), expected) << "trial " << trial << " piece " << k;
                ++checked;
                // A gap under 1e-12 that alone leaves [0, 1] uncovered.
                gapsThatMattered +=
                    expected < HUGE_VAL && coverageThresholdBruteForce(pieces, 0.0) == HUGE_VAL;
                finite += expected < HUGE_VAL;
            }
        }
    }
    EXPECT_GT(checked, 1000);
    EXPECT_GT(finite, 200) << "most cases must cover [0, 1] to test anything";
    EXPECT_GT(gapsThatMattered, 5) << "the 1e-12 rule must decide some cases";
}

TEST(ShadowEdges, ReusedListsKeepTheirBlockWhileTheyGrowALittle) {
    // The lists rebuilt after every move (findShadowEdges' output, orderByPenumbra's scratch)
    // must not move to fresh memory when a move adds a few edges. (Their contents are
    // overwritten, so growing may discard them.)
    std::vector<WorldEdge> list;
    reserveForOverwrite(list, 1000);
    list.resize(1000);
    EXPECT_GE(list.capacity(), 1500u);
    const WorldEdge* block = list.data();
    for (std::size_t n : {1080u, 900u, 1400u, 1500u}) {
        reserveForOverwrite(list, n);
        list.resize(n);
        EXPECT_EQ(list.data(), block) << n << " edges";
    }
    reserveForOverwrite(list, 1501);
    EXPECT_GE(list.capacity(), 2251u);
}
