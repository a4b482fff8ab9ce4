#pragma once
// Runs an EditSession for the editor without blocking the frame loop.
//
// EditSession is not thread-safe (plain members, no locks), so one worker thread owns it and
// everything touching it is serialized by one mutex: the worker applies queued edit commands,
// shoots for a time budget, renders the viewport image, and publishes snapshots (the lit
// image, solver figures, a light document summary) that the frame loop reads without waiting.
// The frame loop only takes the session lock for rare, short work (picking on click, save,
// export) through withSession(). With `threaded` false nothing runs in the background and
// pump() does one worker iteration (tests, deterministic stepping).
//
// Index: snapshots · options · SessionRunner

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "edit/edit_session.h"
#include "ui/viewport_renderer.h"

namespace penumbra {

// ---------------------------------------------------------------------------------------------
// Snapshots.

/// The viewport image of one worker iteration.
struct ViewportImage {
    ViewportRender render;
    Camera camera;                  ///< the view it shows
    std::uint64_t viewSerial = 0;   ///< ViewRequest serial it answers
    std::uint64_t stateSerial = 0;  ///< document/lighting state it shows
    bool reduced = false;           ///< rendered at reduced resolution (interaction)
    double renderMs = 0;
};

/// Solver figures for the solver panel.
struct SolverSnapshot {
    std::uint64_t shots = 0, rays = 0, redistributionShots = 0;
    double shotsPerSecond = 0;
    double unshotFraction = 0;
    double pendingRedistribution = 0;  ///< W
    double emittedEnergy = 0;          ///< W
    std::size_t pendingChanges = 0;
    std::size_t elements = 0, patches = 0;  ///< in the solution
    bool converged = false;                 ///< at the runner's threshold, nothing pending
    bool idle = false;           ///< no solver work happening (converged, paused or auto-solve off)
    std::vector<float> history;  ///< log10 of unshot fraction, sampled about every 100 ms
    std::size_t undoDepth = 0, redoDepth = 0;
    std::string selected;  ///< EditSession::selected() (the object being dragged)
    int previewVersion = -1;
    double solverMsPerIteration = 0;
};

/// What the UI shows of one document object.
struct ObjectSummary {
    std::string id;
    int version = -1;
    ShapeType shape = ShapeType::Box;
    std::string material;  ///< scene material name, "" for mesh-file materials
    Material materialValue;
    Transform transform;
    Vec3 boundsMin{0.0}, boundsMax{0.0};  ///< world-space bounds of the current version
};

/// The document as the UI reads it every frame (not a copy of the Scene: no meshes).
struct DocumentSummary {
    std::uint64_t serial = 0;
    std::vector<ObjectSummary> objects;
    std::vector<NamedMaterial> materials;
    std::vector<Camera> cameras;
    const ObjectSummary* find(const std::string& id) const;
};

/// What the viewport wants rendered.
struct ViewRequest {
    Camera camera;
    int width = 0, height = 0;
    std::string highlight;     ///< object id outlined, "" for none
    bool interactive = false;  ///< render at reduced resolution (camera moving, dragging)
    std::uint64_t serial = 0;  ///< set by setView
};

// ---------------------------------------------------------------------------------------------
// SessionRunner.

struct SessionRunnerOptions {
    bool threaded = true;
    double solveBudgetMs = 12;  ///< solver time per worker iteration
    double convergeEps = 1e-3;  ///< auto-solve stops at unshotFraction ≤ eps, nothing pending
    int reducedDivisor = 2;     ///< interactive images: width / d × height / d
};

class SessionRunner {
public:
    SessionRunner(std::unique_ptr<EditSession> session, SessionRunnerOptions options = {});
    ~SessionRunner();
    SessionRunner(const SessionRunner&) = delete;
    SessionRunner& operator=(const SessionRunner&) = delete;

    /// Queues an edit; the worker applies it in order. An invalid edit is reported through
    /// takeMessages() and changes nothing (EditSession::apply validates first).
    void submit(const EditCommand& command, const EditSource& source = {});
    /// Like submit, but replaces a queued, not yet applied transform of the same object
    /// (a drag sends positions faster than the lighting can follow; only the newest counts).
    void submitCoalescing(const EditCommand& command);
    void setView(const ViewRequest& request);
    /// Pauses the automatic solver work (queued edits, including solve/converge, still run).
    void setPaused(bool paused);
    bool paused() const { return mPaused; }
    /// Automatic solver work on/off (off while a log is played, so the replay shoots exactly
    /// what its solve/converge lines say).
    void setAutoSolve(bool on);
    void setConvergeEps(double eps);

    /// One worker iteration in the calling thread (only when not threaded).
    void pump();

    std::shared_ptr<const ViewportImage> image() const;
    SolverSnapshot solver() const;
    std::shared_ptr<const DocumentSummary> document() const;
    /// Error and status lines since the last call.
    std::vector<std::string> takeMessages();
    /// Commands queued and not yet applied.
    std::size_t queued() const;
    /// Nothing queued, no solver work pending, and the image shows the current state and
    /// the latest view at full resolution.
    bool quiescent() const;

    /// Runs `f` with the session locked (waits for the worker's current step).
    void withSession(const std::function<void(EditSession&)>& f);

private:
    void run();
    /// One iteration; returns whether anything was done. Caller holds mSessionMutex.
    bool iterate();
    void publishDocument();
    void publishSolver(double solverMs);

    std::unique_ptr<EditSession> mSession;
    SessionRunnerOptions mOptions;

    std::mutex mSessionMutex;  ///< guards mSession

    mutable std::mutex mQueueMutex;  ///< guards the queue, view request, flags
    std::condition_variable mWake;
    std::deque<std::pair<EditCommand, EditSource>> mQueue;
    ViewRequest mView;
    std::uint64_t mViewSerial = 0;
    bool mPaused = false;
    bool mAutoSolve = true;
    double mEps = 1e-3;
    bool mStop = false;
    bool mApplying = false;  ///< the worker took commands it has not finished

    mutable std::mutex mPublishMutex;  ///< guards the published snapshots
    std::shared_ptr<const ViewportImage> mImage;
    std::shared_ptr<const DocumentSummary> mDocument;
    SolverSnapshot mSolver;
    std::vector<std::string> mMessages;

    // Worker-only state.
    std::atomic<std::uint64_t> mStateSerial{1};  ///< read by quiescent()
    std::uint64_t mDocumentSerial = 0;
    std::uint64_t mLastShots = 0;
    double mLastRateTime = 0, mLastHistoryTime = 0, mShotsPerSecond = 0;
    std::vector<float> mHistory;
    bool mSolverIdle = false;

    std::thread mThread;
};

}  // namespace penumbra
