// The drag preview (George, Sillion, Greenberg 1990): the temporary buffer a dragged object's
// positions are shot into, and the gather of its shadow in the reflected light. The edits and
// their redistribution shots, which the preview's steps share, are in redistribution.cpp.
//
// Index: the gathered shadow · the temporary buffer
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <chrono>
#include <cmath>

#include "solver/form_factor.h"
#include "solver/progressive_solver.h"
#include "solver/progressive_solver_internal.h"

namespace penumbra {

using namespace solver_detail;

// ---------------------------------------------------------------------------------------------
// Drag preview: the shadow of the previewed object in the reflected light, gathered

namespace {

/// gatherPreviewShadow's receivers: where the object's bounding sphere subtends a cone of
/// half angle at least asin(√kPreviewShadowSin2) (within about seven radii), at most
/// budget / kPreviewShadowMinRays of them, those it subtends most.
constexpr double kPreviewShadowSin2 = 0.02;
/// Rays per receiver, between these bounds (SolverOptions::previewShadowRayBudget in all).
constexpr int kPreviewShadowMinRays = 16, kPreviewShadowMaxRays = 64;
/// The object's elements look at their surroundings with n × n stratified cosine rays.
constexpr int kPreviewObjectStrata = 4;

}  // namespace

void ProgressiveSolver::gatherPreviewShadow(ChangeEntry& c, std::vector<Rgb>& delta) {
    const auto& elements = mDisc.elements();
    c.shadowGathered = true;
    const int object = mImpl->previewObject;
    std::vector<Rgb>& shadow = mImpl->previewShadow;
    // What the buffer holds of an earlier gather comes out of this step's change.
    delta.assign(elements.size(), Rgb(0.0));
    if (c.shadowCarried && shadow.size() == elements.size())
        for (std::size_t e = 0; e < elements.size(); ++e) delta[e] = -shadow[e];
    shadow.assign(elements.size(), Rgb(0.0));
    // What is gathered now is what the next positions move along.
    mImpl->gatheredShadowOf = object;
    if (object < 0 || c.spheres.empty()) {
        mImpl->gatheredShadow = shadow;
        return;
    }
    const Vec3 centre = c.spheres.front().first;
    const double radius = c.spheres.front().second;
    // The shooters the gather stands for: pending, not emitting (the lamps keep their exact
    // shots), not the object's own.
    const std::size_t np = c.shot.size();
    std::vector<std::uint8_t> covered(np, 0);
    for (std::size_t j = 0; j < np; ++j)
        covered[j] = c.pending.key(static_cast<int>(j)) > 0 &&
                     !mDisc.patchMaterial(static_cast<int>(j)).isEmitter() &&
                     mDisc.patches()[j].object != object;
    // Receivers: alive elements off the object where its bounding sphere subtends at least
    // kPreviewShadowSin2 (sin² of the cone's half angle), facing it; the nearest if too many.
    std::vector<std::pair<double, int>> near;
    for (std::size_t e = 0; e < elements.size(); ++e) {
        const Element& el = elements[e];
        if (el.object == object || !mDisc.elementAlive(static_cast<int>(e))) continue;
        const Vec3 d = centre - mDisc.receiver(static_cast<int>(e));
        const double d2 = glm::dot(d, d);
        if (d2 * kPreviewShadowSin2 > radius * radius) continue;
        const double dist = std::sqrt(d2);
        if (dist > radius && glm::dot(el.normal, d) / dist < -radius / dist) continue;
        near.emplace_back(d2, static_cast<int>(e));
    }
    const double budget = mOptions.previewShadowRayBudget;
    const std::size_t most =
        static_cast<std::size_t>(std::max(1.0, budget / kPreviewShadowMinRays));
    if (near.size() > most) {
        std::nth_element(near.begin(), near.begin() + static_cast<std::ptrdiff_t>(most),
                         near.end());
        near.resize(most);
    }
    std::vector<int> receivers;
    receivers.reserve(near.size());
    for (const auto& [d2, e] : near) receivers.push_back(e);
    std::sort(receivers.begin(), receivers.end());
    const Visibility after = c.afterWorld(), before = c.beforeWorld();
    const double eps = mTracer.epsilon();
    const std::uint64_t seed = hashPair(hashPair(mOptions.seed, 0x5ad0ull), mStats.shots);
    // The object's light as its surroundings now reflect it: its gather saw them as the
    // solution has them, without its shadow (the buffer's change there, the lamps' shadow
    // the emitter shots put in and the last gathered one, is what it misses). Each element
    // takes ρ times the buffer's radiosity it sees (one bounce more of the buffer's change).
    const auto [first, count] = mDisc.elementRange(object);
    std::vector<Rgb> objectLight(static_cast<std::size_t>(count), Rgb(0.0));
    tbb::parallel_for(tbb::blocked_range<int>(0, count, 8), [&](const auto& r) {
        constexpr int n = kPreviewObjectStrata;
        for (int k = r.begin(); k != r.end(); ++k) {
            const int a = first + k;
            const Element& el = elements[a];
            Vec3 tx, ty;
            frameAround(el.normal, tx, ty);
            RayRandom rng{hashPair(seed ^ 0x0b1ecull, static_cast<std::uint64_t>(a))};
            Rgb seen(0.0);
            for (int i = 0; i < n * n; ++i) {
                const double ru = rng.next(), rv = rng.next();
                const RayTracer::FirstHit h =
                    mTracer.firstHit(mDisc.receiver(a) + el.normal * eps,
                                     gatherDirection(i, n, n, ru, rv, tx, ty, el.normal), after);
                if (h.element >= 0 && !h.backFace && elements[h.element].object != object)
                    seen += mImpl->temp[h.element];
            }
            const Rgb rho = mDisc.elementMaterial(a).reflectance;
            // Not below nothing: the element's whole light is what it can lose.
            objectLight[k] =
                glm::max(mImpl->temp[a] + rho * seen / double(n * n), Rgb(0.0)) - mImpl->temp[a];
        }
    });
    for (int k = 0; k < count; ++k) {
        const Rgb rho = mDisc.elementMaterial(first + k).reflectance;
        for (int ch = 0; ch < 3; ++ch)
            if (rho[ch] > 0) delta[first + k][ch] += objectLight[k][ch] / rho[ch];
        objectLight[k] += mImpl->temp[first + k];
    }
    const int rays = std::clamp(
        static_cast<int>(budget / static_cast<double>(std::max<std::size_t>(1, receivers.size()))),
        kPreviewShadowMinRays, kPreviewShadowMaxRays);
    const int nx = static_cast<int>(std::ceil(std::sqrt(static_cast<double>(rays))));
    const int ny = (rays + nx - 1) / nx;
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, receivers.size(), 16), [&](const auto& r) {
        for (std::size_t i = r.begin(); i != r.end(); ++i) {
            const int e = receivers[i];
            const Element& el = elements[e];
            const Vec3 x = mDisc.receiver(e) + el.normal * eps;
            const Vec3 toCentre = centre - x;
            const double dist = glm::length(toCentre);
            RayRandom rng{hashPair(seed, static_cast<std::uint64_t>(e))};
            Rgb lost(0.0);
            // Outside the sphere, its cone sampled uniformly in solid angle (weight Ω/n × cosθ
            // per ray, over π); inside, the hemisphere cosine-distributed (weight 1/n).
            const bool inside = dist <= radius;
            Vec3 axis = inside ? el.normal : toCentre / dist, tx, ty;
            frameAround(axis, tx, ty);
            const double cosMax = inside ? 0.0 : std::sqrt(1 - radius * radius / (dist * dist));
            const double omega = 2 * M_PI * (1 - cosMax);
            for (int k = 0; k < nx * ny; ++k) {
                const double ru = rng.next(), rv = rng.next();
                const double u = (k % nx + ru) / nx, v = (k / nx + rv) / ny;
                Vec3 dir;
                double weight;
                if (inside) {
                    dir = gatherDirection(k, nx, ny, ru, rv, tx, ty, axis);
                    weight = 1.0;
                } else {
                    dir = coneDirection(axis, tx, ty, cosMax, u, v);
                    const double cosN = glm::dot(dir, el.normal);
                    if (cosN <= 0) continue;
                    weight = omega * cosN / M_PI;
                }
                const RayTracer::FirstHit a = mTracer.firstHit(x, dir, after);
                if (a.element < 0 || elements[a.element].object != object) continue;
                // The object's own reflected light (its buffer radiosity less its emission,
                // whose light its emitter shots sent) replaces what it hides.
                if (!a.backFace) {
                    const int k = a.element - first;
                    const Rgb light = k < count ? objectLight[k] : mImpl->temp[a.element];
                    lost -= (light - mDisc.elementMaterial(a.element).emission) * weight;
                }
                const RayTracer::FirstHit b = mTracer.firstHit(x, dir, before);
                if (b.element < 0 || b.backFace || b.patch == el.patch || !covered[b.patch])
                    continue;
                lost += c.shot[b.patch] * weight;
            }
            shadow[e] = -lost / static_cast<double>(nx * ny);
        }
    });
    for (int e : receivers) delta[e] += shadow[e];
    mImpl->gatheredShadow = shadow;
    for (std::size_t j = 0; j < np; ++j)
        if (covered[j]) c.pending.update(static_cast<int>(j), 0.0);
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
    // The same object one drag position on: its shadow in the reflected light as gathered at
    // an earlier position, moved with it, until this position's gather replaces it.
    std::vector<Rgb>& shadow = mImpl->previewShadow;
    const int gatheredOf = mImpl->gatheredShadowOf;
    if (gatheredOf >= 0 && gatheredOf < static_cast<int>(mDisc.objects().size()) &&
        mDisc.sameElements(gatheredOf, object) &&
        mImpl->gatheredShadow.size() <= mImpl->temp.size()) {
        shadow = movedPreviewShadow(mImpl->previewEntry, object);
        for (std::size_t e = 0; e < shadow.size(); ++e)
            mImpl->temp[e] += mDisc.elementMaterial(static_cast<int>(e)).reflectance * shadow[e];
        mImpl->previewEntry.shadowCarried = true;
    } else {
        forgetPreviewShadow();
    }
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
            const int j = c.pending.top();
            const double strongest = j >= 0 ? std::max(0.0, c.pending.key(j)) : 0.0;
            if (strongest <= 0 && !c.refinementPending()) break;
            if (!c.shadowGathered && !c.gathered.empty() && mOptions.previewShadowRayBudget > 0 &&
                (j < 0 || !mDisc.patchMaterial(j).isEmitter())) {
                // The object's light and the lamps' shadows are in (the strongest pending
                // shooter no longer emits): its shadow in the weak shooters' light at once.
                gatherPreviewShadow(c, delta);
            } else if (shouldGather(c, strongest)) {
                // The weak shooters reach the dragged object in one gather (as in
                // shootRedistribution); their shots that follow only correct the shadows.
                gatherToAdded(c, true, delta);
            } else if (shouldRefineGather(c, strongest)) {
                refineGather(c, true, delta);
                --done;  // completes the gather's shot (as in shootRedistribution)
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

void ProgressiveSolver::forgetPreviewShadow() {
    mImpl->previewShadow.clear();
    mImpl->gatheredShadow.clear();
    mImpl->gatheredShadowOf = -1;
}

std::vector<Rgb> ProgressiveSolver::movedPreviewShadow(const ChangeEntry& c, int object) const {
    const auto& elements = mDisc.elements();
    std::vector<Rgb> gathered = mImpl->gatheredShadow;
    gathered.resize(elements.size(), Rgb(0.0));  // the versions made since: none
    const int from = mImpl->gatheredShadowOf;
    if (c.spheres.empty()) return gathered;
    // Where a point near the object now was, relative to the object, at the gather.
    const Mat4 back = mDisc.objects()[from].worldFromObject *
                      glm::inverse(mDisc.objects()[object].worldFromObject);
    const Vec3 centre = c.spheres.front().first;
    const double radius = c.spheres.front().second;
    if (glm::length(Vec3(back * glm::dvec4(centre, 1.0)) - centre) <= 1e-9 * (1 + radius))
        return gathered;
    // A receiver off the object takes the value its own surface holds where the object's
    // motion since the gather brings the receiver from, projected onto the receiver's plane
    // (a shadow on the floor moves as the object moves over it; one on a wall the object
    // moves away from stays where it is); none where that surface ends, or where the gather
    // did not reach.
    std::vector<Rgb> moved(elements.size(), Rgb(0.0));
    const Visibility world = c.beforeWorld();
    const double lift = 1e-3 * (1 + radius) + 4 * mTracer.epsilon();
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, elements.size(), 256), [&](const auto& r) {
        for (std::size_t e = r.begin(); e != r.end(); ++e) {
            const Element& el = elements[e];
            if (el.object == object || el.object == from ||
                !mDisc.elementAlive(static_cast<int>(e)))
                continue;
            const Vec3 x = mDisc.receiver(static_cast<int>(e));
            const Vec3 d = centre - x;
            if (glm::dot(d, d) * kPreviewShadowSin2 > radius * radius) continue;
            Vec3 p(back * glm::dvec4(x, 1.0));
            p -= el.normal * glm::dot(p - x, el.normal);
            const RayTracer::FirstHit h = mTracer.firstHit(p + el.normal * lift, -el.normal, world);
            if (h.element < 0 || h.backFace || h.t > 2 * lift ||
                glm::dot(elements[h.element].normal, el.normal) < 0.99)
                continue;
            moved[e] = gathered[h.element];
        }
    });
    return moved;
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

}  // namespace penumbra
