// projectEpiEdges against its reference: the serial projectEdges of the concatenated lists,
// less the edges edgeMayMark() rejects, field by field and bit for bit; and the EPI built from
// either list, identical.

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <span>
#include <vector>

#include "render/display/interactive_display.h"

namespace penumbra {
namespace {

bool sameScreenEdge(const ScreenEdge& x, const ScreenEdge& y) {
    return x.a == y.a && x.b == y.b && x.depthA == y.depthA && x.depthB == y.depthB &&
           x.kind == y.kind;
}

TEST(ProjectEdges, SoftShadowEdgesWithAWidePenumbraAtBothEndsAreDropped) {
    // A camera 4 m from the plane z = 0, 200 pixels over a 60° field: one pixel is
    // 2·4·tan 30° / 200 = 0.0231 m there.
    Camera c;
    c.position = Vec3(0, 0, 4);
    c.lookAt = Vec3(0, 0, 0);
    c.up = Vec3(0, 1, 0);
    c.fovDeg = 60;
    const CameraRays camera(c, 200, 200);
    const double pixel = 2 * 4 * std::tan(glm::radians(30.0)) / 200;
    EXPECT_NEAR(4.0 / camera.pixelsPerUnit(), pixel, 1e-12);
    auto edge = [](EdgeKind kind, double penumbraA, double penumbraB, double y) {
        WorldEdge e;
        e.a = Vec3(-1, y, 0);
        e.b = Vec3(1, y, 0);
        e.kind = kind;
        e.shadow = penumbraA > 0 || penumbraB > 0 ? ShadowKind::Penumbra : ShadowKind::Hard;
        e.penumbraA = penumbraA;
        e.penumbraB = penumbraB;
        return e;
    };
    const std::vector<WorldEdge> edges = {
        edge(EdgeKind::Shadow, 3.1 * pixel, 5 * pixel, -0.5),  // wide at both ends: dropped
        edge(EdgeKind::Shadow, 2.9 * pixel, 9 * pixel, -0.3),  // narrow at a: kept
        edge(EdgeKind::Shadow, 9 * pixel, 1 * pixel, -0.1),    // narrow at b: kept
        edge(EdgeKind::Shadow, 0, 0, 0.1),                     // a hard shadow: kept
        edge(EdgeKind::Silhouette, 0, 0, 0.3),                 // kept
    };
    std::vector<WorldEdge> edges2 = edges;
    // Ends at different depths (4 and 8 m: a pixel there is 2·pixel wide): 4 pixels at a and
    // 3.5 at b, so dropped; pairing the widths with the wrong ends would keep it (2 and 7).
    WorldEdge deep = edge(EdgeKind::Shadow, 4 * pixel, 7 * pixel, 0.5);
    deep.b = Vec3(1, 0.5, -4);
    edges2.push_back(deep);
    const auto all = projectEdges(edges2, camera, 1e-3);
    ASSERT_EQ(all.size(), 6u) << "without the option every edge is kept";
    const auto kept = projectEdges(edges2, camera, 1e-3, 3.0);
    ASSERT_EQ(kept.size(), 4u);
    for (std::size_t k = 0; k < kept.size(); ++k)
        EXPECT_TRUE(sameScreenEdge(kept[k], all[k + 1])) << "edge " << k + 1;
    // The parallel projection applies the same rule.
    std::vector<ScreenEdge> out, scratch;
    const std::vector<std::span<const WorldEdge>> lists = {edges};
    projectEpiEdges(lists, camera, 1e-3, out, scratch, true, 3.0);
    ASSERT_EQ(out.size(), 4u);
    for (std::size_t k = 0; k < out.size(); ++k) EXPECT_TRUE(sameScreenEdge(out[k], kept[k]));
}

TEST(ProjectEdges, ParallelProjectionEqualsTheSerialOneLessUnmarkableEdges) {
    Camera c;
    c.position = Vec3(0.3, 1.2, 2.0);
    c.lookAt = Vec3(0.0, 0.5, -1.0);
    c.up = Vec3(0, 1, 0);
    c.fovDeg = 55;
    const int W = 203, H = 157;
    const CameraRays camera(c, W, H);
    std::mt19937 rng(31);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    // Lists of uneven sizes (empty ones too, one longer than a chunk): edges all around the
    // camera (behind it, across the near plane, off to the sides), most of them tiny as the
    // silhouettes of fine meshes, some long.
    std::vector<std::vector<WorldEdge>> lists(9);
    const int sizes[9] = {0, 3000, 1, 0, 9000, 250, 0, 4097, 20};
    for (int l = 0; l < 9; ++l)
        for (int k = 0; k < sizes[l]; ++k) {
            WorldEdge e;
            e.a = Vec3(u(rng) * 8 - 4, u(rng) * 4 - 1, u(rng) * 9 - 6);
            const double len = u(rng) < 0.8 ? 0.01 : u(rng) < 0.5 ? 0.2 : 5.0;
            e.b = e.a + len * Vec3(u(rng) - 0.5, u(rng) - 0.5, u(rng) - 0.5);
            e.kind = l % 3 == 0   ? EdgeKind::Silhouette
                     : l % 3 == 1 ? EdgeKind::Sharp
                                  : EdgeKind::Shadow;
            e.object = l;
            lists[l].push_back(e);
        }
    std::vector<std::span<const WorldEdge>> spans;
    std::vector<WorldEdge> all;
    for (const auto& list : lists) {
        spans.emplace_back(list);
        all.insert(all.end(), list.begin(), list.end());
    }
    const double near = 0.05;
    const std::vector<ScreenEdge> projected = projectEdges(all, camera, near);
    std::vector<ScreenEdge> expected;
    for (const ScreenEdge& s : projected)
        if (edgeMayMark(s, W, H)) expected.push_back(s);
    ASSERT_LT(projected.size(), all.size()) << "some edges must lie behind the camera";
    ASSERT_LT(expected.size(), projected.size() * 3 / 4) << "most must be unmarkable";
    ASSERT_GT(expected.size(), 1000u);

    // Output and scratch reused with stale content, parallel and serial.
    std::vector<ScreenEdge> out(5), scratch(70000);
    for (bool parallel : {true, false, true}) {
        projectEpiEdges(spans, camera, near, out, scratch, parallel);
        ASSERT_EQ(out.size(), expected.size()) << "parallel " << parallel;
        int differing = 0;
        for (std::size_t k = 0; k < out.size(); ++k)
            differing += !sameScreenEdge(out[k], expected[k]);
        EXPECT_EQ(differing, 0) << "parallel " << parallel;
    }

    // The EPI of the kept edges equals the EPI of every projected edge.
    std::vector<ScreenPoint> points;
    for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x)
            if (u(rng) < 0.5) {
                ScreenPoint p;
                p.position = {x + u(rng), y + u(rng)};
                p.depth = 1.0 + 6.0 * u(rng);
                p.colour = Rgb(u(rng), 0.4, u(rng));
                points.push_back(p);
            }
    EdgePointImage full(W, H), fast(W, H);
    full.build(projected, points);
    fast.build(out, points);
    EXPECT_GT(full.countPixels(PixelClass::Simple) + full.countPixels(PixelClass::Complex), 500u);
    EXPECT_EQ(full.culledIntersections(), fast.culledIntersections());
    int differing = 0;
    for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x)
            differing += !(full.boundaryMasks(x, y) == fast.boundaryMasks(x, y) &&
                           full.halfLineMasks(x, y) == fast.halfLineMasks(x, y) &&
                           full.edgeCode(x, y) == fast.edgeCode(x, y));
    EXPECT_EQ(differing, 0);
    EXPECT_EQ(full.reconstruct(true).pixels, fast.reconstruct(true).pixels);
}

TEST(ProjectEdges, EdgesAfterThePenumbraPrefixAreAllDroppedAndTheOrderKeepsEveryEdge) {
    // Soft shadow edges with penumbrae from 1e-4 to 10 m (log-uniform), hard ones, and a few
    // with a non-finite end or width, seen by cameras inside and outside their bounds.
    std::mt19937 rng(17);
    std::uniform_real_distribution<double> u(0, 1);
    std::vector<WorldEdge> edges;
    for (int i = 0; i < 20000; ++i) {
        WorldEdge e;
        e.a = Vec3(8 * u(rng) - 4, 3 * u(rng), 8 * u(rng) - 4);
        e.b = e.a + 0.05 * Vec3(u(rng) - 0.5, u(rng) - 0.5, u(rng) - 0.5);
        e.kind = EdgeKind::Shadow;
        e.edge = i;
        if (i % 10 != 0) {
            e.penumbraA = std::pow(10.0, -4 + 5 * u(rng));
            e.penumbraB = std::pow(10.0, -4 + 5 * u(rng));
        }
        if (i % 997 == 0) e.a.x = std::nan("");
        if (i % 1009 == 0) e.penumbraB = HUGE_VAL;
        edges.push_back(e);
    }
    std::vector<WorldEdge> ordered = edges, scratch;
    const PenumbraOrder order = orderByPenumbra(ordered, scratch);
    // A permutation, each bucket in the input order.
    ASSERT_EQ(ordered.size(), edges.size());
    ASSERT_EQ(order.start[PenumbraOrder::kBuckets], edges.size());
    std::vector<int> seen(edges.size(), 0);
    for (int k = 0; k < PenumbraOrder::kBuckets; ++k)
        for (std::size_t i = order.start[k]; i < order.start[k + 1]; ++i) {
            ++seen[ordered[i].edge];
            if (i > order.start[k]) {
                EXPECT_LT(ordered[i - 1].edge, ordered[i].edge);
            }
            const double m = std::min(ordered[i].penumbraA, ordered[i].penumbraB);
            if (k >= 2 && k + 1 < PenumbraOrder::kBuckets) {
                EXPECT_GE(m, std::ldexp(1.0, k - 32));
                EXPECT_LT(m, std::ldexp(1.0, k - 31));
            }
        }
    for (int n : seen) ASSERT_EQ(n, 1);
    int cameras = 0;
    std::size_t skipped = 0;
    for (const Vec3& position : {Vec3(0, 2, 12), Vec3(0.5, 1, 0.3), Vec3(-20, 30, 5)}) {
        for (double pixels : {0.0, 0.5, 2.0, 40.0}) {
            Camera c;
            c.position = position;
            c.lookAt = Vec3(0, 0.5, 0);
            c.up = Vec3(0, 1, 0);
            c.fovDeg = 50;
            const CameraRays camera(c, 320, 240);
            const std::size_t prefix = penumbraPrefix(order, camera, 1e-3, pixels);
            ASSERT_LE(prefix, ordered.size());
            if (!(pixels > 0)) {
                EXPECT_EQ(prefix, ordered.size());
            }
            // Everything after the prefix is what projectEdge drops.
            const std::vector<WorldEdge> rest(ordered.begin() + static_cast<std::ptrdiff_t>(prefix),
                                              ordered.end());
            EXPECT_TRUE(projectEdges(rest, camera, 1e-3, pixels).empty())
                << "camera " << cameras << ", " << pixels << " pixels";
            skipped += ordered.size() - prefix;
            ++cameras;
        }
    }
    // Not vacuous: the prefixes leave out many edges.
    EXPECT_GT(skipped, edges.size() / 2);
}

}  // namespace
}  // namespace penumbra
