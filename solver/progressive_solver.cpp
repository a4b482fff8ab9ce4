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

struct ProgressiveSolver::Impl {
    IndexedMaxHeap queue;
    std::vector<Rgb> delta;     ///< per element, radiosity received in the current shot
    std::vector<int> level;     ///< per element, subdivision depth
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
        const Rgb parentBefore = mElementB[e] - mImpl->delta[e];
        const Rgb parentDelta = mImpl->delta[e];
        const double parentArea = mDisc.elements()[e].area;
        const int patch = mDisc.elements()[e].patch;
        const int level = mImpl->level[e] + 1;
        std::vector<int> children = mDisc.subdivideElement(e);
        if (children.size() < 2) continue;
        mElementB.resize(mDisc.elements().size(), Rgb(0.0));
        mImpl->level.resize(mDisc.elements().size(), 0);
        mImpl->delta.resize(mDisc.elements().size(), Rgb(0.0));
        Rgb change(0.0);
        for (int c : children) {
            // Children inherit the parent's radiosity from earlier shots; this shot is
            // recomputed for each of them.
            Rgb d = receivedFrom(shooter, c, dB);
            mElementB[c] = parentBefore + d;
            mImpl->delta[c] = d;
            mImpl->level[c] = level;
            change += d * mDisc.elements()[c].area;
        }
        change -= parentDelta * parentArea;
        mPatchUnshot[patch] += change / mDisc.patches()[patch].area;
        ++mStats.subdivisions;
    }
    mTracer.rebuild();
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
