// The display with the render cache's incremental reprojection against the same display
// reprojecting whole every frame: a still camera over the lit room while its slab is selected,
// dragged in steps (carried points, the shadow drop, hidden points, relights) and dropped; every
// frame's image must be equal bit for bit, and the incremental path must have run.

#include <gtest/gtest.h>

#include <memory>

#include "edit/edit_session.h"
#include "render/camera_rays.h"
#include "render/display/interactive_display.h"
#include "solver/ray_tracer.h"
#include "test_scenes.h"

namespace penumbra {
namespace {

constexpr int kSize = 80;

/// A solved lit room and its display, the cache incremental or not.
struct Room {
    std::unique_ptr<EditSession> session;
    std::unique_ptr<InteractiveDisplay> display;
    /// The tracer subsets handed to the display, alive for the whole drag (the display keeps
    /// the visibilities it was given).
    std::vector<RayTracer::SubsetHandle> subsets;
    Visibility originOnly, previewOnly;

    explicit Room(bool incremental) {
        session = std::make_unique<EditSession>(test::makeLitRoom("red"), SolverOptions{});
        session->converge(1e-3);
        InteractiveDisplayOptions options;
        options.width = options.height = kSize;
        options.synchronous = true;
        options.cache.incremental = incremental;
        display = std::make_unique<InteractiveDisplay>(session->discretization(), session->tracer(),
                                                       interactiveSolverOptions(), options);
        display->apply(SolutionView::of(session->solver()));
    }
    /// The editor's way of handing an edit's event to the display: the drag's origin alone
    /// (from the select on) and the preview alone.
    void apply(const EditEvent& event, int origin, int preview) {
        if (event.kind == EditEvent::Kind::DragBegan) {
            subsets.emplace_back(session->tracer(), std::vector<int>{origin});
            originOnly = subsets.back().visibility();
        }
        if (event.kind != EditEvent::Kind::DragEnded) {
            subsets.emplace_back(session->tracer(), std::vector<int>{preview});
            previewOnly = subsets.back().visibility();
        }
        display->apply(event, {originOnly, previewOnly});
        display->apply(SolutionView::of(session->solver()));
    }
};

TEST(InteractiveDisplayIncremental, ADragUnderAStillCameraShowsWhatWholeReprojectionsShow) {
    Room incremental(true), whole(false);
    const CameraRays camera(test::litRoomTopCamera(), kSize, kSize);
    int frame = 0, incrementalFrames = 0;
    auto compare = [&](const char* when) {
        const Image a = incremental.display->renderFrame(camera);
        const Image b = whole.display->renderFrame(camera);
        ASSERT_EQ(a.pixels, b.pixels) << when << ", frame " << frame;
        incrementalFrames += incremental.display->cache().lastReprojectionIncremental();
        EXPECT_FALSE(whole.display->cache().lastReprojectionIncremental());
        ++frame;
    };
    for (Room* r : {&incremental, &whole}) r->display->warmUp(camera, 0.25);
    for (int f = 0; f < 6; ++f) compare("at rest");

    // Select, then move the slab in four steps towards the drag target, two frames a step.
    int origin = -1, preview = -1;
    for (Room* r : {&incremental, &whole}) {
        const EditEvent select = r->session->apply(SelectCommand{"slab"});
        ASSERT_EQ(select.kind, EditEvent::Kind::DragBegan);
        origin = select.origin;
        r->apply(select, origin, origin);  // the preview starts where the object is
    }
    compare("selected");
    for (int step = 1; step <= 4; ++step) {
        for (Room* r : {&incremental, &whole}) {
            TransformCommand t;
            t.id = "slab";
            t.translate = test::kLitRoomSlabDragTarget * (step / 4.0);
            const EditEvent moved = r->session->apply(t);
            ASSERT_EQ(moved.kind, EditEvent::Kind::PreviewMoved);
            preview = moved.preview;
            r->apply(moved, origin, preview);
        }
        compare("dragged");
        compare("dragged, still");
    }
    for (Room* r : {&incremental, &whole}) {
        const EditEvent drop = r->session->apply(UnselectCommand{});
        r->apply(drop, origin, preview);
    }
    for (int f = 0; f < 6; ++f) compare("dropped");
    EXPECT_GE(incrementalFrames, frame / 3) << "the incremental path ran in too few frames";
}

}  // namespace
}  // namespace penumbra
