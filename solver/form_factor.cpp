#include "solver/form_factor.h"

#include <algorithm>
#include <cmath>
#include <cstring>

#include "solver/discretization.h"
#include "solver/ray_tracer.h"

namespace penumbra {

namespace {

std::uint64_t splitmix(std::uint64_t x) {
    x += 0x9e3779b97f4a7c15ull;
    x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ull;
    x = (x ^ (x >> 27)) * 0x94d049bb133111ebull;
    return x ^ (x >> 31);
}

/// Small deterministic generator for pair-seeded patterns.
struct PairRandom {
    std::uint64_t state;
    double next() { return static_cast<double>((state = splitmix(state)) >> 11) * 0x1.0p-53; }
};

Vec3 polygonNormal(const std::vector<Vec3>& poly) {
    Vec3 n(0.0);
    for (std::size_t i = 0; i < poly.size(); ++i)
        n += glm::cross(poly[i], poly[(i + 1) % poly.size()]);
    return n;
}

/// Cumulative doubled areas of the fan triangles (poly[0], poly[i+1], poly[i+2]) of a convex
/// polygon, for samplePolygon.
void fanAreas(const std::vector<Vec3>& poly, std::vector<double>& cumulative) {
    cumulative.clear();
    double sum = 0;
    for (std::size_t i = 0; i + 2 < poly.size(); ++i)
        cumulative.push_back(sum +=
                             glm::length(glm::cross(poly[i + 1] - poly[0], poly[i + 2] - poly[0])));
}

/// Uniform point in a convex polygon: the fan triangle by area (r0 ∈ [0, 1]), then a uniform
/// point of it.
Vec3 samplePolygon(const std::vector<Vec3>& poly, const std::vector<double>& fans, double r0,
                   double r1, double r2) {
    double pick = r0 * fans.back();
    std::size_t i = 0;
    while (i + 1 < fans.size() && pick > fans[i]) ++i;
    double s = std::sqrt(r1);
    return (1 - s) * poly[0] + s * (1 - r2) * poly[i + 1] + s * r2 * poly[i + 2];
}

}  // namespace

// atan(a) = a·P(a²) on a = min/max ∈ [0, 1], P of degree 10 fitted by us (least squares
// reweighted toward minimax absolute error: max 1.4e-10 on [0, 1]), then the octant. The
// contour integral takes four of these per polygon; libm's atan2 was a tenth of a cube-room
// solve.
double angleAtan2(double y, double x) {
    const double ax = std::abs(x);
    const double hi = std::max(ax, y), lo = std::min(ax, y);
    if (!(hi > 0)) return 0;
    const double a = lo / hi, s = a * a;
    // Estrin's scheme: a short dependency chain.
    const double s2 = s * s, s4 = s2 * s2, s8 = s4 * s4;
    const double p01 = 0.99999999667237049 + s * -0.3333330208903717;
    const double p23 = 0.19999129786621939 + s * -0.14274432022169178;
    const double p45 = 0.11028650565781659 + s * -0.087138588795384275;
    const double p67 = 0.065413758853929485 + s * -0.042088081586575191;
    const double p89 = 0.020467823501212654 + s * -0.0063947658920403376;
    const double p10 = 0.00093755837204316853;
    const double p = (p01 + s2 * p23) + s4 * (p45 + s2 * p67) + s8 * (p89 + s2 * p10);
    double r = a * p;
    if (y > ax) r = M_PI_2 - r;
    if (x < 0) r = M_PI - r;
    return r;
}

std::uint64_t hashPair(std::uint64_t a, std::uint64_t b) {
    return splitmix(splitmix(a) ^ (b + 0x632be59bd9b4e019ull + (a << 6) + (a >> 2)));
}

namespace {

/// Lambert's contour integral over `polygon` (front side toward `pn`) clipped to the
/// hemisphere above (x, n); the clipped polygon is left in `clipped` (empty when nothing is
/// seen) and `wasClipped` tells whether the horizon cut it.
double clippedFormFactor(const Vec3& x, const Vec3& n, const std::vector<Vec3>& polygon,
                         const Vec3& pn, std::vector<Vec3>& clipped, bool& wasClipped) {
    clipped.clear();
    wasClipped = false;
    const std::size_t m = polygon.size();
    if (m < 3) return 0;
    // One-sided: the point must be in front of the polygon.
    if (glm::dot(x - polygon[0], pn) <= 0) return 0;

    // Clip to the receiver's hemisphere, dot(p − x, n) ≥ 0 (Sutherland–Hodgman); each
    // vertex's height is computed once. The output has a vertex per kept vertex and per sign
    // change: at most m + ⌊m/2⌋ (signs alternating, as rounding can make them for a polygon
    // lying in the horizon plane).
    clipped.resize(m + m / 2 + 1);
    Vec3* out = clipped.data();
    std::size_t count = 0;
    double da = glm::dot(polygon[0] - x, n);
    for (std::size_t i = 0; i < m; ++i) {
        const Vec3& a = polygon[i];
        const Vec3& b = polygon[i + 1 < m ? i + 1 : 0];
        const double db = glm::dot(b - x, n);
        if (da >= 0) out[count++] = a;
        if ((da >= 0) != (db >= 0)) out[count++] = a + (b - a) * (da / (da - db));
        wasClipped = wasClipped || da < 0;
        da = db;
    }
    if (count < 3) {
        clipped.clear();
        return 0;
    }
    clipped.resize(count);

    // Lambert's contour integral: F = 1/(2π) Σ β_k n·Γ̂_k, each vertex's offset from x
    // computed once.
    double sum = 0;
    const Vec3 first = out[0] - x;
    Vec3 r0 = first;
    for (std::size_t i = 0; i < count; ++i) {
        const Vec3 r1 = i + 1 < count ? out[i + 1] - x : first;
        const Vec3 c = glm::cross(r0, r1);
        const double cl = glm::length(c);
        if (!(cl <= 0)) {  // as before: a NaN length is not skipped
            const double beta = angleAtan2(cl, glm::dot(r0, r1));
            sum += beta * glm::dot(n, c) / cl;
        }
        r0 = r1;
    }
    return std::abs(sum) / (2 * M_PI);
}

}  // namespace

double polygonFormFactor(const Vec3& x, const Vec3& n, const std::vector<Vec3>& polygon) {
    thread_local std::vector<Vec3> clipped;
    bool wasClipped = false;
    return clippedFormFactor(x, n, polygon, polygonNormal(polygon), clipped, wasClipped);
}

int visibilityRayCount(double fUnoccluded, int maxRays) {
    if (maxRays <= 1) return 1;
    // About one ray per 1e-4 of form factor, growing as its square root: near pairs (large F,
    // sharp shadows matter most) get up to maxRays, distant ones a single ray.
    int n = static_cast<int>(std::ceil(std::sqrt(std::max(fUnoccluded, 0.0) / 1e-4)));
    return std::clamp(n, 1, maxRays);
}

namespace {

/// The pair-seeded sampling shared by every point-to-patch estimate: exact unoccluded form
/// factors of the patch's polygons clipped to the receiver's hemisphere, then `rays` samples
/// stratified over them by form factor, each weighted by the point-to-point kernel relative
/// to its sampling density. `visit(origin, targets, visible, rays)` writes each sample's
/// visibility term (1 visible, 0 blocked; a difference of two such terms for
/// formFactorChange) and counts the rays it traced; the result
/// is unoccluded × Σ w·visit / Σ w (a ratio estimator, exact when nothing blocks and when
/// everything does).
/// Per-thread scratch of estimatePointToPatch: one thread-local lookup per pair.
struct PairScratch {
    std::vector<std::vector<Vec3>> polys;  ///< per polygon: its part above the horizon
    std::vector<double> f;                 ///< per polygon: its unoccluded form factor
    std::vector<Vec3> polygon;
    std::vector<Vec3> normals;  ///< per polygon: unit normal (the plane's, clipping keeps it)
    std::vector<std::vector<double>> fans;
    std::vector<double> areaOverF;
    std::vector<Vec3> targets;
    std::vector<double> weights;
    std::vector<int> visible;
};

PairScratch& pairScratch() {
    static thread_local PairScratch scratch;
    return scratch;
}

template <class Visit>
PointToPatch estimatePointToPatch(const Discretization& disc, const RayTracer& tracer,
                                  const Vec3& x, const Vec3& n, int patch,
                                  std::uint64_t receiverKey, std::uint64_t seed, int maxRays,
                                  Visit&& visit) {
    PointToPatch out;
    const Patch& P = disc.patches()[patch];
    PairScratch& sc = pairScratch();

    // Exact unoccluded form factor of each element polygon of the patch (or of its outline
    // when planar), keeping the part above the receiver's horizon for sampling.
    auto& polys = sc.polys;
    auto& f = sc.f;
    auto& normals = sc.normals;
    double total = 0;
    const std::size_t count = P.outline.empty() ? P.elements.size() : 1;
    if (polys.size() < count) polys.resize(count);
    f.resize(count);
    normals.resize(count);
    for (std::size_t k = 0; k < count; ++k) {
        bool wasClipped = false;
        if (P.outline.empty()) {
            const Element& el = disc.elements()[P.elements[k]];
            const auto& pos = disc.objects()[el.object].worldPositions;
            sc.polygon.clear();
            for (int v : el.vertices) sc.polygon.push_back(pos[v]);
            normals[k] = el.normal;
            total += f[k] = clippedFormFactor(x, n, sc.polygon, el.normal, polys[k], wasClipped);
        } else {
            normals[k] = P.normal;
            total += f[k] = clippedFormFactor(x, n, P.outline, P.normal, polys[k], wasClipped);
        }
    }
    out.unoccluded = total;
    if (!(total > 0)) return out;

    const int rays = visibilityRayCount(total, maxRays);
    PairRandom rng{hashPair(hashPair(seed, receiverKey), static_cast<std::uint64_t>(patch))};
    const double eps = tracer.epsilon();
    const Vec3 origin = x + n * eps;
    // The pair's samples first (targets and weights), then their visibility in one call.
    // Per sampled polygon, once: its fan triangles' cumulative doubled areas and the weight
    // factor A_k / F_k relative to the sampling density (∝ F_k / A_k).
    auto& fans = sc.fans;
    auto& areaOverF = sc.areaOverF;
    if (fans.size() < count) fans.resize(count);
    areaOverF.assign(count, -1.0);
    auto& targets = sc.targets;
    auto& weights = sc.weights;
    targets.resize(static_cast<std::size_t>(rays));
    weights.resize(static_cast<std::size_t>(rays));
    std::size_t taken = 0;
    double wAll = 0;
    const double stratum = total / rays;
    for (int s = 0; s < rays; ++s) {
        double u = (s + rng.next()) * stratum;
        // The polygon by form factor; polygons with nothing above the horizon are never taken.
        std::size_t k = 0;
        while (k + 1 < count && (u > f[k] || !(f[k] > 0))) u -= f[k++];
        while (!(f[k] > 0)) --k;  // rounding past the last polygon seen; total > 0 bounds it
        double r1 = rng.next(), r2 = rng.next();
        if (areaOverF[k] < 0) {
            fanAreas(polys[k], fans[k]);
            areaOverF[k] = 0.5 * fans[k].back() / f[k];
        }
        Vec3 y = samplePolygon(polys[k], fans[k], std::min(u / f[k], 1.0), r1, r2);
        Vec3 d = y - origin;
        double dd = glm::dot(d, d);
        if (!(dd > 0)) continue;
        const Vec3& ny = normals[k];
        // Point-to-point kernel cos·cos/r², over the sampling density: d is unnormalized, so
        // the cosines carry a factor r² more.
        double w = std::max(0.0, glm::dot(n, d)) * std::max(0.0, -glm::dot(ny, d)) * areaOverF[k] /
                   (dd * dd);
        wAll += w;
        // Leave the source surface along its normal (toward x, which is in front of it), so
        // rays grazing the source plane do not hit the source itself in float precision.
        targets[taken] = y + ny * eps;
        weights[taken] = w;
        ++taken;
    }
    targets.resize(taken);
    auto& visible = sc.visible;
    visible.assign(taken, 0);
    visit(origin, targets, visible, out.rays);
    double wVisible = 0;
    for (std::size_t i = 0; i < taken; ++i) wVisible += weights[i] * visible[i];
    out.visible = wAll > 0 ? total * (wVisible / wAll) : 0;
    return out;
}

}  // namespace

PointToPatch formFactorToPatch(const Discretization& disc, const RayTracer& tracer, const Vec3& x,
                               const Vec3& n, int patch, std::uint64_t receiverKey,
                               std::uint64_t seed, int maxRays, const Visibility& visibility) {
    return estimatePointToPatch(
        disc, tracer, x, n, patch, receiverKey, seed, maxRays,
        [&](const Vec3& from, const std::vector<Vec3>& to, std::vector<int>& visible, int& rays) {
            const int count = static_cast<int>(to.size());
            if (count < 4) {
                for (int i = 0; i < count; ++i)
                    visible[i] = tracer.occluded(from, to[i], visibility) ? 0 : 1;
                rays += count;
                return;
            }
            // The samples of one pair leave one point toward one patch: coherent packets.
            bool blocked[8];
            for (int i = 0; i < count; i += 8) {
                const int m = std::min(8, count - i);
                tracer.occluded8(from, to.data() + i, m, blocked, visibility);
                for (int k = 0; k < m; ++k) visible[i + k] = blocked[k] ? 0 : 1;
            }
            rays += count;
        });
}

PointToPatch formFactorChange(const Discretization& disc, const RayTracer& tracer, const Vec3& x,
                              const Vec3& n, int patch, std::uint64_t receiverKey,
                              std::uint64_t seed, int maxRays, const Visibility& before,
                              const Visibility& after, const Visibility& changed) {
    return estimatePointToPatch(
        disc, tracer, x, n, patch, receiverKey, seed, maxRays,
        [&](const Vec3& from, const std::vector<Vec3>& to, std::vector<int>& visible, int& rays) {
            for (std::size_t i = 0; i < to.size(); ++i) {
                // A sample that misses every changed object has the same visibility in both
                // worlds: its terms cancel exactly.
                ++rays;
                if (!tracer.occluded(from, to[i], changed)) continue;
                rays += 2;
                visible[i] = (tracer.occluded(from, to[i], after) ? 0 : 1) -
                             (tracer.occluded(from, to[i], before) ? 0 : 1);
            }
        });
}

}  // namespace penumbra
