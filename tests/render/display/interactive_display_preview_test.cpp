// The edge-and-point display during a drag (George et al.'s temporary buffer): the dragged
// object exists only as the solver's dead preview version plus per-element preview radiosity.
// The display's preview (InteractiveDisplay::apply of PreviewMoved) must show it where it now
// is, lit by that buffer, with its shadow. Independent reference: the same scene built with the
// object really at the new place and solved from scratch, rendered by the same display pipeline
// with the same sample patterns.

#include <gtest/gtest.h>

#include <cmath>

#include "display_events.h"
#include "edit/edit_session.h"
#include "lit_room_display.h"
#include "render/camera_rays.h"
#include "render/display/interactive_display.h"
#include "solver/discretization.h"
#include "solver/ray_tracer.h"
#include "test_scenes.h"

namespace penumbra {
namespace {

constexpr int kSize = 80;
const Vec3 kNewPlace = test::kLitRoomSlabDragTarget;

InteractiveDisplayOptions displayOptions() { return test::litRoomDisplayOptions(kSize); }

/// Warm-up at every pixel, then a few frames so the reconstruction uses settled points.
Image settle(InteractiveDisplay& display) {
    const CameraRays rays(test::litRoomTopCamera(), kSize, kSize);
    display.warmUp(rays, 1.0);
    Image image;
    for (int f = 0; f < 6; ++f) image = display.renderFrame(rays);
    return image;
}

/// Mean sRGB difference over the pixels of `mask`.
double maskedDifference(const Image& a, const Image& b, const std::vector<std::uint8_t>& mask) {
    double sum = 0;
    int n = 0;
    for (int y = 0; y < kSize; ++y)
        for (int x = 0; x < kSize; ++x) {
            if (!mask[y * kSize + x]) continue;
            const Rgb& p = a.at(x, y);
            const Rgb& q = b.at(x, y);
            for (int c = 0; c < 3; ++c)
                sum += std::abs(srgbEncode(std::clamp(p[c], 0.0, 1.0)) -
                                srgbEncode(std::clamp(q[c], 0.0, 1.0)));
            ++n;
        }
    return n ? sum / (3.0 * n) : 0.0;
}

struct Dragged {
    std::unique_ptr<EditSession> session;
    int origin = -1, preview = -1;
};

/// The lit room solved, the slab selected and moved to kNewPlace, the preview solved.
Dragged dragSlab() {
    Dragged d;
    d.session = std::make_unique<EditSession>(test::makeLitRoom("red"), SolverOptions{});
    d.session->converge(1e-3);
    d.origin = d.session->apply(SelectCommand{"slab"}).origin;
    TransformCommand t;
    t.id = "slab";
    t.translate = kNewPlace;
    const EditEvent r = d.session->apply(t);
    d.preview = r.preview;
    d.session->converge(1e-3);  // the preview buffer is finished too
    return d;
}

TEST(InteractiveDisplayPreview, DraggedObjectAppearsAtItsNewPlaceLitByThePreviewBuffer) {
    Dragged drag = dragSlab();
    ASSERT_GE(drag.preview, 0);
    ASSERT_EQ(drag.session->solver().previewObject(), drag.preview);
    const Discretization& disc = drag.session->discretization();
    ASSERT_FALSE(disc.objects()[drag.preview].alive);

    // Reference: the slab built at the new place, solved from scratch.
    Scene moved = test::makeLitRoom("red");
    for (SceneObject& o : moved.objects)
        if (o.id == "slab") o.transform.translate = kNewPlace;
    EditSession reference(moved, SolverOptions{});
    reference.converge(1e-3);
    InteractiveDisplay refDisplay(reference.discretization(), reference.tracer(), SolverOptions{},
                                  displayOptions());
    refDisplay.apply(SolutionView::of(reference.solver()));
    const Image expected = settle(refDisplay);

    // Which pixels show the slab in the reference, and which its neighbourhood.
    const CameraRays rays(test::litRoomTopCamera(), kSize, kSize);
    const int refSlab = reference.objectVersion("slab");
    std::vector<std::uint8_t> slabMask(kSize * kSize, 0);
    int slabPixels = 0;
    for (int y = 0; y < kSize; ++y)
        for (int x = 0; x < kSize; ++x) {
            const RayHit h =
                reference.tracer().intersect(rays.origin(), rays.rayDirection(x + 0.5, y + 0.5));
            if (h.object == refSlab) slabMask[y * kSize + x] = 1, ++slabPixels;
        }
    ASSERT_GT(slabPixels, 200) << "the camera should see the moved slab";
    const std::vector<std::uint8_t> all(kSize * kSize, 1);

    // Without the preview, the display shows the room without the slab.
    InteractiveDisplay blind(disc, drag.session->tracer(), SolverOptions{}, displayOptions());
    blind.apply(SolutionView::of(drag.session->solver()));
    const Image without = settle(blind);

    // With the preview: through a tracer subset (as the editor does), and through the world
    // filter (no subset).
    RayTracer::SubsetHandle subset(drag.session->tracer(), {drag.preview});
    InteractiveDisplay display(disc, drag.session->tracer(), SolverOptions{}, displayOptions());
    display.apply(test::previewMovedEvent(drag.origin, drag.preview), {{}, subset.visibility()},
                  &drag.session->solver());
    EXPECT_EQ(display.previewVersion(), drag.preview);
    const Image with = settle(display);
    InteractiveDisplay filtered(disc, drag.session->tracer(), SolverOptions{}, displayOptions());
    filtered.apply(test::previewMovedEvent(drag.origin, drag.preview), {}, &drag.session->solver());
    const Image withFilter = settle(filtered);

    // A primary ray through the slab's new place meets the preview version (and the scene
    // behind it without the preview).
    const auto top = rays.projectToPixel(kNewPlace + Vec3(0, 0.05, 0));
    ASSERT_TRUE(top.has_value());
    const ShadeRequest probe{*top, rays.origin(), rays.rayDirection(top->x, top->y), 0};
    const ShadedPoint onSlab = display.shader().shade(probe);
    EXPECT_EQ(onSlab.object, drag.preview);
    EXPECT_GT(luminance(onSlab.radiance), 0.0);
    EXPECT_NE(blind.shader().shade(probe).object, drag.preview);

    const double slabWith = maskedDifference(with, expected, slabMask);
    const double slabWithout = maskedDifference(without, expected, slabMask);
    const double allWith = maskedDifference(with, expected, all);
    const double allWithout = maskedDifference(without, expected, all);
    std::printf(
        "mean sRGB |display - moved reference|: slab %.4f (no preview %.4f), image %.4f "
        "(no preview %.4f), subset vs filter %.2e\n",
        slabWith, slabWithout, allWith, allWithout, maskedDifference(with, withFilter, all));
    EXPECT_LT(slabWith, 0.03);
    EXPECT_GT(slabWithout, 5 * slabWith);
    EXPECT_LT(allWith, 0.02);
    EXPECT_GT(allWithout, 2 * allWith);
    EXPECT_LT(maskedDifference(with, withFilter, all), 1e-3);
}

TEST(InteractiveDisplayPreview, ShadowFollowsTheDragAndClearPreviewRestoresTheScene) {
    Dragged drag = dragSlab();
    const Discretization& disc = drag.session->discretization();
    RayTracer::SubsetHandle subset(drag.session->tracer(), {drag.preview});
    InteractiveDisplay display(disc, drag.session->tracer(), SolverOptions{}, displayOptions());
    display.apply(SolutionView::of(drag.session->solver()));
    const Image before = settle(display);

    // The floor point straight under the moved slab (the lamp is above the centre of the
    // room): in its shadow with the preview, lit without.
    const Vec3 under(kNewPlace.x, -1.5, kNewPlace.z);
    const auto pixel = CameraRays(test::litRoomTopCamera(), kSize, kSize).projectToPixel(under);
    ASSERT_TRUE(pixel.has_value());
    const int px = static_cast<int>(pixel->x), py = static_cast<int>(pixel->y);

    // Points in the shadow region are dropped when the preview is set.
    const std::size_t dropped = display.apply(test::previewMovedEvent(drag.origin, drag.preview),
                                              {{}, subset.visibility()}, &drag.session->solver());
    EXPECT_GT(dropped, 0u);
    const Image during = settle(display);
    EXPECT_LT(luminance(during.at(px, py)), 0.7 * luminance(before.at(px, py)));

    // The preview ends with nothing added (a drag this display only saw the preview of).
    display.apply(test::dragEndedEvent(drag.origin, {}), {}, &drag.session->solver());
    EXPECT_EQ(display.previewVersion(), -1);
    const Image after = settle(display);
    EXPECT_NEAR(luminance(after.at(px, py)), luminance(before.at(px, py)),
                0.05 * luminance(before.at(px, py)));
}

}  // namespace
}  // namespace penumbra
