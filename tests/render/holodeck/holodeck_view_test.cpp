// A view reopened from a holodeck filled for no view (Ward & Simmons: fill once, then walk
// anywhere inside): HoloHitIndex finds every stored beam with a hit the view can see, and the
// view's points are the shader's radiance at surface points the eye sees, many more than the
// view's own beams hold. A new display's first frame from them is no further from a reference
// than the display's own 30th frame without the holodeck, and taking them while the display
// finds its shadow edges gives the same frame as taking them first.

#include <gtest/gtest.h>

#include <set>

#include "holo_test_support.h"
#include "render/camera_rays.h"
#include "render/display/interactive_display.h"
#include "render/display/point_shader.h"
#include "render/holodeck/holo_server.h"
#include "render/holodeck/holo_view.h"
#include "solver/discretization.h"
#include "solver/progressive_solver.h"
#include "solver/ray_tracer.h"
#include "test_scenes.h"

namespace penumbra {
namespace {

std::string tempFile(const std::string& name) { return test::holoTempFile("holo_view_test", name); }

/// makeLitRoom solved with a point shader (LitRoom), and a holodeck of one interior section
/// batch-filled (every beam in proportion to its volume: no view). The section's floor lies
/// below the room's (walls at ±1.5), as one laid over a scene's bounds may: the rays starting
/// there see the floor's back, black.
struct FilledRoom : test::LitRoom {
    HoloSection section{Vec3(-1.45, -1.55, -1.45), Vec3(2.9, 3.0, 2.9), {4, 4, 4}};
    std::unique_ptr<HoloFile> file;
    std::unique_ptr<HoloServer> server;
    explicit FilledRoom(std::int64_t samples) {
        file = std::make_unique<HoloFile>(tempFile("filled.hdk"), std::vector{section});
        HoloServerOptions so;
        so.packet = 2;
        server = std::make_unique<HoloServer>(*file, shader.get(), so);
        server->fill(server->batchRequests(double(samples)), samples, 0);
    }
};

/// Two views inside the room: down on the floor and the slab, and into a corner.
std::vector<CameraRays> views() {
    Camera corner;
    corner.position = Vec3(0.8, 0.2, 0.9);
    corner.lookAt = Vec3(-1.5, -0.6, -1.5);
    corner.fovDeg = 50;
    return {CameraRays(test::litRoomTopCamera(), 40, 30), CameraRays(corner, 40, 30)};
}

TEST(HoloHitIndex, FindsEveryStoredBeamWithAHitTheViewSees) {
    FilledRoom room(30000);
    const HoloHitIndex index(*room.server);
    const DistanceCode code(room.section.diagonal());
    std::int64_t hits = 0;
    for (const auto& [section, beam] : room.file->storedBeams())
        for (const HoloSample& s : room.server->beam(section, beam)) hits += s.distance != 0xffff;
    EXPECT_EQ(index.hits(), hits);
    for (const CameraRays& view : views()) {
        std::set<std::int64_t> found;
        for (const BeamRequest& r : index.beamsSeenBy(view)) found.insert(r.beam);
        // Brute force: a beam one of whose decoded hits projects into the raster.
        std::int64_t needed = 0;
        for (const auto& [section, beam] : room.file->storedBeams()) {
            bool inView = false;
            for (const HoloSample& s : room.server->beam(section, beam)) {
                if (s.distance == 0xffff) continue;
                const auto pixel =
                    view.projectToPixel(decodeSample(s, room.section, beam, code).hit);
                inView = inView || (pixel && pixel->x >= 0 && pixel->y >= 0 &&
                                    pixel->x < view.width() && pixel->y < view.height());
            }
            if (!inView) continue;
            ++needed;
            EXPECT_TRUE(found.count(beam)) << "beam " << beam << " has a hit in the view";
        }
        EXPECT_GT(needed, 100);
        // The boxes cull: a view inside a room does not need every beam.
        EXPECT_LT(found.size(), index.beams());
    }
}

TEST(HoloHitIndex, AViewShowsTheShadersRadianceWhereTheEyeSeesAStoredHit) {
    FilledRoom room(60000);
    const HoloHitIndex index(*room.server);
    for (const CameraRays& view : views()) {
        const std::vector<ShadedPoint> points =
            index.viewPoints(room.disc, room.tracer, view, 0, 0);
        // The view's own beams (viewRequests) hold a small part of what it can see.
        const std::vector<ShadedPoint> ownBeams =
            holodeckViewPoints(*room.server, viewRequests({room.section}, view, 10, 8, 1.0),
                               room.disc, room.tracer, view, 0, 0);
        const int pixels = view.width() * view.height();
        EXPECT_GE(points.size(), 0.9 * pixels);
        EXPECT_GT(points.size(), 3 * ownBeams.size());
        int deterministic = 0, close = 0;
        std::set<std::pair<int, int>> pixelsTaken;
        for (const ShadedPoint& p : points) {
            EXPECT_TRUE(pixelsTaken.insert({int(p.pixel.x), int(p.pixel.y)}).second)
                << "two points in pixel " << p.pixel.x << ", " << p.pixel.y;
            // The eye sees the point: its ray through it ends there, on the side shown.
            ShadeRequest request;
            request.origin = view.origin();
            request.direction = glm::normalize(p.position - view.origin());
            request.pixel = p.pixel;
            request.frame = 1;
            const ShadedPoint a = room.shader->shade(request);
            ASSERT_LT(glm::length(a.position - p.position), 1e-4 * (1 + glm::length(p.position)));
            EXPECT_GT(glm::dot(p.normal, view.origin() - p.position), 0);
            // Where the shader's shadow sampling does not vary (no penumbra), the radiance is
            // the shader's within the RGBE encoding; never the floor's black back.
            request.frame = 2;
            const ShadedPoint b = room.shader->shade(request);
            if (glm::length(a.radiance - b.radiance) > 1e-12) continue;
            ++deterministic;
            const double largest = std::max({a.radiance.x, a.radiance.y, a.radiance.z});
            close += glm::length(p.radiance - a.radiance) <= 0.02 * largest + 1e-9;
        }
        EXPECT_GT(deterministic, points.size() / 2);
        // The stored sample's own shadow rays saw a penumbra the eye's two did not, at a few.
        EXPECT_GE(close, 0.98 * deterministic);
    }
}

InteractiveDisplayOptions displayOptionsFor(const CameraRays& view) {
    InteractiveDisplayOptions o;
    o.width = view.width();
    o.height = view.height();
    return o;
}

TEST(HoloHitIndex, PointsTakenWhileTheDisplayFindsItsShadowEdgesGiveTheSameFrame) {
    FilledRoom room(60000);
    const HoloHitIndex index(*room.server);
    for (const CameraRays& view : views()) {
        auto firstFrame = [&](bool concurrent, std::size_t& shadowEdges) {
            InteractiveDisplay display(room.disc, room.tracer, room.options,
                                       displayOptionsFor(view));
            display.apply(SolutionView::of(room.solver));
            const std::uint64_t frame = display.nextFrame(), serial = display.shadingSerial();
            auto gather = [&] {
                return index.viewPoints(room.disc, room.tracer, view, frame, serial);
            };
            if (concurrent) {
                EXPECT_FALSE(display.insertShadedFindingEdges(gather).empty());
            } else {
                display.insertShaded(gather());
            }
            const Image image = display.renderFrame(view);
            shadowEdges = display.lastFrame().shadowEdges;
            // Found before the frame, the frame reuses them.
            if (concurrent) {
                EXPECT_EQ(display.lastFrame().times.shadowMs, 0.0);
            }
            return image;
        };
        std::size_t serialEdges = 0, concurrentEdges = 0;
        const Image serial = firstFrame(false, serialEdges);
        const Image concurrent = firstFrame(true, concurrentEdges);
        EXPECT_GT(serialEdges, 0u);
        EXPECT_EQ(concurrentEdges, serialEdges);
        ASSERT_EQ(concurrent.pixels.size(), serial.pixels.size());
        std::size_t differ = 0;
        for (std::size_t k = 0; k < serial.pixels.size(); ++k)
            differ += serial.pixels[k] != concurrent.pixels[k];
        EXPECT_EQ(differ, 0u) << "pixels differing bit for bit of " << serial.pixels.size();
    }
}

TEST(HoloHitIndex, ANewDisplaysFirstFrameFromTheHolodeckIsNoWorseThanItsThirtieth) {
    // A fill for no view holding several samples a pixel of both views.
    FilledRoom room(400000);
    const HoloHitIndex index(*room.server);
    Camera corner;
    corner.position = Vec3(0.8, 0.2, 0.9);
    corner.lookAt = Vec3(-1.5, -0.6, -1.5);
    corner.fovDeg = 50;
    for (const Camera& camera : {test::litRoomTopCamera(), corner}) {
        const CameraRays view(camera, 96, 72);
        // The display alone: its warm-up and 30 frames.
        InteractiveDisplay alone(room.disc, room.tracer, room.options, displayOptionsFor(view));
        alone.apply(SolutionView::of(room.solver));
        alone.warmUp(view);
        Image image = alone.renderFrame(view);
        for (int k = 1; k < 30; ++k) image = alone.renderFrame(view);
        // The reference: 16 samples in every pixel.
        const Image reference = alone.renderReference(view, 4);
        const double error30 = displayRmse(image, reference);
        // A new display's first frame from the holodeck's points.
        InteractiveDisplay display(room.disc, room.tracer, room.options, displayOptionsFor(view));
        display.apply(SolutionView::of(room.solver));
        const std::uint64_t frame = display.nextFrame(), serial = display.shadingSerial();
        const std::vector<ShadedPoint> points = display.insertShadedFindingEdges(
            [&] { return index.viewPoints(room.disc, room.tracer, view, frame, serial); });
        EXPECT_GE(points.size(), 0.9 * view.width() * view.height());
        const double first = displayRmse(display.renderFrame(view), reference);
        EXPECT_LE(first, error30) << "first frame from the holodeck " << first
                                  << ", the display's 30th " << error30 << ", camera at "
                                  << camera.position.x << ", " << camera.position.y << ", "
                                  << camera.position.z;
    }
}

}  // namespace
}  // namespace penumbra
