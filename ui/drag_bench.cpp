// Index: helpers · DragBench (images, recording, analysis, references)

#include "ui/drag_bench.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>

#include "core/durable_file.h"
#include "edit/edit_session.h"
#include "edit/lit_scene.h"
#include "render/camera_rays.h"
#include "render/display/interactive_display.h"
#include "render/display/point_shader.h"
#include "render/path_tracer.h"
#include "solver/ray_tracer.h"

namespace penumbra {

namespace {

/// The displayed bytes of a radiance image (srgbByte, as the viewport shows it).
std::shared_ptr<const std::vector<std::uint8_t>> displayedBytes(const Image& image) {
    auto out = std::make_shared<std::vector<std::uint8_t>>(image.pixels.size() * 3);
    for (std::size_t k = 0; k < image.pixels.size(); ++k)
        for (int c = 0; c < 3; ++c) (*out)[3 * k + c] = srgbByte(image.pixels[k][c]);
    return out;
}

/// relativeDisplayRmse on displayed bytes: RMS difference over the RMS of `reference`, over
/// the pixels (3 bytes each) whose `leftOut` entry is 0 when given (emitterMask).
double relativeError(const std::vector<std::uint8_t>& a, const std::vector<std::uint8_t>& reference,
                     const std::vector<std::uint8_t>& leftOut = {}) {
    if (a.size() != reference.size() || a.empty()) return -1;
    if (!leftOut.empty() && leftOut.size() * 3 != a.size()) return -1;
    double diff = 0, ref = 0;
    for (std::size_t k = 0; k < a.size(); ++k) {
        if (!leftOut.empty() && leftOut[k / 3]) continue;
        const double d = (double(a[k]) - double(reference[k])) / 255.0;
        const double r = double(reference[k]) / 255.0;
        diff += d * d;
        ref += r * r;
    }
    return ref > 0 ? std::sqrt(diff / ref) : 0.0;
}

nlohmann::json transformJson(const Transform& t) {
    return {{"translate", {t.translate.x, t.translate.y, t.translate.z}},
            {"rotate_deg", {t.rotateDeg.x, t.rotateDeg.y, t.rotateDeg.z}},
            {"scale", {t.scale.x, t.scale.y, t.scale.z}}};
}

/// The edit line (DESIGN.md edit log) that puts `id` where `t` says.
std::string transformLine(const std::string& id, const Transform& t) {
    TransformCommand c;
    c.id = id;
    c.translate = t.translate;
    c.rotateDeg = t.rotateDeg;
    c.scale = t.scale;
    return formatEditCommand(EditCommand(c));
}

/// The byte offsets (3 per pixel, row-major) of the pixels of `rays` whose primary ray meets
/// object `version` in `session`'s scene.
std::vector<std::size_t> objectPixelBytes(EditSession& session, const CameraRays& rays,
                                          int version) {
    std::vector<std::size_t> out;
    for (int y = 0; y < rays.height(); ++y)
        for (int x = 0; x < rays.width(); ++x) {
            const RayHit hit =
                session.tracer().intersect(rays.origin(), rays.rayDirection(x + 0.5, y + 0.5));
            if (hit.object == version)
                out.push_back(3 * (static_cast<std::size_t>(y) * rays.width() + x));
        }
    return out;
}

/// The displayed bytes of `e` and of its reference over the pixels where the reference's
/// primary ray meets object `version`, in the same order.
std::pair<std::vector<std::uint8_t>, std::vector<std::uint8_t>> objectBytes(
    EditSession& session, const CameraRays& rays, int version,
    const std::vector<std::uint8_t>& referenceBytes, const DragBenchImage& e) {
    std::vector<std::uint8_t> a, b;
    for (const std::size_t k : objectPixelBytes(session, rays, version))
        for (int c = 0; c < 3; ++c) {
            a.push_back((*e.shown)[k + c]);
            b.push_back(referenceBytes[k + c]);
        }
    return {std::move(a), std::move(b)};
}

/// The errors of `image` over the dragged object's own pixels (where the reference's primary
/// ray meets object `version`): solid and in the right place, or not. Sets objectError,
/// objectPixels and objectWrong, the share of those pixels that show something else (the
/// background through a hole, the object elsewhere): a channel off by more than a fifth of
/// the range, far beyond what a lagging light gives.
void compareObjectPixels(EditSession& session, const CameraRays& rays, int version,
                         const std::vector<std::uint8_t>& referenceBytes, DragBenchImage& e) {
    const auto [a, b] = objectBytes(session, rays, version, referenceBytes, e);
    e.objectError = relativeError(a, b);
    e.objectPixels = a.size() / 3;
    std::size_t wrong = 0;
    for (std::size_t k = 0; k + 2 < a.size(); k += 3) {
        int off = 0;
        for (int c = 0; c < 3; ++c) off = std::max(off, std::abs(int(a[k + c]) - int(b[k + c])));
        wrong += off > 51;
    }
    e.objectWrong = a.empty() ? -1.0 : double(wrong) / double(a.size() / 3);
}

/// The error of `image` over the floor's pixels (the scene object "floor", where the dragged
/// object's shadow falls), against the reference of its state: the shadow at the object's place
/// or not. -1 without a floor.
void compareFloorPixels(EditSession& session, const CameraRays& rays,
                        const std::vector<std::uint8_t>& referenceBytes, DragBenchImage& e) {
    const int floor = session.objectVersion("floor");
    if (floor < 0) return;
    const auto [a, b] = objectBytes(session, rays, floor, referenceBytes, e);
    e.floorError = relativeError(a, b);
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// Images and recording.

DragBench::DragBench(DragBenchOptions options) : mOptions(std::move(options)) {
    if (!mOptions.recordDir.empty()) std::filesystem::create_directories(mOptions.recordDir);
    mWorker = std::thread([this] { workerLoop(); });
}

DragBench::~DragBench() {
    {
        std::lock_guard<std::mutex> lock(mMutex);
        mStop = true;
    }
    mWake.notify_all();
    if (mWorker.joinable()) mWorker.join();
}

void DragBench::dropped(double now, const Transform& final) {
    mDrop = now;
    mDropped = true;
    mFinal = final;
    // Images so far: their times relative to the drop.
    for (DragBenchImage& e : mImages) e.seconds -= now - mStart;
}

void DragBench::shown(const std::shared_ptr<const ViewportImage>& image, double now, int viewW,
                      int viewH) {
    if (!image) return;
    DragBenchImage e;
    e.afterDrop = mDropped;
    e.seconds = mDropped ? now - mDrop : now - mStart;
    e.width = image->render.radiance.width;
    e.height = image->render.radiance.height;
    // The display rounds its size down to a multiple of 4 (SessionRunner::displayOptions).
    e.reduced = image->reduced || e.width < viewW / 4 * 4 || e.height < viewH / 4 * 4;
    e.unsampled = image->display.unsampledPixels;
    e.unfilled = image->display.unfilledPixels;
    e.dragged = image->dragged;
    e.transform = image->dragged.empty() ? mFinal : image->draggedTransform;
    e.camera = image->camera;
    mImages.push_back(std::move(e));
    queue(mImages.back(), image);
}

void DragBench::settled(const std::shared_ptr<const ViewportImage>& image) {
    if (!image) return;
    mSettled.width = image->render.radiance.width;
    mSettled.height = image->render.radiance.height;
    mSettled.transform = mFinal;
    mSettled.camera = image->camera;
    mSettled.afterDrop = true;
    mSettled.seconds = -1;  // marks the settled image in the index
    queue(mSettled, image);
}

void DragBench::settledAgain(const std::shared_ptr<const ViewportImage>& image) {
    if (!image) return;
    mSettledAgain.width = image->render.radiance.width;
    mSettledAgain.height = image->render.radiance.height;
    mSettledAgain.afterDrop = true;
    mSettledAgain.seconds = -1;
    std::lock_guard<std::mutex> lock(mMutex);
    mJobs.push_back({&mSettledAgain, image, ""});
    mWake.notify_all();
}

void DragBench::queue(DragBenchImage& entry, std::shared_ptr<const ViewportImage> image) {
    std::string line;
    if (!mOptions.recordDir.empty()) {
        char name[32];
        std::snprintf(name, sizeof name, "image-%04d.png", mRecorded++);
        entry.file = (std::filesystem::path(mOptions.recordDir) / name).string();
        line = nlohmann::json{{"image", name},
                              {"phase", &entry == &mSettled ? "settled"
                                        : entry.afterDrop   ? "after-drop"
                                                            : "drag"},
                              {"seconds", entry.seconds},
                              {"width", entry.width},
                              {"height", entry.height},
                              {"reduced", entry.reduced},
                              {"unsampled_pixels", entry.unsampled},
                              {"unfilled_pixels", entry.unfilled},
                              {"log", transformLine(mOptions.object, entry.transform)}}
                   .dump();
    }
    std::lock_guard<std::mutex> lock(mMutex);
    mJobs.push_back({&entry, std::move(image), std::move(line)});
    mWake.notify_all();
}

void DragBench::windowDone() {
    {
        std::lock_guard<std::mutex> lock(mMutex);
        mHold = false;
    }
    mWake.notify_all();
}

void DragBench::drain() {
    windowDone();
    std::unique_lock<std::mutex> lock(mMutex);
    mDone.wait(lock, [&] { return mJobs.empty() && !mBusy; });
}

void DragBench::workerLoop() {
    const std::string index =
        mOptions.recordDir.empty()
            ? std::string()
            : (std::filesystem::path(mOptions.recordDir) / "index.jsonl").string();
    std::string lines;
    for (;;) {
        Job job;
        {
            std::unique_lock<std::mutex> lock(mMutex);
            mWake.wait(lock, [&] { return mStop || (!mHold && !mJobs.empty()); });
            if (mJobs.empty()) return;
            job = std::move(mJobs.front());
            mJobs.pop_front();
            mBusy = true;
        }
        auto bytes = displayedBytes(job.image->render.radiance);
        if (!job.indexLine.empty()) {
            try {
                writePng(job.image->render.radiance, job.entry->file);
                lines += job.indexLine + "\n";
                writeFileAtomically(index, lines);
            } catch (const std::exception& e) {
                std::cerr << "penumbra-editor: --record: " << e.what() << "\n";
            }
        }
        std::size_t outline = 0;
        const std::vector<std::uint8_t>& rgba = job.image->render.rgba;
        for (std::size_t k = 0; k + 3 < rgba.size(); k += 4)
            outline += rgba[k] == 255 && rgba[k + 1] == 150 && rgba[k + 2] == 20;
        std::lock_guard<std::mutex> lock(mMutex);
        job.entry->shown = std::move(bytes);
        job.entry->outlinePixels = outline;
        mBusy = false;
        mDone.notify_all();
    }
}

// ---------------------------------------------------------------------------------------------
// Analysis.

nlohmann::json DragBench::analyse() {
    drain();
    nlohmann::json out;
    analyseImages(out);
    analyseSettling(out);
    out["references"] = renderReferences(chooseReferenceImages());
    double maxDrag = -1;
    for (const DragBenchImage& e : mImages)
        if (!e.afterDrop) maxDrag = std::max(maxDrag, e.referenceError);
    out["max_drag_reference_error"] = maxDrag;
    double maxDragUnlit = -1;
    for (const DragBenchImage& e : mImages)
        if (!e.afterDrop) maxDragUnlit = std::max(maxDragUnlit, e.referenceErrorWithoutLamps);
    out["max_drag_reference_error_without_lamps"] = maxDragUnlit;
    double maxObject = -1;
    for (const DragBenchImage& e : mImages)
        if (!e.afterDrop) maxObject = std::max(maxObject, e.objectError);
    out["max_drag_object_error"] = maxObject;
    double maxWrong = -1;
    for (const DragBenchImage& e : mImages)
        if (!e.afterDrop) maxWrong = std::max(maxWrong, e.objectWrong);
    out["max_drag_object_wrong_fraction"] = maxWrong;
    double maxFloor = -1;
    for (const DragBenchImage& e : mImages)
        if (!e.afterDrop) maxFloor = std::max(maxFloor, e.floorError);
    out["max_drag_floor_error"] = maxFloor;
    // Whose shadow the drag images show (0: their own state's).
    int maxLag = -1;
    double maxDelay = -1;
    for (const auto& lag : mShadowLag) {
        maxLag = std::max(maxLag, lag["lag_images"].get<int>());
        maxDelay = std::max(maxDelay, lag["delay_ms"].get<double>());
    }
    out["shadow_lag"] = mShadowLag;
    out["max_shadow_lag_images"] = maxLag;
    out["max_shadow_delay_ms"] = maxDelay;
    out["settled_reference_error"] = mSettled.referenceError;
    out["settled_reference_error_without_lamps"] = mSettled.referenceErrorWithoutLamps;
    return out;
}

nlohmann::json DragBench::measureShadowLag(EditSession& session,
                                           const SolverOptions& solverOptions) {
    nlohmann::json lags = nlohmann::json::array();
    const int floor = session.objectVersion("floor");
    if (mOptions.shadowLagStates <= 0 || floor < 0) return lags;
    for (std::size_t j = 0; j < mImages.size(); ++j) {
        DragBenchImage& e = mImages[j];
        if (e.afterDrop || !e.referenceShown || !e.shown) continue;
        // The earlier images' states, nearest first, each first shown where the walk back
        // last meets it.
        struct Candidate {
            Transform transform;
            double seconds;  ///< the first image showing it
            int images;      ///< images back from e to that one
        };
        std::vector<Candidate> candidates;
        std::size_t firstOfOwn = j;
        while (firstOfOwn > 0 && mImages[firstOfOwn - 1].transform == e.transform &&
               !mImages[firstOfOwn - 1].afterDrop)
            --firstOfOwn;
        for (std::size_t i = firstOfOwn; i-- > 0;) {
            if (static_cast<int>(candidates.size()) >= mOptions.shadowLagStates) break;
            const DragBenchImage& c = mImages[i];
            if (c.transform == e.transform) continue;
            if (!candidates.empty() && candidates.back().transform == c.transform) {
                candidates.back().seconds = c.seconds;
                candidates.back().images = static_cast<int>(j - i);
                continue;
            }
            candidates.push_back({c.transform, c.seconds, static_cast<int>(j - i)});
        }
        if (candidates.empty()) continue;
        // References of the candidate states, the image's own first.
        std::vector<std::shared_ptr<const std::vector<std::uint8_t>>> refs{e.referenceShown};
        const CameraRays rays(e.camera, e.width, e.height);
        for (const Candidate& c : candidates)
            refs.push_back(displayedBytes(referenceOf(session, solverOptions, c.transform, rays)));
        // The floor's pixels where some candidate's reference differs from the own one by more
        // than a tenth of the range in a channel: where the shadows of the states differ.
        std::vector<std::size_t> mask;
        for (const std::size_t k : objectPixelBytes(session, rays, floor)) {
            bool differs = false;
            for (std::size_t r = 1; r < refs.size() && !differs; ++r)
                for (int ch = 0; ch < 3; ++ch)
                    differs =
                        differs || std::abs(int((*refs[r])[k + ch]) - int((*refs[0])[k + ch])) > 25;
            if (differs) mask.push_back(k);
        }
        nlohmann::json errors = nlohmann::json::array();
        int best = 0;
        double bestError = 1e300;
        for (std::size_t r = 0; r < refs.size(); ++r) {
            std::vector<std::uint8_t> a, b;
            for (std::size_t k : mask)
                for (int ch = 0; ch < 3; ++ch) {
                    a.push_back((*e.shown)[k + ch]);
                    b.push_back((*refs[r])[k + ch]);
                }
            const double err = relativeError(a, b);
            errors.push_back(err);
            if (err >= 0 && err < bestError) bestError = err, best = static_cast<int>(r);
        }
        const int lagImages = best == 0 ? 0 : candidates[best - 1].images;
        const double delayMs = best == 0 ? 0.0 : (e.seconds - candidates[best - 1].seconds) * 1e3;
        lags.push_back({{"ms", e.seconds * 1e3},
                        {"mask_pixels", mask.size()},
                        {"errors", std::move(errors)},
                        {"shown_state", best},
                        {"lag_images", lagImages},
                        {"delay_ms", delayMs},
                        {"oldest_candidate_images", candidates.back().images}});
    }
    return lags;
}

void DragBench::analyseImages(nlohmann::json& out) const {
    std::size_t maxUnsampled = 0, maxUnfilled = 0, reduced = 0, drag = 0;
    double maxUnsampledFraction = 0, maxUnfilledFraction = 0;
    for (const DragBenchImage& e : mImages) {
        const double pixels = double(e.width) * e.height;
        maxUnsampled = std::max(maxUnsampled, e.unsampled);
        maxUnfilled = std::max(maxUnfilled, e.unfilled);
        maxUnsampledFraction = std::max(maxUnsampledFraction, e.unsampled / pixels);
        maxUnfilledFraction = std::max(maxUnfilledFraction, e.unfilled / pixels);
        reduced += e.reduced ? 1 : 0;
        drag += e.afterDrop ? 0 : 1;
    }
    // Drag images without the selection outline, and when (seconds before the drop).
    nlohmann::json withoutOutlineAt = nlohmann::json::array();
    for (const DragBenchImage& e : mImages)
        if (!e.afterDrop && e.outlinePixels == 0) withoutOutlineAt.push_back(e.seconds);
    const std::size_t withoutOutline = withoutOutlineAt.size();
    out["drag_images_without_outline_s"] = std::move(withoutOutlineAt);
    out["images"] = mImages.size();
    out["drag_images"] = drag;
    out["drag_images_without_outline"] = withoutOutline;
    // Lit images the viewport received a second while the object moved (select to drop).
    out["drag_images_per_s"] = mDropped && mDrop > mStart ? drag / (mDrop - mStart) : 0.0;
    out["max_unsampled_fraction"] = maxUnsampledFraction;
    out["max_unfilled_fraction"] = maxUnfilledFraction;
    out["max_unfilled_pixels"] = maxUnfilled;
    out["reduced_share"] = mImages.empty() ? 0.0 : double(reduced) / mImages.size();
}

void DragBench::analyseSettling(nlohmann::json& out) {
    // After the drop, against the settled image: when does it stay within the tolerance?
    double settleSeconds = -1, windowEnd = -1;
    if (mSettled.shown) {
        for (DragBenchImage& e : mImages)
            if (e.afterDrop && e.width == mSettled.width && e.height == mSettled.height)
                e.settledError = relativeError(*e.shown, *mSettled.shown);
        for (auto it = mImages.rbegin(); it != mImages.rend() && it->afterDrop; ++it) {
            if (!(it->settledError >= 0 && it->settledError <= mOptions.settledTolerance)) break;
            settleSeconds = it->seconds;
        }
        double best = 1e300;
        for (const DragBenchImage& e : mImages)
            if (e.afterDrop && std::abs(e.seconds - mOptions.afterDropSeconds) < best) {
                best = std::abs(e.seconds - mOptions.afterDropSeconds);
                windowEnd = e.settledError;
            }
    }
    out["settle_ms"] = settleSeconds >= 0 ? settleSeconds * 1e3 : -1.0;
    out["settled_noise"] = mSettled.shown && mSettledAgain.shown
                               ? relativeError(*mSettledAgain.shown, *mSettled.shown)
                               : -1.0;
    out["settled_error_at_window_end"] = windowEnd;
    out["settled_tolerance"] = mOptions.settledTolerance;
    nlohmann::json after = nlohmann::json::array();
    for (const DragBenchImage& e : mImages)
        if (e.afterDrop)
            after.push_back({{"ms", e.seconds * 1e3}, {"settled_error", e.settledError}});
    out["after_drop"] = std::move(after);
}

std::vector<DragBenchImage*> DragBench::chooseReferenceImages() {
    // A few states: spread over the drag, the first image after the drop, the one at the
    // window's end, the settled image.
    std::vector<DragBenchImage*> chosen;
    std::vector<DragBenchImage*> dragImages, afterImages;
    for (DragBenchImage& e : mImages) (e.afterDrop ? afterImages : dragImages).push_back(&e);
    const int k = std::min<int>(mOptions.dragReferences, static_cast<int>(dragImages.size()));
    for (int i = 0; i < k; ++i)
        chosen.push_back(dragImages[(dragImages.size() - 1) * (i + 1) / (k + 1) + 0]);
    if (!afterImages.empty()) {
        chosen.push_back(afterImages.front());
        DragBenchImage* last = afterImages.front();
        for (DragBenchImage* e : afterImages)
            if (std::abs(e->seconds - mOptions.afterDropSeconds) <
                std::abs(last->seconds - mOptions.afterDropSeconds))
                last = e;
        if (last != afterImages.front()) chosen.push_back(last);
    }
    if (mSettled.shown) chosen.push_back(&mSettled);
    return chosen;
}

nlohmann::json DragBench::renderReferences(const std::vector<DragBenchImage*>& chosen) {
    nlohmann::json references = nlohmann::json::array();
    if (!chosen.empty() && !mOptions.scene.empty()) {
        const SolverOptions solverOptions = interactiveSolverOptions();
        auto session = EditSession::open(mOptions.scene, solverOptions);
        session->converge(1e-3);
        int at = 0;
        for (DragBenchImage* e : chosen) {
            std::cerr << "penumbra-editor: --bench-drag: reference " << ++at << "/" << chosen.size()
                      << "\n";
            references.push_back(compareWithReference(*session, solverOptions, *e, at));
        }
        std::cerr << "penumbra-editor: --bench-drag: shadow lag\n";
        mShadowLag = measureShadowLag(*session, solverOptions);
    }
    return references;
}

Image DragBench::referenceOf(EditSession& session, const SolverOptions& solverOptions,
                             const Transform& transform, const CameraRays& rays) const {
    TransformCommand move;
    move.id = mOptions.object;
    move.translate = transform.translate;
    move.rotateDeg = transform.rotateDeg;
    move.scale = transform.scale;
    session.apply(EditCommand(move));
    session.converge(1e-3);
    // The display's shader on every pixel, and on the pixels whose samples spread (the lamps'
    // and objects' edges, penumbrae) edgeSamplesPerAxis² jittered samples, as the still bench's
    // reference (renderEdgeRefinedReference), so that the display's anti-aliasing of an edge is
    // not measured against a 2 × 2 grid's staircase. (Without the still bench's deep shadow
    // sampling: the bench renders up to 15 references.)
    ConvergedReferenceOptions ro;
    ro.samplesPerAxis = mOptions.referenceSamplesPerAxis;
    PointShaderOptions so = displayShaderOptions();
    so.threads = 0;
    so.recordTriples = false;
    PointShader shader(session.discretization(), session.tracer(), solverOptions, so);
    shader.updateSolution(session.solver());
    return renderEdgeRefinedReference(shader, rays, ro);
}

nlohmann::json DragBench::compareWithReference(EditSession& session,
                                               const SolverOptions& solverOptions,
                                               DragBenchImage& e, int at) {
    const CameraRays rays(e.camera, e.width, e.height);
    const Image reference = referenceOf(session, solverOptions, e.transform, rays);
    const auto referenceBytes = displayedBytes(reference);
    e.referenceError = relativeError(*e.shown, *referenceBytes);
    e.referenceShown = referenceBytes;
    e.referenceErrorWithoutLamps = relativeError(
        *e.shown, *referenceBytes, emitterMask(session.discretization(), session.tracer(), rays));
    compareObjectPixels(session, rays, session.objectVersion(mOptions.object), *referenceBytes, e);
    compareFloorPixels(session, rays, *referenceBytes, e);
    nlohmann::json entry = {{"phase", &e == &mSettled ? "settled"
                                      : e.afterDrop   ? "after-drop"
                                                      : "drag"},
                            {"ms", &e == &mSettled ? -1.0 : e.seconds * 1e3},
                            {"error", e.referenceError},
                            {"error_without_lamps", e.referenceErrorWithoutLamps},
                            {"object_error", e.objectError},
                            {"object_pixels", e.objectPixels},
                            {"object_wrong_fraction", e.objectWrong},
                            {"floor_error", e.floorError},
                            {"transform", transformJson(e.transform)}};
    if (!mOptions.recordDir.empty()) {
        char name[40];
        std::snprintf(name, sizeof name, "reference-%02d.png", at);
        writePng(reference, (std::filesystem::path(mOptions.recordDir) / name).string());
        entry["reference"] = name;
        entry["image"] = std::filesystem::path(e.file).filename().string();
    }
    return entry;
}

}  // namespace penumbra
