#pragma once
// The progressive solver's internals, shared by its three source files and by nothing else:
// progressive_solver.cpp (propagation: Cohen et al. 1988's shots, the stochastic tail,
// adaptive subdivision, queries), redistribution.cpp (George et al. 1990's change log and
// redistribution shots) and drag_preview.cpp (the drag preview's temporary buffer and its
// gathered shadow).
//
// Index: sampling helpers · receiver bounds · ChangeEntry · ProgressiveSolver::Impl

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <utility>
#include <vector>

#include "core/random.h"
#include "solver/indexed_heap.h"
#include "solver/progressive_solver.h"

namespace penumbra {

namespace solver_detail {

inline double energyKey(const Rgb& unshot, double area) {
    return (std::abs(unshot.x) + std::abs(unshot.y) + std::abs(unshot.z)) * area;
}

inline bool isZero(const Rgb& c) { return c.x == 0 && c.y == 0 && c.z == 0; }

/// Per channel, the fraction `part` is of `whole` (0 where whole is 0): the share of a shot
/// radiosity that is emission, which every irradiance the shot sends carries too.
inline Rgb shareOf(const Rgb& part, const Rgb& whole) {
    Rgb s(0.0);
    for (int c = 0; c < 3; ++c)
        if (whole[c] != 0) s[c] = part[c] / whole[c];
    return s;
}

/// Deterministic uniform numbers in [0, 1) for one stochastic ray: SplitMix64 (Steele,
/// Lea, Flood 2014), a Weyl sequence through a 64-bit mixer, seeded per ray by hashPair so
/// a ray's numbers do not depend on which thread traces it. Each 64-bit output gives three
/// numbers of 21 bits (steps of 4.8e-7, about four float ulps at 1: far below an element or a
/// ray's angular spread): a ray's six or so numbers cost two mixes instead of six.
struct RayRandom {
    std::uint64_t state;
    std::uint64_t word = 0;
    int left = 0;
    double next() {
        if (left == 0) {
            word = splitmix64(state);
            state += 0x9e3779b97f4a7c15ull;
            left = 3;
        }
        const double u = static_cast<double>(word >> 43) * 0x1.0p-21;
        word <<= 21;
        --left;
        return u;
    }
};

/// An orthonormal frame (tx, ty) completing unit vector z, without a square root or a branch
/// on the axes (Duff et al. 2017, "Building an Orthonormal Basis, Revisited").
inline void frameAround(const Vec3& z, Vec3& tx, Vec3& ty) {
    const double sign = std::copysign(1.0, z.z);
    const double a = -1.0 / (sign + z.z);
    const double b = z.x * z.y * a;
    tx = Vec3(1.0 + sign * z.x * z.x * a, sign * b, -sign * z.x);
    ty = Vec3(b, sign + z.y * z.y * a, -z.y);
}

/// A gather's ray for stratum k of nx × ny over (φ, sin²θ) about the frame (tx, ty, n), with
/// its two numbers (ru, rv) within the stratum: a cosine-distributed direction.
inline Vec3 gatherDirection(int k, int nx, int ny, double ru, double rv, const Vec3& tx,
                            const Vec3& ty, const Vec3& n) {
    const double u = (k % nx + ru) / nx, v = (k / nx + rv) / ny;
    const double phi = 2 * M_PI * u, rr = std::sqrt(v);
    return rr * std::cos(phi) * tx + rr * std::sin(phi) * ty + std::sqrt(std::max(0.0, 1 - v)) * n;
}

/// A direction in the cone of half-angle acos(cosMax) about unit `axis`, whose frame (tx, ty,
/// axis) is given, uniform in solid angle for (u, v) uniform in [0, 1)²: φ = 2πu,
/// cos θ = 1 − v (1 − cosMax).
inline Vec3 coneDirection(const Vec3& axis, const Vec3& tx, const Vec3& ty, double cosMax, double u,
                          double v) {
    const double cosT = 1 - v * (1 - cosMax);
    const double sinT = std::sqrt(std::max(0.0, 1 - cosT * cosT));
    const double phi = 2 * M_PI * u;
    return sinT * std::cos(phi) * tx + sinT * std::sin(phi) * ty + cosT * axis;
}

/// A cosine-distributed direction about unit normal n, whose frame (tx, ty, n) is given
/// (Malley's method: a uniform point of the unit disk, by rejection from its square, lifted to
/// the hemisphere).
inline Vec3 cosineDirection(const Vec3& n, const Vec3& tx, const Vec3& ty, RayRandom& rng) {
    double a, b, r2;
    do {
        a = 2 * rng.next() - 1;
        b = 2 * rng.next() - 1;
        r2 = a * a + b * b;
    } while (r2 > 1);
    return a * tx + b * ty + std::sqrt(std::max(0.0, 1 - r2)) * n;
}

/// std::lower_bound over a[0, n) (the first index whose value is not below x; n when none),
/// without branches on the comparisons: the searches of the stochastic rays go to random
/// places, so a branching bisection mispredicts about every other step.
inline std::size_t lowerBound(const double* a, std::size_t n, double x) {
    const double* first = a;
    while (n > 1) {
        const std::size_t half = n / 2;
        first = first[half - 1] < x ? first + half : first;
        n -= half;
    }
    return static_cast<std::size_t>(first - a) + (n == 1 && first[0] < x ? 1 : 0);
}

/// The shooter of a batch ray at u ∈ [0, total]: the first whose cumulative power `cdf`
/// reaches u (lower_bound), clamped to the last (rounding). A block's rays come in order of
/// u (each term of u's formula grows with the ray index), so from the previous ray's answer
/// `from` the search steps on: every entry before it is below the previous u. `from` =
/// cdf.size() starts a block with a bisection.
inline std::size_t shooterAt(const std::vector<double>& cdf, std::size_t from, double u) {
    std::size_t k = from;
    if (k >= cdf.size()) {
        k = lowerBound(cdf.data(), cdf.size(), u);
    } else {
        while (k < cdf.size() && cdf[k] < u) ++k;
    }
    return std::min(k, cdf.size() - 1);
}

/// Uniform points of one shooting patch: its fan triangles flattened with their cumulative
/// doubled areas, so a ray's point costs a search in a short array instead of a walk over
/// element records. A batch's rays are ordered by shooter, so each block of rays sets this up
/// about once per shooter it meets; the result does not depend on where blocks start.
class PatchPoints {
public:
    void set(const Discretization& disc, const Patch& patch) {
        mTriangles.clear();
        mCumulative.clear();
        double sum = 0;
        for (int e : patch.elements) {
            const Element& el = disc.elements()[e];
            const auto& pos = disc.objects()[el.object].worldPositions;
            const Vec3& p0 = pos[el.vertices[0]];
            for (std::size_t i = 1; i + 1 < el.vertices.size(); ++i) {
                Triangle& tri = mTriangles.emplace_back();
                tri.p0 = p0;
                tri.e1 = pos[el.vertices[i]] - p0;
                tri.e2 = pos[el.vertices[i + 1]] - p0;
                tri.normal = el.normal;
                frameAround(el.normal, tri.tx, tri.ty);
                mCumulative.push_back(sum += glm::length(glm::cross(tri.e1, tri.e2)));
            }
        }
    }

    /// A uniform point of the patch (three numbers of `rng`) and its surface's frame: the
    /// normal and two tangents (frameAround's).
    void sample(RayRandom& rng, Vec3& point, Vec3& normal, Vec3& tx, Vec3& ty) const {
        // The first triangle whose cumulative area reaches the pick (the last if rounding
        // leaves none). Large patches have dozens of triangles of about equal area, so the
        // search starts where equal areas would put the pick and steps to the answer (a
        // bisection's six dependent loads cost a tenth of large's batch set-up).
        const std::size_t last = mCumulative.size() - 1;
        const double r = rng.next(), pick = r * mCumulative[last];
        std::size_t i = std::min(static_cast<std::size_t>(r * static_cast<double>(last + 1)), last);
        while (i > 0 && !(mCumulative[i - 1] < pick)) --i;
        while (i < last && mCumulative[i] < pick) ++i;
        const Triangle* t = &mTriangles[i];
        const double s = std::sqrt(rng.next()), r2 = rng.next();
        point = t->p0 + (s * (1 - r2)) * t->e1 + (s * r2) * t->e2;
        normal = t->normal;
        tx = t->tx;
        ty = t->ty;
    }

private:
    struct Triangle {
        Vec3 p0, e1, e2, normal, tx, ty;
    };
    std::vector<Triangle> mTriangles;
    std::vector<double> mCumulative;  ///< doubled area of the patch's triangles up to each
};

/// Balls holding the receiving points (Discretization::receiver) of every patch, and per object
/// a binary tree of balls over its patches (leaves of a few patches): redistribution's shaft
/// test rejects whole groups of patches before testing patches and elements. Objects appended
/// since the last update get their trees on the next update; a changed element count of the
/// objects already there (subdivision) rebuilds everything.
struct ReceiverBounds {
    struct Ball {
        Vec3 centre{0};
        double radius = -1;  ///< -1: holds no receiver
    };
    struct Node {
        Ball ball;
        int first = 0, count = 0;   ///< its patches: order[first, first + count)
        int left = -1, right = -1;  ///< children (-1 for a leaf)
    };
    static constexpr int kLeafPatches = 8;
    std::vector<Ball> patches;     ///< per patch
    std::vector<Node> nodes;       ///< every object's tree
    std::vector<int> roots;        ///< per object: its root node, -1 without receivers
    std::vector<int> order;        ///< patch indices, each node's contiguous
    std::size_t elementCount = 0;  ///< elements of the objects already built
    void update(const Discretization& disc) {
        const std::size_t nObjects = disc.objects().size();
        std::size_t built = roots.size(), expected = elementCount;
        for (std::size_t o = built; o < nObjects; ++o)
            expected += static_cast<std::size_t>(disc.elementRange(static_cast<int>(o)).second);
        if (built == nObjects && expected == disc.elements().size()) return;
        if (expected != disc.elements().size()) {
            // Elements of existing objects changed: start again.
            patches.clear();
            nodes.clear();
            roots.clear();
            order.clear();
            built = 0;
        }
        const std::size_t oldPatches = patches.size();
        patches.resize(disc.patches().size());
        std::vector<std::vector<int>> byObject(nObjects);
        for (std::size_t p = oldPatches; p < disc.patches().size(); ++p) {
            const Patch& P = disc.patches()[p];
            Ball& b = patches[p];
            b = Ball{P.centroid, -1};
            for (int e : P.elements)
                b.radius = std::max(b.radius, glm::length(disc.receiver(e) - P.centroid));
            if (b.radius >= 0 && static_cast<std::size_t>(P.object) >= built)
                byObject[P.object].push_back(static_cast<int>(p));
        }
        roots.resize(nObjects, -1);
        for (std::size_t o = built; o < nObjects; ++o) {
            if (byObject[o].empty()) continue;
            const int first = static_cast<int>(order.size());
            order.insert(order.end(), byObject[o].begin(), byObject[o].end());
            roots[o] = build(first, static_cast<int>(order.size()));
        }
        elementCount = disc.elements().size();
    }

private:
    /// The node over order[begin, end): its ball, then halves split at the median of the
    /// patch centres along their longest extent.
    int build(int begin, int end) {
        Vec3 lo(std::numeric_limits<double>::max()), hi(-std::numeric_limits<double>::max());
        Vec3 clo = lo, chi = hi;
        for (int i = begin; i < end; ++i) {
            const Ball& b = patches[order[i]];
            lo = glm::min(lo, b.centre - Vec3(b.radius));
            hi = glm::max(hi, b.centre + Vec3(b.radius));
            clo = glm::min(clo, b.centre);
            chi = glm::max(chi, b.centre);
        }
        Node node;
        node.ball.centre = 0.5 * (lo + hi);
        node.ball.radius = 0;
        for (int i = begin; i < end; ++i) {
            const Ball& b = patches[order[i]];
            node.ball.radius =
                std::max(node.ball.radius, glm::length(b.centre - node.ball.centre) + b.radius);
        }
        node.first = begin;
        node.count = end - begin;
        const int index = static_cast<int>(nodes.size());
        nodes.push_back(node);
        if (end - begin <= kLeafPatches) return index;
        const Vec3 extent = chi - clo;
        const int axis = extent.x >= extent.y && extent.x >= extent.z ? 0
                         : extent.y >= extent.z                       ? 1
                                                                      : 2;
        const int mid = (begin + end) / 2;
        std::nth_element(
            order.begin() + begin, order.begin() + mid, order.begin() + end,
            [&](int a, int b) { return patches[a].centre[axis] < patches[b].centre[axis]; });
        const int left = build(begin, mid);
        const int right = build(mid, end);
        nodes[index].left = left;
        nodes[index].right = right;
        return index;
    }
};

}  // namespace solver_detail

/// One edit's pending redistribution (George et al.: "each log entry records a single
/// environment change and the patch with the most energy left to redistribute").
struct ChangeEntry {
    std::vector<std::uint8_t> before, after;  ///< objects present just before / after the edit
    std::vector<int> added, removed;
    std::vector<Rgb> shot;  ///< per patch: B − ΔB at the time of the edit (radiosity shot)
    std::vector<Rgb> shotEmissionShare;  ///< per patch: the emission share of `shot`
    IndexedMaxHeap pending;  ///< per patch: estimated power to redistribute; 0 when done
    double totalPending = 0;
    Vec3 centre{0};  ///< of the changed objects' bounds, for shadow culling
    double radius = 0;
    /// Bounding sphere (centre, radius) of each changed object: the shaft test.
    std::vector<std::pair<Vec3, double>> spheres;
    /// The changed objects alone in a small ray-tracing scene (RayTracer::createSubset).
    RayTracer::SubsetHandle changed;
    /// The worlds before and after the edit as small instance scenes of their own
    /// (RayTracer::createSubset): their queries need no per-hit history filter.
    RayTracer::SubsetHandle beforeScene, afterScene;
    Visibility beforeWorld() const {
        Visibility v;
        v.world = &before;
        v.subset = beforeScene.id();
        return v;
    }
    Visibility afterWorld() const {
        Visibility v;
        v.world = &after;
        v.subset = afterScene.id();
        return v;
    }
    /// Per patch: its redistribution to the added objects' elements was gathered
    /// (gatherToAdded); its shots skip those receivers. Empty until the gather.
    std::vector<std::uint8_t> gathered;
    bool isGathered(int j) const {
        return j >= 0 && static_cast<std::size_t>(j) < gathered.size() && gathered[j];
    }
    /// The most important pending emitters (at most kAddedFirst) of an edit that adds objects,
    /// most important first. Their light on the added objects' elements goes ahead of every
    /// full shot, in the gather's step or a shot of its own (the added elements change most,
    /// and that part costs only their receivers); the rest of each one's shot, its shadows,
    /// keeps its place in `pending`.
    std::vector<int> addedFirst;
    static constexpr std::size_t kAddedFirst = 8;
    /// Per patch: its light on the added objects' elements was sent ahead (addedFirst); the
    /// rest of its shot skips those receivers. Empty until the first such shot.
    std::vector<std::uint8_t> addedShot;
    /// Whether shooter j has already sent the added objects' elements what it owes them, by
    /// the gather or a shot ahead: its later shots and batches skip them.
    bool reachedAdded(int j) const {
        return isGathered(j) ||
               (j >= 0 && static_cast<std::size_t>(j) < addedShot.size() && addedShot[j]);
    }
    /// A coarse gather's second pass, pending (SolverOptions::gatherCoarseBlock).
    struct GatherRefinement {
        std::vector<int> receivers;      ///< the added objects' elements, ascending
        std::vector<Rgb> firstEstimate;  ///< per receiver: irradiance the first pass gave
        std::vector<Rgb> firstVariance;  ///< per receiver: that estimate's variance, per channel
        /// Per receiver and block: the pending patch whose shot radiosity the block's stratum,
        /// traced from this receiver, returned; -1 for none, -2 when another receiver of its
        /// patch traced the block (the first pass traces each block once per patch).
        std::vector<int> blockHit;
        int nx = 0, ny = 0;      ///< strata over (φ, sin²θ)
        std::uint64_t seed = 0;  ///< the gather's ray seed
        double importance = 0;   ///< W: the gathered shooters' share still to trace
    } refinement;
    bool refinementPending() const { return !refinement.receivers.empty(); }
    /// A preview's gather of the shadow its object casts in the light of the pending shooters
    /// that do not emit (gatherPreviewShadow) has run; their shots are then done.
    bool shadowGathered = false;
    /// The preview's buffer started with the shadow gathered at the drag's last position
    /// (Impl::previewShadow), which its own gather replaces.
    bool shadowCarried = false;
    /// The entry's standing: its strongest pending shooter's importance, or while only a
    /// gather's second pass is left, that pass's importance; 0 when nothing is left.
    double bestPending() const {
        const int top = pending.top();
        if (top >= 0 && pending.key(top) > 0) return pending.key(top);
        return refinementPending() ? std::max(refinement.importance, 1e-300) : 0.0;
    }
};

struct ProgressiveSolver::Impl {
    std::vector<ChangeEntry> changes;
    // The drag preview's temporary buffer.
    int previewObject = -1;
    ChangeEntry previewEntry;
    std::vector<int> previewEmitters;  ///< emitter patches of the preview not yet shot
    std::vector<Rgb> temp;             ///< per element radiosity, display only
    std::vector<Rgb> tempEmission;     ///< the part of temp straight from emission
    /// The last gathered preview shadow (irradiance per element, gatherPreviewShadow) and the
    /// object version it was gathered for (-1: none). A drag's next position starts its
    /// buffer from it moved with the object (movedPreviewShadow: previewShadow, what the
    /// buffer holds), so every published buffer holds the moving object's shadow in the
    /// reflected light about where the object is, until its own gather has run.
    std::vector<Rgb> gatheredShadow;
    int gatheredShadowOf = -1;
    std::vector<Rgb> previewShadow;
    IndexedMaxHeap queue;
    std::vector<Rgb> delta;  ///< per element, radiosity received in the current shot
    std::vector<std::uint8_t> patchReceived;  ///< per patch: received in the current shot
    std::vector<int> level;                   ///< per element, subdivision depth
    /// Per element and channel, Σ dH² over the stochastic contributions to its irradiance (a
    /// batch's hit, a gather's estimate per ray): the variance of the sampling noise the
    /// solution holds there (computeSettling's `noise`).
    std::vector<Rgb> irradianceVariance;
    // Scratch for stochastic batches.
    std::vector<double> patchCdf;    ///< power CDF over the shooters
    std::vector<int> shooters;       ///< patches shot in the batch
    std::vector<Rgb> shooterUnshot;  ///< their ΔB at the start of the batch
    std::vector<Rgb> shooterShares;  ///< the emission share of each one's ΔB
    std::vector<Received> rayHits;   ///< per ray: receiver element and its irradiance
    std::vector<Rgb> carriedPerRay;  ///< per shooter: what one of its rays carries
    // receiveAll's scratch: entries bucketed by block of patches, in list order.
    std::vector<int> blockStart, bucketed;
    std::vector<std::vector<int>> blockTouched;
    // Patches whose unshot energy changed in the current shot: one heap update each.
    std::vector<std::uint8_t> touched;
    std::vector<int> touchedList;
    solver_detail::ReceiverBounds receiverBounds;  ///< redistribution's shaft culling
    /// redistributionDelta's scratch: the receiver-tree nodes to walk in parallel, each with
    /// the changed objects' balls its receivers may meet (0: every element receives), and
    /// the serial walk's stack.
    std::vector<std::pair<int, std::uint64_t>> shaftWork, shaftStack;
    std::uint64_t gatherRefinements = 0;  ///< gathers' second passes so far
    // Deterministic propagation shots so far and their rays (shootsStochastically).
    std::uint64_t deterministicShots = 0, deterministicRays = 0;
};

}  // namespace penumbra
