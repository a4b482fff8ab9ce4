#pragma once
// Runs an EditSession for the editor without blocking the frame loop: the UI thread's one
// door to the services that do the work, each owning its state and its thread:
// - SolverWorker (ui/solver_worker.h): the one thread that changes the session — queued
//   edits and tasks in order, then shots for a time budget — and publishes the document, the
//   lighting and the solver's figures;
// - DisplayProducer (ui/display_producer.h): the render thread, the viewport's images
//   (Gouraud and the other traced modes, the edge-and-point display);
// - HolodeckService (ui/holodeck_service.h): the ray cache the display's views start from;
// - InterpolantService (ui/interpolant_service.h): the high-fidelity interpolants' builds.
// They talk through the EditEvents the solver worker hands its listeners (ui/shared_session.h)
// and the snapshots on the board (ui/runner_board.h), which the UI reads every frame.
//
// Locking (the order is top to bottom; nothing is taken while a lock lower down is held):
//   lock                     solver worker        render thread         others
//   SharedSession::structure exclusive: edits     shared: a frame       shared: holodeck work,
//                                                 (released while the   interpolant and display
//                                                 EPI reconstructs)     builds; UI: pick
//   DisplayProducer display  with the structure:  every call on the     —
//                            events to the        display
//                            display, its shader
//                            paused
//   service queues           takes edits, flags   view request          UI: submit, setView
//   RunnerBoard              publishes light,     publishes the image   UI: reads snapshots
//                            document, figures
// A shot takes no lock: it reads the structure, which only the solver worker changes, and
// writes the solver's own arrays, which the other threads see only as published copies.
// With `threaded` false nothing runs in the background and pump() does one iteration of
// each (tests, deterministic stepping). Adaptive element subdivision (which rebuilds the
// tracer inside a shot) must be off: interactiveSolverOptions() has it off.

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "ui/picking.h"
#include "ui/runner_board.h"
#include "ui/shared_session.h"

namespace penumbra {

class SolverWorker;
class DisplayProducer;
class HolodeckService;
class InterpolantService;

struct SessionRunnerOptions {
    bool threaded = true;
    double solveBudgetMs = 12;  ///< solver time per worker iteration
    double convergeEps = 1e-3;  ///< auto-solve stops at unshotFraction ≤ eps, nothing pending
    double interactiveImageMs = 40;  ///< interactive traced images: resolution for this time
    int maxReducedDivisor = 8;       ///< at most width / d × height / d pixels fewer
    int displayDivisor = 1;          ///< display modes: viewport / d pixels (rounded to 4)
    double displayFrameMs = 30;      ///< display modes: at least this long between frames
    int settleFrames = 40;           ///< display modes: frames before quiescent()
    int referenceDivisor = 4;  ///< difference mode: reference at display / d pixels
    /// Interpolant mode: far-field rays per exact irradiance sample (ExactIrradianceOptions::
    /// farRays, as `render --mode interpolant`).
    int hifiGatherRays = 256;
    /// Scheduling priorities (threaded runners; Linux nice values relative to the UI thread,
    /// 0 leaves a thread level with it). The window and the viewport's lit images come first:
    /// the render thread, which makes them, runs at renderNice (0: level with the UI thread);
    /// the work behind them yields to both: the display's shading workers, the solver, the
    /// holodeck and the interpolant builds run at backgroundNice, and the solver's and the
    /// holodeck's parallel work in low-priority oneTBB arenas (ServiceThread), so the shared
    /// worker threads take a frame's parallel stages first. On a busy machine a drag so gets
    /// its frames ahead of the solver's shots.
    int renderNice = 0;
    int backgroundNice = 5;
    /// The holodeck file (docs/holodeck.md) the display modes start their views from and store
    /// their converged points in, "" for none; created with the scene's sections when missing.
    /// One that cannot be opened is one warning line (spdlog; SolverSnapshot::holodeck says
    /// why) and the runner goes on without it.
    std::string holodeck;
    /// After edits, the relative change of an element's light that makes the holodeck forget
    /// the samples on it (changedElements; replay --holodeck-threshold).
    double holodeckThreshold = 0.01;
};

class SessionRunner {
public:
    SessionRunner(std::unique_ptr<EditSession> session, SessionRunnerOptions options = {});
    ~SessionRunner();
    SessionRunner(const SessionRunner&) = delete;
    SessionRunner& operator=(const SessionRunner&) = delete;

    /// Queues an edit; the solver worker applies it in order. An invalid edit is reported
    /// through takeMessages() and changes nothing (EditSession::apply validates first).
    void submit(const EditCommand& command, const EditSource& source = {});
    /// Like submit, but replaces a queued, not yet applied transform of the same object
    /// (a drag sends positions faster than the lighting can follow; only the newest counts).
    void submitCoalescing(const EditCommand& command);
    /// Queues a task on the session (save, export), run by the solver worker between shots, in
    /// order with the edits. Exceptions are reported through takeMessages(). A task must not
    /// change the lit scene (an edit made there is submitMade): the services hear only of edits.
    void post(std::function<void(EditSession&)> task);
    /// Queues an edit that the solver worker makes when its turn comes, from the session as it
    /// is then (a duplicate of an object as the edits before it left it, a mesh loaded there),
    /// and applies like a submitted one. Exceptions are reported through takeMessages().
    void submitMade(std::function<EditCommand(EditSession&)> make);
    /// Like post, for a task that writes the document to a file (File ▸ Save): when
    /// `holodeckScene` (the file is the scene the holodeck belongs to) and the task succeeds,
    /// the holodeck takes the display's points again (post() leaves it as it was).
    void postSave(std::function<void(EditSession&)> task, bool holodeckScene);
    void setView(const ViewRequest& request);
    /// Pauses the automatic solver work (queued edits, including solve/converge, still run).
    void setPaused(bool paused);
    bool paused() const;
    /// Automatic solver work on/off (off while a log is played, so the replay shoots exactly
    /// what its solve/converge lines say).
    void setAutoSolve(bool on);
    void setConvergeEps(double eps);
    /// Switches George et al.'s interleaving strategy (one: redistribute first down to
    /// `threshold` × emitted power, two: interleave) and strategy one's threshold. Thread-safe;
    /// the solver worker applies it between shots (ProgressiveSolver::setStrategy), before the
    /// next queued edit or shot. Throws std::invalid_argument unless threshold is in [0, 1].
    void setStrategy(RedistributionStrategy strategy, double threshold);
    /// The strategy and threshold last requested (setStrategy, or the solver's options at
    /// construction); SolverSnapshot::strategy says what the solver applied.
    RedistributionStrategy strategy() const;
    double redistributionThreshold() const;

    /// The object under a pixel (picking.h), against the current structure; waits only for
    /// an edit being applied, never for a shot.
    Pick pick(const Camera& camera, int width, int height, double px, double py);

    /// One iteration of each service in the calling thread (only when not threaded).
    void pump();

    std::shared_ptr<const ViewportImage> image() const { return mBoard.image(); }
    SolverSnapshot solver() const { return mBoard.solver(); }
    /// The lighting the solver worker last published (what the display services read).
    PublishedLight light() const { return mBoard.light(); }
    std::shared_ptr<const DocumentSummary> document() const { return mBoard.document(); }
    /// Error and status lines since the last call.
    std::vector<std::string> takeMessages() { return mBoard.takeMessages(); }
    bool hasMessages() const { return mBoard.hasMessages(); }
    /// Commands queued and not yet applied.
    std::size_t queued() const;
    /// Nothing queued, no solver work pending, no drag, and the image shows the current
    /// lighting and the latest view at full resolution (display modes: for settleFrames;
    /// the interpolant mode: its interpolants).
    bool quiescent() const;

private:
    SessionRunnerOptions mOptions;
    SharedSession mShared;
    RunnerBoard mBoard;
    // ~SessionRunner stops the solver worker and the render thread first; the services are
    // then destroyed in reverse order, the display before the holodeck and the interpolants
    // it uses, the holodeck last (it stores what it was handed and flushes its file).
    std::unique_ptr<HolodeckService> mHolodeck;
    std::unique_ptr<InterpolantService> mHifi;
    std::unique_ptr<DisplayProducer> mDisplay;
    std::unique_ptr<SolverWorker> mSolver;
};

}  // namespace penumbra
