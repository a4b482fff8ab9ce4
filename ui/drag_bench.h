#pragma once
// What the user sees while an object is dragged, measured (`penumbra-editor --bench-drag ID`):
// every viewport image shown from the select until two seconds after the drop, then the
// settled image. Per image: the pixels no cached point reached (shown from the display's
// fallback) and those shown with no value at all, whether it is below the viewport's full
// resolution, and for a few of them the error against a reference render of the same scene
// state (the dragged object at the transform the image shows, the lighting converged, every
// pixel shaded with the point shader). After the drop: how long until the image stays within
// 1% of the settled one. For the drag images with a reference, whose shadow the floor shows:
// their own state's or an earlier image's (the shadow lagging the object), in images and
// milliseconds. `--record DIR` writes every image with the edit line that reproduces
// its state, so a person can look.
//
// Index: DragBenchOptions · DragBenchImage · DragBench

#include <condition_variable>
#include <cstdint>
#include <deque>
#include <list>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <string>
#include <thread>
#include <vector>

#include "render/camera_rays.h"
#include "render/image.h"
#include "solver/scene.h"
#include "ui/session_runner.h"

namespace penumbra {

struct DragBenchOptions {
    std::string scene;            ///< the scene file the editor opened (for the references)
    std::string object;           ///< the dragged object's id
    double afterDropSeconds = 2;  ///< images kept after the drop
    std::string recordDir;        ///< "" for none: else every image and an index.jsonl
    /// References: this many images spread over the drag, the first after the drop, the one
    /// nearest afterDropSeconds, and the settled one (each a converged solve of its state
    /// and a full point-shader render).
    int dragReferences = 3;
    int referenceSamplesPerAxis = 2;
    /// "Within" the settled image: relativeDisplayRmse at most this.
    double settledTolerance = 0.01;
    /// Shadow lag: for each drag image with a reference, the states of this many earlier
    /// images (distinct transforms) are rendered too, and the floor's shadow is matched
    /// against each (DragBench::measureShadowLag). 0: not measured.
    int shadowLagStates = 3;
};

/// One viewport image the bench saw.
struct DragBenchImage {
    double seconds = 0;  ///< since the drop (negative while dragging)
    bool afterDrop = false;
    int width = 0, height = 0;  ///< the image's
    bool reduced = false;       ///< below the viewport's resolution
    std::size_t unsampled = 0;  ///< pixels no point reached (DisplayFrameStats)
    std::size_t unfilled = 0;   ///< pixels shown with no value
    std::string dragged;        ///< "" after the drop
    Transform transform;        ///< the dragged object's, in the state shown
    Camera camera;
    std::string file;  ///< recorded PNG, "" when not recording
    /// The image as displayed (sRGB bytes, 3 per pixel, without the selection outline): what
    /// the errors compare, as the user sees it.
    std::shared_ptr<const std::vector<std::uint8_t>> shown;
    double referenceError = -1;  ///< relativeDisplayRmse against its reference, -1: none
    /// The same without the lamps and their edge pixels (emitterMask), as `render --compare`.
    double referenceErrorWithoutLamps = -1;
    /// The same over the pixels where the reference shows the dragged object, and how many.
    double objectError = -1;
    std::size_t objectPixels = 0;
    /// Of those pixels, the share showing something else than the object (a channel off by
    /// more than 51 of 255): holes, background through it, the object elsewhere.
    double objectWrong = -1;
    /// Pixels of the selection outline (drawSelectionOutline's colour) in the image: a drag
    /// image without one shows the object unselected (the outline blinks).
    std::size_t outlinePixels = 0;
    double settledError = -1;  ///< relativeDisplayRmse against the settled image
    /// The same as referenceError over the floor's pixels (where the dragged object's shadow
    /// falls), -1 none.
    double floorError = -1;
    /// The reference's displayed bytes (set with referenceError; kept for the shadow lag).
    std::shared_ptr<const std::vector<std::uint8_t>> referenceShown;
};

class DragBench {
public:
    explicit DragBench(DragBenchOptions options);
    ~DragBench();  ///< finishes writing the recorded images
    DragBench(const DragBench&) = delete;
    DragBench& operator=(const DragBench&) = delete;

    /// The select was submitted at `now` (seconds, any clock the other calls share); the
    /// object was at `start`.
    void started(double now, const Transform& start) {
        mStart = now;
        mFinal = start;
    }
    /// The unselect was submitted at `now`; the object rests at `final`.
    void dropped(double now, const Transform& final);
    bool droppedYet() const { return mDropped; }
    /// Whether the after-drop window is over.
    bool afterDropDone(double now) const {
        return mDropped && now - mDrop >= mOptions.afterDropSeconds;
    }
    /// The measured window is over: the images held so far are converted and written now
    /// (during the window the bench's thread would take the cores the editor is measured on).
    void windowDone();
    /// An image the viewport shows from now on; `viewW` × `viewH` is the display's full
    /// resolution (the viewport's, or its --display-divisor share).
    void shown(const std::shared_ptr<const ViewportImage>& image, double now, int viewW, int viewH);
    /// The settled image (the runner quiescent after the drop), or nullptr after a timeout.
    void settled(const std::shared_ptr<const ViewportImage>& image);
    /// A later settled image of the same state: how far two settled images of the display
    /// differ (its points' noise and their replacement), the floor under settled errors.
    void settledAgain(const std::shared_ptr<const ViewportImage>& image);

    /// Computes the errors (references included: seconds each) and the figures, as JSON:
    /// images, drag_images_per_s, max_unsampled_fraction, max_unfilled_fraction, reduced_share,
    /// settle_ms (from the drop until every later image is within the tolerance of the
    /// settled one; -1 when the window ends before), error_at_window_end, reference errors.
    nlohmann::json analyse();
    /// The images seen so far (their displayed bytes arrive on the bench's own thread).
    const std::deque<DragBenchImage>& images() const { return mImages; }

private:
    /// Queues `image` for `entry` (converted to displayed bytes, and written when recording,
    /// on the bench's thread once the window is over: the frame loop does not wait for either).
    void queue(DragBenchImage& entry, std::shared_ptr<const ViewportImage> image);
    /// Waits until every queued image is converted and written.
    void drain();
    void workerLoop();

    // The steps of analyse().
    /// Image counts, the largest unsampled and unfilled shares, and the reduced share.
    void analyseImages(nlohmann::json& out) const;
    /// Each after-drop image's error against the settled image, and how soon after the drop
    /// every later image stays within the tolerance.
    void analyseSettling(nlohmann::json& out);
    /// The images worth a reference: a few spread over the drag, the first after the drop, the
    /// one nearest afterDropSeconds, the settled one.
    std::vector<DragBenchImage*> chooseReferenceImages();
    /// Renders a reference of each chosen image's state (one session solved again per state)
    /// and fills in the images' reference errors; one JSON entry per image.
    nlohmann::json renderReferences(const std::vector<DragBenchImage*>& chosen);
    /// Moves the dragged object to `image`'s state in `session`, converges, renders the
    /// reference and compares (the `at`-th reference: its file name when recording).
    nlohmann::json compareWithReference(EditSession& session, const SolverOptions& solverOptions,
                                        DragBenchImage& image, int at);
    /// The dragged object moved to `transform` in `session`, the lighting converged, and a
    /// point-shader reference of that state rendered for `rays`.
    Image referenceOf(EditSession& session, const SolverOptions& solverOptions,
                      const Transform& transform, const CameraRays& rays) const;
    /// Whose shadow each referenced drag image shows on the floor: its own state's, or that of
    /// an image before it (the shadow lags the object). Per image: the candidate states'
    /// errors over the floor pixels where their references differ, the best one's lag in
    /// images and in milliseconds (from the first image showing that state to this one).
    nlohmann::json measureShadowLag(EditSession& session, const SolverOptions& solverOptions);

    DragBenchOptions mOptions;
    double mStart = 0, mDrop = 0;
    bool mDropped = false;
    Transform mFinal;
    std::deque<DragBenchImage> mImages;  ///< stable addresses: the thread fills them in
    DragBenchImage mSettled;             ///< width 0: none
    DragBenchImage mSettledAgain;
    nlohmann::json mShadowLag = nlohmann::json::array();  ///< measureShadowLag's
    int mRecorded = 0;

    // The bench's thread: displayed bytes and recorded PNGs, so the frame loop does not wait.
    struct Job {
        DragBenchImage* entry;
        std::shared_ptr<const ViewportImage> image;
        std::string indexLine;  ///< "" when not recording
    };
    std::mutex mMutex;
    std::condition_variable mWake, mDone;
    std::deque<Job> mJobs;
    bool mBusy = false;
    bool mHold = true;  ///< jobs wait until windowDone (or drain)
    bool mStop = false;
    std::thread mWorker;
};

}  // namespace penumbra
