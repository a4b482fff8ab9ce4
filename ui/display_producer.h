#pragma once
// The display producer: the render thread that makes the viewport's images. The ray-traced
// modes (Gouraud, out of date, interpolants) trace an image whenever the lighting or the view
// changed, at a reduced resolution while the view is interactive. The display modes (View ▸
// Mode, ui/view_mode.h) use one InteractiveDisplay (Bala et al. 2003) that it owns: built in
// the background (Gouraud meanwhile), rendering a frame whenever it can (the cache reprojects
// on camera moves), shading on its own asynchronous workers, and updated from every published
// lighting (InteractiveDisplay::apply(SolutionView)).
//
// It hears of edits as an EditListener on the solver worker's thread, which holds the
// structure exclusively: editsBegin pauses the display's shader (its workers read the
// structure), the batch's events reach the display through InteractiveDisplay::apply(EditEvent)
// (a batch of drag positions as its last, coalescePreviews), editsEnd resumes it. The drag's
// tracer subsets (the origin alone, the preview alone, the occluders) are made and released
// there too, following the events: the display traces them while the drag goes on.
//
// Locking: mDisplayMutex guards the display and the subsets; the solver thread takes it
// inside the structure's exclusive section, the render thread inside the shared one. A frame
// releases both while its edge-and-point image is reconstructed (reconstructFrame touches
// only the display's own image arrays): an edit waits for a frame step, not a frame.
//
// Index: options · DisplayProducer

#include <condition_variable>
#include <cstdint>
#include <future>
#include <memory>
#include <mutex>
#include <optional>
#include <shared_mutex>
#include <string>
#include <thread>
#include <vector>

#include "render/display/interactive_display.h"
#include "ui/holodeck_service.h"
#include "ui/interpolant_service.h"
#include "ui/runner_board.h"
#include "ui/service_thread.h"
#include "ui/shared_session.h"

namespace penumbra {

struct DisplayProducerOptions {
    double interactiveImageMs = 40;  ///< traced interactive images: resolution for this time
    int maxReducedDivisor = 8;       ///< at most width / d × height / d pixels fewer
    int displayDivisor = 1;          ///< display modes: viewport / d pixels (rounded to 4)
    double displayFrameMs = 30;      ///< display modes: at least this long between frames
    int settleFrames = 40;           ///< display modes: frames with a view and lighting to rest
    int referenceDivisor = 4;        ///< difference mode: reference at display / d pixels
    /// The first display is built on a thread of its own (else in iterate(), tests).
    bool threaded = true;
    int renderNice = 0;      ///< nice of the render thread (SessionRunnerOptions::renderNice)
    int backgroundNice = 0;  ///< nice of the display's shading workers
};

class DisplayProducer : public EditListener {
public:
    /// `hifi` and `holodeck` outlive the producer (they are the runner's, as `shared` and
    /// `board`).
    DisplayProducer(SharedSession& shared, RunnerBoard& board, DisplayProducerOptions options,
                    InterpolantService& hifi, HolodeckService& holodeck);
    ~DisplayProducer() override;
    DisplayProducer(const DisplayProducer&) = delete;
    DisplayProducer& operator=(const DisplayProducer&) = delete;

    void start();
    void stop();
    /// The UI thread: what the viewport wants (a new serial when anything changed).
    void setView(const ViewRequest& request);
    ViewRequest view() const;
    /// Renders if the light or the view changed (display modes: a frame when due); returns
    /// whether it rendered.
    bool iterate();

    // -- EditListener (the solver worker's thread, structure exclusive) ---------------------------

    void editsBegin() override;
    void edited(const EditEvent& event) override;
    void editsEnd() override;
    void published() override { mThread.wake(); }

private:
    /// A RayTracer subset admitting one object version alone.
    struct VersionSubset {
        int version = -1;
        RayTracer::SubsetHandle handle;
        VersionSubset() = default;
        VersionSubset(RayTracer& tracer, int v) : version(v), handle(tracer, {v}) {}
        Visibility visibility() const { return handle.visibility(); }
    };
    /// What iterate found for the ray-traced modes: the interpolant mesh (when the interpolant
    /// mode has one), its note, and whether a display or mesh is still loading (Gouraud meanwhile).
    struct TracedView {
        const HifiMesh* hifi = nullptr;
        std::string hifiNote;
        bool loading = false;
    };
    /// The first display, built on a thread of its own (displayLanded).
    struct BuiltDisplay {
        std::unique_ptr<InteractiveDisplay> display;
        std::uint64_t edits = 0;  ///< mEditBatches when it was built
        int viewWidth = 0, viewHeight = 0;
    };
    // The ray-traced modes.
    bool renderTracedView(const ViewRequest& view, const PublishedLight& light,
                          const std::shared_ptr<const ViewportImage>& last, int highlight,
                          const TracedView& traced);
    int reducedDivisor(const ViewRequest& view) const;
    /// `values` over every element: a drag appends a version before the solver publishes
    /// lighting for it, so elements of versions the image does not show get 0; any other gap
    /// gives null (wait for the next lighting), or `unseen` when given.
    std::shared_ptr<const std::vector<Rgb>> coverElements(
        const std::shared_ptr<const std::vector<Rgb>>& values, int previewVersion,
        const std::optional<Rgb>& unseen = std::nullopt) const;
    bool traceImage(const ViewRequest& view, const PublishedLight& light, int w, int h, int highlight,
                    const HifiMesh* hifi, const std::vector<Rgb>& radiosity,
                    const std::vector<Rgb>* pending, ViewportImage& img);
    /// View ▸ Overlay ▸ Settling: the published settling estimate as a heat map over the
    /// image (render/settling_overlay.h), at the image's size.
    void overlaySettling(const ViewRequest& view, const PublishedLight& light, ViewportImage& img);
    // The display modes.
    InteractiveDisplayOptions displayOptions(const ViewRequest& view) const;
    /// Whether the display exists for `view`'s size; builds the first one in the background
    /// (threaded) and a resized one as a copy of the last.
    bool displayLanded(const ViewRequest& view);
    /// A new display starts over: frame figures and the holodeck request of its view.
    void startDisplay(const ViewRequest& view, std::uint64_t holoRead);
    bool renderDisplay(const ViewRequest& view, const PublishedLight& light,
                       const std::shared_ptr<const ViewportImage>& last, int highlight,
                       std::shared_lock<std::shared_mutex>& structure);
    /// The display mode's layer over a frame: its edges, its new samples, or the difference
    /// from a reference of the same view (computed once the solver is idle).
    void overlayDisplayMode(const ViewRequest& view, const PublishedLight& light, ViewportImage& img);
    /// One edit's event for the display, the drag's subsets following it.
    void applyEvent(const EditEvent& event);
    /// Releases the subsets the display no longer uses; makes the occluder subset it asks for.
    void pruneSubsets();
    // The holodeck's part.
    /// Puts the holodeck's answer into the display when it came; false while the first frame
    /// should still wait for it.
    bool takeHolodeckPoints();
    /// Asks the holodeck for the points of `view` when its camera moved since the last read
    /// and that read was answered (a walk or an orbit takes each view's stored points), or
    /// when the holodeck's index came since (the first read took only the view's own beams).
    void requestMovedView(const ViewRequest& view);
    /// Once the view rested on the converged light, hands the display's points shaded from it
    /// (and not from the holodeck), at most one per pixel the holodeck does not show yet, to
    /// the holodeck to store.
    void handHolodeckPoints(const ViewRequest& view, const PublishedLight& light, int settledFrames,
                            const CameraRays& rays);

    SharedSession& mShared;
    RunnerBoard& mBoard;
    DisplayProducerOptions mOptions;
    InterpolantService& mHifi;
    HolodeckService& mHolodeck;

    mutable std::mutex mViewMutex;  ///< the view request
    ViewRequest mView;
    std::uint64_t mViewSerial = 0;
    ServiceThread mThread;

    // The render thread's.
    double mMsPerPixel = 0;        ///< running estimate of the traced render cost
    double mLastLoadingImage = 0;  ///< the last Gouraud image while the display is built
    double mLastDisplayFrame = 0;
    /// The selection and its transform in the state being rendered (ViewportImage::dragged).
    std::string mDragged;
    Transform mDraggedTransform;
    // The settling overlay's change image for the estimate, preview version and view it was
    // rendered for: rendered again only when one of them changes, not every frame.
    Image mSettlingChange;
    std::shared_ptr<const std::vector<Rgb>> mSettlingChangeOf;
    int mSettlingChangePreview = -1;
    std::optional<Camera> mSettlingChangeCamera;
    Image mReference;  ///< difference mode
    Camera mReferenceCamera;
    std::uint64_t mReferenceDone = 0;

    // The display and the drag's subsets: under mDisplayMutex.
    std::mutex mDisplayMutex;
    std::unique_ptr<InteractiveDisplay> mDisplay;
    int mViewWidth = 0, mViewHeight = 0;  ///< the viewport size the display was made for
    std::uint64_t mSolution = 0;          ///< PublishedLight::serial of its solution, 0 none yet
    double mFrameMs = 0;                  ///< running estimate of its frame time
    int mFrames = 0;                      ///< frames rendered
    std::future<BuiltDisplay> mBuild;
    std::uint64_t mBuildHoloRead = 0;  ///< the holodeck read asked for the display being built
    std::uint64_t mEditBatches = 0;    ///< edit batches applied
    /// The holodeck: the read the display waits for (0 none) and since when; the points it
    /// took or handed over to be stored (the pixels they project to in a view take no other);
    /// the first cache frame whose points were shaded from the converged light
    /// `mConvergedLight`; the view and light it last handed points of.
    std::uint64_t mHoloRead = 0;
    double mHoloReadTime = 0;
    /// The camera of the last read and the holodeck's index builds then: a display whose
    /// camera moved, or whose view was read before the index came, asks again.
    std::optional<Camera> mHoloCamera;
    std::uint64_t mHoloIndexBuilds = 0;
    std::int64_t mHoloPoints = 0;
    std::vector<Vec3> mHoloPositions;
    std::uint64_t mConvergedLight = 0, mConvergedFrame = 0;
    std::uint64_t mStoredView = 0, mStoredLight = 0;
    /// The batch's events (editsBegin to editsEnd, the solver thread's).
    std::vector<EditEvent> mEvents;
    std::unique_lock<std::mutex> mEditLock;
    std::optional<PointShader::Pause> mEditPause;
    /// The subset of the version the drag previews, and earlier previews' subsets a background
    /// estimate still traces (InteractiveDisplay::directJobPreview).
    VersionSubset mPreviewSubset;
    std::vector<VersionSubset> mOldSubsets;
    /// The object the display hides points behind (InteractiveDisplay::occluder).
    VersionSubset mOccluderSubset;
    /// The drag's origin alone, for the display's drag estimates; earlier drags' origins while
    /// a background estimate may still trace them.
    VersionSubset mOriginSubset;
    std::vector<VersionSubset> mOldOrigins;
};

}  // namespace penumbra
