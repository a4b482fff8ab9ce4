// The editor's default view and a drag in it, in the real window (CTest label `display`, under
// `xvfb-run -a`): the viewport starts in the edge-and-point mode, showing Gouraud until the
// display has been built in the background; the --bench-drag path (select, one position per
// frame) shows the object moved, in the edge-and-point mode, while the drag is still going. How
// many frames that takes depends on the machine's load, so it is printed (and measured by
// `penumbra-editor --bench-drag`), not asserted.

#include <gtest/gtest.h>

#include <cstdio>
#include <string>

#include "editor_test_support.h"
#include "ui/editor_app.h"
#include "ui/session_runner.h"
#include "ui/view_mode.h"

namespace penumbra {
namespace {

const std::string kSource = PENUMBRA_SOURCE_DIR;

TEST(EditorDragDisplay, DefaultViewIsEdgeAndPointAndADragShowsTheMoveWithinFewFrames) {
    EditorOptions options;
    EXPECT_EQ(options.mode, ViewMode::EdgeAndPoint) << "the editor's default view";
    options.scene = kSource + "/scenes/cube-room.json";
    options.quiet = true;
    options.displayDivisor = 2;  // keeps the test short under sanitizers
    options.benchDrag = "table-top";
    options.frames = 1 << 20;  // the drag lasts until the test ends
    EditorApp app(options);
    SessionRunner& runner = *app.runner();

    // Until the display lands: Gouraud, saying so.
    std::shared_ptr<const ViewportImage> first;
    ASSERT_TRUE(test::runUntil(
        app,
        [&] {
            first = runner.image();
            return first != nullptr;
        },
        30));
    EXPECT_EQ(first->mode, ViewMode::Gouraud);
    EXPECT_NE(first->note.find("loading"), std::string::npos) << first->note;

    // The benchmark starts the drag once the display has settled; the moved object must show
    // while the drag goes on (the frame count is load-dependent: printed, not asserted).
    const bool moved = test::runUntil(
        app, [&] { return app.frameStats().dragStartFrames >= 0; }, 240);
    ASSERT_TRUE(moved) << "no image of the moved table";
    const FrameStats& stats = app.frameStats();
    std::printf("drag start: %d frames, %.0f ms; %d images in %d frames\n", stats.dragStartFrames,
                stats.dragStartMs, stats.imagesShown, stats.frames);
    EXPECT_GT(stats.dragStartFrames, 0);
    ASSERT_NE(runner.image(), nullptr);
    EXPECT_EQ(runner.image()->mode, ViewMode::EdgeAndPoint);
    EXPECT_GE(runner.image()->previewVersion, 0);
}

}  // namespace
}  // namespace penumbra
