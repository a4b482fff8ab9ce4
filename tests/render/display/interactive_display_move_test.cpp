// What the display shows after an object moves (the drag issue): the points behind the moved
// object are exactly those a ray from the eye finds it in front of (brute force over every
// cached point, by closest hits against the object alone); the object's own points move with
// it; no pixel is left without a value, whatever the cache holds; and the dragged object's
// pixels match a reference of its new place.

#include <gtest/gtest.h>

#include <cmath>
#include <map>

#include "display_events.h"
#include "edit/edit_session.h"
#include "lit_room_display.h"
#include "point_shader_test_access.h"
#include "render/camera_rays.h"
#include "render/display/interactive_display.h"
#include "solver/discretization.h"
#include "solver/ray_tracer.h"
#include "test_scenes.h"

namespace penumbra {
namespace {

constexpr int kSize = 80;

InteractiveDisplayOptions displayOptions() { return test::litRoomDisplayOptions(kSize); }

struct Scene3 {
    std::unique_ptr<EditSession> session;
    int origin = -1, preview = -1;
};

/// The lit room solved and the slab selected (not yet moved).
Scene3 selectSlab() {
    Scene3 s;
    s.session = std::make_unique<EditSession>(test::makeLitRoom("red"), SolverOptions{});
    s.session->converge(1e-3);
    s.origin = s.session->objectVersion("slab");
    s.session->apply(SelectCommand{"slab"});
    return s;
}

int moveSlab(Scene3& s, const Vec3& to) {
    TransformCommand t;
    t.id = "slab";
    t.translate = to;
    s.preview = s.session->apply(t).preview;
    s.session->solve(40);
    return s.preview;
}

/// A display of the solved room that has begun dragging the selected slab at its origin.
struct DragDisplay {
    RayTracer::SubsetHandle origin;
    InteractiveDisplay display;
    explicit DragDisplay(Scene3& s)
        : origin(s.session->tracer(), {s.origin}),
          display(s.session->discretization(), s.session->tracer(), SolverOptions{},
                  displayOptions()) {
        display.apply(SolutionView::of(s.session->solver()));
        display.apply(test::dragBeganEvent(s.origin, s.origin),
                      {origin.visibility(), origin.visibility()}, &s.session->solver());
    }
};

TEST(InteractiveDisplayMove, PointsBehindTheMovedObjectAreExactlyThoseItCoversFromTheEye) {
    Scene3 s = selectSlab();
    DragDisplay drag(s);
    InteractiveDisplay& display = drag.display;
    const CameraRays rays(test::litRoomTopCamera(), kSize, kSize);
    display.warmUp(rays, 1.0);
    for (int f = 0; f < 3; ++f) display.renderFrame(rays);

    // The slab moves over the floor the camera saw: those floor points are now behind it.
    const int preview = moveSlab(s, test::kLitRoomSlabDragTarget);
    RayTracer::SubsetHandle subset(s.session->tracer(), {preview});
    display.apply(test::previewMovedEvent(s.origin, preview),
                  {drag.origin.visibility(), subset.visibility()}, &s.session->solver());
    display.renderFrame(rays);

    // Brute force: every cached point not on the slab, behind it from the eye (a closest hit
    // on the slab alone nearer than the point).
    const RenderCache& cache = display.cache();
    std::size_t behind = 0, mismatches = 0, onSlab = 0;
    for (std::size_t i = 0; i < cache.size(); ++i) {
        const CachePoint& p = cache.points()[i];
        if (p.object == preview) {
            ++onSlab;
            EXPECT_FALSE(cache.hidden(i));
            continue;
        }
        const Vec3 d = p.position - rays.origin();
        const double distance = glm::length(d);
        const RayHit hit = s.session->tracer().intersect(
            rays.origin(), d / distance, 0.0, distance * (1 - 1e-6), subset.visibility());
        const bool expected = hit.object == preview;
        behind += expected;
        // A point within a hair of the slab's surface may go either way.
        const bool borderline = hit.object == preview && distance - hit.t < 1e-4;
        if (expected != cache.hidden(i) && !borderline) ++mismatches;
    }
    std::printf("%zu cached points, %zu behind the moved slab, %zu on it\n", cache.size(), behind,
                onSlab);
    EXPECT_GT(behind, 100u) << "the slab should cover floor points the camera saw";
    EXPECT_GT(onSlab, 100u) << "the slab's points moved with it";
    EXPECT_EQ(mismatches, 0u);
}

TEST(InteractiveDisplayMove, TheMovedObjectsPointsFollowItAndNoPixelIsLeftEmpty) {
    // The display sees the room before the select, as the editor's does; the select's first
    // preview is already moved (no preview at the origin in between).
    Scene3 s;
    s.session = std::make_unique<EditSession>(test::makeLitRoom("red"), SolverOptions{});
    s.session->converge(1e-3);
    s.origin = s.session->objectVersion("slab");
    const Discretization& disc = s.session->discretization();
    InteractiveDisplay display(disc, s.session->tracer(), SolverOptions{}, displayOptions());
    display.apply(SolutionView::of(s.session->solver()));
    const CameraRays rays(test::litRoomTopCamera(), kSize, kSize);
    display.warmUp(rays, 1.0);
    display.renderFrame(rays);
    s.session->apply(SelectCommand{"slab"});
    RayTracer::SubsetHandle origin(s.session->tracer(), {s.origin});
    std::vector<Vec3> before;
    for (const CachePoint& p : display.cache().points())
        if (p.object == s.origin) before.push_back(p.position);
    ASSERT_GT(before.size(), 100u);

    // The select reaches the display coalesced with the first move (DragBegan previewing it).
    const Vec3 by = test::kLitRoomSlabDragTarget - Vec3(0.2, -0.8, 0.1);
    const int preview = moveSlab(s, test::kLitRoomSlabDragTarget);
    RayTracer::SubsetHandle subset(s.session->tracer(), {preview});
    display.apply(test::dragBeganEvent(s.origin, preview),
                  {origin.visibility(), subset.visibility()}, &s.session->solver());
    std::vector<Vec3> after;
    for (std::size_t i = 0; i < display.cache().size(); ++i) {
        const CachePoint& p = display.cache().points()[i];
        EXPECT_NE(p.object, s.origin) << "no point stays where the slab was";
        if (p.object == preview) {
            after.push_back(p.position);
            EXPECT_TRUE(display.cache().stale(i)) << "moved points are re-shaded first";
        }
    }
    ASSERT_EQ(after.size(), before.size());
    for (std::size_t k = 0; k < after.size(); ++k)
        EXPECT_LT(glm::length(after[k] - (before[k] + by)), 1e-9);

    // Every pixel has a value in every frame, also with an empty cache (all fallback).
    for (int f = 0; f < 4; ++f) {
        const Image image = display.renderFrame(rays);
        EXPECT_EQ(display.lastFrame().unfilledPixels, 0u);
        for (const Rgb& c : image.pixels) ASSERT_TRUE(std::isfinite(c.x + c.y + c.z));
    }
    display.cache().clear();
    const Image filled = display.renderFrame(rays);
    EXPECT_EQ(display.lastFrame().unsampledPixels, std::size_t(kSize * kSize));
    EXPECT_EQ(display.lastFrame().unfilledPixels, 0u);
    std::size_t black = 0;
    for (const Rgb& c : filled.pixels) black += luminance(c) <= 0;
    EXPECT_LT(black, std::size_t(kSize * kSize / 100)) << "the fallback lights the room";

    // Without the fallback the same holes stay black, and are counted as such.
    InteractiveDisplayOptions plain = displayOptions();
    plain.fillHoles = false;
    InteractiveDisplay bare(disc, s.session->tracer(), SolverOptions{}, plain);
    bare.apply(SolutionView::of(s.session->solver()));
    const Image empty = bare.renderFrame(rays);
    EXPECT_EQ(bare.lastFrame().unfilledPixels, bare.lastFrame().unsampledPixels);
    EXPECT_EQ(bare.lastFrame().unfilledPixels, std::size_t(kSize * kSize));
    for (const Rgb& c : empty.pixels) EXPECT_EQ(luminance(c), 0.0);
}

TEST(InteractiveDisplayMove, PointsShadedBeforeTheirElementWasRelitArriveStale) {
    // Asynchronous shading: requests shaded with the room half converged, taken after the
    // solution moved on. Each arrives stale exactly when the relight marked its element (the
    // element's older points, relit in place, tell which): the change is not in its colour.
    auto session = std::make_unique<EditSession>(test::makeLitRoom("red"), SolverOptions{});
    session->solve(6);
    InteractiveDisplayOptions options = displayOptions();
    options.synchronous = false;
    options.sampleFraction = 0.3;
    InteractiveDisplay display(session->discretization(), session->tracer(), SolverOptions{},
                               options);
    display.apply(SolutionView::of(session->solver()));
    const CameraRays rays(test::litRoomTopCamera(), kSize, kSize);
    display.warmUp(rays, 0.5);
    display.renderFrame(rays);  // requests go to the workers
    display.shader().waitIdle();
    const std::size_t before = display.cache().size();
    session->converge(1e-3);
    display.apply(SolutionView::of(session->solver()));
    display.renderFrame(rays);  // takes the results shaded with the older state
    ASSERT_GT(display.cache().size(), before) << "results arrived";
    std::map<int, bool> relit;  // element → its older points were marked stale
    for (std::size_t i = 0; i < before; ++i)
        relit[display.cache().points()[i].element] = display.cache().stale(i);
    std::size_t compared = 0, stale = 0;
    for (std::size_t i = before; i < display.cache().size(); ++i) {
        const auto it = relit.find(display.cache().points()[i].element);
        if (it == relit.end()) continue;
        EXPECT_EQ(display.cache().stale(i), it->second) << display.cache().points()[i].toString();
        ++compared;
        stale += display.cache().stale(i);
    }
    EXPECT_GT(compared, 100u);
    EXPECT_GT(stale, 0u) << "the solution moved on: some elements were relit";
}

TEST(InteractiveDisplayMove, TheFallbackOfANewDragPositionIsNeverBlack) {
    // A drag position the solution has not been snapshotted for yet: the pixels the object
    // newly covers have no point and take the fallback, which shows the object lit as its
    // previous position was (the same mesh), not black; the same for a shader whose state has
    // never blended that object (the sampled direct light at the hit).
    Scene3 s = selectSlab();
    const Discretization& disc = s.session->discretization();
    RayTracer::SubsetHandle origin(s.session->tracer(), {s.origin});
    PointShaderOptions so;
    so.threads = 0;
    PointShader shader(disc, s.session->tracer(), SolverOptions{}, so);
    shader.updateSolution(s.session->solver());
    PointShaderTestAccess::beginDrag(shader, s.origin, origin.visibility());
    PointShaderTestAccess::setPreview(shader, s.origin, origin.visibility());
    const int preview = moveSlab(s, test::kLitRoomSlabDragTarget);
    RayTracer::SubsetHandle subset(s.session->tracer(), {preview});
    // No updateSolution after it.
    PointShaderTestAccess::setPreview(shader, preview, subset.visibility());

    const CameraRays rays(test::litRoomTopCamera(), kSize, kSize);
    int onSlab = 0;
    for (int y = 0; y < kSize; ++y)
        for (int x = 0; x < kSize; ++x) {
            const Vec3 dir = rays.rayDirection(x + 0.5, y + 0.5);
            const ShadedPoint p = shader.shade({{x + 0.5, y + 0.5}, rays.origin(), dir, 1});
            if (p.object != preview || luminance(p.radiance) <= 0) continue;
            ++onSlab;
            const Rgb fallback = shader.shadeFallback(rays.origin(), dir);
            EXPECT_GT(luminance(fallback), 0.2 * luminance(p.radiance))
                << "pixel " << x << ", " << y << ": shaded " << luminance(p.radiance);
        }
    EXPECT_GT(onSlab, 20) << "the camera sees the slab at its new place";
}

/// Σ luminance(H_indirect)·area over the elements of `object`.
double reflectedLight(const Discretization& disc, int object, const std::vector<Rgb>& indirect) {
    double sum = 0;
    const auto [first, count] = disc.elementRange(object);
    for (int k = 0; k < count; ++k)
        sum += luminance(indirect[first + k]) * disc.elements()[first + k].area;
    return sum;
}

/// reflectedLight of `object` once the session's solution has converged (a fresh shader).
double settledReflectedLight(Scene3& s, int object) {
    s.session->converge(1e-4);
    PointShaderOptions so;
    so.threads = 0;
    PointShader settled(s.session->discretization(), s.session->tracer(), SolverOptions{}, so);
    settled.updateSolution(s.session->solver());
    return reflectedLight(s.session->discretization(), object, settled.elementIndirect());
}

TEST(InteractiveDisplayMove, ADroppedObjectKeepsItsReflectedLightUntilTheNextSnapshot) {
    // The editor ends a drag (DragEnded) before the solver's next snapshot reaches the display:
    // the snapshot it has is the drag's, in which the dropped version has no light of its own
    // (the preview buffer had it). Its last buffer's reflected light stands in at once, close
    // to what the converged solution gives it, instead of none.
    Scene3 s = selectSlab();
    const Discretization& disc = s.session->discretization();
    DragDisplay drag(s);
    InteractiveDisplay& display = drag.display;
    const int preview = moveSlab(s, test::kLitRoomSlabDragTarget);
    RayTracer::SubsetHandle subset(s.session->tracer(), {preview});
    display.apply(test::previewMovedEvent(s.origin, preview),
                  {drag.origin.visibility(), subset.visibility()}, &s.session->solver());
    s.session->solve(200);  // the preview buffer complete
    display.apply(SolutionView::of(s.session->solver()));
    const EditEvent r = s.session->apply(UnselectCommand{});
    ASSERT_EQ(r.kind, EditEvent::Kind::DragEnded);
    ASSERT_EQ(r.added.size(), 1u);
    const int dropped = r.added[0];
    // The display followed the drag to the dropped version: the drop folds its last change in.
    ASSERT_EQ(display.previewVersion(), dropped);
    display.apply(r);  // no snapshot yet
    ASSERT_EQ(display.dragOrigin(), -1);

    const double shown = reflectedLight(disc, dropped, display.shader().elementIndirect());
    const double expected = settledReflectedLight(s, dropped);
    ASSERT_GT(expected, 0.0);
    EXPECT_NEAR(shown, expected, 0.15 * expected);
}

TEST(InteractiveDisplayMove, ADropJustAfterAMoveKeepsTheDragsLightNotABufferThatBarelyBegan) {
    // The drag's last move came just before the drop: the solver's buffer for that place has
    // had one shot (the lamp's direct light, no reflected light yet) when the snapshot reaches
    // the display. The dropped object's stand-in is the drag's best estimate (the buffer of
    // the place before, complete), not that one, so it shows about the light it settles to.
    Scene3 s = selectSlab();
    const Discretization& disc = s.session->discretization();
    DragDisplay drag(s);
    InteractiveDisplay& display = drag.display;
    const int first = moveSlab(s, test::kLitRoomSlabDragTarget);
    {
        RayTracer::SubsetHandle subset(s.session->tracer(), {first});
        display.apply(test::previewMovedEvent(s.origin, first),
                      {drag.origin.visibility(), subset.visibility()}, &s.session->solver());
        s.session->solve(200);
        display.apply(SolutionView::of(s.session->solver()));
    }
    TransformCommand t;
    t.id = "slab";
    t.translate = test::kLitRoomSlabDragTarget + Vec3(0.05, 0.0, 0.0);
    const int last = s.session->apply(t).preview;
    ASSERT_GE(last, 0);
    RayTracer::SubsetHandle subset(s.session->tracer(), {last});
    display.apply(test::previewMovedEvent(s.origin, last),
                  {drag.origin.visibility(), subset.visibility()}, &s.session->solver());
    s.session->solve(1);
    display.apply(SolutionView::of(s.session->solver()));
    ASSERT_FALSE(s.session->solver().previewComplete());
    const EditEvent r = s.session->apply(UnselectCommand{});
    ASSERT_EQ(r.kind, EditEvent::Kind::DragEnded);
    ASSERT_EQ(r.added.size(), 1u);
    const int dropped = r.added[0];
    ASSERT_EQ(display.previewVersion(), dropped);
    display.apply(r);
    ASSERT_EQ(display.dragOrigin(), -1);

    const double shown = reflectedLight(disc, dropped, display.shader().elementIndirect());
    // Still so after the next snapshot (the solver has not yet reached the dropped version).
    display.apply(SolutionView::of(s.session->solver()));
    const double next = reflectedLight(disc, dropped, display.shader().elementIndirect());
    const double expected = settledReflectedLight(s, dropped);
    ASSERT_GT(expected, 0.0);
    EXPECT_NEAR(shown, expected, 0.2 * expected);
    EXPECT_NEAR(next, expected, 0.2 * expected);
}

TEST(InteractiveDisplayMove, TheFallbackIsTheSolutionBlendedPerVertex) {
    // On the converged room without a preview, the fallback of a ray equals (E + ρ·H)/π with
    // H the element irradiance blended per vertex (the Gouraud view's interpolation), which is
    // recomputed here from the solver's irradiance with the hit's barycentric weights.
    EditSession session(test::makeLitRoom("red"), SolverOptions{});
    session.converge(1e-3);
    const Discretization& disc = session.discretization();
    PointShaderOptions so;
    so.threads = 0;
    PointShader shader(disc, session.tracer(), SolverOptions{}, so);
    shader.updateSolution(session.solver());
    std::vector<Rgb> H = session.solver().irradiance();
    const CameraRays rays(test::litRoomTopCamera(), 16, 16);
    int checked = 0;
    for (int y = 0; y < 16; ++y)
        for (int x = 0; x < 16; ++x) {
            const Vec3 dir = rays.rayDirection(x + 0.5, y + 0.5);
            const RayHit hit = session.tracer().intersect(rays.origin(), dir);
            if (hit.object < 0 || hit.backFace) continue;
            const Element& el = disc.elements()[hit.element];
            const std::vector<Rgb> vertex = disc.vertexValues(el.object, H);
            Rgb h(0.0);
            for (std::size_t i = 0; i < hit.weights.size(); ++i)
                h += hit.weights[i] * vertex[el.vertices[i]];
            const Material& m = disc.elementMaterial(hit.element);
            const Rgb expected = (m.emission + m.reflectance * h) / M_PI;
            const Rgb got = shader.shadeFallback(rays.origin(), dir);
            for (int c = 0; c < 3; ++c)
                EXPECT_NEAR(got[c], expected[c], 1e-9 + 1e-9 * expected[c])
                    << "pixel " << x << ", " << y;
            ++checked;
        }
    EXPECT_GT(checked, 200);
}

}  // namespace
}  // namespace penumbra
