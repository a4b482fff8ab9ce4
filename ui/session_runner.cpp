// Index: DocumentSummary · construction and threads · queue and requests · the solver
//        iteration (edits, tasks, shots) · the render iteration · the holodeck · snapshots

#include "ui/session_runner.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <optional>
#include <stdexcept>

#ifdef __linux__
#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>
#endif

#include "core/log.h"
#include "render/camera_rays.h"
#include "render/exact_irradiance.h"
#include "render/holodeck/holo_view.h"
#include "solver/discretization.h"

namespace penumbra {

namespace {

double nowSeconds() {
    using namespace std::chrono;
    return duration<double>(steady_clock::now().time_since_epoch()).count();
}

/// Lowers the calling thread's scheduling priority (Linux nice increment): the solver, render
/// and shading threads yield the cores to the UI thread, so frames keep their rate on a loaded
/// machine while the lighting images follow.
void lowerThreadPriority(int nice) {
#ifdef __linux__
    if (nice <= 0) return;
    const auto tid = static_cast<id_t>(syscall(SYS_gettid));
    (void)setpriority(PRIO_PROCESS, tid, getpriority(PRIO_PROCESS, tid) + nice);
#else
    (void)nice;
#endif
}

/// While the first display is built: at most one Gouraud image of new lighting per this long.
constexpr double kLoadingImageMs = 250;

/// A new display's first frame waits at most this long for the holodeck's points of its view.
constexpr double kHolodeckWaitMs = 500;

bool sameCamera(const Camera& a, const Camera& b) {
    return a.position == b.position && a.lookAt == b.lookAt && a.up == b.up && a.fovDeg == b.fovDeg;
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// DocumentSummary.

const ObjectSummary* DocumentSummary::find(const std::string& id) const {
    for (const ObjectSummary& o : objects)
        if (o.id == id) return &o;
    return nullptr;
}

// ---------------------------------------------------------------------------------------------
// Construction and threads.

SessionRunner::SessionRunner(std::unique_ptr<EditSession> session, SessionRunnerOptions options)
    : mSession(std::move(session)),
      mOptions(options),
      mEps(options.convergeEps),
      mSolveEps(options.convergeEps) {
    if (!mSession) throw std::invalid_argument("SessionRunner: no session");
    mStrategy = mSession->solver().options().strategy;
    mThreshold = mSession->solver().options().redistributionThreshold;
    publishDocument();
    publishLight();
    publishSolver(0);
    if (mOptions.threaded) {
        // spdlog makes its registry at the first log call: here, not racing in two threads.
        (void)spdlog::default_logger_raw();
        mSolverThread = std::thread([this] { runSolver(); });
        mRenderThread = std::thread([this] { runRender(); });
    }
}

SessionRunner::~SessionRunner() {
    {
        std::lock_guard<std::mutex> lock(mQueueMutex);
        mStop = true;
    }
    mWake.notify_all();
    mRenderWake.notify_all();
    if (mSolverThread.joinable()) mSolverThread.join();
    if (mRenderThread.joinable()) mRenderThread.join();
    // A display or interpolants being built hold the structure: wait for them.
    if (mBuild.valid()) mBuild.wait();
    mHifiOutdated = true;
    if (mHifiBuild.valid()) mHifiBuild.wait();
    // The displays' shader workers may use the preview subset until they are joined.
    for (DisplaySlot& slot : mSlots) slot.display.reset();
    closeHolodeck();
}

void SessionRunner::runSolver() {
    lowerThreadPriority(mOptions.backgroundNice);
    for (;;) {
        const bool worked = solverIteration();
        std::unique_lock<std::mutex> lock(mQueueMutex);
        if (mStop) return;
        // Sleep when there is nothing to do, until an edit or a setting wakes us.
        if (!worked) mWake.wait_for(lock, std::chrono::milliseconds(50));
    }
}

void SessionRunner::runRender() {
    lowerThreadPriority(mOptions.backgroundNice);
    for (;;) {
        const bool rendered = renderIteration();
        std::unique_lock<std::mutex> lock(mQueueMutex);
        if (mStop) return;
        if (!rendered) mRenderWake.wait_for(lock, std::chrono::milliseconds(10));
    }
}

void SessionRunner::pump() {
    if (mOptions.threaded) throw std::logic_error("SessionRunner::pump: runner is threaded");
    solverIteration();
    renderIteration();
}

void SessionRunner::report(const std::string& message) {
    std::lock_guard<std::mutex> lock(mPublishMutex);
    mMessages.push_back(message);
}

// ---------------------------------------------------------------------------------------------
// Queue and requests.

void SessionRunner::submit(const EditCommand& command, const EditSource& source) {
    {
        std::lock_guard<std::mutex> lock(mQueueMutex);
        mQueue.push_back({command, source, {}, {}});
    }
    mWake.notify_all();
}

void SessionRunner::submitCoalescing(const EditCommand& command) {
    {
        std::lock_guard<std::mutex> lock(mQueueMutex);
        const auto* t = std::get_if<TransformCommand>(&command.op);
        const auto* last = mQueue.empty() || mQueue.back().task || mQueue.back().make
                               ? nullptr
                               : std::get_if<TransformCommand>(&mQueue.back().command.op);
        if (t && last && last->id == t->id)
            mQueue.back().command = command;
        else
            mQueue.push_back({command, EditSource{}, {}, {}});
    }
    mWake.notify_all();
}

void SessionRunner::post(std::function<void(EditSession&)> task) {
    {
        std::lock_guard<std::mutex> lock(mQueueMutex);
        // Tasks run in order with the edits.
        mQueue.push_back({EditCommand{}, EditSource{}, std::move(task), {}});
    }
    mWake.notify_all();
}

void SessionRunner::postSave(std::function<void(EditSession&)> task, bool holodeckScene) {
    {
        std::lock_guard<std::mutex> lock(mQueueMutex);
        mQueue.push_back({EditCommand{}, EditSource{}, std::move(task), {}, holodeckScene});
    }
    mWake.notify_all();
}

void SessionRunner::submitMade(std::function<EditCommand(EditSession&)> make) {
    {
        std::lock_guard<std::mutex> lock(mQueueMutex);
        mQueue.push_back({EditCommand{}, EditSource{}, {}, std::move(make)});
    }
    mWake.notify_all();
}

void SessionRunner::setView(const ViewRequest& request) {
    {
        std::lock_guard<std::mutex> lock(mQueueMutex);
        if (request.width == mView.width && request.height == mView.height &&
            request.highlight == mView.highlight && request.interactive == mView.interactive &&
            request.mode == mView.mode && request.referenceRequest == mView.referenceRequest &&
            sameCamera(request.camera, mView.camera))
            return;
        mView = request;
        mView.serial = ++mViewSerial;
    }
    mRenderWake.notify_all();
}

void SessionRunner::setPaused(bool paused) {
    {
        std::lock_guard<std::mutex> lock(mQueueMutex);
        mPaused = paused;
    }
    mWake.notify_all();
}

bool SessionRunner::paused() const {
    std::lock_guard<std::mutex> lock(mQueueMutex);
    return mPaused;
}

void SessionRunner::setAutoSolve(bool on) {
    {
        std::lock_guard<std::mutex> lock(mQueueMutex);
        mAutoSolve = on;
    }
    mWake.notify_all();
}

void SessionRunner::setConvergeEps(double eps) {
    {
        std::lock_guard<std::mutex> lock(mQueueMutex);
        if (eps > 0 && eps < 1) mEps = eps;
    }
    mWake.notify_all();
}

void SessionRunner::setStrategy(RedistributionStrategy strategy, double threshold) {
    if (!(threshold >= 0 && threshold <= 1))
        throw std::invalid_argument("redistribution threshold must be in [0, 1]");
    {
        std::lock_guard<std::mutex> lock(mQueueMutex);
        mStrategy = strategy;
        mThreshold = threshold;
        mStrategyChanged = true;
    }
    mWake.notify_all();
}

RedistributionStrategy SessionRunner::strategy() const {
    std::lock_guard<std::mutex> lock(mQueueMutex);
    return mStrategy;
}

double SessionRunner::redistributionThreshold() const {
    std::lock_guard<std::mutex> lock(mQueueMutex);
    return mThreshold;
}

Pick SessionRunner::pick(const Camera& camera, int width, int height, double px, double py) {
    std::shared_lock<std::shared_mutex> lock(mStructure);
    return pickObject(mSession->discretization(), mSession->tracer(), camera, width, height, px,
                      py);
}

std::size_t SessionRunner::queued() const {
    std::lock_guard<std::mutex> lock(mQueueMutex);
    return mQueue.size() + (mApplying ? 1 : 0);
}

// ---------------------------------------------------------------------------------------------
// The solver iteration.

bool SessionRunner::solverIteration() {
    SolverWork work;
    {
        std::lock_guard<std::mutex> lock(mQueueMutex);
        work.commands.swap(mQueue);
        mApplying = !work.commands.empty();
        work.solve = mAutoSolve && !mPaused;
        work.eps = mEps;
        mSolveEps = mEps;
        if (mStrategyChanged) work.strategy.emplace(mStrategy, mThreshold);
        mStrategyChanged = false;
    }
    // A strategy switch only reorders pending work: applied between shots, no structure lock
    // (the render thread never reads the solver's options).
    if (work.strategy) {
        try {
            mSession->solver().setStrategy(work.strategy->first, work.strategy->second);
        } catch (const std::exception& e) {
            report(std::string("strategy: ") + e.what());
        }
    }
    if (!work.commands.empty()) applyCommands(work.commands);

    const double t0 = nowSeconds();
    const std::uint64_t shots = shootForBudget(work.solve, work.eps, t0);
    const double solverMs = (nowSeconds() - t0) * 1e3;
    spdlog::debug("solver: {} edits, {} shots in {:.1f} ms", work.commands.size(), shots, solverMs);
    const bool holodeck = holodeckIteration();
    publishSolver(solverMs);
    {
        std::lock_guard<std::mutex> lock(mQueueMutex);
        mApplying = false;
    }
    if (!work.commands.empty() || shots > 0) mRenderWake.notify_all();
    return !work.commands.empty() || !mSolverIdle || holodeck;
}

void SessionRunner::applyCommands(std::deque<Queued>& commands) {
    const double a0 = nowSeconds();
    // An interpolant build holding the structure stops at its next element.
    ++mEditsWaiting;
    std::unique_lock<std::shared_mutex> lock(mStructure);
    --mEditsWaiting;
    // The display's asynchronous shader reads the structure: paused while it changes, and
    // told what changed before it resumes.
    std::unique_lock<std::mutex> displayLock(mDisplayMutex);
    std::optional<PointShader::Pause> pauses[2];
    for (int i = 0; i < 2; ++i)
        if (mSlots[i].display) pauses[i].emplace(mSlots[i].display->shader());
    const double a1 = nowSeconds();
    std::vector<EditEvent> events;
    bool structural = false;  // a task ran: it may have changed anything
    for (Queued& q : commands) {
        try {
            if (q.task) {
                q.task(*mSession);
                structural = true;
                if (q.savesHolodeckScene) holodeckSaved();
            } else if (q.make) {
                events.push_back(mSession->apply(q.make(*mSession), q.source));
            } else {
                events.push_back(mSession->apply(q.command, q.source));
            }
        } catch (const std::exception& e) {
            report(e.what());
        }
    }
    // The holodeck forgets what the edits changed once the solution converges again.
    for (const EditEvent& event : events)
        if (event.kind != EditEvent::Kind::Solved) mHoloDirty = mHoloUnsaved = true;
    // The interpolants' next build re-meshes what the edits changed (mDisplayMutex is held).
    for (const EditEvent& event : events)
        if (event.kind != EditEvent::Kind::Solved)
            for (int v : event.changed()) mHifiChanged.push_back(v);
    // The displays see a batch of drag positions as its last one.
    coalescePreviews(events);
    for (const EditEvent& event : events) applyDisplayEvent(event);
    if (structural) notifyStructuralChange();
    pruneSubsets();
    ++mEditBatches;
    for (auto& pause : pauses) pause.reset();
    displayLock.unlock();
    // The snapshots only read what this thread alone writes: outside the exclusive section.
    lock.unlock();
    publishDocument();
    publishLight();
    spdlog::debug("apply: waited {:.1f} ms, applied {} in {:.1f} ms", (a1 - a0) * 1e3,
                  commands.size(), (nowSeconds() - a1) * 1e3);
}

void SessionRunner::notifyStructuralChange() {
    for (int i = 0; i < 2; ++i) {
        DisplaySlot& slot = mSlots[i];
        if (!slot.display) continue;
        if (liveSlot(i) && !slot.behind) {
            try {
                slot.display->notifyChanged({}, &mSession->solver());
                slot.solution = mLightSerial + 1;  // publishLight follows the edits
            } catch (const std::exception& e) {
                report(std::string("display: ") + e.what());
            }
        } else {
            slot.behind = true;
            slot.pendingStructural = true;
        }
    }
}

void SessionRunner::pruneSubsets() {
    std::erase_if(mOldSubsets, [&](const VersionSubset& s) {
        for (const DisplaySlot& slot : mSlots)
            if (slot.display && slot.display->directJobPreview() == s.version) return false;
        return true;
    });
    std::erase_if(mOldOrigins, [&](const VersionSubset& s) {
        for (const DisplaySlot& slot : mSlots)
            if (slot.display &&
                (slot.display->dragOrigin() == s.version || slot.display->directJobPreview() >= 0))
                return false;
        return true;
    });
    // Objects that hide points behind them trace a subset of their own, not a filter over the
    // whole scene; kept while a display hides behind them.
    for (DisplaySlot& slot : mSlots) {
        if (!slot.display || !slot.display->occluderNeedsSubset()) continue;
        const int occluder = slot.display->occluder();
        auto it = std::find_if(mOccluderSubsets.begin(), mOccluderSubsets.end(),
                               [&](const VersionSubset& s) { return s.version == occluder; });
        if (it == mOccluderSubsets.end())
            it = mOccluderSubsets.insert(mOccluderSubsets.end(),
                                         VersionSubset(mSession->tracer(), occluder));
        slot.display->setOccluderSubset(occluder, it->visibility());
    }
    std::erase_if(mOccluderSubsets, [&](const VersionSubset& s) {
        for (const DisplaySlot& slot : mSlots)
            if (slot.display && slot.display->occluder() == s.version) return false;
        return true;
    });
    // The drag's origin subset lives while a display may still use it.
    if (mSession->previewVersion() < 0) {
        bool used = false;
        for (const DisplaySlot& slot : mSlots)
            used = used || (slot.display && slot.display->dragOrigin() >= 0);
        if (!used) mOriginSubset = VersionSubset();
    }
}

std::uint64_t SessionRunner::shootForBudget(bool solve, double eps, double t0) {
    // Shots, one at a time, for the budget. The sequence of shots depends only on the edits
    // between them, not on timing.
    double lastPublish = t0;
    std::uint64_t shots = 0;
    mSolverIdle = true;
    const bool dragging = !mSession->selected().empty();
    if (!solve || (!dragging && mSession->solver().converged(eps))) return 0;
    mSolverIdle = false;
    while (nowSeconds() - t0 < mOptions.solveBudgetMs * 1e-3) {
        const std::uint64_t n = mSession->solve(1);
        shots += n;
        const bool done = n == 0 || (!dragging && mSession->solver().converged(eps));
        if (done) mSolverIdle = true;
        // Show progress of long shots as it comes.
        if (done || nowSeconds() - lastPublish > 0.03) {
            if (n > 0) publishLight();
            lastPublish = nowSeconds();
        }
        if (done) break;
    }
    if (shots > 0 && lastPublish < nowSeconds() - 1e-9) publishLight();
    return shots;
}

// ---------------------------------------------------------------------------------------------
// The render iteration.

bool SessionRunner::renderIteration() {
    ViewRequest view;
    {
        std::lock_guard<std::mutex> lock(mQueueMutex);
        view = mView;
    }
    if (view.width <= 0 || view.height <= 0) return false;
    std::shared_lock<std::shared_mutex> structure(mStructure);
    Light light;
    std::shared_ptr<const ViewportImage> last;
    std::shared_ptr<const DocumentSummary> doc;
    std::string dragged;
    bool solverIdle = false;
    {
        std::lock_guard<std::mutex> lock(mPublishMutex);
        light = mLight;
        last = mImage;
        doc = mDocument;
        dragged = mSolver.selected;
        solverIdle = mSolver.idle;
    }
    // The dragged object's transform in the state rendered (the structure is held shared).
    mRenderDragged = mSession->selected();
    if (!mRenderDragged.empty())
        for (const SceneObject& o : mSession->scene().objects)
            if (o.id == mRenderDragged) mRenderDraggedTransform = o.transform;
    int highlight = -1;
    if (const ObjectSummary* o = doc ? doc->find(view.highlight) : nullptr) highlight = o->version;
    // The dragged object is seen as its preview version.
    if (light.previewVersion >= 0 && !dragged.empty() && dragged == view.highlight)
        highlight = light.previewVersion;
    // The display modes show Gouraud until their display lands (built in the background).
    bool loading = false;
    if (usesInteractiveDisplay(view.mode)) {
        if (displayLanded(view)) return renderDisplay(view, light, last, highlight, structure);
        loading = true;
    }
    // The interpolant mode shows Gouraud until its mesh of this lighting lands.
    TracedView traced;
    traced.loading = loading;
    if (view.mode == ViewMode::Interpolant) {
        const bool still = solverIdle && dragged.empty() && light.previewVersion < 0;
        traced.hifi = hifiLanded(view, light, still, traced.hifiNote);
        traced.loading = traced.hifi == nullptr;
    }
    return renderTracedView(view, light, last, highlight, traced);
}

bool SessionRunner::renderTracedView(const ViewRequest& view, const Light& light,
                                     const std::shared_ptr<const ViewportImage>& last,
                                     int highlight, const TracedView& traced) {
    const bool loading = traced.loading;
    const bool need = !last || last->stateSerial != light.serial ||
                      last->viewSerial != view.serial || (last->reduced && !view.interactive) ||
                      (!loading && last->mode != view.mode) ||
                      (view.mode == ViewMode::Interpolant && last->note != traced.hifiNote);
    if (!need || !light.radiosity) return false;
    // While the display is built, new lighting is shown at most every loadingImageMs (the
    // cores go to the build); view changes at once.
    if (loading && last && last->viewSerial == view.serial &&
        !(last->reduced && !view.interactive) &&
        nowSeconds() - mLastLoadingImage < kLoadingImageMs * 1e-3 &&
        (view.mode != ViewMode::Interpolant || last->stateSerial == light.serial))
        return false;
    if (loading) mLastLoadingImage = nowSeconds();

    const int d = reducedDivisor(view);
    const int w = std::max(1, view.width / d), h = std::max(1, view.height / d);
    const auto radiosity = coverElements(light.radiosity, light.previewVersion);
    if (!radiosity) return false;
    const auto pendingValues = coverElements(light.pending, light.previewVersion);

    auto img = std::make_shared<ViewportImage>();
    const double r0 = nowSeconds();
    if (!traceImage(view, light, w, h, highlight, traced.hifi, *radiosity, pendingValues.get(),
                    *img))
        return false;
    img->renderMs = (nowSeconds() - r0) * 1e3;
    spdlog::debug("render {}x{} {:.1f} ms light {}", w, h, img->renderMs, light.serial);
    const double perPixel = img->renderMs / (double(w) * h);
    mMsPerPixel = mMsPerPixel > 0 ? 0.7 * mMsPerPixel + 0.3 * perPixel : perPixel;
    img->camera = view.camera;
    img->viewSerial = view.serial;
    img->stateSerial = light.serial;
    img->reduced = d > 1;
    img->mode = loading ? ViewMode::Gouraud : view.mode;
    if (view.mode == ViewMode::Interpolant)
        img->note = traced.hifiNote;
    else if (loading)
        img->note = std::string(viewModeLabel(view.mode)) + " display loading: Gouraud meanwhile";
    img->previewVersion = light.previewVersion;
    img->dragged = mRenderDragged;
    img->draggedTransform = mRenderDraggedTransform;
    std::lock_guard<std::mutex> lock(mPublishMutex);
    mImage = std::move(img);
    return true;
}

int SessionRunner::reducedDivisor(const ViewRequest& view) const {
    if (!view.interactive) return 1;
    int d = 2;
    if (mMsPerPixel > 0) {
        const double pixels = mOptions.interactiveImageMs / mMsPerPixel;
        d = static_cast<int>(std::ceil(std::sqrt(double(view.width) * view.height / pixels)));
    }
    return std::clamp(d, 1, std::max(1, mOptions.maxReducedDivisor));
}

std::shared_ptr<const std::vector<Rgb>> SessionRunner::coverElements(
    const std::shared_ptr<const std::vector<Rgb>>& values, int previewVersion) const {
    const Discretization& disc = mSession->discretization();
    const std::size_t n = disc.elements().size();
    if (!values || values->size() >= n) return values;
    for (std::size_t e = values->size(); e < n; ++e) {
        const int o = disc.elements()[e].object;
        if (disc.objects()[o].alive || o == previewVersion) return nullptr;
    }
    auto padded = std::make_shared<std::vector<Rgb>>(*values);
    padded->resize(n, Rgb(0.0));
    return padded;
}

bool SessionRunner::traceImage(const ViewRequest& view, const Light& light, int w, int h,
                               int highlight, const HifiMesh* hifi,
                               const std::vector<Rgb>& radiosity, const std::vector<Rgb>* pending,
                               ViewportImage& img) {
    const Discretization& disc = mSession->discretization();
    try {
        img.render = renderViewport(disc, mSession->tracer(), radiosity, view.camera, w, h,
                                    light.previewVersion, highlight);
        if (view.mode == ViewMode::OutOfDate && pending) {
            // The pending |ΔB| interpolated like the image, as a red tint.
            const ViewportRender tint = renderViewport(disc, mSession->tracer(), *pending,
                                                       view.camera, w, h, light.previewVersion);
            tintPending(img.render.rgba, tint.radiance, light.pendingScale / M_PI);
            img.note = "red: pending unshot / redistribution |dB| (full at 5% of mean B)";
        }
        if (hifi) {
            // One ray per pixel finds the triangle whose interpolant it shows (the editor's GL
            // context belongs to the UI thread); the outline over it as over Gouraud.
            img.render.radiance =
                renderInterpolants(disc, mSession->tracer(), *hifi, CameraRays(view.camera, w, h));
            img.render.rgba = encodeDisplay(img.render.radiance);
            if (highlight >= 0)
                drawSelectionOutline(img.render.rgba, img.render.objectAt, w, h, highlight);
        }
    } catch (const std::exception& e) {
        report(std::string("viewport: ") + e.what());
        return false;
    }
    return true;
}

// ---------------------------------------------------------------------------------------------
// The interpolant mode.

const HifiMesh* SessionRunner::hifiLanded(const ViewRequest& view, const Light& light, bool still,
                                          std::string& note) {
    if (mHifiBuild.valid() &&
        mHifiBuild.wait_for(std::chrono::seconds(0)) == std::future_status::ready) {
        std::unique_ptr<HifiMesh> built = mHifiBuild.get();
        if (built && mHifiBuildSerial == light.serial) {
            landHifi(std::move(built), light.serial, mHifiBuildRadiosity);
            spdlog::debug("interpolants: {} triangles, {} elements meshed in {:.1f} s (light {})",
                          mHifi->stats().triangles, mHifi->stats().remeshed,
                          mHifi->stats().seconds, light.serial);
        } else {
            spdlog::debug("interpolants: build for light {} dropped (light {} now)",
                          mHifiBuildSerial, light.serial);
        }
    }
    auto shown = [&] {
        char text[160];
        std::snprintf(text, sizeof text,
                      "interpolants: %d triangles, %d of %d elements meshed in %.1f s",
                      mHifi->stats().triangles, mHifi->stats().remeshed, mHifi->stats().elements,
                      mHifi->stats().seconds);
        note = text;
        return mHifi.get();
    };
    if (mHifi && mHifiSerial == light.serial) return shown();
    if (mHifiBuild.valid()) {
        if (mHifiBuildSerial != light.serial) mHifiOutdated = true;  // stops at its next element
        char text[160];
        std::snprintf(text, sizeof text, "interpolants: building %.0f%% (Gouraud meanwhile)",
                      100 * mHifiProgress.load());
        note = text;
        return nullptr;
    }
    if (!still || view.interactive || !light.radiosity) {
        note = "interpolants: built when the lighting and the view are still (Gouraud meanwhile)";
        return nullptr;
    }
    mHifiBuildSerial = light.serial;
    mHifiBuildRadiosity = light.radiosity;
    mHifiProgress = 0;
    mHifiOutdated = false;
    note = "interpolants: building 0% (Gouraud meanwhile)";
    HifiBase base = hifiBase();
    mHifiBuildChanges = base.changed.size();
    if (!mOptions.threaded) {
        // renderIteration already holds the structure shared.
        std::unique_ptr<HifiMesh> built = buildHifiHeld(light.radiosity, base);
        if (!built) return nullptr;
        landHifi(std::move(built), light.serial, light.radiosity);
        return shown();
    }
    mHifiBuild = std::async(std::launch::async,
                            [this, radiosity = light.radiosity, base = std::move(base)] {
                                lowerThreadPriority(mOptions.backgroundNice);
                                return buildHifi(radiosity, base);
                            });
    return nullptr;
}

SessionRunner::HifiBase SessionRunner::hifiBase() {
    HifiBase base;
    if (!mHifi || !mHifiRadiosity) return base;  // nothing shown yet: a full build
    base.mesh = mHifi;
    base.radiosity = mHifiRadiosity;
    std::lock_guard<std::mutex> lock(mDisplayMutex);
    base.changed = mHifiChanged;
    return base;
}

void SessionRunner::landHifi(std::unique_ptr<HifiMesh> mesh, std::uint64_t serial,
                             std::shared_ptr<const std::vector<Rgb>> radiosity) {
    mHifi = std::move(mesh);
    mHifiSerial = serial;
    mHifiRadiosity = std::move(radiosity);
    // The edits the build took in are in the mesh now; later ones wait for the next build.
    std::lock_guard<std::mutex> lock(mDisplayMutex);
    mHifiChanged.erase(mHifiChanged.begin(),
                       mHifiChanged.begin() +
                           std::ptrdiff_t(std::min(mHifiBuildChanges, mHifiChanged.size())));
}

std::unique_ptr<HifiMesh> SessionRunner::buildHifi(
    std::shared_ptr<const std::vector<Rgb>> radiosity, HifiBase base) {
    std::shared_lock<std::shared_mutex> structure(mStructure);
    return buildHifiHeld(std::move(radiosity), base);
}

std::unique_ptr<HifiMesh> SessionRunner::buildHifiHeld(
    std::shared_ptr<const std::vector<Rgb>> radiosity, const HifiBase& base) {
    const Discretization& disc = mSession->discretization();
    if (radiosity->size() != disc.elements().size()) return nullptr;
    try {
        ExactIrradiance exact(disc,
                              ExactIrradianceOptions::forInterpolants(mOptions.hifiGatherRays),
                              &mSession->tracer());
        exact.setReflected(reflectedRadiosity(disc, *radiosity));
        HifiOptions options;
        options.cancelled = [this] { return mEditsWaiting.load() > 0 || mHifiOutdated.load(); };
        auto progress = [this](double f) { mHifiProgress = f; };
        std::unique_ptr<HifiMesh> mesh;
        if (base.mesh) {
            // Only what the edits and the new lighting changed (HifiMesh::update).
            mesh = std::make_unique<HifiMesh>(*base.mesh);
            mesh->update(disc, exact,
                         hifiRemeshElements(disc, *base.radiosity, *radiosity, base.changed),
                         options, progress);
        } else {
            mesh = std::make_unique<HifiMesh>();
            mesh->build(disc, exact, options, progress);
        }
        if (mesh->stats().cancelled) return nullptr;
        return mesh;
    } catch (const std::exception& e) {
        report(std::string("interpolants: ") + e.what());
        return nullptr;
    }
}

// ---------------------------------------------------------------------------------------------
// The display modes.

void SessionRunner::applyDisplayEvent(const EditEvent& event) {
    using Kind = EditEvent::Kind;
    if (event.kind == Kind::Solved) return;
    // The subsets first: the drag's origin alone from its start; the preview alone whenever
    // another version is previewed (the old one kept while a background estimate traces it).
    if (event.kind == Kind::DragBegan) {
        // A display that missed the last drag's end may still estimate against its origin.
        if (mOriginSubset.version >= 0) mOldOrigins.push_back(std::move(mOriginSubset));
        mOriginSubset = VersionSubset(mSession->tracer(), event.origin);
    }
    if (event.preview != mPreviewSubset.version) {
        if (mPreviewSubset.version >= 0) mOldSubsets.push_back(std::move(mPreviewSubset));
        mPreviewSubset =
            event.preview >= 0 ? VersionSubset(mSession->tracer(), event.preview) : VersionSubset();
    }
    const InteractiveDisplay::DragVisibility drag{mOriginSubset.visibility(),
                                                  mPreviewSubset.visibility()};
    // Changes of the solution take the solver's snapshot at once; a preview's buffer comes
    // with the light published next (the render thread), so a drag position costs no copy.
    const bool solution = event.kind == Kind::Changed || event.kind == Kind::DragEnded;
    const ProgressiveSolver* solver = solution ? &mSession->solver() : nullptr;
    for (int i = 0; i < 2; ++i) {
        DisplaySlot& slot = mSlots[i];
        if (!slot.display) continue;
        if (!liveSlot(i) || slot.behind) {
            // Caught up before it is shown (catchUpDisplay).
            slot.behind = true;
            const std::vector<int> changed = event.changed();
            slot.pendingChanged.insert(slot.pendingChanged.end(), changed.begin(), changed.end());
            continue;
        }
        InteractiveDisplay& d = *slot.display;
        try {
            const double t0 = nowSeconds();
            const std::size_t points = d.apply(event, drag, solver);
            if (solution) slot.solution = mLightSerial + 1;  // publishLight follows the edits
            spdlog::debug("display {}x{}: {} in {:.1f} ms, {} points", d.width(), d.height(),
                          event.toString(), (nowSeconds() - t0) * 1e3, points);
        } catch (const std::exception& e) {
            report(std::string("display: ") + e.what());
        }
    }
}

void SessionRunner::catchUpDisplay(DisplaySlot& slot, const Light& light) {
    InteractiveDisplay& d = *slot.display;
    const double t0 = nowSeconds();
    const std::size_t missed = slot.pendingChanged.size();
    try {
        DisplaySlot& other = mSlots[&slot == &mSlots[0] ? 1 : 0];
        if (slot.behind && other.display && !other.behind && other.solution != 0) {
            // Take the other display's state: it saw every edit (nothing recomputed).
            PointShader::Pause pause(d.shader());
            PointShader::Pause otherPause(other.display->shader());
            std::vector<int>& changed = slot.pendingChanged;
            std::sort(changed.begin(), changed.end());
            changed.erase(std::unique(changed.begin(), changed.end()), changed.end());
            d.catchUpFrom(*other.display, changed);
            slot.solution = other.solution;
            slot.pendingChanged.clear();
            slot.pendingStructural = false;
            slot.behind = false;
        } else if (slot.behind) {
            PointShader::Pause pause(d.shader());
            // Its preview subset may have been released: leave the preview first.
            d.clearPreview();
            std::vector<int>& changed = slot.pendingChanged;
            std::sort(changed.begin(), changed.end());
            changed.erase(std::unique(changed.begin(), changed.end()), changed.end());
            if (!changed.empty() || slot.pendingStructural) d.notifyChanged(changed);
            const int preview = mSession->previewVersion();
            if (preview >= 0) d.setPreview(preview, mPreviewSubset.visibility());
            slot.pendingChanged.clear();
            slot.pendingStructural = false;
            slot.behind = false;
        }
        if (light.irradiance && slot.solution != light.serial) {
            d.updateSolution(*light.irradiance, *light.fromEmission, light.previewBuffer.get(),
                             light.previewFromEmission.get(), light.previewVersion,
                             light.previewComplete);
            slot.solution = light.serial;
            // Points requested from the next frame on are shaded from this light.
            if (light.converged) {
                slot.convergedLight = light.serial;
                slot.convergedFrame = d.cache().frame() + 1;
            }
        }
    } catch (const std::exception& e) {
        report(std::string("display: ") + e.what());
    }
    if (missed > 0)
        spdlog::debug("display {}x{}: caught up ({} changed objects) in {:.1f} ms", d.width(),
                      d.height(), missed, (nowSeconds() - t0) * 1e3);
}

InteractiveDisplayOptions SessionRunner::displayOptions(int slot, const ViewRequest& view) const {
    int d = std::max(1, mOptions.displayDivisor);
    if (slot == 1) {
        int r = mOptions.interactiveDisplayDivisor;
        if (r <= 0) {
            r = 2;
            if (mSlots[0].frameMs > 0)
                r = static_cast<int>(
                    std::ceil(std::sqrt(mSlots[0].frameMs / mOptions.interactiveImageMs)));
            r = std::clamp(r, 2, std::max(2, mOptions.maxReducedDivisor));
        }
        d *= r;
    }
    InteractiveDisplayOptions options;
    options.width = std::max(4, view.width / d / 4 * 4);
    options.height = std::max(4, view.height / d / 4 * 4);
    options.synchronous = false;
    // Drag positions: the preview's direct light is estimated on the shader's workers, not in
    // the edit's exclusive section.
    options.shader.backgroundPreview = true;
    options.shader.workerNice = mOptions.threaded ? mOptions.backgroundNice : 0;
    // Edits come while the solver redistributes: no dark patches where its H lags.
    options.shader.clampIndirect = true;
    // After an edit or a drop, what changed is re-shaded at up to five times the base rate:
    // the shader's workers have the capacity, and at the base rate the old and new shadows of
    // a moved table take seconds to re-shade.
    options.changedSampleFraction = 0.08;
    if (slot == 1) {
        // Interaction: shadow edges are not worth their cost (tens of thousands of them in
        // robot-room, recomputed at every drag position); a few more samples per (smaller)
        // frame.
        options.shadowEdges = false;
        options.sampleFraction = 0.04;
    }
    return options;
}

bool SessionRunner::displayLanded(const ViewRequest& view) {
    std::lock_guard<std::mutex> displayLock(mDisplayMutex);
    if (mSlots[0].display || mSlots[1].display) return true;
    if (!mOptions.threaded) return true;  // renderDisplay builds it in place
    if (!mBuild.valid()) {
        // The first display takes seconds to build (edge trees, every element's direct light):
        // on a thread of its own, with the structure held shared, the Gouraud view meanwhile.
        const InteractiveDisplayOptions options = displayOptions(0, view);
        const Camera camera = view.camera;
        const int viewWidth = view.width, viewHeight = view.height;
        // The holodeck's points of the view are read meanwhile (solver thread).
        DisplaySlot& first = mSlots[0];
        requestHolodeckPoints(first, camera, options.width, options.height);
        mBuildHoloRead = first.holoRead;
        // Not niced: the user waits for it.
        mBuild = std::async(std::launch::async, [this, options, camera, viewWidth, viewHeight] {
            BuiltDisplay built;
            std::shared_lock<std::shared_mutex> structure(mStructure);
            const double t0 = nowSeconds();
            built.edits = mEditBatches;
            built.viewWidth = viewWidth;
            built.viewHeight = viewHeight;
            try {
                built.display = std::make_unique<InteractiveDisplay>(
                    mSession->discretization(), mSession->tracer(), interactiveSolverOptions(),
                    options);
                const int preview = mSession->previewVersion();
                if (preview >= 0) built.display->setPreview(preview, mPreviewSubset.visibility());
                built.display->warmUp(CameraRays(camera, options.width, options.height));
            } catch (const std::exception& e) {
                built.display.reset();
                report(std::string("display: ") + e.what());
            }
            spdlog::debug("display {}x{}: built in the background in {:.1f} ms", options.width,
                          options.height, (nowSeconds() - t0) * 1e3);
            return built;
        });
        return false;
    }
    if (mBuild.wait_for(std::chrono::seconds(0)) != std::future_status::ready) return false;
    BuiltDisplay built = mBuild.get();
    // Edits since it started, or another viewport size: build again.
    if (!built.display || built.edits != mEditBatches || built.viewWidth != view.width ||
        built.viewHeight != view.height)
        return false;
    DisplaySlot& slot = mSlots[0];
    slot.display = std::move(built.display);
    slot.viewWidth = view.width;
    slot.viewHeight = view.height;
    slot.behind = false;
    slot.pendingChanged.clear();
    slot.pendingStructural = false;
    slot.solution = 0;
    slot.frameMs = 0;
    slot.frames = 0;
    requestHolodeckPoints(slot, view.camera, slot.display->width(), slot.display->height(),
                          mBuildHoloRead);
    return true;
}

bool SessionRunner::renderDisplay(const ViewRequest& view, const Light& light,
                                  const std::shared_ptr<const ViewportImage>& last, int highlight,
                                  std::shared_lock<std::shared_mutex>& structure) {
    // Frames run continuously (the cache keeps improving), at most one per displayFrameMs.
    const double now = nowSeconds();
    if (now - mLastDisplayFrame < mOptions.displayFrameMs * 1e-3) return false;
    mLastDisplayFrame = now;
    auto img = std::make_shared<ViewportImage>();
    std::unique_lock<std::mutex> displayLock(mDisplayMutex);
    // Interactive views (camera moves, drags) render a second, smaller display, and the full
    // one again when the interaction stops; each switch waits until the other display is up
    // to date (the solver thread catches it up between shots).
    const bool reduce = mOptions.interactiveDisplayDivisor != 1;
    const int want = reduce && view.interactive ? 1 : 0;
    mWantedSlot = want;
    for (DisplaySlot& slot : mSlots)
        if (slot.display && (slot.viewWidth != view.width || slot.viewHeight != view.height))
            slot.display.reset();
    // The reduced display is made ahead of time, from the full one once it has its solution
    // and a few frames (its frame time sets the reduction): a drag starts on it at once.
    const bool early = reduce && want == 0 && !mSlots[1].display && mSlots[0].display &&
                       mSlots[0].ready() && mActiveSlot == 0 && mSlots[0].frames >= 4;
    for (int make : {want, early ? 1 : -1})
        if (make >= 0 && !mSlots[make].display && !makeDisplay(make, view)) return false;
    DisplaySlot& wanted = mSlots[want];
    // Solutions and missed edits, from the published light (structure held shared).
    for (int i = 0; i < 2; ++i)
        if (mSlots[i].display && liveSlot(i)) catchUpDisplay(mSlots[i], light);
    // Switch when the wanted display has the solution and every edit, or when the shown one
    // is gone.
    if (mActiveSlot != want && (wanted.ready() || !mSlots[mActiveSlot].display)) {
        if (mSlots[mActiveSlot].display) mSlots[mActiveSlot].display->shader().cancelPending();
        mActiveSlot = want;
    }
    DisplaySlot& slot = mSlots[mActiveSlot];
    // A new display's first frame starts from the holodeck's points of its view.
    if (!takeHolodeckPoints(slot)) return false;
    InteractiveDisplay* display = slot.display.get();
    const int w = display->width(), h = display->height();
    const CameraRays rays(view.camera, w, h);
    int shownPreview = -1;
    try {
        const double r0 = nowSeconds();
        // The frame in its steps: edits wait for the first (points, edges), not for the
        // reconstruction, which touches only the display's edge-and-point image.
        display->beginFrame(rays, view.mode != ViewMode::Cache);
        shownPreview = display->previewVersion();
        // The selection outline of the state the frame shows (the preview version while
        // dragged; it is in the display only through the preview subset), drawn after encoding.
        std::vector<int> objectAt;
        if (highlight >= 0 && view.mode != ViewMode::Difference)
            objectAt =
                selectionPixels(mSession->discretization(), mSession->tracer(), view.camera, w, h,
                                highlight, mSession->previewVersion(), mPreviewSubset.visibility());
        displayLock.unlock();
        structure.unlock();
        try {
            img->render.radiance = display->reconstructFrame();
        } catch (...) {
            structure.lock();
            displayLock.lock();
            throw;
        }
        structure.lock();
        displayLock.lock();
        display->finishFrame(rays, img->render.radiance);
        img->display = display->lastFrame();
        img->render.rgba = encodeDisplay(img->render.radiance);
        if (!objectAt.empty()) drawSelectionOutline(img->render.rgba, objectAt, w, h, highlight);
        overlayDisplayMode(view, light, slot, *img);
        img->renderMs = (nowSeconds() - r0) * 1e3;
        slot.frameMs = slot.frameMs > 0 ? 0.7 * slot.frameMs + 0.3 * img->renderMs : img->renderMs;
        ++slot.frames;
    } catch (const std::exception& e) {
        report(std::string("display: ") + e.what());
        return false;
    }
    img->reduced = mActiveSlot == 1;
    if (spdlog::should_log(spdlog::level::debug))
        spdlog::debug("display {}x{} {:.1f} ms {}", w, h, img->renderMs, img->display.toString());
    img->camera = view.camera;
    img->viewSerial = view.serial;
    img->stateSerial = light.serial;
    img->mode = view.mode;
    img->previewVersion = shownPreview;
    img->dragged = mRenderDragged;
    img->draggedTransform = mRenderDraggedTransform;
    img->settledFrames = last && last->mode == view.mode && last->viewSerial == view.serial &&
                                 last->stateSerial == light.serial
                             ? last->settledFrames + 1
                             : 0;
    img->holodeckPoints = slot.holoPoints;
    if (mActiveSlot == 0) handHolodeckPoints(view, light, slot, img->settledFrames, rays);
    std::lock_guard<std::mutex> lock(mPublishMutex);
    mImage = std::move(img);
    return true;
}

bool SessionRunner::makeDisplay(int make, const ViewRequest& view) {
    DisplaySlot& wanted = mSlots[make];
    DisplaySlot& source = mSlots[1 - make];
    const bool copy = source.display && !source.behind && source.solution != 0;
    try {
        const InteractiveDisplayOptions options = displayOptions(make, view);
        const int w = options.width, h = options.height;
        const double t0 = nowSeconds();
        if (copy) {
            // Copies the other display's edge finder, lights, direct light, solution and
            // preview (milliseconds; built from scratch it takes seconds in robot-room).
            PointShader::Pause pause(source.display->shader());
            wanted.display = std::make_unique<InteractiveDisplay>(*source.display, options);
            wanted.solution = source.solution;
        } else {
            wanted.display =
                std::make_unique<InteractiveDisplay>(mSession->discretization(), mSession->tracer(),
                                                     interactiveSolverOptions(), options);
            wanted.solution = 0;
            // A drag in progress: the preview version and its subset are current (the solver
            // thread changes them only with the structure held exclusively).
            const int preview = mSession->previewVersion();
            if (preview >= 0) wanted.display->setPreview(preview, mPreviewSubset.visibility());
        }
        wanted.viewWidth = view.width;
        wanted.viewHeight = view.height;
        wanted.behind = false;
        wanted.pendingChanged.clear();
        wanted.pendingStructural = false;
        wanted.frameMs = 0;
        wanted.frames = 0;
        wanted.display->warmUp(CameraRays(view.camera, w, h));
        if (make == 0) requestHolodeckPoints(wanted, view.camera, w, h);
        spdlog::debug("display {}x{}: made ({}) in {:.1f} ms", w, h, copy ? "copy" : "built",
                      (nowSeconds() - t0) * 1e3);
    } catch (const std::exception& e) {
        wanted.display.reset();
        report(std::string("display: ") + e.what());
        return false;
    }
    return true;
}

void SessionRunner::overlayDisplayMode(const ViewRequest& view, const Light& light,
                                       DisplaySlot& slot, ViewportImage& img) {
    InteractiveDisplay* display = slot.display.get();
    const int w = display->width(), h = display->height();
    if (view.mode == ViewMode::EdgesOverlay) {
        blendEdges(img.render.rgba, display->edgeImage());
    } else if (view.mode == ViewMode::SamplesOverlay) {
        // This frame's new samples (age 0 after insertion) as dots.
        std::vector<std::uint8_t> flags(static_cast<std::size_t>(w) * h, 0);
        for (const ScreenPoint& p : display->cache().screenPoints()) {
            const int x = static_cast<int>(p.position.x), y = static_cast<int>(p.position.y);
            if (p.age == 0 && x >= 0 && y >= 0 && x < w && y < h)
                flags[static_cast<std::size_t>(y) * w + x] = 1;
        }
        markSamples(img.render.rgba, flags);
        img.note = std::to_string(img.display.newSamples) + " new samples";
    } else if (view.mode == ViewMode::Difference) {
        const int f = std::max(1, mOptions.referenceDivisor);
        const bool sized = w % f == 0 && h % f == 0;
        // The reference shows the display's current solution: wait until the solver is idle
        // and the display has its last published solution.
        bool solverIdle;
        {
            std::lock_guard<std::mutex> lock(mPublishMutex);
            solverIdle = mSolver.idle;
        }
        const bool waiting = view.referenceRequest != mReferenceDone;
        if (waiting && sized && solverIdle && slot.ready() && slot.solution == light.serial) {
            const CameraRays low(view.camera, w / f, h / f);
            mReference = display->renderReference(low, 2);
            mReferenceCamera = view.camera;
            mReferenceDone = view.referenceRequest;
        }
        if (mReference.width * f == w && mReference.height * f == h &&
            sameCamera(mReferenceCamera, view.camera)) {
            img.render.rgba =
                differenceImage(img.render.radiance, mReference, 0.1, &img.meanDifference);
            img.note = "false colour |epi - reference| sRGB, red at 0.1";
        } else {
            img.note = waiting ? "reference waits for the solver to settle"
                               : "no reference for this view: View > Compute reference";
        }
    }
}

// ---------------------------------------------------------------------------------------------
// The holodeck.

std::string HolodeckStatus::toString() const {
    if (path.empty()) return "";
    if (!open) return error.empty() ? "holodeck: opening" : "holodeck: not used";
    auto count = [](std::int64_t n) {
        char text[32];
        if (n >= 10000000)
            std::snprintf(text, sizeof text, "%.0fM", n * 1e-6);
        else if (n >= 1000000)
            std::snprintf(text, sizeof text, "%.1fM", n * 1e-6);
        else if (n >= 1000)
            std::snprintf(text, sizeof text, "%.0fk", n * 1e-3);
        else
            std::snprintf(text, sizeof text, "%lld", static_cast<long long>(n));
        return std::string(text);
    };
    std::string text = "holodeck: " + count(samples) + " samples";
    if (served > 0) text += ", " + count(served) + " shown";
    if (stored > 0) text += ", " + count(stored) + " stored";
    if (invalidated > 0) text += ", " + count(invalidated) + " forgotten";
    return text;
}

void SessionRunner::openHolodeck() {
    mHoloTried = true;
    mHoloStatus.path = mOptions.holodeck;
    try {
        // A new file gets the scene's sections; an existing one keeps its own.
        mHoloFile.emplace(mOptions.holodeck, holodeckSections(mSession->scene().settings,
                                                              mSession->discretization()));
        mHoloServer = std::make_unique<HoloServer>(*mHoloFile, nullptr);
        mHoloStatus.open = true;
        mHoloStatus.samples = mHoloFile->info().samples;
        spdlog::debug("holodeck {}: {} samples", mOptions.holodeck, mHoloStatus.samples);
    } catch (const std::exception& e) {
        // A bad cache is no reason not to edit the scene.
        mHoloServer.reset();
        mHoloFile.reset();
        mHoloStatus.error = e.what();
        // One warning line; the status line says "holodeck: not used".
        spdlog::warn("holodeck not used: {}", e.what());
    }
}

bool SessionRunner::holodeckIteration() {
    if (mOptions.holodeck.empty()) return false;
    if (!mHoloTried) openHolodeck();
    std::optional<HoloRead> read;
    std::vector<HoloStore> stores;
    {
        std::lock_guard<std::mutex> lock(mQueueMutex);
        read.swap(mHoloRead);
        stores.swap(mHoloStores);
    }
    bool worked = read.has_value() || !stores.empty();
    const bool converged = mSession->selected().empty() && mSession->previewVersion() < 0 &&
                           mSession->solver().converged(mSolveEps);
    if (mHoloServer && converged) {
        if (mHoloDirty) {
            // Without the light of the solution the holodeck matched, or when the scene file
            // was saved in between and edited since, every element counts as changed.
            invalidateHolodeck(mHoloLuminance.empty() || (mHoloBehindFile && mHoloUnsaved));
            worked = true;
        } else if (mHoloLuminance.empty()) {
            mHoloLuminance = elementLuminance(mSession->solver().radiosity());
        }
    }
    if (read) {
        std::vector<ShadedPoint> points;
        if (mHoloServer && !mHoloDirty && mSession->selected().empty())
            points = holodeckPointsOf(*read);
        mHoloStatus.served += std::int64_t(points.size());
        {
            std::lock_guard<std::mutex> lock(mQueueMutex);
            mHoloPoints = HoloPoints{read->id, std::move(points)};
        }
        mRenderWake.notify_all();
    }
    if (!stores.empty() && mHoloServer && !mHoloDirty && !mHoloUnsaved)
        storeHolodeckPoints(stores);
    return worked;
}

std::vector<ShadedPoint> SessionRunner::holodeckPointsOf(const HoloRead& read) {
    const double t0 = nowSeconds();
    try {
        const CameraRays rays(read.camera, read.width, read.height);
        const auto view = viewRequests(mHoloFile->sections(), rays, std::max(1, read.width / 4),
                                       std::max(1, read.height / 4), 1.0);
        std::vector<ShadedPoint> points = holodeckViewPoints(
            *mHoloServer, view, mSession->discretization(), mSession->tracer(), rays, 0, 0);
        spdlog::debug("holodeck: {} points of a {}x{} view in {:.1f} ms", points.size(),
                      read.width, read.height, (nowSeconds() - t0) * 1e3);
        return points;
    } catch (const std::exception& e) {
        report(std::string("holodeck: ") + e.what());
        return {};
    }
}

void SessionRunner::invalidateHolodeck(bool everyElement) {
    const double t0 = nowSeconds();
    std::vector<double> now = elementLuminance(mSession->solver().radiosity());
    const std::vector<std::uint8_t> changed =
        everyElement ? std::vector<std::uint8_t>(now.size(), 1)
                     : changedElements(mHoloLuminance, now, mOptions.holodeckThreshold);
    try {
        const Invalidation result = mHoloServer->invalidate(mSession->tracer(), changed);
        mHoloServer->flush();
        mHoloStatus.invalidated += result.samples;
        mHoloStatus.samples = mHoloFile->info().samples;
        spdlog::debug("holodeck: edits took {} samples from {} beams ({} kept) in {:.1f} ms",
                      result.samples, result.beams, result.kept, (nowSeconds() - t0) * 1e3);
    } catch (const std::exception& e) {
        report(std::string("holodeck: ") + e.what());
    }
    mHoloLuminance = std::move(now);
    mHoloDirty = false;
    // Matching the solution now, it matches the scene file when nothing was edited since the
    // save (or it holds nothing any scene could contradict).
    if (!mHoloUnsaved || everyElement) mHoloBehindFile = false;
}

void SessionRunner::holodeckSaved() {
    if (mHoloDirty) mHoloBehindFile = true;
    mHoloUnsaved = false;
}

void SessionRunner::storeHolodeckPoints(std::vector<HoloStore>& stores) {
    const double t0 = nowSeconds();
    std::int64_t added = 0;
    try {
        for (const HoloStore& store : stores)
            if (store.lightSerial == mLightSerial)  // nothing changed since they were shaded
                added += storeViewPoints(*mHoloServer, store.points, mSession->tracer(),
                                         store.eye);
        mHoloServer->flush();
        mHoloStatus.samples = mHoloFile->info().samples;
    } catch (const std::exception& e) {
        report(std::string("holodeck: ") + e.what());
    }
    mHoloStatus.stored += added;
    stores.clear();
    spdlog::debug("holodeck: stored {} samples in {:.1f} ms", added, (nowSeconds() - t0) * 1e3);
}

void SessionRunner::closeHolodeck() {
    if (!mHoloServer) return;
    if (!mHoloDirty && !mHoloUnsaved && !mHoloStores.empty()) storeHolodeckPoints(mHoloStores);
    // The scene file was saved with edits the holodeck did not forget yet: it forgets every
    // element's light (the converged light of those edits is not known).
    if (mHoloDirty && mHoloBehindFile) invalidateHolodeck(true);
    try {
        mHoloServer->flush();
    } catch (const std::exception& e) {
        spdlog::warn("holodeck: {}", e.what());
    }
    mHoloServer.reset();
    mHoloFile.reset();
}

void SessionRunner::requestHolodeckPoints(DisplaySlot& slot, const Camera& camera, int w, int h,
                                          std::uint64_t id) {
    slot.holoRead = 0;
    slot.holoPoints = 0;
    slot.holoPositions.clear();
    slot.convergedLight = slot.convergedFrame = 0;
    slot.storedView = slot.storedLight = 0;
    if (mOptions.holodeck.empty()) return;
    if (id == 0) {
        id = ++mHoloReadIds;
        {
            std::lock_guard<std::mutex> lock(mQueueMutex);
            mHoloRead = HoloRead{id, camera, w, h};
        }
        mWake.notify_all();
    }
    slot.holoRead = id;
    slot.holoReadTime = nowSeconds();
}

bool SessionRunner::takeHolodeckPoints(DisplaySlot& slot) {
    if (slot.holoRead == 0) return true;
    std::optional<HoloPoints> answer;
    {
        std::lock_guard<std::mutex> lock(mQueueMutex);
        if (mHoloPoints && mHoloPoints->id == slot.holoRead) answer.swap(mHoloPoints);
    }
    if (!answer)
        return slot.frames > 0 || nowSeconds() - slot.holoReadTime > kHolodeckWaitMs * 1e-3;
    InteractiveDisplay& d = *slot.display;
    // Stamped as points shaded now: the display relights them with its own.
    for (ShadedPoint& p : answer->points) {
        p.frame = d.cache().frame();
        p.shading = d.shadingSerial();
        slot.holoPositions.push_back(p.position);
    }
    d.insertShaded(answer->points);
    slot.holoPoints = std::int64_t(answer->points.size());
    slot.holoRead = 0;
    return true;
}

void SessionRunner::handHolodeckPoints(const ViewRequest& view, const Light& light,
                                       DisplaySlot& slot, int settledFrames,
                                       const CameraRays& rays) {
    if (mOptions.holodeck.empty() || view.interactive || !light.converged ||
        slot.solution != light.serial || slot.convergedLight != light.serial ||
        settledFrames < mOptions.settleFrames || slot.holoRead != 0 ||
        (slot.storedView == view.serial && slot.storedLight == light.serial))
        return;
    slot.storedView = view.serial;
    slot.storedLight = light.serial;
    // At most one sample per pixel of the view: the pixels a point already in the holodeck
    // (brought from it or stored) shows take no other, so revisiting a view does not grow it.
    const RenderCache& cache = slot.display->cache();
    const int w = rays.width(), h = rays.height();
    std::vector<std::uint8_t> covered(static_cast<std::size_t>(w) * h, 0);
    auto pixelOf = [&](const Vec3& position) -> long {
        const auto pixel = rays.projectToPixel(position);
        if (!pixel || pixel->x < 0 || pixel->y < 0 || pixel->x >= w || pixel->y >= h) return -1;
        return static_cast<long>(pixel->y) * w + static_cast<long>(pixel->x);
    };
    for (const Vec3& position : slot.holoPositions)
        if (const long pixel = pixelOf(position); pixel >= 0) covered[pixel] = 1;
    const std::vector<CachePoint>& points = cache.points();
    // The points shaded from the converged light, visible, one per uncovered pixel.
    HoloStore store;
    store.eye = rays.origin();
    store.lightSerial = light.serial;
    for (std::size_t i = 0; i < points.size(); ++i) {
        const CachePoint& p = points[i];
        if (p.frame < slot.convergedFrame || cache.stale(i) || !cache.visible(i)) continue;
        const long pixel = pixelOf(p.position);
        if (pixel < 0 || covered[pixel]) continue;
        covered[pixel] = 1;
        slot.holoPositions.push_back(p.position);
        store.points.push_back(p);
    }
    if (store.points.empty()) return;
    spdlog::debug("holodeck: {} points handed over to be stored ({} in it before)",
                  store.points.size(), slot.holoPositions.size() - store.points.size());
    {
        std::lock_guard<std::mutex> lock(mQueueMutex);
        mHoloStores.push_back(std::move(store));
    }
    mWake.notify_all();
}

// ---------------------------------------------------------------------------------------------
// Snapshots.

void SessionRunner::publishDocument() {
    auto doc = std::make_shared<DocumentSummary>();
    const Scene& scene = mSession->scene();
    const Discretization& disc = mSession->discretization();
    doc->serial = ++mDocumentSerial;
    doc->materials = scene.materials;
    doc->cameras = scene.cameras;
    for (const SceneObject& o : scene.objects) {
        ObjectSummary s;
        s.id = o.id;
        s.version = mSession->objectVersion(o.id);
        s.shape = o.shape.type;
        s.material = o.material;
        if (const Material* m = scene.findMaterial(o.material)) s.materialValue = *m;
        s.transform = o.transform;
        if (s.version >= 0 && s.version < static_cast<int>(disc.objects().size())) {
            const auto& positions = disc.objects()[s.version].worldPositions;
            if (!positions.empty()) {
                s.boundsMin = s.boundsMax = positions[0];
                for (const Vec3& p : positions) {
                    s.boundsMin = glm::min(s.boundsMin, p);
                    s.boundsMax = glm::max(s.boundsMax, p);
                }
            }
        }
        doc->objects.push_back(std::move(s));
    }
    std::lock_guard<std::mutex> lock(mPublishMutex);
    mDocument = std::move(doc);
}

void SessionRunner::publishLight() {
    Light light;
    light.radiosity = std::make_shared<const std::vector<Rgb>>(mSession->displayRadiosity());
    light.previewVersion = mSession->previewVersion();
    light.irradiance = std::make_shared<const std::vector<Rgb>>(mSession->solver().irradiance());
    light.fromEmission =
        std::make_shared<const std::vector<Rgb>>(mSession->solver().irradianceFromEmission());
    if (light.previewVersion >= 0) {
        light.previewBuffer =
            std::make_shared<const std::vector<Rgb>>(mSession->solver().previewRadiosity());
        light.previewFromEmission = std::make_shared<const std::vector<Rgb>>(
            mSession->solver().previewRadiosityFromEmission());
        light.previewComplete = mSession->solver().previewComplete();
    }
    light.converged = light.previewVersion < 0 && mSession->selected().empty() &&
                      mSession->solver().converged(mSolveEps);
    light.serial = ++mLightSerial;
    {
        // Out-of-date overlay: per element the |unshot radiosity| of its patch.
        const Discretization& disc = mSession->discretization();
        const ProgressiveSolver& solver = mSession->solver();
        const auto& b = *light.radiosity;
        auto pending = std::make_shared<std::vector<Rgb>>(disc.elements().size(), Rgb(0.0));
        double sum = 0;
        std::size_t n = 0;
        for (std::size_t e = 0; e < disc.elements().size(); ++e) {
            const int patch = disc.elements()[e].patch;
            if (patch < 0 || !disc.patchAlive(patch)) continue;
            (*pending)[e] = glm::abs(solver.unshotRadiosity(patch));
            sum += luminance(b[e]);
            ++n;
        }
        light.pending = std::move(pending);
        light.pendingScale = n > 0 ? 0.05 * sum / double(n) : 0.0;
    }
    {
        std::lock_guard<std::mutex> lock(mPublishMutex);
        mLight = std::move(light);
    }
    mRenderWake.notify_all();
}

void SessionRunner::publishSolver(double solverMs) {
    const ProgressiveSolver& solver = mSession->solver();
    const SolverStats& stats = solver.stats();
    const double now = nowSeconds();
    if (mLastRateTime == 0) mLastRateTime = now, mLastShots = stats.shots;
    if (now - mLastRateTime >= 0.5) {
        mShotsPerSecond = (stats.shots - mLastShots) / (now - mLastRateTime);
        mLastShots = stats.shots;
        mLastRateTime = now;
    }
    if (now - mLastHistoryTime >= 0.1) {
        mLastHistoryTime = now;
        mHistory.push_back(
            static_cast<float>(std::log10(std::max(solver.unshotFraction(), 1e-12))));
        if (mHistory.size() > 300) mHistory.erase(mHistory.begin());
    }
    SolverSnapshot s;
    s.shots = stats.shots;
    s.rays = stats.rays;
    s.redistributionShots = stats.redistributionShots;
    s.shotsPerSecond = mShotsPerSecond;
    s.unshotFraction = solver.unshotFraction();
    s.pendingRedistribution = solver.pendingRedistribution();
    s.emittedEnergy = solver.emittedEnergy();
    s.pendingChanges = solver.pendingChanges();
    const Discretization& disc = mSession->discretization();
    for (std::size_t e = 0; e < disc.elements().size(); ++e)
        s.elements += disc.elementAlive(static_cast<int>(e)) ? 1 : 0;
    for (std::size_t p = 0; p < disc.patches().size(); ++p)
        s.patches += disc.patchAlive(static_cast<int>(p)) ? 1 : 0;
    double eps;
    {
        std::lock_guard<std::mutex> lock(mQueueMutex);
        eps = mEps;
    }
    s.converged = solver.converged(eps);
    s.idle = mSolverIdle;
    s.history = mHistory;
    s.undoDepth = mSession->undoDepth();
    s.redoDepth = mSession->redoDepth();
    s.selected = mSession->selected();
    s.previewVersion = mSession->previewVersion();
    s.solverMsPerIteration = solverMs;
    s.strategy = solver.options().strategy;
    s.redistributionThreshold = solver.options().redistributionThreshold;
    s.holodeck = mHoloStatus;
    std::lock_guard<std::mutex> lock(mPublishMutex);
    mSolver = std::move(s);
}

std::shared_ptr<const ViewportImage> SessionRunner::image() const {
    std::lock_guard<std::mutex> lock(mPublishMutex);
    return mImage;
}

SolverSnapshot SessionRunner::solver() const {
    std::lock_guard<std::mutex> lock(mPublishMutex);
    return mSolver;
}

std::shared_ptr<const DocumentSummary> SessionRunner::document() const {
    std::lock_guard<std::mutex> lock(mPublishMutex);
    return mDocument;
}

std::vector<std::string> SessionRunner::takeMessages() {
    std::lock_guard<std::mutex> lock(mPublishMutex);
    std::vector<std::string> out;
    out.swap(mMessages);
    return out;
}

bool SessionRunner::hasMessages() const {
    std::lock_guard<std::mutex> lock(mPublishMutex);
    return !mMessages.empty();
}

bool SessionRunner::quiescent() const {
    ViewRequest view;
    {
        std::lock_guard<std::mutex> lock(mQueueMutex);
        if (!mQueue.empty() || mApplying) return false;
        view = mView;
    }
    std::lock_guard<std::mutex> lock(mPublishMutex);
    return mSolver.idle && mSolver.selected.empty() && mImage &&
           mImage->viewSerial == view.serial && !mImage->reduced &&
           mImage->stateSerial == mLight.serial &&
           (view.mode != ViewMode::Interpolant || mImage->mode == view.mode) &&
           (!usesInteractiveDisplay(view.mode) ||
            (mImage->mode == view.mode && mImage->settledFrames >= mOptions.settleFrames));
}

}  // namespace penumbra
