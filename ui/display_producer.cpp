// Index: threads and the view · the iteration · the ray-traced modes · the display modes ·
//        edits · the holodeck's part

#include "ui/display_producer.h"

#include <algorithm>
#include <cmath>

#include "core/log.h"
#include "core/thread_priority.h"
#include "core/timing.h"
#include "render/settling_overlay.h"
#include "solver/discretization.h"

namespace penumbra {

namespace {

double nowSeconds() { return std::chrono::duration<double>(Clock::now().time_since_epoch()).count(); }

/// While the first display is built: at most one Gouraud image of new lighting per this long.
constexpr double kLoadingImageMs = 250;

/// A new display's first frame waits at most this long for the holodeck's points of its view.
constexpr double kHolodeckWaitMs = 500;

}  // namespace

// ---------------------------------------------------------------------------------------------
// Threads and the view.

DisplayProducer::DisplayProducer(SharedSession& shared, RunnerBoard& board,
                                 DisplayProducerOptions options, InterpolantService& hifi,
                                 HolodeckService& holodeck)
    : mShared(shared), mBoard(board), mOptions(options), mHifi(hifi), mHolodeck(holodeck) {}

DisplayProducer::~DisplayProducer() {
    stop();
    // A display being built holds the structure: wait for it.
    if (mBuild.valid()) mBuild.wait();
    // The display's shader workers may trace the drag's subsets until they are joined.
    mDisplay.reset();
}

void DisplayProducer::start() {
    mThread.start("render", mOptions.renderNice, std::chrono::milliseconds(10),
                  [this] { return iterate(); });
}

void DisplayProducer::stop() { mThread.stop(); }

void DisplayProducer::setView(const ViewRequest& request) {
    {
        std::lock_guard<std::mutex> lock(mViewMutex);
        if (request.sameAs(mView)) return;
        mView = request;
        mView.serial = ++mViewSerial;
    }
    mThread.wake();
}

ViewRequest DisplayProducer::view() const {
    std::lock_guard<std::mutex> lock(mViewMutex);
    return mView;
}

// ---------------------------------------------------------------------------------------------
// The iteration.

bool DisplayProducer::iterate() {
    const ViewRequest view = this->view();
    if (view.width <= 0 || view.height <= 0) return false;
    std::shared_lock<std::shared_mutex> structure(mShared.structure);
    const PublishedLight light = mBoard.light();
    const std::shared_ptr<const ViewportImage> last = mBoard.image();
    const RunnerBoard::Glance glance = mBoard.glance();
    // The dragged object's transform in the state rendered (the structure is held shared).
    const EditSession& session = mShared.read();
    mDragged = session.selected();
    if (!mDragged.empty())
        for (const SceneObject& o : session.scene().objects)
            if (o.id == mDragged) mDraggedTransform = o.transform;
    // The outlined version, from the structure held (the board's document and lighting may
    // lag it by an edit): the dragged object is seen as its preview version, in the display as
    // the structure has it, in a traced image as the lighting shows it.
    int highlight = view.highlight.empty() ? -1 : session.objectVersion(view.highlight);
    const bool draggedOutlined = !mDragged.empty() && mDragged == view.highlight;
    // The display modes show Gouraud until their display lands (built in the background).
    TracedView traced;
    if (usesInteractiveDisplay(view.mode)) {
        if (displayLanded(view))
            return renderDisplay(view, light, last,
                                 draggedOutlined && session.previewVersion() >= 0
                                     ? session.previewVersion()
                                     : highlight,
                                 structure);
        traced.loading = true;
    }
    if (draggedOutlined && light.previewVersion >= 0) highlight = light.previewVersion;
    // The interpolant mode shows Gouraud until its mesh of this lighting lands.
    if (view.mode == ViewMode::Interpolant) {
        const bool still = glance.solverIdle && glance.selected.empty() &&
                           light.previewVersion < 0 && !view.interactive;
        traced.hifi = mHifi.landed(light, still, traced.hifiNote);
        traced.loading = traced.hifi == nullptr;
    }
    return renderTracedView(view, light, last, highlight, traced);
}

// ---------------------------------------------------------------------------------------------
// The ray-traced modes.

bool DisplayProducer::renderTracedView(const ViewRequest& view, const PublishedLight& light,
                                       const std::shared_ptr<const ViewportImage>& last,
                                       int highlight, const TracedView& traced) {
    const bool loading = traced.loading;
    const bool need = !last || last->stateSerial != light.serial ||
                      last->viewSerial != view.serial || (last->reduced && !view.interactive) ||
                      (!loading && last->mode != view.mode) ||
                      (view.mode == ViewMode::Interpolant && last->note != traced.hifiNote);
    if (!need || !light.radiosity) return false;
    // While the display is built, new lighting is shown at most every loadingImageMs (the
    // cores go to the build); view changes at once.
    if (loading && last && last->viewSerial == view.serial &&
        !(last->reduced && !view.interactive) &&
        nowSeconds() - mLastLoadingImage < kLoadingImageMs * 1e-3 &&
        (view.mode != ViewMode::Interpolant || last->stateSerial == light.serial))
        return false;
    if (loading) mLastLoadingImage = nowSeconds();

    const int d = reducedDivisor(view);
    const int w = std::max(1, view.width / d), h = std::max(1, view.height / d);
    const auto radiosity = coverElements(light.radiosity, light.previewVersion);
    if (!radiosity) return false;
    const auto pendingValues = coverElements(light.pending, light.previewVersion);

    auto img = std::make_shared<ViewportImage>();
    const double r0 = nowSeconds();
    if (!traceImage(view, light, w, h, highlight, traced.hifi, *radiosity, pendingValues.get(),
                    *img))
        return false;
    img->renderMs = (nowSeconds() - r0) * 1e3;
    spdlog::debug("render {}x{} {:.1f} ms light {}", w, h, img->renderMs, light.serial);
    const double perPixel = img->renderMs / (double(w) * h);
    mMsPerPixel = mMsPerPixel > 0 ? 0.7 * mMsPerPixel + 0.3 * perPixel : perPixel;
    img->camera = view.camera;
    img->viewSerial = view.serial;
    img->stateSerial = light.serial;
    img->reduced = d > 1;
    img->mode = loading ? ViewMode::Gouraud : view.mode;
    if (view.mode == ViewMode::Interpolant)
        img->note = traced.hifiNote;
    else if (loading)
        img->note = std::string(viewModeLabel(view.mode)) + " display loading: Gouraud meanwhile";
    img->previewVersion = light.previewVersion;
    img->dragged = mDragged;
    img->draggedTransform = mDraggedTransform;
    mBoard.setImage(std::move(img));
    return true;
}

int DisplayProducer::reducedDivisor(const ViewRequest& view) const {
    if (!view.interactive) return 1;
    int d = 2;
    if (mMsPerPixel > 0) {
        const double pixels = mOptions.interactiveImageMs / mMsPerPixel;
        d = static_cast<int>(std::ceil(std::sqrt(double(view.width) * view.height / pixels)));
    }
    return std::clamp(d, 1, std::max(1, mOptions.maxReducedDivisor));
}

std::shared_ptr<const std::vector<Rgb>> DisplayProducer::coverElements(
    const std::shared_ptr<const std::vector<Rgb>>& values, int previewVersion,
    const std::optional<Rgb>& unseen) const {
    const Discretization& disc = mShared.read().discretization();
    const std::size_t n = disc.elements().size();
    if (!values || values->size() >= n) return values;
    auto shown = [&](std::size_t e) {
        const int o = disc.elements()[e].object;
        return disc.objects()[o].alive || o == previewVersion;
    };
    if (!unseen)
        for (std::size_t e = values->size(); e < n; ++e)
            if (shown(e)) return nullptr;
    auto padded = std::make_shared<std::vector<Rgb>>(*values);
    padded->resize(n, Rgb(0.0));
    for (std::size_t e = values->size(); e < n; ++e)
        if (shown(e)) (*padded)[e] = *unseen;
    return padded;
}

bool DisplayProducer::traceImage(const ViewRequest& view, const PublishedLight& light, int w, int h,
                                 int highlight, const HifiMesh* hifi,
                                 const std::vector<Rgb>& radiosity,
                                 const std::vector<Rgb>* pending, ViewportImage& img) {
    const Discretization& disc = mShared.read().discretization();
    const RayTracer& tracer = mShared.read().tracer();
    try {
        img.render =
            renderViewport(disc, tracer, radiosity, view.camera, w, h, light.previewVersion,
                           highlight);
        if (view.mode == ViewMode::OutOfDate && pending) {
            // The pending |ΔB| interpolated like the image, as a red tint.
            const ViewportRender tint =
                renderViewport(disc, tracer, *pending, view.camera, w, h, light.previewVersion);
            tintPending(img.render.rgba, tint.radiance, light.pendingScale / M_PI);
            img.note = "red: pending unshot / redistribution |dB| (full at 5% of mean B)";
        }
        if (hifi) {
            // One ray per pixel finds the triangle whose interpolant it shows (the editor's GL
            // context belongs to the UI thread); the outline over it as over Gouraud.
            img.render.radiance = renderInterpolants(disc, tracer, *hifi,
                                                     CameraRays(view.camera, w, h));
            img.render.rgba = encodeDisplay(img.render.radiance);
            if (highlight >= 0)
                drawSelectionOutline(img.render.rgba, img.render.objectAt, w, h, highlight);
        }
        overlaySettling(view, light, img);
    } catch (const std::exception& e) {
        mBoard.report(std::string("viewport: ") + e.what());
        return false;
    }
    return true;
}

// ---------------------------------------------------------------------------------------------
// The display modes.

InteractiveDisplayOptions DisplayProducer::displayOptions(const ViewRequest& view) const {
    const int d = std::max(1, mOptions.displayDivisor);
    InteractiveDisplayOptions options;
    options.width = std::max(4, view.width / d / 4 * 4);
    options.height = std::max(4, view.height / d / 4 * 4);
    options.synchronous = false;
    // Drag positions: the preview's direct light is estimated on the shader's workers, not in
    // the edit's exclusive section.
    options.shader.backgroundPreview = true;
    options.shader.workerNice = mOptions.threaded ? mOptions.backgroundNice : 0;
    // Edits come while the solver redistributes: no dark patches where its H lags.
    options.shader.clampIndirect = true;
    // After an edit or a drop, what changed is re-shaded at up to five times the base rate:
    // the shader's workers have the capacity, and at the base rate the old and new shadows of
    // a moved table take seconds to re-shade.
    options.changedSampleFraction = 0.08;
    // A still camera's frames reconstruct only the pixels that changed, and while an object is
    // dragged the shader re-shades only what the drag changed: the drag's frames cost what its
    // object and shadows cover, not the viewport.
    options.windowedFrames = true;
    // Drag positions and the solver's lighting arrive several times a frame: relit once a frame.
    options.deferRelight = true;
    options.dragSamplesChangedOnly = true;
    // A converged still view rests: no samples, no reconstruction, until something changes.
    options.restWhenConverged = true;
    return options;
}

void DisplayProducer::startDisplay(const ViewRequest& view, std::uint64_t holoRead) {
    mViewWidth = view.width;
    mViewHeight = view.height;
    mFrameMs = 0;
    mFrames = 0;
    mHoloPoints = 0;
    mHoloPositions.clear();
    mConvergedLight = mConvergedFrame = 0;
    mStoredView = mStoredLight = 0;
    mHoloRead = holoRead != 0 ? holoRead
                              : mHolodeck.requestView(view.camera, mDisplay->width(),
                                                      mDisplay->height());
    mHoloReadTime = nowSeconds();
    mHoloCamera = view.camera;
    mHoloIndexBuilds = mHolodeck.indexBuilds();
}

bool DisplayProducer::displayLanded(const ViewRequest& view) {
    std::lock_guard<std::mutex> displayLock(mDisplayMutex);
    if (mDisplay && mViewWidth == view.width && mViewHeight == view.height) return true;
    const InteractiveDisplayOptions options = displayOptions(view);
    if (mDisplay) {
        // Another viewport size: a copy of the display at the new size takes its edge finder,
        // lights, direct light, solution and preview (milliseconds; built from scratch it
        // takes seconds in robot-room); its cache starts empty.
        try {
            std::unique_ptr<InteractiveDisplay> resized;
            {
                PointShader::Pause pause(mDisplay->shader());
                resized = std::make_unique<InteractiveDisplay>(*mDisplay, options);
            }
            mDisplay = std::move(resized);
            mDisplay->warmUp(CameraRays(view.camera, options.width, options.height));
        } catch (const std::exception& e) {
            mDisplay.reset();
            mBoard.report(std::string("display: ") + e.what());
            return false;
        }
        startDisplay(view, 0);
        return true;
    }
    if (!mOptions.threaded || !mBuild.valid()) {
        // The first display takes seconds to build (edge trees, every element's direct light):
        // on a thread of its own, with the structure held shared, the Gouraud view meanwhile.
        // The holodeck's points of the view are read meanwhile.
        const Camera camera = view.camera;
        mBuildHoloRead = mHolodeck.requestView(camera, options.width, options.height);
        auto make = [this, options, camera, viewWidth = view.width, viewHeight = view.height,
                     edits = mEditBatches] {
            BuiltDisplay built;
            const auto t0 = Clock::now();
            built.edits = edits;
            built.viewWidth = viewWidth;
            built.viewHeight = viewHeight;
            try {
                const EditSession& session = mShared.read();
                built.display = std::make_unique<InteractiveDisplay>(
                    session.discretization(), session.tracer(), interactiveSolverOptions(),
                    options);
                // A drag in progress: the display, built without the dragged object, shows its
                // preview estimated from there (not relative to the origin, which it never
                // saw). The preview and its subset are current: the solver thread changes them
                // only with the structure held exclusively.
                if (session.previewVersion() >= 0) {
                    EditEvent drag;
                    drag.kind = EditEvent::Kind::PreviewMoved;
                    drag.object = session.selected();
                    drag.preview = session.previewVersion();
                    built.display->apply(drag, {Visibility{}, mPreviewSubset.visibility()});
                }
                built.display->warmUp(CameraRays(camera, options.width, options.height));
            } catch (const std::exception& e) {
                built.display.reset();
                mBoard.report(std::string("display: ") + e.what());
            }
            spdlog::debug("display {}x{}: built in {:.1f} ms", options.width, options.height,
                          msSince(t0));
            return built;
        };
        if (!mOptions.threaded) {
            // iterate() holds the structure shared.
            BuiltDisplay built = make();
            if (!built.display) return false;
            mDisplay = std::move(built.display);
            startDisplay(view, mBuildHoloRead);
            mSolution = 0;
            return true;
        }
        // Not niced: the user waits for it.
        mBuild = std::async(std::launch::async, [this, make] {
            nameThisThread("display-build");
            std::shared_lock<std::shared_mutex> structure(mShared.structure);
            return make();
        });
        return false;
    }
    if (mBuild.wait_for(std::chrono::seconds(0)) != std::future_status::ready) return false;
    BuiltDisplay built = mBuild.get();
    // Edits since it started, or another viewport size: build again.
    if (!built.display || built.edits != mEditBatches || built.viewWidth != view.width ||
        built.viewHeight != view.height)
        return false;
    mDisplay = std::move(built.display);
    mSolution = 0;
    startDisplay(view, mBuildHoloRead);
    return true;
}

bool DisplayProducer::renderDisplay(const ViewRequest& view, const PublishedLight& light,
                                    const std::shared_ptr<const ViewportImage>& last,
                                    int highlight, std::shared_lock<std::shared_mutex>& structure) {
    // Frames run continuously (the cache keeps improving), at most one per displayFrameMs.
    const double now = nowSeconds();
    if (now - mLastDisplayFrame < mOptions.displayFrameMs * 1e-3) return false;
    mLastDisplayFrame = now;
    auto img = std::make_shared<ViewportImage>();
    std::unique_lock<std::mutex> displayLock(mDisplayMutex);
    InteractiveDisplay& display = *mDisplay;
    // The published lighting (the display took the solver's own at an edit: mSolution then
    // names the light that follows it).
    try {
        if (light.irradiance && mSolution != light.serial) {
            display.apply(light.solutionView());
            mSolution = light.serial;
            // Points requested from the next frame on are shaded from this light.
            if (light.converged) {
                mConvergedLight = light.serial;
                mConvergedFrame = display.cache().frame() + 1;
            }
        }
    } catch (const std::exception& e) {
        mBoard.report(std::string("display: ") + e.what());
    }
    // A new display's first frame starts from the holodeck's points of its view; a moved
    // camera's view takes them as they come.
    if (!takeHolodeckPoints()) return false;
    requestMovedView(view);
    const int w = display.width(), h = display.height();
    const CameraRays rays(view.camera, w, h);
    int shownPreview = -1;
    try {
        const double r0 = nowSeconds();
        // The frame in its steps: edits wait for the first (points, edges), not for the
        // reconstruction, which touches only the display's edge-and-point image.
        display.beginFrame(rays, view.mode != ViewMode::Cache);
        shownPreview = display.previewVersion();
        // The selection outline of the state the frame shows (the preview version while
        // dragged; it is in the display only through the preview subset), drawn after encoding.
        std::vector<int> objectAt;
        if (highlight >= 0 && view.mode != ViewMode::Difference) {
            const EditSession& session = mShared.read();
            objectAt = selectionPixels(session.discretization(), session.tracer(), view.camera,
                                       w, h, highlight, session.previewVersion(),
                                       mPreviewSubset.visibility());
        }
        displayLock.unlock();
        structure.unlock();
        try {
            img->render.radiance = display.reconstructFrame();
        } catch (...) {
            structure.lock();
            displayLock.lock();
            throw;
        }
        structure.lock();
        displayLock.lock();
        display.finishFrame(rays, img->render.radiance);
        img->display = display.lastFrame();
        img->render.rgba = encodeDisplay(img->render.radiance);
        if (!objectAt.empty()) drawSelectionOutline(img->render.rgba, objectAt, w, h, highlight);
        overlayDisplayMode(view, light, *img);
        overlaySettling(view, light, *img);
        img->renderMs = (nowSeconds() - r0) * 1e3;
        mFrameMs = mFrameMs > 0 ? 0.7 * mFrameMs + 0.3 * img->renderMs : img->renderMs;
        ++mFrames;
    } catch (const std::exception& e) {
        mBoard.report(std::string("display: ") + e.what());
        return false;
    }
    if (spdlog::should_log(spdlog::level::debug))
        spdlog::debug("display {}x{} {:.1f} ms {}", w, h, img->renderMs, img->display.toString());
    img->camera = view.camera;
    img->viewSerial = view.serial;
    img->stateSerial = light.serial;
    img->mode = view.mode;
    img->previewVersion = shownPreview;
    img->dragged = mDragged;
    img->draggedTransform = mDraggedTransform;
    img->settledFrames = last && last->mode == view.mode && last->viewSerial == view.serial &&
                                 last->stateSerial == light.serial
                             ? last->settledFrames + 1
                             : 0;
    img->holodeckPoints = mHoloPoints;
    handHolodeckPoints(view, light, img->settledFrames, rays);
    mBoard.setImage(std::move(img));
    return true;
}

void DisplayProducer::overlaySettling(const ViewRequest& view, const PublishedLight& light,
                                      ViewportImage& img) {
    if (!view.settlingOverlay || !light.settling) return;
    // An object added since the estimate has all its light still to come: until the next
    // estimate it shows as the estimate's largest change, not as a gap in the overlay.
    Rgb largest(0.0);
    if (light.settling->size() < mShared.read().discretization().elements().size())
        for (const Rgb& v : *light.settling) largest = glm::max(largest, v);
    const auto settling = coverElements(light.settling, light.previewVersion, largest);
    // The estimate interpolated like the picture, relative to what the picture shows.
    const Discretization& disc = mShared.read().discretization();
    const RayTracer& tracer = mShared.read().tracer();
    const int w = img.render.radiance.width, h = img.render.radiance.height;
    if (mSettlingChangeOf != light.settling || mSettlingChangePreview != light.previewVersion ||
        !mSettlingChangeCamera || !sameCamera(*mSettlingChangeCamera, view.camera) ||
        mSettlingChange.width != w || mSettlingChange.height != h) {
        mSettlingChange =
            renderViewport(disc, tracer, *settling, view.camera, w, h, light.previewVersion)
                .radiance;
        mSettlingChangeOf = light.settling;
        mSettlingChangePreview = light.previewVersion;
        mSettlingChangeCamera = view.camera;
    }
    blendSettling(img.render.rgba, img.render.radiance, mSettlingChange,
                  light.settlingFloor / M_PI);
    if (!img.note.empty()) img.note += "; ";
    img.note += "heat: light still to change (yellow 1%, red 30%)";
}

void DisplayProducer::overlayDisplayMode(const ViewRequest& view, const PublishedLight& light,
                                         ViewportImage& img) {
    InteractiveDisplay& display = *mDisplay;
    const int w = display.width(), h = display.height();
    if (view.mode == ViewMode::EdgesOverlay) {
        blendEdges(img.render.rgba, display.edgeImage());
    } else if (view.mode == ViewMode::SamplesOverlay) {
        // This frame's new samples (age 0 after insertion) as dots.
        std::vector<std::uint8_t> flags(static_cast<std::size_t>(w) * h, 0);
        for (const ScreenPoint& p : display.cache().screenPoints()) {
            const int x = static_cast<int>(p.position.x), y = static_cast<int>(p.position.y);
            if (p.age == 0 && x >= 0 && y >= 0 && x < w && y < h)
                flags[static_cast<std::size_t>(y) * w + x] = 1;
        }
        markSamples(img.render.rgba, flags);
        img.note = std::to_string(img.display.newSamples) + " new samples";
    } else if (view.mode == ViewMode::Difference) {
        const int f = std::max(1, mOptions.referenceDivisor);
        const bool sized = w % f == 0 && h % f == 0;
        // The reference shows the display's current solution: wait until the solver is idle
        // and the display has its last published solution.
        const bool solverIdle = mBoard.glance().solverIdle;
        const bool waiting = view.referenceRequest != mReferenceDone;
        if (waiting && sized && solverIdle && mSolution == light.serial) {
            const CameraRays low(view.camera, w / f, h / f);
            mReference = display.renderReference(low, 2);
            mReferenceCamera = view.camera;
            mReferenceDone = view.referenceRequest;
        }
        if (mReference.width * f == w && mReference.height * f == h &&
            sameCamera(mReferenceCamera, view.camera)) {
            img.render.rgba =
                differenceImage(img.render.radiance, mReference, 0.1, &img.meanDifference);
            img.note = "false colour |epi - reference| sRGB, red at 0.1";
        } else {
            img.note = waiting ? "reference waits for the solver to settle"
                               : "no reference for this view: View > Compute reference";
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Edits (the solver worker's thread, structure held exclusively).

void DisplayProducer::editsBegin() {
    // The display's asynchronous shader reads the structure: paused while it changes, and
    // told what changed before it resumes.
    mEditLock = std::unique_lock<std::mutex>(mDisplayMutex);
    if (mDisplay) mEditPause.emplace(mDisplay->shader());
    mEvents.clear();
}

void DisplayProducer::edited(const EditEvent& event) {
    if (event.kind != EditEvent::Kind::Solved) mEvents.push_back(event);
}

void DisplayProducer::editsEnd() {
    // The display sees a batch of drag positions as its last one.
    coalescePreviews(mEvents);
    for (const EditEvent& event : mEvents) applyEvent(event);
    mEvents.clear();
    pruneSubsets();
    ++mEditBatches;
    mEditPause.reset();
    mEditLock.unlock();
}

void DisplayProducer::applyEvent(const EditEvent& event) {
    using Kind = EditEvent::Kind;
    RayTracer& tracer = mShared.session->tracer();
    // The subsets first: the drag's origin alone from its start; the preview alone whenever
    // another version is previewed (the old one kept while a background estimate traces it).
    if (event.kind == Kind::DragBegan) {
        if (mOriginSubset.version >= 0) mOldOrigins.push_back(std::move(mOriginSubset));
        mOriginSubset = VersionSubset(tracer, event.origin);
    }
    if (event.preview != mPreviewSubset.version) {
        if (mPreviewSubset.version >= 0) mOldSubsets.push_back(std::move(mPreviewSubset));
        mPreviewSubset =
            event.preview >= 0 ? VersionSubset(tracer, event.preview) : VersionSubset();
    }
    if (!mDisplay) return;  // a display being built starts again (mEditBatches)
    // Changes of the solution take the solver's snapshot at once; a preview's buffer comes
    // with the light published next, so a drag position costs no copy.
    const bool solution = event.kind == Kind::Changed || event.kind == Kind::DragEnded;
    const ProgressiveSolver* solver = solution ? &mShared.session->solver() : nullptr;
    try {
        const auto t0 = Clock::now();
        const std::size_t points = mDisplay->apply(
            event, {mOriginSubset.visibility(), mPreviewSubset.visibility()}, solver);
        // The solver worker publishes the lighting after the batch: the display has it.
        if (solution) mSolution = mBoard.lightSerial() + 1;
        spdlog::debug("display {}x{}: {} in {:.1f} ms, {} points", mDisplay->width(),
                      mDisplay->height(), event.toString(), msSince(t0), points);
    } catch (const std::exception& e) {
        mBoard.report(std::string("display: ") + e.what());
    }
}

void DisplayProducer::pruneSubsets() {
    const int jobPreview = mDisplay ? mDisplay->directJobPreview() : -1;
    const int dragOrigin = mDisplay ? mDisplay->dragOrigin() : -1;
    // A frame between its steps fills its holes with the preview it began with.
    const int framePreview = mDisplay ? mDisplay->framePreview() : -1;
    std::erase_if(mOldSubsets, [&](const VersionSubset& s) {
        return jobPreview != s.version && framePreview != s.version;
    });
    std::erase_if(mOldOrigins, [&](const VersionSubset& s) {
        return dragOrigin != s.version && jobPreview < 0;
    });
    // The object that hides points behind it traces a subset of its own, not a filter over the
    // whole scene; kept while the display hides behind it.
    const int occluder = mDisplay ? mDisplay->occluder() : -1;
    if (mDisplay && mDisplay->occluderNeedsSubset()) {
        if (mOccluderSubset.version != occluder)
            mOccluderSubset = VersionSubset(mShared.session->tracer(), occluder);
        mDisplay->setOccluderSubset(occluder, mOccluderSubset.visibility());
    } else if (mOccluderSubset.version != occluder) {
        mOccluderSubset = VersionSubset();
    }
    // The drag's origin subset lives while the display may still use it.
    if (mShared.session->previewVersion() < 0 && dragOrigin < 0) mOriginSubset = VersionSubset();
}

// ---------------------------------------------------------------------------------------------
// The holodeck's part.

bool DisplayProducer::takeHolodeckPoints() {
    if (mHoloRead == 0) return true;
    std::optional<std::vector<ShadedPoint>> answer = mHolodeck.takeView(mHoloRead);
    if (!answer) return mFrames > 0 || nowSeconds() - mHoloReadTime > kHolodeckWaitMs * 1e-3;
    InteractiveDisplay& d = *mDisplay;
    // Stamped as points shaded now for the frame that shows them (its own points, trusted as
    // such: InteractiveDisplay::nextFrame); the display relights them with its own.
    for (ShadedPoint& p : *answer) {
        p.frame = d.nextFrame();
        p.shading = d.shadingSerial();
        mHoloPositions.push_back(p.position);
    }
    d.insertShaded(*answer);
    mHoloPoints += std::int64_t(answer->size());
    mHoloRead = 0;
    // The positions of points brought or stored keep later stores off their pixels; a long
    // walk keeps the latest, about a view's worth.
    const std::size_t keep = static_cast<std::size_t>(d.width()) * d.height();
    if (mHoloPositions.size() > 2 * keep)
        mHoloPositions.erase(mHoloPositions.begin(),
                             mHoloPositions.end() - static_cast<std::ptrdiff_t>(keep));
    return true;
}

void DisplayProducer::requestMovedView(const ViewRequest& view) {
    if (!mHolodeck.enabled() || mHoloRead != 0 || mFrames == 0) return;
    const Camera& c = view.camera;
    const std::uint64_t builds = mHolodeck.indexBuilds();
    if (mHoloCamera && sameCamera(*mHoloCamera, c) && builds == mHoloIndexBuilds) return;
    mHoloCamera = c;
    mHoloIndexBuilds = builds;
    // At half the resolution: the cache's points, reprojected, already cover most of a moved
    // view; a sample in every 2 × 2 pixels fills what they leave, in a quarter of the time.
    mHoloRead = mHolodeck.requestView(c, std::max(1, mDisplay->width() / 2),
                                      std::max(1, mDisplay->height() / 2));
    mHoloReadTime = nowSeconds();
}

void DisplayProducer::handHolodeckPoints(const ViewRequest& view, const PublishedLight& light,
                                         int settledFrames, const CameraRays& rays) {
    if (!mHolodeck.enabled() || view.interactive || !light.converged ||
        mSolution != light.serial || mConvergedLight != light.serial ||
        settledFrames < mOptions.settleFrames || mHoloRead != 0 ||
        (mStoredView == view.serial && mStoredLight == light.serial))
        return;
    mStoredView = view.serial;
    mStoredLight = light.serial;
    // At most one sample per pixel of the view: the pixels a point already in the holodeck
    // (brought from it or stored) shows take no other, so revisiting a view does not grow it.
    const RenderCache& cache = mDisplay->cache();
    const int w = rays.width(), h = rays.height();
    std::vector<std::uint8_t> covered(static_cast<std::size_t>(w) * h, 0);
    auto pixelOf = [&](const Vec3& position) -> long {
        const auto pixel = rays.projectToPixel(position);
        if (!pixel || pixel->x < 0 || pixel->y < 0 || pixel->x >= w || pixel->y >= h) return -1;
        return static_cast<long>(pixel->y) * w + static_cast<long>(pixel->x);
    };
    for (const Vec3& position : mHoloPositions)
        if (const long pixel = pixelOf(position); pixel >= 0) covered[pixel] = 1;
    const std::vector<CachePoint>& points = cache.points();
    // The points shaded from the converged light, visible, one per uncovered pixel.
    std::vector<CachePoint> store;
    for (std::size_t i = 0; i < points.size(); ++i) {
        const CachePoint& p = points[i];
        if (p.frame < mConvergedFrame || cache.stale(i) || !cache.visible(i)) continue;
        const long pixel = pixelOf(p.position);
        if (pixel < 0 || covered[pixel]) continue;
        covered[pixel] = 1;
        mHoloPositions.push_back(p.position);
        store.push_back(p);
    }
    if (store.empty()) return;
    spdlog::debug("holodeck: {} points handed over to be stored ({} in it before)", store.size(),
                  mHoloPositions.size() - store.size());
    mHolodeck.store(std::move(store), rays.origin(), light.serial);
}

}  // namespace penumbra
