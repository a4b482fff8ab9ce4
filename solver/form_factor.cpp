#include "solver/form_factor.h"

#include <algorithm>
#include <cmath>
#include <cstring>

#include "core/random.h"
#include "solver/contour_integral.h"
#include "solver/discretization.h"
#include "solver/ray_tracer.h"

namespace penumbra {

namespace {

/// Uniform point in a convex polygon: the fan triangle by area (r0 ∈ [0, 1]; `fans` from
/// accumulateFanAreas), then a uniform point of it.
Vec3 samplePolygon(const std::vector<Vec3>& poly, const std::vector<double>& fans, double r0,
                   double r1, double r2) {
    double pick = r0 * fans.back();
    std::size_t i = 0;
    while (i + 1 < fans.size() && pick > fans[i]) ++i;
    double s = std::sqrt(r1);
    return (1 - s) * poly[0] + s * (1 - r2) * poly[i + 1] + s * r2 * poly[i + 2];
}

}  // namespace

namespace {

/// Whether (x, n) sees all of `polygon` (front side toward `pn`, at least three vertices): x
/// in front of its plane (one-sided) and no vertex below x's horizon. clippedFormFactor's and
/// formFactorsToPatch's one test.
bool seesWhole(const Vec3& x, const Vec3& n, const std::vector<Vec3>& polygon, const Vec3& pn) {
    if (glm::dot(x - polygon[0], pn) <= 0) return false;
    bool below = false;
    for (const Vec3& v : polygon) below = below || glm::dot(v - x, n) < 0;
    return !below;
}

/// Lambert's contour integral over `polygon` (front side toward `pn`) clipped to the
/// hemisphere above (x, n). `usesClipped` tells where the part x sees is: true, in `clipped`
/// (the horizon cut the polygon; empty when nothing is seen); false, the polygon itself (all
/// of it above the horizon, nothing copied).
double clippedFormFactor(const Vec3& x, const Vec3& n, const std::vector<Vec3>& polygon,
                         const Vec3& pn, std::vector<Vec3>& clipped, bool& usesClipped) {
    usesClipped = false;
    const std::size_t m = polygon.size();
    if (m < 3) {
        usesClipped = true;
        clipped.clear();
        return 0;
    }
    if (seesWhole(x, n, polygon, pn))
        return std::abs(integrateContour(x, n, polygon.data(), m)) / (2 * M_PI);
    // One-sided: the point must be in front of the polygon.
    if (glm::dot(x - polygon[0], pn) <= 0) {
        usesClipped = true;
        clipped.clear();
        return 0;
    }

    // Clip to the receiver's hemisphere, dot(p − x, n) ≥ 0 (Sutherland–Hodgman); each
    // vertex's height is computed once. The output has a vertex per kept vertex and per sign
    // change: at most m + ⌊m/2⌋ (signs alternating, as rounding can make them for a polygon
    // lying in the horizon plane).
    usesClipped = true;
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
        da = db;
    }
    if (count < 3) {
        clipped.clear();
        return 0;
    }
    clipped.resize(count);
    return std::abs(integrateContour(x, n, out, count)) / (2 * M_PI);
}

}  // namespace

double polygonFormFactor(const Vec3& x, const Vec3& n, const std::vector<Vec3>& polygon) {
    thread_local std::vector<Vec3> clipped;
    bool usesClipped = false;
    return clippedFormFactor(x, n, polygon, newellNormal(polygon), clipped, usesClipped);
}

int visibilityRayCount(double fUnoccluded, int maxRays) {
    if (maxRays <= 1) return 1;
    // About one ray per 1e-4 of form factor, growing as its square root: near pairs (large F,
    // sharp shadows matter most) get up to maxRays, distant ones a single ray.
    int n = static_cast<int>(std::ceil(std::sqrt(std::max(fUnoccluded, 0.0) * 1e4)));
    return std::clamp(n, 1, maxRays);
}

namespace {

/// Per-thread scratch of estimatePointToPatch: one thread-local lookup per pair.
struct PairScratch {
    std::vector<std::vector<Vec3>> polys;  ///< per polygon: its part above the horizon
    std::vector<double> f;                 ///< per polygon: its unoccluded form factor
    std::vector<Vec3> polygon;
    std::vector<Vec3> normals;  ///< per polygon: unit normal (the plane's, clipping keeps it)
    std::vector<std::vector<double>> fans;          ///< per polygon: fan areas, when computed
    std::vector<const std::vector<Vec3>*> source;   ///< per polygon: what is sampled
    std::vector<const std::vector<double>*> fanOf;  ///< per polygon: its fans, once known
    std::vector<double> areaOverF;
    std::vector<Vec3> points;    ///< per sample: its point on the patch
    std::vector<int> polygonOf;  ///< per sample: the polygon it was taken from
    std::vector<Vec3> targets;   ///< per sample: the point off the surface, where its ray ends
    std::vector<double> weights;
    std::vector<int> visible;
};

PairScratch& pairScratch() {
    static thread_local PairScratch scratch;
    return scratch;
}

/// Exact unoccluded form factor of each of the `count` polygons of patch P seen from (x, n):
/// its element polygons, or its outline when planar (`wholeOutline`, when given, is the whole
/// outline's form factor, known to be in front of x and above its horizon:
/// formFactorsToPatch). Keeps the part above the receiver's horizon for sampling in `sc`: the
/// polygon itself when the horizon does not cut it (with the patch's own fan areas for an
/// outline), else its clipped part (fans computed when first sampled). Returns their sum.
double unoccludedFormFactors(const Discretization& disc, const Patch& P, const Vec3& x,
                             const Vec3& n, std::size_t count, const double* wholeOutline,
                             PairScratch& sc) {
    auto& polys = sc.polys;
    auto& f = sc.f;
    auto& normals = sc.normals;
    auto& source = sc.source;
    auto& fans = sc.fans;
    auto& fanOf = sc.fanOf;
    double total = 0;
    // The scratch only grows: a pair sizes nothing and initializes nothing it does not use.
    if (f.size() < count) {
        polys.resize(count);
        fans.resize(count);
        f.resize(count);
        normals.resize(count);
        source.resize(count);
        fanOf.resize(count);
        sc.areaOverF.resize(count);
    }
    for (std::size_t k = 0; k < count; ++k) {
        bool usesClipped = false;
        if (P.outline.empty()) {
            const Element& el = disc.elements()[P.elements[k]];
            const auto& pos = disc.objects()[el.object].worldPositions;
            sc.polygon.clear();
            for (int v : el.vertices) sc.polygon.push_back(pos[v]);
            normals[k] = el.normal;
            total += f[k] = clippedFormFactor(x, n, sc.polygon, el.normal, polys[k], usesClipped);
            if (!usesClipped) polys[k].swap(sc.polygon);
            source[k] = &polys[k];
            fanOf[k] = nullptr;
        } else {
            normals[k] = P.normal;
            total += f[k] =
                wholeOutline ? *wholeOutline
                             : clippedFormFactor(x, n, P.outline, P.normal, polys[k], usesClipped);
            source[k] = usesClipped ? &polys[k] : &P.outline;
            fanOf[k] = usesClipped || P.outlineFans.empty() ? nullptr : &P.outlineFans;
        }
    }
    return total;
}

/// The pair's `rays` samples over the polygons unoccludedFormFactors left in `sc` (their sum
/// `total`), stratified by form factor: each one's point, polygon and ray target (off the
/// surface) in `sc`, and per sampled polygon the weight factor A_k / F_k relative to the
/// sampling density (∝ F_k / A_k). `pairHash` seeds the sample numbers. Returns how many were
/// taken (a sample at the receiver's own point is not).
int placeSamples(const Patch& P, std::size_t count, int rays, double total, std::uint64_t pairHash,
                 const Vec3& origin, double eps, PairScratch& sc) {
    const auto& f = sc.f;
    const auto& normals = sc.normals;
    const auto& source = sc.source;
    auto& fans = sc.fans;
    auto& fanOf = sc.fanOf;
    auto& areaOverF = sc.areaOverF;
    std::fill_n(areaOverF.begin(), count, -1.0);
    const std::size_t most = static_cast<std::size_t>(rays);
    if (sc.targets.size() < most) {
        sc.points.resize(most);
        sc.polygonOf.resize(most);
        sc.targets.resize(most);
        sc.weights.resize(most);
        sc.visible.resize(most);
    }
    Vec3* const points = sc.points.data();
    int* const polygonOf = sc.polygonOf.data();
    Vec3* const targets = sc.targets.data();
    int taken = 0;
    const double stratum = total / rays;
    // A sample's numbers follow Kronecker sequences q_s = (q_0 + s·α) mod 1, each started at a
    // pair-seeded offset (a Cranley–Patterson rotation): every sample is uniform, the pair's
    // samples are spread evenly, and a sample costs an addition per number instead of a hash.
    // The steps: the golden ratio's 1/φ for a lone coordinate (the best spread in one
    // dimension) and R2's (1/ρ, 1/ρ²), ρ³ = ρ + 1 (Roberts 2018), for a pair. (R3's steps were
    // used first: its second one, 0.671, is so near 2/3 that 8 to 40 samples bunch into three
    // bands along that coordinate, worse than random numbers for an edge across it.)
    constexpr double kGolden = 0.61803398874989485, kR2x = 0.75487766624669276,
                     kR2y = 0.56984029099805327;
    constexpr double kUnit = 0x1.0p-21;
    constexpr std::uint64_t kMask = (1u << 21) - 1;
    double q0 = static_cast<double>(pairHash >> 43) * kUnit;
    double q1 = static_cast<double>((pairHash >> 22) & kMask) * kUnit;
    double q2 = static_cast<double>((pairHash >> 1) & kMask) * kUnit;
    auto advance = [](double& q, double step) {
        q += step;
        q -= q >= 1 ? 1.0 : 0.0;
    };
    // Leave the source surface along its normal (toward x, which is in front of it), so rays
    // grazing the source plane do not hit the source itself in float precision. A sample at
    // the receiver's own point (d = 0) is not taken.
    auto addSample = [&](const Vec3& y, std::size_t k) {
        const Vec3 d = y - origin;
        const double dd = glm::dot(d, d);
        if (!(dd > 0)) return;
        points[taken] = y;
        polygonOf[taken] = static_cast<int>(k);
        targets[taken] = y + normals[k] * eps;
        ++taken;
    };
    if (count == 1 && source[0] == &P.outline && P.parallelogram) {
        // The whole of a parallelogram outline is seen: its point (a, b), a stratified by
        // sample (jitter q0, step 1/ρ) and b by the golden-ratio sequence (q1): a lattice-like
        // set even along both sides, with no search and no square root.
        const Vec3 o = P.outline[0], eu = P.outline[1] - o, ev = P.outline[3] - o;
        areaOverF[0] = P.area / f[0];
        for (int s = 0; s < rays; ++s) {
            if (s > 0) advance(q0, kR2x), advance(q1, kGolden);
            addSample(o + ((s + q0) / rays) * eu + q1 * ev, 0);
        }
    } else {
        // The jitter within the stratum by the golden-ratio sequence (q0), the point in the
        // chosen polygon by R2 (q1, q2).
        for (int s = 0; s < rays; ++s) {
            if (s > 0) advance(q0, kGolden), advance(q1, kR2x), advance(q2, kR2y);
            double u = (s + q0) * stratum;
            // The polygon by form factor; polygons with nothing above the horizon are never
            // taken.
            std::size_t k = 0;
            while (k + 1 < count && (u > f[k] || !(f[k] > 0))) u -= f[k++];
            while (!(f[k] > 0)) --k;  // rounding past the last polygon seen; total > 0 bounds it
            if (areaOverF[k] < 0) {
                if (!fanOf[k]) {
                    accumulateFanAreas(*source[k], fans[k]);
                    fanOf[k] = &fans[k];
                }
                areaOverF[k] = 0.5 * fanOf[k]->back() / f[k];
            }
            addSample(samplePolygon(*source[k], *fanOf[k], std::min(u / f[k], 1.0), q1, q2), k);
        }
    }
    return taken;
}

/// The ratio estimate unoccluded × Σ w·visible / Σ w over the `taken` samples in `sc`, whose
/// visibility terms are set, seen from `origin` with unit normal n.
double ratioEstimate(PairScratch& sc, int taken, const Vec3& origin, const Vec3& n, double total) {
    const Vec3* const points = sc.points.data();
    const int* const polygonOf = sc.polygonOf.data();
    double* const weights = sc.weights.data();
    const int* const visible = sc.visible.data();
    const auto& normals = sc.normals;
    const auto& areaOverF = sc.areaOverF;
    // Each sample's weight is the point-to-point kernel cos·cos/r² over the sampling density
    // (A_k / F_k of its polygon): d is unnormalized, so the cosines carry a factor r² more.
    auto weightOf = [&](int i) {
        const Vec3 d = points[i] - origin;
        const double dd = glm::dot(d, d);
        const int k = polygonOf[i];
        return std::max(0.0, glm::dot(n, d)) * std::max(0.0, -glm::dot(normals[k], d)) *
               areaOverF[k] / (dd * dd);
    };
    // Every sample with the same term (all seen, the common case, or all blocked): the ratio
    // estimate is that term once any weight is positive, and 0 when none is (every sample at
    // the receiver's or the source's horizon, where the form factor is rounding).
    bool same = true;
    for (int i = 1; i < taken; ++i) same = same && visible[i] == visible[0];
    if (same) {
        for (int i = 0; i < taken; ++i)
            if (weightOf(i) > 0) return total * visible[0];
        return 0;
    }
    for (int i = 0; i < taken; ++i) weights[i] = weightOf(i);
    double wAll = 0;
    for (int i = 0; i < taken; ++i) wAll += weights[i];
    double wVisible = 0;
    for (int i = 0; i < taken; ++i) wVisible += weights[i] * visible[i];
    return wAll > 0 ? total * (wVisible / wAll) : 0;
}

/// The pair-seeded sampling shared by every point-to-patch estimate: exact unoccluded form
/// factors of the patch's polygons clipped to the receiver's hemisphere, then `rays` samples
/// stratified over them by form factor, each weighted by the point-to-point kernel relative
/// to its sampling density. `visit(origin, targets, count, visible, rays)` writes each sample's
/// visibility term (1 visible, 0 blocked; a difference of two such terms for
/// formFactorChange) and counts the rays it traced; the result
/// is unoccluded × Σ w·visit / Σ w (a ratio estimator, exact when nothing blocks and when
/// everything does). The weights are computed only when the samples' terms differ: when
/// every term is the same v, the estimate is unoccluded × v whatever the weights.
template <class Visit>
PointToPatch estimatePointToPatch(const Discretization& disc, const RayTracer& tracer,
                                  const Vec3& x, const Vec3& n, int patch,
                                  std::uint64_t receiverKey, std::uint64_t seed, int maxRays,
                                  const double* wholeOutline, Visit&& visit) {
    PointToPatch out;
    const Patch& P = disc.patches()[patch];
    PairScratch& sc = pairScratch();
    const std::size_t count = P.outline.empty() ? P.elements.size() : 1;
    const double total = unoccludedFormFactors(disc, P, x, n, count, wholeOutline, sc);
    out.unoccluded = total;
    if (!(total > 0)) return out;

    const int rays = visibilityRayCount(total, maxRays);
    const double eps = tracer.epsilon();
    const Vec3 origin = x + n * eps;
    // The pair's samples first (targets and weights), then their visibility in one call.
    const std::uint64_t h =
        hashPair(hashPair(seed, receiverKey), static_cast<std::uint64_t>(patch));
    const int taken = placeSamples(P, count, rays, total, h, origin, eps, sc);
    int* const visible = sc.visible.data();
    std::fill_n(visible, taken, 0);
    visit(origin, sc.targets.data(), taken, visible, out.rays);
    out.visible = ratioEstimate(sc, taken, origin, n, total);
    return out;
}

/// The visibility of formFactorToPatch's samples: the segments from one point toward one patch
/// as coherent packets.
auto occlusionVisit(const RayTracer& tracer, const Visibility& visibility) {
    return [&tracer, &visibility](const Vec3& from, const Vec3* to, int count, int* visible,
                                  int& rays) {
        if (count < 2) {
            for (int i = 0; i < count; ++i)
                visible[i] = tracer.occluded(from, to[i], visibility) ? 0 : 1;
            rays += count;
            return;
        }
        bool blocked[16];
        for (int i = 0; i < count; i += 16) {
            const int m = std::min(16, count - i);
            tracer.occludedPacket(from, to + i, m, blocked, visibility);
            for (int k = 0; k < m; ++k) visible[i + k] = blocked[k] ? 0 : 1;
        }
        rays += count;
    };
}

}  // namespace

PointToPatch formFactorToPatch(const Discretization& disc, const RayTracer& tracer, const Vec3& x,
                               const Vec3& n, int patch, std::uint64_t receiverKey,
                               std::uint64_t seed, int maxRays, const Visibility& visibility) {
    return estimatePointToPatch(disc, tracer, x, n, patch, receiverKey, seed, maxRays, nullptr,
                                occlusionVisit(tracer, visibility));
}

void formFactorsToPatch(const Discretization& disc, const RayTracer& tracer, int patch,
                        const Receiver* receivers, int count, std::uint64_t seed, int maxRays,
                        const Visibility& visibility, PointToPatch* out) {
    const Patch& P = disc.patches()[patch];
    const auto visit = occlusionVisit(tracer, visibility);
    auto one = [&](int i, const double* whole) {
        const Receiver& r = receivers[i];
        out[i] =
            estimatePointToPatch(disc, tracer, r.x, r.n, patch, r.key, seed, maxRays, whole, visit);
    };
    if (P.outline.size() < 3) {
        for (int i = 0; i < count; ++i) one(i, nullptr);
        return;
    }
    constexpr int L = kContourLanes;
    const std::vector<Vec3>& outline = P.outline;
    for (int base = 0; base < count; base += L) {
        const int m = std::min(L, count - base);
        Vec3 xs[L], ns[L];
        bool whole[L];
        for (int l = 0; l < L; ++l) {
            // Unused lanes repeat the first receiver, so every lane computes finite numbers.
            const Receiver& r = receivers[base + (l < m ? l : 0)];
            xs[l] = r.x;
            ns[l] = r.n;
            // Receivers that do not see the whole outline take their own path.
            whole[l] = seesWhole(r.x, r.n, outline, P.normal);
        }
        double sums[L];
        integrateContourLanes(xs, ns, outline.data(), outline.size(), sums);
        for (int l = 0; l < m; ++l) {
            const double f = std::abs(sums[l]) / (2 * M_PI);
            one(base + l, whole[l] ? &f : nullptr);
        }
    }
}

PointToPatch formFactorChange(const Discretization& disc, const RayTracer& tracer, const Vec3& x,
                              const Vec3& n, int patch, std::uint64_t receiverKey,
                              std::uint64_t seed, int maxRays, const Visibility& before,
                              const Visibility& after, const Visibility& changed,
                              ChangedObjectsIn where) {
    return estimatePointToPatch(
        disc, tracer, x, n, patch, receiverKey, seed, maxRays, nullptr,
        [&](const Vec3& from, const Vec3* to, int count, int* visible, int& rays) {
            for (int i = 0; i < count; i += 16) {
                const int m = std::min(16, count - i);
                // A sample that misses every changed object has the same visibility in both
                // worlds: its terms cancel exactly.
                bool meets[16];
                tracer.occludedPacket(from, to + i, m, meets, changed);
                rays += m;
                Vec3 met[16];
                int which[16], k = 0;
                for (int s = 0; s < m; ++s)
                    if (meets[s]) met[k] = to[i + s], which[k++] = i + s;
                if (k == 0) continue;
                // The world holding every changed object blocks these samples; the other
                // world decides.
                bool blockedBefore[16], blockedAfter[16];
                if (where == ChangedObjectsIn::Before)
                    std::fill_n(blockedBefore, k, true);
                else
                    tracer.occludedPacket(from, met, k, blockedBefore, before), rays += k;
                if (where == ChangedObjectsIn::After)
                    std::fill_n(blockedAfter, k, true);
                else
                    tracer.occludedPacket(from, met, k, blockedAfter, after), rays += k;
                for (int s = 0; s < k; ++s)
                    visible[which[s]] = (blockedAfter[s] ? 0 : 1) - (blockedBefore[s] ? 0 : 1);
            }
        });
}

}  // namespace penumbra
