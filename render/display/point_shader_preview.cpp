// PointShader's drag preview (see point_shader.h): the estimate of the preview's H_direct
// change per element, computed in chunks inline or on the workers, and applied.

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include "core/random.h"
#include "render/display/point_shader.h"
#include "render/display/point_shader_internal.h"
#include "solver/discretization.h"
#include "solver/form_factor.h"
#include "solver/ray_tracer.h"

namespace penumbra {

using namespace point_shader_detail;

namespace {

BoundingSphere objectSphere(const Discretization& disc, int object, double pad) {
    BoundingSphere s;
    if (object < 0 || object >= static_cast<int>(disc.objects().size())) return s;
    const auto& ws = disc.objects()[object].worldPositions;
    if (ws.empty()) return s;
    Vec3 lo = ws[0], hi = ws[0];
    for (const Vec3& w : ws) lo = glm::min(lo, w), hi = glm::max(hi, w);
    s.centre = 0.5 * (lo + hi);
    s.radius = 0.5 * glm::length(hi - lo) + pad;
    return s;
}

}  // namespace

std::shared_ptr<PointShader::DirectJob> PointShader::makeDirectJob(int ignore) const {
    auto job = std::make_shared<DirectJob>();
    job->state = state();
    const State& st = *job->state;
    job->preview = st.previewObject;
    job->origin = mDragOrigin;
    job->ignore = ignore;
    const std::size_t objects = mDisc.objects().size();
    if (job->preview >= 0) {
        job->previewOnly = st.previewOnly;
        if (!admitsSomething(job->previewOnly)) {
            job->previewWorld.assign(objects, 0);
            job->previewWorld[job->preview] = 1;
        }
        job->previewLights = lightsOf(job->preview);
        job->previewSphere = objectSphere(mDisc, job->preview, 4 * mTracer.epsilon());
    }
    if (job->origin >= 0 && job->origin != job->preview) {
        job->originOnly = mOriginOnly;
        if (!admitsSomething(job->originOnly)) {
            job->originWorld.assign(objects, 0);
            job->originWorld[job->origin] = 1;
        }
        job->originLights = lightsOf(job->origin);
        job->originSphere = objectSphere(mDisc, job->origin, 4 * mTracer.epsilon());
    } else {
        // The preview where the drag started: nothing changes.
        job->atOrigin = job->origin >= 0;
        job->origin = -1;
    }
    for (const Light& L : st.lights)
        if (L.object != job->preview && L.object != mDragOrigin) job->others.push_back(L);
    for (const Light& L : job->others) {
        Vec3 llo(std::numeric_limits<double>::infinity()), lhi(-llo);
        for (const auto& poly : L.polygons)
            for (const Vec3& p : poly) llo = glm::min(llo, p), lhi = glm::max(lhi, p);
        job->lightSpheres.push_back({0.5 * (llo + lhi), 0.5 * glm::length(lhi - llo)});
    }
    job->elements = mDisc.elements().size();
    job->chunkSize = static_cast<std::size_t>(std::max(16, mOptions.directChunk));
    job->chunks = (job->elements + job->chunkSize - 1) / job->chunkSize;
    job->value.assign(job->elements, Rgb(0.0));
    job->kind.assign(job->elements, 0);
    // The filters' pointers into the job (it does not move: shared_ptr).
    if (!job->previewWorld.empty()) job->previewOnly.world = &job->previewWorld;
    if (!job->originWorld.empty()) job->originOnly.world = &job->originWorld;
    return job;
}

void PointShader::runDirectChunk(DirectJob& job, std::size_t chunk) const {
    if (job.atOrigin) return;
    const std::size_t begin = chunk * job.chunkSize;
    const std::size_t end = std::min(job.elements, begin + job.chunkSize);
    const State& st = *job.state;
    const bool moved = job.origin >= 0;  // the origin's terms cancel the preview's at its place
    // Whether `sphere` can block the shaft from the element to a light of `others`: a cone from
    // the centroid (an element is small next to an object) to the light's bounding sphere,
    // radius t·r at parameter t; conservative: only for t ≤ t* + (R + r)/|d|.
    auto inShaft = [&](const Element& el, const BoundingSphere& s) {
        if (s.radius < 0) return false;
        if (glm::dot(el.normal, s.centre - el.centroid) < -s.radius) return false;
        for (const auto& [c, rl] : job.lightSpheres) {
            const Vec3 a = el.centroid, d = c - a;
            const double dd = glm::dot(d, d);
            if (!(dd > 0)) continue;
            const double t = std::clamp(glm::dot(s.centre - a, d) / dd, 0.0, 1.0);
            const double tMax = std::min(1.0, t + (s.radius + rl) / std::sqrt(dd));
            if (glm::length(s.centre - (a + t * d)) <= s.radius + tMax * rl) return true;
        }
        return false;
    };
    for (std::size_t e = begin; e < end; ++e) {
        const Element& el = mDisc.elements()[e];
        const std::uint64_t key = hashPair(mOptions.seed ^ 0x5EEDull, e);
        if (el.object == job.preview) {
            job.value[e] = directWith(st, el.centroid, el.normal, job.preview, key);
            job.kind[e] = 1;
            continue;
        }
        if (el.object == job.ignore) continue;
        if (!mDisc.objects()[el.object].alive) continue;
        Rgb change(0.0);
        if (job.preview >= 0 && inShaft(el, job.previewSphere))
            change += blockedChange(job.others, job.previewOnly, job.ignore, el.centroid, el.normal,
                                    el.object, key);
        if (moved && inShaft(el, job.originSphere))
            change -= blockedChange(job.others, job.originOnly, job.ignore, el.centroid, el.normal,
                                    el.object, key);
        if (!job.previewLights.empty())
            change += emittedBy(job.previewLights, job.previewOnly, job.ignore, el.centroid,
                                el.normal, el.object, key);
        if (moved && !job.originLights.empty())
            change -= emittedBy(job.originLights, job.originOnly, job.ignore, el.centroid,
                                el.normal, el.object, key);
        if (!isZero(change)) {
            job.value[e] = change;
            job.kind[e] = 2;
        }
    }
}

std::vector<int> PointShader::applyDirectJob(const DirectJob& job) {
    const std::size_t n = mDisc.elements().size();
    mElementDirect.resize(n, Rgb(0.0));
    std::vector<Rgb> delta(n, Rgb(0.0));
    std::vector<int> touched;
    for (std::size_t e = 0; e < job.elements && e < n; ++e) {
        if (job.kind[e] == 0) continue;
        delta[e] = job.kind[e] == 1 ? job.value[e] - mElementDirect[e] : job.value[e];
        touched.push_back(static_cast<int>(e));
    }
    // Elements whose preview direct changed: the old estimate's and the new one's.
    std::vector<int> changed;
    std::vector<std::uint8_t> seen(n, 0);
    auto consider = [&](int e, const Rgb& old) {
        if (e >= static_cast<int>(n) || seen[e]) return;
        seen[e] = 1;
        if (delta[e] != old) changed.push_back(e);
    };
    for (int e : mPreviewElements)
        consider(e, e < static_cast<int>(mPreviewDirectDelta.size()) ? mPreviewDirectDelta[e]
                                                                     : Rgb(0.0));
    for (int e : touched) consider(e, Rgb(0.0));
    std::sort(changed.begin(), changed.end());
    mPreviewElements = std::move(touched);
    mPreviewDirectDelta = std::move(delta);
    mPreviewDirectFor = job.preview;
    return changed;
}

void PointShader::dropDirectJob() {
    std::lock_guard lock(mQueueMutex);
    mJob.reset();
    mJobWanted = false;
}

void PointShader::queueDirectJob() {
    {
        std::lock_guard lock(mQueueMutex);
        if (mJob) {
            mJobWanted = true;
            return;
        }
    }
    auto job = makeDirectJob(-1);
    {
        std::lock_guard lock(mQueueMutex);
        mJob = std::move(job);
        mJobWanted = false;
    }
    mWake.notify_all();
}

std::vector<int> PointShader::setPreview(int object, const Visibility& previewOnly) {
    if (object < 0 || object >= static_cast<int>(mDisc.objects().size()))
        throw std::invalid_argument("PointShader::setPreview: no object " + std::to_string(object));
    auto next = std::make_shared<State>(*state());
    const int old = next->previewObject;
    next->previewObject = object;
    next->previewOnly = previewOnly;
    next->previewWorld.assign(mDisc.objects().size(), 0);
    for (std::size_t o = 0; o < mDisc.objects().size(); ++o)
        next->previewWorld[o] = mDisc.objects()[o].alive ? 1 : 0;
    next->previewWorld[object] = 1;
    // The preview's light replaces the previous preview's and the drag origin's (a dragged
    // lamp lights the scene from where it is now).
    std::vector<Light> lights;
    for (Light& L : next->lights)
        if (L.object != old && L.object != mDragOrigin && L.object != object)
            lights.push_back(std::move(L));
    for (Light& L : lightsOf(object)) lights.push_back(std::move(L));
    next->lights = std::move(lights);
    // Until the next solution snapshot blends the new version's light, it takes the light of
    // the version it replaces (the previous position, or the drag's origin): the same mesh, so
    // the same vertices. Without it the fallback of the pixels the object newly covers (no
    // point there yet) would be black.
    carryVertexLight(*next, old, object);
    carryVertexLight(*next, mDragOrigin, object);
    mElementDirect.resize(mDisc.elements().size(), Rgb(0.0));
    publish(std::move(next));

    // H_direct per element at its centroid with the point shading's light sampling (seeded by
    // the element): the object's own elements in the preview world; other elements whose shaft
    // to a light can meet the object's (or the drag origin's) bounding sphere get the change
    // (only rays the object blocks are traced twice); every element the change of a moved
    // lamp's light.
    if (mOptions.backgroundPreview && !mWorkers.empty()) {
        queueDirectJob();
        return {};
    }
    dropDirectJob();
    auto job = makeDirectJob(-1);
    tbb::parallel_for(std::size_t(0), job->chunks, [&](std::size_t c) { runDirectChunk(*job, c); });
    return applyDirectJob(*job);
}

void PointShader::carryVertexLight(State& st, int from, int to) const {
    if (from < 0 || from == to || !mDisc.sameElements(from, to)) return;
    const std::size_t need = static_cast<std::size_t>(std::max(from, to)) + 1;
    if (st.vertexDirect.size() < need) st.vertexDirect.resize(need);
    if (st.vertexIndirect.size() < need) st.vertexIndirect.resize(need);
    if (!st.vertexDirect[to].empty() && !st.vertexIndirect[to].empty()) return;
    if (st.vertexDirect[from].empty() || st.vertexIndirect[from].empty()) return;
    st.vertexDirect[to] = st.vertexDirect[from];
    st.vertexIndirect[to] = st.vertexIndirect[from];
}

std::vector<int> PointShader::takeDirectUpdate() {
    std::shared_ptr<DirectJob> done;
    bool wanted = false;
    {
        std::lock_guard lock(mQueueMutex);
        if (mJob && mJob->complete()) {
            done = std::move(mJob);
            mJob.reset();
        }
        wanted = !mJob && mJobWanted;
    }
    std::vector<int> changed;
    const int current = state()->previewObject;
    if (done && done->state->previewObject == current) {
        changed = applyDirectJob(*done);
        if (mHasSolution) rebuildIndirect();
    } else if (done) {
        wanted = true;  // the preview ended or changed object: estimate again
        if (current >= 0 && done->preview >= 0 && mDisc.sameElements(done->preview, current)) {
            // Finished for an earlier place of the object dragged now, as a drag's estimates
            // mostly are (the object moves on while its estimate runs): its own elements' direct
            // light, moved onto the current version, stands in until the estimate for this
            // place comes. A step behind is far closer than the light where the drag began,
            // which the object's carried points would show meanwhile. The rest of the scene
            // keeps the estimate it has (the moving shadow's points are dropped and re-shaded
            // by the display instead).
            const std::size_t n = mDisc.elements().size();
            DirectJob moved;
            moved.preview = current;
            moved.elements = n;
            moved.kind.assign(n, 0);
            moved.value.assign(n, Rgb(0.0));
            const auto [to, count] = mDisc.elementRange(current);
            const int from = mDisc.elementRange(done->preview).first;
            for (int e : mPreviewElements)
                if (e >= 0 && static_cast<std::size_t>(e) < n &&
                    static_cast<std::size_t>(e) < mPreviewDirectDelta.size() &&
                    (e < to || e >= to + count) && (e < from || e >= from + count)) {
                    moved.kind[e] = 2;
                    moved.value[e] = mPreviewDirectDelta[e];
                }
            for (int k = 0; k < count; ++k) {
                const auto f = static_cast<std::size_t>(from + k);
                if (f < done->elements && done->kind[f] == 1) {
                    moved.kind[to + k] = 1;
                    moved.value[to + k] = done->value[f];
                }
            }
            changed = applyDirectJob(moved);
            if (mHasSolution) rebuildIndirect();
        }
    }
    if (wanted && state()->previewObject >= 0) queueDirectJob();
    return changed;
}

int PointShader::directJobPreview() const {
    std::lock_guard lock(mQueueMutex);
    return mJob ? mJob->preview : -1;
}

bool PointShader::directUpdatePending() const {
    std::lock_guard lock(mQueueMutex);
    return mJob != nullptr || mJobWanted;
}

std::vector<int> PointShader::clearPreview() {
    dropDirectJob();
    std::vector<int> changed;
    for (int e : mPreviewElements)
        if (e < static_cast<int>(mPreviewDirectDelta.size()) && !isZero(mPreviewDirectDelta[e]))
            changed.push_back(e);
    mPreviewElements.clear();
    mPreviewDirectDelta.clear();
    mPreviewDirectFor = -1;
    auto next = std::make_shared<State>(*state());
    const int old = next->previewObject;
    next->previewObject = -1;
    next->previewOnly = Visibility{};
    next->previewWorld.clear();
    if (old >= 0 && !lightsOf(old).empty()) next->lights = aliveLights();
    publish(std::move(next));
    if (mDragOrigin >= 0) {
        // H_direct still had the origin in place: take it out now.
        const int origin = mDragOrigin;
        mDragOrigin = -1;
        mOriginOnly = Visibility{};
        const std::vector<Rgb> before = mElementDirect;
        refreshDirect(std::vector<int>{origin});
        for (std::size_t e = 0; e < mElementDirect.size(); ++e)
            if (e >= before.size() || before[e] != mElementDirect[e])
                changed.push_back(static_cast<int>(e));
        std::sort(changed.begin(), changed.end());
        changed.erase(std::unique(changed.begin(), changed.end()), changed.end());
    }
    // A drop (the object alive again a little further on) or a cancel (back at its origin):
    // its stand-in light comes with this state, not with the next solution snapshot.
    if (!mDragEstimate.empty()) rememberDropped();
    if (mHasSolution) rebuildIndirect();
    return changed;
}

void PointShader::beginDrag(int origin, const Visibility& originOnly) {
    if (origin < 0 || origin >= static_cast<int>(mDisc.objects().size()))
        throw std::invalid_argument("PointShader::beginDrag: no object " + std::to_string(origin));
    dropDirectJob();
    mDragOrigin = origin;
    mOriginOnly = originOnly;
    // The object's solved indirect light where it rests: the first estimate for its moves.
    mDragEstimate.clear();
    mDragEstimateObject = -1;
    if (mHasSolution) {
        const auto [first, count] = mDisc.elementRange(origin);
        const std::size_t n = std::min(mElementH.size(), mElementHEmission.size());
        mDragEstimate.assign(static_cast<std::size_t>(count), Rgb(0.0));
        for (int k = 0; k < count; ++k) {
            const auto e = static_cast<std::size_t>(first + k);
            if (e < n) mDragEstimate[k] = glm::max(mElementH[e] - mElementHEmission[e], Rgb(0.0));
        }
        mDragEstimateObject = origin;
    }
}

std::vector<int> PointShader::endDrag(int added) {
    if (added < 0 || added >= static_cast<int>(mDisc.objects().size()))
        throw std::invalid_argument("PointShader::endDrag: no object " + std::to_string(added));
    dropDirectJob();
    // The final change, with `added` in the preview slot and out of the scene's rays.
    {
        auto next = std::make_shared<State>(*state());
        if (next->previewObject != added) {
            next->previewObject = added;
            next->previewWorld.assign(mDisc.objects().size(), 0);
            for (std::size_t o = 0; o < mDisc.objects().size(); ++o)
                next->previewWorld[o] = mDisc.objects()[o].alive ? 1 : 0;
            next->previewWorld[added] = 1;
            publish(std::move(next));
        }
    }
    auto job = makeDirectJob(added);
    tbb::parallel_for(std::size_t(0), job->chunks, [&](std::size_t c) { runDirectChunk(*job, c); });
    const std::size_t n = mDisc.elements().size();
    mElementDirect.resize(n, Rgb(0.0));
    std::vector<int> changed;
    for (int e : mPreviewElements)
        if (e < static_cast<int>(n) && e < static_cast<int>(mPreviewDirectDelta.size()) &&
            !isZero(mPreviewDirectDelta[e]))
            changed.push_back(e);
    for (std::size_t e = 0; e < job->elements && e < n; ++e) {
        if (job->kind[e] == 0) continue;
        mElementDirect[e] = job->kind[e] == 1 ? job->value[e] : mElementDirect[e] + job->value[e];
        changed.push_back(static_cast<int>(e));
    }
    std::sort(changed.begin(), changed.end());
    changed.erase(std::unique(changed.begin(), changed.end()), changed.end());
    mPreviewElements.clear();
    mPreviewDirectDelta.clear();
    mPreviewDirectFor = -1;
    mDragOrigin = -1;
    mOriginOnly = Visibility{};
    auto next = std::make_shared<State>(*state());
    next->previewObject = -1;
    next->previewOnly = Visibility{};
    next->previewWorld.clear();
    next->lights = aliveLights();
    publish(std::move(next));
    // The solution snapshot is still the drag's, in which the object has no light of its own
    // (the preview buffer had it): the drag's estimate stands in from now on, not only from
    // the next snapshot, so no point is shaded without its indirect light meanwhile.
    if (!mDragEstimate.empty()) rememberDropped();
    mLastPreviewIndirect.clear();
    mLastPreviewObject = -1;
    if (mHasSolution) rebuildIndirect();
    return changed;
}

void PointShader::copyDirectFrom(const PointShader& source) {
    if (&source.mDisc != &mDisc)
        throw std::invalid_argument("PointShader::copyDirectFrom: another Discretization");
    dropDirectJob();
    mElementDirect = source.mElementDirect;
    mElementH = source.mElementH;
    mElementHEmission = source.mElementHEmission;
    mLastPreviewIndirect = source.mLastPreviewIndirect;
    mLastPreviewObject = source.mLastPreviewObject;
    mDragEstimate = source.mDragEstimate;
    mDragEstimateObject = source.mDragEstimateObject;
    mDroppedObject = source.mDroppedObject;
    mDroppedIndirect = source.mDroppedIndirect;
    mHasSolution = source.mHasSolution;
    mPreviewDirectDelta = source.mPreviewDirectDelta;
    mPreviewElements = source.mPreviewElements;
    mPreviewDirectFor = source.mPreviewDirectFor;
    mDragOrigin = source.mDragOrigin;
    mOriginOnly = source.mOriginOnly;
    {
        // The source's state first: one shader's mutex is never taken while another's is held.
        std::shared_ptr<const State> state = source.state();  // its serial stays: the same shading
        std::lock_guard lock(mStateMutex);
        mState = std::move(state);
    }
    if (source.directUpdatePending()) queueDirectJob();
}

int PointShader::previewObject() const { return state()->previewObject; }

std::vector<Rgb> PointShader::elementIndirect() const { return state()->elementIndirect; }

}  // namespace penumbra
