#pragma once
// Runs an EditSession for the editor without blocking the frame loop.
//
// EditSession is not thread-safe (plain members, no locks) and one solver shot cannot be
// interrupted (ProgressiveSolver::step(1) is one shot, long in a large scene, longest for a
// stochastic tail batch). So:
// - the solver thread owns the session: it applies queued edits and tasks, then shoots one
//   shot at a time for a time budget, publishing a copy of the display radiosity as it goes;
// - the render thread draws the viewport image from the latest published radiosity while
//   shots run: shots only read the discretization and the tracer (Embree queries are
//   thread-safe) and write the solver's own arrays, which the render thread never reads;
// - structural changes (edits: new object versions, tracer updates) take mStructure
//   exclusively; rendering and picking take it shared. The frame loop therefore waits for
//   nothing but, when picking, for an edit being applied. A display frame releases it (and
//   mDisplayMutex) while its edge-and-point image is reconstructed (InteractiveDisplay::
//   reconstructFrame touches nothing an edit changes): an edit waits for a frame step.
// View modes (ui/view_mode.h) other than Gouraud and out-of-date use an InteractiveDisplay
// (Bala et al. 2003) owned by the render thread, shading asynchronously on its own workers:
// the render thread renders a frame whenever it can (the cache reprojects on camera moves);
// the solver thread hands it each published solution (updateSolution, between shots, under
// mDisplayMutex) and, with the display's shader paused, tells it what an edit changed
// (notifyChanged) while holding mStructure exclusively.
// An edit reaches the displays as the EditEvent EditSession::apply returns (the solver took
// the same event inside apply): applyDisplayEvent hands it to each live display
// (InteractiveDisplay::apply) and keeps the drag's tracer subsets in step with it.
// The holodeck (Ward & Simmons 1999; docs/holodeck.md), when the options name one, belongs to
// the solver thread alone (HoloServer is not thread-safe), which serves it between shots: it
// opens the file, answers a new display's request for its view's samples (the render thread
// puts them into the display before its first frame, waiting for them at most
// kHolodeckWaitMs), stores the points a display shaded from the converged solution once the
// view rested (handed over by the render thread), and, once the solution converges after
// edits, forgets what they changed (HoloServer::invalidate). Requests, answers and points to
// store pass under mQueueMutex. While edits wait for that invalidation the holodeck is neither
// read nor written; new points are stored only while the document is the one in the scene
// file the holodeck belongs to (no edits since it was opened or saved there).
//
// Locking (enforced here; the order is top to bottom, nothing is taken while a lock lower
// in the table is held):
//   lock           solver thread                  render thread                  UI thread
//   mStructure     exclusive: edits, tasks        shared: a frame (released      shared: pick
//                  (solverIteration)              while the EPI reconstructs),
//                                                 display and interpolant builds
//   mDisplayMutex  with mStructure: events to     every call on a display; the   —
//                  the displays, shaders paused;  interpolants' edits (a build
//                  edits for the interpolants     takes, a landed one drops them)
//   mQueueMutex    takes the queue and flags      reads the view request         submit, setView,
//                                                                                flags
//   mPublishMutex  publishes light, document,     publishes the image            reads snapshots
//                  solver figures
// A shot takes no lock: it reads the structure, which only the solver thread changes, and
// writes the solver's own arrays, which the render thread sees only as published copies.
// With `threaded` false nothing runs in the background and pump() does one iteration of
// each (tests, deterministic stepping). Adaptive element subdivision (which rebuilds the
// tracer inside a shot) must be off: interactiveSolverOptions() has it off.
//
// Index: snapshots · options · SessionRunner

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <future>
#include <memory>
#include <mutex>
#include <optional>
#include <shared_mutex>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "edit/edit_session.h"
#include "render/hifi_mesh.h"
#include "render/holodeck/holo_file.h"
#include "render/holodeck/holo_server.h"
#include "render/interactive_display.h"
#include "ui/picking.h"
#include "ui/view_mode.h"
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
    ViewMode mode = ViewMode::Gouraud;
    /// The drag preview version it shows (the dragged object's position), -1 none.
    int previewVersion = -1;
    /// The object dragged in the state shown ("" when none) and its document transform there:
    /// with the scene file, the edit that reproduces what the image shows.
    std::string dragged;
    Transform draggedTransform;
    /// Display modes: display frames rendered with this view and lighting (the cache fills).
    int settledFrames = 0;
    DisplayFrameStats display;   ///< display modes: the last frame's figures
    /// Display modes: points the shown display took from the holodeck (before its first frame).
    std::int64_t holodeckPoints = 0;
    double meanDifference = -1;  ///< difference mode: mean sRGB |epi − reference|, -1 none
    std::string note;            ///< what the viewport should say about the image
};

/// The holodeck as the status line shows it.
struct HolodeckStatus {
    std::string path;           ///< "" when the runner has none
    bool open = false;          ///< opened (false before, or when it could not be: `error`)
    std::string error;          ///< why it could not be opened
    std::int64_t samples = 0;   ///< stored, after the last commit
    std::int64_t served = 0;    ///< samples handed to displays as points
    std::int64_t stored = 0;    ///< display points stored since the runner opened it
    std::int64_t invalidated = 0;  ///< samples dropped after edits since then
    /// "holodeck: N samples" (with what this runner took and gave), "" without one.
    std::string toString() const;
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
    /// George et al.'s interleaving strategy and threshold the solver uses now (applied).
    RedistributionStrategy strategy = RedistributionStrategy::RedistributeFirst;
    double redistributionThreshold = 0;
    HolodeckStatus holodeck;
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
    ViewMode mode = ViewMode::Gouraud;
    /// Difference mode: a new reference is computed whenever this grows.
    std::uint64_t referenceRequest = 0;
    std::uint64_t serial = 0;  ///< set by setView
};

// ---------------------------------------------------------------------------------------------
// SessionRunner.

struct SessionRunnerOptions {
    bool threaded = true;
    double solveBudgetMs = 12;  ///< solver time per worker iteration
    double convergeEps = 1e-3;  ///< auto-solve stops at unshotFraction ≤ eps, nothing pending
    double interactiveImageMs = 40;  ///< interactive images: resolution for about this time
    int maxReducedDivisor = 8;       ///< at most width / d × height / d pixels fewer
    int displayDivisor = 1;          ///< display modes: viewport / d pixels (rounded to 4)
    double displayFrameMs = 30;      ///< display modes: at least this long between frames
    int settleFrames = 40;           ///< display modes: frames before quiescent()
    /// Display modes while the view is interactive: 1 (the default) keeps the one display at
    /// its resolution, a moving view or a drag costing samples per frame, not pixels; d ≥ 2
    /// shows a second display at viewport / (displayDivisor · d) pixels instead; 0 picks d from
    /// the full display's frame time so a frame takes about interactiveImageMs (2 ≤ d ≤
    /// maxReducedDivisor).
    int interactiveDisplayDivisor = 1;
    int referenceDivisor = 4;  ///< difference mode: reference at display / d pixels
    /// Interpolant mode: far-field rays per exact irradiance sample (ExactIrradianceOptions::
    /// farRays, as `render --mode interpolant`).
    int hifiGatherRays = 256;
    /// Linux nice increment of the solver, render and display-shading threads (threaded
    /// runners): the UI thread keeps its frame rate on a busy machine. 0 leaves them as is.
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

    /// Queues an edit; the solver thread applies it in order. An invalid edit is reported
    /// through takeMessages() and changes nothing (EditSession::apply validates first).
    void submit(const EditCommand& command, const EditSource& source = {});
    /// Like submit, but replaces a queued, not yet applied transform of the same object
    /// (a drag sends positions faster than the lighting can follow; only the newest counts).
    void submitCoalescing(const EditCommand& command);
    /// Queues work on the session (save, export), run by the solver thread between shots, in
    /// order with the edits. Exceptions are reported through takeMessages(). A task that edits
    /// should be an edit made there (submitMade): the displays see a task's changes only as
    /// "anything may have changed".
    void post(std::function<void(EditSession&)> task);
    /// Queues an edit that the solver thread makes when its turn comes, from the session as it
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
    /// the solver thread applies it between shots (ProgressiveSolver::setStrategy), before the
    /// next queued edit or shot. Throws std::invalid_argument unless threshold is in [0, 1].
    void setStrategy(RedistributionStrategy strategy, double threshold);
    /// The strategy and threshold last requested (setStrategy, or the solver's options at
    /// construction); SolverSnapshot::strategy says what the solver applied.
    RedistributionStrategy strategy() const;
    double redistributionThreshold() const;

    /// The object under a pixel (picking.h), against the current structure; waits only for
    /// an edit being applied, never for a shot.
    Pick pick(const Camera& camera, int width, int height, double px, double py);

    /// One solver iteration and one render in the calling thread (only when not threaded).
    void pump();

    std::shared_ptr<const ViewportImage> image() const;
    SolverSnapshot solver() const;
    std::shared_ptr<const DocumentSummary> document() const;
    /// Error and status lines since the last call.
    std::vector<std::string> takeMessages();
    bool hasMessages() const;
    /// Commands queued and not yet applied.
    std::size_t queued() const;
    /// Nothing queued, no solver work pending, no drag, and the image shows the current
    /// lighting and the latest view at full resolution (display modes: for settleFrames;
    /// the interpolant mode: its interpolants).
    bool quiescent() const;

private:
    struct Light {
        std::shared_ptr<const std::vector<Rgb>> radiosity;  ///< displayRadiosity()
        /// Per element: |unshot radiosity| of its patch (pending shooting/redistribution).
        std::shared_ptr<const std::vector<Rgb>> pending;
        double pendingScale = 0;  ///< radiosity luminance that tints fully
        int previewVersion = -1;
        /// The display modes' solution: ProgressiveSolver::irradiance(),
        /// irradianceFromEmission() and, while dragging, previewRadiosity() and
        /// previewRadiosityFromEmission() (copies: the render thread updates its displays
        /// from them).
        std::shared_ptr<const std::vector<Rgb>> irradiance, fromEmission, previewBuffer,
            previewFromEmission;
        bool previewComplete = false;  ///< ProgressiveSolver::previewComplete()
        /// Converged at the runner's threshold, nothing pending, no drag: what the holodeck may
        /// keep.
        bool converged = false;
        std::uint64_t serial = 0;
    };
    void runSolver();
    void runRender();
    /// Edits, tasks and a budget of shots; returns whether anything was done.
    bool solverIteration();
    /// Renders if the light or the view changed; returns whether it rendered.
    bool renderIteration();
    /// What renderIteration found for the ray-traced modes: the interpolant mesh (when the
    /// interpolant mode has one), its build's note, and whether a display or mesh is still
    /// loading (Gouraud is shown meanwhile).
    struct TracedView {
        const HifiMesh* hifi = nullptr;
        std::string hifiNote;
        bool loading = false;
    };
    /// renderIteration for the ray-traced modes (Gouraud, out of date, interpolants, and the
    /// display modes while their display loads), at a reduced resolution while interactive.
    bool renderTracedView(const ViewRequest& view, const Light& light,
                          const std::shared_ptr<const ViewportImage>& last, int highlight,
                          const TracedView& traced);
    /// The divisor of the view's resolution that renders in about interactiveImageMs while
    /// the view is interactive; 1 otherwise.
    int reducedDivisor(const ViewRequest& view) const;
    /// `values` over every element: a drag appends a version (its elements) before the solver
    /// publishes lighting for it, so elements of versions the image does not show (dead, not
    /// `previewVersion`) get 0; any other gap gives null (wait for the next lighting).
    std::shared_ptr<const std::vector<Rgb>> coverElements(
        const std::shared_ptr<const std::vector<Rgb>>& values, int previewVersion) const;
    /// Traces the ray-traced image into `img` (its render and note); false, reported, when
    /// rendering threw.
    bool traceImage(const ViewRequest& view, const Light& light, int w, int h, int highlight,
                    const HifiMesh* hifi, const std::vector<Rgb>& radiosity,
                    const std::vector<Rgb>* pending, ViewportImage& img);
    /// Whether a display exists for the display modes; starts building the first one in the
    /// background (threaded runners) and installs it when done (structure held shared).
    bool displayLanded(const ViewRequest& view);
    /// The options of display slot 0 (full) or 1 (reduced) for `view`.
    InteractiveDisplayOptions displayOptions(int slot, const ViewRequest& view) const;
    /// renderIteration for the display modes (`structure` held shared: released while the
    /// frame's image is reconstructed, so that an edit waits for a frame step, not a frame).
    bool renderDisplay(const ViewRequest& view, const Light& light,
                       const std::shared_ptr<const ViewportImage>& last, int highlight,
                       std::shared_lock<std::shared_mutex>& structure);
    /// Interpolant mode (render thread): the mesh of `light`'s lighting when one is built;
    /// otherwise starts or follows its build (in the background once the lighting is still:
    /// `still`) and says how far it got in `note`.
    const HifiMesh* hifiLanded(const ViewRequest& view, const Light& light, bool still,
                               std::string& note);
    /// What a build starts from: the mesh shown last (null: none, a full build), the lighting
    /// it was built of and the versions edits changed since (HifiMesh::update re-meshes only
    /// what they and the new lighting changed).
    struct HifiBase {
        std::shared_ptr<const HifiMesh> mesh;
        std::shared_ptr<const std::vector<Rgb>> radiosity;
        std::vector<int> changed;
    };
    /// The build itself (any thread): the interpolants of the structure now and `radiosity`;
    /// null when an edit came first. buildHifi takes the structure shared; buildHifiHeld is
    /// for a caller that holds it already (a shared_mutex must not be locked twice by one
    /// thread).
    std::unique_ptr<HifiMesh> buildHifi(std::shared_ptr<const std::vector<Rgb>> radiosity,
                                        HifiBase base);
    std::unique_ptr<HifiMesh> buildHifiHeld(std::shared_ptr<const std::vector<Rgb>> radiosity,
                                            const HifiBase& base);
    /// The base of a new build of the mesh shown (render thread).
    HifiBase hifiBase();
    /// A build landed: `mesh` of lighting `serial` (`radiosity`) is shown and the base of the
    /// next (render thread).
    void landHifi(std::unique_ptr<HifiMesh> mesh, std::uint64_t serial,
                  std::shared_ptr<const std::vector<Rgb>> radiosity);
    void publishDocument();
    void publishLight();
    void publishSolver(double solverMs);
    void report(const std::string& message);

    std::unique_ptr<EditSession> mSession;
    SessionRunnerOptions mOptions;
    std::shared_mutex mStructure;  ///< exclusive: edits; shared: rendering, picking

    mutable std::mutex mQueueMutex;       ///< guards the queue, view request and flags
    std::condition_variable mWake;        ///< solver thread
    std::condition_variable mRenderWake;  ///< render thread
    /// An edit, an edit to make (`make`), or a task (`task`).
    struct Queued {
        EditCommand command;
        EditSource source;
        std::function<void(EditSession&)> task;
        std::function<EditCommand(EditSession&)> make;
        bool savesHolodeckScene = false;  ///< postSave for the holodeck's scene
    };
    std::deque<Queued> mQueue;
    /// What one solver iteration takes from the queue and flags (under mQueueMutex).
    struct SolverWork {
        std::deque<Queued> commands;
        bool solve = false;
        double eps = 0;
        std::optional<std::pair<RedistributionStrategy, double>> strategy;
    };
    /// Applies a batch of edits and tasks with the structure exclusive and the displays'
    /// shaders paused, hands the events to the displays, then publishes the new state.
    void applyCommands(std::deque<Queued>& commands);
    /// After a task (which may have changed anything): the live displays recompute; the
    /// others are marked behind.
    void notifyStructuralChange();
    /// Drops the visibility subsets no display uses any more and makes the occluder subsets
    /// the displays ask for.
    void pruneSubsets();
    /// Shoots one shot at a time until `t0` + the solve budget, or until converged to `eps`
    /// (not while dragging); publishes the light as it goes. Returns the shots.
    std::uint64_t shootForBudget(bool solve, double eps, double t0);
    ViewRequest mView;
    std::uint64_t mViewSerial = 0;
    bool mPaused = false;
    bool mAutoSolve = true;
    double mEps = 1e-3;
    RedistributionStrategy mStrategy = RedistributionStrategy::RedistributeFirst;
    double mThreshold = 0;
    bool mStrategyChanged = false;  ///< the solver thread has not applied mStrategy yet
    bool mStop = false;
    bool mApplying = false;

    mutable std::mutex mPublishMutex;  ///< guards the published snapshots
    std::shared_ptr<const ViewportImage> mImage;
    std::shared_ptr<const DocumentSummary> mDocument;
    SolverSnapshot mSolver;
    Light mLight;
    std::vector<std::string> mMessages;

    // Solver-thread state.
    std::uint64_t mDocumentSerial = 0;
    std::uint64_t mLightSerial = 0;
    std::uint64_t mLastShots = 0;
    double mLastRateTime = 0, mLastHistoryTime = 0, mShotsPerSecond = 0;
    std::vector<float> mHistory;
    bool mSolverIdle = false;
    double mSolveEps = 1e-3;  ///< the threshold of the last iteration (Light::converged)

    // The holodeck. The requests and points pass under mQueueMutex; the file, the server and
    // the rest are the solver thread's alone (the destructor's once it joined).
    /// A display's request for its view's samples (render thread to solver thread).
    struct HoloRead {
        std::uint64_t id = 0;
        Camera camera;
        int width = 0, height = 0;
    };
    /// Its answer: points stamped with frame and shading 0 (the display stamps its own).
    struct HoloPoints {
        std::uint64_t id = 0;
        std::vector<ShadedPoint> points;
    };
    /// Points a display shaded from the converged light `lightSerial`, seen from `eye`.
    struct HoloStore {
        std::vector<CachePoint> points;
        Vec3 eye{0.0};
        std::uint64_t lightSerial = 0;
    };
    std::optional<HoloRead> mHoloRead;      ///< under mQueueMutex
    std::optional<HoloPoints> mHoloPoints;  ///< under mQueueMutex
    std::vector<HoloStore> mHoloStores;     ///< under mQueueMutex
    std::uint64_t mHoloReadIds = 0;         ///< render thread
    /// The holodeck's work between shots: opens it, invalidates after edits once the solution
    /// converged, answers the read and stores the points waiting. Returns whether it did work.
    bool holodeckIteration();
    void openHolodeck();
    /// Forgets what the edits since the last invalidation changed: the elements whose light
    /// moved beyond the threshold, or every element's when that is not known.
    void invalidateHolodeck(bool everyElement);
    /// A save of the holodeck's scene file succeeded (in applyCommands).
    void holodeckSaved();
    /// Stores what was handed over, makes the file match the scene file and flushes it
    /// (the destructor, threads joined).
    void closeHolodeck();
    /// Stores the points handed over (solver thread, or the destructor).
    void storeHolodeckPoints(std::vector<HoloStore>& stores);
    std::vector<ShadedPoint> holodeckPointsOf(const HoloRead& read);
    void publishHolodeck();
    std::optional<HoloFile> mHoloFile;
    std::unique_ptr<HoloServer> mHoloServer;
    HolodeckStatus mHoloStatus;  ///< published with the solver snapshot
    bool mHoloTried = false;
    /// Edits applied since the holodeck last matched the solution (invalidated when it next
    /// converges); while set, the holodeck is neither read nor written.
    bool mHoloDirty = false;
    /// Edits since the document was the holodeck's scene file (opened or saved there): no
    /// new points go in.
    bool mHoloUnsaved = false;
    /// The scene file was saved with edits the holodeck had not yet forgotten: it matches the
    /// file again only when it forgets them with nothing edited since the save (otherwise it
    /// forgets every element's light).
    bool mHoloBehindFile = false;
    /// Element luminance of the solution the holodeck matches (empty before it first
    /// converged).
    std::vector<double> mHoloLuminance;
    // Render-thread state.
    double mMsPerPixel = 0;        ///< running estimate of the render cost
    double mLastLoadingImage = 0;  ///< the last Gouraud image while the display is built
    /// The selection and its transform in the state being rendered (ViewportImage::dragged).
    std::string mRenderDragged;
    Transform mRenderDraggedTransform;
    // The displays (created by the render thread; every call under mDisplayMutex). Slot 0
    // renders at displayDivisor; slot 1, while the view is interactive (camera moves, drags),
    // at a reduced resolution: an InteractiveDisplay's size is fixed, so each keeps its cache.
    // Only the live slots (the one shown and the one wanted next) take edits as they come; the
    // other collects them (behind) and the render thread brings it up to date (catchUpDisplay)
    // before it switches to it. Solutions reach the displays through the published Light: the
    // render thread updates them itself, so the solver thread never waits for a frame between
    // shots (it takes the display mutex only to apply edits).
    struct DisplaySlot {
        std::unique_ptr<InteractiveDisplay> display;
        int viewWidth = 0, viewHeight = 0;  ///< the viewport size it was made for
        std::uint64_t solution = 0;         ///< Light::serial of its solution, 0 none yet
        bool behind = false;                ///< missed edits (pendingChanged, the preview)
        std::vector<int> pendingChanged;
        bool pendingStructural = false;
        double frameMs = 0;  ///< running estimate of its frame time
        int frames = 0;      ///< frames rendered
        // The holodeck (slot 0): the read it waits for (0 none) and since when; the points it
        // took or handed over to be stored (where they are: the pixels they project to in a
        // view take no other); the
        // first cache frame whose points were shaded from the converged light `convergedLight`;
        // the view and light it last handed points of.
        std::uint64_t holoRead = 0;
        double holoReadTime = 0;
        std::int64_t holoPoints = 0;
        std::vector<Vec3> holoPositions;
        std::uint64_t convergedLight = 0, convergedFrame = 0;
        std::uint64_t storedView = 0, storedLight = 0;
        bool ready() const { return display && !behind && solution != 0; }
    };
    /// Hands an edit's event to the live displays (InteractiveDisplay::apply) and marks the
    /// others behind (solver thread, structure exclusive, display mutex held, shaders paused);
    /// keeps the drag's subsets in step with it.
    void applyDisplayEvent(const EditEvent& event);
    /// Brings a slot up to date: missed edits, then `light`'s solution (render thread,
    /// structure shared, display mutex held).
    void catchUpDisplay(DisplaySlot& slot, const Light& light);
    bool liveSlot(int i) const { return i == mActiveSlot || i == mWantedSlot; }
    /// Makes display slot `make` for `view` (render thread, display mutex held): a copy of
    /// the other slot's display when that one is up to date, built from the structure
    /// otherwise; false, reported, when it failed.
    bool makeDisplay(int make, const ViewRequest& view);
    /// The display mode's layer over a frame of `slot`'s display: its edges, its new samples,
    /// or the difference from a reference of the same view (computed once the solver is idle).
    void overlayDisplayMode(const ViewRequest& view, const Light& light, DisplaySlot& slot,
                            ViewportImage& img);
    /// The holodeck's part of a new slot-0 display: asks the solver thread for `camera`'s
    /// samples at w × h (render thread, display mutex held; `id` an earlier request's).
    void requestHolodeckPoints(DisplaySlot& slot, const Camera& camera, int w, int h,
                               std::uint64_t id = 0);
    /// Puts the answer into the slot's display when it came; false while the display's first
    /// frame should still wait for it (at most kHolodeckWaitMs).
    bool takeHolodeckPoints(DisplaySlot& slot);
    /// Once the view rested on the converged light, hands the display's points shaded from it
    /// (and not from the holodeck), at most one per pixel the holodeck does not show yet, to
    /// the solver thread to store.
    void handHolodeckPoints(const ViewRequest& view, const Light& light, DisplaySlot& slot,
                            int settledFrames, const CameraRays& rays);
    std::mutex mDisplayMutex;
    DisplaySlot mSlots[2];
    /// The first display, built on a thread of its own (displayLanded).
    struct BuiltDisplay {
        std::unique_ptr<InteractiveDisplay> display;
        std::uint64_t edits = 0;  ///< mEditBatches when it was built
        int viewWidth = 0, viewHeight = 0;
    };
    std::future<BuiltDisplay> mBuild;
    std::uint64_t mBuildHoloRead = 0;  ///< the holodeck read asked for the display being built
    std::uint64_t mEditBatches = 0;  ///< edit batches applied (written under mStructure exclusive)
    int mActiveSlot = 0;             ///< the slot rendered
    int mWantedSlot = 0;             ///< the slot the view asks for (1 while interactive)
    double mLastDisplayFrame = 0;
    /// A RayTracer subset admitting one object version alone.
    struct VersionSubset {
        int version = -1;
        RayTracer::SubsetHandle handle;
        VersionSubset() = default;
        VersionSubset(RayTracer& tracer, int v) : version(v), handle(tracer, {v}) {}
        Visibility visibility() const { return handle.visibility(); }
    };
    /// The subset of the version the drag previews (EditSession::previewVersion(), which the
    /// solver holds); written by the solver thread with mStructure held exclusively and the
    /// displays' shaders paused.
    VersionSubset mPreviewSubset;
    /// Previous previews' subsets a display's background estimate still traces
    /// (InteractiveDisplay::directJobPreview), released at a later edit.
    std::vector<VersionSubset> mOldSubsets;
    /// Subsets of the objects the displays hide points behind (InteractiveDisplay::occluder);
    /// same thread and lock as mPreviewSubset.
    std::vector<VersionSubset> mOccluderSubsets;
    /// The drag's origin (the version selected) alone, for the displays' drag estimates; earlier
    /// drags' origins while a display (one that missed their end) may still use them.
    VersionSubset mOriginSubset;
    std::vector<VersionSubset> mOldOrigins;
    Image mReference;  ///< difference mode
    Camera mReferenceCamera;
    std::uint64_t mReferenceDone = 0;
    // Interpolant mode. The build runs on a thread of its own holding the structure shared;
    // an edit waiting for it (mEditsWaiting) or newer lighting (mHifiOutdated) stops it
    // between elements, so an edit waits for one element's samples, not the build.
    std::shared_ptr<const HifiMesh> mHifi;  ///< the mesh shown, of lighting mHifiSerial
    std::uint64_t mHifiSerial = 0;
    /// The lighting mHifi was built of, and how many of mHifiChanged its build had taken in.
    std::shared_ptr<const std::vector<Rgb>> mHifiRadiosity;
    std::size_t mHifiBuildChanges = 0;
    /// The versions edits changed since mHifi was built (EditEvent::changed()): the solver
    /// thread appends, the render thread takes them for a build and drops those a landed build
    /// took in; both under mDisplayMutex.
    std::vector<int> mHifiChanged;
    std::shared_ptr<const std::vector<Rgb>> mHifiBuildRadiosity;  ///< the lighting being built
    std::future<std::unique_ptr<HifiMesh>> mHifiBuild;
    std::uint64_t mHifiBuildSerial = 0;  ///< the lighting being built
    std::atomic<double> mHifiProgress{0};
    std::atomic<bool> mHifiOutdated{false};
    std::atomic<int> mEditsWaiting{0};  ///< edit batches waiting for the structure

    std::thread mSolverThread, mRenderThread;
};

}  // namespace penumbra
