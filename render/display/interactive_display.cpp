// The interactive display (Bala, Walter, Greenberg 2003 §3): point shader, render cache, edge
// finder and edge-and-point image wired into frames.
//
// Index: helpers · toString · construction · frames · warm-up · edits and solution updates ·
//        reference · image error (edge projection: edge_projection.cpp)
#include "render/display/interactive_display.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>
#include <tbb/task_group.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <limits>
#include <sstream>
#include <stdexcept>

#include "core/random.h"
#include "core/timing.h"
#include "render/display/parallel_indices.h"
#include "render/display/shadow_volume.h"
#include "solver/discretization.h"
#include "solver/form_factor.h"
#include "solver/ray_tracer.h"

namespace penumbra {

// ---------------------------------------------------------------------------------------------
// toString

std::string DisplayStageTimes::toString() const {
    std::ostringstream s;
    s.precision(3);
    s << "DisplayStageTimes{edges " << findEdgesMs << " ms (silhouettes " << silhouetteMs
      << ", shadows " << shadowMs << ", project " << projectMs << "), rasterize " << rasterizeMs
      << ", points " << pointsMs << " (relight " << relightMs << ", hide " << hideMs
      << ", shadow drop " << shadowDropMs << " (re-shade " << shadowReshadeMs << "), insert "
      << insertMs << ", reproject " << reprojectMs << "), reach " << reachabilityMs << ", interp "
      << interpolateMs << ", aa " << antiAliasMs << ", complex " << complexFilterMs << ", smooth "
      << smoothMs << ", fill " << fillMs << ", request " << requestMs << ", total " << totalMs
      << ", shade " << shadeMs << "}";
    return s.str();
}

std::string DisplayFrameStats::toString() const {
    std::ostringstream s;
    s << "DisplayFrameStats{frame " << frame << ", " << times.toString() << ", edges "
      << silhouetteEdges << " sil + " << sharpEdges << " sharp + " << shadowEdges << " shadow -> "
      << screenEdges << " on screen, " << visiblePoints << " points, " << newSamples << " new ("
      << newSampleFraction << "), " << requestedSamples << " requested, pixels " << emptyPixels
      << " empty / " << simplePixels << " simple / " << complexPixels << " complex, "
      << unsampledPixels << " unsampled (" << unfilledPixels << " unfilled), " << reprojectedPixels
      << " reprojected, " << reconstructedPixels << " reconstructed, " << droppedShadowed
      << " dropped in moved shadows" << (usedEdges ? "" : ", no edges") << "}";
    return s.str();
}

std::string InteractiveDisplayOptions::toString() const {
    std::ostringstream s;
    s << "InteractiveDisplayOptions{" << width << "x" << height << ", sampleFraction "
      << sampleFraction << ", " << (synchronous ? "synchronous" : "asynchronous") << ", cache "
      << cacheCapacityPerPixel << "/pixel, near " << nearPlane << ", shadows "
      << (shadowEdges ? "on" : "off") << ", invalidate " << invalidateThreshold << ", "
      << epi.toString() << ", moving dense " << movingDenseComplexLimit << "}";
    return s.str();
}

std::string InteractiveDisplay::toString() const {
    std::ostringstream s;
    s << "InteractiveDisplay{" << mOptions.toString() << ", " << mCache.toString() << ", "
      << mEdges.toString() << ", " << mShadowEdges.size() << " shadow edges"
      << (mShadowsStale ? " (stale)" : "") << "}";
    return s.str();
}

// ---------------------------------------------------------------------------------------------
// Construction

namespace {

/// The display's points may be negative (PointShaderOptions::clampNegative off); a frame is
/// not. NaN stays NaN (every output path shows it as black).
Image clampedAtZero(Image image) {
    for (Rgb& p : image.pixels) p = Rgb(std::max(p.x, 0.0), std::max(p.y, 0.0), std::max(p.z, 0.0));
    return image;
}

PointShaderOptions shaderOptionsFor(const InteractiveDisplayOptions& o) {
    PointShaderOptions s = o.shader;
    if (o.synchronous) s.threads = 0;
    return s;
}

std::size_t capacityFor(const InteractiveDisplayOptions& o) {
    if (o.width <= 0 || o.height <= 0)
        throw std::invalid_argument("InteractiveDisplay: image size must be positive, got " +
                                    std::to_string(o.width) + "x" + std::to_string(o.height));
    const double pixels = static_cast<double>(o.width) * o.height;
    return static_cast<std::size_t>(std::max(1.0, std::ceil(o.cacheCapacityPerPixel * pixels)));
}

RenderCacheOptions cacheOptionsFor(const InteractiveDisplayOptions& o) {
    RenderCacheOptions c = o.cache;
    c.sampleFraction = o.sampleFraction;
    return c;
}

}  // namespace

InteractiveDisplay::InteractiveDisplay(const Discretization& disc, const RayTracer& tracer,
                                       const SolverOptions& solverOptions,
                                       InteractiveDisplayOptions options)
    : mDisc(disc),
      mTracer(tracer),
      mOptions(options),
      mShader(
          std::make_unique<PointShader>(disc, tracer, solverOptions, shaderOptionsFor(options))),
      mCache(options.width, options.height, capacityFor(options), cacheOptionsFor(options)),
      mEdges(disc, options.edges),
      mEpi(options.width, options.height, options.epi) {
    startShown();
}

void InteractiveDisplay::startShown() {
    elementShading(mShownTotal, mShownDirect);
    mShownValid.assign(mShownTotal.size(), 0);
    for (std::size_t e = 0; e < mShownValid.size(); ++e)
        mShownValid[e] = mDisc.elementAlive(static_cast<int>(e)) ? kShownAll : kShownNone;
    noteAlive();
}

InteractiveDisplay::InteractiveDisplay(const InteractiveDisplay& source,
                                       InteractiveDisplayOptions options)
    : mDisc(source.mDisc),
      mTracer(source.mTracer),
      mOptions(options),
      mShader(std::make_unique<PointShader>(*source.mShader, shaderOptionsFor(options))),
      mCache(options.width, options.height, capacityFor(options), cacheOptionsFor(options)),
      mEdges(source.mEdges),
      mEpi(options.width, options.height, options.epi),
      mShadowEdges(source.mShadowEdges),
      mShadowOrder(source.mShadowOrder),
      mShadowsStale(source.mShadowsStale) {
    startShown();
    setOccluder(source.mOccluder, source.mOccluderOnly, source.mOccluderFrames);
}

InteractiveDisplay::~InteractiveDisplay() = default;

// ---------------------------------------------------------------------------------------------
// Frames

std::vector<ShadedPoint> InteractiveDisplay::shadeAll(
    const std::vector<ShadeRequest>& requests) const {
    std::vector<ShadedPoint> out(requests.size());
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, requests.size(), 16),
                      [&](const tbb::blocked_range<std::size_t>& r) {
                          for (std::size_t i = r.begin(); i != r.end(); ++i)
                              out[i] = mShader->shade(requests[i]);
                      });
    return out;
}

Image InteractiveDisplay::renderFrame(const CameraRays& camera, bool useEdges) {
    beginFrame(camera, useEdges);
    Image image = reconstructFrame();
    finishFrame(camera, image);
    return image;
}

void InteractiveDisplay::beginFrame(const CameraRays& camera, bool useEdges) {
    if (camera.width() != mOptions.width || camera.height() != mOptions.height)
        throw std::invalid_argument(
            "InteractiveDisplay::renderFrame: camera raster " + std::to_string(camera.width()) +
            "x" + std::to_string(camera.height()) + " differs from the display's " +
            std::to_string(mOptions.width) + "x" + std::to_string(mOptions.height));
    const auto frameStart = Clock::now();
    mFrame = DisplayFrameStats{};
    DisplayFrameStats& st = mFrame;
    st.usedEdges = useEdges;
    // The world of this frame's points, for its holes (finishFrame).
    mFrameShading = mShader->snapshot();
    const bool sameAsLast = mPreviousCamera && *mPreviousCamera == camera;
    // The first frame counts as still: a view just opened is looked at.
    mCameraMoving = mPreviousCamera && !sameAsLast;
    mPreviousCamera = camera;
    // A windowed frame needs the camera and the mode of the last reconstruction.
    if (mOptions.windowedFrames) {
        mFrameCameraSame = mWindowValid && mWindowUseEdges == useEdges && sameAsLast;
        if (!mFrameCameraSame) mWindowValid = false;
    }

    // A finished estimate of the drag preview's direct light (backgroundPreview): drop the
    // points on elements whose H_direct changed (the moving shadow, a moved lamp's light).
    auto t = Clock::now();
    if (mShader->previewObject() >= 0 || mShader->directUpdatePending())
        if (!mShader->takeDirectUpdate().empty()) mRelightPending = true;
    if (mRelightPending) relightChanged();
    st.times.relightMs = msSince(t);
    // A preview left without an object taking its points (a cancelled drag): they go.
    dropLeftPreview();
    // Points behind a moving or new object, for this view, stay out of the image.
    const auto hideStart = Clock::now();
    hideOccluded(camera);
    st.times.hideMs = msSince(hideStart);
    // Take the points the asynchronous workers finished.
    std::vector<ShadedPoint> done;
    if (!mOptions.synchronous) done = mShader->takeResults();
    // The lamps a dragged object blocks now or blocked before: the points whose view of them
    // changed go, and so do results there shaded before it moved.
    if (!mMovedVersions.empty()) {
        const auto dropStart = Clock::now();
        st.droppedShadowed = dropShadowed(done, camera);
        st.times.shadowDropMs = msSince(dropStart);
    }
    if (!mOptions.synchronous) {
        // Requested before the dragged object moved on: a hit on an earlier place of the
        // dragged object moves with it, as its cached points did (carryPoints), and is re-shaded
        // first; a hit on another version no longer shown goes (the rest of the scene is as it
        // was; its light changes come as relights).
        const int preview = mShader->previewObject();
        if (preview >= 0) carryResults(done, preview);
        std::erase_if(done, [&](const ShadedPoint& p) {
            return p.object >= 0 && p.object != preview && !mDisc.objects()[p.object].alive;
        });
        // Shaded before its element's last relight: the change is not in its colour.
        for (ShadedPoint& p : done)
            if (p.element >= 0 && static_cast<std::size_t>(p.element) < mChangedAt.size() &&
                p.shading < mChangedAt[p.element])
                p.stale = true;
        const auto insertStart = Clock::now();
        mCache.insert(done);
        st.times.insertMs = msSince(insertStart);
        mInsertedSinceFrame += done.size();
    }
    st.newSamples = mInsertedSinceFrame;
    mInsertedSinceFrame = 0;

    // Reproject the cache to this camera (Walter et al. 1999), its visible points written
    // straight into the EPI's point arrays (§4.3).
    const auto reprojectStart = Clock::now();
    mCache.reproject(camera, mEpi.pointArrays());
    st.times.reprojectMs = msSince(reprojectStart);
    st.frame = mCache.frame();
    st.visiblePoints = mCache.visibleCount();
    st.reprojectedPixels = mCache.lastReprojectedPixels();
    st.times.pointsMs = msSince(t);

    // Edges (§6): silhouettes and forward-facing sharp edges per frame, shadow edges kept until
    // something changes; then clip and project.
    if (useEdges) {
        t = Clock::now();
        const Vec3 eye = camera.origin();
        // Per object in parallel, into lists kept across frames.
        mEdges.findSilhouettes(eye, mSilhouettes);
        mEdges.findSharpEdges(eye, mSharpEdges);
        st.silhouetteEdges = st.sharpEdges = 0;
        for (const auto& list : mSilhouettes) st.silhouetteEdges += list.size();
        for (const auto& list : mSharpEdges) st.sharpEdges += list.size();
        st.times.silhouetteMs = msSince(t);
        if (mOptions.shadowEdges) {
            st.times.shadowMs = updateShadowEdges();
            st.shadowEdges = mShadowEdges.size();
        }
        // Silhouettes, sharp edges and shadow edges projected in that order (findSilhouettes,
        // findSharpEdges, mShadowEdges concatenated), less the edges that cannot mark the EPI.
        t = Clock::now();
        std::vector<std::span<const WorldEdge>> lists;
        lists.reserve(mSilhouettes.size() + mSharpEdges.size() + 1);
        for (const auto& list : mSilhouettes) lists.emplace_back(list);
        for (const auto& list : mSharpEdges) lists.emplace_back(list);
        // Shadow edges by penumbra: those too soft to mark from any depth of this view are
        // not projected at all (armadillo-field: 74k of 190k).
        if (mOptions.shadowEdges)
            lists.emplace_back(mShadowEdges.data(),
                               penumbraPrefix(mShadowOrder, camera, mOptions.nearPlane,
                                              mOptions.maxPenumbraPixels));
        projectEpiEdges(lists, camera, mOptions.nearPlane, mScreenEdges, mProjectScratch, true,
                        mOptions.maxPenumbraPixels);
        st.times.projectMs = msSince(t);
        st.times.findEdgesMs = st.times.silhouetteMs + st.times.shadowMs + st.times.projectMs;
    } else {
        mScreenEdges.clear();
    }
    st.screenEdges = mScreenEdges.size();
    st.times.totalMs = msSince(frameStart);
}

Image InteractiveDisplay::reconstructFrame() {
    // The edge-and-point image and its reconstruction (§4–5): the EPI's own arrays only.
    const auto t = Clock::now();
    // A moving camera's frame filters fewer complex pixels (movingDenseComplexLimit); only a
    // frame filtered as `epi` says can seed the windowed frames that follow it.
    const int denseLimit = mCameraMoving && mOptions.movingDenseComplexLimit > 0
                               ? mOptions.movingDenseComplexLimit
                               : mOptions.epi.denseComplexLimit;
    mEpi.setDenseComplexLimit(denseLimit);
    const std::optional<std::vector<PixelWindow>> windows =
        mOptions.windowedFrames ? changedWindows() : std::nullopt;
    Image image;
    mFrameWindowed = windows.has_value();
    if (windows) {
        // Only the pixels the changes reach (a still camera): the rest is the last image.
        mWindowTimes = {};
        const int reach = mEpi.reconstructionReach();
        for (const PixelWindow& window : *windows) {
            mEpi.reconstructWindow(mScreenEdges, window, mFrame.usedEdges, mShownImage);
            const EpiStageTimes& t = mEpi.stageTimes();
            mWindowTimes.depthFilterMs += t.depthFilterMs;
            mWindowTimes.rasterizeMs += t.rasterizeMs;
            mWindowTimes.classifyMs += t.classifyMs;
            mWindowTimes.reachabilityMs += t.reachabilityMs;
            mWindowTimes.interpolateMs += t.interpolateMs;
            mWindowTimes.antiAliasMs += t.antiAliasMs;
            mWindowTimes.complexFilterMs += t.complexFilterMs;
            mWindowTimes.smoothMs += t.smoothMs;
            const PixelWindow out = window.grownWithin(reach, mOptions.width, mOptions.height);
            for (int y = out.y0; y < out.y1; ++y)
                for (int x = out.x0; x < out.x1; ++x)
                    mShownImage.at(x, y) = glm::max(mShownImage.at(x, y), Rgb(0.0));
            noteShown(out);
            mFrame.reconstructedPixels += static_cast<std::size_t>(out.area());
        }
        mLastWindowed = mLastWindowed || !windows->empty();
        noteShownEdges();
        image = mShownImage;
    } else {
        mEpi.build(mScreenEdges);
        image = clampedAtZero(mEpi.reconstruct(mFrame.usedEdges));
        mFrame.reconstructedPixels = static_cast<std::size_t>(mOptions.width) * mOptions.height;
        mLastWindowed = false;
        if (mOptions.windowedFrames) {
            mShownImage = image;
            noteShown({0, 0, mOptions.width, mOptions.height});
            noteShownEdges();
            mWindowValid = denseLimit == mOptions.epi.denseComplexLimit;
            mWindowUseEdges = mFrame.usedEdges;
        }
    }
    mFrame.times.totalMs += msSince(t);
    return image;
}

void InteractiveDisplay::finishFrame(const CameraRays& camera, Image& image) {
    const auto finishStart = Clock::now();
    DisplayFrameStats& st = mFrame;
    const EpiStageTimes& epi = mFrameWindowed ? mWindowTimes : mEpi.stageTimes();
    st.times.rasterizeMs = epi.depthFilterMs + epi.rasterizeMs + epi.classifyMs;
    st.times.reachabilityMs = epi.reachabilityMs;
    st.times.interpolateMs = epi.interpolateMs;
    st.times.antiAliasMs = epi.antiAliasMs;
    st.times.complexFilterMs = epi.complexFilterMs;
    st.times.smoothMs = epi.smoothMs;
    // Holes: pixels no point reached take the fallback, never black.
    st.unsampledPixels = mEpi.holeCount();
    st.unfilledPixels = st.unsampledPixels;
    auto t = Clock::now();
    if (mOptions.fillHoles && st.unsampledPixels > 0) {
        fillHoles(camera, image);
        st.unfilledPixels = 0;
        st.times.fillMs = msSince(t);
    }
    st.emptyPixels = mEpi.countPixels(PixelClass::Empty);
    st.simplePixels = mEpi.countPixels(PixelClass::Simple);
    st.complexPixels = mEpi.countPixels(PixelClass::Complex);

    // New sample requests from the cache's priority image (§5.3 feedback).
    t = Clock::now();
    const double pixels = static_cast<double>(mOptions.width) * mOptions.height;
    int budget = static_cast<int>(std::lround(mOptions.sampleFraction * pixels));
    int changedBudget = static_cast<int>(std::lround(mOptions.changedSampleFraction * pixels));
    if (!mOptions.synchronous) {
        const std::size_t cap =
            mOptions.maxPendingPerFrame * static_cast<std::size_t>(budget + changedBudget);
        const std::size_t pending = mShader->pendingCount();
        const std::size_t room = pending >= cap ? 0 : cap - pending;
        budget = static_cast<int>(std::min<std::size_t>(budget, room));
        changedBudget = static_cast<int>(std::min<std::size_t>(changedBudget, room - budget));
    }
    std::vector<ShadeRequest> requests;
    mCache.setRequestChangedOnly(mOptions.dragSamplesChangedOnly && mShader->previewObject() >= 0);
    if (mOptions.restWhenConverged) {
        const int merge = mOptions.cache.mergeSamples;
        const std::uint8_t converged =
            merge > 0 ? static_cast<std::uint8_t>(std::min<int>(merge, kEpiTrustExact))
                      : kEpiTrustExact;
        mCache.setRequestConverged(mEpi.pointArrays().trust, converged, 2 * converged);
    }
    if (budget > 0) {
        mCache.applyInterpolationFeedback(mEpi.interpolationWeights());
        requests = mCache.requestSamples(camera, budget, changedBudget);
    }
    st.requestedSamples = requests.size();
    if (!mOptions.synchronous && !requests.empty()) mShader->submit(requests);
    st.times.requestMs = msSince(t);
    st.times.totalMs += msSince(finishStart);
    st.newSampleFraction = static_cast<double>(st.newSamples) / pixels;

    // Synchronous mode: shade now, visible from the next frame on.
    if (mOptions.synchronous && !requests.empty()) {
        t = Clock::now();
        std::vector<ShadedPoint> done = shadeAll(requests);
        mCache.insert(done);
        mInsertedSinceFrame += done.size();
        st.times.shadeMs = msSince(t);
    }
    mLast = st;
    mFrameShading = {};
}

Image InteractiveDisplay::reconstructLast(bool useEdges) {
    // After windowed frames the EPI's whole build is older than its points: build it again.
    if (mLastWindowed) mEpi.build(mScreenEdges);
    mLastWindowed = false;
    mWindowValid = false;  // the EPI's state is no longer the shown image's
    return clampedAtZero(mEpi.reconstruct(useEdges));
}

void InteractiveDisplay::fillHoles(const CameraRays& camera, Image& image) const {
    const std::vector<std::uint8_t>& holes = mEpi.holes();
    const int w = mOptions.width;
    tbb::parallel_for(tbb::blocked_range<int>(0, mOptions.height, 8),
                      [&](const tbb::blocked_range<int>& rows) {
                          for (int y = rows.begin(); y != rows.end(); ++y)
                              for (int x = 0; x < w; ++x)
                                  if (holes[static_cast<std::size_t>(y) * w + x])
                                      image.at(x, y) = mShader->shadeFallback(
                                          mFrameShading, camera.origin(),
                                          camera.rayDirection(x + 0.5, y + 0.5));
                      });
}

// ---------------------------------------------------------------------------------------------
// Warm-up

std::size_t InteractiveDisplay::warmUp(const CameraRays& camera, double density) {
    if (camera.width() != mOptions.width || camera.height() != mOptions.height)
        throw std::invalid_argument("InteractiveDisplay::warmUp: camera raster differs");
    if (!(density > 0)) return 0;
    const int step =
        std::max(1, static_cast<int>(std::lround(1.0 / std::sqrt(std::min(1.0, density)))));
    // One pixel per step × step cell, its position inside the cell and inside the pixel jittered
    // from a key of (pixel, frame) so the pattern is deterministic.
    std::vector<ShadeRequest> requests;
    const std::uint64_t frame = mCache.frame();
    for (int cy = 0; cy < mOptions.height; cy += step)
        for (int cx = 0; cx < mOptions.width; cx += step) {
            const std::uint64_t key =
                hashPair(hashPair(static_cast<std::uint64_t>(cy), static_cast<std::uint64_t>(cx)),
                         frame + 0x57A1ULL);
            const int w = std::min(step, mOptions.width - cx);
            const int h = std::min(step, mOptions.height - cy);
            const int px = cx + std::min(w - 1, static_cast<int>(unitFromKey(key) * w));
            const int py = cy + std::min(h - 1, static_cast<int>(unitFromKey(key + 1) * h));
            const glm::dvec2 p(px + unitFromKey(key + 2), py + unitFromKey(key + 3));
            requests.push_back({p, camera.origin(), camera.rayDirection(p.x, p.y), frame});
        }
    // Shaded from the current lighting: a deferred relight goes to the points before them.
    if (mRelightPending) relightChanged();
    std::vector<ShadedPoint> done = shadeAll(requests);
    mCache.insert(done);
    mInsertedSinceFrame += done.size();
    return done.size();
}

void InteractiveDisplay::insertShaded(const std::vector<ShadedPoint>& points) {
    if (mRelightPending) relightChanged();
    mCache.insert(points);
    mInsertedSinceFrame += points.size();
}

std::vector<ShadedPoint> InteractiveDisplay::insertShadedFindingEdges(
    const std::function<std::vector<ShadedPoint>()>& gather) {
    std::vector<ShadedPoint> points;
    tbb::task_group edges;
    if (mOptions.shadowEdges) edges.run([this] { updateShadowEdges(); });
    try {
        points = gather();
    } catch (...) {
        edges.wait();
        throw;
    }
    edges.wait();
    insertShaded(points);
    return points;
}

double InteractiveDisplay::updateShadowEdges() {
    if (!mShadowsStale) return 0;
    const auto t = Clock::now();
    mEdges.findShadowEdges(mShadowEdges);
    mShadowOrder = orderByPenumbra(mShadowEdges, mShadowScratch);
    mShadowsStale = false;
    mLastShadowUpdateMs = msSince(t);
    return mLastShadowUpdateMs;
}

std::uint64_t InteractiveDisplay::shadingSerial() const { return mShader->stateSerial(); }

// ---------------------------------------------------------------------------------------------
// Edits and solution updates

void InteractiveDisplay::elementShading(std::vector<Rgb>& total, std::vector<Rgb>& direct) const {
    const std::vector<Rgb> d = mShader->elementDirect();
    const std::vector<Rgb> indirect = mShader->elementIndirect();
    const std::size_t n = mDisc.elements().size();
    total.assign(n, Rgb(0.0));
    direct.assign(n, Rgb(0.0));
    const double invPi = 1.0 / M_PI;
    for (std::size_t e = 0; e < n; ++e) {
        const Material& m = mDisc.elementMaterial(static_cast<int>(e));
        const Rgb hd = e < d.size() ? d[e] : Rgb(0.0);
        const Rgb hi = e < indirect.size() ? indirect[e] : Rgb(0.0);
        total[e] = (m.emission + m.reflectance * (hd + hi)) * invPi;
        direct[e] = m.reflectance * hd * invPi;
    }
}

std::size_t InteractiveDisplay::relightOrDefer() {
    if (!mOptions.deferRelight) return relightChanged();
    mRelightPending = true;
    return 0;
}

std::size_t InteractiveDisplay::relightChanged() {
    mRelightPending = false;
    std::vector<Rgb> total, direct;
    elementShading(total, direct);
    const std::size_t n = total.size();
    double mean = 0;
    std::size_t alive = 0;
    for (std::size_t e = 0; e < n; ++e)
        if (mDisc.elementAlive(static_cast<int>(e))) {
            mean += luminance(total[e]);
            ++alive;
        }
    mean = alive ? mean / static_cast<double>(alive) : 0.0;
    const std::size_t known = mShownTotal.size();
    std::vector<Rgb> delta(n, Rgb(0.0)), directDelta(n, Rgb(0.0));
    std::vector<std::uint8_t> stale(n, 0);
    bool any = false;
    for (std::size_t e = 0; e < std::min(n, known); ++e) {
        const double before = luminance(mShownTotal[e]), after = luminance(total[e]);
        const double scale = std::max({std::abs(before), std::abs(after), 0.01 * mean});
        // Stale when the element's shading moved, or its direct light (a shadow moving across
        // it, which the element's total may hide while the solver catches up).
        const double change = std::max(std::abs(after - before),
                                       std::abs(luminance(direct[e]) - luminance(mShownDirect[e])));
        stale[e] = change > mOptions.invalidateThreshold * scale;
        // The element's change, added to its points where they follow the element's shading.
        if (mShownValid[e] == kShownAll) {
            delta[e] = total[e] - mShownTotal[e];
            directDelta[e] = direct[e] - mShownDirect[e];
        } else if (mShownValid[e] == kShownDirect) {
            // A moved object's points take the change of their direct light from the place
            // they were shaded at (a shadow they left or entered) once the shader's estimate
            // for the new place is in; until then they keep what they show.
            if (mShader->directKnown(mDisc.elements()[e].object))
                delta[e] = direct[e] - mShownDirect[e];
            else
                direct[e] = mShownDirect[e];
        }
        any = any || stale[e] || delta[e] != Rgb(0.0);
    }
    // Points shaded before this on the elements that went stale are stale when they arrive.
    const std::uint64_t serial = mShader->stateSerial();
    mChangedAt.resize(n, 0);
    for (std::size_t e = 0; e < std::min(n, known); ++e)
        if (stale[e]) mChangedAt[e] = serial;
    std::vector<Rgb> before = std::move(mShownTotal);
    mShownTotal = std::move(total);
    mShownDirect = std::move(direct);
    // Elements of versions that appeared since: nothing cached reflects them yet.
    mShownValid.resize(n, kShownNone);
    // Points on the scene's objects shaded since its geometry and lights last changed (or
    // since a drag began: its moves re-shade the points whose view of a lamp they change,
    // dropShadowed) hold their direct light: the element's estimate catching up with it (a
    // drag's estimate that comes positions late, the exact one at the drop) is not theirs.
    return any ? mCache.relight(delta, stale, before, directDelta, mDirectSince) : 0;
}

SolutionView SolutionView::of(const ProgressiveSolver& solver) {
    SolutionView view;
    view.irradiance = &solver.irradiance();
    view.fromEmission = &solver.irradianceFromEmission();
    if (solver.previewObject() >= 0) {
        view.previewRadiosity = &solver.previewRadiosity();
        view.previewFromEmission = &solver.previewRadiosityFromEmission();
        view.previewObject = solver.previewObject();
        view.previewComplete = solver.previewComplete();
    }
    return view;
}

std::size_t InteractiveDisplay::apply(const SolutionView& solution) {
    if (!solution.irradiance || !solution.fromEmission)
        throw std::invalid_argument(
            "InteractiveDisplay::apply: a SolutionView without irradiance or fromEmission");
    mShader->updateSolution(*solution.irradiance, *solution.fromEmission, solution.previewRadiosity,
                            solution.previewFromEmission, solution.previewObject,
                            solution.previewComplete);
    return relightOrDefer();
}

std::size_t InteractiveDisplay::dropShadowed(std::vector<ShadedPoint>& results,
                                             const CameraRays& camera) {
    std::vector<int> moved;
    moved.swap(mMovedVersions);
    // The object where the last frame showed it and where it is now (the places in between
    // were never shown), as world boxes a little larger than the object.
    auto boxOf = [&](int v) {
        const auto& positions = mDisc.objects()[v].worldPositions;
        Vec3 lo = positions.front(), hi = positions.front();
        for (const Vec3& p : positions) lo = glm::min(lo, p), hi = glm::max(hi, p);
        const Vec3 pad(4 * mTracer.epsilon() + 1e-6 * glm::length(hi - lo));
        return std::pair<Vec3, Vec3>(lo - pad, hi + pad);
    };
    if (mDisc.objects()[moved.front()].worldPositions.empty() ||
        mDisc.objects()[moved.back()].worldPositions.empty())
        return 0;
    const auto [thenLo, thenHi] = boxOf(moved.front());
    const auto [nowLo, nowHi] = boxOf(moved.back());
    // The live lamps other than the moved object (a dragged object that emits is not here).
    std::vector<ShaftLight> lights;
    for (int l = 0; l < mEdges.lightCount(); ++l)
        if (mEdges.lightAlive(l) &&
            std::find(moved.begin(), moved.end(), mEdges.light(l).object) == moved.end())
            lights.emplace_back(mEdges.light(l));
    if (lights.empty()) return 0;
    // How much the move changed the share of the lamps the object hides from x (the lamps
    // weighted by their form factors at x), relative to the light arriving there.
    auto shadowChange = [&](const Vec3& x, const Vec3& n) {
        double change = 0, total = 0;
        for (const ShaftLight& light : lights) {
            const double w = lightWeight(x, n, light);
            if (!(w > 0)) continue;
            total += w;
            change += w * std::abs(blockedFraction(x, light, nowLo, nowHi) -
                                   blockedFraction(x, light, thenLo, thenHi));
        }
        return total > 0 ? change / total : 0.0;
    };
    // Per element: whether the change exceeds shadowDropChange of its light at the centroid or
    // at a corner (pulled in a little: a shadow's edge may cross a large element anywhere).
    const double minChange = mOptions.shadowDropChange;
    const std::size_t elements = mDisc.elements().size();
    std::vector<std::uint8_t> changed(elements, 0);
    // Whether some probe point of an element (all within its radius r of the centroid c) can
    // have a shaft to a lamp that meets either box: no lamp lights a probe when the element
    // lies wholly behind the lamp's plane; one straddling it may; otherwise every probe's
    // shaft lies within r of c's, so c's shaft against the boxes grown by r decides. One
    // test a lamp instead of one per probe (most elements of a room), and never a miss.
    auto mayChange = [&](const Element& el, const std::vector<Vec3>& world) {
        double r = 0;
        for (int v : el.vertices) r = std::max(r, glm::length(world[v] - el.centroid));
        const Vec3 grow(r);
        for (const ShaftLight& light : lights) {
            const double n = glm::length(light.normal);
            if (light.polygon.size() > 1 && n > 0) {
                const double side = glm::dot(el.centroid - light.centroid, light.normal) / n;
                if (side < -r) continue;
                if (side <= r) return true;
            }
            if (shaftMeetsBox(el.centroid, light, nowLo - grow, nowHi + grow) ||
                shaftMeetsBox(el.centroid, light, thenLo - grow, thenHi + grow))
                return true;
        }
        return false;
    };
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, elements, 512),
                      [&](const tbb::blocked_range<std::size_t>& r) {
                          for (std::size_t e = r.begin(); e != r.end(); ++e) {
                              const Element& el = mDisc.elements()[e];
                              if (std::find(moved.begin(), moved.end(), el.object) != moved.end())
                                  continue;
                              if (!mDisc.objects()[el.object].alive) continue;
                              const auto& world = mDisc.objects()[el.object].worldPositions;
                              if (mOptions.shadowDropCull && !mayChange(el, world)) continue;
                              bool any = shadowChange(el.centroid, el.normal) > minChange;
                              for (std::size_t k = 0; !any && k < el.vertices.size(); ++k)
                                  any =
                                      shadowChange(world[el.vertices[k]] +
                                                       0.1 * (el.centroid - world[el.vertices[k]]),
                                                   el.normal) > minChange;
                              changed[e] = any ? 1 : 0;
                          }
                      });
    // A point of such an element goes when it lies in the object's old or new shadow volume
    // (its shaft to a lamp meets either box): outside both the object hides nothing of any
    // lamp from it, before or after, and its direct light stands. So the drop follows the
    // shadow, not the elements it crosses.
    auto shadowed = [&](int element, const Vec3& x) {
        if (element < 0 || static_cast<std::size_t>(element) >= elements || !changed[element])
            return false;
        for (const ShaftLight& light : lights)
            if (shaftMeetsBox(x, light, nowLo, nowHi) || shaftMeetsBox(x, light, thenLo, thenHi))
                return true;
        return false;
    };
    const std::vector<CachePoint>& points = mCache.points();
    const std::vector<std::int32_t>& objectOf = mCache.pointObjects();
    const std::vector<std::int32_t>& elementOf = mCache.pointElements();
    const std::vector<Vec3>& positionOf = mCache.pointPositions();
    std::vector<std::uint8_t> drop(points.size(), 0);
    // Dropped points the last frame showed.
    const std::size_t seen = tbb::parallel_reduce(
        tbb::blocked_range<std::size_t>(0, points.size(), 8192), std::size_t{0},
        [&](const tbb::blocked_range<std::size_t>& r, std::size_t count) {
            for (std::size_t i = r.begin(); i != r.end(); ++i) {
                drop[i] = objectOf[i] >= 0 && shadowed(elementOf[i], positionOf[i]) ? 1 : 0;
                count += drop[i] && mCache.visible(i) && !mCache.hidden(i);
            }
            return count;
        },
        std::plus<>());
    // One pixel per cell of the dropped points' pixels in this view, re-shaded below; the cell
    // grows so that at most shadowReshadeMax are.
    int cell = std::max(0, mOptions.shadowReshadeCell);
    const double cap = std::max(1, mOptions.shadowReshadeMax);
    if (cell > 0 && double(seen) > cap * cell * cell)
        cell = static_cast<int>(std::ceil(std::sqrt(double(seen) / cap)));
    std::vector<ShadeRequest> requests;
    if (cell > 0) {
        const int cw = (mOptions.width + cell - 1) / cell, ch = (mOptions.height + cell - 1) / cell;
        std::vector<std::uint8_t> taken(static_cast<std::size_t>(cw) * ch, 0);
        // Requested in the frame being made (reproject numbers it next).
        const std::uint64_t frame = mCache.frame() + 1;
        auto request = [&](const Vec3& position) {
            const auto pixel = camera.projectToPixel(position);
            if (!pixel || pixel->x < 0 || pixel->y < 0 || pixel->x >= mOptions.width ||
                pixel->y >= mOptions.height)
                return;
            const int x = static_cast<int>(pixel->x), y = static_cast<int>(pixel->y);
            std::uint8_t& t = taken[static_cast<std::size_t>(y / cell) * cw + x / cell];
            if (t) return;
            t = 1;
            const glm::dvec2 p(x + 0.5, y + 0.5);
            requests.push_back({p, camera.origin(), camera.rayDirection(p.x, p.y), frame});
        };
        // The moved object's own points, where they were when the frame before was drawn:
        // what it uncovered there has no point yet.
        const int now = moved.back();
        const Mat4 thenFromNow = motion(now, moved.front());
        // The points to ask about, found in parallel; the requests made in index order.
        const std::vector<int> asked = indicesWhere(points.size(), [&](std::size_t i) {
            // Dropped, seen in the last frame and not now behind the moved object.
            return (drop[i] && mCache.visible(i) && !mCache.hidden(i)) || objectOf[i] == now;
        });
        for (const int i : asked) {
            if (drop[i] && mCache.visible(i) && !mCache.hidden(i)) request(positionOf[i]);
            if (objectOf[i] == now) request(Vec3(thenFromNow * glm::dvec4(positionOf[i], 1.0)));
        }
    }
    const std::size_t dropped = mCache.invalidatePoints(drop);
    std::erase_if(results, [&](const ShadedPoint& p) {
        return p.shading < mMoveSerial && p.object >= 0 && shadowed(p.element, p.position);
    });
    if (!requests.empty()) {
        const auto reshadeStart = Clock::now();
        std::vector<ShadedPoint> done = shadeAll(requests);
        mCache.insert(done);
        mInsertedSinceFrame += done.size();
        mFrame.times.shadowReshadeMs = msSince(reshadeStart);
    }
    return dropped;
}

void InteractiveDisplay::syncLights() {
    // Which objects emit (from their patches' materials).
    const int objects = static_cast<int>(mDisc.objects().size());
    std::vector<char> emits(objects, 0);
    for (const Patch& p : mDisc.patches())
        if (mDisc.materials()[p.material].isEmitter()) emits[p.object] = 1;
    std::vector<char> hasLight(objects, 0);
    for (int l = 0; l < mEdges.lightCount(); ++l) {
        const int o = mEdges.light(l).object;
        const bool live = o >= 0 && o < objects && emits[o] && mDisc.objects()[o].alive;
        mEdges.setLightAlive(l, live);
        if (o >= 0 && o < objects) hasLight[o] = 1;
    }
    // Lights for emitters the finder does not know yet (added, moved or made emitting).
    for (int o = 0; o < objects; ++o) {
        if (!emits[o] || hasLight[o] || !mDisc.objects()[o].alive) continue;
        Light light = lightForObject(mDisc, o);
        if (!light.polygon.empty()) mEdges.addLight(light);
    }
}

void InteractiveDisplay::syncEdges() {
    mEdges.syncWith(mDisc);
    const int preview = mShader->previewObject();
    if (preview >= 0 && preview < mEdges.objectCount()) mEdges.setObjectAlive(preview, true);
}

std::size_t InteractiveDisplay::carryPoints(int from, int to) {
    const int objects = static_cast<int>(mDisc.objects().size());
    if (from < 0 || to < 0 || from == to || from >= objects || to >= objects) return 0;
    // The same mesh at another place (a move): its points move with it. Otherwise (another
    // shape, or a scale that changed the elements) they go.
    if (!mDisc.sameElements(from, to)) return mCache.invalidateObjects({from});
    const auto [firstA, countA] = mDisc.elementRange(from);
    const int firstB = mDisc.elementRange(to).first;
    const std::size_t moved = mCache.carry(from, to, motion(from, to), firstB - firstA);
    // The moved points show what the old elements showed (not the new ones' lighting); the
    // change of their direct light is added when the shader knows it (relightChanged).
    const std::size_t n = mDisc.elements().size();
    if (mShownTotal.size() < n) {
        mShownTotal.resize(n, Rgb(0.0));
        mShownDirect.resize(n, Rgb(0.0));
        mShownValid.resize(n, kShownNone);
    }
    for (int k = 0; k < countA; ++k) {
        mShownTotal[firstB + k] = mShownTotal[firstA + k];
        mShownDirect[firstB + k] = mShownDirect[firstA + k];
        mShownValid[firstB + k] = mShownValid[firstA + k] != kShownNone ? kShownDirect : kShownNone;
    }
    return moved;
}

Mat4 InteractiveDisplay::motion(int from, int to) const {
    return mDisc.objects()[to].worldFromObject *
           glm::inverse(mDisc.objects()[from].worldFromObject);
}

void InteractiveDisplay::carryResults(std::vector<ShadedPoint>& results, int preview) const {
    const ObjectSurface& now = mDisc.objects()[preview];
    const int firstNow = mDisc.elementRange(preview).first;
    for (ShadedPoint& p : results) {
        if (p.object < 0 || p.object == preview || mDisc.objects()[p.object].alive ||
            mDisc.objects()[p.object].id != now.id || !mDisc.sameElements(p.object, preview))
            continue;
        // Shaded at an earlier place of the drag: its light is that place's, a step or two
        // behind, which the element-level change (relightChanged) then follows; it is
        // re-shaded first (stale), and never an exact own point.
        const Mat4 toNow = motion(p.object, preview);
        p.position = Vec3(toNow * glm::dvec4(p.position, 1.0));
        p.normal =
            glm::normalize(Vec3(glm::transpose(glm::inverse(toNow)) * glm::dvec4(p.normal, 0.0)));
        p.element += firstNow - mDisc.elementRange(p.object).first;
        p.object = preview;
        p.stale = true;
        p.exact = false;
    }
}

void InteractiveDisplay::setOccluder(int version, const Visibility& only, int frames) {
    if (version != mOccluder) mHiddenFor = -1;  // test every point again
    mOccluder = version;
    mOccluderFrames = frames;
    mOccluderOnly = only;
    if (version >= 0 && only.subset < 0) {
        // No subset of its own: a world filter admitting it alone.
        mOccluderMask.assign(mDisc.objects().size(), 0);
        mOccluderMask[version] = 1;
        mOccluderOnly = Visibility{};
        mOccluderOnly.world = &mOccluderMask;
    }
}

std::size_t InteractiveDisplay::hideOccluded(const CameraRays& camera) {
    const bool active = mOccluder >= 0 && mOccluder < static_cast<int>(mDisc.objects().size()) &&
                        mOccluderFrames != 0;
    if (!active) {
        if (mHiding) mCache.setHidden({});
        mHiding = false;
        return 0;
    }
    if (mOccluderFrames > 0) --mOccluderFrames;
    // Hidden points stay hidden while neither the view nor the occluder moves: points shaded
    // since are what the eye sees first, never behind it.
    const bool sameView = mHiddenFor == mOccluder && mHiddenWidth == camera.width() &&
                          mHiddenHeight == camera.height() && mHiddenEye == camera.origin() &&
                          mHiddenForward == camera.forward() && mHiddenRight == camera.right() &&
                          mHiddenUp == camera.up();
    if (mHiding && sameView) return 0;
    mHiddenFor = mOccluder;
    mHiddenWidth = camera.width();
    mHiddenHeight = camera.height();
    mHiddenEye = camera.origin();
    mHiddenForward = camera.forward();
    mHiddenRight = camera.right();
    mHiddenUp = camera.up();
    // The occluder's bounding sphere, seen from the eye, bounds the points it can hide: a cone
    // of directions and the sphere's nearest depth (a point in front of it, or outside the
    // cone, is not tested).
    const ObjectSurface& s = mDisc.objects()[mOccluder];
    const Vec3 eye = camera.origin();
    Vec3 lo(std::numeric_limits<double>::infinity()), hi(-lo);
    for (const Vec3& p : s.worldPositions) lo = glm::min(lo, p), hi = glm::max(hi, p);
    const Vec3 centre = 0.5 * (lo + hi);
    const double radius = 0.5 * glm::length(hi - lo);
    const double distance = glm::length(centre - eye);
    const bool inside = !(distance > radius);  // the eye in the sphere: every direction
    const Vec3 axis = inside ? Vec3(0.0) : (centre - eye) / distance;
    const double cosCone =
        inside ? -1.0 : std::sqrt(std::max(0.0, 1.0 - (radius / distance) * (radius / distance)));
    const double nearest = inside ? 0.0 : distance - radius;
    const RayTracer& tracer = mTracer;
    const Visibility only = mOccluderOnly;
    const int occluder = mOccluder;
    mHiding = true;
    return mCache.setHidden([&](const Vec3& position, int object) {
        if (object == occluder) return false;
        const Vec3 d = position - eye;
        const double length = glm::length(d);
        if (!(length > nearest) || glm::dot(d, axis) < cosCone * length) return false;
        return tracer.occluded(eye, position, only);
    });
}

std::size_t InteractiveDisplay::apply(const EditEvent& event, const DragVisibility& drag,
                                      const ProgressiveSolver* solver) {
    using Kind = EditEvent::Kind;
    std::size_t n = 0;
    switch (event.kind) {
        case Kind::Solved:
            return 0;
        case Kind::Changed:
            n = notifyChanged(event.changed(), solver);
            if (event.preview >= 0) n += setPreview(event.preview, drag.preview, solver);
            return n;
        case Kind::DragBegan:
            if (previewVersion() >= 0) n += clearPreview(solver);
            beginDrag(event.origin, drag.origin);
            return n + setPreview(event.preview, drag.preview, solver);
        case Kind::PreviewMoved:
            return setPreview(event.preview, drag.preview, solver);
        case Kind::DragEnded: {
            const int added = event.added.empty() ? -1 : event.added.front();
            // The drag this display followed ends where it last saw it: its last change joins
            // the direct light, nothing recomputed.
            if (added >= 0 && dragOrigin() >= 0 && previewVersion() == added)
                return endDrag(added, solver);
            if (previewVersion() >= 0) n += clearPreview(solver);
            return n + notifyChanged(event.added, solver);
        }
    }
    return n;
}

std::size_t InteractiveDisplay::notifyChanged(const std::vector<int>& changedObjects,
                                              const ProgressiveSolver* solver) {
    // Work from before the edit is stale.
    mShader->cancelPending();
    if (!mOptions.synchronous) (void)mShader->takeResults();

    // Versions that entered and left: a moved object is both (the same document id), and
    // its points move with it; a removed object's points go; an added one has none yet.
    const int objects = static_cast<int>(mDisc.objects().size());
    std::vector<int> entered, left;
    for (int o : changedObjects) {
        if (o < 0 || o >= objects) continue;
        const bool known = o < static_cast<int>(mKnownAlive.size());
        const bool wasAlive = known && mKnownAlive[o];
        const bool alive = mDisc.objects()[o].alive;
        if (alive && !wasAlive) entered.push_back(o);
        if (!alive && wasAlive) left.push_back(o);
    }
    std::size_t changed = 0;
    for (int o : entered) {
        const auto from = std::find_if(left.begin(), left.end(), [&](int u) {
            return mDisc.objects()[u].id == mDisc.objects()[o].id;
        });
        if (from != left.end()) {
            changed += carryPoints(*from, o);
            left.erase(from);
        } else if (mLeftPreview >= 0 && mDisc.objects()[mLeftPreview].id == mDisc.objects()[o].id) {
            // The drag's last preview (clearPreview): the object rests a little further on.
            changed += carryPoints(mLeftPreview, o);
            mLeftPreview = -1;
        }
        // Points behind it (for the next frames' views) are hidden while its own arrive.
        setOccluder(o, Visibility{}, kOccluderFrames);
    }
    if (!left.empty())
        changed += mCache.invalidateObjects(std::unordered_set<int>(left.begin(), left.end()));
    changed += dropLeftPreview();
    // A material edit: the points on the object are stale (relightChanged adds the element's
    // change meanwhile).
    std::unordered_set<int> materials;
    for (int o : changedObjects)
        if (o >= 0 && o < objects && mDisc.objects()[o].alive &&
            std::find(entered.begin(), entered.end(), o) == entered.end())
            materials.insert(o);
    if (!materials.empty()) changed += mCache.markStale(materials);
    noteAlive();

    // Edge finder: new object versions, alive flags, lights; shadows recomputed next frame.
    syncEdges();
    syncLights();
    mShadowsStale = true;

    // Direct lighting the change affects, then the solution; points on elements whose
    // shading changed take the change and are re-shaded first (Bala et al. §7.5).
    mShader->refreshDirect(changedObjects);
    if (solver) mShader->updateSolution(*solver);
    mDirectSince = mShader->stateSerial();
    changed += relightChanged();
    for (int o : entered) trustShown(o);
    return changed;
}

void InteractiveDisplay::trustShown(int object) {
    // From now on the object rests: the points shaded on it reflect the shading relightChanged
    // just recorded, and later changes (the solver catching up with it) are added to them. (A
    // drag's preview versions are not trusted: their shading lags the moves, so adding its
    // changes would darken the moving object by whatever the solver has not yet shot to it.)
    const auto [first, count] = mDisc.elementRange(object);
    for (int k = 0; k < count; ++k)
        if (static_cast<std::size_t>(first + k) < mShownValid.size())
            mShownValid[first + k] = kShownAll;
}

void InteractiveDisplay::noteAlive() {
    mKnownAlive.resize(mDisc.objects().size());
    for (std::size_t o = 0; o < mDisc.objects().size(); ++o)
        mKnownAlive[o] = mDisc.objects()[o].alive ? 1 : 0;
}

std::size_t InteractiveDisplay::setPreview(int previewVersion, const Visibility& previewOnly,
                                           const ProgressiveSolver* solver) {
    // Requests and results stay: a drag moves positions faster than they are shaded, and
    // dropping them at every move left the display without new points for the whole drag.
    // Those that hit an earlier preview are dropped when taken (renderFrame).
    dropLeftPreview();
    const int old = mShader->previewObject();
    // The dragged object's points move with it, from the last preview or, at a drag's first
    // move, from its origin (a first preview at the origin moves nothing).
    const int from = old >= 0 ? old : mShader->dragOrigin();
    std::size_t changed = 0;
    if (from >= 0 && previewVersion >= 0) {
        changed += carryPoints(from, previewVersion);
    } else if (old >= 0) {
        changed += mCache.invalidateObjects({old});
    }
    // The moving shadow: with backgroundPreview the estimate comes later (renderFrame).
    (void)mShader->setPreview(previewVersion, previewOnly);
    // The points whose view of a lamp the move changed go at the next frame (dropShadowed).
    // A moved lamp changes every point's light: its estimate alone follows it.
    const bool moved =
        from >= 0 && previewVersion >= 0 && from != previewVersion &&
        mDisc.objects()[from].worldFromObject != mDisc.objects()[previewVersion].worldFromObject;
    bool emits = false;
    for (const Patch& p : mDisc.patches())
        emits = emits || (p.object == previewVersion && mDisc.materials()[p.material].isEmitter());
    if (moved && !emits && mOptions.followShadows) {
        if (mMovedVersions.empty()) mMovedVersions.push_back(from);
        mMovedVersions.push_back(previewVersion);
        mMoveSerial = mShader->stateSerial();
    }
    // Its silhouettes (object-space queries: the version reuses the object's edge tree) and,
    // when on, the shadows it casts now.
    syncEdges();
    mShadowsStale = true;
    // A lamp moved: the edge finder's light follows it.
    syncLights();
    if (solver) mShader->updateSolution(*solver);
    // What it hides in this view stays out of the image.
    setOccluder(previewVersion, previewOnly, -1);
    return changed + relightOrDefer();
}

std::size_t InteractiveDisplay::clearPreview(const ProgressiveSolver* solver) {
    const int old = mShader->previewObject();
    if (old < 0) return 0;
    mShader->cancelPending();
    if (!mOptions.synchronous) (void)mShader->takeResults();
    // Its points wait for the next notifyChanged: an unselect that adds the object back at a
    // newer place than the display previewed carries them there; otherwise they go.
    dropLeftPreview();
    mLeftPreview = old;
    (void)mShader->clearPreview();
    syncEdges();
    mShadowsStale = true;
    if (solver) mShader->updateSolution(*solver);
    mDirectSince = mShader->stateSerial();
    setOccluder(-1, {}, 0);
    // (Not noteAlive: the notifyChanged that follows must see the object come back.)
    return relightChanged();
}

std::size_t InteractiveDisplay::dropLeftPreview() {
    const int left = mLeftPreview;
    mLeftPreview = -1;
    return left >= 0 ? mCache.invalidateObjects({left}) : 0;
}

void InteractiveDisplay::beginDrag(int origin, const Visibility& originOnly) {
    mShader->cancelPending();
    mShader->beginDrag(origin, originOnly);
    mDirectSince = mShader->stateSerial();
    noteAlive();
}

std::size_t InteractiveDisplay::endDrag(int added, const ProgressiveSolver* solver) {
    mShader->cancelPending();
    if (!mOptions.synchronous) (void)mShader->takeResults();
    const int old = mShader->previewObject();
    // The preview version is the object now: its points stay (moved there if it was another).
    std::size_t changed = old != added ? carryPoints(old, added) : 0;
    (void)mShader->endDrag(added);
    syncEdges();
    syncLights();
    mShadowsStale = true;
    if (solver) mShader->updateSolution(*solver);
    // Its subset goes with the drag: a filter admitting it hides what it covers a while.
    setOccluder(added, Visibility{}, kOccluderFrames);
    noteAlive();
    changed += relightChanged();
    trustShown(added);
    return changed;
}

// ---------------------------------------------------------------------------------------------
// Reference

Image InteractiveDisplay::renderReference(const CameraRays& camera, int samplesPerAxis) const {
    return renderShaderReference(*mShader, camera, samplesPerAxis);
}

std::string ConvergedReferenceOptions::toString() const {
    std::ostringstream s;
    s << "ConvergedReferenceOptions{seed " << seed << ", " << samplesPerAxis << "x"
      << samplesPerAxis << " samples, edges " << edgeSamplesPerAxis << "x" << edgeSamplesPerAxis
      << " (spread > " << edgeSpread << (useEpiEdges ? ", EPI edges" : "") << "), above white "
      << brightEdgeSamplesPerAxis << "x" << brightEdgeSamplesPerAxis << ", strata "
      << maxStrataPerAxis << ", shadow refine " << shadowRefine << " up to "
      << shadowMaxRefinedPerAxis << ", decision " << shadowDecisionPerAxis << "}";
    return s.str();
}

// ---------------------------------------------------------------------------------------------
// Image error

double imageRmse(const Image& a, const Image& b) {
    if (a.width != b.width || a.height != b.height)
        throw std::invalid_argument("imageRmse: sizes differ (" + a.toString() + " vs " +
                                    b.toString() + ")");
    if (a.pixels.empty()) return 0.0;
    double sum = 0;
    for (std::size_t k = 0; k < a.pixels.size(); ++k) {
        const Rgb d = a.pixels[k] - b.pixels[k];
        sum += glm::dot(d, d);
    }
    return std::sqrt(sum / (3.0 * static_cast<double>(a.pixels.size())));
}

double displayRmse(const Image& a, const Image& b) {
    if (a.width != b.width || a.height != b.height)
        throw std::invalid_argument("displayRmse: sizes differ (" + a.toString() + " vs " +
                                    b.toString() + ")");
    if (a.pixels.empty()) return 0.0;
    double sum = 0;
    for (std::size_t k = 0; k < a.pixels.size(); ++k)
        for (int c = 0; c < 3; ++c) {
            const double d = srgbEncodeClipped(a.pixels[k][c]) - srgbEncodeClipped(b.pixels[k][c]);
            sum += d * d;
        }
    return std::sqrt(sum / (3.0 * static_cast<double>(a.pixels.size())));
}

double relativeDisplayRmse(const Image& a, const Image& reference) {
    const double err = displayRmse(a, reference);
    double sum = 0;
    for (const Rgb& c : reference.pixels)
        for (int k = 0; k < 3; ++k) {
            const double v = srgbEncodeClipped(c[k]);
            sum += v * v;
        }
    const double rms =
        reference.pixels.empty() ? 0.0 : std::sqrt(sum / (3.0 * reference.pixels.size()));
    return rms > 0 ? err / rms : 0.0;
}

double relativeImageRmse(const Image& a, const Image& reference) {
    const double err = imageRmse(a, reference);
    double sum = 0;
    for (const Rgb& c : reference.pixels) sum += glm::dot(c, c);
    const double rms =
        reference.pixels.empty() ? 0.0 : std::sqrt(sum / (3.0 * reference.pixels.size()));
    return rms > 0 ? err / rms : 0.0;
}

}  // namespace penumbra
