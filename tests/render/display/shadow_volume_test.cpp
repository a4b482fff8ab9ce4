// The shadow volumes of a dragged object (render/display/shadow_volume.h) and what the display does
// with them: shaftMeetsBox against brute force (segments to many points of the lamp),
// blockedFraction and lightWeight against closed forms, and a drag in the edge-and-point
// display, where the points whose view of the lamp the move changed go at the next frame and
// the frames after are closer to the new state than a display that keeps them.
//
// Index: helpers · shaftMeetsBox against brute force · blockedFraction, lightWeight · a drag
//        drops the shadowed points

#include "render/display/shadow_volume.h"

#include <gtest/gtest.h>

#include <random>

#include "edit/edit_session.h"
#include "render/camera_rays.h"
#include "render/display/edge_finder.h"
#include "render/display/interactive_display.h"
#include "solver/contour_integral.h"
#include "solver/discretization.h"
#include "solver/ray_tracer.h"
#include "test_scenes.h"

namespace penumbra {
namespace {

// ---------------------------------------------------------------------------------------------
// Helpers

/// Whether the segment a→b meets the box [lo, hi] (slab test).
bool segmentMeetsBox(const Vec3& a, const Vec3& b, const Vec3& lo, const Vec3& hi) {
    double t0 = 0, t1 = 1;
    const Vec3 d = b - a;
    for (int k = 0; k < 3; ++k) {
        if (d[k] == 0) {
            if (a[k] < lo[k] || a[k] > hi[k]) return false;
            continue;
        }
        double ta = (lo[k] - a[k]) / d[k], tb = (hi[k] - a[k]) / d[k];
        if (ta > tb) std::swap(ta, tb);
        t0 = std::max(t0, ta);
        t1 = std::min(t1, tb);
        if (t0 > t1) return false;
    }
    return true;
}

/// Brute force: some segment from x to a point of the convex polygon (a fan of triangles, each
/// sampled on an n × n barycentric grid, edges and vertices included) meets the box.
bool bruteForceMeets(const Vec3& x, const std::vector<Vec3>& polygon, const Vec3& lo,
                     const Vec3& hi, int n = 24) {
    for (std::size_t t = 1; t + 1 < polygon.size(); ++t)
        for (int i = 0; i <= n; ++i)
            for (int j = 0; i + j <= n; ++j) {
                const double u = double(i) / n, v = double(j) / n;
                const Vec3 p = polygon[0] + u * (polygon[t] - polygon[0]) +
                               v * (polygon[t + 1] - polygon[0]);
                if (segmentMeetsBox(x, p, lo, hi)) return true;
            }
    return false;
}

/// A convex polygon: a regular k-gon of radius r about `centre` in the plane with normal `n`,
/// counter-clockwise seen from the side `n` points to.
std::vector<Vec3> regularPolygon(const Vec3& centre, const Vec3& n, double r, int k,
                                 double phase) {
    const Vec3 a = glm::normalize(std::abs(n.x) < 0.9 ? glm::cross(n, Vec3(1, 0, 0))
                                                      : glm::cross(n, Vec3(0, 1, 0)));
    const Vec3 b = glm::cross(n, a);
    std::vector<Vec3> out;
    for (int i = 0; i < k; ++i) {
        const double t = phase + 2 * M_PI * i / k;
        out.push_back(centre + r * (std::cos(t) * a + std::sin(t) * b));
    }
    return out;
}

std::pair<Vec3, Vec3> versionBox(const Discretization& disc, int version) {
    const auto& p = disc.objects()[version].worldPositions;
    Vec3 lo = p.at(0), hi = p.at(0);
    for (const Vec3& q : p) lo = glm::min(lo, q), hi = glm::max(hi, q);
    return {lo, hi};
}

// ---------------------------------------------------------------------------------------------
// shaftMeetsBox against brute force

TEST(ShadowVolume, ShaftTestNeverMissesASegmentThatMeetsTheBox) {
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> u(-1, 1);
    int meets = 0, says = 0, saysButMisses = 0;
    for (int trial = 0; trial < 3000; ++trial) {
        const Vec3 normal = glm::normalize(Vec3(u(rng), u(rng), u(rng)) + Vec3(0, -1.5, 0));
        Light light;
        light.polygon = regularPolygon(Vec3(u(rng), 1.5 + 0.3 * u(rng), u(rng)), normal,
                                       0.1 + 0.4 * std::abs(u(rng)), 3 + trial % 4, u(rng));
        const ShaftLight shaft(light);
        const Vec3 centre(u(rng), 0.3 * u(rng), u(rng));
        const Vec3 half(0.05 + 0.3 * std::abs(u(rng)), 0.05 + 0.3 * std::abs(u(rng)),
                        0.05 + 0.3 * std::abs(u(rng)));
        const Vec3 x(2 * u(rng), -1.5 + 0.5 * std::abs(u(rng)), 2 * u(rng));
        const bool front = glm::dot(x - shaft.centroid, newellNormal(light.polygon)) > 0;
        const bool truth = front && bruteForceMeets(x, light.polygon, centre - half, centre + half);
        const bool test = shaftMeetsBox(x, shaft, centre - half, centre + half);
        meets += truth;
        says += test;
        saysButMisses += test && !truth;
        ASSERT_TRUE(!truth || test) << "trial " << trial << ": a segment from " << x.x << " "
                                    << x.y << " " << x.z << " meets the box, the test says no";
        if (!front) {
            EXPECT_FALSE(test) << "trial " << trial << ": behind the lamp";
        }
    }
    // Both kinds occur, and the conservative test is not trivially "yes".
    EXPECT_GT(meets, 200);
    EXPECT_LT(says, 3000 - 200);
    EXPECT_LT(saysButMisses, says / 4) << "false positives " << saysButMisses << " of " << says;
}

TEST(ShadowVolume, PointLightIsTheSegment) {
    Light light;
    light.polygon = {Vec3(0, 2, 0)};
    const ShaftLight shaft(light);
    const Vec3 lo(-0.1, 0.9, -0.1), hi(0.1, 1.1, 0.1);
    EXPECT_TRUE(shaftMeetsBox(Vec3(0, 0, 0), shaft, lo, hi));         // straight below
    EXPECT_TRUE(shaftMeetsBox(Vec3(0.15, 0, 0.15), shaft, lo, hi));   // inside its shadow
    EXPECT_FALSE(shaftMeetsBox(Vec3(0.25, 0, 0.0), shaft, lo, hi));   // just outside it
    EXPECT_FALSE(shaftMeetsBox(Vec3(0, 1.5, 0), shaft, lo, hi));      // between box and light
}

TEST(ShadowVolume, BlockedFractionAndLightWeight) {
    Light light;
    light.polygon = regularPolygon(Vec3(0, 2, 0), Vec3(0, -1, 0), 0.2, 4, 0.3);
    const ShaftLight shaft(light);
    const Vec3 x(0, 0, 0), n(0, 1, 0);
    // A box hiding the whole lamp, one beside the shaft, one hiding part of it.
    EXPECT_EQ(blockedFraction(x, shaft, Vec3(-0.5, 0.9, -0.5), Vec3(0.5, 1.1, 0.5)), 1.0);
    EXPECT_EQ(blockedFraction(x, shaft, Vec3(1.0, 0.9, -0.5), Vec3(2.0, 1.1, 0.5)), 0.0);
    const double part = blockedFraction(x, shaft, Vec3(0.01, 0.9, -0.5), Vec3(0.5, 1.1, 0.5));
    EXPECT_GT(part, 0.0);
    EXPECT_LT(part, 1.0);
    // A small distant lamp: the form factor from its centroid is Lambert's (contour integral).
    for (const Vec3& at : {Vec3(0, 0, 0), Vec3(1.5, 0.5, -0.7)}) {
        const double exact =
            std::abs(integrateContour(at, n, light.polygon.data(), light.polygon.size())) /
            (2 * M_PI);
        EXPECT_NEAR(lightWeight(at, n, shaft), exact, 0.05 * exact) << at.x;
    }
    EXPECT_EQ(lightWeight(Vec3(0, 3, 0), n, shaft), 0.0) << "behind the lamp";
}

// ---------------------------------------------------------------------------------------------
// A drag drops the shadowed points

/// The lit room's slab selected and moved in a display that has rendered a few frames; the
/// display takes the events and subsets as the editor hands them, and the lighting the solver
/// publishes after the move.
struct DraggedSlab {
    static constexpr int kSize = 96;
    std::unique_ptr<EditSession> session;
    std::unique_ptr<InteractiveDisplay> display;
    CameraRays camera{test::litRoomTopCamera(), kSize, kSize};
    int origin = -1, preview = -1;
    RayTracer::SubsetHandle originOnly, previewOnly;

    explicit DraggedSlab(bool followShadows, bool cull = true) {
        session = std::make_unique<EditSession>(test::makeLitRoom("red"), SolverOptions{});
        session->converge(1e-3);
        InteractiveDisplayOptions options;
        options.width = options.height = kSize;
        options.synchronous = true;
        options.followShadows = followShadows;
        options.shadowDropCull = cull;
        display = std::make_unique<InteractiveDisplay>(
            session->discretization(), session->tracer(), interactiveSolverOptions(), options);
        display->apply(SolutionView::of(session->solver()));
        display->warmUp(camera, 1.0);
        for (int f = 0; f < 3; ++f) (void)display->renderFrame(camera);
        const EditEvent select = session->apply(SelectCommand{"slab"});
        EXPECT_EQ(select.kind, EditEvent::Kind::DragBegan);
        origin = select.origin;
        originOnly = RayTracer::SubsetHandle(session->tracer(), {origin});
        previewOnly = RayTracer::SubsetHandle(session->tracer(), {origin});
        display->apply(select, {originOnly.visibility(), previewOnly.visibility()});
        (void)display->renderFrame(camera);
        TransformCommand t;
        t.id = "slab";
        t.translate = test::kLitRoomSlabDragTarget;
        const EditEvent moved = session->apply(t);
        EXPECT_EQ(moved.kind, EditEvent::Kind::PreviewMoved);
        preview = moved.preview;
        previewOnly = RayTracer::SubsetHandle(session->tracer(), {preview});
        display->apply(moved, {originOnly.visibility(), previewOnly.visibility()});
        display->apply(SolutionView::of(session->solver()));
    }
    /// Brute force: whether a point lies in the slab's old or new shadow volume (segments to
    /// the lamp's polygon against the slab's boxes), not on the slab.
    bool inVolume(const Vec3& position, int object) const {
        if (object == origin || object == preview || object < 0) return false;
        const Discretization& disc = session->discretization();
        const std::vector<Vec3> lamp =
            lightForObject(disc, session->objectVersion("lamp")).polygon;
        for (int v : {origin, preview}) {
            const auto [lo, hi] = versionBox(disc, v);
            if (bruteForceMeets(position, lamp, lo, hi, 12)) return true;
        }
        return false;
    }
    /// Brute force: the share of the lamp the slab hides from a point, before and after the
    /// move, differs by more than `by` (segments to a 12 × 12 grid of each of the lamp's
    /// triangles).
    bool changesBy(const Vec3& position, int object, double by) const {
        if (object == origin || object == preview || object < 0) return false;
        const Discretization& disc = session->discretization();
        const std::vector<Vec3> lamp =
            lightForObject(disc, session->objectVersion("lamp")).polygon;
        const auto [lo0, hi0] = versionBox(disc, origin);
        const auto [lo1, hi1] = versionBox(disc, preview);
        int n = 0, before = 0, after = 0;
        for (std::size_t t = 1; t + 1 < lamp.size(); ++t)
            for (int i = 0; i <= 12; ++i)
                for (int j = 0; i + j <= 12; ++j) {
                    const Vec3 p = lamp[0] + (i / 12.0) * (lamp[t] - lamp[0]) +
                                   (j / 12.0) * (lamp[t + 1] - lamp[0]);
                    ++n;
                    before += segmentMeetsBox(position, p, lo0, hi0);
                    after += segmentMeetsBox(position, p, lo1, hi1);
                }
        return std::abs(before - after) > by * n;
    }
    /// The pixels whose primary hit lies in the volumes.
    std::vector<int> volumePixels() const {
        std::vector<int> out;
        for (int y = 0; y < kSize; ++y)
            for (int x = 0; x < kSize; ++x) {
                const RayHit hit = session->tracer().intersect(
                    camera.origin(), camera.rayDirection(x + 0.5, y + 0.5));
                if (inVolume(hit.position, hit.object)) out.push_back(y * kSize + x);
            }
        return out;
    }
};

/// Relative RMS luminance difference over `pixels`.
double regionError(const Image& image, const Image& reference, const std::vector<int>& pixels) {
    double err = 0, ref = 0;
    for (int k : pixels) {
        const double a = luminance(image.pixels[k]), b = luminance(reference.pixels[k]);
        err += (a - b) * (a - b);
        ref += b * b;
    }
    return ref > 0 ? std::sqrt(err / ref) : 0.0;
}

TEST(ShadowVolume, TheFrameAfterAMoveKeepsNoPointWhoseViewOfTheLampChangedMuch) {
    DraggedSlab drag(true);
    std::size_t changedMuch = 0, inVolume = 0;
    for (const CachePoint& p : drag.display->cache().points()) {
        changedMuch += drag.changesBy(p.position, p.object, 0.3);
        inVolume += drag.inVolume(p.position, p.object);
    }
    ASSERT_GT(changedMuch, 200u) << "the move changes what the floor sees of the lamp";
    const std::size_t pointsBefore = drag.display->cache().size();
    const std::uint64_t frameBefore = drag.display->cache().frame();

    (void)drag.display->renderFrame(drag.camera);
    // Dropped: every point where the slab hides a share of the lamp 0.3 larger or smaller than
    // before (and others on the same elements), not the view wholesale.
    EXPECT_GE(drag.display->lastFrame().droppedShadowed, changedMuch);
    EXPECT_LT(drag.display->lastFrame().droppedShadowed, pointsBefore / 4);
    std::size_t left = 0, reshaded = 0;
    for (const CachePoint& p : drag.display->cache().points()) {
        left += p.frame <= frameBefore && drag.changesBy(p.position, p.object, 0.3);
        reshaded += p.frame > frameBefore && drag.inVolume(p.position, p.object);
    }
    EXPECT_EQ(left, 0u) << "cached points whose view of the lamp changed survived the move";
    // Re-shaded in the frame itself: about one per 5 × 5 pixels of the region.
    const std::size_t region = drag.volumePixels().size();
    EXPECT_GE(reshaded, region / 50) << "of a region of " << region << " pixels";
    std::printf("dropped %zu points (brute force: %zu changed much, %zu in the volumes), %zu "
                "re-shaded in a region of %zu pixels\n",
                drag.display->lastFrame().droppedShadowed, changedMuch, inVolume, reshaded,
                region);
}

TEST(ShadowVolume, CullingTheElementsNoShaftReachesDropsExactlyWhatTestingEveryElementDrops) {
    DraggedSlab culled(true, true), every(true, false);
    const Image a = culled.display->renderFrame(culled.camera);
    const Image b = every.display->renderFrame(every.camera);
    EXPECT_GT(every.display->lastFrame().droppedShadowed, 0u);
    EXPECT_EQ(culled.display->lastFrame().droppedShadowed,
              every.display->lastFrame().droppedShadowed);
    ASSERT_EQ(culled.display->cache().size(), every.display->cache().size());
    for (std::size_t i = 0; i < culled.display->cache().size(); ++i) {
        EXPECT_EQ(culled.display->cache().points()[i].element,
                  every.display->cache().points()[i].element);
        EXPECT_EQ(culled.display->cache().points()[i].colour,
                  every.display->cache().points()[i].colour);
    }
    EXPECT_EQ(a.pixels, b.pixels);
}

TEST(ShadowVolume, TheShadowRegionIsCloserToItsNewStateInTheFramesAfterAMove) {
    // The same drag with and without following the shadows; the region where the floor's view
    // of the lamp changed against a reference of the new state (every pixel shaded by the
    // display's shader, 2 × 2 samples).
    DraggedSlab follow(true), keep(false);
    const std::vector<int> pixels = follow.volumePixels();
    ASSERT_GT(pixels.size(), 500u);
    const Image reference = follow.display->renderReference(follow.camera, 2);
    double errors[2][12];
    for (int f = 0; f < 12; ++f) {
        errors[0][f] = regionError(follow.display->renderFrame(follow.camera), reference, pixels);
        errors[1][f] = regionError(keep.display->renderFrame(keep.camera), reference, pixels);
    }
    for (int f = 0; f < 3; ++f) {
        EXPECT_LT(errors[0][f], errors[1][f])
            << "frame " << f + 1 << " after the move: following the shadows " << errors[0][f]
            << ", keeping the points " << errors[1][f];
        std::printf("frame %d after the move: %.4f (keeping the points: %.4f)\n", f + 1,
                    errors[0][f], errors[1][f]);
    }
    std::printf("frame 12 after the move: %.4f (keeping the points: %.4f)\n", errors[0][11],
                errors[1][11]);
    // From the first frame after the move on, within 1.6 times of where the region settles
    // (its points' noise against the reference): the moved slab's carried points take their
    // change of direct light at once, the floor's shadow follows it.
    EXPECT_LT(errors[0][0], 1.6 * errors[0][11]);
    EXPECT_LT(errors[0][2], 1.6 * errors[0][11]);
}

}  // namespace
}  // namespace penumbra
