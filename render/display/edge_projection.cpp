// Edges onto the screen for the edge-and-point image (Bala et al. §6): world edges clipped to
// the near plane and projected (projectEdges, projectEpiEdges), and shadow edges ordered by
// their penumbra so a view projects only those that can mark it (orderByPenumbra,
// penumbraPrefix). Declared in interactive_display.h.

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <span>
#include <vector>

#include "render/display/interactive_display.h"

namespace penumbra {

namespace {

ScreenEdge::Kind screenKind(EdgeKind kind) {
    switch (kind) {
        case EdgeKind::Silhouette:
            return ScreenEdge::Kind::Silhouette;
        case EdgeKind::Sharp:
            return ScreenEdge::Kind::Sharp;
        case EdgeKind::Shadow:
            return ScreenEdge::Kind::Shadow;
    }
    return ScreenEdge::Kind::Silhouette;
}

/// One edge of projectEdges: false when it is dropped (behind the near plane or not
/// projectable).
bool projectEdge(const WorldEdge& e, const CameraRays& camera, double nearPlane,
                 double maxPenumbraPixels, ScreenEdge& out) {
    const Vec3& o = camera.origin();
    const Vec3& f = camera.forward();
    Vec3 a = e.a, b = e.b;
    double da = glm::dot(a - o, f), db = glm::dot(b - o, f);
    if (!(da >= nearPlane) && !(db >= nearPlane)) return false;  // behind (or NaN)
    // A wide penumbra at both ends: the radiance is smooth across this soft shadow edge.
    if (maxPenumbraPixels > 0 && (e.penumbraA > 0 || e.penumbraB > 0)) {
        const double limit = maxPenumbraPixels / camera.pixelsPerUnit();
        if (e.penumbraA > limit * std::max(da, nearPlane) &&
            e.penumbraB > limit * std::max(db, nearPlane))
            return false;
    }
    // Clip the part in front of the near plane.
    if (da < nearPlane) {
        a = a + (b - a) * ((nearPlane - da) / (db - da));
        da = nearPlane;
    } else if (db < nearPlane) {
        b = b + (a - b) * ((nearPlane - db) / (da - db));
        db = nearPlane;
    }
    // Both depths are now at least the near plane (> 0): both ends project.
    if (!(da > 0) || !(db > 0)) return false;
    out.a = camera.projectAtDepth(a, da);
    out.b = camera.projectAtDepth(b, db);
    out.depthA = da;
    out.depthB = db;
    out.kind = screenKind(e.kind);
    return true;
}

}  // namespace

std::vector<ScreenEdge> projectEdges(const std::vector<WorldEdge>& edges, const CameraRays& camera,
                                     double nearPlane, double maxPenumbraPixels) {
    std::vector<ScreenEdge> out;
    out.reserve(edges.size());
    ScreenEdge s;
    for (const WorldEdge& e : edges)
        if (projectEdge(e, camera, nearPlane, maxPenumbraPixels, s)) out.push_back(s);
    return out;
}

void projectEpiEdges(const std::vector<std::span<const WorldEdge>>& lists, const CameraRays& camera,
                     double nearPlane, std::vector<ScreenEdge>& out,
                     std::vector<ScreenEdge>& scratch, bool parallel, double maxPenumbraPixels) {
    const int W = camera.width(), H = camera.height();
    // Global index n of the concatenation: list l holds [listStart[l], listStart[l + 1]).
    std::vector<std::size_t> listStart(lists.size() + 1, 0);
    for (std::size_t l = 0; l < lists.size(); ++l)
        listStart[l + 1] = listStart[l] + lists[l].size();
    const std::size_t total = listStart.back();
    constexpr std::size_t kChunk = 4096;
    const std::size_t chunks = (total + kChunk - 1) / kChunk;
    // Each chunk projects its edges into its own stretch of `scratch`, kept ones first.
    scratch.resize(total);
    std::vector<std::size_t> kept(chunks + 1, 0);
    auto project = [&](std::size_t c) {
        const std::size_t lo = c * kChunk, hi = std::min(total, lo + kChunk);
        std::size_t l = static_cast<std::size_t>(
            std::upper_bound(listStart.begin(), listStart.end(), lo) - listStart.begin() - 1);
        std::size_t m = lo;
        for (std::size_t n = lo; n < hi; ++n) {
            while (n >= listStart[l + 1]) ++l;
            ScreenEdge& s = scratch[m];
            if (projectEdge(lists[l][n - listStart[l]], camera, nearPlane, maxPenumbraPixels, s) &&
                edgeMayMark(s, W, H)) {
                ++m;
            }
        }
        kept[c + 1] = m - lo;
    };
    if (parallel) {
        tbb::parallel_for(std::size_t(0), chunks, project);
    } else {
        for (std::size_t c = 0; c < chunks; ++c) project(c);
    }
    // Offsets, then the kept edges of each chunk at its offset, in input order.
    for (std::size_t c = 0; c < chunks; ++c) kept[c + 1] += kept[c];
    out.resize(kept[chunks]);
    auto gather = [&](std::size_t c) {
        std::copy_n(scratch.begin() + static_cast<std::ptrdiff_t>(c * kChunk),
                    kept[c + 1] - kept[c], out.begin() + static_cast<std::ptrdiff_t>(kept[c]));
    };
    if (parallel) {
        tbb::parallel_for(std::size_t(0), chunks, gather);
    } else {
        for (std::size_t c = 0; c < chunks; ++c) gather(c);
    }
}

namespace {

/// orderByPenumbra's bucket of an edge.
int penumbraBucket(const WorldEdge& e) {
    const double m = std::min(e.penumbraA, e.penumbraB);
    const bool finiteEnds = std::isfinite(e.a.x) && std::isfinite(e.a.y) && std::isfinite(e.a.z) &&
                            std::isfinite(e.b.x) && std::isfinite(e.b.y) && std::isfinite(e.b.z);
    if (!finiteEnds || !(m > 0) || !std::isfinite(m)) return 0;
    // m in [2^x, 2^(x+1)), x = ilogb(m), exactly.
    return std::clamp(std::ilogb(m) + 32, 1, PenumbraOrder::kBuckets - 1);
}

}  // namespace

PenumbraOrder orderByPenumbra(std::vector<WorldEdge>& edges, std::vector<WorldEdge>& scratch) {
    constexpr int K = PenumbraOrder::kBuckets;
    constexpr std::size_t kChunk = 8192;
    const std::size_t n = edges.size();
    const std::size_t chunks = (n + kChunk - 1) / kChunk;
    std::vector<std::uint8_t> bucket(n);
    std::vector<std::size_t> count(chunks * K, 0);
    std::vector<Box3> boxes(chunks);
    // Per chunk: each edge's bucket, the chunk's bucket counts and box.
    tbb::parallel_for(std::size_t(0), chunks, [&](std::size_t c) {
        for (std::size_t i = c * kChunk; i < std::min(n, (c + 1) * kChunk); ++i) {
            const int k = penumbraBucket(edges[i]);
            bucket[i] = static_cast<std::uint8_t>(k);
            ++count[c * K + k];
            if (k > 0) boxes[c].extend(edges[i].a), boxes[c].extend(edges[i].b);
        }
    });
    // Offsets, bucket-major and chunks in order (so each bucket keeps the input order), then
    // the scatter.
    PenumbraOrder order;
    std::size_t at = 0;
    for (int k = 0; k < K; ++k) {
        order.start[k] = at;
        for (std::size_t c = 0; c < chunks; ++c) {
            const std::size_t here = count[c * K + k];
            count[c * K + k] = at;
            at += here;
        }
    }
    order.start[K] = at;
    for (const Box3& b : boxes) order.bounds.extend(b);
    reserveForOverwrite(scratch, n);  // as findShadowEdges' list, which this swaps with
    scratch.resize(n);
    tbb::parallel_for(std::size_t(0), chunks, [&](std::size_t c) {
        for (std::size_t i = c * kChunk; i < std::min(n, (c + 1) * kChunk); ++i)
            scratch[count[c * K + bucket[i]]++] = edges[i];
    });
    edges.swap(scratch);
    return order;
}

std::size_t penumbraPrefix(const PenumbraOrder& order, const CameraRays& camera, double nearPlane,
                           double maxPenumbraPixels) {
    constexpr int K = PenumbraOrder::kBuckets;
    const std::size_t all = order.start[K];
    if (!(maxPenumbraPixels > 0) || order.start[2] == all) return all;
    // The largest view depth of the bounded edges' endpoints: a linear function's maximum
    // over the box is at a corner. projectEdge drops an edge when both penumbrae exceed
    // limit × max(depth, nearPlane) at their ends, which is at most limit × deepest; a bucket
    // whose narrowest penumbra exceeds that (with a margin for rounding) is dropped whole.
    const Box3& b = order.bounds;
    double deepest = nearPlane;
    for (int corner = 0; corner < 8; ++corner) {
        const Vec3 p(corner & 1 ? b.hi.x : b.lo.x, corner & 2 ? b.hi.y : b.lo.y,
                     corner & 4 ? b.hi.z : b.lo.z);
        deepest = std::max(deepest, glm::dot(p - camera.origin(), camera.forward()));
    }
    if (!std::isfinite(deepest)) return all;
    const double widest =
        maxPenumbraPixels / camera.pixelsPerUnit() * deepest * (1.0 + 1e-9) + 1e-300;
    for (int k = 2; k < K; ++k)
        if (std::ldexp(1.0, k - 32) > widest) return order.start[k];
    return all;
}

}  // namespace penumbra
