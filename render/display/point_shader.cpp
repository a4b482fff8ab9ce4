// Index: helpers (random numbers, hull, light sampling) · lights · per-element direct part
//        · solution snapshot · synchronous shading · workers · shadow triples · toString
//        (the drag preview's direct light: point_shader_preview.cpp)
#include "render/display/point_shader.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <glm/gtc/constants.hpp>
#include <limits>
#include <sstream>
#include <stdexcept>

#include "core/random.h"
#include "core/thread_priority.h"
#include "render/display/point_shader_internal.h"
#include "solver/discretization.h"
#include "solver/form_factor.h"
#include "solver/ray_tracer.h"

namespace penumbra {

using namespace point_shader_detail;

// ---------------------------------------------------------------------------------------------
// Helpers

namespace {

std::uint64_t bitsOf(double v) {
    std::uint64_t b;
    std::memcpy(&b, &v, sizeof b);
    return b;
}

/// Deterministic uniform numbers in [0, 1) from a 64-bit state.
struct SampleRandom {
    std::uint64_t state;
    double next() {
        state = hashPair(state, 0x2545f4914f6cdd1dull);
        return static_cast<double>(state >> 11) * 0x1.0p-53;
    }
};

/// Twice the signed area of the 2D triangle (o, a, b).
double cross2(const glm::dvec2& o, const glm::dvec2& a, const glm::dvec2& b) {
    return (a.x - o.x) * (b.y - o.y) - (a.y - o.y) * (b.x - o.x);
}

/// Convex hull (Andrew's monotone chain), counter-clockwise, collinear points dropped.
std::vector<int> convexHull2d(const std::vector<glm::dvec2>& p) {
    std::vector<int> idx(p.size());
    for (std::size_t i = 0; i < p.size(); ++i) idx[i] = static_cast<int>(i);
    std::sort(idx.begin(), idx.end(), [&](int a, int b) {
        return p[a].x < p[b].x || (p[a].x == p[b].x && p[a].y < p[b].y);
    });
    if (idx.size() < 3) return idx;
    std::vector<int> hull(2 * idx.size());
    std::size_t k = 0;
    for (int i : idx) {
        while (k >= 2 && cross2(p[hull[k - 2]], p[hull[k - 1]], p[i]) <= 0) --k;
        hull[k++] = i;
    }
    for (std::size_t j = idx.size() - 1, t = k + 1; j-- > 0;) {
        int i = idx[j];
        while (k >= t && cross2(p[hull[k - 2]], p[hull[k - 1]], p[i]) <= 0) --k;
        hull[k++] = i;
    }
    hull.resize(k - 1);
    return hull;
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// Lights

namespace {

/// Emitter patches of alive objects.
std::vector<int> emitterPatches(const Discretization& disc) {
    std::vector<int> out;
    for (std::size_t p = 0; p < disc.patches().size(); ++p)
        if (disc.patchAlive(static_cast<int>(p)) &&
            disc.patchMaterial(static_cast<int>(p)).isEmitter())
            out.push_back(static_cast<int>(p));
    return out;
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// Set-up and per-element direct part

PointShader::PointShader(const Discretization& disc, const RayTracer& tracer,
                         const SolverOptions& solverOptions, PointShaderOptions options)
    : mDisc(disc), mTracer(tracer), mSolverOptions(solverOptions), mOptions(options) {
    mState = std::make_shared<State>();
    refreshDirect();
    for (int t = 0; t < mOptions.threads; ++t) mWorkers.emplace_back([this] { workerLoop(); });
}

PointShader::PointShader(const PointShader& source, PointShaderOptions options)
    : mDisc(source.mDisc),
      mTracer(source.mTracer),
      mSolverOptions(source.mSolverOptions),
      mOptions(options) {
    mState = source.state();
    copyDirectFrom(source);
    for (int t = 0; t < mOptions.threads; ++t) mWorkers.emplace_back([this] { workerLoop(); });
}

PointShader::~PointShader() {
    {
        std::lock_guard lock(mQueueMutex);
        mStop = true;
    }
    mWake.notify_all();
    for (auto& w : mWorkers) w.join();
}

std::shared_ptr<const PointShader::State> PointShader::state() const {
    std::lock_guard lock(mStateMutex);
    return mState;
}

namespace {
/// State serials, one sequence for every shader: a state shared between two shaders
/// (copyDirectFrom) keeps its number, still older than either's next.
std::atomic<std::uint64_t> gStateSerial{0};
}  // namespace

void PointShader::publish(std::shared_ptr<State> state) {
    state->serial = ++gStateSerial;
    std::lock_guard lock(mStateMutex);
    mState = std::move(state);
}

std::uint64_t PointShader::stateSerial() const { return state()->serial; }

Rgb PointShader::computeElementDirect(int e, const std::vector<int>& emitters) const {
    // The solver's irradianceFrom for the emitters' own shots: same culls, same pair seeds.
    // (Only the emitter patches are visited: a loop over all patches per element cost
    // 25k × 1M checks on armadillo-field, 39 s of the display's set-up.)
    const Element& el = mDisc.elements()[e];
    if (!mDisc.objects()[el.object].alive) return Rgb(0.0);
    Rgb sum(0.0);
    for (int j : emitters) {
        const Patch& P = mDisc.patches()[j];
        const Rgb& emission = mDisc.patchMaterial(j).emission;
        if (el.patch == j) continue;
        Vec3 toReceiver = el.centroid - P.centroid;
        if (glm::dot(toReceiver, P.normal) < -P.radius) continue;
        if (glm::dot(-toReceiver, el.normal) < -P.radius) continue;
        PointToPatch ff = formFactorToPatch(mDisc, mTracer, el.centroid, el.normal,
                                            static_cast<int>(j), static_cast<std::uint64_t>(e),
                                            mSolverOptions.seed, mSolverOptions.maxRaysPerPair);
        sum += emission * ff.visible;
    }
    return sum;
}

std::vector<PointShader::Light> PointShader::lightsOf(int o) const {
    // Merge the patches of a planar emitter object into their convex outline when they tile
    // it exactly (quads, boxes' faces are separate objects' patches only when coplanar),
    // otherwise one light per patch.
    std::vector<Light> out;
    std::vector<int> ps;
    for (std::size_t p = 0; p < mDisc.patches().size(); ++p)
        if (mDisc.patches()[p].object == o && mDisc.patchMaterial(static_cast<int>(p)).isEmitter())
            ps.push_back(static_cast<int>(p));
    if (ps.empty()) return out;
    bool mergeable = true;
    const Patch& first = mDisc.patches()[ps[0]];
    const Rgb e0 = mDisc.patchMaterial(ps[0]).emission;
    double areaSum = 0;
    for (int p : ps) {
        const Patch& P = mDisc.patches()[p];
        areaSum += P.area;
        if (P.outline.empty() || mDisc.patchMaterial(p).emission != e0 ||
            glm::dot(P.normal, first.normal) < 1 - 1e-9)
            mergeable = false;
    }
    if (mergeable && ps.size() > 1) {
        // Project every outline vertex to the plane; hull; accept when it tiles exactly.
        Vec3 n = glm::normalize(first.normal);
        Vec3 u = glm::normalize(glm::cross(std::abs(n.x) > 0.5 ? Vec3(0, 1, 0) : Vec3(1, 0, 0), n));
        Vec3 v = glm::cross(n, u);
        const Vec3 origin = first.outline[0];
        std::vector<Vec3> points;
        std::vector<glm::dvec2> flat;
        for (int p : ps)
            for (const Vec3& q : mDisc.patches()[p].outline) {
                if (std::abs(glm::dot(q - origin, n)) > 1e-9 * (1 + glm::length(q - origin)))
                    mergeable = false;
                points.push_back(q);
                flat.push_back({glm::dot(q - origin, u), glm::dot(q - origin, v)});
            }
        std::vector<int> hull = convexHull2d(flat);
        std::vector<Vec3> polygon;
        for (int i : hull) polygon.push_back(points[i]);
        double hullArea = 0.5 * glm::length(newellNormal(polygon));
        if (mergeable && std::abs(hullArea - areaSum) <= 1e-6 * areaSum) {
            Light light;
            light.object = o;
            light.emission = e0;
            light.polygons.push_back(polygon);
            light.finish();
            out.push_back(std::move(light));
            return out;
        }
    }
    for (int p : ps) {
        Light light;
        light.object = o;
        light.emission = mDisc.patchMaterial(p).emission;
        const Patch& P = mDisc.patches()[p];
        if (!P.outline.empty())
            light.polygons.push_back(P.outline);
        else
            for (int e : P.elements) light.polygons.push_back(mDisc.elementPolygon(e));
        light.finish();
        if (light.area > 0) out.push_back(std::move(light));
    }
    return out;
}

std::vector<PointShader::Light> PointShader::aliveLights() const {
    std::vector<char> emits(mDisc.objects().size(), 0);
    for (int p : emitterPatches(mDisc)) emits[mDisc.patches()[p].object] = 1;
    std::vector<Light> out;
    for (std::size_t o = 0; o < emits.size(); ++o)
        if (emits[o])
            for (Light& l : lightsOf(static_cast<int>(o))) out.push_back(std::move(l));
    return out;
}

void PointShader::refreshDirect() {
    // Every H_direct is recomputed in the scene as it is: a drag's origin is no longer in it.
    mDragOrigin = -1;
    mOriginOnly = Visibility{};
    dropDirectJob();
    auto next = std::make_shared<State>(*state());
    next->lights = aliveLights();

    // H_direct(e) for every element, in parallel.
    const std::size_t n = mDisc.elements().size();
    mElementDirect.assign(n, Rgb(0.0));
    const std::vector<int> emitters = emitterPatches(mDisc);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 64), [&](const auto& r) {
        for (std::size_t e = r.begin(); e != r.end(); ++e)
            mElementDirect[e] = computeElementDirect(static_cast<int>(e), emitters);
    });
    const int preview = next->previewObject;
    const Visibility previewOnly = next->previewOnly;
    publish(std::move(next));
    if (preview >= 0) setPreview(preview, previewOnly);
}

void PointShader::refreshDirect(const std::vector<int>& changedObjectList) {
    // A drag's origin leaves H_direct here too (its shaft elements are recomputed without it).
    std::vector<int> changedObjects = changedObjectList;
    if (mDragOrigin >= 0) changedObjects.push_back(mDragOrigin);
    mDragOrigin = -1;
    mOriginOnly = Visibility{};
    // A changed emitter changes the lights themselves: recompute everything.
    for (int o : changedObjects)
        for (const Patch& P : mDisc.patches())
            if (P.object == o && mDisc.materials()[P.material].isEmitter()) return refreshDirect();

    // Bounding spheres of the changed objects (dead versions keep their geometry).
    struct Sphere {
        Vec3 centre;
        double radius;
    };
    std::vector<Sphere> spheres;
    std::vector<std::uint8_t> changed(mDisc.objects().size(), 0);
    for (int o : changedObjects) {
        if (o < 0 || o >= static_cast<int>(mDisc.objects().size())) continue;
        changed[o] = 1;
        const auto& ws = mDisc.objects()[o].worldPositions;
        if (ws.empty()) continue;
        Vec3 lo = ws[0], hi = ws[0];
        for (const Vec3& w : ws) lo = glm::min(lo, w), hi = glm::max(hi, w);
        spheres.push_back({0.5 * (lo + hi), 0.5 * glm::length(hi - lo) + mTracer.epsilon()});
    }
    const std::vector<int> emitters = emitterPatches(mDisc);
    const std::size_t n = mDisc.elements().size(), old = mElementDirect.size();
    mElementDirect.resize(n, Rgb(0.0));

    // Recompute an element when it is new, on a changed object, or when the shaft from its
    // centroid to an emitter patch (inside the cone of balls of radius t·R about the segment
    // centroid → patch centre) can meet a changed object's bounding sphere.
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 64), [&](const auto& r) {
        for (std::size_t e = r.begin(); e != r.end(); ++e) {
            const Element& el = mDisc.elements()[e];
            bool redo = e >= old || changed[el.object];
            for (std::size_t k = 0; !redo && k < emitters.size(); ++k) {
                const Patch& P = mDisc.patches()[emitters[k]];
                Vec3 a = el.centroid, d = P.centroid - a;
                double dd = glm::dot(d, d);
                for (const Sphere& s : spheres) {
                    double t = dd > 0 ? std::clamp(glm::dot(s.centre - a, d) / dd, 0.0, 1.0) : 0;
                    if (glm::length(s.centre - (a + t * d)) <= s.radius + P.radius) {
                        redo = true;
                        break;
                    }
                }
            }
            if (redo) mElementDirect[e] = computeElementDirect(static_cast<int>(e), emitters);
        }
    });
    const auto st = state();
    if (st->previewObject >= 0) setPreview(st->previewObject, st->previewOnly);
}

std::vector<Rgb> PointShader::elementDirect() const {
    std::vector<Rgb> out = mElementDirect;
    for (int e : mPreviewElements)
        if (e < static_cast<int>(out.size())) out[e] += mPreviewDirectDelta[e];
    return out;
}

// ---------------------------------------------------------------------------------------------
// Solution snapshot

void PointShader::updateSolution(const ProgressiveSolver& solver) {
    const bool preview = solver.previewObject() >= 0;
    updateSolution(solver.irradiance(), solver.irradianceFromEmission(),
                   preview ? &solver.previewRadiosity() : nullptr,
                   preview ? &solver.previewRadiosityFromEmission() : nullptr,
                   solver.previewObject(), solver.previewComplete());
}

void PointShader::updateSolution(const std::vector<Rgb>& H, const std::vector<Rgb>& fromEmission,
                                 const std::vector<Rgb>* previewRadiosity,
                                 const std::vector<Rgb>* previewFromEmission, int previewObject,
                                 bool previewComplete) {
    mElementH = H;
    mElementHEmission = fromEmission;
    const bool dragging = state()->previewObject >= 0 || mDragOrigin >= 0;
    if (!dragging && !mDragEstimate.empty()) rememberDropped();
    mLastPreviewIndirect.clear();
    if (previewRadiosity) {
        // George et al.'s buffer T holds ρ·ΔH; its reflected part (T − T_emission)/ρ is the
        // indirect irradiance the preview adds.
        const std::vector<Rgb>& T = *previewRadiosity;
        mLastPreviewIndirect.assign(T.size(), Rgb(0.0));
        for (std::size_t e = 0; e < T.size() && e < mDisc.elements().size(); ++e) {
            const Rgb reflected = previewFromEmission && e < previewFromEmission->size()
                                      ? T[e] - (*previewFromEmission)[e]
                                      : T[e];
            if (isZero(reflected)) continue;
            const Rgb rho = mDisc.elementMaterial(static_cast<int>(e)).reflectance;
            for (int c = 0; c < 3; ++c)
                if (rho[c] > 0) mLastPreviewIndirect[e][c] = reflected[c] / rho[c];
        }
    }
    mLastPreviewObject = previewRadiosity ? previewObject : -1;
    // (A snapshot taken before the drop reached the solver leaves the estimate alone.)
    if (previewRadiosity && previewObject >= 0 && dragging)
        noteDragEstimate(previewObject, previewComplete);
    mHasSolution = true;
    rebuildIndirect();
}

void PointShader::noteDragEstimate(int object, bool complete) {
    if (mDragEstimateObject >= 0 && !mDisc.sameElements(mDragEstimateObject, object)) {
        mDragEstimate.clear();
        mDragEstimateObject = -1;
    }
    const auto [first, count] = mDisc.elementRange(object);
    std::vector<Rgb> candidate(static_cast<std::size_t>(count), Rgb(0.0));
    double light = 0;
    for (int k = 0; k < count && first + k < static_cast<int>(mLastPreviewIndirect.size()); ++k) {
        candidate[k] = glm::max(mLastPreviewIndirect[first + k], Rgb(0.0));
        light += luminance(candidate[k]);
    }
    double estimated = 0;
    for (const Rgb& h : mDragEstimate) estimated += luminance(h);
    if (mDragEstimate.empty() || complete || object == mDragEstimateObject ||
        light >= kDragEstimateShare * estimated) {
        mDragEstimate = std::move(candidate);
        mDragEstimateObject = object;
    }
}

void PointShader::rememberDropped() {
    // The drag ended: the object is alive again at its last preview's place (or a little
    // further on, or back at its origin: the same mesh), and the drag's estimate is the best
    // guess of its indirect irradiance there.
    mDroppedObject = -1;
    mDroppedIndirect.clear();
    const int from = mDragEstimateObject;
    std::vector<Rgb> estimate = std::move(mDragEstimate);
    mDragEstimate.clear();
    mDragEstimateObject = -1;
    if (from < 0 || from >= static_cast<int>(mDisc.objects().size())) return;
    for (int o = 0; o < static_cast<int>(mDisc.objects().size()); ++o) {
        if (!mDisc.objects()[o].alive || !mDisc.sameElements(from, o)) continue;
        mDroppedIndirect = std::move(estimate);
        mDroppedObject = o;
        return;
    }
}

void PointShader::computeMissingElementDirect() {
    if (mElementDirect.size() < mDisc.elements().size()) {
        const std::size_t old = mElementDirect.size();
        const std::size_t n = mDisc.elements().size();
        mElementDirect.resize(n, Rgb(0.0));
        const std::vector<int> emitters = emitterPatches(mDisc);
        tbb::parallel_for(tbb::blocked_range<std::size_t>(old, n, 64), [&](const auto& r) {
            for (std::size_t e = r.begin(); e != r.end(); ++e)
                mElementDirect[e] = computeElementDirect(static_cast<int>(e), emitters);
        });
    }
}

void PointShader::holdDroppedEstimate(std::vector<Rgb>& indirect, std::size_t n) {
    if (mDroppedObject >= 0) {
        const auto [first, count] = mDisc.elementRange(mDroppedObject);
        double solved = 0, estimated = 0;
        for (int k = 0; k < count && k < static_cast<int>(mDroppedIndirect.size()); ++k) {
            const std::size_t e = static_cast<std::size_t>(first + k);
            if (e >= indirect.size()) break;
            const Rgb h = e < n ? indirect[e] : Rgb(0.0);
            const Rgb& estimate = mDroppedIndirect[k];
            solved += luminance(h);
            estimated += luminance(estimate);
            indirect[e] = glm::max(glm::max(h, estimate), Rgb(0.0));
        }
        if (!mDisc.objects()[mDroppedObject].alive || solved >= 0.9 * estimated) {
            mDroppedObject = -1;
            mDroppedIndirect.clear();
        }
    }
}

void PointShader::addPreviewBuffer(std::vector<Rgb>& indirect, int preview) const {
    // While a drag moves on faster than the solver's buffer follows, the buffer is for where
    // the object was a moment ago (an earlier version of the same mesh): its elements' values
    // move with it, so the object keeps its light instead of going black until the solver
    // catches up; the rest of the scene keeps the buffer's changes.
    std::vector<Rgb> moved;
    const bool lagging = preview >= 0 && !mLastPreviewIndirect.empty() &&
                         mLastPreviewObject != preview &&
                         mDisc.sameElements(mLastPreviewObject, preview);
    if (lagging) {
        moved = mLastPreviewIndirect;
        moved.resize(std::max(moved.size(), mDisc.elements().size()), Rgb(0.0));
        const auto [from, count] = mDisc.elementRange(mLastPreviewObject);
        const int to = mDisc.elementRange(preview).first;
        for (int k = 0; k < count; ++k) {
            moved[to + k] = moved[from + k];
            moved[from + k] = Rgb(0.0);
        }
    }
    if (preview >= 0 && !mLastPreviewIndirect.empty() &&
        (mLastPreviewObject == preview || lagging)) {
        // The reflected part of George et al.'s temporary buffer (the preview object's whole
        // indirect irradiance, the change elsewhere) adds to the solution's.
        const std::vector<Rgb>& T = lagging ? moved : mLastPreviewIndirect;
        for (std::size_t e = 0; e < indirect.size() && e < T.size(); ++e) indirect[e] += T[e];
    }
}

void PointShader::applyDragEstimate(std::vector<Rgb>& indirect, int preview) const {
    if (preview >= 0 && !mDragEstimate.empty() &&
        mDisc.sameElements(mDragEstimateObject, preview)) {
        const auto [first, count] = mDisc.elementRange(preview);
        for (int k = 0; k < count && k < static_cast<int>(mDragEstimate.size()); ++k) {
            const auto e = static_cast<std::size_t>(first + k);
            if (e < indirect.size()) indirect[e] = glm::max(indirect[e], mDragEstimate[k]);
        }
    }
}

void PointShader::clampEstimatedIndirect(std::vector<Rgb>& indirect, int preview,
                                         std::size_t n) const {
    auto clampRange = [&](int first, int count) {
        for (int e = std::max(first, 0); e < first + count && e < static_cast<int>(indirect.size());
             ++e)
            indirect[e] = glm::max(indirect[e], Rgb(0.0));
    };
    if (mOptions.clampIndirect) {
        clampRange(0, static_cast<int>(indirect.size()));
    } else if (preview >= 0) {
        const auto [first, count] = mDisc.elementRange(preview);
        clampRange(first, count);
    }
    clampRange(static_cast<int>(n), static_cast<int>(indirect.size()) - static_cast<int>(n));
}

void PointShader::blendVertexLight(State& next) {
    const int preview = next.previewObject;
    std::vector<Rgb> direct(mElementDirect);
    direct.resize(mDisc.elements().size(), Rgb(0.0));
    if (preview >= 0)
        for (int e : mPreviewElements)
            if (e < static_cast<int>(direct.size()) &&
                e < static_cast<int>(mPreviewDirectDelta.size()))
                direct[e] += mPreviewDirectDelta[e];
    const std::size_t objects = mDisc.objects().size();
    std::vector<std::uint8_t> directChanged(objects, 0);
    for (std::size_t e = 0; e < direct.size(); ++e)
        if (e >= mVertexDirectOf.size() || direct[e] != mVertexDirectOf[e])
            directChanged[mDisc.elements()[e].object] = 1;
    const auto previous = state();
    next.vertexIndirect.resize(objects);
    next.vertexDirect.resize(objects);
    tbb::parallel_for(std::size_t(0), objects, [&](std::size_t o) {
        if (!mDisc.objects()[o].alive && static_cast<int>(o) != preview) return;
        next.vertexIndirect[o] = mDisc.vertexValues(static_cast<int>(o), next.elementIndirect);
        const bool known = o < previous->vertexDirect.size() && !previous->vertexDirect[o].empty();
        next.vertexDirect[o] = known && !directChanged[o]
                                   ? previous->vertexDirect[o]
                                   : mDisc.vertexValues(static_cast<int>(o), direct);
    });
    mVertexDirectOf = std::move(direct);
}

void PointShader::rebuildIndirect() {
    const std::vector<Rgb>& H = mElementH;
    const std::size_t n = std::min({H.size(), mElementHEmission.size(), mDisc.elements().size()});
    // Every element's direct light, also of versions newer than the solution (a preview, an
    // object just added): the fallback shows them lit by it.
    computeMissingElementDirect();
    auto next = std::make_shared<State>();
    {
        const auto st = state();
        next->lights = st->lights;
        next->previewObject = st->previewObject;
        next->previewOnly = st->previewOnly;
        next->previewWorld = st->previewWorld;
    }
    const int preview = next->previewObject;
    next->elementIndirect.assign(mDisc.elements().size(), Rgb(0.0));
    for (std::size_t e = 0; e < n; ++e) next->elementIndirect[e] = H[e] - mElementHEmission[e];
    // An object just dropped after a drag: its last preview's estimate until the solution
    // catches up.
    holdDroppedEstimate(next->elementIndirect, n);
    // The drag preview's buffer, moved with the object when it lags behind the drag.
    addPreviewBuffer(next->elementIndirect, preview);
    // The moving object no darker than the drag's estimate while its buffer fills.
    applyDragEstimate(next->elementIndirect, preview);
    // No indirect light below 0 where it comes from an estimate (or everywhere, with
    // clampIndirect).
    clampEstimatedIndirect(next->elementIndirect, preview, n);
    // The fallback's direct part, and both parts blended per vertex.
    blendVertexLight(*next);
    publish(std::move(next));
}

// ---------------------------------------------------------------------------------------------
// Synchronous shading

ShadedPoint PointShader::shade(const ShadeRequest& request) const {
    return shadeWith(*state(), request);
}

Rgb PointShader::directIrradiance(const Vec3& x, const Vec3& n, int receiver,
                                  std::uint64_t key) const {
    return directWith(*state(), x, n, receiver, key);
}

Rgb PointShader::indirectIrradiance(int element, const std::vector<double>& weights) const {
    auto st = state();
    const Element& el = mDisc.elements()[element];
    if (el.object >= static_cast<int>(st->vertexIndirect.size())) return Rgb(0.0);
    const auto& vi = st->vertexIndirect[el.object];
    if (vi.empty() || weights.size() != el.vertices.size())
        return element < static_cast<int>(st->elementIndirect.size()) ? st->elementIndirect[element]
                                                                      : Rgb(0.0);
    Rgb h(0.0);
    for (std::size_t i = 0; i < weights.size(); ++i) h += weights[i] * vi[el.vertices[i]];
    return h;
}

namespace {

/// How forEachLightSample chooses its shadow rays (PointShaderOptions' fields).
struct ShadowSampling {
    double formFactorPerRay = 2e-3;
    int maxStrataPerAxis = 4;
    int refine = 0;  ///< 0: plain estimator
    int maxRefinedPerAxis = 16;
    int decisionPerAxis = 4;
};

ShadowSampling shadowSamplingOf(const PointShaderOptions& o) {
    return {o.formFactorPerRay, o.maxStrataPerAxis, o.shadowRefine, o.shadowMaxRefinedPerAxis,
            o.shadowDecisionPerAxis};
}

/// Rays a light's set must have tested for their agreement to count (ShadedPoint::exact): a
/// 4 × 4 set, the display's largest.
constexpr int kAgreeingRays = 16;

// Stream tags of the adaptive sampler's extra patterns (independent of the plain pattern).
constexpr std::uint64_t kDecisionStream = 0xDEC1DE5EEDull;
constexpr std::uint64_t kRefinedStream = 0x5EF1AEDull;

/// The stratified samples of every light seen from (x, n), Bala et al.'s area lights:
/// `visit(light, from, to)` for each sample y returns whether the sample counts as blocked;
/// `done(light, unoccluded F, blocked F, agreed)` then gets the light's totals, and whether
/// the rays of the set the estimate came from agreed (all blocked or none: no penumbra seen,
/// so the estimate has no sampling noise). The estimators below
/// share this pattern, so their samples match (and, with adaptive sampling, so do their
/// decisions wherever their visits agree).
///
/// Blocked part (unbiased): (A/N) Σ K(x, y_i)·(1 − V(x, y_i)), K = cosθ_x cosθ_y / (π r²).
/// Adaptive (sampling.refine > 0): a decision set D, independent of the plain set P and of the
/// refined set R, picks the estimator: P's when D's rays agree, R's (finer) otherwise. Since D
/// is independent of both, E[estimate] = P(agree)·truth + P(disagree)·truth.
template <class Lights, class Visit, class Done>
void forEachLightSample(const Lights& lights, const Vec3& x, const Vec3& n, int receiver,
                        std::uint64_t key, double eps, const ShadowSampling& sampling,
                        Visit&& visit, Done&& done) {
    const double invPi = glm::one_over_pi<double>();
    const Vec3 from = x + n * eps;
    for (std::size_t l = 0; l < lights.size(); ++l) {
        const auto& L = lights[l];
        if (L.planar && L.object == receiver) continue;  // a plane cannot light itself
        // Analytic unoccluded form factor (Lambert's contour formula).
        double fUnoccluded = 0;
        for (const auto& poly : L.polygons) fUnoccluded += polygonFormFactor(x, n, poly);
        if (!(fUnoccluded > 0)) continue;
        // Strata by the light's projected solid angle.
        int perAxis =
            static_cast<int>(std::ceil(std::sqrt(fUnoccluded / sampling.formFactorPerRay)));
        perAxis = std::clamp(perAxis, 1, std::max(1, sampling.maxStrataPerAxis));
        // One stratified set of s² rays from `stream`: the blocked part's estimate, and (when
        // asked) whether its rays agreed. Directions the light faces away from count as
        // unblocked with no weight.
        auto estimate = [&](int s, std::uint64_t stream, bool* agreed, int* testedRays) {
            const int rays = s * s;
            SampleRandom rng{hashPair(key ^ stream, l)};
            double blocked = 0;
            int blockedRays = 0, tested = 0;
            for (int i = 0; i < rays; ++i) {
                double r0 = rng.next(), r1 = rng.next();
                Vec3 ny;
                Vec3 y = L.sample(i, rays, s, r0, r1, ny);
                Vec3 d = y - x;
                double r2 = glm::dot(d, d);
                double cx = glm::dot(n, d), cy = -glm::dot(ny, d);
                if (!(r2 > 0) || cx <= 0 || cy <= 0) continue;
                ++tested;
                if (visit(L, from, y + ny * eps)) {
                    blocked += cx * cy / (r2 * r2) * invPi;
                    ++blockedRays;
                }
            }
            if (agreed) *agreed = blockedRays == 0 || blockedRays == tested;
            if (testedRays) *testedRays = tested;
            return blocked * (L.area / rays);
        };
        if (sampling.refine > 0) {
            bool agreed = true;
            (void)estimate(std::max(1, sampling.decisionPerAxis), kDecisionStream, &agreed,
                           nullptr);
            if (!agreed) {
                // A penumbra: the finer set alone (the decision rays stay out of it).
                const int fine = std::clamp(perAxis * sampling.refine, perAxis,
                                            std::max(perAxis, sampling.maxRefinedPerAxis));
                done(L, fUnoccluded, estimate(fine, kRefinedStream, nullptr, nullptr), false);
                continue;
            }
        }
        bool agreed = true;
        int tested = 0;
        const double fBlocked = estimate(perAxis, 0, &agreed, &tested);
        // Agreement of a few rays says little (one ray always agrees): a set that tested
        // fewer than kAgreeingRays counts as a penumbra.
        done(L, fUnoccluded, fBlocked, agreed && tested >= kAgreeingRays);
    }
}

}  // namespace

Rgb PointShader::directWith(const State& st, const Vec3& x, const Vec3& n, int receiver,
                            std::uint64_t key, bool* exact) const {
    Rgb total(0.0);
    if (exact) *exact = true;
    forEachLightSample(
        st.lights, x, n, receiver, key, mTracer.epsilon(), shadowSamplingOf(mOptions),
        [&](const Light& L, const Vec3& from, const Vec3& to) {
            const bool sceneBlocked = mTracer.occluded(from, to);
            if (!sceneBlocked && !previewBlocks(st, from, to)) return false;
            // The edge finder knows the scene's objects, not the preview version.
            if (mOptions.recordTriples && sceneBlocked) {
                // Who blocked: the first surface along the shadow ray (Bala et al. §6.5).
                RayTracer::FirstHit b = mTracer.firstHit(from, glm::normalize(to - from));
                if (b.element >= 0) {
                    int blocker = mDisc.elements()[b.element].object;
                    if (blocker != L.object) recordTriple({L.object, blocker, receiver});
                }
            }
            return true;
        },
        [&](const Light& L, double fUnoccluded, double fBlocked, bool agreed) {
            if (exact && !agreed) *exact = false;
            double f = fUnoccluded - fBlocked;
            if (f > 0 || !mOptions.clampNegative) total += L.emission * f;
        });
    return total;
}

Rgb PointShader::blockedChange(const std::vector<Light>& lights, const Visibility& blocker,
                               int ignore, const Vec3& x, const Vec3& n, int receiver,
                               std::uint64_t key) const {
    // directWith's samples (same strata and pattern for the same lights), counting only the
    // rays `blocker` blocks and the scene does not: the change of the blocked part.
    Rgb change(0.0);
    const Visibility scene(ignore);
    forEachLightSample(
        lights, x, n, receiver, key, mTracer.epsilon(), shadowSamplingOf(mOptions),
        [&](const Light&, const Vec3& from, const Vec3& to) {
            return mTracer.occluded(from, to, blocker) && !mTracer.occluded(from, to, scene);
        },
        [&](const Light& L, double fUnoccluded, double fBlocked, bool) {
            change -= L.emission * std::min(fBlocked, fUnoccluded);
        });
    return change;
}

Rgb PointShader::emittedBy(const std::vector<Light>& lights, const Visibility& extra, int ignore,
                           const Vec3& x, const Vec3& n, int receiver, std::uint64_t key) const {
    Rgb total(0.0);
    const Visibility scene(ignore);
    const bool blocks = admitsSomething(extra);
    forEachLightSample(
        lights, x, n, receiver, key, mTracer.epsilon(), shadowSamplingOf(mOptions),
        [&](const Light&, const Vec3& from, const Vec3& to) {
            return mTracer.occluded(from, to, scene) ||
                   (blocks && mTracer.occluded(from, to, extra));
        },
        [&](const Light& L, double fUnoccluded, double fBlocked, bool) {
            const double f = fUnoccluded - fBlocked;
            if (f > 0) total += L.emission * f;
        });
    return total;
}

RayHit PointShader::traceWith(const State& st, const Vec3& origin, const Vec3& direction) const {
    if (st.previewObject < 0) return mTracer.intersect(origin, direction);
    if (st.previewOnly.subset < 0)
        return mTracer.intersect(origin, direction, 0.0, 1e30, st.worldVisibility());
    // The scene, then the preview object alone up to the scene's hit.
    RayHit hit = mTracer.intersect(origin, direction);
    RayHit preview =
        mTracer.intersect(origin, direction, 0.0, hit.object >= 0 ? hit.t : 1e30, st.previewOnly);
    return preview.object >= 0 ? preview : hit;
}

bool PointShader::previewBlocks(const State& st, const Vec3& from, const Vec3& to) const {
    if (st.previewObject < 0) return false;
    return mTracer.occluded(from, to,
                            st.previewOnly.subset >= 0 ? st.previewOnly : st.worldVisibility());
}

ShadedPoint PointShader::shadeWith(const State& st, const ShadeRequest& request) const {
    mShaded.fetch_add(1, std::memory_order_relaxed);
    ShadedPoint out;
    out.pixel = request.pixel;
    out.frame = request.frame;
    out.shading = st.serial;
    out.exact = true;
    const RayHit hit = traceWith(st, request.origin, request.direction);
    if (hit.object < 0 || hit.element < 0) {
        out.position = request.origin + request.direction * kMissDistance;
        out.normal = -request.direction;
        return out;
    }
    const Element& el = mDisc.elements()[hit.element];
    out.position = hit.position;
    out.object = el.object;
    out.element = hit.element;
    out.normal = hit.backFace ? -el.normal : el.normal;
    // Back faces absorb (black) unless two-sided, which shows the front's radiosity.
    if (hit.backFace && !mDisc.objects()[el.object].twoSided) return out;

    const Material& material = mDisc.elementMaterial(hit.element);
    const std::uint64_t key = hashPair(
        hashPair(hashPair(mOptions.seed, bitsOf(request.pixel.x)), bitsOf(request.pixel.y)),
        request.frame);
    Rgb h = directWith(st, hit.position, el.normal, el.object, key, &out.exact);
    // H_indirect blended from per-vertex values with the hit's barycentric weights.
    if (el.object < static_cast<int>(st.vertexIndirect.size()) &&
        !st.vertexIndirect[el.object].empty() && hit.weights.size() == el.vertices.size()) {
        const auto& vi = st.vertexIndirect[el.object];
        for (std::size_t i = 0; i < hit.weights.size(); ++i)
            h += hit.weights[i] * vi[el.vertices[i]];
    } else if (hit.element < static_cast<int>(st.elementIndirect.size())) {
        h += st.elementIndirect[hit.element];
    }
    if (mOptions.clampNegative) h = glm::max(h, Rgb(0.0));
    const Rgb emission = hit.backFace ? Rgb(0.0) : material.emission;
    out.radiance = (emission + material.reflectance * h) * glm::one_over_pi<double>();
    return out;
}

PointShader::Snapshot PointShader::snapshot() const {
    Snapshot at;
    at.mState = state();
    return at;
}

int PointShader::Snapshot::previewObject() const { return mState ? mState->previewObject : -1; }

Rgb PointShader::shadeFallback(const Vec3& origin, const Vec3& direction) const {
    return shadeFallback(Snapshot{}, origin, direction);
}

Rgb PointShader::shadeFallback(const Snapshot& at, const Vec3& origin,
                               const Vec3& direction) const {
    const auto st = at.mState ? at.mState : state();
    const RayHit hit = traceWith(*st, origin, direction);
    if (hit.object < 0 || hit.element < 0) return Rgb(0.0);
    const Element& el = mDisc.elements()[hit.element];
    if (hit.backFace && !mDisc.objects()[el.object].twoSided) return Rgb(0.0);
    const Material& material = mDisc.elementMaterial(hit.element);
    Rgb h(0.0);
    if (el.object < static_cast<int>(st->vertexDirect.size()) &&
        !st->vertexDirect[el.object].empty() && !st->vertexIndirect[el.object].empty() &&
        hit.weights.size() == el.vertices.size()) {
        const auto& vd = st->vertexDirect[el.object];
        const auto& vi = st->vertexIndirect[el.object];
        Rgb direct(0.0);
        for (std::size_t i = 0; i < hit.weights.size(); ++i) {
            direct += hit.weights[i] * vd[el.vertices[i]];
            h += hit.weights[i] * vi[el.vertices[i]];
        }
        // No direct light blended here: a surface an edit has just uncovered (the top of what
        // a lifted object stood on) whose element estimate has not been redone yet; its light
        // sampled at the hit as a point's instead (in a shadow, rays that all come back blocked).
        if (luminance(direct) <= 0 && !hit.backFace)
            direct = directWith(*st, hit.position, el.normal, el.object,
                                static_cast<std::uint64_t>(hit.element));
        h += direct;
    } else if (!hit.backFace) {
        // A version no snapshot has blended yet: its direct light at the hit, sampled as a
        // point's, and its element's indirect light when known. Dimmer than the truth at
        // worst, never black.
        h = directWith(*st, hit.position, el.normal, el.object,
                       static_cast<std::uint64_t>(hit.element));
        if (hit.element < static_cast<int>(st->elementIndirect.size()))
            h += glm::max(st->elementIndirect[hit.element], Rgb(0.0));
    }
    const Rgb emission = hit.backFace ? Rgb(0.0) : material.emission;
    return glm::max(emission + material.reflectance * h, Rgb(0.0)) * glm::one_over_pi<double>();
}

// ---------------------------------------------------------------------------------------------
// Workers

void PointShader::workerLoop() {
    nameThisThread("shade");
    lowerThreadPriority(mOptions.workerNice);
    std::vector<ShadeRequest> batch;
    std::vector<ShadedPoint> done;
    bool jobTurn = true;  // alternate H_direct chunks and shading batches
    for (;;) {
        std::shared_ptr<DirectJob> job;
        std::size_t chunk = 0;
        {
            std::unique_lock lock(mQueueMutex);
            auto jobReady = [&] { return mJob && mJob->nextChunk < mJob->chunks; };
            mWake.wait(lock, [&] {
                return mStop || (mPauseCount == 0 && (!mRequests.empty() || jobReady()));
            });
            if (mStop) return;
            batch.clear();
            if (jobReady() && (jobTurn || mRequests.empty())) {
                job = mJob;
                chunk = job->nextChunk++;
            } else {
                while (!mRequests.empty() && static_cast<int>(batch.size()) < mOptions.batchSize) {
                    batch.push_back(mRequests.front());
                    mRequests.pop_front();
                }
                mBusy += batch.size();
            }
            jobTurn = !jobTurn;
            ++mActiveWorkers;
        }
        if (job) {
            runDirectChunk(*job, chunk);
            std::lock_guard lock(mQueueMutex);
            ++job->doneChunks;
            --mActiveWorkers;
        } else {
            auto st = state();
            done.clear();
            for (const ShadeRequest& r : batch) done.push_back(shadeWith(*st, r));
            std::lock_guard lock(mQueueMutex);
            mResults.insert(mResults.end(), done.begin(), done.end());
            mBusy -= batch.size();
            --mActiveWorkers;
        }
        mIdle.notify_all();
    }
}

void PointShader::submit(const std::vector<ShadeRequest>& requests) {
    {
        std::lock_guard lock(mQueueMutex);
        mRequests.insert(mRequests.end(), requests.begin(), requests.end());
    }
    mWake.notify_all();
}

void PointShader::cancelPending() {
    std::lock_guard lock(mQueueMutex);
    mRequests.clear();
}

std::vector<ShadedPoint> PointShader::takeResults() {
    std::lock_guard lock(mQueueMutex);
    std::vector<ShadedPoint> out;
    out.swap(mResults);
    return out;
}

std::size_t PointShader::pendingCount() const {
    std::lock_guard lock(mQueueMutex);
    return mRequests.size() + mBusy;
}

void PointShader::waitIdle() {
    if (mWorkers.empty()) {
        // No workers: shade the queue here.
        std::vector<ShadeRequest> batch;
        {
            std::lock_guard lock(mQueueMutex);
            batch.assign(mRequests.begin(), mRequests.end());
            mRequests.clear();
        }
        auto st = state();
        std::vector<ShadedPoint> done;
        for (const ShadeRequest& r : batch) done.push_back(shadeWith(*st, r));
        std::lock_guard lock(mQueueMutex);
        mResults.insert(mResults.end(), done.begin(), done.end());
        return;
    }
    std::unique_lock lock(mQueueMutex);
    mIdle.wait(lock, [&] { return (mRequests.empty() || mPauseCount > 0) && mBusy == 0; });
}

void PointShader::pause() {
    std::unique_lock lock(mQueueMutex);
    ++mPauseCount;
    mIdle.wait(lock, [&] { return mActiveWorkers == 0; });
}

void PointShader::resume() {
    {
        std::lock_guard lock(mQueueMutex);
        mPauseCount = std::max(0, mPauseCount - 1);
    }
    mWake.notify_all();
}

// ---------------------------------------------------------------------------------------------
// Shadow triples

std::size_t ShadowTripleHash::operator()(const ShadowTriple& t) const {
    return static_cast<std::size_t>(hashPair(
        hashPair(static_cast<std::uint64_t>(t.light), static_cast<std::uint64_t>(t.blocker)),
        static_cast<std::uint64_t>(t.receiver)));
}

void PointShader::recordTriple(const ShadowTriple& t) const {
    if (mTriples.count(t)) return;
    if (mTriples.insert(t).second) mNewTriples.push(t);
}

std::vector<ShadowTriple> PointShader::shadowTriples() const {
    return std::vector<ShadowTriple>(mTriples.begin(), mTriples.end());
}

std::vector<ShadowTriple> PointShader::takeNewShadowTriples() {
    std::vector<ShadowTriple> out;
    ShadowTriple t;
    while (mNewTriples.try_pop(t)) out.push_back(t);
    return out;
}

void PointShader::clearShadowTriples() {
    mTriples.clear();
    mNewTriples.clear();
}

std::uint64_t PointShader::shadedCount() const { return mShaded.load(); }

// ---------------------------------------------------------------------------------------------
// toString

std::string ShadeRequest::toString() const {
    std::ostringstream s;
    s << "ShadeRequest{pixel (" << pixel.x << ", " << pixel.y << "), origin (" << origin.x << ", "
      << origin.y << ", " << origin.z << "), direction (" << direction.x << ", " << direction.y
      << ", " << direction.z << "), frame " << frame << "}";
    return s.str();
}

std::string ShadedPoint::toString() const {
    std::ostringstream s;
    s << "ShadedPoint{pixel (" << pixel.x << ", " << pixel.y << "), position (" << position.x
      << ", " << position.y << ", " << position.z << "), radiance (" << radiance.x << ", "
      << radiance.y << ", " << radiance.z << "), object " << object << ", element " << element
      << ", frame " << frame << ", samples " << samples << "}";
    return s.str();
}

std::string ShadowTriple::toString() const {
    return "ShadowTriple{light " + std::to_string(light) + ", blocker " + std::to_string(blocker) +
           ", receiver " + std::to_string(receiver) + "}";
}

std::string PointShader::toString() const {
    auto st = state();
    std::ostringstream s;
    s << "PointShader{" << st->lights.size() << " lights, " << mElementDirect.size()
      << " elements, " << mWorkers.size() << " workers, seed " << mOptions.seed << ", "
      << shadedCount() << " shaded, " << mTriples.size() << " shadow triples}";
    return s.str();
}

}  // namespace penumbra
