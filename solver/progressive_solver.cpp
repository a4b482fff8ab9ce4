// Index: set-up · step/converge · one shot (Cohen et al. 1988 §4 pseudo-code) · adaptive
//        subdivision (§3.4) · queries (ambient, irradiance)
#include "solver/progressive_solver.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>

#include "solver/form_factor.h"
#include "solver/indexed_heap.h"

namespace penumbra {

namespace {

double energyKey(const Rgb& unshot, double area) {
    return (std::abs(unshot.x) + std::abs(unshot.y) + std::abs(unshot.z)) * area;
}

bool isZero(const Rgb& c) { return c.x == 0 && c.y == 0 && c.z == 0; }

}  // namespace

SolverOptions interactiveSolverOptions() {
    SolverOptions o;
    o.stochasticBelow = 1e-3;
    o.raysPerEmittedPower = 1e7;
    return o;
}

struct ProgressiveSolver::Impl {
    IndexedMaxHeap queue;
    std::vector<Rgb> delta;     ///< per element, radiosity received in the current shot
    std::vector<int> level;     ///< per element, subdivision depth
    // Scratch for stochastic batches.
    std::vector<double> patchCdf;              ///< power CDF over the shooters
    std::vector<int> shooters;                 ///< patches shot in the batch
    std::vector<Rgb> shooterUnshot;            ///< their ΔB at the start of the batch
    std::vector<std::pair<int, Rgb>> rayHits;  ///< per ray: receiver element and ΔRad
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
    mElementB.assign(elements.size(), Rgb(0.0));
    mImpl->level.assign(elements.size(), 0);
    mImpl->queue.reset(patches.size());
    mEmittedEnergy = 0;
    for (std::size_t p = 0; p < patches.size(); ++p) {
        const Rgb& e = mDisc.patchMaterial(static_cast<int>(p)).emission;
        mPatchUnshot[p] = e;
        for (int el : patches[p].elements) mElementB[el] = e;
        mEmittedEnergy += (e.x + e.y + e.z) * patches[p].area;
        mImpl->queue.update(static_cast<int>(p), energyKey(e, patches[p].area));
    }
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
        if (p < 0 || mImpl->queue.key(p) <= 0) break;
        if (mOptions.stochasticBelow > 0 &&
            mImpl->queue.key(p) < mOptions.stochasticBelow * mEmittedEnergy)
            shootStochasticBatch();
        else
            shootPatch(p);
    }
    mStats.seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    return done;
}

std::uint64_t ProgressiveSolver::converge(double eps, std::uint64_t maxShots,
                                          const std::function<void(double)>& progress) {
    std::uint64_t shots = 0;
    while (shots < maxShots && unshotFraction() > eps) {
        if (step(1) == 0) break;
        ++shots;
        if (progress) progress(unshotFraction());
    }
    return shots;
}

void ProgressiveSolver::shootPatch(int shooter) {
    const auto& patches = mDisc.patches();
    const Rgb dB = mPatchUnshot[shooter];
    mPatchUnshot[shooter] = Rgb(0.0);
    mImpl->queue.update(shooter, 0.0);
    if (isZero(dB)) return;
    const unsigned long long raysBefore = mTracer.rayCount();

    // Gather the radiosity each element receives from this shot (Cohen §4:
    // ΔRad = ρ_e ΔB_i F_ie A_i / A_e, with F_ie A_i / A_e = F_e→i by reciprocity).
    const std::size_t n = mDisc.elements().size();
    auto& delta = mImpl->delta;
    delta.assign(n, Rgb(0.0));
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 256), [&](const auto& range) {
        for (std::size_t e = range.begin(); e != range.end(); ++e)
            delta[e] = receivedFrom(shooter, static_cast<int>(e), dB);
    });

    // Apply in element order, so results do not depend on the thread count.
    for (std::size_t e = 0; e < n; ++e) {
        if (isZero(delta[e])) continue;
        const Element& el = mDisc.elements()[e];
        mElementB[e] += delta[e];
        mPatchUnshot[el.patch] += delta[e] * (el.area / patches[el.patch].area);
    }
    if (mOptions.gradientThreshold > 0) subdivideSteepElements(shooter, dB);
    for (std::size_t e = 0; e < mDisc.elements().size(); ++e) {
        if (e < delta.size() && isZero(delta[e])) continue;
        int p = mDisc.elements()[e].patch;
        mImpl->queue.update(p, energyKey(mPatchUnshot[p], patches[p].area));
    }
    ++mStats.shots;
    mStats.rays += mTracer.rayCount() - raysBefore;
}

Rgb ProgressiveSolver::receivedFrom(int shooter, int e, const Rgb& dB) const {
    const Patch& P = mDisc.patches()[shooter];
    const Element& el = mDisc.elements()[e];
    if (el.patch == shooter) return Rgb(0.0);
    const Rgb& rho = mDisc.patchMaterial(el.patch).reflectance;
    if (isZero(rho)) return Rgb(0.0);
    // Cull pairs that cannot see each other: receiver behind the shooter's bounding plane or
    // shooter behind the receiver's plane.
    Vec3 toReceiver = el.centroid - P.centroid;
    if (glm::dot(toReceiver, P.normal) < -P.radius) return Rgb(0.0);
    if (glm::dot(-toReceiver, el.normal) < -P.radius) return Rgb(0.0);
    PointToPatch ff = formFactorToPatch(mDisc, mTracer, el.centroid, el.normal, shooter,
                                        static_cast<std::uint64_t>(e), mOptions.seed,
                                        mOptions.maxRaysPerPair);
    return rho * dB * ff.visible;
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
    shooters.clear();
    unshot.clear();
    cdf.clear();
    double total = 0;
    for (std::size_t p = 0; p < patches.size(); ++p) {
        double power = energyKey(mPatchUnshot[p], patches[p].area);
        if (!(power > 0)) continue;
        shooters.push_back(static_cast<int>(p));
        unshot.push_back(mPatchUnshot[p]);
        cdf.push_back(total += power);
        mPatchUnshot[p] = Rgb(0.0);
        mImpl->queue.update(static_cast<int>(p), 0.0);
    }
    if (shooters.empty()) return;
    const double share = mEmittedEnergy > 0 ? total / mEmittedEnergy : 1.0;
    const std::size_t rays = static_cast<std::size_t>(std::clamp(
        std::ceil(share * mOptions.raysPerEmittedPower),
        static_cast<double>(mOptions.minStochasticRays), 6.4e7));
    const std::uint64_t batchSeed = hashPair(hashPair(mOptions.seed, 0x5707c4a57ull),
                                             mStats.stochasticBatches);
    auto& hits = mImpl->rayHits;
    hits.assign(rays, {-1, Rgb(0.0)});
    const double eps = mTracer.epsilon();
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, rays, 256), [&](const auto& range) {
        std::vector<Vec3> poly;
        for (std::size_t r = range.begin(); r != range.end(); ++r) {
            std::uint64_t state = hashPair(batchSeed, r);
            auto next = [&state] {
                state = hashPair(state, 0x9e3779b97f4a7c15ull);
                return static_cast<double>(state >> 11) * 0x1.0p-53;
            };
            // The shooter, by power; the element, by area; a uniform point in it.
            double u = (static_cast<double>(r) + next()) / static_cast<double>(rays) * total;
            std::size_t k = std::lower_bound(cdf.begin(), cdf.end(), u) - cdf.begin();
            k = std::min(k, cdf.size() - 1);
            const Patch& P = patches[shooters[k]];
            double pickArea = next() * P.area;
            int se = P.elements.back();
            for (int e : P.elements) {
                if (pickArea <= mDisc.elements()[e].area) {
                    se = e;
                    break;
                }
                pickArea -= mDisc.elements()[e].area;
            }
            const Element& src = mDisc.elements()[se];
            poly = mDisc.elementPolygon(se);
            double pick = next() * src.area * 2, r1 = next(), r2 = next();
            std::size_t t = 1;
            for (; t + 2 < poly.size(); ++t) {
                double a = glm::length(glm::cross(poly[t] - poly[0], poly[t + 1] - poly[0]));
                if (pick <= a) break;
                pick -= a;
            }
            double sq = std::sqrt(r1);
            Vec3 origin = (1 - sq) * poly[0] + sq * (1 - r2) * poly[t] + sq * r2 * poly[t + 1];
            // Cosine-distributed direction about the source normal (Malley's method).
            double phi = 2 * M_PI * next(), rr = std::sqrt(next());
            const Vec3& nz = src.normal;
            Vec3 tx = std::abs(nz.x) > 0.5 ? Vec3(0, 1, 0) : Vec3(1, 0, 0);
            tx = glm::normalize(glm::cross(tx, nz));
            Vec3 ty = glm::cross(nz, tx);
            Vec3 dir = rr * std::cos(phi) * tx + rr * std::sin(phi) * ty +
                       std::sqrt(std::max(0.0, 1 - rr * rr)) * nz;
            RayHit hit = mTracer.intersect(origin + nz * eps, dir, 0.0, 1e30);
            if (hit.element < 0 || hit.backFace) continue;  // escaped, or absorbed by a back
            const Element& rec = mDisc.elements()[hit.element];
            if (rec.patch == shooters[k]) continue;
            // This ray carries power total/rays, in the colour of its shooter's ΔB.
            const Rgb carried = unshot[k] * (P.area * total /
                                             (static_cast<double>(rays) *
                                              energyKey(unshot[k], P.area)));
            const Rgb& rho = mDisc.patchMaterial(rec.patch).reflectance;
            hits[r] = {hit.element, rho * carried / rec.area};
        }
    });
    // Accumulate in ray order: independent of the thread count.
    for (const auto& [e, d] : hits) {
        if (e < 0) continue;
        const Element& el = mDisc.elements()[e];
        mElementB[e] += d;
        mPatchUnshot[el.patch] += d * (el.area / patches[el.patch].area);
    }
    for (const auto& [e, d] : hits) {
        if (e < 0) continue;
        int p = mDisc.elements()[e].patch;
        mImpl->queue.update(p, energyKey(mPatchUnshot[p], patches[p].area));
    }
    ++mStats.shots;
    ++mStats.stochasticBatches;
    mStats.rays += mTracer.rayCount() - raysBefore;
}

void ProgressiveSolver::subdivideSteepElements(int shooter, const Rgb& dB) {
    // Cohen §3.4: where the radiosity difference between neighbouring elements is too high,
    // subdivide and reshoot this patch to the new elements.
    std::vector<int> steep;
    const std::size_t n = mDisc.elements().size();
    double maxY = 0;
    for (std::size_t e = 0; e < n; ++e) maxY = std::max(maxY, luminance(mElementB[e]));
    for (std::size_t e = 0; e < n; ++e) {
        if (isZero(mImpl->delta[e]) || mImpl->level[e] >= mOptions.maxSubdivisionLevel) continue;
        double ye = luminance(mElementB[e]);
        for (int nb : mDisc.elementNeighbours(static_cast<int>(e))) {
            if (mDisc.elements()[nb].patch != mDisc.elements()[e].patch &&
                glm::dot(mDisc.elements()[nb].normal, mDisc.elements()[e].normal) < 0.99)
                continue;
            double yn = luminance(mElementB[nb]);
            if (std::abs(ye - yn) > mOptions.gradientThreshold * std::max(maxY * 1e-2, std::max(ye, yn))) {
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
        const double parentArea = mDisc.elements()[e].area;
        std::vector<int> children = mDisc.subdivideElement(e);
        if (children.size() < 2) continue;
        mElementB.resize(mDisc.elements().size(), Rgb(0.0));
        mImpl->level.resize(mDisc.elements().size(), 0);
        mImpl->delta.resize(mDisc.elements().size(), Rgb(0.0));
        // Each child gathers everything shot so far: every earlier shot of patch j used the
        // same pair-seeded F(child ← j), so Σ over j of (B_j − ΔB_j) F is its exact history
        // (Cohen's "reshoot patch i", extended to all earlier shooters).
        Rgb change(0.0);
        for (int c : children) {
            mElementB[c] = mDisc.patchMaterial(patch).emission + gatherShotRadiosity(c);
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
    (void)dB;
    (void)shooter;
}

Rgb ProgressiveSolver::gatherShotRadiosity(int element) const {
    const std::size_t np = mDisc.patches().size();
    std::vector<Rgb> parts(np, Rgb(0.0));
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, np, 64), [&](const auto& range) {
        for (std::size_t j = range.begin(); j != range.end(); ++j) {
            Rgb shot = patchRadiosity(static_cast<int>(j)) - mPatchUnshot[j];
            if (!isZero(shot)) parts[j] = receivedFrom(static_cast<int>(j), element, shot);
        }
    });
    Rgb sum(0.0);
    for (const Rgb& p : parts) sum += p;
    return sum;
}

std::vector<Rgb> ProgressiveSolver::displayRadiosity() const {
    Rgb amb = ambient();
    std::vector<Rgb> out(mElementB.size());
    for (std::size_t e = 0; e < out.size(); ++e)
        out[e] = mElementB[e] + mDisc.elementMaterial(static_cast<int>(e)).reflectance * amb;
    return out;
}

Rgb ProgressiveSolver::ambient() const {
    // Cohen eqs. 9–12: R = 1/(1 − ρ_ave), Ambient = R Σ ΔB_j A_j / Σ A_j.
    Rgb rhoSum(0.0), unshot(0.0);
    double area = 0;
    for (std::size_t p = 0; p < mPatchUnshot.size(); ++p) {
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
        Rgb b = patchRadiosity(static_cast<int>(p));
        if (isZero(b)) continue;
        PointToPatch ff = formFactorToPatch(mDisc, mTracer, x, un, static_cast<int>(p), key,
                                            mOptions.seed, rays);
        h += b * ff.visible;
    }
    return h;
}

}  // namespace penumbra
