#include "ui/solver_worker.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "core/log.h"
#include "core/timing.h"
#include "render/settling_overlay.h"
#include "solver/discretization.h"

namespace penumbra {

namespace {

double nowSeconds() { return std::chrono::duration<double>(Clock::now().time_since_epoch()).count(); }

}  // namespace

SolverWorker::SolverWorker(SharedSession& shared, RunnerBoard& board, SolverWorkerOptions options,
                           std::vector<EditListener*> listeners)
    : mShared(shared),
      mSession(*shared.session),
      mBoard(board),
      mOptions(options),
      mListeners(std::move(listeners)),
      mEps(options.convergeEps),
      mSolveEps(options.convergeEps) {
    mStrategy = mSession.solver().options().strategy;
    mThreshold = mSession.solver().options().redistributionThreshold;
    publishDocument();
    publishLight();
    publishSolver(0);
}

SolverWorker::~SolverWorker() { stop(); }

void SolverWorker::start() {
    mThread.start("solver", mOptions.backgroundNice, std::chrono::milliseconds(50),
                  [this] { return iterate(); });
}

void SolverWorker::stop() { mThread.stop(); }

// ---------------------------------------------------------------------------------------------
// Queue and settings.

void SolverWorker::push(Queued queued) {
    {
        std::lock_guard<std::mutex> lock(mMutex);
        mQueue.push_back(std::move(queued));
    }
    mThread.wake();
}

void SolverWorker::submit(const EditCommand& command, const EditSource& source) {
    push({command, source, {}, {}});
}

void SolverWorker::submitCoalescing(const EditCommand& command) {
    {
        std::lock_guard<std::mutex> lock(mMutex);
        const auto* t = std::get_if<TransformCommand>(&command.op);
        const auto* last = mQueue.empty() || mQueue.back().task || mQueue.back().make
                               ? nullptr
                               : std::get_if<TransformCommand>(&mQueue.back().command.op);
        if (t && last && last->id == t->id)
            mQueue.back().command = command;
        else
            mQueue.push_back({command, EditSource{}, {}, {}});
    }
    mThread.wake();
}

void SolverWorker::submitMade(std::function<EditCommand(EditSession&)> make) {
    push({EditCommand{}, EditSource{}, {}, std::move(make)});
}

void SolverWorker::post(std::function<void(EditSession&)> task, bool holodeckScene) {
    push({EditCommand{}, EditSource{}, std::move(task), {}, holodeckScene});
}

void SolverWorker::setPaused(bool paused) {
    {
        std::lock_guard<std::mutex> lock(mMutex);
        mPaused = paused;
    }
    mThread.wake();
}

bool SolverWorker::paused() const {
    std::lock_guard<std::mutex> lock(mMutex);
    return mPaused;
}

void SolverWorker::setAutoSolve(bool on) {
    {
        std::lock_guard<std::mutex> lock(mMutex);
        mAutoSolve = on;
    }
    mThread.wake();
}

void SolverWorker::setConvergeEps(double eps) {
    {
        std::lock_guard<std::mutex> lock(mMutex);
        if (eps > 0 && eps < 1) mEps = eps;
    }
    mThread.wake();
}

void SolverWorker::setStrategy(RedistributionStrategy strategy, double threshold) {
    if (!(threshold >= 0 && threshold <= 1))
        throw std::invalid_argument("redistribution threshold must be in [0, 1]");
    {
        std::lock_guard<std::mutex> lock(mMutex);
        mStrategy = strategy;
        mThreshold = threshold;
        mStrategyChanged = true;
    }
    mThread.wake();
}

RedistributionStrategy SolverWorker::strategy() const {
    std::lock_guard<std::mutex> lock(mMutex);
    return mStrategy;
}

double SolverWorker::redistributionThreshold() const {
    std::lock_guard<std::mutex> lock(mMutex);
    return mThreshold;
}

std::size_t SolverWorker::queued() const {
    std::lock_guard<std::mutex> lock(mMutex);
    return mQueue.size() + (mApplying ? 1 : 0);
}

// ---------------------------------------------------------------------------------------------
// Iteration.

bool SolverWorker::iterate() {
    std::deque<Queued> commands;
    bool solve = false;
    double eps = 0;
    std::optional<std::pair<RedistributionStrategy, double>> strategy;
    {
        std::lock_guard<std::mutex> lock(mMutex);
        commands.swap(mQueue);
        mApplying = !commands.empty();
        solve = mAutoSolve && !mPaused;
        eps = mEps;
        mSolveEps = mEps;
        if (mStrategyChanged) strategy.emplace(mStrategy, mThreshold);
        mStrategyChanged = false;
    }
    // A strategy switch only reorders pending work: applied between shots, no structure lock
    // (no other thread reads the solver's options).
    if (strategy) {
        try {
            mSession.solver().setStrategy(strategy->first, strategy->second);
        } catch (const std::exception& e) {
            mBoard.report(std::string("strategy: ") + e.what());
        }
    }
    const std::size_t edits = commands.size();
    if (!commands.empty()) applyCommands(commands);

    const double t0 = nowSeconds();
    const std::uint64_t shots = shootForBudget(solve, eps, t0);
    const double solverMs = (nowSeconds() - t0) * 1e3;
    spdlog::debug("solver: {} edits, {} shots in {:.1f} ms", edits, shots, solverMs);
    publishSolver(solverMs);
    {
        std::lock_guard<std::mutex> lock(mMutex);
        mApplying = false;
    }
    if (edits > 0 || shots > 0) notifyPublished();
    return edits > 0 || !mIdle;
}

void SolverWorker::applyCommands(std::deque<Queued>& commands) {
    const double a0 = nowSeconds();
    // A long reader holding the structure (an interpolant build) stops at its next element.
    ++mShared.editsWaiting;
    std::unique_lock<std::shared_mutex> lock(mShared.structure);
    --mShared.editsWaiting;
    for (EditListener* l : mListeners) l->editsBegin();
    const double a1 = nowSeconds();
    bool edited = false;
    for (Queued& q : commands) {
        try {
            if (q.task) {
                q.task(mSession);
                if (q.savesHolodeckScene)
                    for (EditListener* l : mListeners) l->savedHolodeckScene();
                continue;
            }
            const EditEvent event = mSession.apply(q.make ? q.make(mSession) : q.command, q.source);
            for (EditListener* l : mListeners) l->edited(event);
            if (event.solutionChanged()) edited = true;
        } catch (const std::exception& e) {
            mBoard.report(e.what());
        }
    }
    for (EditListener* l : mListeners) l->editsEnd();
    // The snapshots only read what this thread alone writes: outside the exclusive section.
    lock.unlock();
    if (edited) {
        mLastEditTime = nowSeconds();
        mSettleSeconds = -1;
        mLastSettling = -1;  // the next publication estimates again
    }
    publishDocument();
    publishLight();
    spdlog::debug("apply: waited {:.1f} ms, applied {} in {:.1f} ms", (a1 - a0) * 1e3,
                  commands.size(), (nowSeconds() - a1) * 1e3);
}

std::uint64_t SolverWorker::shootForBudget(bool solve, double eps, double t0) {
    // Shots, one at a time, for the budget. The sequence of shots depends only on the edits
    // between them, not on timing.
    double lastPublish = t0;
    std::uint64_t shots = 0;
    mIdle = true;
    const bool dragging = !mSession.selected().empty();
    if (!solve || (!dragging && mSession.solver().converged(eps))) return 0;
    mIdle = false;
    while (nowSeconds() - t0 < mOptions.solveBudgetMs * 1e-3) {
        const std::uint64_t n = mSession.solve(1);
        shots += n;
        const bool done = n == 0 || (!dragging && mSession.solver().converged(eps));
        if (done) mIdle = true;
        // Show progress of long shots as it comes.
        if (done || nowSeconds() - lastPublish > 0.03) {
            if (n > 0) {
                publishLight();
                notifyPublished();
            }
            lastPublish = nowSeconds();
        }
        if (done) break;
    }
    if (shots > 0 && lastPublish < nowSeconds() - 1e-9) publishLight();
    return shots;
}

void SolverWorker::notifyPublished() {
    for (EditListener* l : mListeners) l->published();
}

// ---------------------------------------------------------------------------------------------
// Publishing.

void SolverWorker::publishDocument() {
    auto doc = std::make_shared<DocumentSummary>();
    const Scene& scene = mSession.scene();
    const Discretization& disc = mSession.discretization();
    doc->serial = ++mDocumentSerial;
    doc->materials = scene.materials;
    doc->cameras = scene.cameras;
    for (const SceneObject& o : scene.objects) {
        ObjectSummary s;
        s.id = o.id;
        s.version = mSession.objectVersion(o.id);
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
    mBoard.setDocument(std::move(doc));
}

void SolverWorker::publishLight() {
    const ProgressiveSolver& solver = mSession.solver();
    PublishedLight light;
    light.radiosity = std::make_shared<const std::vector<Rgb>>(mSession.displayRadiosity());
    light.previewVersion = mSession.previewVersion();
    light.dragging = !mSession.selected().empty();
    light.irradiance = std::make_shared<const std::vector<Rgb>>(solver.irradiance());
    light.fromEmission = std::make_shared<const std::vector<Rgb>>(solver.irradianceFromEmission());
    if (light.previewVersion >= 0) {
        light.previewBuffer = std::make_shared<const std::vector<Rgb>>(solver.previewRadiosity());
        light.previewFromEmission =
            std::make_shared<const std::vector<Rgb>>(solver.previewRadiosityFromEmission());
        light.previewComplete = solver.previewComplete();
    }
    light.converged = light.previewVersion < 0 && !light.dragging && solver.converged(mSolveEps);
    if (light.converged)
        light.convergedRadiosity = std::make_shared<const std::vector<Rgb>>(solver.radiosity());
    light.serial = ++mLightSerial;
    {
        // Out-of-date overlay: per element the |unshot radiosity| of its patch.
        const Discretization& disc = mSession.discretization();
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
    updateSettling(light.converged);
    light.settling = mSettling;
    light.settlingFloor = mSettlingFloor;
    mBoard.setLight(std::move(light));
}

void SolverWorker::updateSettling(bool force) {
    // The estimate costs passes over the elements (on robot-room 20-120 ms, more while much is
    // unshot): at most every kPeriodSeconds, and no more than kShare of this thread's time, so
    // the solver keeps shooting.
    constexpr double kPeriodSeconds = 0.2, kShare = 0.1;
    const double now = nowSeconds();
    // The map only for the overlay; asked for since the last estimate, at once.
    const bool map = mSettlingMapWanted.load(std::memory_order_relaxed);
    if (map && !mSettling) force = true;
    if (!force && mLastSettling >= 0 &&
        now - mLastSettling < std::max(kPeriodSeconds, mSettlingCost / kShare))
        return;
    // Not while an object is dragged: each step's preview must reach the display at once, and
    // nobody waits for "settled" in the middle of a drag (the overlay keeps the last estimate).
    if (!mSession.selected().empty() && mSettlingRms >= 0 && (mSettling || !map)) return;
    const SettlingEstimate estimate =
        map ? mSession.solver().computeSettling() : mSession.solver().computeSettlingSummary();
    mLastSettling = nowSeconds();
    mSettlingCost = mLastSettling - now;
    mSettling =
        map ? std::make_shared<const std::vector<Rgb>>(settlingChangeValues(estimate)) : nullptr;
    mSettlingRms = estimate.reflectedRms;
    mSettlingFloor =
        settlingFloorRadiosity(mSession.discretization(), mSession.solver().radiosity());
    if (mSettlingRms < kSettledRms && mSession.selected().empty() && mLastEditTime >= 0 &&
        mSettleSeconds < 0)
        mSettleSeconds = now - mLastEditTime;
}

void SolverWorker::setSettlingMap(bool wanted) {
    mSettlingMapWanted.store(wanted, std::memory_order_relaxed);
}

void SolverWorker::publishSolver(double solverMs) {
    const ProgressiveSolver& solver = mSession.solver();
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
    const Discretization& disc = mSession.discretization();
    for (std::size_t e = 0; e < disc.elements().size(); ++e)
        s.elements += disc.elementAlive(static_cast<int>(e)) ? 1 : 0;
    for (std::size_t p = 0; p < disc.patches().size(); ++p)
        s.patches += disc.patchAlive(static_cast<int>(p)) ? 1 : 0;
    double eps;
    {
        std::lock_guard<std::mutex> lock(mMutex);
        eps = mEps;
    }
    s.converged = solver.converged(eps);
    s.settlingRms = mSettlingRms;
    s.settled = mSettlingRms >= 0 && mSettlingRms < kSettledRms && mSession.selected().empty();
    s.settleSeconds = mSettleSeconds;
    s.idle = mIdle;
    s.history = mHistory;
    s.undoDepth = mSession.undoDepth();
    s.redoDepth = mSession.redoDepth();
    s.selected = mSession.selected();
    s.previewVersion = mSession.previewVersion();
    s.solverMsPerIteration = solverMs;
    s.strategy = solver.options().strategy;
    s.redistributionThreshold = solver.options().redistributionThreshold;
    mBoard.setSolver(std::move(s));
}

}  // namespace penumbra
