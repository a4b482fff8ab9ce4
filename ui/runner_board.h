#pragma once
// What the editor's services publish and the UI thread reads: the document, the lighting, the
// solver's figures, the viewport image, the holodeck's status and error lines. Each value is
// an immutable snapshot (a shared pointer or a copy) swapped in under one mutex, so a reader
// never waits for work, only for a pointer copy (Dear ImGui's "minimize state
// synchronization": the UI keeps no shadow copy of the scene).
//
// Index: snapshot types · PublishedLight · RunnerBoard

#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "render/camera_rays.h"
#include "render/display/interactive_display.h"
#include "solver/progressive_solver.h"
#include "solver/scene.h"
#include "ui/view_mode.h"
#include "ui/viewport_renderer.h"

namespace penumbra {

// ---------------------------------------------------------------------------------------------
// Snapshot types.

/// The viewport image of one render iteration.
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
    /// SettlingEstimate::reflectedRms of the lighting last published (-1 before the first).
    double settlingRms = -1;
    /// settlingRms is below kSettledRms (render/settling_overlay.h) and no object is dragged.
    bool settled = false;
    /// Seconds from the last edit until the lighting settled; -1 while it settles, or before
    /// any edit.
    double settleSeconds = -1;
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

/// The same view of the scene: eye, look-at point, up and field of view (the name aside).
bool sameCamera(const Camera& a, const Camera& b);

/// What the viewport wants rendered.
struct ViewRequest {
    Camera camera;
    int width = 0, height = 0;
    std::string highlight;     ///< object id outlined, "" for none
    bool interactive = false;  ///< render at reduced resolution (camera moving, dragging)
    ViewMode mode = ViewMode::Gouraud;
    /// Difference mode: a new reference is computed whenever this grows.
    std::uint64_t referenceRequest = 0;
    /// View ▸ Overlay ▸ Settling: the settling estimate as a heat map over any mode's image
    /// (render/settling_overlay.h).
    bool settlingOverlay = false;
    std::uint64_t serial = 0;  ///< set by setView
    /// Everything but the serial is equal.
    bool sameAs(const ViewRequest& other) const;
};

// ---------------------------------------------------------------------------------------------
// PublishedLight.

/// The lighting the solver worker publishes after edits and shots (copies of the solver's
/// arrays: the render and holodeck threads read them while the solver shoots on).
struct PublishedLight {
    std::shared_ptr<const std::vector<Rgb>> radiosity;  ///< displayRadiosity()
    /// Per element: |unshot radiosity| of its patch (pending shooting/redistribution).
    std::shared_ptr<const std::vector<Rgb>> pending;
    double pendingScale = 0;  ///< radiosity luminance that tints fully
    /// Per element: SettlingEstimate::change (luminance, in every channel), interpolated like
    /// the image for the settling overlay; refreshed at most every few tenths of a second.
    std::shared_ptr<const std::vector<Rgb>> settling;
    /// Luminance below which a pixel's relative change is not measured (dark pixels): a
    /// hundredth of the mean element luminance.
    double settlingFloor = 0;
    int previewVersion = -1;
    bool dragging = false;  ///< an object is selected (EditSession::selected())
    /// The display modes' solution: ProgressiveSolver::irradiance(),
    /// irradianceFromEmission() and, while dragging, previewRadiosity() and
    /// previewRadiosityFromEmission().
    std::shared_ptr<const std::vector<Rgb>> irradiance, fromEmission, previewBuffer,
        previewFromEmission;
    bool previewComplete = false;  ///< ProgressiveSolver::previewComplete()
    /// Converged at the runner's threshold, nothing pending, no drag: what the holodeck may
    /// keep.
    bool converged = false;
    /// When converged: the solver's radiosity() (no ambient term), what the holodeck compares
    /// solutions by.
    std::shared_ptr<const std::vector<Rgb>> convergedRadiosity;
    std::uint64_t serial = 0;
    /// The display's view of it (InteractiveDisplay::apply(SolutionView)).
    SolutionView solutionView() const;
};

// ---------------------------------------------------------------------------------------------
// RunnerBoard.

/// The published snapshots, one mutex for all (held only to copy a pointer or a small value).
class RunnerBoard {
public:
    void setLight(PublishedLight light);
    PublishedLight light() const;
    std::uint64_t lightSerial() const;
    void setDocument(std::shared_ptr<const DocumentSummary> document);
    std::shared_ptr<const DocumentSummary> document() const;
    void setSolver(SolverSnapshot solver);
    /// The solver's figures with the holodeck's status.
    SolverSnapshot solver() const;
    void setHolodeck(HolodeckStatus status);
    void setImage(std::shared_ptr<const ViewportImage> image);
    std::shared_ptr<const ViewportImage> image() const;
    /// An error or status line for the UI.
    void report(const std::string& message);
    std::vector<std::string> takeMessages();
    bool hasMessages() const;
    /// The solver's idleness and selection, the image and the lighting serial, read together.
    struct Glance {
        bool solverIdle = false;
        std::string selected;
        std::shared_ptr<const ViewportImage> image;
        std::uint64_t lightSerial = 0;
    };
    Glance glance() const;

private:
    mutable std::mutex mMutex;
    PublishedLight mLight;
    std::shared_ptr<const DocumentSummary> mDocument;
    SolverSnapshot mSolver;
    HolodeckStatus mHolodeck;
    std::shared_ptr<const ViewportImage> mImage;
    std::vector<std::string> mMessages;
};

}  // namespace penumbra
