#pragma once
// The solver worker: the one thread that changes the editing session. It takes the queued
// edits and tasks in order, applies them (EditSession::apply, structure held exclusively),
// tells the listeners what changed (EditListener), then shoots one shot at a time for a time
// budget (one shot cannot be interrupted; the shots take no lock), publishing the lighting,
// the document and the solver's figures on the board as it goes.
//
// Index: queue and settings · iteration · publishing

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <mutex>
#include <optional>
#include <thread>
#include <utility>
#include <vector>

#include "ui/runner_board.h"
#include "ui/service_thread.h"
#include "ui/shared_session.h"

namespace penumbra {

struct SolverWorkerOptions {
    double solveBudgetMs = 12;  ///< solver time per iteration
    double convergeEps = 1e-3;  ///< auto-solve stops at unshotFraction ≤ eps, nothing pending
    int backgroundNice = 0;     ///< Linux nice increment of the thread
};

class SolverWorker {
public:
    /// `shared` and `board` outlive the worker; listeners hear of edits in the order given.
    SolverWorker(SharedSession& shared, RunnerBoard& board, SolverWorkerOptions options,
                 std::vector<EditListener*> listeners);
    ~SolverWorker();
    SolverWorker(const SolverWorker&) = delete;
    SolverWorker& operator=(const SolverWorker&) = delete;

    /// Starts the thread (threaded runners); without it, iterate() runs on the caller's.
    void start();
    /// Stops and joins the thread.
    void stop();

    // -- Queue and settings (any thread) ---------------------------------------------------------

    /// Queues an edit; applied in order. An invalid edit is reported and changes nothing.
    void submit(const EditCommand& command, const EditSource& source = {});
    /// Like submit, but replaces a queued, not yet applied transform of the same object.
    void submitCoalescing(const EditCommand& command);
    /// Queues an edit made from the session as it is when its turn comes.
    void submitMade(std::function<EditCommand(EditSession&)> make);
    /// Queues a task on the session (save, export, reading it). A task must not change the lit
    /// scene: edits go through submit/submitMade, so that the listeners hear of them.
    /// `holodeckScene`: the task writes the scene file the holodeck belongs to; when it
    /// succeeds the listeners hear savedHolodeckScene().
    void post(std::function<void(EditSession&)> task, bool holodeckScene = false);
    void setPaused(bool paused);
    bool paused() const;
    void setAutoSolve(bool on);
    void setConvergeEps(double eps);
    /// Throws std::invalid_argument unless threshold is in [0, 1].
    void setStrategy(RedistributionStrategy strategy, double threshold);
    RedistributionStrategy strategy() const;
    double redistributionThreshold() const;
    /// Whether the settling overlay is shown (ViewRequest::settlingOverlay): the estimate's
    /// per-element map (ProgressiveSolver::computeSettling) is computed only then; otherwise
    /// the status line's figure comes from the cheaper sampled sums (computeSettlingSummary).
    void setSettlingMap(bool wanted);
    /// Commands queued or being applied.
    std::size_t queued() const;

    // -- Iteration (the worker's thread, or the caller's when not started) ------------------------

    /// Edits, tasks and a budget of shots; returns whether anything was done.
    bool iterate();

private:
    /// An edit, an edit to make (`make`), or a task (`task`).
    struct Queued {
        EditCommand command;
        EditSource source;
        std::function<void(EditSession&)> task;
        std::function<EditCommand(EditSession&)> make;
        bool savesHolodeckScene = false;
    };
    void push(Queued queued);
    /// Applies a batch with the structure exclusive, telling the listeners; then publishes.
    void applyCommands(std::deque<Queued>& commands);
    /// Shoots one shot at a time until `t0` + the budget, or until converged to `eps` (not
    /// while dragging); publishes the light as it goes. Returns the shots.
    std::uint64_t shootForBudget(bool solve, double eps, double t0);
    void publishDocument();
    void publishLight();
    /// Recomputes the settling estimate when it is older than a few tenths of a second, or
    /// `force`; notes when the lighting settles after an edit.
    void updateSettling(bool force);
    void publishSolver(double solverMs);
    void notifyPublished();

    SharedSession& mShared;
    EditSession& mSession;
    RunnerBoard& mBoard;
    SolverWorkerOptions mOptions;
    std::vector<EditListener*> mListeners;

    mutable std::mutex mMutex;  ///< the queue and the settings
    std::deque<Queued> mQueue;
    bool mPaused = false;
    bool mAutoSolve = true;
    double mEps = 1e-3;
    RedistributionStrategy mStrategy = RedistributionStrategy::RedistributeFirst;
    double mThreshold = 0;
    bool mStrategyChanged = false;  ///< the worker has not applied mStrategy yet
    bool mApplying = false;
    ServiceThread mThread;

    // The worker's own state.
    std::uint64_t mDocumentSerial = 0;
    std::uint64_t mLightSerial = 0;
    std::uint64_t mLastShots = 0;
    double mLastRateTime = 0, mLastHistoryTime = 0, mShotsPerSecond = 0;
    std::vector<float> mHistory;
    bool mIdle = false;
    // The settling estimate: when it was last computed, its values, and the edit it follows.
    double mLastSettling = -1;
    double mSettlingCost = 0;  ///< seconds the last estimate took
    std::shared_ptr<const std::vector<Rgb>> mSettling;  ///< null while no map is wanted
    std::atomic<bool> mSettlingMapWanted{false};
    double mSettlingRms = -1, mSettlingFloor = 0;
    double mLastEditTime = -1;  ///< when the last edit was applied (-1: none yet)
    double mSettleSeconds = -1;
    double mSolveEps = 1e-3;  ///< the threshold of the last iteration (PublishedLight::converged)
};

}  // namespace penumbra
