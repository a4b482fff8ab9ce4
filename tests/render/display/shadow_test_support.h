#pragma once
// Shared by the shadow-edge tests: compare two sets of shadow edges line by line.
//
// Index: distanceToSegment · groupEdges · expectSameShadowLines
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <map>
#include <tuple>
#include <vector>

#include "render/display/edge_finder.h"

namespace penumbra::test {

/// Distance from p to segment a–b.
inline double distanceToSegment(const Vec3& p, const Vec3& a, const Vec3& b) {
    Vec3 d = b - a;
    double dd = glm::dot(d, d);
    double t = dd > 0 ? std::clamp(glm::dot(p - a, d) / dd, 0.0, 1.0) : 0.0;
    return glm::length(p - (a + t * d));
}

using EdgeGroupKey = std::tuple<int, int, int, int, int>;

/// Shadow edges grouped by what casts them: (light, blocker, receiver, blocker feature, kind).
inline std::map<EdgeGroupKey, std::vector<WorldEdge>> groupEdges(
    const std::vector<WorldEdge>& edges) {
    std::map<EdgeGroupKey, std::vector<WorldEdge>> out;
    for (const WorldEdge& e : edges)
        out[{e.light, e.blocker, e.object, e.edge, static_cast<int>(e.shadow)}].push_back(e);
    return out;
}

/// The two edge sets cover the same lines (segmentation may differ): per group equal total
/// length, every segment's midpoint on the other set. Groups on one side only must be
/// negligible (below `tiny` in total). Returns the number of groups compared.
inline int expectSameShadowLines(const std::vector<WorldEdge>& fast,
                                 const std::vector<WorldEdge>& ref, double tiny, const char* what) {
    auto a = groupEdges(fast), b = groupEdges(ref);
    auto length = [](const std::vector<WorldEdge>& v) {
        double s = 0;
        for (const WorldEdge& e : v) s += glm::length(e.b - e.a);
        return s;
    };
    auto onSet = [](const Vec3& p, const std::vector<WorldEdge>& v) {
        double best = 1e300;
        for (const WorldEdge& e : v) best = std::min(best, distanceToSegment(p, e.a, e.b));
        return best;
    };
    int compared = 0;
    double onlyA = 0, onlyB = 0;
    for (const auto& [key, edges] : a) {
        auto it = b.find(key);
        if (it == b.end()) {
            onlyA += length(edges);
            continue;
        }
        ++compared;
        EXPECT_NEAR(length(edges), length(it->second), 1e-9 + 1e-7 * length(it->second))
            << what << ": " << edges.front().toString();
        for (const WorldEdge& e : edges)
            EXPECT_LT(onSet(0.5 * (e.a + e.b), it->second), 1e-8) << what << ": " << e.toString();
        for (const WorldEdge& e : it->second)
            EXPECT_LT(onSet(0.5 * (e.a + e.b), edges), 1e-8) << what << ": " << e.toString();
    }
    for (const auto& [key, edges] : b)
        if (!a.count(key)) onlyB += length(edges);
    EXPECT_LT(onlyA, tiny) << what << ": shadow lines only in the first set";
    EXPECT_LT(onlyB, tiny) << what << ": shadow lines only in the second set";
    std::printf(
        "[ measure  ] %s: %d groups compared, lengths only in the first set %.3g, only in "
        "the second %.3g\n",
        what, compared, onlyA, onlyB);
    return compared;
}

}  // namespace penumbra::test
