// Propagation (Cohen, Chen, Wallace, Greenberg 1988); the edits' redistribution and the drag
// preview are in redistribution.cpp.
//
// Index: set-up · step/converge (scheduling propagation and redistribution) · one shot
//        (Cohen et al. 1988 §4 pseudo-code) · stochastic tail · adaptive subdivision (§3.4)
//        · queries
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
#include "solver/progressive_solver_internal.h"

namespace penumbra {

using namespace solver_detail;

SolverOptions interactiveSolverOptions() {
    SolverOptions o;
    o.stochasticBelow = 1e-3;
    o.raysPerEmittedPower = 1e7;
    o.redistributionRaysPerEmittedPower = 2.5e6;
    o.redistributionThreshold = 1e-4;
    o.gatherRays = 256;
    o.gatherRayBudget = 1e5;
    o.gatherBelow = 1.0;
    o.gatherCoarseBlock = 2;
    o.previewShadowRayBudget = 6e4;
    return o;
}

ProgressiveSolver::ProgressiveSolver(Discretization& disc, RayTracer& tracer, SolverOptions options)
    : mDisc(disc), mTracer(tracer), mOptions(options), mImpl(std::make_unique<Impl>()) {
    if (mOptions.placeReceivers) mDisc.placeReceivers(mTracer);
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
    mImpl->irradianceVariance.assign(elements.size(), Rgb(0.0));
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
    // Redistribution's receiver bounds, ahead of the first edit.
    mImpl->receiverBounds.update(mDisc);
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
            // Only a gather's second pass ran: no shot yet, choose again.
            if (!shootRedistribution()) --done;
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
            const std::uint64_t refinements = mImpl->gatherRefinements;
            bool shot = shootRedistribution();
            mStats.seconds +=
                std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
            if (!shot && mImpl->gatherRefinements != refinements) continue;  // not a shot
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
    mImpl->irradianceVariance.resize(ne, Rgb(0.0));
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
            // Each hit is an independent sample: its square adds to the noise's variance.
            mImpl->irradianceVariance[r.element] += r.irradiance * r.irradiance;
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
                            receivers[m] = {mDisc.receiver(e), el.normal,
                                            static_cast<std::uint64_t>(e)};
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
    Vec3 toReceiver = mDisc.receiver(e) - P.centroid;
    if (glm::dot(toReceiver, P.normal) < -P.radius) return false;
    if (glm::dot(-toReceiver, el.normal) < -P.radius) return false;
    return true;
}

Rgb ProgressiveSolver::irradianceFrom(int shooter, int e, const Rgb& dB,
                                      const Visibility& visibility, int* rays) const {
    if (!mayReceive(shooter, e, visibility)) return Rgb(0.0);
    const Element& el = mDisc.elements()[e];
    PointToPatch ff = formFactorToPatch(mDisc, mTracer, mDisc.receiver(e), el.normal, shooter,
                                        static_cast<std::uint64_t>(e), mOptions.seed,
                                        mOptions.maxRaysPerPair, visibility);
    if (rays) *rays += ff.rays;
    return dB * ff.visible;
}

Rgb ProgressiveSolver::irradianceChange(int shooter, int receiverPatch, const Receiver& r,
                                        const Rgb& dB, const Visibility& before,
                                        const Visibility& after, const Visibility& changed,
                                        ChangedObjectsIn where) const {
    const Patch& P = mDisc.patches()[shooter];
    if (receiverPatch == shooter) return Rgb(0.0);
    // The same culls as irradianceFrom: pairs that cannot see each other.
    Vec3 toReceiver = r.x - P.centroid;
    if (glm::dot(toReceiver, P.normal) < -P.radius) return Rgb(0.0);
    if (glm::dot(-toReceiver, r.n) < -P.radius) return Rgb(0.0);
    PointToPatch ff = formFactorChange(mDisc, mTracer, r.x, r.n, shooter, r.key, mOptions.seed,
                                       mOptions.maxRaysPerPair, before, after, changed, where);
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
            mImpl->irradianceVariance[c] = Rgb(0.0);  // its history is gathered exactly
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
// Queries

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
