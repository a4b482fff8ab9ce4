// Windowed frames (InteractiveDisplayOptions::windowedFrames) against whole ones:
// synchronous displays of the lit room, some reconstructing only the window their changes
// reach, see the same still camera while the slab is dragged (samples going to what the drag
// changed alone). With no colour tolerance every frame of a windowed display equals the whole
// display's; with the default tolerance the frames stay within it, during the drag and after
// the drop, and the drag's frames reconstruct far fewer pixels than the raster.

#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <vector>

#include "display_events.h"
#include "edit/edit_session.h"
#include "lit_room_display.h"
#include "render/camera_rays.h"
#include "render/display/interactive_display.h"
#include "solver/ray_tracer.h"
#include "test_scenes.h"

namespace penumbra {
namespace {

constexpr int kSize = 160;

/// The largest difference between two frames, relative to the brighter pixel (at least 1).
double largestDifference(const Image& a, const Image& b) {
    double worst = 0;
    for (std::size_t i = 0; i < a.pixels.size(); ++i)
        worst = std::max(worst, glm::length(a.pixels[i] - b.pixels[i]) /
                                    std::max(1.0, glm::length(b.pixels[i])));
    return worst;
}

TEST(DisplayWindow, ADragsWindowedFramesEqualWholeFrames) {
    EditSession session(test::makeLitRoom("red"), SolverOptions{});
    session.converge(1e-3);
    const int origin = session.objectVersion("slab");
    session.apply(SelectCommand{"slab"});

    InteractiveDisplayOptions whole = test::litRoomDisplayOptions(kSize);
    whole.dragSamplesChangedOnly = true;
    InteractiveDisplayOptions exact = whole, tolerant = whole;
    exact.windowedFrames = tolerant.windowedFrames = true;
    exact.windowColourTolerance = 0;
    exact.windowMaxShare = tolerant.windowMaxShare = 1.0;
    InteractiveDisplay a(session.discretization(), session.tracer(), SolverOptions{}, whole);
    InteractiveDisplay b(session.discretization(), session.tracer(), SolverOptions{}, exact);
    InteractiveDisplay c(session.discretization(), session.tracer(), SolverOptions{}, tolerant);
    const CameraRays rays(test::litRoomTopCamera(), kSize, kSize);
    for (InteractiveDisplay* d : {&a, &b, &c}) {
        d->apply(SolutionView::of(session.solver()));
        d->warmUp(rays, 1.0);
    }
    double worstTolerant = 0;
    auto frame = [&](const char* what) {
        const Image ia = a.renderFrame(rays), ib = b.renderFrame(rays), ic = c.renderFrame(rays);
        EXPECT_LT(largestDifference(ib, ia), 1e-9) << what;
        worstTolerant = std::max(worstTolerant, largestDifference(ic, ia));
        return c.lastFrame().reconstructedPixels;
    };
    for (int f = 0; f < 3; ++f) frame("still");

    // The drag: the slab moved a little each frame, each display told as the editor's is.
    RayTracer::SubsetHandle originSubset(session.tracer(), {origin});
    int previous = origin;
    // The displays test their hiding against the moved slab's subset: kept while they may.
    std::vector<std::unique_ptr<RayTracer::SubsetHandle>> subsets;
    std::size_t dragPixels = 0;
    int dragFrames = 0;
    for (int step = 1; step <= 5; ++step) {
        TransformCommand t;
        t.id = "slab";
        t.translate = test::kLitRoomSlabDragTarget * (0.1 * step);
        const int preview = session.apply(t).preview;
        session.solve(20);
        subsets.push_back(
            std::make_unique<RayTracer::SubsetHandle>(session.tracer(), std::vector<int>{preview}));
        const RayTracer::SubsetHandle& subset = *subsets.back();
        const EditEvent event = step == 1 ? test::dragBeganEvent(origin, preview)
                                          : test::previewMovedEvent(origin, preview);
        for (InteractiveDisplay* d : {&a, &b, &c})
            d->apply(event, {originSubset.visibility(), subset.visibility()}, &session.solver());
        previous = preview;
        for (int f = 0; f < 2; ++f, ++dragFrames) dragPixels += frame("dragging");
    }
    EXPECT_GT(previous, origin);
    EXPECT_GT(dragPixels, 0u);
    // Colours that moved by less than the tolerance wait: a bounded difference.
    EXPECT_LT(worstTolerant, 0.02);

    // Dropped: the frames after it stay within twice the tolerance of the whole display.
    const EditEvent drop = session.apply(UnselectCommand{});
    RayTracer::SubsetHandle dropped(session.tracer(), {previous});
    for (InteractiveDisplay* d : {&a, &b, &c})
        d->apply(drop, {originSubset.visibility(), dropped.visibility()}, &session.solver());
    worstTolerant = 0;
    for (int f = 0; f < 2; ++f) frame("dropped");
    EXPECT_LT(worstTolerant, 2 * tolerant.windowColourTolerance);

    // A moved camera: whole again, and still equal.
    Camera moved = test::litRoomTopCamera();
    moved.position += Vec3(0.05, 0.0, 0.0);
    const CameraRays other(moved, kSize, kSize);
    const Image ia = a.renderFrame(other), ib = b.renderFrame(other), ic = c.renderFrame(other);
    EXPECT_LT(largestDifference(ib, ia), 1e-9);
    EXPECT_LT(largestDifference(ic, ia), 1e-9);
    EXPECT_EQ(c.lastFrame().reconstructedPixels, std::size_t(kSize * kSize));
}

TEST(DisplayWindow, LocalChangesReconstructTheirWindowsAlone) {
    EditSession session(test::makeLitRoom("red"), SolverOptions{});
    session.converge(1e-3);
    InteractiveDisplayOptions whole = test::litRoomDisplayOptions(kSize);
    whole.sampleFraction = 0;  // no new samples: the frames change only as told below
    InteractiveDisplayOptions windowed = whole;
    windowed.windowedFrames = true;
    windowed.windowColourTolerance = 0;
    InteractiveDisplay a(session.discretization(), session.tracer(), SolverOptions{}, whole);
    InteractiveDisplay b(session.discretization(), session.tracer(), SolverOptions{}, windowed);
    const CameraRays rays(test::litRoomTopCamera(), kSize, kSize);
    for (InteractiveDisplay* d : {&a, &b}) {
        d->apply(SolutionView::of(session.solver()));
        d->warmUp(rays, 1.0);
    }
    Image first;
    for (int f = 0; f < 2; ++f) {
        first = b.renderFrame(rays);
        EXPECT_LT(largestDifference(first, a.renderFrame(rays)), 1e-9);
    }
    EXPECT_EQ(b.lastFrame().reconstructedPixels, 0u) << "nothing changed";

    // Brighter samples of the points seen in two blocks of pixels far apart (each display's
    // own: their shaders' state serials differ).
    const PixelWindow blocks[] = {{60, 50, 70, 58}, {20, 120, 30, 128}};
    auto inBlock = [&](const glm::dvec2& p) {
        for (const PixelWindow& b : blocks)
            if (p.x >= b.x0 && p.x < b.x1 && p.y >= b.y0 && p.y < b.y1) return true;
        return false;
    };
    auto brighter = [&](const InteractiveDisplay& d) {
        std::vector<ShadedPoint> out;
        for (const CachePoint& p : d.cache().points()) {
            const auto pixel = rays.projectToPixel(p.position);
            if (!pixel || !inBlock(*pixel)) continue;
            ShadedPoint s;
            s.pixel = *pixel;
            s.position = p.position;
            s.radiance = 1.7 * p.colour + Rgb(0.05);
            s.object = p.object;
            s.element = p.element;
            s.frame = d.cache().frame();
            s.shading = p.shading;
            out.push_back(s);
        }
        return out;
    };
    const std::vector<ShadedPoint> forA = brighter(a), forB = brighter(b);
    ASSERT_GT(forA.size(), 40u);
    a.insertShaded(forA);
    b.insertShaded(forB);
    const Image ia = a.renderFrame(rays), ib = b.renderFrame(rays);
    EXPECT_LT(largestDifference(ib, ia), 1e-9);
    EXPECT_GT(largestDifference(ib, first), 0.01) << "the blocks changed";
    const int reach = b.epi().reconstructionReach();
    // Each block's window alone, not the rectangle around both.
    std::size_t most = 0;
    for (const PixelWindow& b : blocks)
        most += static_cast<std::size_t>(b.x1 - b.x0 + 2 * reach) * (b.y1 - b.y0 + 2 * reach);
    EXPECT_GT(b.lastFrame().reconstructedPixels, 0u);
    EXPECT_LE(b.lastFrame().reconstructedPixels, most);
}

TEST(DisplayWindow, AConvergedStillViewRests) {
    // Every pixel's own point exact or the mean of mergeSamples samples: no more requests, and
    // with windowed frames nothing reconstructed; without the option the sampling goes on.
    EditSession session(test::makeLitRoom("red"), SolverOptions{});
    session.converge(1e-3);
    constexpr int kSmall = 48;
    InteractiveDisplayOptions resting = test::litRoomDisplayOptions(kSmall);
    resting.cache.mergeSamples = 4;
    resting.windowedFrames = true;
    resting.restWhenConverged = true;
    InteractiveDisplayOptions busy = resting;
    busy.restWhenConverged = false;
    InteractiveDisplay a(session.discretization(), session.tracer(), SolverOptions{}, resting);
    InteractiveDisplay b(session.discretization(), session.tracer(), SolverOptions{}, busy);
    const CameraRays rays(test::litRoomTopCamera(), kSmall, kSmall);
    for (InteractiveDisplay* d : {&a, &b}) d->apply(SolutionView::of(session.solver()));
    int frames = 0;
    for (; frames < 2000 && (frames < 2 || a.lastFrame().requestedSamples > 0); ++frames) {
        a.renderFrame(rays);
        b.renderFrame(rays);
    }
    ASSERT_LT(frames, 2000) << "the still view never converged";
    EXPECT_EQ(a.lastFrame().requestedSamples, 0u);
    EXPECT_GT(b.lastFrame().requestedSamples, 0u);
    // The next frames change nothing: nothing is reconstructed, and the picture is the same.
    const Image before = a.renderFrame(rays);
    const Image after = a.renderFrame(rays);
    EXPECT_EQ(a.lastFrame().reconstructedPixels, 0u);
    EXPECT_EQ(largestDifference(after, before), 0.0);
    // At rest it shows the same as the display that kept sampling, within the samples' noise.
    EXPECT_LT(relativeImageRmse(after, b.renderFrame(rays)), 0.05);
    std::printf("converged after %d frames\n", frames);
}

TEST(DisplayWindow, AMovingCameraFiltersDenseClustersLessAndTheNextStillFrameFiltersAll) {
    // InteractiveDisplayOptions::movingDenseComplexLimit: a frame whose camera moved leaves
    // the complex pixels of dense clusters at their estimate; the next frame of the same
    // camera filters every complex pixel, as a display that never takes the shortcut does,
    // and a windowed display reconstructs that frame whole (the moving frame cannot seed its
    // windows), then nothing.
    // A small raster, so that the room's edges crowd into clusters of complex pixels.
    constexpr int kSmall = 40;
    EditSession session(test::makeLitRoom("red"), SolverOptions{});
    session.converge(1e-3);
    InteractiveDisplayOptions fast = test::litRoomDisplayOptions(kSmall);
    fast.sampleFraction = 0;  // no new samples: the frames differ only by their filtering
    ASSERT_GT(fast.movingDenseComplexLimit, 0);
    InteractiveDisplayOptions full = fast, windowed = fast;
    full.movingDenseComplexLimit = 0;
    windowed.windowedFrames = true;
    windowed.windowColourTolerance = 0;
    InteractiveDisplay f(session.discretization(), session.tracer(), SolverOptions{}, full);
    InteractiveDisplay m(session.discretization(), session.tracer(), SolverOptions{}, fast);
    InteractiveDisplay w(session.discretization(), session.tracer(), SolverOptions{}, windowed);
    const CameraRays still(test::litRoomTopCamera(), kSmall, kSmall);
    Camera turned = test::litRoomTopCamera();
    turned.lookAt += Vec3(0.08, 0.0, 0.0);
    const CameraRays moved(turned, kSmall, kSmall);
    for (InteractiveDisplay* d : {&f, &m, &w}) {
        d->apply(SolutionView::of(session.solver()));
        d->warmUp(still, 1.0);
    }
    // The first frame counts as still.
    const Image f0 = f.renderFrame(still);
    EXPECT_LT(largestDifference(m.renderFrame(still), f0), 1e-9);
    EXPECT_LT(largestDifference(w.renderFrame(still), f0), 1e-9);

    // The camera moves: the shortcut changes some complex pixels and nothing else.
    const Image f1 = f.renderFrame(moved), m1 = m.renderFrame(moved), w1 = w.renderFrame(moved);
    EXPECT_LT(largestDifference(w1, m1), 1e-9);
    std::size_t differing = 0;
    for (std::size_t i = 0; i < f1.pixels.size(); ++i)
        differing += glm::length(f1.pixels[i] - m1.pixels[i]) > 1e-9;
    EXPECT_GT(differing, 0u) << "no dense cluster of complex pixels in the moved view";
    EXPECT_LE(differing, m.lastFrame().complexPixels);

    // It stops: every complex pixel filtered again, the windowed display whole, then idle.
    const Image f2 = f.renderFrame(moved);
    EXPECT_LT(largestDifference(m.renderFrame(moved), f2), 1e-9);
    EXPECT_LT(largestDifference(w.renderFrame(moved), f2), 1e-9);
    EXPECT_EQ(w.lastFrame().reconstructedPixels, std::size_t(kSmall * kSmall));
    EXPECT_LT(largestDifference(w.renderFrame(moved), f.renderFrame(moved)), 1e-9);
    EXPECT_EQ(w.lastFrame().reconstructedPixels, 0u);
    std::printf("moving frame: %zu of %zu complex pixels kept their estimate\n", differing,
                m.lastFrame().complexPixels);
}

}  // namespace
}  // namespace penumbra
