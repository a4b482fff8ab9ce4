// Edits (George, Sillion, Greenberg 1990): the change log and its redistribution shots.
// Propagation is in progressive_solver.cpp, the drag preview in drag_preview.cpp.
//
// Index: edits (change entries, apply, material changes) · redistribution shots
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "solver/form_factor.h"
#include "solver/progressive_solver.h"
#include "solver/progressive_solver_internal.h"

namespace penumbra {

using namespace solver_detail;

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
    // g(t) ≥ √q2 − max(pr, 0): far enough from the line, no square root needed.
    const double reach = r + std::max(pr, 0.0);
    if (reach < 0 || q2 >= reach * reach) return false;
    const double s = pr * std::sqrt(q2) / (std::sqrt(l2) * std::sqrt(l2 - pr * pr));
    const double t = std::clamp(t0 + s, 0.0, 1.0);
    return std::sqrt(l2 * (t - t0) * (t - t0) + q2) - pr * t < r;
}

/// The mean of a polygon's vertices: a point inside a convex polygon.
Vec3 polygonMean(const std::vector<Vec3>& poly) {
    Vec3 inside(0.0);
    for (const Vec3& v : poly) inside += v;
    return inside / static_cast<double>(poly.size());
}

/// Whether the sphere (c, r) can meet a segment from x to a point of the convex polygon `poly`
/// (front side toward unit `pn`): it is not wholly beyond the polygon's plane, seen from x, nor
/// wholly outside one of the planes through x and an edge. (Spheres near the pyramid's edges
/// may pass without meeting it; none that meets it fails.)
/// `inside` is the mean of the polygon's vertices (polygonMean).
bool sphereMeetsPyramid(const Vec3& x, const std::vector<Vec3>& poly, const Vec3& pn,
                        const Vec3& inside, const Vec3& c, double r) {
    const double hx = glm::dot(x - poly[0], pn), hc = glm::dot(c - poly[0], pn);
    if ((hx > 0 && hc < -r) || (hx < 0 && hc > r)) return false;
    const Vec3 toInside = inside - x, toCentre = c - x;
    for (std::size_t i = 0; i < poly.size(); ++i) {
        const Vec3 m = glm::cross(poly[i] - x, poly[i + 1 < poly.size() ? i + 1 : 0] - x);
        const double side = glm::dot(toInside, m);
        if (side == 0) continue;  // x in the polygon's plane: no side plane here
        const double d = side > 0 ? glm::dot(toCentre, m) : -glm::dot(toCentre, m);
        if (d < 0 && d < -r * glm::length(m)) return false;  // r ≥ 0: only d < 0 can fail
    }
    return true;
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
    // Per patch in parallel (each writes its own slots); the heap and the sum in patch order.
    std::vector<char> added(nObjects, 0);
    for (int o : entry.added) added[o] = 1;
    std::vector<double> importance(patches.size(), 0.0);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, patches.size(), 256), [&](const auto& r) {
        for (std::size_t j = r.begin(); j != r.end(); ++j) {
            const Patch& P = patches[j];
            if (!entry.before[P.object] || added[P.object]) continue;
            Rgb shot = patchRadiosity(static_cast<int>(j)) - mPatchUnshot[j];
            if (isZero(shot)) continue;
            entry.shot[j] = shot;
            entry.shotEmissionShare[j] = shareOf(
                mDisc.patchMaterial(static_cast<int>(j)).emission - mPatchUnshotEmission[j], shot);
            if (changed[P.object]) {
                importance[j] = energyKey(shot, P.area);  // a removed shooter: all it shot is
                continue;                                 // cancelled
            }
            double f = 0;
            for (const Vec3& sp : samples) {
                const Vec3 d = sp - P.centroid;
                const double r2 = glm::dot(d, d), facing = glm::dot(P.normal, d);
                if (!(facing > 0) || !(r2 > 0)) continue;  // behind the patch: cos ≤ 0
                const double cosj = facing / std::sqrt(r2);
                if (cosj > 0) f += P.area * cosj / (M_PI * r2 + P.area);
            }
            f /= static_cast<double>(samples.size());
            // Power reaching the objects: radiosity × F × (about a quarter of their area
            // faces any one direction); at least a tiny amount so every shooter is visited.
            importance[j] = std::max(energyKey(shot, 1.0) * f * changedArea / 4, 1e-300);
        }
    });
    for (std::size_t j = 0; j < patches.size(); ++j) {
        if (!(importance[j] > 0)) continue;
        entry.pending.update(static_cast<int>(j), importance[j]);
        entry.totalPending += importance[j];
        // An addition's emitters light the added objects first (dueAddedFirst).
        if (!entry.added.empty() && !changed[patches[j].object] &&
            mDisc.patchMaterial(static_cast<int>(j)).isEmitter())
            entry.addedFirst.push_back(static_cast<int>(j));
    }
    std::stable_sort(entry.addedFirst.begin(), entry.addedFirst.end(),
                     [&](int a, int b) { return importance[a] > importance[b]; });
    if (entry.addedFirst.size() > ChangeEntry::kAddedFirst)
        entry.addedFirst.resize(ChangeEntry::kAddedFirst);
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
            for (int e : patches[j].elements) {
                mElementB[e] = mElementH[e] = mElementHEmission[e] = Rgb(0.0);
                mImpl->irradianceVariance[e] = Rgb(0.0);
            }
            mPatchUnshot[j] = mPatchUnshotEmission[j] = Rgb(0.0);
            updatePriority(static_cast<int>(j));
        }
    // Added objects start with their emission unshot (Cohen's initialization).
    for (int o : change.added)
        for (std::size_t j = 0; j < patches.size(); ++j) {
            if (patches[j].object != o) continue;
            const Rgb& e = mDisc.patchMaterial(static_cast<int>(j)).emission;
            for (int el : patches[j].elements) {
                mElementB[el] = e, mElementH[el] = mElementHEmission[el] = Rgb(0.0);
                mImpl->irradianceVariance[el] = Rgb(0.0);
            }
            mPatchUnshot[j] = mPatchUnshotEmission[j] = e;
            updatePriority(static_cast<int>(j));
        }
    recomputeEmitted();
    if (redistribute && entry.totalPending > 0) {
        buildWorldScenes(entry);
        mImpl->changes.push_back(std::move(entry));
    }
}

void ProgressiveSolver::apply(const EditEvent& event) {
    using Kind = EditEvent::Kind;
    switch (event.kind) {
        case Kind::Solved:
            return;
        case Kind::Changed: {
            const int preview = previewObject();  // applyChange ends it
            if (!event.materialChanged.empty()) {
                if (!event.newMaterial)
                    throw std::invalid_argument("ProgressiveSolver::apply: " + event.toString() +
                                                " has no new material");
                for (int object : event.materialChanged) changeMaterial(object, *event.newMaterial);
            }
            if (!event.added.empty() || !event.removed.empty())
                applyChange({event.removed, event.added});
            // The preview was computed in the scene as it was: start it again.
            if (preview >= 0) setPreview(preview);
            return;
        }
        case Kind::DragBegan:
            // George et al.: "when the user selects an object for change, the object is
            // removed from the radiosity solution"; the preview shows it where it is.
            forgetPreviewShadow();
            applyChange({{event.origin}, {}});
            setPreview(event.origin);
            return;
        case Kind::PreviewMoved:
            setPreview(event.preview);
            return;
        case Kind::DragEnded:
            // "When the object is unselected, it is added back into the environment."
            clearPreview();
            forgetPreviewShadow();
            applyChange({{}, event.added});
            return;
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
        const double key = mImpl->changes[k].bestPending();
        if (key <= 0) continue;
        if (key > best) {
            best = key;
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

std::vector<int> ProgressiveSolver::dueAddedFirst(const ChangeEntry& c) const {
    std::vector<int> due;
    for (int j : c.addedFirst) {
        const double key = c.pending.key(j);
        // Not shot in full already, nor weak enough for the stochastic tail's rays.
        if (key > 0 && !c.reachedAdded(j) &&
            !(mOptions.stochasticBelow > 0 && key < mOptions.stochasticBelow * mEmittedEnergy))
            due.push_back(j);
    }
    return due;
}

void ProgressiveSolver::redistributionDelta(const ChangeEntry& c, int j, bool preview,
                                            std::vector<Rgb>& delta, bool addedOnly) const {
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
    const ChangedObjectsIn where = c.removed.empty() ? ChangedObjectsIn::After
                                   : c.added.empty() ? ChangedObjectsIn::Before
                                                     : ChangedObjectsIn::Either;
    const double margin = 4 * mTracer.epsilon();
    const bool reachedAdded = c.reachedAdded(j);

    // Haines–Wallace style shaft: which changed objects (bits of `mask`, those past the 64th
    // sharing the last) can meet a segment from a receiver within the ball (x, a) to the
    // shooter patch? Segments from B(x, a) to B(p, b) lie in the union of the balls
    // B(x + t(p − x), a + t(b − a)), so the test for the ball is the point test with the patch
    // radius b − a and each sphere widened by a (and the margin again, so the ball's test
    // passes wherever one of its receivers' tests would). A ball inside another passes only
    // for spheres the outer one passes for, so the tests narrow the mask going down.
    auto bitOf = [](std::size_t k) { return std::uint64_t(1) << std::min<std::size_t>(k, 63); };
    auto shaftMask = [&](const Vec3& x, double a, std::uint64_t mask) {
        if (a > 0) a += margin;
        std::uint64_t out = 0;
        for (std::size_t k = 0; k < c.spheres.size(); ++k) {
            const std::uint64_t bit = bitOf(k);
            if (!(mask & bit) || (out & bit)) continue;
            const auto& [centre, radius] = c.spheres[k];
            if (sphereMeetsCone(x, P.centroid, P.radius + margin - a, centre, radius + margin + a))
                out |= bit;
        }
        return out;
    };
    // A planar shooter's segments from x end on its outline: the pyramid with apex x over
    // the outline holds them, tighter than the cone to the patch's bounding ball. Segments
    // from a point of B(x, a) lie within a of those from x (at the same parameter), so the
    // test for the ball is the one for x with each sphere widened by a. Returns the changed
    // objects of `mask` that pass.
    const bool planar = P.outline.size() >= 3;
    const Vec3 outlineMean = planar ? polygonMean(P.outline) : Vec3(0.0);
    auto pyramidMask = [&](const Vec3& x, double a, std::uint64_t mask) {
        if (!planar) return mask;
        if (a > 0) a += margin;
        std::uint64_t out = 0;
        for (std::size_t k = 0; k < c.spheres.size(); ++k) {
            const std::uint64_t bit = bitOf(k);
            if (!(mask & bit) || (out & bit)) continue;
            if (sphereMeetsPyramid(x, P.outline, P.normal, outlineMean, c.spheres[k].first,
                                   c.spheres[k].second + margin + a))
                out |= bit;
        }
        return out;
    };
    // Both tests: the changed objects whose spheres may meet a segment from B(x, a).
    auto shaftAndPyramidMask = [&](const Vec3& x, double a, std::uint64_t mask) {
        const std::uint64_t m = shaftMask(x, a, mask);
        return m ? pyramidMask(x, a, m) : m;
    };
    constexpr std::uint64_t kAll = ~std::uint64_t(0);
    mImpl->receiverBounds.update(mDisc);
    const ReceiverBounds& bounds = mImpl->receiverBounds;

    // The work: subtrees of the receivers' trees, each with the changed objects its receivers
    // may meet (0: every element of every patch receives: added receivers, or the
    // cancellation of a removed shooter). Large subtrees are opened here, so the parallel
    // walk below has pieces of a few dozen patches.
    constexpr int kWorkPatches = 64;
    const auto& objects = mDisc.objects();
    auto& work = mImpl->shaftWork;
    work.clear();
    std::vector<std::pair<int, std::uint64_t>>& stack = mImpl->shaftStack;
    for (std::size_t o = 0; o < objects.size() && o < c.after.size(); ++o) {
        if (!c.after[o] ||
            (!objects[o].alive && !(preview && static_cast<int>(o) == mImpl->previewObject)))
            continue;
        const int root = o < bounds.roots.size() ? bounds.roots[o] : -1;
        if (root < 0) continue;
        const bool receiverAdded = !c.before[o];
        if (addedOnly && (shooterRemoved || !receiverAdded)) continue;
        if (shooterRemoved || receiverAdded) {
            // Cancel what a removed patch shot: −F(t−1) (George et al.: "energy that was
            // distributed by patches on the dynamic object is canceled"). A shooter's light
            // on added receivers that came with gatherToAdded, or in a shot ahead, is not sent
            // again. Every element receives: the object's tree in pieces of a few patches, so
            // one large object (robot-room's head is 1,456 elements) is not one thread's work.
            if (shooterRemoved ? receiverAdded : reachedAdded) continue;
            stack.assign(1, {root, 0});
            while (!stack.empty()) {
                const int index = stack.back().first;
                stack.pop_back();
                const ReceiverBounds::Node& n = bounds.nodes[index];
                if (n.left < 0 || n.count <= ReceiverBounds::kLeafPatches) {
                    work.push_back({index, 0});
                    continue;
                }
                stack.push_back({n.right, 0});
                stack.push_back({n.left, 0});
            }
            continue;
        }
        stack.assign(1, {root, kAll});
        while (!stack.empty()) {
            const auto [index, inherited] = stack.back();
            stack.pop_back();
            const ReceiverBounds::Node& n = bounds.nodes[index];
            if (n.count <= kWorkPatches) {
                work.push_back({index, inherited});
                continue;
            }
            const std::uint64_t mask = shaftAndPyramidMask(n.ball.centre, n.ball.radius, inherited);
            if (!mask) continue;
            stack.push_back({n.right, mask});
            stack.push_back({n.left, mask});
        }
    }

    // Each piece in parallel: its subtree's balls, patches and elements (a patch's elements
    // belong to no other piece).
    delta.assign(mDisc.elements().size(), Rgb(0.0));
    auto receivePatch = [&](int q, std::uint64_t mask) {
        for (int e : mDisc.patches()[q].elements) {
            if (mask == 0) {
                delta[e] = shooterRemoved ? -irradianceFrom(j, e, shot, before)
                                          : irradianceFrom(j, e, shot, after);
                continue;
            }
            const Vec3& x = mDisc.receiver(e);
            if (shaftAndPyramidMask(x, 0, mask))
                delta[e] = irradianceChange(
                    j, q, {x, mDisc.elements()[e].normal, static_cast<std::uint64_t>(e)}, shot,
                    before, after, changed, where);
        }
    };
    tbb::parallel_for(std::size_t(0), work.size(), [&](std::size_t w) {
        const auto [root, rootMask] = work[w];
        if (rootMask == 0) {
            const ReceiverBounds::Node& n = bounds.nodes[root];
            for (int i = n.first; i < n.first + n.count; ++i) receivePatch(bounds.order[i], 0);
            return;
        }
        std::pair<int, std::uint64_t> local[64];
        int depth = 0;
        local[depth++] = {root, rootMask};
        while (depth > 0) {
            const auto [index, inherited] = local[--depth];
            const ReceiverBounds::Node& n = bounds.nodes[index];
            const std::uint64_t mask = shaftAndPyramidMask(n.ball.centre, n.ball.radius, inherited);
            if (!mask) continue;
            if (n.left >= 0) {
                local[depth++] = {n.right, mask};
                local[depth++] = {n.left, mask};
                continue;
            }
            for (int i = n.first; i < n.first + n.count; ++i) {
                const int q = bounds.order[i];
                const ReceiverBounds::Ball& b = bounds.patches[q];
                if (const std::uint64_t m = shaftAndPyramidMask(b.centre, b.radius, mask))
                    receivePatch(q, m);
            }
        }
    });
}

bool ProgressiveSolver::shouldGather(const ChangeEntry& c, double best) const {
    const double below = mOptions.gatherBelow > 0 ? mOptions.gatherBelow : mOptions.stochasticBelow;
    return mOptions.gatherRays > 0 && !c.added.empty() && c.gathered.empty() &&
           best < below * mEmittedEnergy;
}

bool ProgressiveSolver::shouldRefineGather(const ChangeEntry& c, double best) const {
    return c.refinementPending() && (best <= 0 || best < mOptions.stochasticBelow * mEmittedEnergy);
}

namespace {

/// The strata of a gather: nx × ny over (φ, sin²θ), grouped in blocks of `block` × `block`
/// (smaller along the far edges) for a coarse first pass.
struct GatherStrata {
    int nx = 1, ny = 1, block = 1;
    int bx = 1, by = 1;         ///< blocks along each direction
    std::vector<int> blockOf;   ///< per stratum: its block
    std::vector<double> share;  ///< per block: its share of the strata
    GatherStrata(int nx_, int ny_, int block_) : nx(nx_), ny(ny_), block(std::max(1, block_)) {
        bx = (nx + block - 1) / block;
        by = (ny + block - 1) / block;
        blockOf.resize(static_cast<std::size_t>(count()));
        share.assign(static_cast<std::size_t>(blocks()), 0.0);
        for (int k = 0; k < count(); ++k) {
            blockOf[k] = (k % nx) / block + bx * ((k / nx) / block);
            share[blockOf[k]] += 1.0 / count();
        }
    }
    int count() const { return nx * ny; }
    int blocks() const { return bx * by; }
    /// Per block, the stratum the first pass traces for element e: uniform over the block's.
    void choose(std::uint64_t seed, int e, int* chosen) const {
        const std::uint64_t h = hashPair(seed, static_cast<std::uint64_t>(e)) ^ 0xb10cull;
        for (int b = 0; b < blocks(); ++b) {
            const int x = b % bx, y = b / bx;
            const int w = std::min(nx, (x + 1) * block) - x * block;
            const int size = w * (std::min(ny, (y + 1) * block) - y * block);
            const int pick = static_cast<int>(hashPair(h, static_cast<std::uint64_t>(b)) %
                                              static_cast<std::uint64_t>(size));
            chosen[b] = (x * block + pick % w) + nx * (y * block + pick / w);
        }
    }
};

/// GatherRefinement::blockHit of a block the receiver did not trace in the first pass.
constexpr int kGatherNotTraced = -2;

/// The first pass of a coarse gather, per receiving patch: each block of strata is traced
/// once for the whole patch, from one of its receivers (that receiver's own ray of the one-pass
/// gather, so the second pass can keep it), and every receiver of the patch takes the patch's
/// estimate Σ_b share_b S(hit_b). The receivers that trace are drawn by area, systematically
/// (block b from the receiver at area fraction (π(b) + u) / blocks, π a random permutation and
/// u a random offset per patch), so the estimate is unbiased for the patch's area-weighted mean
/// and spread over it; a patch of many small elements (a sphere's, a mesh's) costs the rays of
/// one element, not of each. `trace(e, k, ru, rv)` returns the pending patch receiver e's ray
/// toward stratum k hits (-1 for none); `shot` is the entry's shot radiosity per patch. Fills
/// `refinement` (receivers, strata and seed already set), writes each receiver's estimate to
/// `delta` and returns the rays traced.
template <class Trace>
std::size_t traceFirstGatherPass(const std::vector<Element>& elements, const GatherStrata& strata,
                                 const std::vector<Rgb>& shot, const Trace& trace,
                                 ChangeEntry::GatherRefinement& refinement,
                                 std::vector<Rgb>& delta) {
    const auto& receivers = refinement.receivers;
    const int rays = strata.count(), blocks = strata.blocks();
    // The receivers grouped by patch, each group in receiver order.
    std::vector<int> byPatch(receivers.size());
    for (std::size_t i = 0; i < byPatch.size(); ++i) byPatch[i] = static_cast<int>(i);
    std::stable_sort(byPatch.begin(), byPatch.end(), [&](int a, int b) {
        return elements[receivers[a]].patch < elements[receivers[b]].patch;
    });
    std::vector<std::size_t> groupStart;
    for (std::size_t g = 0; g < byPatch.size(); ++g)
        if (g == 0 ||
            elements[receivers[byPatch[g]]].patch != elements[receivers[byPatch[g - 1]]].patch)
            groupStart.push_back(g);
    groupStart.push_back(byPatch.size());
    const std::size_t groups = groupStart.size() - 1;
    refinement.firstEstimate.assign(receivers.size(), Rgb(0.0));
    refinement.firstVariance.assign(receivers.size(), Rgb(0.0));
    refinement.blockHit.assign(receivers.size() * static_cast<std::size_t>(blocks),
                               kGatherNotTraced);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, groups, 4), [&](const auto& r) {
        thread_local std::vector<int> chosen, order, tracerOf;
        chosen.resize(static_cast<std::size_t>(blocks));
        order.resize(static_cast<std::size_t>(blocks));
        tracerOf.resize(static_cast<std::size_t>(blocks));
        for (std::size_t g = r.begin(); g != r.end(); ++g) {
            const std::size_t first = groupStart[g], m = groupStart[g + 1] - first;
            // Which receiver (its place q in the group) traces each block.
            const int patch = elements[receivers[byPatch[first]]].patch;
            RayRandom pick{
                hashPair(refinement.seed ^ 0x9a7c4ull, static_cast<std::uint64_t>(patch))};
            for (int b = 0; b < blocks; ++b) order[b] = b;
            for (int b = blocks - 1; b > 0; --b)
                std::swap(order[b], order[std::min(b, static_cast<int>(pick.next() * (b + 1)))]);
            double area = 0;
            for (std::size_t q = 0; q < m; ++q)
                area += elements[receivers[byPatch[first + q]]].area;
            const double u = pick.next();
            std::size_t q = 0;
            double below = 0;  // area of the receivers before q
            for (int p = 0; p < blocks; ++p) {
                const double at = (p + u) / blocks * area;
                while (q + 1 < m && below + elements[receivers[byPatch[first + q]]].area <= at)
                    below += elements[receivers[byPatch[first + q++]]].area;
                tracerOf[order[p]] = static_cast<int>(q);
            }
            Rgb estimate(0.0), variance(0.0);
            for (std::size_t t = 0; t < m; ++t) {
                if (std::find(tracerOf.begin(), tracerOf.end(), static_cast<int>(t)) ==
                    tracerOf.end())
                    continue;
                const int i = byPatch[first + t];
                const int e = receivers[i];
                RayRandom rng{hashPair(refinement.seed, static_cast<std::uint64_t>(e))};
                strata.choose(refinement.seed, e, chosen.data());
                int* hitOf = &refinement.blockHit[static_cast<std::size_t>(i) * blocks];
                // Every stratum draws its numbers, so the second pass meets the same ones.
                for (int k = 0; k < rays; ++k) {
                    const double ru = rng.next(), rv = rng.next();
                    const int b = strata.blockOf[k];
                    if (chosen[b] != k || tracerOf[b] != static_cast<int>(t)) continue;
                    const int j = trace(e, k, ru, rv);
                    hitOf[b] = j;
                    if (j >= 0) {
                        const Rgb sample = shot[j] * strata.share[b];
                        estimate += sample;
                        variance += sample * sample;
                    }
                }
            }
            for (std::size_t t = 0; t < m; ++t) {
                const int i = byPatch[first + t];
                refinement.firstEstimate[i] = delta[receivers[i]] = estimate;
                refinement.firstVariance[i] = variance;
            }
        }
    });
    return groups * static_cast<std::size_t>(blocks);
}

}  // namespace

void ProgressiveSolver::gatherToAdded(ChangeEntry& c, bool preview, std::vector<Rgb>& delta) {
    const auto& patches = mDisc.patches();
    const auto& elements = mDisc.elements();
    // The entry knows the patches that existed at its edit; later edits append more.
    const std::size_t np = c.shot.size();
    c.gathered.assign(np, 0);
    // Emitters keep their shots: a gather would see a small bright light with few rays.
    double gatheredImportance = 0;
    for (std::size_t j = 0; j < np; ++j)
        if (c.pending.key(static_cast<int>(j)) > 0 && !c.reachedAdded(static_cast<int>(j)) &&
            !mDisc.patchMaterial(static_cast<int>(j)).isEmitter()) {
            c.gathered[j] = 1;
            gatheredImportance += c.pending.key(static_cast<int>(j));
        }
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
        n = std::clamp(
            static_cast<int>(mOptions.gatherRayBudget / static_cast<double>(receivers.size())),
            std::min(n, std::max(1, mOptions.minGatherRays)), n);
    const int nx = static_cast<int>(std::ceil(std::sqrt(static_cast<double>(n))));
    const GatherStrata strata(nx, (n + nx - 1) / nx, mOptions.gatherCoarseBlock);
    const bool coarse = strata.blocks() < strata.count();
    const int rays = strata.count();
    const double eps = mTracer.epsilon();
    const std::uint64_t seed = hashPair(hashPair(mOptions.seed, 0x6a7e5ull), mStats.shots);
    // The pending patch whose shot radiosity receiver e's ray toward stratum k returns (its
    // numbers ru, rv within the stratum), -1 for none.
    auto trace = [&](int e, int k, double ru, double rv) {
        const Element& el = elements[e];
        Vec3 tx, ty;
        frameAround(el.normal, tx, ty);
        const RayTracer::FirstHit h = mTracer.firstHit(
            mDisc.receiver(e) + el.normal * eps,
            gatherDirection(k, strata.nx, strata.ny, ru, rv, tx, ty, el.normal), after);
        if (h.element < 0 || h.backFace) return -1;
        return h.patch == el.patch || !c.isGathered(h.patch) ? -1 : h.patch;
    };
    if (coarse) {
        ChangeEntry::GatherRefinement& refinement = c.refinement;
        refinement.receivers = receivers;
        refinement.nx = strata.nx;
        refinement.ny = strata.ny;
        refinement.seed = seed;
        const std::size_t traced =
            traceFirstGatherPass(elements, strata, c.shot, trace, refinement, delta);
        if (!preview)
            for (std::size_t i = 0; i < receivers.size(); ++i)
                mImpl->irradianceVariance[receivers[i]] += refinement.firstVariance[i];
        refinement.importance =
            gatheredImportance *
            (1 - static_cast<double>(traced) / (static_cast<double>(rays) * receivers.size()));
        return;
    }
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, receivers.size(), 16), [&](const auto& r) {
        for (std::size_t i = r.begin(); i != r.end(); ++i) {
            const int e = receivers[i];
            RayRandom rng{hashPair(seed, static_cast<std::uint64_t>(e))};
            Rgb sum(0.0), squares(0.0);
            for (int k = 0; k < rays; ++k) {
                const double ru = rng.next(), rv = rng.next();
                const int j = trace(e, k, ru, rv);
                if (j >= 0) sum += c.shot[j], squares += c.shot[j] * c.shot[j];
            }
            delta[e] = sum / static_cast<double>(rays);
            // The mean of `rays` samples: its variance is at most Σ x² / rays².
            if (!preview)
                mImpl->irradianceVariance[e] +=
                    squares / (static_cast<double>(rays) * static_cast<double>(rays));
        }
    });
}

void ProgressiveSolver::refineGather(ChangeEntry& c, bool preview, std::vector<Rgb>& delta) {
    const auto& elements = mDisc.elements();
    ChangeEntry::GatherRefinement& refinement = c.refinement;
    delta.assign(elements.size(), Rgb(0.0));
    Visibility after = c.afterWorld();
    if (afterIsCurrentScene(c, preview)) after = Visibility{};
    const GatherStrata strata(refinement.nx, refinement.ny, mOptions.gatherCoarseBlock);
    const int rays = strata.count(), blocks = strata.blocks();
    const double eps = mTracer.epsilon();
    const std::uint64_t seed = refinement.seed;
    const auto& receivers = refinement.receivers;
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, receivers.size(), 16), [&](const auto& r) {
        thread_local std::vector<int> chosen;
        chosen.resize(static_cast<std::size_t>(blocks));
        for (std::size_t i = r.begin(); i != r.end(); ++i) {
            const int e = receivers[i];
            const Element& el = elements[e];
            // Receivers removed since the first pass receive nothing more.
            if (!mDisc.objects()[el.object].alive &&
                !(preview && el.object == mImpl->previewObject))
                continue;
            // The same rays in the same order as the one-pass gather: strata the first pass
            // traced return what they returned then.
            RayRandom rng{hashPair(seed, static_cast<std::uint64_t>(e))};
            Vec3 tx, ty;
            frameAround(el.normal, tx, ty);
            const Vec3 origin = mDisc.receiver(e) + el.normal * eps;
            strata.choose(seed, e, chosen.data());
            const int* hitOf = &refinement.blockHit[i * static_cast<std::size_t>(blocks)];
            Rgb sum(0.0), squares(0.0);
            for (int k = 0; k < rays; ++k) {
                const double ru = rng.next(), rv = rng.next();
                const int b = strata.blockOf[k];
                int j = hitOf[b];
                if (chosen[b] != k || j == kGatherNotTraced) {
                    const RayTracer::FirstHit h = mTracer.firstHit(
                        origin, gatherDirection(k, strata.nx, strata.ny, ru, rv, tx, ty, el.normal),
                        after);
                    j = h.element < 0 || h.backFace || h.patch == el.patch || !c.isGathered(h.patch)
                            ? -1
                            : h.patch;
                }
                if (j >= 0) sum += c.shot[j], squares += c.shot[j] * c.shot[j];
            }
            delta[e] = sum / static_cast<double>(rays) - refinement.firstEstimate[i];
            // The whole gather's variance replaces the first pass's.
            if (!preview)
                mImpl->irradianceVariance[e] +=
                    squares / (static_cast<double>(rays) * static_cast<double>(rays)) -
                    refinement.firstVariance[i];
        }
    });
    refinement = ChangeEntry::GatherRefinement{};
}

bool ProgressiveSolver::shootRedistribution() {
    int k = -1;
    double best = bestRedistribution(&k);
    if (best <= 0 || k < 0) return false;
    ChangeEntry& c = mImpl->changes[k];
    const int top = c.pending.top();
    const double strongest = top >= 0 ? std::max(0.0, c.pending.key(top)) : 0.0;
    const bool gather = shouldGather(c, strongest);
    const bool refine = !gather && shouldRefineGather(c, strongest);
    if (!gather && !refine && mOptions.stochasticBelow > 0 &&
        best < mOptions.stochasticBelow * mEmittedEnergy) {
        shootRedistributionBatch(k);
        return true;
    }
    const unsigned long long raysBefore = mTracer.rayCount();
    auto& delta = mImpl->delta;
    // What delta holds, with its emission share.
    auto receiveDelta = [&](const Rgb& share) {
        for (std::size_t e = 0; e < delta.size(); ++e)
            if (!isZero(delta[e])) {
                receive(static_cast<int>(e), delta[e], share);
                touchElement(static_cast<int>(e));
            }
    };
    // The emitters' light on the added objects goes ahead of every full shot: with the
    // gather, so the added objects have all their light after one step, or in a shot of its
    // own.
    const std::vector<int> addedFirst = refine ? std::vector<int>{} : dueAddedFirst(c);
    if (gather) {
        // The added objects' elements gather what the weak shooters would send them: far
        // less noise than the same rays shot, and the edit's most changed elements. Gathered
        // shooters are not emitters: no emission share.
        gatherToAdded(c, false, delta);
        receiveDelta(Rgb(0.0));
    } else if (refine) {
        // The coarse gather's other strata: the added objects' light to its full precision.
        refineGather(c, false, delta);
        receiveDelta(Rgb(0.0));
    } else if (addedFirst.empty()) {
        const int j = c.pending.top();
        c.totalPending -= c.pending.key(j);
        c.pending.update(j, 0.0);
        redistributionDelta(c, j, false, delta);
        receiveDelta(c.shotEmissionShare[j]);
    }
    // Each emitter's shot to the added objects alone; the rest of it, its shadows, keeps its
    // place in the heap.
    if (!addedFirst.empty()) c.addedShot.resize(c.shot.size(), 0);
    for (int j : addedFirst) {
        redistributionDelta(c, j, false, delta, true);
        c.addedShot[j] = 1;
        receiveDelta(c.shotEmissionShare[j]);
    }
    updateTouchedPriorities();

    if (c.bestPending() <= 0) mImpl->changes.erase(mImpl->changes.begin() + k);
    mStats.rays += mTracer.rayCount() - raysBefore;
    // A gather's second pass completes the gather's shot: not a shot of its own, so the shot
    // counts (the seeds of later gathers and batches, what step and converge report) are
    // those of a one-pass gather.
    if (refine) {
        ++mImpl->gatherRefinements;
        return false;
    }
    ++mStats.shots;
    ++mStats.redistributionShots;
    return true;
}

namespace {

/// Takes entry c's most important pending shooters off its heap, as many as fit in one batch
/// of `maxBatchRays` rays at `raysPerWatt` (at least one); the rest stay pending for the next
/// batch, so the first corrections arrive quickly. Appends them and their cumulative power to
/// `shooters` and `cdf`; returns their total power (W).
double takeBatchShooters(ChangeEntry& c, double raysPerWatt, double maxBatchRays,
                         std::vector<int>& shooters, std::vector<double>& cdf) {
    double total = 0;
    while (c.pending.top() >= 0 && c.pending.key(c.pending.top()) > 0) {
        int j = c.pending.top();
        if (!shooters.empty() && (total + c.pending.key(j)) * raysPerWatt > maxBatchRays) break;
        shooters.push_back(j);
        cdf.push_back(total += c.pending.key(j));
        c.totalPending -= c.pending.key(j);
        c.pending.update(j, 0.0);
    }
    return total;
}

/// A redistribution ray's direction from `origin` on a shooter with frame (nz, tx, ty): into
/// the cones that the changed objects' bounding `spheres` subtend (one picked by solid angle;
/// the density counts every cone holding the direction), or the hemisphere when the point is
/// inside a sphere, there are more than eight, or the shooter was `removed`. `weight` is cos/π
/// over the sampling density (∫ cos/π dω per unit area). False for a direction below the
/// shooter's horizon: the ray carries nothing.
bool sampleRedistributionDirection(const std::vector<std::pair<Vec3, double>>& spheres,
                                   bool removed, const Vec3& origin, const Vec3& nz, const Vec3& tx,
                                   const Vec3& ty, RayRandom& rng, Vec3& dir, double& weight) {
    struct Cone {
        Vec3 axis;
        double cosMax, solidAngle;
    };
    Cone cones[8];
    std::size_t nCones = 0;
    bool inside = removed || spheres.size() > 8;
    double totalSolidAngle = 0;
    for (std::size_t k = 0; !inside && k < spheres.size(); ++k) {
        Vec3 axis = spheres[k].first - origin;
        const double dist = glm::length(axis), r = spheres[k].second;
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
        return true;
    }
    double pickCone = rng.next() * totalSolidAngle;
    std::size_t k = 0;
    while (k + 1 < nCones && pickCone > cones[k].solidAngle) pickCone -= cones[k++].solidAngle;
    const Cone& cone = cones[k];
    const double v = rng.next(), u = rng.next();  // in this order: cos θ's number first
    Vec3 coneX, coneY;
    frameAround(cone.axis, coneX, coneY);
    dir = coneDirection(cone.axis, coneX, coneY, cone.cosMax, u, v);
    double cosSrc = glm::dot(dir, nz);
    if (cosSrc <= 0) return false;
    int holding = 0;
    for (std::size_t m = 0; m < nCones; ++m)
        if (m == k || glm::dot(dir, cones[m].axis) >= cones[m].cosMax) ++holding;
    weight = totalSolidAngle / holding * cosSrc / M_PI;
    return true;
}

/// The worlds a redistribution batch traces its rays in.
struct BatchWorlds {
    Visibility before, after;
    Visibility changed;      ///< the changed objects alone
    bool onlyAdded = false;  ///< nothing removed: after = before ∪ added
};

/// The front-face elements a ray from `origin` reaches first before the edit (`eb`) and after
/// it (`ea`), -1 for none. False when the ray misses every changed object: it hits the same
/// element in both worlds, and only the changed objects are traced.
bool hitsBeforeAndAfter(const RayTracer& tracer, const BatchWorlds& worlds, bool removed,
                        const Vec3& origin, const Vec3& dir, int& eb, int& ea) {
    RayTracer::FirstHit hc;
    if (!removed && (hc = tracer.firstHit(origin, dir, worlds.changed)).element < 0) return false;
    RayTracer::FirstHit hb = tracer.firstHit(origin, dir, worlds.before);
    RayTracer::FirstHit ha;
    if (removed) {
        // The shooter is gone: nothing reaches anything after the edit.
    } else if (worlds.onlyAdded) {
        // After = before ∪ added: the nearer of the two first hits (the same
        // instances and transforms give the same t as tracing the union).
        ha = hb.element < 0 || hc.t < hb.t ? hc : hb;
    } else {
        ha = tracer.firstHit(origin, dir, worlds.after);
    }
    eb = hb.element >= 0 && !hb.backFace ? hb.element : -1;
    ea = ha.element >= 0 && !ha.backFace ? ha.element : -1;
    return true;
}

}  // namespace

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
    // The most important shooters first, as many as fit in one batch of rays.
    const double raysPerEmitted = mOptions.redistributionRaysPerEmittedPower > 0
                                      ? mOptions.redistributionRaysPerEmittedPower
                                      : mOptions.raysPerEmittedPower;
    const double raysPerWatt = raysPerEmitted / std::max(mEmittedEnergy, 1e-300);
    const double total = takeBatchShooters(c, raysPerWatt, mOptions.maxBatchRays, shooters, cdf);
    if (shooters.empty()) return;
    const double share = mEmittedEnergy > 0 ? total / mEmittedEnergy : 1.0;
    const std::size_t rays = static_cast<std::size_t>(std::clamp(
        std::ceil(share * raysPerEmitted), static_cast<double>(mOptions.minStochasticRays), 6.4e7));
    const std::uint64_t batchSeed =
        hashPair(hashPair(mOptions.seed, 0x7ed157ull), mStats.redistributionShots);
    BatchWorlds worlds{c.beforeWorld(), c.afterWorld(), c.changed.visibility(), c.removed.empty()};
    if (afterIsCurrentScene(c, false)) worlds.after = Visibility{};
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
            // Direction: into the changed objects' cones, or the hemisphere.
            double weight;  // cos/π over the sampling density: ∫ cos/π dω per unit area
            Vec3 dir;
            if (!sampleRedistributionDirection(c.spheres, removed, origin, nz, tx, ty, rng, dir,
                                               weight))
                continue;
            const Rgb carried = c.shot[j] * (P.area * weight / (static_cast<double>(rays) * pj));
            // The elements it reaches before and after the edit.
            int eb = -1, ea = -1;
            if (!hitsBeforeAndAfter(mTracer, worlds, removed, origin, dir, eb, ea)) continue;
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
                !(c.reachedAdded(j) && !c.before[mDisc.elements()[ea].object])) {
                const Element& el = mDisc.elements()[ea];
                out[2 * r + 1] = {ea, el.patch, el.area, carried / el.area, j};
            }
        }
    });
    // Apply in ray order: independent of the thread count.
    receiveAll(out, c.shotEmissionShare);
    if (c.bestPending() <= 0) mImpl->changes.erase(mImpl->changes.begin() + k);
    ++mStats.shots;
    ++mStats.redistributionShots;
    ++mStats.stochasticBatches;
    mStats.rays += mTracer.rayCount() - raysBefore;
}

}  // namespace penumbra
