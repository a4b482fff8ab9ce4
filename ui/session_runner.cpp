#include "ui/session_runner.h"

#include <stdexcept>

#include "core/log.h"
#include "ui/display_producer.h"
#include "ui/holodeck_service.h"
#include "ui/interpolant_service.h"
#include "ui/solver_worker.h"

namespace penumbra {

SessionRunner::SessionRunner(std::unique_ptr<EditSession> session, SessionRunnerOptions options)
    : mOptions(options), mShared(std::move(session)) {
    const int nice = mOptions.threaded ? mOptions.backgroundNice : 0;
    mHolodeck = std::make_unique<HolodeckService>(
        mShared, mBoard, HolodeckServiceOptions{options.holodeck, options.holodeckThreshold, nice});
    mHifi = std::make_unique<InterpolantService>(
        mShared, mBoard, InterpolantServiceOptions{options.hifiGatherRays, options.threaded, nice});
    DisplayProducerOptions display;
    display.interactiveImageMs = options.interactiveImageMs;
    display.maxReducedDivisor = options.maxReducedDivisor;
    display.displayDivisor = options.displayDivisor;
    display.displayFrameMs = options.displayFrameMs;
    display.settleFrames = options.settleFrames;
    display.referenceDivisor = options.referenceDivisor;
    display.threaded = options.threaded;
    display.renderNice = mOptions.threaded ? mOptions.renderNice : 0;
    display.backgroundNice = nice;
    mDisplay = std::make_unique<DisplayProducer>(mShared, mBoard, display, *mHifi, *mHolodeck);
    // Listeners in order: the display first (its shader pauses before the structure changes).
    mSolver = std::make_unique<SolverWorker>(
        mShared, mBoard, SolverWorkerOptions{options.solveBudgetMs, options.convergeEps, nice},
        std::vector<EditListener*>{mDisplay.get(), mHifi.get(), mHolodeck.get()});
    if (mOptions.threaded) {
        // spdlog makes its registry at the first log call: here, not racing in two threads.
        (void)spdlog::default_logger_raw();
        mSolver->start();
        mDisplay->start();
        mHolodeck->start();
    }
}

SessionRunner::~SessionRunner() {
    mSolver->stop();
    mDisplay->stop();
}

void SessionRunner::pump() {
    if (mOptions.threaded) throw std::logic_error("SessionRunner::pump: runner is threaded");
    mSolver->iterate();
    mHolodeck->iterate();
    mDisplay->iterate();
}

void SessionRunner::submit(const EditCommand& command, const EditSource& source) {
    mSolver->submit(command, source);
}

void SessionRunner::submitCoalescing(const EditCommand& command) {
    mSolver->submitCoalescing(command);
}

void SessionRunner::post(std::function<void(EditSession&)> task) { mSolver->post(std::move(task)); }

void SessionRunner::postSave(std::function<void(EditSession&)> task, bool holodeckScene) {
    mSolver->post(std::move(task), holodeckScene);
}

void SessionRunner::submitMade(std::function<EditCommand(EditSession&)> make) {
    mSolver->submitMade(std::move(make));
}

void SessionRunner::setView(const ViewRequest& request) {
    mSolver->setSettlingMap(request.settlingOverlay);
    mDisplay->setView(request);
}

void SessionRunner::setPaused(bool paused) { mSolver->setPaused(paused); }

bool SessionRunner::paused() const { return mSolver->paused(); }

void SessionRunner::setAutoSolve(bool on) { mSolver->setAutoSolve(on); }

void SessionRunner::setConvergeEps(double eps) { mSolver->setConvergeEps(eps); }

void SessionRunner::setStrategy(RedistributionStrategy strategy, double threshold) {
    mSolver->setStrategy(strategy, threshold);
}

RedistributionStrategy SessionRunner::strategy() const { return mSolver->strategy(); }

double SessionRunner::redistributionThreshold() const {
    return mSolver->redistributionThreshold();
}

Pick SessionRunner::pick(const Camera& camera, int width, int height, double px, double py) {
    std::shared_lock<std::shared_mutex> lock(mShared.structure);
    return pickObject(mShared.read().discretization(), mShared.read().tracer(), camera, width,
                      height, px, py);
}

std::size_t SessionRunner::queued() const { return mSolver->queued(); }

bool SessionRunner::quiescent() const {
    if (mSolver->queued() > 0) return false;
    const ViewRequest view = mDisplay->view();
    const RunnerBoard::Glance g = mBoard.glance();
    return g.solverIdle && g.selected.empty() && g.image && g.image->viewSerial == view.serial &&
           !g.image->reduced && g.image->stateSerial == g.lightSerial &&
           (view.mode != ViewMode::Interpolant || g.image->mode == view.mode) &&
           (!usesInteractiveDisplay(view.mode) ||
            (g.image->mode == view.mode && g.image->settledFrames >= mOptions.settleFrames));
}

}  // namespace penumbra
