// Index: set-up · step/converge (scheduling propagation and redistribution) · one shot
//        (Cohen et al. 1988 §4 pseudo-code) · stochastic tail · adaptive subdivision (§3.4)
//        · edits: change log and redistribution shots (George et al. 1990) · queries
#include "core/random.h"
#include "solver/progressive_solver.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstring>
#include <limits>
#include <stdexcept>

#include "solver/form_factor.h"
#include "solver/indexed_heap.h"

namespace penumbra {

namespace {

double energyKey(const Rgb& unshot, double area) {
    return (std::abs(unshot.x) + std::abs(unshot.y) + std::abs(unshot.z)) * area;
}

bool isZero(const Rgb& c) { return c.x == 0 && c.y == 0 && c.z == 0; }

/// Per channel, the fraction `part` is of `whole` (0 where whole is 0): the share of a shot
/// radiosity that is emission, which every irradiance the shot sends carries too.
Rgb shareOf(const Rgb& part, const Rgb& whole) {
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
void frameAround(const Vec3& z, Vec3& tx, Vec3& ty) {
    const double sign = std::copysign(1.0, z.z);
    const double a = -1.0 / (sign + z.z);
    const double b = z.x * z.y * a;
    tx = Vec3(1.0 + sign * z.x * z.x * a, sign * b, -sign * z.x);
    ty = Vec3(b, sign + z.y * z.y * a, -z.y);
}

/// A cosine-distributed direction about unit normal n, whose frame (tx, ty, n) is given
/// (Malley's method: a uniform point of the unit disk, by rejection from its square, lifted to
/// the hemisphere).
Vec3 cosineDirection(const Vec3& n, const Vec3& tx, const Vec3& ty, RayRandom& rng) {
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
std::size_t lowerBound(const double* a, std::size_t n, double x) {
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
std::size_t shooterAt(const std::vector<double>& cdf, std::size_t from, double u) {
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

}  // namespace

SolverOptions interactiveSolverOptions() {
    SolverOptions o;
    o.stochasticBelow = 1e-3;
    o.raysPerEmittedPower = 1e7;
    o.redistributionRaysPerEmittedPower = 2.5e6;
    o.redistributionThreshold = 1e-4;
    o.gatherRays = 256;
    o.gatherRayBudget = 1e5;
    o.gatherBelow = 1.0;
    return o;
}

/// One edit's pending redistribution (George et al.: "each log entry records a single
/// environment change and the patch with the most energy left to redistribute").
struct ChangeEntry {
    std::vector<std::uint8_t> before, after;  ///< objects present just before / after the edit
    std::vector<int> added, removed;
    std::vector<Rgb> shot;   ///< per patch: B − ΔB at the time of the edit (radiosity shot)
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

ProgressiveSolver::ProgressiveSolver(Discretization& disc, RayTracer& tracer, SolverOptions options)
    : mDisc(disc), mTracer(tracer), mOptions(options), mImpl(std::make_unique<Impl>()) {
    initialize();
}

ProgressiveSolver::~ProgressiveSolver() = default;

void ProgressiveSolver::initialize() {
    const auto& patches = mDisc.patches();
    const auto& elements = mDisc.elements();
    // Cohen §4: ΔB_i = E_i for every patch; B_e = E_i for its elements.
    mPatchUnshot.assign(patches.size(), Rgb(0.0));
    mPatchUnshotEmission.assign(patches.size(), Rgb(0.0));
    mElementB.assign(elements.size(), Rgb(0.0));
    mElementH.assign(elements.size(), Rgb(0.0));
    mElementHEmission.assign(elements.size(), Rgb(0.0));
    mImpl->level.assign(elements.size(), 0);
    mImpl->queue.reset(patches.size());
    mEmittedEnergy = 0;
    for (std::size_t p = 0; p < patches.size(); ++p) {
        if (!mDisc.patchAlive(static_cast<int>(p))) continue;
        const Rgb& e = mDisc.patchMaterial(static_cast<int>(p)).emission;
        mPatchUnshot[p] = mPatchUnshotEmission[p] = e;
        for (int el : patches[p].elements) mElementB[el] = e;
        mEmittedEnergy += (e.x + e.y + e.z) * patches[p].area;
        mImpl->queue.update(static_cast<int>(p), energyKey(e, patches[p].area));
    }
}

void ProgressiveSolver::setStrategy(RedistributionStrategy strategy,
                                    double redistributionThreshold) {
    if (!(redistributionThreshold >= 0 && redistributionThreshold <= 1))
        throw std::invalid_argument("redistribution threshold must be in [0, 1]");
    mOptions.strategy = strategy;
    mOptions.redistributionThreshold = redistributionThreshold;
}

double ProgressiveSolver::unshotEnergy() const {
    double sum = 0;
    for (std::size_t p = 0; p < mPatchUnshot.size(); ++p)
        sum += energyKey(mPatchUnshot[p], mDisc.patches()[p].area);
    return sum;
}

double ProgressiveSolver::unshotFraction() const {
    return mEmittedEnergy > 0 ? unshotEnergy() / mEmittedEnergy : 0.0;
}

int ProgressiveSolver::step(int maxShots) {
    auto start = std::chrono::steady_clock::now();
    int done = 0;
    for (; done < maxShots; ++done) {
        int p = mImpl->queue.top();
        double propagation = p >= 0 ? mImpl->queue.key(p) : 0.0;
        double redistribution = bestRedistribution(nullptr);
        if (propagation <= 0 && redistribution <= 0) break;
        // George et al.: emitters on an added object propagate first; strategy one then
        // redistributes down to the threshold; after that (and always in strategy two) the
        // shot carrying more energy goes next.
        bool redistribute;
        if (redistribution <= 0) {
            redistribute = false;
        } else if (propagation <= 0) {
            redistribute = true;
        } else if (mDisc.patchMaterial(p).isEmitter() &&
                   mPatchUnshot[p] == mDisc.patchMaterial(p).emission) {
            redistribute = false;  // a light not yet shot at all
        } else if (mOptions.strategy == RedistributionStrategy::RedistributeFirst &&
                   redistribution > mOptions.redistributionThreshold * mEmittedEnergy) {
            redistribute = true;
        } else {
            redistribute = redistribution >= propagation;
        }
        if (redistribute) {
            shootRedistribution();
        } else if (shootsStochastically(propagation)) {
            shootStochasticBatch();
        } else {
            shootPatch(p);
        }
    }
    mStats.seconds +=
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    return done;
}

bool ProgressiveSolver::shootsStochastically(double propagation) const {
    if (!(mOptions.stochasticBelow > 0) || !(mEmittedEnergy > 0) ||
        propagation >= mOptions.stochasticBelow * mEmittedEnergy)
        return false;
    // Below the threshold, the stochastic batch takes over once it moves power for less
    // tracing than a deterministic shot: a shot of power Φ costs about the mean ray count of
    // the deterministic shots so far, a batch hitRayCost × raysPerEmittedPower × Φ / Φ_emitted
    // deterministic-ray equivalents (its rays are closest-hit rays with their own set-up). Small
    // scenes (few receivers) keep shooting deterministically a little longer; ray counts
    // follow from the geometry only, so the choice does not depend on the thread count.
    if (mImpl->deterministicShots == 0) return true;
    const double meanRays = static_cast<double>(mImpl->deterministicRays) /
                            static_cast<double>(mImpl->deterministicShots);
    return mOptions.hitRayCost * propagation / mEmittedEnergy * mOptions.raysPerEmittedPower <
           meanRays;
}

std::uint64_t ProgressiveSolver::converge(double eps, std::uint64_t maxShots,
                                          const std::function<void(double)>& progress) {
    std::uint64_t shots = 0;
    while (shots < maxShots && !converged(eps)) {
        // Propagation is done to eps: finish the logged redistribution, whatever its
        // estimated importance (George et al.'s error elimination).
        if (unshotFraction() <= eps) {
            auto start = std::chrono::steady_clock::now();
            bool shot = shootRedistribution();
            mStats.seconds +=
                std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
            if (!shot) break;
        } else if (step(1) == 0) {
            break;
        }
        ++shots;
        if (progress) progress(unshotFraction());
    }
    return shots;
}

bool ProgressiveSolver::converged(double eps) const {
    return unshotFraction() <= eps && mImpl->changes.empty();
}

void ProgressiveSolver::ensureSizes() {
    const std::size_t ne = mDisc.elements().size(), np = mDisc.patches().size();
    mElementB.resize(ne, Rgb(0.0));
    mElementH.resize(ne, Rgb(0.0));
    mElementHEmission.resize(ne, Rgb(0.0));
    mImpl->level.resize(ne, 0);
    mPatchUnshot.resize(np, Rgb(0.0));
    mPatchUnshotEmission.resize(np, Rgb(0.0));
    while (mImpl->queue.size() < np) mImpl->queue.push(0.0);
}

void ProgressiveSolver::receive(int e, const Rgb& dH, const Rgb& emissionShare) {
    const Element& el = mDisc.elements()[e];
    receive(e, el.patch, el.area, dH, emissionShare);
}

void ProgressiveSolver::receive(int e, int patch, double area, const Rgb& dH,
                                const Rgb& emissionShare) {
    const Rgb dB = mDisc.patchMaterial(patch).reflectance * dH;
    mElementH[e] += dH;
    mElementHEmission[e] += dH * emissionShare;
    mElementB[e] += dB;
    mPatchUnshot[patch] += dB * (area / mDisc.patches()[patch].area);
}

void ProgressiveSolver::touchElement(int e) {
    const int p = mDisc.elements()[e].patch;
    auto& touched = mImpl->touched;
    if (touched.size() <= static_cast<std::size_t>(p)) touched.resize(mDisc.patches().size(), 0);
    if (!touched[p]) touched[p] = 1, mImpl->touchedList.push_back(p);
}

void ProgressiveSolver::updateTouchedPriorities() {
    for (int p : mImpl->touchedList) {
        updatePriority(p);
        mImpl->touched[p] = 0;
    }
    mImpl->touchedList.clear();
}

void ProgressiveSolver::receiveAll(const std::vector<Received>& list,
                                   const std::vector<Rgb>& shares) {
    // Bucket the entries by block of patches, keeping list order within each block; every
    // element and patch belongs to one block, so blocks apply in parallel while each sum
    // runs in list order, exactly as a serial loop over the list would.
    const std::size_t np = mDisc.patches().size();
    const std::size_t blocks = std::min<std::size_t>(64, std::max<std::size_t>(np, 1));
    auto blockOf = [&](int patch) { return static_cast<std::size_t>(patch) * blocks / np; };
    auto& start = mImpl->blockStart;
    auto& bucketed = mImpl->bucketed;
    start.assign(blocks + 1, 0);
    for (const Received& r : list)
        if (r.element >= 0) ++start[blockOf(r.patch) + 1];
    for (std::size_t b = 0; b < blocks; ++b) start[b + 1] += start[b];
    bucketed.resize(start[blocks]);
    {
        std::vector<int> next(start.begin(), start.end() - 1);
        for (std::size_t i = 0; i < list.size(); ++i)
            if (list[i].element >= 0)
                bucketed[next[blockOf(list[i].patch)]++] = static_cast<int>(i);
    }
    auto& touched = mImpl->touched;
    if (touched.size() < np) touched.resize(np, 0);
    auto& blockTouched = mImpl->blockTouched;
    blockTouched.resize(blocks);
    tbb::parallel_for(std::size_t(0), blocks, [&](std::size_t b) {
        blockTouched[b].clear();
        // The entries' elements are anywhere in a large scene: prefetch a few ahead. An entry
        // carries its element's patch and area, so receive's sums need no element record.
        constexpr int kAhead = 12;
        for (int i = start[b]; i < start[b + 1]; ++i) {
            if (i + kAhead < start[b + 1]) {
                const int ahead = list[bucketed[i + kAhead]].element;
                __builtin_prefetch(&mElementH[ahead], 1);
                __builtin_prefetch(&mElementB[ahead], 1);
                __builtin_prefetch(&mElementHEmission[ahead], 1);
            }
            const Received& r = list[bucketed[i]];
            receive(r.element, r.patch, r.area, r.irradiance, shares[r.shooter]);
            if (!touched[r.patch]) touched[r.patch] = 1, blockTouched[b].push_back(r.patch);
        }
    });
    for (const std::vector<int>& t : blockTouched)
        mImpl->touchedList.insert(mImpl->touchedList.end(), t.begin(), t.end());
    updateTouchedPriorities();
}

void ProgressiveSolver::updatePriority(int patch) {
    mImpl->queue.update(patch, energyKey(mPatchUnshot[patch], mDisc.patches()[patch].area));
}

void ProgressiveSolver::shootPatch(int shooter) {
    const auto& patches = mDisc.patches();
    const Rgb dB = mPatchUnshot[shooter];
    const Rgb share = shareOf(mPatchUnshotEmission[shooter], dB);
    mPatchUnshot[shooter] = mPatchUnshotEmission[shooter] = Rgb(0.0);
    mImpl->queue.update(shooter, 0.0);
    if (isZero(dB)) return;
    const unsigned long long raysBefore = mTracer.rayCount();

    // Gather the radiosity each element receives from this shot (Cohen §4:
    // ΔRad = ρ_e ΔB_i F_ie A_i / A_e, with F_ie A_i / A_e = F_e→i by reciprocity).
    const std::size_t n = mDisc.elements().size();
    std::atomic<std::uint64_t> rays{0};
    if (mOptions.gradientThreshold > 0) {
        // Subdivision needs every element's delta: gather, then apply in element order, so
        // results do not depend on the thread count.
        auto& delta = mImpl->delta;
        delta.assign(n, Rgb(0.0));
        tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 32), [&](const auto& range) {
            int traced = 0;
            for (std::size_t e = range.begin(); e != range.end(); ++e)
                delta[e] = irradianceFrom(shooter, static_cast<int>(e), dB, {}, &traced);
            rays += static_cast<std::uint64_t>(traced);
        });
        for (std::size_t e = 0; e < n; ++e)
            if (!isZero(delta[e])) receive(static_cast<int>(e), delta[e], share);
        subdivideSteepElements();
        for (std::size_t e = 0; e < mDisc.elements().size(); ++e)
            if (e >= delta.size() || !isZero(delta[e])) touchElement(static_cast<int>(e));
    } else {
        // By receiving patch: a task owns its patches' elements and unshot sums, so it applies
        // what it gathers at once, in the patch's element order (ascending, as the element
        // loop above applies them), and the shot has no serial pass over the elements. The
        // form factors of a patch's receivers are computed together (formFactorsToPatch: the
        // same values as irradianceFrom's one at a time).
        auto& received = mImpl->patchReceived;
        received.assign(patches.size(), 0);
        tbb::parallel_for(
            tbb::blocked_range<std::size_t>(0, patches.size(), 8), [&](const auto& range) {
                int traced = 0;
                constexpr int kBatch = 16;
                Receiver receivers[kBatch];
                int receiving[kBatch];
                PointToPatch ff[kBatch];
                for (std::size_t p = range.begin(); p != range.end(); ++p) {
                    const std::vector<int>& els = patches[p].elements;
                    for (std::size_t i = 0; i < els.size();) {
                        int m = 0;
                        for (; i < els.size() && m < kBatch; ++i) {
                            const int e = els[i];
                            if (!mayReceive(shooter, e, {})) continue;
                            const Element& el = mDisc.elements()[e];
                            receivers[m] = {el.centroid, el.normal, static_cast<std::uint64_t>(e)};
                            receiving[m++] = e;
                        }
                        formFactorsToPatch(mDisc, mTracer, shooter, receivers, m, mOptions.seed,
                                           mOptions.maxRaysPerPair, {}, ff);
                        for (int k = 0; k < m; ++k) {
                            traced += ff[k].rays;
                            const Rgb d = dB * ff[k].visible;
                            if (isZero(d)) continue;
                            receive(receiving[k], d, share);
                            received[p] = 1;
                        }
                    }
                }
                rays += static_cast<std::uint64_t>(traced);
            });
        for (std::size_t p = 0; p < patches.size(); ++p)
            if (received[p]) updatePriority(static_cast<int>(p));
    }
    updateTouchedPriorities();
    ++mStats.shots;
    mStats.rays += mTracer.rayCount() - raysBefore;
    ++mImpl->deterministicShots;
    mImpl->deterministicRays += rays;  // this shot's own, whatever else shares the tracer
}

bool ProgressiveSolver::mayReceive(int shooter, int e, const Visibility& visibility) const {
    const Patch& P = mDisc.patches()[shooter];
    const Element& el = mDisc.elements()[e];
    if (el.patch == shooter) return false;
    // Only receivers present in the scene the form factor is evaluated in.
    if (visibility.world ? !(*visibility.world)[el.object] : !mDisc.objects()[el.object].alive)
        return false;
    // Cull pairs that cannot see each other: receiver behind the shooter's bounding plane or
    // shooter behind the receiver's plane.
    Vec3 toReceiver = el.centroid - P.centroid;
    if (glm::dot(toReceiver, P.normal) < -P.radius) return false;
    if (glm::dot(-toReceiver, el.normal) < -P.radius) return false;
    return true;
}

Rgb ProgressiveSolver::irradianceFrom(int shooter, int e, const Rgb& dB,
                                      const Visibility& visibility, int* rays) const {
    if (!mayReceive(shooter, e, visibility)) return Rgb(0.0);
    const Element& el = mDisc.elements()[e];
    PointToPatch ff = formFactorToPatch(mDisc, mTracer, el.centroid, el.normal, shooter,
                                        static_cast<std::uint64_t>(e), mOptions.seed,
                                        mOptions.maxRaysPerPair, visibility);
    if (rays) *rays += ff.rays;
    return dB * ff.visible;
}

Rgb ProgressiveSolver::irradianceChange(int shooter, int e, const Rgb& dB, const Visibility& before,
                                        const Visibility& after, const Visibility& changed) const {
    const Patch& P = mDisc.patches()[shooter];
    const Element& el = mDisc.elements()[e];
    if (el.patch == shooter) return Rgb(0.0);
    // The same culls as irradianceFrom: pairs that cannot see each other.
    Vec3 toReceiver = el.centroid - P.centroid;
    if (glm::dot(toReceiver, P.normal) < -P.radius) return Rgb(0.0);
    if (glm::dot(-toReceiver, el.normal) < -P.radius) return Rgb(0.0);
    PointToPatch ff = formFactorChange(mDisc, mTracer, el.centroid, el.normal, shooter,
                                       static_cast<std::uint64_t>(e), mOptions.seed,
                                       mOptions.maxRaysPerPair, before, after, changed);
    return dB * ff.visible;
}

void ProgressiveSolver::shootStochasticBatch() {
    // Stochastic shooting of the weak tail (every remaining shooter is below
    // stochasticBelow × emitted power): all unshot power leaves at once on N rays, chosen
    // in proportion to ΔB·A (systematic sampling over the patches), from uniform points of
    // the patch in cosine-distributed directions. A ray carrying power Φ that reaches the
    // front of element e adds ρ_e Φ / A_e to its radiosity: in expectation exactly Cohen's
    // ρ_e ΔB_i F_ie A_i / A_e, at a cost that follows the shot energy, not the element count.
    const auto& patches = mDisc.patches();
    const unsigned long long raysBefore = mTracer.rayCount();
    auto& cdf = mImpl->patchCdf;
    auto& shooters = mImpl->shooters;
    auto& unshot = mImpl->shooterUnshot;
    auto& shares = mImpl->shooterShares;
    shooters.clear();
    unshot.clear();
    shares.clear();
    cdf.clear();
    // All unshot power leaves at once, unless that would take more than maxBatchRays rays:
    // then the strongest patches go first (progressive refinement's order, batch by batch)
    // and the rest stays unshot for the next batch, so no step blocks for long.
    double all = 0;
    for (std::size_t p = 0; p < patches.size(); ++p)
        all += std::max(0.0, energyKey(mPatchUnshot[p], patches[p].area));
    const double raysPerWatt = mOptions.raysPerEmittedPower / std::max(mEmittedEnergy, 1e-300);
    double floorPower = 0;  // patches with at least this power shoot in this batch
    if (all * raysPerWatt > mOptions.maxBatchRays) {
        std::vector<double> powers;
        for (std::size_t p = 0; p < patches.size(); ++p) {
            double power = energyKey(mPatchUnshot[p], patches[p].area);
            if (power > 0) powers.push_back(power);
        }
        std::sort(powers.begin(), powers.end(), std::greater<>());
        double taken = 0;
        for (double power : powers) {
            if (taken > 0 && (taken + power) * raysPerWatt > mOptions.maxBatchRays) break;
            taken += power;
            floorPower = power;
        }
    }
    double total = 0;
    for (std::size_t p = 0; p < patches.size(); ++p) {
        double power = energyKey(mPatchUnshot[p], patches[p].area);
        if (!(power > 0) || power < floorPower) continue;
        shooters.push_back(static_cast<int>(p));
        unshot.push_back(mPatchUnshot[p]);
        shares.push_back(shareOf(mPatchUnshotEmission[p], mPatchUnshot[p]));
        cdf.push_back(total += power);
        mPatchUnshot[p] = mPatchUnshotEmission[p] = Rgb(0.0);
        mImpl->queue.update(static_cast<int>(p), 0.0);
    }
    if (shooters.empty()) return;
    const double share = mEmittedEnergy > 0 ? total / mEmittedEnergy : 1.0;
    const std::size_t rays = static_cast<std::size_t>(
        std::clamp(std::ceil(share * mOptions.raysPerEmittedPower),
                   static_cast<double>(mOptions.minStochasticRays), 6.4e7));
    const std::uint64_t batchSeed =
        hashPair(hashPair(mOptions.seed, 0x5707c4a57ull), mStats.stochasticBatches);
    auto& hits = mImpl->rayHits;
    hits.resize(rays);
    // A ray of shooter k carries power total/rays, in the colour of its ΔB.
    auto& carriedPerRay = mImpl->carriedPerRay;
    carriedPerRay.resize(shooters.size());
    for (std::size_t k = 0; k < shooters.size(); ++k) {
        const double area = patches[shooters[k]].area;
        carriedPerRay[k] =
            unshot[k] * (area * total / (static_cast<double>(rays) * energyKey(unshot[k], area)));
    }
    const double eps = mTracer.epsilon();
    // Blocks of 256 rays at fixed offsets: the groups (and firstHits' packets of sixteen) hold
    // the same rays whatever the threads' split, so a hit that a packet's traversal order
    // could break differently from another packet's (a ray through a shared edge) is still
    // the same from run to run.
    constexpr std::size_t kBlock = 256;
    const std::size_t blocks = (rays + kBlock - 1) / kBlock;
    tbb::parallel_for(std::size_t(0), blocks, [&](std::size_t block) {
        const std::size_t begin = block * kBlock, end = std::min(rays, begin + kBlock);
        thread_local PatchPoints points;
        std::size_t current = shooters.size();  // none yet in this block
        // Rays go to the tracer in groups (RayTracer::firstHits prefetches each hit's record
        // while the group's later rays trace).
        constexpr int kGroup = 32;
        Vec3 origins[kGroup], dirs[kGroup];
        std::size_t shooterOf[kGroup];
        RayTracer::FirstHit found[kGroup];
        for (std::size_t g = begin; g < end; g += kGroup) {
            const int m = static_cast<int>(std::min<std::size_t>(kGroup, end - g));
            for (int i = 0; i < m; ++i) {
                const std::size_t r = g + static_cast<std::size_t>(i);
                hits[r].element = -1;
                RayRandom rng{hashPair(batchSeed, r)};
                // The shooter, by power; a uniform point of it; a cosine-distributed direction.
                double u =
                    (static_cast<double>(r) + rng.next()) / static_cast<double>(rays) * total;
                const std::size_t k = shooterAt(cdf, current, u);
                if (k != current) points.set(mDisc, patches[shooters[current = k]]);
                Vec3 origin, nz, tx, ty;
                points.sample(rng, origin, nz, tx, ty);
                dirs[i] = cosineDirection(nz, tx, ty, rng);
                origins[i] = origin + nz * eps;
                shooterOf[i] = k;
            }
            mTracer.firstHits(origins, dirs, m, found);
            for (int i = 0; i < m; ++i) {
                const RayTracer::FirstHit& hit = found[i];
                const std::size_t k = shooterOf[i];
                if (hit.element < 0 || hit.backFace) continue;  // escaped, or absorbed by a back
                if (hit.patch == shooters[k]) continue;
                hits[g + static_cast<std::size_t>(i)] = {hit.element, hit.patch, hit.area,
                                                         carriedPerRay[k] / hit.area,
                                                         static_cast<int>(k)};
            }
        }
    });
    receiveAll(hits, shares);
    ++mStats.shots;
    ++mStats.stochasticBatches;
    mStats.stochasticRays += rays;
    mStats.rays += mTracer.rayCount() - raysBefore;
}

void ProgressiveSolver::subdivideSteepElements() {
    // Cohen §3.4: where the radiosity difference between neighbouring elements is too high,
    // subdivide and reshoot this patch to the new elements.
    std::vector<int> steep;
    const std::size_t n = mDisc.elements().size();
    double maxY = 0;
    for (std::size_t e = 0; e < n; ++e) maxY = std::max(maxY, luminance(mElementB[e]));
    for (std::size_t e = 0; e < n; ++e) {
        if (isZero(mImpl->delta[e]) || mImpl->level[e] >= mOptions.maxSubdivisionLevel) continue;
        // Two-sided faces keep their twins' geometry: not subdivided.
        if (!mDisc.objects()[mDisc.elements()[e].object].faceTwin.empty()) continue;
        double ye = luminance(mElementB[e]);
        for (int nb : mDisc.elementNeighbours(static_cast<int>(e))) {
            if (mDisc.elements()[nb].patch != mDisc.elements()[e].patch &&
                glm::dot(mDisc.elements()[nb].normal, mDisc.elements()[e].normal) < 0.99)
                continue;
            double yn = luminance(mElementB[nb]);
            if (std::abs(ye - yn) >
                mOptions.gradientThreshold * std::max(maxY * 1e-2, std::max(ye, yn))) {
                steep.push_back(static_cast<int>(e));
                break;
            }
        }
    }
    if (steep.empty()) return;
    for (int e : steep) {
        const int patch = mDisc.elements()[e].patch;
        const int level = mImpl->level[e] + 1;
        const Rgb parentB = mElementB[e];
        const Rgb parentShare = shareOf(mElementHEmission[e], mElementH[e]);
        const double parentArea = mDisc.elements()[e].area;
        std::vector<int> children = mDisc.subdivideElement(e);
        if (children.size() < 2) continue;
        ensureSizes();
        mImpl->delta.resize(mDisc.elements().size(), Rgb(0.0));
        // Each child gathers everything shot so far: every earlier shot of patch j used the
        // same pair-seeded F(child ← j), so Σ over j of (B_j − ΔB_j) F is its exact history
        // (Cohen's "reshoot patch i", extended to all earlier shooters).
        Rgb change(0.0);
        for (int c : children) {
            mElementH[c] = gatherShotIrradiance(c);
            mElementHEmission[c] = mElementH[c] * parentShare;
            mElementB[c] = mDisc.patchMaterial(patch).emission +
                           mDisc.patchMaterial(patch).reflectance * mElementH[c];
            mImpl->delta[c] = mElementB[c] - parentB;
            mImpl->level[c] = level;
            change += mElementB[c] * mDisc.elements()[c].area;
        }
        // The patch's radiosity changed by the children's correction: it is unshot.
        change -= parentB * parentArea;
        mPatchUnshot[patch] += change / mDisc.patches()[patch].area;
        ++mStats.subdivisions;
    }
    mTracer.rebuild();
}

Rgb ProgressiveSolver::gatherShotIrradiance(int element) const {
    const std::size_t np = mDisc.patches().size();
    std::vector<Rgb> parts(np, Rgb(0.0));
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, np, 64), [&](const auto& range) {
        for (std::size_t j = range.begin(); j != range.end(); ++j) {
            if (!mDisc.patchAlive(static_cast<int>(j))) continue;
            Rgb shot = patchRadiosity(static_cast<int>(j)) - mPatchUnshot[j];
            if (!isZero(shot)) parts[j] = irradianceFrom(static_cast<int>(j), element, shot);
        }
    });
    Rgb sum(0.0);
    for (const Rgb& p : parts) sum += p;
    return sum;
}

// ---------------------------------------------------------------------------------------------
// Edits (George, Sillion, Greenberg 1990)

namespace {

struct Bounds {
    Vec3 lo{std::numeric_limits<double>::max()}, hi{-std::numeric_limits<double>::max()};
    void add(const Vec3& p) { lo = glm::min(lo, p), hi = glm::max(hi, p); }
    bool empty() const { return lo.x > hi.x; }
};

/// Whether the sphere (c, r) can meet a segment from x to a point within distance pr of p.
/// Those segments fill the union of the balls B(x + t(p − x), t·pr), t ∈ [0, 1]; the
/// sphere meets it iff g(t) = |x + t(p − x) − c| − t·pr < r for some t. g is convex, so its
/// minimum over [0, 1] is the clamped stationary point, in closed form.
bool sphereMeetsCone(const Vec3& x, const Vec3& p, double pr, const Vec3& c, double r) {
    const Vec3 d = p - x;
    const double l2 = glm::dot(d, d);
    if (l2 <= pr * pr) return true;  // x is within the patch's bounds
    const Vec3 w = x - c;
    const double k = glm::dot(w, d);
    const double t0 = -k / l2;                                     // closest point on the line
    const double q2 = std::max(0.0, glm::dot(w, w) - k * k / l2);  // squared line distance
    const double s = pr * std::sqrt(q2) / (std::sqrt(l2) * std::sqrt(l2 - pr * pr));
    const double t = std::clamp(t0 + s, 0.0, 1.0);
    return std::sqrt(l2 * (t - t0) * (t - t0) + q2) - pr * t < r;
}

}  // namespace

ChangeEntry ProgressiveSolver::makeChangeEntry(const SceneChange& change) const {
    const auto& patches = mDisc.patches();
    const std::size_t nObjects = mDisc.objects().size();
    ChangeEntry entry;
    entry.added = change.added;
    entry.removed = change.removed;
    entry.after.assign(nObjects, 0);
    for (std::size_t o = 0; o < nObjects; ++o) entry.after[o] = mDisc.objects()[o].alive ? 1 : 0;
    entry.before = entry.after;
    for (int o : change.added) entry.before[o] = 0;
    for (int o : change.removed) entry.before[o] = 1;

    // Bounds of everything that changed, and sample points for the importance estimate.
    Bounds bounds;
    double changedArea = 0;
    std::vector<char> changed(nObjects, 0);
    for (const auto* list : {&change.added, &change.removed})
        for (int o : *list) {
            changed[o] = 1;
            for (const Vec3& w : mDisc.objects()[o].worldPositions) bounds.add(w);
        }
    for (const Patch& P : patches)
        if (changed[P.object]) changedArea += P.area;
    std::vector<int> changedObjects;
    for (std::size_t o = 0; o < nObjects; ++o) {
        if (!changed[o]) continue;
        changedObjects.push_back(static_cast<int>(o));
        Bounds b;
        for (const Vec3& w : mDisc.objects()[o].worldPositions) b.add(w);
        if (b.empty()) continue;
        const Vec3 c = 0.5 * (b.lo + b.hi);
        double r = 0;
        for (const Vec3& w : mDisc.objects()[o].worldPositions) r = std::max(r, glm::length(w - c));
        entry.spheres.push_back({c, r});
    }
    entry.changed = RayTracer::SubsetHandle(mTracer, changedObjects);
    if (!bounds.empty()) {
        entry.centre = 0.5 * (bounds.lo + bounds.hi);
        entry.radius = 0.5 * glm::length(bounds.hi - bounds.lo);
    }
    std::vector<Vec3> samples{entry.centre};
    if (!bounds.empty())
        for (int k = 0; k < 8; ++k)
            samples.push_back(entry.centre +
                              0.5 * Vec3((k & 1 ? 0.5 : -0.5) * (bounds.hi.x - bounds.lo.x),
                                         (k & 2 ? 0.5 : -0.5) * (bounds.hi.y - bounds.lo.y),
                                         (k & 4 ? 0.5 : -0.5) * (bounds.hi.z - bounds.lo.z)));

    // Snapshot the radiosity already shot, B − ΔB, and rank the shooters by the power they
    // would send toward the changed objects: George et al.'s point-sample estimate, a
    // differential area at each sample point facing the patch, F ≈ A cosθ / (πr² + A).
    entry.shot.assign(patches.size(), Rgb(0.0));
    entry.shotEmissionShare.assign(patches.size(), Rgb(0.0));
    entry.pending.reset(patches.size());
    for (std::size_t j = 0; j < patches.size(); ++j) {
        const Patch& P = patches[j];
        if (!entry.before[P.object] ||
            entry.added.end() != std::find(entry.added.begin(), entry.added.end(), P.object))
            continue;
        Rgb shot = patchRadiosity(static_cast<int>(j)) - mPatchUnshot[j];
        if (isZero(shot)) continue;
        entry.shot[j] = shot;
        entry.shotEmissionShare[j] =
            shareOf(mDisc.patchMaterial(static_cast<int>(j)).emission - mPatchUnshotEmission[j],
                    shot);
        double power = energyKey(shot, P.area);
        double importance;
        if (changed[P.object]) {
            importance = power;  // a removed shooter: all it shot is cancelled
        } else {
            double f = 0;
            for (const Vec3& sp : samples) {
                Vec3 d = sp - P.centroid;
                double r2 = glm::dot(d, d);
                double cosj = r2 > 0 ? glm::dot(P.normal, d) / std::sqrt(r2) : 0;
                if (cosj > 0) f += P.area * cosj / (M_PI * r2 + P.area);
            }
            f /= static_cast<double>(samples.size());
            // Power reaching the objects: radiosity × F × (about a quarter of their area
            // faces any one direction); at least a tiny amount so every shooter is visited.
            importance = std::max(energyKey(shot, 1.0) * f * changedArea / 4, 1e-300);
        }
        entry.pending.update(static_cast<int>(j), importance);
        entry.totalPending += importance;
    }
    return entry;
}

void ProgressiveSolver::buildWorldScenes(ChangeEntry& entry) const {
    std::vector<int> before, after;
    for (std::size_t o = 0; o < entry.before.size(); ++o) {
        if (entry.before[o]) before.push_back(static_cast<int>(o));
        if (entry.after[o]) after.push_back(static_cast<int>(o));
    }
    entry.beforeScene = RayTracer::SubsetHandle(mTracer, before);
    entry.afterScene = RayTracer::SubsetHandle(mTracer, after);
}

void ProgressiveSolver::applyChange(const SceneChange& change, bool redistribute) {
    ensureSizes();
    clearPreview();
    ChangeEntry entry = makeChangeEntry(change);
    const auto& patches = mDisc.patches();

    // Removed objects leave the solution: their radiosity and unshot energy are gone.
    for (int o : change.removed)
        for (std::size_t j = 0; j < patches.size(); ++j) {
            if (patches[j].object != o) continue;
            for (int e : patches[j].elements)
                mElementB[e] = mElementH[e] = mElementHEmission[e] = Rgb(0.0);
            mPatchUnshot[j] = mPatchUnshotEmission[j] = Rgb(0.0);
            updatePriority(static_cast<int>(j));
        }
    // Added objects start with their emission unshot (Cohen's initialization).
    for (int o : change.added)
        for (std::size_t j = 0; j < patches.size(); ++j) {
            if (patches[j].object != o) continue;
            const Rgb& e = mDisc.patchMaterial(static_cast<int>(j)).emission;
            for (int el : patches[j].elements)
                mElementB[el] = e, mElementH[el] = mElementHEmission[el] = Rgb(0.0);
            mPatchUnshot[j] = mPatchUnshotEmission[j] = e;
            updatePriority(static_cast<int>(j));
        }
    recomputeEmitted();
    if (redistribute && entry.totalPending > 0) {
        buildWorldScenes(entry);
        mImpl->changes.push_back(std::move(entry));
    }
}

void ProgressiveSolver::recomputeEmitted() {
    mEmittedEnergy = 0;
    for (std::size_t p = 0; p < mDisc.patches().size(); ++p) {
        if (!mDisc.patchAlive(static_cast<int>(p))) continue;
        const Rgb& e = mDisc.patchMaterial(static_cast<int>(p)).emission;
        mEmittedEnergy += (e.x + e.y + e.z) * mDisc.patches()[p].area;
    }
}

void ProgressiveSolver::changeMaterial(int object, const Material& material) {
    ensureSizes();
    // George et al.: "it is sufficient to compute and propagate a radiosity correction for
    // each patch on the object": ΔB = Δρ·H + ΔE, all of it unshot.
    const auto& patches = mDisc.patches();
    std::vector<std::pair<int, Rgb>> old;
    for (std::size_t j = 0; j < patches.size(); ++j)
        if (patches[j].object == object) old.push_back({static_cast<int>(j), Rgb(0.0)});
    if (old.empty()) return;
    const Material before = mDisc.patchMaterial(old.front().first);
    mDisc.setObjectMaterial(object, material);
    const Rgb dRho = material.reflectance - before.reflectance;
    const Rgb dE = material.emission - before.emission;
    for (const auto& [j, unused] : old) {
        const Patch& P = patches[j];
        Rgb sum(0.0);
        for (int e : P.elements) {
            Rgb dB = dRho * mElementH[e] + dE;
            mElementB[e] += dB;
            sum += dB * mDisc.elements()[e].area;
        }
        mPatchUnshot[j] += sum / P.area;
        mPatchUnshotEmission[j] += dE;
        updatePriority(j);
    }
    recomputeEmitted();
}

double ProgressiveSolver::bestRedistribution(int* entryIndex) const {
    double best = 0;
    for (std::size_t k = 0; k < mImpl->changes.size(); ++k) {
        const ChangeEntry& c = mImpl->changes[k];
        int top = c.pending.top();
        if (top < 0 || c.pending.key(top) <= 0) continue;
        if (c.pending.key(top) > best) {
            best = c.pending.key(top);
            if (entryIndex) *entryIndex = static_cast<int>(k);
        }
    }
    return best;
}

double ProgressiveSolver::pendingRedistribution() const {
    double sum = 0;
    for (const ChangeEntry& c : mImpl->changes) sum += c.totalPending;
    return sum;
}

std::size_t ProgressiveSolver::pendingChanges() const { return mImpl->changes.size(); }

bool ProgressiveSolver::afterIsCurrentScene(const ChangeEntry& c, bool preview) const {
    if (preview) return false;
    for (std::size_t o = 0; o < mDisc.objects().size(); ++o)
        if ((o < c.after.size() && c.after[o]) != mDisc.objects()[o].alive) return false;
    return true;
}

void ProgressiveSolver::redistributionDelta(const ChangeEntry& c, int j, bool preview,
                                            std::vector<Rgb>& delta) const {
    const Rgb shot = c.shot[j];
    const Patch& P = mDisc.patches()[j];
    const bool shooterRemoved =
        std::find(c.removed.begin(), c.removed.end(), P.object) != c.removed.end();
    Visibility before = c.beforeWorld(), after = c.afterWorld();

    // Receivers: elements present after the edit (and still alive, or the previewed object).
    // Elements of added objects gain F(t) (F(t−1) = 0: they did not exist); others change
    // only if the changed objects can block a segment between them and the shooter: a
    // conservative shaft, the capsule around the segment from the patch centre to the
    // receiver widened by the patch radius, tested against the changed objects' bounding
    // sphere. Unchanged visibility cancels exactly: F(t) and F(t−1) trace the same
    // pair-seeded rays.
    // The world after the edit is usually the current scene: trace it without a filter.
    if (afterIsCurrentScene(c, preview)) after = Visibility{};
    const Visibility changed = c.changed.visibility();
    const double margin = 4 * mTracer.epsilon();
    const bool gathered = c.isGathered(j);

    const auto& elements = mDisc.elements();
    const std::size_t n = elements.size();
    delta.assign(n, Rgb(0.0));
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 256), [&](const auto& range) {
        for (std::size_t e = range.begin(); e != range.end(); ++e) {
            const Element& el = elements[e];
            if (el.object >= static_cast<int>(c.after.size()) || !c.after[el.object]) continue;
            if (!mDisc.objects()[el.object].alive &&
                !(preview && el.object == mImpl->previewObject))
                continue;
            const bool receiverAdded = !c.before[el.object];
            const int ie = static_cast<int>(e);
            if (shooterRemoved) {
                // Cancel what the removed patch shot: −F(t−1) (George et al.: "energy that
                // was distributed by patches on the dynamic object is canceled").
                if (receiverAdded) continue;
                delta[e] = -irradianceFrom(j, ie, shot, before);
            } else if (receiverAdded) {
                if (gathered) continue;  // gatherToAdded delivered it
                delta[e] = irradianceFrom(j, ie, shot, after);
            } else {
                // Haines–Wallace style shaft: can any changed object meet a segment from
                // the receiver to the shooter patch?
                bool inShaft = false;
                for (const auto& [centre, radius] : c.spheres)
                    if (sphereMeetsCone(el.centroid, P.centroid, P.radius + margin, centre,
                                        radius + margin)) {
                        inShaft = true;
                        break;
                    }
                if (!inShaft) continue;
                delta[e] = irradianceChange(j, ie, shot, before, after, changed);
            }
        }
    });
}

bool ProgressiveSolver::shouldGather(const ChangeEntry& c, double best) const {
    const double below = mOptions.gatherBelow > 0 ? mOptions.gatherBelow : mOptions.stochasticBelow;
    return mOptions.gatherRays > 0 && !c.added.empty() && c.gathered.empty() &&
           best < below * mEmittedEnergy;
}

void ProgressiveSolver::gatherToAdded(ChangeEntry& c, bool preview, std::vector<Rgb>& delta) {
    const auto& patches = mDisc.patches();
    const auto& elements = mDisc.elements();
    // The entry knows the patches that existed at its edit; later edits append more.
    const std::size_t np = c.shot.size();
    c.gathered.assign(np, 0);
    // Emitters keep their shots: a gather would see a small bright light with few rays.
    for (std::size_t j = 0; j < np; ++j)
        if (c.pending.key(static_cast<int>(j)) > 0 &&
            !mDisc.patchMaterial(static_cast<int>(j)).isEmitter())
            c.gathered[j] = 1;
    // Receivers: the elements of the added objects (the previewed one in a preview).
    std::vector<int> receivers;
    for (int o : c.added) {
        if (!mDisc.objects()[o].alive && !(preview && o == mImpl->previewObject)) continue;
        for (const Patch& P : patches)
            if (P.object == o)
                receivers.insert(receivers.end(), P.elements.begin(), P.elements.end());
    }
    std::sort(receivers.begin(), receivers.end());
    delta.assign(elements.size(), Rgb(0.0));
    Visibility after = c.afterWorld();
    if (afterIsCurrentScene(c, preview)) after = Visibility{};
    // Stratified cosine directions: nx × ny strata over (φ, sin²θ).
    int n = std::max(1, mOptions.gatherRays);
    if (mOptions.gatherRayBudget > 0 && !receivers.empty())
        n = std::clamp(static_cast<int>(mOptions.gatherRayBudget /
                                        static_cast<double>(receivers.size())),
                       std::min(n, std::max(1, mOptions.minGatherRays)), n);
    int nx = static_cast<int>(std::ceil(std::sqrt(static_cast<double>(n))));
    const int ny = (n + nx - 1) / nx;
    const double eps = mTracer.epsilon();
    const std::uint64_t seed = hashPair(hashPair(mOptions.seed, 0x6a7e5ull), mStats.shots);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, receivers.size(), 16), [&](const auto& r) {
        for (std::size_t i = r.begin(); i != r.end(); ++i) {
            const int e = receivers[i];
            const Element& el = elements[e];
            RayRandom rng{hashPair(seed, static_cast<std::uint64_t>(e))};
            Vec3 tx, ty;
            frameAround(el.normal, tx, ty);
            const Vec3 origin = el.centroid + el.normal * eps;
            Rgb sum(0.0);
            for (int k = 0; k < nx * ny; ++k) {
                const double u = (k % nx + rng.next()) / nx, v = (k / nx + rng.next()) / ny;
                const double phi = 2 * M_PI * u, rr = std::sqrt(v);
                const Vec3 dir = rr * std::cos(phi) * tx + rr * std::sin(phi) * ty +
                                 std::sqrt(std::max(0.0, 1 - v)) * el.normal;
                const RayTracer::FirstHit h = mTracer.firstHit(origin, dir, after);
                if (h.element < 0 || h.backFace) continue;
                const int j = elements[h.element].patch;
                if (j == el.patch || !c.isGathered(j)) continue;
                sum += c.shot[j];
            }
            delta[e] = sum / static_cast<double>(nx * ny);
        }
    });
}

bool ProgressiveSolver::shootRedistribution() {
    int k = -1;
    double best = bestRedistribution(&k);
    if (best <= 0 || k < 0) return false;
    ChangeEntry& c = mImpl->changes[k];
    const bool gather = shouldGather(c, best);
    if (!gather && mOptions.stochasticBelow > 0 &&
        best < mOptions.stochasticBelow * mEmittedEnergy) {
        shootRedistributionBatch(k);
        return true;
    }
    const unsigned long long raysBefore = mTracer.rayCount();
    auto& delta = mImpl->delta;
    Rgb share(0.0);  // gathered shooters are not emitters: no emission share
    if (gather) {
        // The added objects' elements gather what the weak shooters would send them: far
        // less noise than the same rays shot, and the edit's most changed elements.
        gatherToAdded(c, false, delta);
    } else {
        const int j = c.pending.top();
        c.totalPending -= c.pending.key(j);
        c.pending.update(j, 0.0);
        redistributionDelta(c, j, false, delta);
        share = c.shotEmissionShare[j];
    }
    for (std::size_t e = 0; e < delta.size(); ++e)
        if (!isZero(delta[e])) {
            receive(static_cast<int>(e), delta[e], share);
            touchElement(static_cast<int>(e));
        }
    updateTouchedPriorities();

    if (c.pending.key(c.pending.top()) <= 0) mImpl->changes.erase(mImpl->changes.begin() + k);
    ++mStats.shots;
    ++mStats.redistributionShots;
    mStats.rays += mTracer.rayCount() - raysBefore;
    return true;
}

void ProgressiveSolver::shootRedistributionBatch(int k) {
    // The weak tail of an edit's redistribution, stochastically (as the propagation tail):
    // rays leave the pending shooters in proportion to their importance, aimed into the cone
    // that the changed objects' bounding sphere subtends (no other ray can change), and are
    // traced in the world before and after the edit. Where the first hits differ, the ray's
    // power leaves the old receiver (negative energy into the new shadow, or the cancelled
    // light of a removed object) and reaches the new one. In expectation this is exactly
    // ρ_i S_j (F_ij(after) − F_ij(before)) summed over the batch.
    ChangeEntry& c = mImpl->changes[k];
    const auto& patches = mDisc.patches();
    const unsigned long long raysBefore = mTracer.rayCount();
    std::vector<int> shooters;
    std::vector<double> cdf;
    double total = 0;
    // The most important shooters first, as many as fit in one batch of rays; the rest stay
    // pending for the next batch, so the first corrections arrive quickly.
    const double raysPerEmitted = mOptions.redistributionRaysPerEmittedPower > 0
                                      ? mOptions.redistributionRaysPerEmittedPower
                                      : mOptions.raysPerEmittedPower;
    const double raysPerWatt = raysPerEmitted / std::max(mEmittedEnergy, 1e-300);
    while (c.pending.top() >= 0 && c.pending.key(c.pending.top()) > 0) {
        int j = c.pending.top();
        if (!shooters.empty() && (total + c.pending.key(j)) * raysPerWatt > mOptions.maxBatchRays)
            break;
        shooters.push_back(j);
        cdf.push_back(total += c.pending.key(j));
        c.totalPending -= c.pending.key(j);
        c.pending.update(j, 0.0);
    }
    if (shooters.empty()) return;
    const double share = mEmittedEnergy > 0 ? total / mEmittedEnergy : 1.0;
    const std::size_t rays = static_cast<std::size_t>(std::clamp(
        std::ceil(share * raysPerEmitted), static_cast<double>(mOptions.minStochasticRays), 6.4e7));
    const std::uint64_t batchSeed =
        hashPair(hashPair(mOptions.seed, 0x7ed157ull), mStats.redistributionShots);
    Visibility before = c.beforeWorld(), after = c.afterWorld();
    if (afterIsCurrentScene(c, false)) after = Visibility{};
    const Visibility changed = c.changed.visibility();
    const bool onlyAdded = c.removed.empty();
    // Per ray: what leaves the element it reached before the edit (2r) and what reaches the
    // element it reaches after (2r + 1).
    auto& out = mImpl->rayHits;
    out.assign(2 * rays, Received{});
    const double eps = mTracer.epsilon();
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, rays, 256), [&](const auto& range) {
        thread_local PatchPoints points;
        std::size_t current = shooters.size();  // none yet in this block
        for (std::size_t r = range.begin(); r != range.end(); ++r) {
            RayRandom rng{hashPair(batchSeed, r)};
            double u = (static_cast<double>(r) + rng.next()) / static_cast<double>(rays) * total;
            const std::size_t pick = shooterAt(cdf, current, u);
            const int j = shooters[pick];
            const double pj = (cdf[pick] - (pick ? cdf[pick - 1] : 0.0)) / total;
            const Patch& P = patches[j];
            const bool removed =
                std::find(c.removed.begin(), c.removed.end(), P.object) != c.removed.end();
            if (pick != current) points.set(mDisc, P), current = pick;
            Vec3 origin, nz, tx, ty;
            points.sample(rng, origin, nz, tx, ty);
            origin += nz * eps;
            // Direction: into the cones the changed objects' bounding spheres subtend (one
            // picked by solid angle; the density counts every cone holding the direction), or
            // the hemisphere when the point is inside a sphere or the shooter was removed.
            double weight;  // cos/π over the sampling density: ∫ cos/π dω per unit area
            Vec3 dir;
            struct Cone {
                Vec3 axis;
                double cosMax, solidAngle;
            };
            Cone cones[8];
            std::size_t nCones = 0;
            bool inside = removed || c.spheres.size() > 8;
            double totalSolidAngle = 0;
            for (std::size_t k = 0; !inside && k < c.spheres.size(); ++k) {
                Vec3 axis = c.spheres[k].first - origin;
                const double dist = glm::length(axis), r = c.spheres[k].second;
                if (dist <= r) {
                    inside = true;
                    break;
                }
                const double cosMax = std::sqrt(std::max(0.0, 1 - (r / dist) * (r / dist)));
                cones[nCones++] = {axis / dist, cosMax, 2 * M_PI * (1 - cosMax)};
                totalSolidAngle += 2 * M_PI * (1 - cosMax);
            }
            if (inside || nCones == 0) {
                dir = cosineDirection(nz, tx, ty, rng);
                weight = 1.0;  // cosine sampling of the whole hemisphere
            } else {
                double pickCone = rng.next() * totalSolidAngle;
                std::size_t k = 0;
                while (k + 1 < nCones && pickCone > cones[k].solidAngle)
                    pickCone -= cones[k++].solidAngle;
                const Cone& cone = cones[k];
                double cosT = 1 - rng.next() * (1 - cone.cosMax);
                double sinT = std::sqrt(std::max(0.0, 1 - cosT * cosT));
                double phi = 2 * M_PI * rng.next();
                Vec3 tx, ty;
                frameAround(cone.axis, tx, ty);
                dir = sinT * std::cos(phi) * tx + sinT * std::sin(phi) * ty + cosT * cone.axis;
                double cosSrc = glm::dot(dir, nz);
                if (cosSrc <= 0) continue;
                int holding = 0;
                for (std::size_t m = 0; m < nCones; ++m)
                    if (m == k || glm::dot(dir, cones[m].axis) >= cones[m].cosMax) ++holding;
                weight = totalSolidAngle / holding * cosSrc / M_PI;
            }
            const Rgb carried = c.shot[j] * (P.area * weight / (static_cast<double>(rays) * pj));
            // A ray that misses every changed object hits the same element in both worlds.
            RayTracer::FirstHit hc;
            if (!removed && (hc = mTracer.firstHit(origin, dir, changed)).element < 0) continue;
            RayTracer::FirstHit hb = mTracer.firstHit(origin, dir, before);
            RayTracer::FirstHit ha;
            if (removed) {
                // The shooter is gone: nothing reaches anything after the edit.
            } else if (onlyAdded) {
                // After = before ∪ added: the nearer of the two first hits (the same
                // instances and transforms give the same t as tracing the union).
                ha = hb.element < 0 || hc.t < hb.t ? hc : hb;
            } else {
                ha = mTracer.firstHit(origin, dir, after);
            }
            int eb = hb.element >= 0 && !hb.backFace ? hb.element : -1;
            int ea = ha.element >= 0 && !ha.backFace ? ha.element : -1;
            if (eb == ea) continue;
            auto receives = [&](int e) {
                int o = mDisc.elements()[e].object;
                return mDisc.objects()[o].alive && c.after[o] && mDisc.elements()[e].patch != j;
            };
            if (eb >= 0 && c.before[mDisc.elements()[eb].object] && receives(eb)) {
                const Element& el = mDisc.elements()[eb];
                out[2 * r] = {eb, el.patch, el.area, -carried / el.area, j};
            }
            if (ea >= 0 && receives(ea) &&
                !(c.isGathered(j) && !c.before[mDisc.elements()[ea].object])) {
                const Element& el = mDisc.elements()[ea];
                out[2 * r + 1] = {ea, el.patch, el.area, carried / el.area, j};
            }
        }
    });
    // Apply in ray order: independent of the thread count.
    receiveAll(out, c.shotEmissionShare);
    if (c.pending.top() < 0 || c.pending.key(c.pending.top()) <= 0)
        mImpl->changes.erase(mImpl->changes.begin() + k);
    ++mStats.shots;
    ++mStats.redistributionShots;
    ++mStats.stochasticBatches;
    mStats.rays += mTracer.rayCount() - raysBefore;
}

// ---------------------------------------------------------------------------------------------
// Drag preview: the temporary buffer

void ProgressiveSolver::setPreview(int object) {
    ensureSizes();
    clearPreview();
    mImpl->previewObject = object;
    mImpl->previewEntry = makeChangeEntry({{}, {object}});
    mImpl->previewEntry.after[object] = 1;
    buildWorldScenes(mImpl->previewEntry);
    mImpl->previewEmitters.clear();
    for (std::size_t j = 0; j < mDisc.patches().size(); ++j)
        if (mDisc.patches()[j].object == object &&
            mDisc.patchMaterial(static_cast<int>(j)).isEmitter())
            mImpl->previewEmitters.push_back(static_cast<int>(j));
    mImpl->temp.assign(mDisc.elements().size(), Rgb(0.0));
    mImpl->tempEmission.assign(mDisc.elements().size(), Rgb(0.0));
    // The object shows its own emission at once.
    for (int j : mImpl->previewEmitters)
        for (int e : mDisc.patches()[j].elements)
            mImpl->temp[e] = mImpl->tempEmission[e] = mDisc.patchMaterial(j).emission;
}

int ProgressiveSolver::stepPreview(int maxShots) {
    if (mImpl->previewObject < 0) return 0;
    auto start = std::chrono::steady_clock::now();
    const unsigned long long raysBefore = mTracer.rayCount();
    ChangeEntry& c = mImpl->previewEntry;
    auto& delta = mImpl->delta;
    int done = 0;
    for (; done < maxShots; ++done) {
        Rgb share(0.0);  // of the shot's radiosity that is emission
        if (!mImpl->previewEmitters.empty()) {
            // The dragged object's own light first (direct only): E·F to every receiver.
            int j = mImpl->previewEmitters.back();
            mImpl->previewEmitters.pop_back();
            const Rgb e = mDisc.patchMaterial(j).emission;
            const Visibility after = c.afterWorld();
            const std::size_t n = mDisc.elements().size();
            delta.assign(n, Rgb(0.0));
            tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 256), [&](const auto& range) {
                for (std::size_t el = range.begin(); el != range.end(); ++el)
                    delta[el] = irradianceFrom(j, static_cast<int>(el), e, after);
            });
            share = Rgb(1.0);
        } else {
            int j = c.pending.top();
            if (j < 0 || c.pending.key(j) <= 0) break;
            if (shouldGather(c, c.pending.key(j))) {
                // The weak shooters reach the dragged object in one gather (as in
                // shootRedistribution); their shots that follow only correct the shadows.
                gatherToAdded(c, true, delta);
            } else {
                c.pending.update(j, 0.0);
                redistributionDelta(c, j, true, delta);
                share = c.shotEmissionShare[j];
            }
        }
        mImpl->tempEmission.resize(mImpl->temp.size(), Rgb(0.0));
        for (std::size_t el = 0; el < delta.size(); ++el)
            if (!isZero(delta[el])) {
                const Rgb dB = mDisc.elementMaterial(static_cast<int>(el)).reflectance * delta[el];
                mImpl->temp[el] += dB;
                mImpl->tempEmission[el] += dB * share;
            }
    }
    mStats.shots += static_cast<std::uint64_t>(done);
    mStats.rays += mTracer.rayCount() - raysBefore;
    mStats.seconds +=
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    return done;
}

void ProgressiveSolver::clearPreview() {
    mImpl->previewObject = -1;
    mImpl->previewEmitters.clear();
    mImpl->previewEntry = ChangeEntry{};
    std::fill(mImpl->temp.begin(), mImpl->temp.end(), Rgb(0.0));
    std::fill(mImpl->tempEmission.begin(), mImpl->tempEmission.end(), Rgb(0.0));
}

int ProgressiveSolver::previewObject() const { return mImpl->previewObject; }

bool ProgressiveSolver::previewComplete() const {
    if (mImpl->previewObject < 0) return false;
    const ChangeEntry& c = mImpl->previewEntry;
    if (!mImpl->previewEmitters.empty()) return false;
    const int j = c.pending.top();
    return !c.gathered.empty() || j < 0 || c.pending.key(j) <= 0;
}

const std::vector<Rgb>& ProgressiveSolver::previewRadiosity() const {
    mImpl->temp.resize(mDisc.elements().size(), Rgb(0.0));
    return mImpl->temp;
}

const std::vector<Rgb>& ProgressiveSolver::previewRadiosityFromEmission() const {
    mImpl->tempEmission.resize(mDisc.elements().size(), Rgb(0.0));
    return mImpl->tempEmission;
}

std::vector<Rgb> ProgressiveSolver::displayRadiosity() const {
    Rgb amb = ambient();
    std::vector<Rgb> out(mElementB.size());
    for (std::size_t e = 0; e < out.size(); ++e)
        out[e] = mElementB[e] + mDisc.elementMaterial(static_cast<int>(e)).reflectance * amb +
                 (e < mImpl->temp.size() ? mImpl->temp[e] : Rgb(0.0));
    return out;
}

Rgb ProgressiveSolver::ambient() const {
    // Cohen eqs. 9–12: R = 1/(1 − ρ_ave), Ambient = R Σ ΔB_j A_j / Σ A_j.
    Rgb rhoSum(0.0), unshot(0.0);
    double area = 0;
    for (std::size_t p = 0; p < mPatchUnshot.size(); ++p) {
        if (!mDisc.patchAlive(static_cast<int>(p))) continue;
        double a = mDisc.patches()[p].area;
        rhoSum += mDisc.patchMaterial(static_cast<int>(p)).reflectance * a;
        unshot += mPatchUnshot[p] * a;
        area += a;
    }
    if (!(area > 0)) return Rgb(0.0);
    Rgb rhoAve = rhoSum / area;
    Rgb R = 1.0 / (1.0 - rhoAve);
    return R * unshot / area;
}

Rgb ProgressiveSolver::patchRadiosity(int patch) const {
    const Patch& P = mDisc.patches()[patch];
    Rgb sum(0.0);
    for (int e : P.elements) sum += mElementB[e] * mDisc.elements()[e].area;
    return P.area > 0 ? sum / P.area : sum;
}

Rgb ProgressiveSolver::irradianceAt(const Vec3& x, const Vec3& n, int rays) const {
    std::uint64_t key = 0;
    for (double c : {x.x, x.y, x.z, n.x, n.y, n.z}) {
        std::uint64_t bits;
        std::memcpy(&bits, &c, sizeof bits);
        key = hashPair(key, bits);
    }
    Vec3 un = glm::normalize(n);
    Rgb h(0.0);
    for (std::size_t p = 0; p < mDisc.patches().size(); ++p) {
        if (!mDisc.patchAlive(static_cast<int>(p))) continue;
        Rgb b = patchRadiosity(static_cast<int>(p));
        if (isZero(b)) continue;
        PointToPatch ff =
            formFactorToPatch(mDisc, mTracer, x, un, static_cast<int>(p), key, mOptions.seed, rays);
        h += b * ff.visible;
    }
    return h;
}

}  // namespace penumbra
