#pragma once
// The progressive solver's internals, shared by its two source files and by nothing else:
// progressive_solver.cpp (propagation: Cohen et al. 1988's shots, the stochastic tail,
// adaptive subdivision, queries) and redistribution.cpp (George et al. 1990's change log,
// redistribution shots and the drag preview's temporary buffer).
//
// Index: sampling helpers · ChangeEntry · ProgressiveSolver::Impl

#include <cmath>
#include <cstdint>
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
};

struct ProgressiveSolver::Impl {
    std::vector<ChangeEntry> changes;
    // The drag preview's temporary buffer.
    int previewObject = -1;
    ChangeEntry previewEntry;
    std::vector<int> previewEmitters;  ///< emitter patches of the preview not yet shot
    std::vector<Rgb> temp;             ///< per element radiosity, display only
    std::vector<Rgb> tempEmission;     ///< the part of temp straight from emission
    IndexedMaxHeap queue;
    std::vector<Rgb> delta;  ///< per element, radiosity received in the current shot
    std::vector<std::uint8_t> patchReceived;  ///< per patch: received in the current shot
    std::vector<int> level;                   ///< per element, subdivision depth
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
    // Deterministic propagation shots so far and their rays (shootsStochastically).
    std::uint64_t deterministicShots = 0, deterministicRays = 0;
};

}  // namespace penumbra
