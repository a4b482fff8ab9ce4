// Index: DocumentSummary · construction and thread · queue and requests · the worker
//        iteration (edits, solver budget, image) · snapshots

#include "ui/session_runner.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>

#include "edit/input_error.h"

namespace penumbra {

namespace {

double nowSeconds() {
    using namespace std::chrono;
    return duration<double>(steady_clock::now().time_since_epoch()).count();
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
// Construction and thread.

SessionRunner::SessionRunner(std::unique_ptr<EditSession> session, SessionRunnerOptions options)
    : mSession(std::move(session)), mOptions(options), mEps(options.convergeEps) {
    if (!mSession) throw std::invalid_argument("SessionRunner: no session");
    {
        std::lock_guard<std::mutex> lock(mSessionMutex);
        publishDocument();
        publishSolver(0);
    }
    if (mOptions.threaded) mThread = std::thread([this] { run(); });
}

SessionRunner::~SessionRunner() {
    {
        std::lock_guard<std::mutex> lock(mQueueMutex);
        mStop = true;
    }
    mWake.notify_all();
    if (mThread.joinable()) mThread.join();
}

void SessionRunner::run() {
    for (;;) {
        bool worked;
        {
            std::lock_guard<std::mutex> lock(mSessionMutex);
            worked = iterate();
        }
        std::unique_lock<std::mutex> lock(mQueueMutex);
        if (mStop) return;
        // Sleep when there is nothing to do, until woken by an edit or a view change.
        if (!worked) mWake.wait_for(lock, std::chrono::milliseconds(30));
    }
}

void SessionRunner::pump() {
    if (mOptions.threaded) throw std::logic_error("SessionRunner::pump: runner is threaded");
    std::lock_guard<std::mutex> lock(mSessionMutex);
    iterate();
}

// ---------------------------------------------------------------------------------------------
// Queue and requests.

void SessionRunner::submit(const EditCommand& command, const EditSource& source) {
    {
        std::lock_guard<std::mutex> lock(mQueueMutex);
        mQueue.emplace_back(command, source);
    }
    mWake.notify_all();
}

void SessionRunner::submitCoalescing(const EditCommand& command) {
    {
        std::lock_guard<std::mutex> lock(mQueueMutex);
        const auto* t = std::get_if<TransformCommand>(&command.op);
        if (t && !mQueue.empty()) {
            const auto* last = std::get_if<TransformCommand>(&mQueue.back().first.op);
            if (last && last->id == t->id) {
                mQueue.back().first = command;
                return;
            }
        }
        mQueue.emplace_back(command, EditSource{});
    }
    mWake.notify_all();
}

void SessionRunner::setView(const ViewRequest& request) {
    {
        std::lock_guard<std::mutex> lock(mQueueMutex);
        const bool same =
            request.width == mView.width && request.height == mView.height &&
            request.highlight == mView.highlight && request.interactive == mView.interactive &&
            request.camera.position == mView.camera.position &&
            request.camera.lookAt == mView.camera.lookAt && request.camera.up == mView.camera.up &&
            request.camera.fovDeg == mView.camera.fovDeg;
        if (same) return;
        mView = request;
        mView.serial = ++mViewSerial;
    }
    mWake.notify_all();
}

void SessionRunner::setPaused(bool paused) {
    {
        std::lock_guard<std::mutex> lock(mQueueMutex);
        mPaused = paused;
    }
    mWake.notify_all();
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

void SessionRunner::withSession(const std::function<void(EditSession&)>& f) {
    std::lock_guard<std::mutex> lock(mSessionMutex);
    f(*mSession);
    // Saving and exporting do not change the document; anything else would be published on
    // the next iteration.
}

std::size_t SessionRunner::queued() const {
    std::lock_guard<std::mutex> lock(mQueueMutex);
    return mQueue.size() + (mApplying ? 1 : 0);
}

// ---------------------------------------------------------------------------------------------
// The worker iteration.

bool SessionRunner::iterate() {
    // Take the queued edits and the view request.
    std::deque<std::pair<EditCommand, EditSource>> commands;
    ViewRequest view;
    bool solve;
    double eps;
    {
        std::lock_guard<std::mutex> lock(mQueueMutex);
        commands.swap(mQueue);
        mApplying = !commands.empty();
        view = mView;
        solve = mAutoSolve && !mPaused;
        eps = mEps;
    }
    bool changed = false, documentChanged = false;

    // Apply edits in order; an invalid one is reported and skipped.
    for (auto& [command, source] : commands) {
        try {
            const EditResult r = mSession->apply(command, source);
            documentChanged |= !command.isSolverWork() || r.geometry || r.material;
            changed = true;
        } catch (const std::exception& e) {
            std::lock_guard<std::mutex> lock(mPublishMutex);
            mMessages.emplace_back(e.what());
        }
    }

    // Solver work for the budget: one shot at a time (the sequence of shots does not depend
    // on timing, only on the edits between them).
    const double t0 = nowSeconds();
    std::uint64_t shots = 0;
    mSolverIdle = true;
    if (solve) {
        const bool dragging = !mSession->selected().empty();
        if (dragging || !mSession->solver().converged(eps)) {
            mSolverIdle = false;
            while (nowSeconds() - t0 < mOptions.solveBudgetMs * 1e-3) {
                const std::uint64_t n = mSession->solve(1);
                shots += n;
                if (n == 0 || (!dragging && mSession->solver().converged(eps))) {
                    mSolverIdle = true;
                    break;
                }
            }
        }
    }
    const double solverMs = (nowSeconds() - t0) * 1e3;
    if (shots > 0) changed = true;
    if (changed) ++mStateSerial;
    if (documentChanged) publishDocument();

    // Render when the state or the view changed, or to refine a reduced image.
    std::shared_ptr<const ViewportImage> last = image();
    const bool wantReduced = view.interactive;
    const bool needImage = view.width > 0 && view.height > 0 &&
                           (!last || last->stateSerial != mStateSerial ||
                            last->viewSerial != view.serial || (last->reduced && !wantReduced));
    if (needImage) {
        const int d = wantReduced ? std::max(1, mOptions.reducedDivisor) : 1;
        const int w = std::max(1, view.width / d), h = std::max(1, view.height / d);
        auto img = std::make_shared<ViewportImage>();
        const double r0 = nowSeconds();
        try {
            const int preview =
                mSession->selected().empty() ? -1 : mSession->solver().previewObject();
            const int highlight =
                view.highlight.empty() ? -1 : mSession->objectVersion(view.highlight);
            img->render = renderViewport(mSession->discretization(), mSession->tracer(),
                                         mSession->displayRadiosity(), view.camera, w, h, preview,
                                         highlight >= 0 ? highlight : preview);
        } catch (const std::exception& e) {
            std::lock_guard<std::mutex> lock(mPublishMutex);
            mMessages.emplace_back(std::string("viewport: ") + e.what());
        }
        img->renderMs = (nowSeconds() - r0) * 1e3;
        img->camera = view.camera;
        img->viewSerial = view.serial;
        img->stateSerial = mStateSerial;
        img->reduced = d > 1;
        std::lock_guard<std::mutex> lock(mPublishMutex);
        mImage = std::move(img);
    }
    publishSolver(solverMs);
    {
        std::lock_guard<std::mutex> lock(mQueueMutex);
        mApplying = false;
    }
    return changed || needImage || !mSolverIdle;
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
    {
        std::lock_guard<std::mutex> lock(mQueueMutex);
        s.converged = solver.converged(mEps);
    }
    s.idle = mSolverIdle;
    s.history = mHistory;
    s.undoDepth = mSession->undoDepth();
    s.redoDepth = mSession->redoDepth();
    s.selected = mSession->selected();
    s.previewVersion = s.selected.empty() ? -1 : solver.previewObject();
    s.solverMsPerIteration = solverMs;
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

bool SessionRunner::quiescent() const {
    ViewRequest view;
    {
        std::lock_guard<std::mutex> lock(mQueueMutex);
        if (!mQueue.empty() || mApplying) return false;
        view = mView;
    }
    std::lock_guard<std::mutex> lock(mPublishMutex);
    return mSolver.idle && mImage && mImage->viewSerial == view.serial && !mImage->reduced &&
           mImage->stateSerial == mStateSerial && mSolver.selected.empty();
}

}  // namespace penumbra
