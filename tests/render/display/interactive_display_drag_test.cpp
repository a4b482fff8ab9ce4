// The edge-and-point display through a whole drag as the editor runs it (George et al.'s
// select → temporary buffer → unselect): InteractiveDisplay::apply of the select (DragBegan)
// keeps the direct light of the scene as it was, each position (PreviewMoved) estimates its
// change relative to the drag's origin (in the background with
// PointShaderOptions::backgroundPreview), the drop (DragEnded) folds the last change in.
// Independent references: the scene built with the object really at its new place and solved
// from scratch (a dragged lamp must light the scene from there), a display that recomputes the
// removal the old way (refreshDirect), and the edge finder's silhouettes.
//
// Index: helpers · a dragged lamp lights the scene from its new place · the origin-relative
//        estimate against recomputation · background estimate = synchronous estimate ·
//        the dragged object's silhouettes · a dragged object's points leave a shadow they were in ·
//        a frame's holes show the world it began in · results shaded at an earlier place move on

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <thread>

#include "display_events.h"
#include "edit/edit_session.h"
#include "render/camera_rays.h"
#include "render/display/interactive_display.h"
#include "solver/discretization.h"
#include "solver/ray_tracer.h"
#include "test_scenes.h"

namespace penumbra {
namespace {

// ---------------------------------------------------------------------------------------------
// Helpers

constexpr int kSize = 64;
const Vec3 kNewPlace = test::kLitRoomSlabDragTarget;
/// Where the lamp goes: towards a corner of the ceiling (makeLitRoom's lamp is at the centre).
const Vec3 kLampPlace(-0.8, 1.49, -0.7);

InteractiveDisplayOptions displayOptions() {
    InteractiveDisplayOptions o;
    o.width = o.height = kSize;
    o.synchronous = true;
    return o;
}

/// Every pixel shaded by the display's point shader (no cache: the shading itself).
Image shaded(const InteractiveDisplay& display) {
    return display.renderReference(CameraRays(test::litRoomTopCamera(), kSize, kSize), 1);
}

/// Relative RMS difference of two per-element arrays' luminance over `elements`, relative to the
/// mean luminance of `reference` there.
double relativeRms(const std::vector<Rgb>& a, const std::vector<Rgb>& reference,
                   const std::vector<int>& elements) {
    double sum = 0, mean = 0;
    for (int e : elements) {
        const double d = luminance(a[e]) - luminance(reference[e]);
        sum += d * d;
        mean += luminance(reference[e]);
    }
    if (elements.empty() || mean <= 0) return 0;
    mean /= double(elements.size());
    return std::sqrt(sum / double(elements.size())) / mean;
}

/// The editor's select of `id` and move to `place`: the display takes each edit's event (the
/// select: beginDrag, nothing recomputed; each position: setPreview).
struct Drag {
    std::unique_ptr<EditSession> session;
    int origin = -1, preview = -1;
    RayTracer::SubsetHandle originSubset, previewSubset;
};

void select(Drag& d, InteractiveDisplay& display, const std::string& id) {
    const EditEvent r = d.session->apply(SelectCommand{id});
    ASSERT_EQ(r.kind, EditEvent::Kind::DragBegan);
    d.origin = r.origin;
    d.originSubset = RayTracer::SubsetHandle(d.session->tracer(), {d.origin});
    d.previewSubset = RayTracer::SubsetHandle(d.session->tracer(), {d.origin});
    display.apply(r, {d.originSubset.visibility(), d.previewSubset.visibility()});
    EXPECT_EQ(display.dragOrigin(), d.origin);
    EXPECT_EQ(display.previewVersion(), d.origin);
}

void move(Drag& d, InteractiveDisplay& display, const std::string& id, const Vec3& place) {
    TransformCommand t;
    t.id = id;
    t.translate = place;
    const EditEvent r = d.session->apply(t);
    ASSERT_EQ(r.kind, EditEvent::Kind::PreviewMoved);
    d.preview = r.preview;
    d.previewSubset = RayTracer::SubsetHandle(d.session->tracer(), {d.preview});
    display.apply(r, {d.originSubset.visibility(), d.previewSubset.visibility()});
    EXPECT_EQ(display.previewVersion(), d.preview);
}

/// The scene with `id` really at `place`, solved from scratch.
std::unique_ptr<EditSession> movedAndSolved(const std::string& id, const Vec3& place) {
    Scene moved = test::makeLitRoom("red");
    for (SceneObject& o : moved.objects)
        if (o.id == id) o.transform.translate = place;
    auto session = std::make_unique<EditSession>(moved, SolverOptions{});
    session->converge(1e-3);
    return session;
}

// ---------------------------------------------------------------------------------------------
// A dragged lamp lights the scene from its new place

TEST(InteractiveDisplayDrag, DraggedLampLightsTheSceneFromItsNewPlace) {
    Drag drag;
    drag.session = std::make_unique<EditSession>(test::makeLitRoom("red"), SolverOptions{});
    drag.session->converge(1e-3);
    InteractiveDisplay display(drag.session->discretization(), drag.session->tracer(),
                               SolverOptions{}, displayOptions());
    display.apply(SolutionView::of(drag.session->solver()));
    const Image before = shaded(display);

    select(drag, display, "lamp");
    // The select shows what was there: same light, same image (same sample patterns).
    drag.session->converge(1e-3);
    display.apply(SolutionView::of(drag.session->solver()));
    const double atSelect = displayRmse(shaded(display), before);
    EXPECT_LT(atSelect, 0.02) << "selecting the lamp changed the image";

    move(drag, display, "lamp", kLampPlace);
    drag.session->converge(1e-3);  // the temporary buffer holds the lamp's light at its place
    display.apply(SolutionView::of(drag.session->solver()));
    const Image preview = shaded(display);

    // Reference: the lamp really there, solved and shaded from scratch.
    auto reference = movedAndSolved("lamp", kLampPlace);
    InteractiveDisplay refDisplay(reference->discretization(), reference->tracer(), SolverOptions{},
                                  displayOptions());
    refDisplay.apply(SolutionView::of(reference->solver()));
    const Image expected = shaded(refDisplay);

    const double previewError = displayRmse(preview, expected);
    const double staleError = displayRmse(before, expected);  // the lamp left where it was
    std::printf("lamp drag: select %.4f, preview vs moved %.4f, unmoved vs moved %.4f\n", atSelect,
                previewError, staleError);
    EXPECT_GT(staleError, 0.02) << "the move should change the image";
    EXPECT_LT(previewError, 0.35 * staleError);
    EXPECT_LT(previewError, 0.012);

    // Dropped there: the same light without a preview.
    display.apply(drag.session->apply(UnselectCommand{}),
                  {drag.originSubset.visibility(), drag.previewSubset.visibility()},
                  &drag.session->solver());
    drag.session->converge(1e-3);
    display.apply(SolutionView::of(drag.session->solver()));
    const double droppedError = displayRmse(shaded(display), expected);
    std::printf("lamp drop: vs moved %.4f\n", droppedError);
    EXPECT_LT(droppedError, 0.006);
    EXPECT_EQ(display.previewVersion(), -1);
    EXPECT_EQ(display.dragOrigin(), -1);
}

// ---------------------------------------------------------------------------------------------
// The origin-relative estimate against recomputation

TEST(InteractiveDisplayDrag, OriginRelativeDirectLightMatchesRecomputation) {
    Drag drag;
    drag.session = std::make_unique<EditSession>(test::makeLitRoom("red"), SolverOptions{});
    drag.session->converge(1e-3);
    const Discretization& disc = drag.session->discretization();
    InteractiveDisplay display(disc, drag.session->tracer(), SolverOptions{}, displayOptions());
    const std::vector<Rgb> atStart = display.shader().elementDirect();

    // The select: nothing recomputed, nothing changed.
    const EditEvent sel = drag.session->apply(SelectCommand{"slab"});
    drag.origin = sel.preview;
    drag.originSubset = RayTracer::SubsetHandle(drag.session->tracer(), {drag.origin});
    drag.previewSubset = RayTracer::SubsetHandle(drag.session->tracer(), {drag.origin});
    ASSERT_EQ(sel.kind, EditEvent::Kind::DragBegan);
    ASSERT_EQ(sel.origin, drag.origin);
    EXPECT_EQ(display.apply(sel, {drag.originSubset.visibility(), drag.previewSubset.visibility()}),
              0u);
    EXPECT_EQ(display.shader().elementDirect(), atStart);

    // A move: H_direct in the preview world, against a display that recomputed the removal
    // (notifyChanged, the old path) and estimates the preview from there.
    move(drag, display, "slab", kNewPlace);
    InteractiveDisplay recomputed(disc, drag.session->tracer(), SolverOptions{}, displayOptions());
    recomputed.apply(test::previewMovedEvent(drag.origin, drag.preview),
                     {Visibility{}, drag.previewSubset.visibility()});
    const std::vector<int> alive = disc.aliveElements();
    const std::vector<Rgb> mine = display.shader().elementDirect();
    const std::vector<Rgb> theirs = recomputed.shader().elementDirect();
    const double moved = relativeRms(atStart, theirs, alive);
    const double error = relativeRms(mine, theirs, alive);
    std::printf("slab drag: H_direct rel. RMS vs recomputed %.4f (unmoved %.4f)\n", error, moved);
    EXPECT_GT(moved, 0.05) << "the move should change the direct light";
    EXPECT_LT(error, 0.2 * moved);

    // The drop: the folded estimate against H_direct computed from scratch for the scene.
    display.apply(drag.session->apply(UnselectCommand{}),
                  {drag.originSubset.visibility(), drag.previewSubset.visibility()});
    InteractiveDisplay fresh(disc, drag.session->tracer(), SolverOptions{}, displayOptions());
    const std::vector<int> after = disc.aliveElements();
    const double dropError =
        relativeRms(display.shader().elementDirect(), fresh.shader().elementDirect(), after);
    std::printf("slab drop: H_direct rel. RMS vs fresh %.4f\n", dropError);
    EXPECT_LT(dropError, 0.2 * moved);
    EXPECT_EQ(display.dragOrigin(), -1);
}

// ---------------------------------------------------------------------------------------------
// Background estimate = synchronous estimate

TEST(InteractiveDisplayDrag, BackgroundEstimateEqualsTheSynchronousOne) {
    Drag drag;
    drag.session = std::make_unique<EditSession>(test::makeLitRoom("red"), SolverOptions{});
    drag.session->converge(1e-3);
    const Discretization& disc = drag.session->discretization();
    InteractiveDisplayOptions async = displayOptions();
    async.synchronous = false;
    async.shader.backgroundPreview = true;
    async.shader.threads = 2;
    async.shader.directChunk = 32;  // many chunks, interleaved with shading
    InteractiveDisplay background(disc, drag.session->tracer(), SolverOptions{}, async);
    InteractiveDisplay inline_(disc, drag.session->tracer(), SolverOptions{}, displayOptions());
    background.apply(SolutionView::of(drag.session->solver()));
    inline_.apply(SolutionView::of(drag.session->solver()));

    const EditEvent sel = drag.session->apply(SelectCommand{"slab"});
    drag.origin = sel.preview;
    drag.originSubset = RayTracer::SubsetHandle(drag.session->tracer(), {drag.origin});
    TransformCommand t;
    t.id = "slab";
    t.translate = kNewPlace;
    const EditEvent r = drag.session->apply(t);
    drag.preview = r.preview;
    drag.previewSubset = RayTracer::SubsetHandle(drag.session->tracer(), {drag.preview});
    std::vector<Rgb> bg;
    {
        PointShader::Pause pause(background.shader());
        background.apply(test::dragBeganEvent(drag.origin, drag.preview),
                         {drag.originSubset.visibility(), drag.previewSubset.visibility()});
        // Nothing estimated yet: the preview's direct light waits for the workers.
        EXPECT_TRUE(background.shader().directUpdatePending());
        EXPECT_EQ(background.directJobPreview(), drag.preview);
    }
    inline_.apply(test::dragBeganEvent(drag.origin, drag.preview),
                  {drag.originSubset.visibility(), drag.previewSubset.visibility()});

    // Frames take the finished estimate (bounded number of frames, each waits for the workers).
    const CameraRays rays(test::litRoomTopCamera(), kSize, kSize);
    int frames = 0;
    while (background.shader().directUpdatePending() && frames < 200) {
        background.renderFrame(rays);
        background.shader().waitIdle();
        std::this_thread::sleep_for(std::chrono::milliseconds(1));
        ++frames;
    }
    EXPECT_FALSE(background.shader().directUpdatePending()) << "after " << frames << " frames";
    EXPECT_EQ(background.directJobPreview(), -1);
    bg = background.shader().elementDirect();
    const std::vector<Rgb> in = inline_.shader().elementDirect();
    ASSERT_EQ(bg.size(), in.size());
    std::size_t differ = 0;
    for (std::size_t e = 0; e < bg.size(); ++e) differ += bg[e] != in[e] ? 1 : 0;
    EXPECT_EQ(differ, 0u) << "the same per-element sample patterns must give the same values";
}

// ---------------------------------------------------------------------------------------------
// The dragged object's silhouettes

TEST(InteractiveDisplayDrag, DraggedObjectHasSilhouetteEdgesAtItsPreviewPosition) {
    Drag drag;
    drag.session = std::make_unique<EditSession>(test::makeLitRoom("red"), SolverOptions{});
    drag.session->converge(1e-3);
    const Discretization& disc = drag.session->discretization();
    InteractiveDisplay display(disc, drag.session->tracer(), SolverOptions{}, displayOptions());
    display.apply(SolutionView::of(drag.session->solver()));
    select(drag, display, "slab");
    move(drag, display, "slab", kNewPlace);

    const CameraRays rays(test::litRoomTopCamera(), kSize, kSize);
    display.renderFrame(rays);
    // World silhouettes of the preview version: on its box at the new place; none of the origin.
    const std::vector<WorldEdge> edges = display.edgeFinder().findSilhouettes(rays.origin());
    Vec3 lo(1e9), hi(-1e9);
    for (const Vec3& p : disc.objects()[drag.preview].worldPositions)
        lo = glm::min(lo, p), hi = glm::max(hi, p);
    int onPreview = 0, onOrigin = 0, outside = 0;
    for (const WorldEdge& e : edges) {
        if (e.object == drag.origin) ++onOrigin;
        if (e.object != drag.preview) continue;
        ++onPreview;
        for (const Vec3& p : {e.a, e.b})
            if (glm::any(glm::lessThan(p, lo - 1e-6)) || glm::any(glm::greaterThan(p, hi + 1e-6)))
                ++outside;
    }
    EXPECT_GE(onPreview, 4) << "a box seen from above has a silhouette loop";
    EXPECT_EQ(onOrigin, 0);
    EXPECT_EQ(outside, 0);

    // Projected: the frame's screen edges pass near the preview's top centre.
    const glm::dvec2 top = *rays.projectToPixel(kNewPlace + Vec3(0, 0.05, 0));
    const glm::dvec2 corner = *rays.projectToPixel(Vec3(lo.x, hi.y, lo.z));
    const double reach = glm::length(top - corner) + 2;
    int near = 0;
    for (const ScreenEdge& s : display.screenEdges())
        if (s.kind == ScreenEdge::Kind::Silhouette && glm::length(s.a - top) <= reach &&
            glm::length(s.b - top) <= reach)
            ++near;
    EXPECT_GE(near, 4);
}

// ---------------------------------------------------------------------------------------------
// A dragged object's points leave a shadow they were in

TEST(InteractiveDisplayDrag, CarriedPointsTakeTheDirectChangeOfTheirElementsAndAreNotTrusted) {
    // The slab rests in the shadow of a shade under the lamp and is dragged into the open. Its
    // points move with it (carried, stale) and show what they showed under the shade until they
    // are re-shaded; once the shader's estimate of the new place's direct light is in, they take
    // each element's change, and the frames do not show them as exact own points meanwhile.
    // Reference: every pixel shaded afresh at the new place (renderReference).
    Scene scene = test::makeLitRoom("white");
    scene.objects.push_back(
        test::makeQuad("shade", 0.5, 0.5, "white", {0.2, 0.4, 0.1}, {180, 0, 0}));
    Drag drag;
    drag.session = std::make_unique<EditSession>(scene, SolverOptions{});
    drag.session->converge(1e-3);
    const Discretization& disc = drag.session->discretization();
    InteractiveDisplay display(disc, drag.session->tracer(), SolverOptions{}, displayOptions());
    display.apply(SolutionView::of(drag.session->solver()));
    const CameraRays rays(test::litRoomTopCamera(), kSize, kSize);
    display.warmUp(rays, 1.0);
    display.renderFrame(rays);
    select(drag, display, "slab");
    std::vector<Rgb> atOrigin;
    for (const CachePoint& p : display.cache().points()) atOrigin.push_back(p.colour);
    const Vec3 open(-0.75, -0.8, -0.55);  // no shadow of the shade reaches it
    move(drag, display, "slab", open);

    const Image reference = display.renderReference(rays, 1);
    const RenderCache& cache = display.cache();
    // The slab's top face: each carried point against the reference at its pixel, with its
    // colour now and as it was carried (read before the move: carrying keeps the indices).
    double now = 0, carried = 0, sum = 0;
    int n = 0;
    for (std::size_t i = 0; i < cache.size(); ++i) {
        const CachePoint& p = cache.points()[i];
        if (p.object != drag.preview || !cache.carried(i) || i >= atOrigin.size()) continue;
        if (disc.elements()[p.element].normal.y < 0.9) continue;
        const auto pixel = rays.projectToPixel(p.position);
        if (!pixel) continue;
        const int x = static_cast<int>(pixel->x), y = static_cast<int>(pixel->y);
        if (x < 0 || y < 0 || x >= kSize || y >= kSize) continue;
        const double ref = luminance(reference.at(x, y));
        now += std::abs(luminance(p.colour) - ref);
        carried += std::abs(luminance(atOrigin[i]) - ref);
        sum += ref;
        ++n;
    }
    ASSERT_GT(n, 20) << "the slab's top is in view with its carried points";
    std::printf("carried slab points vs fresh shading: %.4f, as carried %.4f (%d points)\n",
                now / sum, carried / sum, n);
    EXPECT_GT(carried / sum, 0.25) << "the shade darkened the slab where it rested";
    EXPECT_LT(now, 0.4 * carried);
}

// ---------------------------------------------------------------------------------------------
// A frame's holes show the world it began in

TEST(InteractiveDisplayDrag, AFramesHolesShowTheWorldItBeganInNotAMoveMadeMeanwhile) {
    // The editor lets edits in while a frame is reconstructed (beginFrame, reconstructFrame,
    // finishFrame). A move of the dragged slab between the steps must not reach the frame's
    // holes: they are filled in the world its points came from, or the slab shows at its new
    // place in pixels whose points show it at the old one (the body's colour over what it just
    // uncovered). Reference: a second display given the same frame with no move in between.
    Drag drag;
    drag.session = std::make_unique<EditSession>(test::makeLitRoom("red"), SolverOptions{});
    drag.session->converge(1e-3);
    InteractiveDisplayOptions options = displayOptions();
    options.sampleFraction = 0;  // no points: every pixel of the first frame is a hole
    InteractiveDisplay moved(drag.session->discretization(), drag.session->tracer(),
                             SolverOptions{}, options);
    InteractiveDisplay still(drag.session->discretization(), drag.session->tracer(),
                             SolverOptions{}, options);
    const EditEvent began = drag.session->apply(SelectCommand{"slab"});
    drag.origin = began.origin;
    drag.originSubset = RayTracer::SubsetHandle(drag.session->tracer(), {drag.origin});
    drag.previewSubset = RayTracer::SubsetHandle(drag.session->tracer(), {drag.origin});
    for (InteractiveDisplay* d : {&moved, &still}) {
        d->apply(SolutionView::of(drag.session->solver()));
        d->apply(began, {drag.originSubset.visibility(), drag.previewSubset.visibility()});
    }
    const CameraRays rays(test::litRoomTopCamera(), kSize, kSize);
    moved.beginFrame(rays);
    still.beginFrame(rays);
    EXPECT_EQ(moved.framePreview(), drag.origin);
    Image a = moved.reconstructFrame(), b = still.reconstructFrame();
    // The slab moves while the frame is reconstructed; the first display takes the event.
    RayTracer::SubsetHandle keep = std::move(drag.previewSubset);
    move(drag, moved, "slab", kNewPlace);
    moved.finishFrame(rays, a);
    still.finishFrame(rays, b);
    EXPECT_EQ(moved.framePreview(), -1) << "the frame is finished";
    ASSERT_GT(moved.lastFrame().unsampledPixels, std::size_t(kSize * kSize / 2));
    EXPECT_LT(displayRmse(a, b), 1e-12) << "the move reached the frame's holes";
    // The move is visible to the fallback: the next frame's holes show the slab moved.
    moved.beginFrame(rays);
    Image next = moved.reconstructFrame();
    moved.finishFrame(rays, next);
    EXPECT_GT(displayRmse(next, b), 0.01);
}

// ---------------------------------------------------------------------------------------------
// Results shaded at an earlier place of the drag move on with the object

TEST(InteractiveDisplayDrag, ResultsShadedAtAnEarlierPlaceMoveOnWithTheDraggedObject) {
    // An asynchronous display's requests are shaded while the drag goes on: the results on the
    // slab arrive after its next move, on a version no longer shown. They move with it (as its
    // cached points do), stale, rather than going: otherwise a dragged object shows its
    // shading from the drag's start for the whole drag.
    Drag drag;
    drag.session = std::make_unique<EditSession>(test::makeLitRoom("red"), SolverOptions{});
    drag.session->converge(1e-3);
    InteractiveDisplayOptions options = displayOptions();
    options.synchronous = false;
    options.sampleFraction = 0.5;
    const Discretization& disc = drag.session->discretization();
    InteractiveDisplay display(disc, drag.session->tracer(), SolverOptions{}, options);
    display.apply(SolutionView::of(drag.session->solver()));
    select(drag, display, "slab");
    move(drag, display, "slab", 0.5 * kNewPlace);
    const int earlier = drag.preview;
    const CameraRays rays(test::litRoomTopCamera(), kSize, kSize);
    display.renderFrame(rays);  // an empty cache: requests over the view, the slab's among them
    display.shader().waitIdle();
    move(drag, display, "slab", kNewPlace);
    ASSERT_NE(drag.preview, earlier);
    display.renderFrame(rays);  // takes the results shaded at the earlier place

    // Every point on the slab lies on its surface at the new place and waits to be re-shaded.
    const auto& world = disc.objects()[drag.preview].worldPositions;
    Vec3 lo = world.front(), hi = world.front();
    for (const Vec3& p : world) lo = glm::min(lo, p), hi = glm::max(hi, p);
    const RenderCache& cache = display.cache();
    int onSlab = 0;
    for (std::size_t i = 0; i < cache.size(); ++i) {
        if (cache.pointObjects()[i] != drag.preview) continue;
        ++onSlab;
        const Vec3 p = cache.pointPositions()[i];
        EXPECT_TRUE(glm::all(glm::greaterThanEqual(p, lo - Vec3(1e-6))) &&
                    glm::all(glm::lessThanEqual(p, hi + Vec3(1e-6))))
            << "a point off the slab at its new place";
        EXPECT_TRUE(cache.stale(i));
        EXPECT_EQ(disc.elements()[cache.pointElements()[i]].object, drag.preview);
    }
    EXPECT_GT(onSlab, 20) << "the results on the slab went";
}

}  // namespace
}  // namespace penumbra
