// Starting and ending a drag in the edge-and-point display costs the runner one iteration
// each, counted in iterations (SessionRunner::pump: one solver iteration, one render), not in
// milliseconds: the one display (full resolution, also while interacting) takes the select
// without recomputing direct light (InteractiveDisplay's DragBegan), each position's direct
// change is estimated on the shader's workers, and the drop folds it in (DragEnded).

#include <gtest/gtest.h>

#include <chrono>
#include <functional>
#include <thread>

#include "render/camera_rays.h"
#include "test_scenes.h"
#include "ui/session_runner.h"

namespace penumbra {
namespace {

constexpr int kSize = 96;

ViewRequest view(bool interactive) {
    ViewRequest v;
    v.camera = test::litRoomTopCamera();
    v.width = v.height = kSize;
    v.mode = ViewMode::EdgeAndPoint;
    v.highlight = "slab";
    v.interactive = interactive;
    return v;
}

/// Pumps until `done` holds for the latest image; returns the pumps it took (limit + 1: never).
int pumpsUntil(SessionRunner& runner, int limit,
               const std::function<bool(const ViewportImage&)>& done) {
    for (int n = 1; n <= limit; ++n) {
        runner.pump();
        const auto img = runner.image();
        if (img && done(*img)) return n;
        std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
    return limit + 1;
}

TEST(SessionRunnerDragStart, DragStartsMovesAndDropsWithinOneIterationEach) {
    SessionRunnerOptions options;
    options.threaded = false;
    options.solveBudgetMs = 20;
    options.displayFrameMs = 0;
    options.settleFrames = 10;
    SessionRunner runner(std::make_unique<EditSession>(test::makeLitRoom("red"), SolverOptions{}),
                         options);
    runner.setView(view(false));
    ASSERT_LE(pumpsUntil(runner, 20000, [&](const ViewportImage&) { return runner.quiescent(); }),
              20000);
    const int origin = runner.document()->find("slab")->version;
    ASSERT_GE(origin, 0);

    // Select and the first position, with the view interactive: the next image is the display
    // at full resolution showing the object moved (a preview version other than the one
    // selected).
    runner.submit(SelectCommand{"slab"});
    TransformCommand t;
    t.id = "slab";
    t.translate = test::kLitRoomSlabDragTarget;
    runner.submitCoalescing(t);
    runner.setView(view(true));
    int first = -1;
    const int start = pumpsUntil(runner, 50, [&](const ViewportImage& img) {
        if (img.previewVersion < 0 || img.previewVersion == origin) return false;
        first = img.previewVersion;
        return !img.reduced && img.render.radiance.width == kSize;
    });
    EXPECT_EQ(start, 1) << "pumps until the first moved image";
    EXPECT_EQ(runner.solver().selected, "slab");

    // Another position: shown by the next iteration.
    t.translate = test::kLitRoomSlabDragTarget + Vec3(0.1, 0, 0.1);
    runner.submitCoalescing(t);
    const int next = pumpsUntil(runner, 50, [&](const ViewportImage& img) {
        return img.previewVersion >= 0 && img.previewVersion != first;
    });
    EXPECT_EQ(next, 1) << "pumps until the next position's image";

    // The drop: the display, up to date, by the next iteration.
    runner.submit(UnselectCommand{});
    runner.setView(view(false));
    const int drop = pumpsUntil(runner, 50, [&](const ViewportImage& img) {
        return !img.reduced && img.previewVersion < 0 && img.mode == ViewMode::EdgeAndPoint;
    });
    EXPECT_EQ(drop, 1) << "pumps until the dropped state is shown";
    EXPECT_EQ(runner.solver().selected, "");
    EXPECT_TRUE(runner.takeMessages().empty());
}

}  // namespace
}  // namespace penumbra
