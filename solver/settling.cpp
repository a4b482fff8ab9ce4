// The settling estimate (docs/solver.md "Settling"): per element, how much the radiosity can
// still change before the solution converges, from the work the solver still holds (unshot
// energy, pending redistribution) and point form factors, without tracing a ray.
//
// Index: point form factors · the estimate (first order, interreflection, noise)
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <numeric>

#include "solver/form_factor.h"
#include "solver/progressive_solver.h"
#include "solver/progressive_solver_internal.h"

namespace penumbra {

using namespace solver_detail;

namespace {

// ---------------------------------------------------------------------------------------------
// Point form factors (no visibility: an upper estimate where something blocks).

/// Beyond this many patch radii from a planar patch, a receiver clearly in front of it (both
/// cosines above the patch's angular radius) takes the point form factor A cosθ cosθ′ / πr²
/// instead of the contour integral: there the two differ by O((radius / r)²), a few percent,
/// and the point form costs a fraction of the integral, which most receivers of a room would
/// otherwise pay for each of the strongest shooters.
constexpr double kExactWithinRadii = 4.0;

/// Unoccluded form factor from a differential area at x (unit normal n) to patch P: for a
/// planar patch Lambert's contour integral, clipped to the horizon (or the point form far
/// from it, above); for a curved one George et al.'s point estimate
/// A' cosθ / (πr² + A), the receiver's cosine taking the patch's extent as slack (a patch
/// partly above the horizon still sends light). A' is the area the patch shows the receiver,
/// ∫ max(0, n·ω) dA = (∫ |n·ω| dA + A N̄·ω) / 2 ≤ A (1 + N̄·ω) / 2, with N̄ = ∫ n dA / A its
/// mean normal (`meanNormal`, shorter than unit where the patch curves) and ω the direction
/// to the receiver: a whole sphere shows at most half its area, a flat patch facing the
/// receiver all of it.
double pointFormFactor(const Vec3& x, const Vec3& n, const Patch& P, const Vec3& meanNormal) {
    const Vec3 d = P.centroid - x;
    const double r2 = glm::dot(d, d);
    if (!P.outline.empty()) {
        if (r2 > kExactWithinRadii * kExactWithinRadii * P.radius * P.radius) {
            const double r = std::sqrt(r2), slack = P.radius / r;
            const double cosi = glm::dot(n, d) / r, cosj = -glm::dot(P.normal, d) / r;
            if (cosi >= slack && cosj >= slack) return P.area * cosi * cosj / (M_PI * r2);
        }
        return polygonFormFactor(x, n, P.outline);
    }
    if (!(r2 > 0)) return 0;
    const double r = std::sqrt(r2), slack = P.radius / r;
    const double cosi = std::clamp(glm::dot(n, d) / r + slack, 0.0, 1.0);
    const double shown = std::clamp(0.5 * (1.0 - glm::dot(meanNormal, d) / r), 0.0, 1.0);
    return P.area * shown * cosi / (M_PI * r2 + P.area);
}

/// Form factor from a differential area at x (unit normal n) to a sphere (c, rs): sin²α cosθ
/// for a sphere wholly above the horizon, α its angular radius; the horizon's cut is taken
/// as slack (cosθ + sinα, clamped), and a receiver inside the sphere sees it whole.
double sphereFormFactor(const Vec3& x, const Vec3& n, const Vec3& c, double rs) {
    const Vec3 d = c - x;
    const double d2 = glm::dot(d, d);
    if (d2 <= rs * rs) return 1.0;
    const double dist = std::sqrt(d2), sinA = rs / dist;
    const double cosT = std::clamp(glm::dot(n, d) / dist + sinA, 0.0, 1.0);
    return std::min(1.0, sinA * sinA * cosT);
}

/// Whether the sphere (c, r) can meet a segment from x to a point within pr of p (the shaft
/// test of redistribution.cpp's sphereMeetsCone, repeated: it is local there).
bool sphereNearSegment(const Vec3& x, const Vec3& p, double pr, const Vec3& c, double r) {
    const Vec3 d = p - x;
    const double l2 = glm::dot(d, d);
    if (l2 <= pr * pr) return true;
    const Vec3 w = x - c;
    const double k = glm::dot(w, d);
    const double t0 = -k / l2;
    const double q2 = std::max(0.0, glm::dot(w, w) - k * k / l2);
    const double reach = r + std::max(pr, 0.0);
    if (reach < 0 || q2 >= reach * reach) return false;
    const double s = pr * std::sqrt(q2) / (std::sqrt(l2) * std::sqrt(l2 - pr * pr));
    const double t = std::clamp(t0 + s, 0.0, 1.0);
    return std::sqrt(l2 * (t - t0) * (t - t0) + q2) - pr * t < r;
}

Rgb absRgb(const Rgb& c) { return Rgb(std::abs(c.x), std::abs(c.y), std::abs(c.z)); }

/// Shooters weighed one by one: the strongest kExplicit of each kind; the rest are spread.
constexpr std::size_t kExplicitUnshot = 16;
constexpr std::size_t kExplicitPending = 8;

/// One pending edit as the estimate sees it.
struct PendingEdit {
    const ChangeEntry* entry = nullptr;
    std::vector<int> top;  ///< its strongest pending shooters (not on removed objects)
    /// Irradiance (W/m², per channel) a surface of the changed objects gets from the other
    /// pending shooters on average over its orientations: what the objects block or, added,
    /// receive from them.
    Rgb restFacing{0.0};
    /// The same, from the pending shooters that have not yet reached the added objects (by
    /// the gather or a shot ahead: ChangeEntry::reachedAdded).
    Rgb restFacingUngathered{0.0};
    /// Per channel, what a receiver sees in a changed object's direction (within the solid
    /// angle of its bounding sphere, ChangeEntry::spheres): an added object blocks the light
    /// behind it (about restFacing: a loss) and shows its own radiosity once lit
    /// (`addedRadiosity`: a gain); where a removed object was, the light behind shows again
    /// (a gain) instead of its radiosity (`removedRadiosity`: a loss).
    Rgb addedRadiosity{0.0}, removedRadiosity{0.0};
    /// Per sphere of the entry: the object was added (1) or removed (2).
    std::vector<char> sphereKind;
    /// The sign of what the changed objects' shadows do to the light of a strong shooter: an
    /// addition only takes light away (+1 loss), a removal only gives it back (gain), a move
    /// either (0).
    int shadowSign = 0;
    /// The edit removes an emitter (and adds none): the light it had sent is taken back with
    /// no gain to cancel it, so its reflections are lost too (the interreflection term).
    bool removesEmitter = false;
};

PendingEdit describePending(const ChangeEntry& c, const Discretization& disc) {
    PendingEdit p;
    p.entry = &c;
    const auto& patches = disc.patches();
    std::vector<char> changed(disc.objects().size(), 0);
    for (int o : c.added) changed[o] = 1;
    for (int o : c.removed) changed[o] = 2;
    double changedArea = 0;
    Rgb addedRho(0.0), removedShot(0.0);
    bool removesEmitter = false, addsEmitter = false;
    for (std::size_t j = 0; j < patches.size(); ++j) {
        const char kind = changed[patches[j].object];
        if (!kind) continue;
        changedArea += patches[j].area;
        if (luminance(disc.patchMaterial(static_cast<int>(j)).emission) > 0)
            (kind == 2 ? removesEmitter : addsEmitter) = true;
        if (kind == 1)
            addedRho = glm::max(addedRho, disc.patchMaterial(static_cast<int>(j)).reflectance);
    }
    // Facing irradiance of each pending shooter: its importance is S_j · F̄ · (area / 4).
    std::vector<std::pair<double, int>> ranked;
    Rgb facing(0.0);
    std::vector<Rgb> facingOf(patches.size(), Rgb(0.0));
    for (std::size_t j = 0; j < c.shot.size(); ++j) {
        const double key = c.pending.key(static_cast<int>(j));
        if (!(key > 1e-250)) continue;
        if (changed[patches[j].object] == 2) {
            removedShot = glm::max(removedShot, absRgb(c.shot[j]));
            continue;
        }
        const double sum = energyKey(c.shot[j], 1.0);
        if (!(sum > 0) || !(changedArea > 0)) continue;
        // Σ_j F̄_j over every direction is about 4 (the sphere's solid angle over π), so a
        // surface oriented one way gets about a quarter of the sum: what restFacing holds.
        facingOf[j] = absRgb(c.shot[j]) * (key / (sum * changedArea));
        facing += facingOf[j];
        ranked.push_back({key, static_cast<int>(j)});
    }
    const std::size_t n = std::min(kExplicitPending, ranked.size());
    std::partial_sort(ranked.begin(), ranked.begin() + n, ranked.end(),
                      [](const auto& a, const auto& b) {
                          return a.first != b.first ? a.first > b.first : a.second < b.second;
                      });
    std::vector<char> isTop(patches.size(), 0);
    for (std::size_t k = 0; k < n; ++k)
        p.top.push_back(ranked[k].second), isTop[ranked[k].second] = 1;
    for (const auto& [key, j] : ranked) {
        if (isTop[j]) continue;
        p.restFacing += facingOf[j];
        if (!c.reachedAdded(j)) p.restFacingUngathered += facingOf[j];
    }
    // In the changed objects' direction a receiver sees, instead of the light they block
    // (about restFacing), their own radiosity (ρ times their mean irradiance), or, where an
    // object was removed, what was behind it instead of the removed object's radiosity: the
    // change, a difference of two of these, is at most the largest.
    p.addedRadiosity = addedRho * facing;
    p.removedRadiosity = removedShot;
    p.shadowSign = c.removed.empty() ? 1 : c.added.empty() ? -1 : 0;
    // The spheres, as makeChangeEntry lists them: per changed object in ascending order, those
    // with vertices.
    for (std::size_t o = 0; o < changed.size(); ++o)
        if (changed[o] && !disc.objects()[o].worldPositions.empty())
            p.sphereKind.push_back(changed[o]);
    if (p.sphereKind.size() != c.spheres.size()) p.sphereKind.assign(c.spheres.size(), 0);
    // A moved emitter's new place is lit by its unshot emission: gain and loss cancel there.
    p.removesEmitter = removesEmitter && !addsEmitter;
    return p;
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// The estimate.

SettlingEstimate ProgressiveSolver::computeSettling() const {
    // Every alive element, standing for itself.
    const std::vector<int> receivers = mDisc.aliveElements();
    return estimateSettling(receivers, std::vector<double>(receivers.size(), 1.0), true);
}

SettlingEstimate ProgressiveSolver::computeSettlingSummary() const {
    // Per object, one alive element in kSettlingSummaryStride (at least one), evenly spaced
    // over its faces (neighbours in the mesh), weighted so that the sample's area is the
    // object's.
    std::vector<int> receivers = mDisc.aliveElements(), alive;
    if (receivers.size() <= kSettlingSummaryFullBelow)
        return estimateSettling(receivers, std::vector<double>(receivers.size(), 1.0), false);
    receivers.clear();
    std::vector<double> weights;
    const auto& elements = mDisc.elements();
    for (const ObjectSurface& object : mDisc.objects()) {
        alive.clear();
        double area = 0;
        for (int e : object.faceElement)
            if (e >= 0 && mDisc.elementAlive(e)) alive.push_back(e), area += elements[e].area;
        if (alive.empty()) continue;
        const std::size_t n = alive.size();
        const std::size_t m = (n + kSettlingSummaryStride - 1) / kSettlingSummaryStride;
        double sampled = 0;
        for (std::size_t k = 0; k < m; ++k) {
            const int e = alive[(2 * k + 1) * n / (2 * m)];
            receivers.push_back(e);
            sampled += elements[e].area;
        }
        const double w = sampled > 0 ? area / sampled : 0.0;
        weights.resize(receivers.size(), w);
    }
    return estimateSettling(receivers, weights, false);
}

SettlingEstimate ProgressiveSolver::estimateSettling(const std::vector<int>& receivers,
                                                     const std::vector<double>& weights,
                                                     bool perElement) const {
    const auto& elements = mDisc.elements();
    const auto& patches = mDisc.patches();
    const std::size_t ne = elements.size();
    SettlingEstimate out;
    if (perElement) {
        out.change.assign(ne, 0.0);
        out.noise.assign(ne, 0.0);
        out.referenceNoise.assign(ne, 0.0);
    }
    if (mElementB.size() != ne) return out;
    const std::size_t nr = receivers.size();

    // Unshot energy: the strongest shooters one by one, the rest per object (below).
    std::vector<std::pair<double, int>> unshot;
    double totalArea = 0;
    Rgb rhoArea(0.0), emittedPower(0.0);
    for (std::size_t j = 0; j < patches.size(); ++j) {
        if (!mDisc.patchAlive(static_cast<int>(j))) continue;
        const Material& m = mDisc.patchMaterial(static_cast<int>(j));
        totalArea += patches[j].area;
        rhoArea += m.reflectance * patches[j].area;
        emittedPower += m.emission * patches[j].area;
        const double key = energyKey(mPatchUnshot[j], patches[j].area);
        if (key > 0) unshot.push_back({key, static_cast<int>(j)});
    }
    if (!(totalArea > 0)) return out;
    const std::size_t nTop = std::min(kExplicitUnshot, unshot.size());
    std::partial_sort(unshot.begin(), unshot.begin() + nTop, unshot.end(),
                      [](const auto& a, const auto& b) {
                          return a.first != b.first ? a.first > b.first : a.second < b.second;
                      });
    // The rest, per object: a diffuse source of its patches' power at their power-weighted
    // centre, its intensity at most Φ/π (a flat source, seen face on).
    std::vector<int> topUnshot;
    struct Source {
        Rgb powerPos{0.0}, powerNeg{0.0};  ///< of its positive and of its negative unshot energy
        Vec3 centre{0.0};
        double weight = 0, radius2 = 0;
    };
    std::vector<Source> sources(mDisc.objects().size());
    for (std::size_t k = 0; k < unshot.size(); ++k) {
        const int j = unshot[k].second;
        if (k < nTop) {
            topUnshot.push_back(j);
            continue;
        }
        Source& s = sources[patches[j].object];
        s.powerPos += glm::max(mPatchUnshot[j], Rgb(0.0)) * patches[j].area;
        s.powerNeg += glm::max(-mPatchUnshot[j], Rgb(0.0)) * patches[j].area;
        s.centre += unshot[k].first * patches[j].centroid;
        s.weight += unshot[k].first;
    }
    std::vector<Source> restSources;
    for (std::size_t o = 0; o < sources.size(); ++o) {
        Source s = sources[o];
        if (!(s.weight > 0)) continue;
        s.centre /= s.weight;
        for (const Vec3& w : mDisc.objects()[o].worldPositions)
            s.radius2 = std::max(s.radius2, glm::dot(w - s.centre, w - s.centre));
        restSources.push_back(s);
    }

    std::vector<PendingEdit> pending;
    for (const ChangeEntry& c : mImpl->changes) pending.push_back(describePending(c, mDisc));

    // Each curved patch's mean normal Σ n A / ΣA (pointFormFactor: the area it shows).
    std::vector<Vec3> meanNormal(patches.size(), Vec3(0.0));
    for (std::size_t j = 0; j < patches.size(); ++j) {
        if (!patches[j].outline.empty() || !(patches[j].area > 0)) continue;
        for (int e : patches[j].elements) meanNormal[j] += elements[e].area * elements[e].normal;
        meanNormal[j] /= patches[j].area;
    }

    // A strong shooter's shadow: rays from the receiver to points of the patch (the outline's
    // corners pulled toward the centre, or a few of its elements' centroids) traced against
    // the changed objects alone; the fraction they block.
    std::vector<Visibility> changedOnly;
    for (const PendingEdit& p : pending) changedOnly.push_back(p.entry->changed.visibility());
    const double lift = 4 * mTracer.epsilon();
    auto blockedFraction = [&](const Vec3& x, int j, const Visibility& only) {
        const Patch& P = patches[j];
        Vec3 to[9];
        int count = 0;
        to[count++] = P.centroid;
        if (!P.outline.empty()) {
            for (std::size_t k = 0; k < P.outline.size() && count < 9; ++k)
                to[count++] = P.centroid + 0.9 * (P.outline[k] - P.centroid);
        } else {
            const std::size_t m = P.elements.size(), stride = std::max<std::size_t>(1, m / 8);
            for (std::size_t k = 0; k < m && count < 9; k += stride)
                to[count++] = elements[P.elements[k]].centroid;
        }
        bool blocked[9];
        mTracer.occludedPacket(x, to, count, blocked, only);
        int hits = 0;
        for (int k = 0; k < count; ++k) hits += blocked[k] ? 1 : 0;
        return static_cast<double>(hits) / count;
    };

    // First order: the irradiance each element may still gain or lose directly from the
    // pending work, per channel.
    // unshotFirst: the unshot energy's part of `first`; lostFirst: the part of edits that
    // remove emitters. Both are reflected again (the interreflection term below).
    std::vector<Rgb> first(nr, Rgb(0.0)), unshotFirst(nr, Rgb(0.0)), lostFirst(nr, Rgb(0.0));
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, nr, 512), [&](const auto& range) {
        for (std::size_t r = range.begin(); r != range.end(); ++r) {
            const Element& el = elements[receivers[r]];
            const Vec3& x = mDisc.receiver(receivers[r]);
            const Vec3& n = el.normal;
            // The positive and the negative unshot energy's irradiance apart: the change is at
            // most the larger of the two (a gain and a loss at the same receiver cancel).
            Rgb hPos(0.0), hNeg(0.0);
            for (int j : topUnshot)
                if (j != el.patch) {
                    const double f = pointFormFactor(x, n, patches[j], meanNormal[j]);
                    hPos += glm::max(mPatchUnshot[j], Rgb(0.0)) * f;
                    hNeg += glm::max(-mPatchUnshot[j], Rgb(0.0)) * f;
                }
            for (const Source& s : restSources) {
                // E = Φ cosθ / (π (d² + r²)), the source's extent r softening it up close.
                const Vec3 d = s.centre - x;
                const double d2 = glm::dot(d, d) + s.radius2;
                const double cosi = std::clamp(
                    glm::dot(n, d) / std::sqrt(d2) + std::sqrt(s.radius2 / d2), 0.0, 1.0);
                hPos += s.powerPos * (cosi / (M_PI * d2));
                hNeg += s.powerNeg * (cosi / (M_PI * d2));
            }
            unshotFirst[r] = glm::max(hPos, hNeg);
            // What the pending edits add, as gains and losses where their sign is known (an
            // addition takes light away in its shadows and gives its own reflected light; a
            // removal the reverse; light still to come to an added receiver is a gain), and
            // as `either` where it is not (a move). A gain and a loss at the same receiver
            // cancel, so the change is at most the larger of the two, plus `either`.
            Rgb gain = hPos, loss = hNeg, either(0.0);
            for (const PendingEdit& p : pending) {
                const ChangeEntry& c = *p.entry;
                const bool addedHere =
                    static_cast<std::size_t>(el.object) < c.before.size() && !c.before[el.object];
                if (addedHere) {
                    // A receiver the edit added: all it gets from the pending shooters.
                    gain += p.restFacingUngathered;
                    for (int j : p.top)
                        if (!c.reachedAdded(j))
                            gain += absRgb(c.shot[j]) *
                                    pointFormFactor(x, n, patches[j], meanNormal[j]);
                    continue;
                }
                // Elsewhere: what the changed objects block, reflect or no longer reflect,
                // within the solid angle they subtend; a strong shooter only where they may
                // cut its shaft to the receiver.
                const Rgb lossBefore = loss + either;
                Rgb& shadow = p.shadowSign > 0 ? loss : p.shadowSign < 0 ? gain : either;
                for (std::size_t k = 0; k < c.spheres.size(); ++k) {
                    const auto& [centre, radius] = c.spheres[k];
                    const double fs = sphereFormFactor(x, n, centre, radius);
                    if (!(fs > 0)) continue;
                    if (p.sphereKind[k] == 1) {
                        gain += p.addedRadiosity * fs, loss += p.restFacing * fs;
                    } else if (p.sphereKind[k] == 2) {
                        gain += p.restFacing * fs, loss += p.removedRadiosity * fs;
                    } else {
                        either +=
                            glm::max(glm::max(p.restFacing, p.addedRadiosity), p.removedRadiosity) *
                            fs;
                    }
                    for (int j : p.top) {
                        const Patch& P = patches[j];
                        if (!sphereNearSegment(x, P.centroid, P.radius, centre, radius)) continue;
                        const double blocked =
                            blockedFraction(x + n * lift, j, changedOnly[&p - pending.data()]);
                        if (blocked > 0)
                            shadow += absRgb(c.shot[j]) * pointFormFactor(x, n, P, meanNormal[j]) *
                                      blocked;
                    }
                }
                if (p.removesEmitter) lostFirst[r] += loss + either - lossBefore;
            }
            first[r] = glm::max(gain, loss) + either;
        }
    });

    // Interreflection: the first-order change, reflected, is unshot energy again; Cohen's
    // ambient term spreads it, R = 1 / (1 − ρ̄) per channel for the geometric series. The
    // unshot energy's, and that of edits removing an emitter (a pure loss); not the other
    // edits': a redistribution's gains (on the changed objects) and losses (in their shadows)
    // are about equal, so their reflections cancel but for the reflectances' contrast, and the
    // changed objects' solid-angle term already covers what sees them.
    Rgb reflectedPower(0.0);
    for (std::size_t r = 0; r < nr; ++r) {
        const int i = receivers[r];
        reflectedPower += mDisc.elementMaterial(i).reflectance * (unshotFirst[r] + lostFirst[r]) *
                          (elements[i].area * weights[r]);
    }
    const Rgb rhoMean = rhoArea / totalArea;
    const Rgb series = Rgb(1.0) / glm::max(Rgb(1.0) - rhoMean, Rgb(1e-3));
    const Rgb interreflected = reflectedPower / totalArea * series;
    out.interreflected = interreflected;

    // The stochastic tail's sampling noise: a ray carries the emitted power over
    // raysPerEmittedPower, so an element's tail radiosity T, built of hits worth ρΦ/A, has
    // variance ρ(Φ/A)·T; T is at most its indirect radiosity ρ(H − H_emission). An element's
    // own indirect radiosity is one draw of that noise: where it drew few hits it would
    // understate its own variance, so T is also at least its patch's area-weighted mean (the
    // pooled hits of elements that face the same shooters).
    const bool stochastic = mOptions.stochasticBelow > 0 && mOptions.raysPerEmittedPower > 0;
    const Rgb rayPower = stochastic ? emittedPower / mOptions.raysPerEmittedPower : Rgb(0.0);
    auto indirectOf = [&](int e) {
        return glm::max(
            mDisc.elementMaterial(e).reflectance * (mElementH[e] - mElementHEmission[e]), Rgb(0.0));
    };
    std::vector<Rgb> patchIndirect;
    if (perElement && stochastic) {
        patchIndirect.assign(patches.size(), Rgb(0.0));
        for (std::size_t j = 0; j < patches.size(); ++j) {
            if (!mDisc.patchAlive(static_cast<int>(j))) continue;
            Rgb sum(0.0);
            for (int e : patches[j].elements) sum += indirectOf(e) * elements[e].area;
            patchIndirect[j] = sum / patches[j].area;
        }
    }

    double num = 0, den = 0, denReflected = 0;
    for (std::size_t r = 0; r < nr; ++r) {
        const int i = receivers[r];
        const Rgb& rho = mDisc.elementMaterial(i).reflectance;
        const double area = elements[i].area * weights[r];
        const double change = luminance(rho * (first[r] + interreflected));
        if (perElement) {
            out.change[i] = change;
            // The solution's own noise: per channel σ = √variance of the irradiance, times ρ;
            // the channels' noise comes from the same rays, so their σ add.
            const Rgb& variance = mImpl->irradianceVariance[i];
            const double held = luminance(
                rho * Rgb(std::sqrt(variance.x), std::sqrt(variance.y), std::sqrt(variance.z)));
            if (stochastic) {
                const Rgb tail = glm::max(indirectOf(i), patchIndirect[elements[i].patch]);
                out.referenceNoise[i] =
                    std::sqrt(luminance(rho * rayPower / elements[i].area) * luminance(tail));
            }
            // The solution went through the same kind of tail as the reference: its noise is
            // at least the modelled one, even where its hits (`held`) happened to be few.
            out.noise[i] = std::max(held, out.referenceNoise[i]);
        }
        const double y = luminance(mElementB[i]);
        const double reflected = luminance(mElementB[i] - mDisc.elementMaterial(i).emission);
        num += change * change * area;
        den += y * y * area;
        denReflected += reflected * reflected * area;
    }
    out.relativeRms = den > 0 ? std::sqrt(num / den) : 0.0;
    out.reflectedRms = denReflected > 0 ? std::sqrt(num / denReflected) : 0.0;
    return out;
}

}  // namespace penumbra
