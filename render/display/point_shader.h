#pragma once
// The point shader of the edge-and-point renderer (Bala, Walter, Greenberg 2003 §3, §6.5):
// an external, asynchronous shading process that turns primary-ray requests into shaded 3D
// points for the render cache, and reports the light–blocker–receiver triples it discovers to
// the edge finder.
//
// Index: requests and results · shadow triples · options · PointShader (set-up, solution
//        snapshot, synchronous shading, asynchronous workers, triples)
//
// Shading of a hit x on element e with reflectance ρ and emission E (front faces):
//     L(x) = (E + ρ·(H_direct(x) + H_indirect(x))) / π
// H_direct(x) is computed per sample from every emitter as an area light with stratified
// shadow rays (soft shadows); H_indirect is the radiosity solution's non-direct part,
// H_e − H_e,emission (ProgressiveSolver::irradianceFromEmission: the solver books what came
// straight from emission apart, so the difference does not depend on whether the emitters'
// redistribution after an edit is done yet), blended across elements from per-vertex values
// as the Gouraud renderer does. The per-element direct light H_direct(e) = Σ_j E_j·F(e←j)
// lights the fallback and the drag preview's estimates.

#include <tbb/concurrent_queue.h>
#include <tbb/concurrent_unordered_set.h>

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <glm/glm.hpp>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "solver/progressive_solver.h"
#include "solver/ray_tracer.h"
#include "solver/scene.h"

namespace penumbra {

class Discretization;
class InteractiveDisplay;
struct PointShaderTestAccess;

// ---------------------------------------------------------------------------------------------
// Requests and results

/// One primary ray to shade: the pixel position it was generated for (pixel coordinates as in
/// CameraRays: x right in [0, width], y down in [0, height]), the ray, and the frame that
/// asked for it (part of the sample's random seed, and recorded in the result).
struct ShadeRequest {
    glm::dvec2 pixel{0.0};
    Vec3 origin{0.0};
    Vec3 direction{0, 0, -1};  ///< unit
    std::uint64_t frame = 0;
    std::string toString() const;
};

/// A shaded point: the nearest hit of the request's ray and its radiance (W/m²/sr, linear).
/// A miss has object == element == −1, radiance 0 and position at origin + direction·1e6 m
/// (a point "at infinity" the render cache can reproject like any other).
struct ShadedPoint {
    glm::dvec2 pixel{0.0};  ///< the request's pixel position
    Vec3 position{0.0};     ///< world space
    Vec3 normal{0.0};       ///< unit, the side the ray arrived at
    Rgb radiance{0.0};
    int object = -1;  ///< Discretization object index
    int element = -1;
    std::uint64_t frame = 0;  ///< the request's frame
    /// The shader state it was shaded with (PointShader::stateSerial): a display that relit
    /// its element since takes it as stale (the change is not in its colour).
    std::uint64_t shading = 0;
    bool stale = false;  ///< RenderCache::insert marks it stale (re-shaded first)
    /// No sampling noise in its value: a miss, a black back face, or a hit where every
    /// light's shadow rays agreed (all blocked or none), so its direct light is the exact
    /// unoccluded part or (up to the small noise of the sampled blocked part against the
    /// analytic unoccluded one) zero, and its indirect light the solution's smooth blend.
    /// Another sample of the same point gives the same value; a noisy one (in a penumbra)
    /// needs averaging (RenderCache::insert merges a pixel's samples). A light's rays count as
    /// agreeing only from 16 tested rays on (a 4 × 4 set).
    bool exact = false;
    /// The samples of its pixel whose mean `radiance` is: 1 for a point shaded now; a
    /// holodeck's point holds the mean of the stored samples of its surface in its pixel
    /// (RenderCache::insert takes it as that many merged samples).
    int samples = 1;
    bool hit() const { return object >= 0; }
    std::string toString() const;
};

/// Distance at which misses are placed (metres from the ray origin).
inline constexpr double kMissDistance = 1e6;

// ---------------------------------------------------------------------------------------------
// Shadow triples (Bala et al. §6.5 "Finding light-blocker-receiver triples")

/// A shadow ray from a point on object `receiver` toward emitter object `light` was blocked by
/// object `blocker`. Discretization object indices (object versions).
struct ShadowTriple {
    int light = -1;
    int blocker = -1;
    int receiver = -1;
    bool operator==(const ShadowTriple&) const = default;
    std::string toString() const;
};

struct ShadowTripleHash {
    std::size_t operator()(const ShadowTriple& t) const;
};

// ---------------------------------------------------------------------------------------------
// Options

struct PointShaderOptions {
    std::uint64_t seed = 1;  ///< sample patterns depend on (seed, pixel, frame) only
    /// Shadow rays per light: strata per axis s = clamp(ceil(sqrt(F / formFactorPerRay)), 1,
    /// maxStrataPerAxis) for a light of unoccluded form factor F (its projected solid angle
    /// over π), s² rays on a jittered grid over the light.
    int maxStrataPerAxis = 4;
    double formFactorPerRay = 2e-3;
    /// Adaptive shadow sampling (0 = off, the plain estimator above). Per light, a separate
    /// decision set of shadowDecisionPerAxis² stratified rays is traced first; when its rays
    /// all agree (all blocked or all unblocked) the plain estimate is used unchanged (bit for
    /// bit the same as with adaptive sampling off), otherwise (a penumbra) the blocked part is
    /// estimated from a fresh stratified set of s'² rays, s' = clamp(s·shadowRefine, s,
    /// shadowMaxRefinedPerAxis). The decision rays never enter the estimate, so it stays
    /// unbiased. Costs the decision rays for every lit sample: off for the interactive display,
    /// deep for converged references.
    int shadowRefine = 0;
    int shadowMaxRefinedPerAxis = 16;
    int shadowDecisionPerAxis = 4;
    /// Clamp each light's estimate and the total irradiance at 0 (the display: no negative
    /// radiance from the blocked-part estimate's noise). Off for converged references, where
    /// the clamp's bias would not average away.
    bool clampNegative = true;
    /// Clamp every element's H_indirect at 0. While the solver redistributes after an edit, a
    /// new shadow's negative shots can run ahead of the positive ones that follow them and the
    /// difference would show as dark patches; the editor's displays clamp it. Off, the value
    /// stays as it is (unbiased on a converged solution); the dragged object and versions
    /// newer than the solution are clamped either way.
    bool clampIndirect = false;
    int threads = 2;     ///< worker threads for asynchronous shading
    int batchSize = 64;  ///< requests a worker takes at a time
    bool recordTriples = true;
    /// With workers (threads > 0): setPreview() does not estimate the preview's H_direct
    /// change before returning but queues it to the workers in chunks of `directChunk`
    /// elements, interleaved with shading batches; takeDirectUpdate() applies it when done.
    bool backgroundPreview = false;
    int directChunk = 256;
    /// Linux nice increment of the worker threads (0: as the creating thread): an interactive
    /// program keeps its UI thread ahead of the shading.
    int workerNice = 0;
};

// ---------------------------------------------------------------------------------------------
// PointShader

/// Thread safety: shade(), directIrradiance() and the queue functions may be called from any
/// thread. The Discretization and RayTracer are read by the workers; whoever changes them
/// (edits, element subdivision) must hold a Pause (or call pause()/resume()) around the change
/// and then call refreshDirect() and updateSolution() before resuming.
class PointShader {
public:
    /// `disc` and `tracer` must outlive the shader. `solverOptions` must be the options of the
    /// ProgressiveSolver whose solution is displayed (its seed and maxRaysPerPair reproduce the
    /// solver's form factors). Computes the per-element direct irradiance (refreshDirect()) and
    /// starts options.threads workers (none when threads ≤ 0: synchronous use only). Until
    /// updateSolution() is called the indirect part is zero (direct lighting only).
    PointShader(const Discretization& disc, const RayTracer& tracer,
                const SolverOptions& solverOptions, PointShaderOptions options = {});
    /// A shader over `source`'s Discretization and RayTracer that takes its lights, H_direct,
    /// solution snapshot and preview (copyDirectFrom) instead of computing them. `source`
    /// must not change meanwhile (same thread, or paused).
    PointShader(const PointShader& source, PointShaderOptions options);
    ~PointShader();  ///< stops and joins the workers
    PointShader(const PointShader&) = delete;
    PointShader& operator=(const PointShader&) = delete;

    // -- Solution snapshot -------------------------------------------------------------------

    /// Recomputes the lights (emitter patches of alive objects, coplanar patches of one planar
    /// emitter merged into one polygon) and H_direct(e) = Σ_j E_j·F(e←j) for every element
    /// (oneTBB parallel). Call after any change to emitters or after subdivision.
    void refreshDirect();
    /// Snapshots the solver's element irradiance: H_indirect(e) = H_e − H_e,emission and its
    /// per-vertex blend. Call from the thread that steps the solver, between steps; shading
    /// picks the new snapshot up at its next batch. `solver` must be over the same
    /// Discretization.
    void updateSolution(const ProgressiveSolver& solver);
    /// H_direct(e) for every element (W/m²), as used by updateSolution() (with a preview set:
    /// in the world that includes the preview object).
    std::vector<Rgb> elementDirect() const;
    /// The indirect irradiance snapshot per element (W/m²).
    std::vector<Rgb> elementIndirect() const;
    /// The serial of the state shading uses now (ShadedPoint::shading), growing with every
    /// change of the lighting or the preview.
    std::uint64_t stateSerial() const;

    // -- Drag preview (George et al.'s temporary buffer) -------------------------------------

    // A drag is InteractiveDisplay's: its apply() takes the preview's steps (private below).

    /// The preview object, -1 for none.
    int previewObject() const;
    /// The origin of the drag in progress (beginDrag), -1 for none.
    int dragOrigin() const { return mDragOrigin; }
    /// An H_direct estimate is queued, being computed or waits for takeDirectUpdate().
    bool directUpdatePending() const;
    /// The preview object of the estimate the workers have (queued, running or done, not yet
    /// taken), -1 for none: its `previewOnly` subset must stay alive until then, also after a
    /// newer setPreview (which lets the running estimate finish rather than restart it).
    int directJobPreview() const;
    /// Whether elementDirect() holds an estimate of `object`'s own elements at its current
    /// place: every object but a preview whose estimate has not come in yet (setPreview with
    /// backgroundPreview queues it; takeDirectUpdate applies it).
    bool directKnown(int object) const {
        return object != previewObject() || mPreviewDirectFor == object;
    }

    // -- Synchronous shading -----------------------------------------------------------------

    /// Shades one request on the calling thread. Deterministic in (seed, request).
    ShadedPoint shade(const ShadeRequest& request) const;
    /// The display's cheap fallback for a pixel no sample reaches: the nearest hit of the ray
    /// in the displayed world (the scene and the preview object) shaded with the radiosity
    /// solution's irradiance blended per vertex, as the Gouraud view shows it (one ray). Where
    /// no direct light is blended (an object version no snapshot has seen yet, a surface an
    /// edit has just uncovered) the direct light is sampled at the hit as a point's, so an
    /// uncovered surface is not black. Radiance, W/m²/sr; 0 for a miss or a back face.
    Rgb shadeFallback(const Vec3& origin, const Vec3& direction) const;
    /// The shading state as of now (the lighting and the preview object), kept by a caller
    /// that shades later against the world it saw then: a frame's holes are filled in the
    /// world its points were taken from, not the one edits made meanwhile. The preview's
    /// subset must stay alive while the snapshot is used.
    class Snapshot;
    Snapshot snapshot() const;
    /// shadeFallback in the world and lighting of `at` (the current ones when it is empty).
    Rgb shadeFallback(const Snapshot& at, const Vec3& origin, const Vec3& direction) const;
    /// Direct irradiance (W/m²) at x with unit normal n on object `receiver` from all lights,
    /// estimated with stratified shadow rays whose pattern depends on `key`:
    /// H = Σ_L E_L·(F_L − (A_L/N)·Σ_i K(x, y_i)·(1 − V(x, y_i))), the analytic unoccluded form
    /// factor F_L (Lambert's contour formula) minus an unbiased estimate of the blocked part
    /// (exact where nothing blocks; each light's term clamped at 0). Blocked rays are recorded
    /// as shadow triples when options.recordTriples.
    Rgb directIrradiance(const Vec3& x, const Vec3& n, int receiver, std::uint64_t key) const;
    /// H_indirect at a hit of `element` with barycentric `weights` over its vertices.
    Rgb indirectIrradiance(int element, const std::vector<double>& weights) const;

    // -- Asynchronous shading ----------------------------------------------------------------

    /// Queues requests for the workers (FIFO).
    void submit(const std::vector<ShadeRequest>& requests);
    /// Drops queued requests no worker has started (e.g. after a fast camera move).
    void cancelPending();
    /// Takes every result finished so far (in completion order).
    std::vector<ShadedPoint> takeResults();
    /// Requests queued or being shaded.
    std::size_t pendingCount() const;
    /// Blocks until every submitted request is shaded.
    void waitIdle();

    /// Workers finish their current batch and wait; the Discretization and RayTracer may be
    /// changed until resume(). Nested pauses count.
    void pause();
    void resume();
    class Pause {
    public:
        explicit Pause(PointShader& shader) : mShader(shader) { mShader.pause(); }
        ~Pause() { mShader.resume(); }
        Pause(const Pause&) = delete;
        Pause& operator=(const Pause&) = delete;

    private:
        PointShader& mShader;
    };

    // -- Shadow triples ----------------------------------------------------------------------

    /// All triples found so far (a snapshot; safe while workers run).
    std::vector<ShadowTriple> shadowTriples() const;
    /// Triples first found since the previous call (each triple is returned once).
    std::vector<ShadowTriple> takeNewShadowTriples();
    /// Forgets every triple (call while paused, e.g. when objects moved).
    void clearShadowTriples();

    /// Samples shaded since construction (synchronous and asynchronous).
    std::uint64_t shadedCount() const;
    const PointShaderOptions& options() const { return mOptions; }
    std::string toString() const;

private:
    friend class InteractiveDisplay;
    /// Checks one of the steps below alone (defined by the tests).
    friend struct PointShaderTestAccess;

    // -- The display's steps (InteractiveDisplay::apply) -------------------------------------

    /// Incremental refresh after an edit: `changedObjects` are the object versions added or
    /// removed. Recomputes H_direct(e) for elements on changed objects, new elements, and
    /// elements whose shaft to some emitter patch meets a changed object's bounding sphere; a
    /// changed emitter triggers refreshDirect().
    void refreshDirect(const std::vector<int>& changedObjects);
    /// updateSolution(solver) from views of the solver's arrays or of copies of them
    /// (InteractiveDisplay::apply(SolutionView)): `irradiance` = ProgressiveSolver::
    /// irradiance(), `fromEmission` its irradianceFromEmission(), and while `previewObject` ≥ 0
    /// is the solver's previewObject(), `previewRadiosity` and `previewFromEmission` its
    /// previewRadiosity() and previewRadiosityFromEmission() (null: none), and
    /// `previewComplete` its previewComplete(). Lets another thread update the display from a
    /// published snapshot while the solver keeps shooting.
    void updateSolution(const std::vector<Rgb>& irradiance, const std::vector<Rgb>& fromEmission,
                        const std::vector<Rgb>* previewRadiosity = nullptr,
                        const std::vector<Rgb>* previewFromEmission = nullptr,
                        int previewObject = -1, bool previewComplete = false);
    /// Shows `object`, a dead object version present in the tracer (ProgressiveSolver::
    /// previewObject(): the dragged object at its current position), as if it were in the
    /// scene: primary rays see it and shadow rays are blocked by it. `previewOnly` must admit
    /// exactly that object (a RayTracer::createSubset visibility, kept alive by the caller while
    /// the preview is set); without a subset the rays use a Visibility::world filter over
    /// every version (correct, slower as drag versions pile up). Estimates H_direct in the
    /// preview world at element centroids with the point sampling of directIrradiance: for
    /// the object's elements, and the change the object makes for elements whose shaft to a
    /// light meets its bounding sphere (rays traced twice only where the object blocks). From the
    /// next updateSolution() on, H_indirect(e) = H_e − H_e,emission + (T_e − T_e,emission)/ρ_e,
    /// T = the solver's previewRadiosity() (when the solver's previewObject() is `object`): the
    /// per-sample direct light shows the object's shadow, the buffer its reflected light; the
    /// H_direct estimate lights the fallback. Call while paused (or without workers). Returns
    /// the elements whose H_direct changed.
    std::vector<int> setPreview(int object, const Visibility& previewOnly = {});
    /// Back to the scene without a preview object (H_direct as before setPreview). During a
    /// drag (beginDrag) the origin's removal is then recomputed (refreshDirect({origin})).
    std::vector<int> clearPreview();
    /// Starts a drag (George et al.'s select): `origin`, the object version just removed from
    /// the scene, is previewed where it was, so nothing shown changes and H_direct(e) is not
    /// recomputed: it keeps the light with `origin` in place. Every later preview's change is
    /// estimated relative to it: the light `origin` blocked comes back and the preview's is
    /// taken away; for an emitting object its light moves (the lights of `origin` give way to
    /// the preview's, for the per-sample direct light and H_direct(e) alike). `originOnly`
    /// admits exactly `origin` (a RayTracer subset kept alive by the caller until endDrag or
    /// clearPreview), or is empty (a world filter). Call while paused, before setPreview.
    void beginDrag(int origin, const Visibility& originOnly = {});
    /// Ends a drag started with beginDrag (George et al.'s unselect): `added`, the preview
    /// version, is now alive in the scene. The change it and the origin make becomes part of
    /// H_direct(e) (estimated now, synchronously, with the preview's light sampling; no
    /// recomputation of the rest) and the preview ends. Returns the elements whose H_direct
    /// changed. Call while paused; the preview subset must still be alive.
    std::vector<int> endDrag(int added);
    /// backgroundPreview: when the workers have finished a queued H_direct estimate, applies
    /// it (the indirect snapshot is rebuilt from the last solution) and starts the estimate of
    /// a newer preview if one was set meanwhile; returns the elements whose H_direct changed
    /// (empty when nothing finished). Call from the thread that calls setPreview/updateSolution.
    std::vector<int> takeDirectUpdate();
    /// Takes `source`'s lights, H_direct, solution snapshot, preview and drag (same
    /// Discretization; `source` paused or on this thread); queues its own estimate when the
    /// source's is pending. Call while paused.
    void copyDirectFrom(const PointShader& source);

    // -- Parts -------------------------------------------------------------------------------

    struct Light;
    struct State;
    struct DirectJob;
    std::shared_ptr<const State> state() const;
    /// Makes `state` the one shading uses from now on, numbered by the next serial.
    void publish(std::shared_ptr<State> state);
    /// Σ_j E_j·F(e←j) with the solver's pair-seeded form factors, over `emitters` (the
    /// alive emitter patches, ascending: emitterPatches).
    Rgb computeElementDirect(int element, const std::vector<int>& emitters) const;
    ShadedPoint shadeWith(const State& state, const ShadeRequest& request) const;
    /// Nearest hit in the displayed world (the scene plus the preview object).
    RayHit traceWith(const State& state, const Vec3& origin, const Vec3& direction) const;
    /// Whether the preview object blocks the segment (false without a preview).
    bool previewBlocks(const State& state, const Vec3& from, const Vec3& to) const;
    /// H_direct at x from every light (stratified shadow rays); `exact` (optional) is set to
    /// whether every light's rays agreed, all blocked or none (ShadedPoint::exact).
    Rgb directWith(const State& state, const Vec3& x, const Vec3& n, int receiver,
                   std::uint64_t key, bool* exact = nullptr) const;
    /// The change of the direct estimate over `lights` that the objects `blocker` admits make
    /// (≤ 0: only rays they block and the scene, less `ignore`, does not count).
    Rgb blockedChange(const std::vector<Light>& lights, const Visibility& blocker, int ignore,
                      const Vec3& x, const Vec3& n, int receiver, std::uint64_t key) const;
    /// Direct irradiance from `lights` with the scene (less `ignore`) and `extra` blocking.
    Rgb emittedBy(const std::vector<Light>& lights, const Visibility& extra, int ignore,
                  const Vec3& x, const Vec3& n, int receiver, std::uint64_t key) const;
    /// The area lights of one object's emitting patches (alive or not), [] when it emits not.
    std::vector<Light> lightsOf(int object) const;
    /// Lights of every alive emitting object.
    std::vector<Light> aliveLights() const;
    /// The preview's H_direct estimate for the current state (relative to the drag origin),
    /// the scene's `ignore` version left out of the scene's rays.
    std::shared_ptr<DirectJob> makeDirectJob(int ignore) const;
    void runDirectChunk(DirectJob& job, std::size_t chunk) const;
    /// Applies a finished estimate; returns the elements whose H_direct changed.
    std::vector<int> applyDirectJob(const DirectJob& job);
    /// Queues makeDirectJob(-1) to the workers, or marks it wanted while one runs.
    void queueDirectJob();
    /// Drops the queued estimate (call while paused).
    void dropDirectJob();
    /// The indirect snapshot from mElementH and the stored preview buffer.
    void rebuildIndirect();
    // rebuildIndirect's steps, in its order: `indirect` is the new state's elementIndirect,
    // `n` the number of elements the solution covers (H_e and H_e,emission both known).
    /// H_direct(e) of the elements past the end of mElementDirect (newer than it).
    void computeMissingElementDirect();
    /// An object just dropped after a drag: until the solver's redistribution reaches its
    /// elements, the indirect part of its last preview buffer's irradiance stands in (the
    /// larger of the two), so it does not show lit by its direct light alone; forgotten once
    /// the solution's indirect light has caught up (nine tenths of the estimate's) or the
    /// object is gone.
    void holdDroppedEstimate(std::vector<Rgb>& indirect, std::size_t n);
    /// Adds the preview buffer's indirect irradiance (mLastPreviewIndirect) for preview
    /// version `preview`, moved with the object when the buffer is for an earlier version.
    void addPreviewBuffer(std::vector<Rgb>& indirect, int preview) const;
    /// Raises the preview object's elements to the drag's estimate (mDragEstimate).
    void applyDragEstimate(std::vector<Rgb>& indirect, int preview) const;
    /// The dragged object, and versions newer than the solution: their indirect light comes
    /// from an estimate (the buffer, a lagging buffer moved with the object) or not at all
    /// yet, and may be below 0 where the estimate's negative shots ran ahead of its positive
    /// ones: no indirect light there instead. Elsewhere the difference stays as it is,
    /// negative or not (the solution's negative energy in a new shadow), unless
    /// PointShaderOptions::clampIndirect.
    void clampEstimatedIndirect(std::vector<Rgb>& indirect, int preview, std::size_t n) const;
    /// The fallback's direct part: H_direct in the displayed world, blended per vertex again
    /// only for the objects whose elements' values changed since the last snapshot (the
    /// solution changes far more often than the direct light); and next.elementIndirect
    /// blended per vertex. Remembers the direct light blended in mVertexDirectOf.
    void blendVertexLight(State& next);
    /// Gives object version `to` the vertex light of version `from` in `st` when both have the
    /// same mesh and `to` has none yet.
    void carryVertexLight(State& st, int from, int to) const;
    /// At a drop (the preview cleared or ended): mDroppedIndirect from mDragEstimate, for the
    /// alive version of the same object; the estimate is used up.
    void rememberDropped();
    /// Takes preview version `object`'s part of mLastPreviewIndirect into mDragEstimate when
    /// it is at least as good an estimate (see mDragEstimate).
    void noteDragEstimate(int object, bool complete);
    void recordTriple(const ShadowTriple& t) const;
    void workerLoop();

    const Discretization& mDisc;
    const RayTracer& mTracer;
    SolverOptions mSolverOptions;
    PointShaderOptions mOptions;

    mutable std::mutex mStateMutex;
    std::shared_ptr<const State> mState;
    std::vector<Rgb> mElementDirect;     ///< H_direct(e); written only while paused/idle
    std::vector<Rgb> mElementH;          ///< the last solver snapshot's H_e
    std::vector<Rgb> mElementHEmission;  ///< and its H_e,emission
    /// Its preview buffer's indirect irradiance (T − T_emission)/ρ per element (empty: none).
    std::vector<Rgb> mLastPreviewIndirect;
    /// The per-element direct light the published vertexDirect blends (rebuildIndirect).
    std::vector<Rgb> mVertexDirectOf;
    /// An object just dropped after a drag (-1 none) and, per element of it, the indirect
    /// irradiance its last preview buffer estimated: shown until the solution catches up.
    int mDroppedObject = -1;
    std::vector<Rgb> mDroppedIndirect;
    /// While dragging, per element of the dragged mesh, the best estimate of its indirect
    /// irradiance so far, for version mDragEstimateObject (-1: none): the origin's solution at
    /// beginDrag, then each preview buffer that has reached the object (previewComplete, the
    /// same version again, or at least kDragEstimateShare of the estimate's light). A buffer
    /// for a new position starts empty and fills shooter by shooter; the moving object is
    /// shown with no less than the estimate meanwhile (rebuildIndirect), and the dropped
    /// object starts from it (rememberDropped), never from a buffer that has barely begun.
    std::vector<Rgb> mDragEstimate;
    int mDragEstimateObject = -1;
    static constexpr double kDragEstimateShare = 0.8;
    int mLastPreviewObject = -1;
    bool mHasSolution = false;
    /// Drag (beginDrag): the origin H_direct still includes, and a subset admitting it.
    int mDragOrigin = -1;
    Visibility mOriginOnly;
    /// Preview: H_direct in the preview world minus mElementDirect, nonzero only on the
    /// elements listed in mPreviewElements; written only while paused/idle.
    std::vector<Rgb> mPreviewDirectDelta;
    std::vector<int> mPreviewElements;
    /// The preview version the applied estimate (mPreviewDirectDelta) is of, -1 for none.
    int mPreviewDirectFor = -1;

    // Queues.
    mutable std::mutex mQueueMutex;
    std::condition_variable mWake;  ///< workers: requests, pause changes, stop
    std::condition_variable mIdle;  ///< waitIdle/pause: a batch finished
    std::deque<ShadeRequest> mRequests;
    std::vector<ShadedPoint> mResults;
    std::size_t mBusy = 0;  ///< requests taken by workers, not yet in mResults
    int mPauseCount = 0;
    int mActiveWorkers = 0;
    bool mStop = false;
    /// backgroundPreview: the H_direct estimate in progress (chunks handed out under
    /// mQueueMutex), and whether a newer preview wants one after it.
    std::shared_ptr<DirectJob> mJob;
    bool mJobWanted = false;
    std::vector<std::thread> mWorkers;

    // Triples.
    mutable tbb::concurrent_unordered_set<ShadowTriple, ShadowTripleHash> mTriples;
    mutable tbb::concurrent_queue<ShadowTriple> mNewTriples;
    mutable std::atomic<std::uint64_t> mShaded{0};
};

/// PointShader::snapshot's handle on a shading state.
class PointShader::Snapshot {
public:
    Snapshot() = default;
    bool empty() const { return !mState; }
    /// Its preview object, -1 for none (or an empty snapshot).
    int previewObject() const;

private:
    friend class PointShader;
    std::shared_ptr<const State> mState;
};

}  // namespace penumbra
