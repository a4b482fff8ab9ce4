// SessionRunner in the edge-and-point display mode during a drag (no window needed: the
// display runs on the CPU). While the view is interactive the display keeps its full
// resolution; the dragged object, which exists only as the solver's preview version, must
// appear at its new place with the selection outline around it; after the drop the object is
// put back where it was dropped.

#include <gtest/gtest.h>

#include <chrono>
#include <thread>

#include "render/camera_rays.h"
#include "runner_test_support.h"
#include "test_scenes.h"
#include "ui/session_runner.h"

namespace penumbra {
namespace {

constexpr int kSize = 96;
const Vec3 kNewPlace = test::kLitRoomSlabDragTarget;
const Vec3 kOldPlace(0.2, -0.8, 0.1);  // makeLitRoom's slab

ViewRequest view(bool interactive) {
    ViewRequest v;
    v.camera = test::litRoomTopCamera();
    v.width = v.height = kSize;
    v.mode = ViewMode::EdgeAndPoint;
    v.highlight = "slab";
    v.interactive = interactive;
    return v;
}

using test::pumpUntil;

struct Rgba {
    int r, g, b;
};
Rgba pixel(const ViewportImage& img, glm::dvec2 p) {
    const int w = img.render.radiance.width;
    const int x = static_cast<int>(p.x), y = static_cast<int>(p.y);
    const std::uint8_t* q = &img.render.rgba[4 * (static_cast<std::size_t>(y) * w + x)];
    return {q[0], q[1], q[2]};
}
bool isOutline(const std::uint8_t* q) { return q[0] == 255 && q[1] == 150 && q[2] == 20; }

/// Mean pixel position of the outline (x, y), and how many there are.
std::pair<glm::dvec2, int> outline(const ViewportImage& img) {
    const int w = img.render.radiance.width, h = img.render.radiance.height;
    glm::dvec2 sum(0.0);
    int n = 0;
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x)
            if (isOutline(&img.render.rgba[4 * (static_cast<std::size_t>(y) * w + x)]))
                sum += glm::dvec2(x + 0.5, y + 0.5), ++n;
    return {n ? sum / double(n) : sum, n};
}

bool reddish(const Rgba& c) { return c.r > 40 && c.r > 1.3 * c.g + 10; }

TEST(SessionRunnerDrag, EdgeAndPointModeShowsTheDraggedObjectAndItsOutline) {
    SessionRunnerOptions options;
    options.threaded = false;
    options.solveBudgetMs = 20;
    options.displayFrameMs = 0;
    options.settleFrames = 10;
    SessionRunner runner(std::make_unique<EditSession>(test::makeLitRoom("red"), SolverOptions{}),
                         options);
    runner.setView(view(false));
    // Generous: a sanitizer build converges several times slower.
    auto settled = pumpUntil(runner, 90, [&](const ViewportImage&) { return runner.quiescent(); });
    ASSERT_TRUE(settled);
    ASSERT_TRUE(runner.quiescent());
    EXPECT_EQ(settled->render.radiance.width, kSize);
    EXPECT_FALSE(settled->reduced);

    const CameraRays full(test::litRoomTopCamera(), kSize, kSize);
    const glm::dvec2 oldTop = *full.projectToPixel(kOldPlace + Vec3(0, 0.05, 0));
    const glm::dvec2 newTop = *full.projectToPixel(kNewPlace + Vec3(0, 0.05, 0));
    ASSERT_GT(glm::length(oldTop - newTop), 15.0);
    EXPECT_TRUE(reddish(pixel(*settled, oldTop)));
    EXPECT_FALSE(reddish(pixel(*settled, newTop)));
    const auto [before, beforeCount] = outline(*settled);
    ASSERT_GT(beforeCount, 10);
    EXPECT_LT(glm::length(before - oldTop), 12.0);

    // The drag: select, move, interactive view.
    runner.submit(SelectCommand{"slab"});
    TransformCommand t;
    t.id = "slab";
    t.translate = kNewPlace;
    runner.submitCoalescing(t);
    runner.setView(view(true));
    // The one display keeps its full resolution while interacting.
    int frames = 0;
    auto dragging = pumpUntil(runner, 60, [&](const ViewportImage& img) {
        if (img.previewVersion < 0) return false;
        return ++frames > 30 && reddish(pixel(img, newTop));
    });
    ASSERT_TRUE(dragging);
    EXPECT_GE(runner.solver().previewVersion, 0);
    EXPECT_EQ(runner.solver().selected, "slab");
    EXPECT_FALSE(dragging->reduced);
    EXPECT_EQ(dragging->render.radiance.width, kSize);
    EXPECT_TRUE(reddish(pixel(*dragging, newTop)))
        << "the dragged slab is not displayed: " << pixel(*dragging, newTop).r << " "
        << pixel(*dragging, newTop).g << " " << pixel(*dragging, newTop).b;
    EXPECT_FALSE(reddish(pixel(*dragging, oldTop))) << "the slab still shows where it was";
    const auto [during, duringCount] = outline(*dragging);
    EXPECT_GT(duringCount, 10);
    EXPECT_LT(glm::length(during - newTop), 12.0);

    // Drop it: the slab (alive again) where it was dropped.
    runner.submit(UnselectCommand{});
    runner.setView(view(false));
    auto dropped = pumpUntil(runner, 90, [&](const ViewportImage&) { return runner.quiescent(); });
    ASSERT_TRUE(dropped);
    EXPECT_TRUE(runner.quiescent());
    EXPECT_FALSE(dropped->reduced);
    EXPECT_EQ(dropped->render.radiance.width, kSize);
    EXPECT_TRUE(reddish(pixel(*dropped, newTop)))
        << pixel(*dropped, newTop).r << " " << pixel(*dropped, newTop).g << " "
        << pixel(*dropped, newTop).b << " settled " << dropped->settledFrames;
    EXPECT_FALSE(reddish(pixel(*dropped, oldTop)));
    const auto [after, afterCount] = outline(*dropped);
    EXPECT_GT(afterCount, 10);
    EXPECT_LT(glm::length(after - newTop), 12.0);
    EXPECT_TRUE(runner.takeMessages().empty());
}

TEST(SessionRunnerDrag, GouraudImagesKeepComingWhileADragAppendsVersions) {
    // Every move of a drag appends a version of the object before the solver publishes
    // lighting with its elements; the Gouraud view must render meanwhile (those elements are
    // not shown) instead of failing on the shorter lighting.
    SessionRunnerOptions options;
    options.solveBudgetMs = 5;
    SessionRunner runner(std::make_unique<EditSession>(test::makeLitRoom("red"), SolverOptions{}),
                         options);
    ViewRequest v = view(true);
    v.mode = ViewMode::Gouraud;
    runner.setView(v);
    runner.submit(SelectCommand{"slab"});
    for (int i = 0; i < 40; ++i) {
        TransformCommand t;
        t.id = "slab";
        t.translate = kOldPlace + (kNewPlace - kOldPlace) * ((i + 1) / 40.0);
        runner.submitCoalescing(t);
        std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
    runner.submit(UnselectCommand{});
    v.interactive = false;
    runner.setView(v);
    const auto end = std::chrono::steady_clock::now() + std::chrono::seconds(30);
    while (!runner.quiescent() && std::chrono::steady_clock::now() < end)
        std::this_thread::sleep_for(std::chrono::milliseconds(5));
    ASSERT_TRUE(runner.quiescent());
    for (const std::string& m : runner.takeMessages())
        EXPECT_EQ(m.find("viewport:"), std::string::npos) << m;
    const auto img = runner.image();
    ASSERT_TRUE(img);
    const CameraRays full(test::litRoomTopCamera(), kSize, kSize);
    EXPECT_TRUE(reddish(pixel(*img, *full.projectToPixel(kNewPlace + Vec3(0, 0.05, 0)))));
}

}  // namespace
}  // namespace penumbra
