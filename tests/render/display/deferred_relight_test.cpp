// InteractiveDisplayOptions::deferRelight against relighting at once: two synchronous displays
// of the lit room told the same drag (several positions and solutions between two frames, as
// the editor's display is told them), one relighting at every position and solution, one once
// per frame. The changes add up, so after every frame both caches hold the same points with
// the same colours; the deferred display's positions relight nothing until the frame.

#include <gtest/gtest.h>

#include <algorithm>
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

constexpr int kSize = 128;

/// The largest difference between the two caches' point colours, relative to the brighter
/// colour (at least 0.01); the caches must hold the same points in the same order.
double largestColourDifference(const RenderCache& a, const RenderCache& b) {
    EXPECT_EQ(a.points().size(), b.points().size());
    double worst = 0;
    for (std::size_t i = 0; i < std::min(a.points().size(), b.points().size()); ++i) {
        const CachePoint& p = a.points()[i];
        const CachePoint& q = b.points()[i];
        EXPECT_EQ(p.position, q.position) << i;
        EXPECT_EQ(p.element, q.element) << i;
        const double scale = std::max({0.01, glm::length(p.colour), glm::length(q.colour)});
        worst = std::max(worst, glm::length(p.colour - q.colour) / scale);
    }
    return worst;
}

TEST(DeferredRelight, ADragRelitOncePerFrameEndsWithTheColoursOfRelightingAtEveryChange) {
    EditSession session(test::makeLitRoom("red"), SolverOptions{});
    session.converge(1e-3);
    const int origin = session.objectVersion("slab");
    session.apply(SelectCommand{"slab"});

    // No new samples: the caches change only through the drag, the relights and the drop.
    InteractiveDisplayOptions eager = test::litRoomDisplayOptions(kSize);
    eager.sampleFraction = 0;
    eager.changedSampleFraction = 0;
    InteractiveDisplayOptions deferred = eager;
    deferred.deferRelight = true;
    InteractiveDisplay a(session.discretization(), session.tracer(), SolverOptions{}, eager);
    InteractiveDisplay b(session.discretization(), session.tracer(), SolverOptions{}, deferred);
    const CameraRays rays(test::litRoomTopCamera(), kSize, kSize);
    for (InteractiveDisplay* d : {&a, &b}) {
        d->apply(SolutionView::of(session.solver()));
        d->warmUp(rays, 1.0);
        (void)d->renderFrame(rays);
    }
    ASSERT_LT(largestColourDifference(a.cache(), b.cache()), 1e-9);

    RayTracer::SubsetHandle originSubset(session.tracer(), {origin});
    std::vector<std::unique_ptr<RayTracer::SubsetHandle>> subsets;
    int previous = origin;
    std::size_t eagerRelit = 0, deferredRelit = 0;
    double worst = 0;
    for (int frame = 0; frame < 3; ++frame) {
        // Three positions a frame, each followed by the solver's lighting of it.
        for (int step = 1; step <= 3; ++step) {
            TransformCommand t;
            t.id = "slab";
            t.translate = test::kLitRoomSlabDragTarget * (0.05 * (3 * frame + step));
            const int preview = session.apply(t).preview;
            session.solve(10);
            subsets.push_back(std::make_unique<RayTracer::SubsetHandle>(session.tracer(),
                                                                        std::vector<int>{preview}));
            const EditEvent event = previous == origin ? test::dragBeganEvent(origin, preview)
                                                       : test::previewMovedEvent(origin, preview);
            const InteractiveDisplay::DragVisibility drag{originSubset.visibility(),
                                                          subsets.back()->visibility()};
            const std::size_t na = a.apply(event, drag, &session.solver());
            const std::size_t nb = b.apply(event, drag, &session.solver());
            if (event.kind == EditEvent::Kind::PreviewMoved) {
                // The deferred display carried the slab's points and relit none.
                EXPECT_LE(nb, na);
                eagerRelit += na;
                deferredRelit += nb;
            }
            a.apply(SolutionView::of(session.solver()));
            EXPECT_EQ(b.apply(SolutionView::of(session.solver())), 0u);
            previous = preview;
        }
        (void)a.renderFrame(rays);
        (void)b.renderFrame(rays);
        worst = std::max(worst, largestColourDifference(a.cache(), b.cache()));
    }
    EXPECT_GT(eagerRelit, deferredRelit) << "the eager display relit points at the positions";
    EXPECT_LT(worst, 1e-9);

    // Dropped: relit at once by both, and still equal after the next frame.
    const EditEvent drop = session.apply(UnselectCommand{});
    RayTracer::SubsetHandle dropped(session.tracer(), {previous});
    for (InteractiveDisplay* d : {&a, &b})
        d->apply(drop, {originSubset.visibility(), dropped.visibility()}, &session.solver());
    (void)a.renderFrame(rays);
    (void)b.renderFrame(rays);
    EXPECT_LT(largestColourDifference(a.cache(), b.cache()), 1e-9);
}

}  // namespace
}  // namespace penumbra
