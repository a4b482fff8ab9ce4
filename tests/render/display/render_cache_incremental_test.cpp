// The render cache's incremental reprojection (RenderCacheOptions::incremental) against the
// whole one: two caches given the same points and the same edits — inserts that merge and
// that replace, drops, relights, carries, stale marks, hidden points — one redoing only the
// changed pixels while the camera stands still, the other everything; after every frame the
// EPI's point arrays, the visible points, the screen list, the priority image and the requests
// must be equal bit for bit.

#include <gtest/gtest.h>

#include <cstring>
#include <functional>
#include <glm/gtc/matrix_transform.hpp>
#include <random>
#include <unordered_set>
#include <vector>

#include "render/camera_rays.h"
#include "render/display/edge_point_image.h"
#include "render/display/render_cache.h"

namespace penumbra {
namespace {

Camera cameraAt(Vec3 position, Vec3 lookAt) {
    Camera c;
    c.name = "test";
    c.position = position;
    c.lookAt = lookAt;
    c.up = Vec3(0, 1, 0);
    c.fovDeg = 50;
    return c;
}

/// Whether two EPIs' point arrays hold the same bits in every pixel; the first difference
/// otherwise.
std::string differingPixel(const EpiPointArrays& a, const EpiPointArrays& b) {
    const std::size_t n = static_cast<std::size_t>(a.width) * a.height;
    for (std::size_t k = 0; k < n; ++k)
        if (std::memcmp(&a.depth[k], &b.depth[k], sizeof(double)) != 0 ||
            std::memcmp(&a.colour[k], &b.colour[k], sizeof(glm::vec3)) != 0 ||
            a.position[k] != b.position[k] || a.trust[k] != b.trust[k])
            return "pixel " + std::to_string(k) + ": depth " + std::to_string(a.depth[k]) + " vs " +
                   std::to_string(b.depth[k]) + ", colour " + std::to_string(a.colour[k].x) +
                   " vs " + std::to_string(b.colour[k].x);
    return "";
}

TEST(RenderCacheIncremental, EqualsTheWholeReprojectionThroughEveryKindOfEdit) {
    const int w = 72, h = 54;
    RenderCacheOptions incrementalOptions;
    incrementalOptions.mergeSamples = 4;
    incrementalOptions.incrementalShare = 0.5;
    RenderCacheOptions wholeOptions = incrementalOptions;
    wholeOptions.incremental = false;
    // Room for about two points a pixel: inserts replace hidden and old points.
    const std::size_t capacity = 2 * w * h;
    RenderCache incremental(w, h, capacity, incrementalOptions),
        whole(w, h, capacity, wholeOptions);
    EdgePointImage epiIncremental(w, h), epiWhole(w, h);
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> u(0.0, 1.0);

    // A wall (object 0, 5 m) and a slab in front of part of it (object 1, 2.5 m): culling and
    // near-equal depths. A point's element is its object and pixel, so that a later sample of
    // the same pixel and surface merges into it.
    auto sample = [&](const CameraRays& rays, std::uint64_t frame) {
        ShadedPoint p;
        const double px = u(rng) * (w + 8) - 4, py = u(rng) * (h + 8) - 4;
        const bool slab = px > 0.3 * w && px < 0.6 * w && py > 0.2 * h && py < 0.7 * h;
        const int object = slab && u(rng) < 0.9 ? 1 : 0;
        const double t = (object ? 2.5 : 5.0) * (1 + 0.003 * u(rng));
        p.pixel = {px, py};
        p.position = rays.origin() + t * rays.rayDirection(px, py);
        p.radiance = Rgb(u(rng), u(rng), 0.3);
        p.object = object;
        p.element = object * 100000 + static_cast<int>(std::floor(px)) +
                    1000 * static_cast<int>(std::floor(py));
        p.frame = frame;
        p.exact = u(rng) < 0.5;
        p.shading = u(rng) < 0.9 ? 1 : 2;
        p.stale = u(rng) < 0.02;
        return p;
    };

    int stillFrames = 0, incrementalFrames = 0;
    std::size_t fewerPixels = 0;
    for (int frame = 0; frame < 48; ++frame) {
        // The camera moves at frames 0, 16 and 32 and stands still in between.
        const int view = frame / 16;
        const CameraRays rays(
            cameraAt(Vec3(0.2 * view, 1 + 0.05 * view, 3), Vec3(0.1 * view, 1, 0)), w, h);
        std::vector<ShadedPoint> batch;
        const int count = frame % 16 == 0 ? w * h : static_cast<int>(0.03 * w * h);
        for (int k = 0; k < count; ++k) batch.push_back(sample(rays, incremental.frame()));
        for (RenderCache* c : {&incremental, &whole}) c->insert(batch);

        // One or two edits a frame, the same on both.
        const int edit = frame % 7;
        if (edit == 1) {
            std::vector<std::uint8_t> drop(incremental.size(), 0);
            for (auto& d : drop) d = u(rng) < 0.03;
            for (RenderCache* c : {&incremental, &whole}) c->invalidatePoints(drop);
        } else if (edit == 2) {
            std::vector<Rgb> delta(200000, Rgb(0.0));
            std::vector<std::uint8_t> stale(200000, 0);
            for (int e = 0; e < 40; ++e) {
                const auto at = static_cast<std::size_t>(u(rng) * 60000);
                delta[at] = Rgb(0.1 * u(rng));
                stale[(at + 7) % 60000] = 1;
            }
            for (RenderCache* c : {&incremental, &whole}) c->relight(delta, stale);
        } else if (edit == 6) {
            // Every element a little brighter (a solution update): colours alone change.
            const std::vector<Rgb> delta(200000, Rgb(0.001 * (1 + frame % 3)));
            for (RenderCache* c : {&incremental, &whole}) c->relight(delta, {});
        } else if (edit == 3) {
            const Mat4 shift = glm::translate(Mat4(1.0), Vec3(0.01 * u(rng), 0.02, 0.0));
            for (RenderCache* c : {&incremental, &whole}) c->carry(1, 1, shift, 0);
        } else if (edit == 4) {
            for (RenderCache* c : {&incremental, &whole}) c->markStale({0});
        } else if (edit == 5) {
            // Points behind a small box that moves with the frame, or none.
            const double x0 = -0.4 + 0.05 * (frame % 16);
            auto hidden = [x0](const Vec3& p, int object) {
                return object == 0 && p.x > x0 && p.x < x0 + 0.3 && p.y > 0.8 && p.y < 1.2;
            };
            for (RenderCache* c : {&incremental, &whole})
                c->setHidden(frame % 2 ? std::function<bool(const Vec3&, int)>(hidden) : nullptr);
        }

        incremental.reproject(rays, epiIncremental.pointArrays());
        whole.reproject(rays, epiWhole.pointArrays());
        ASSERT_FALSE(whole.lastReprojectionIncremental());
        if (frame % 16 >= 2) {
            ++stillFrames;
            if (incremental.lastReprojectionIncremental()) {
                ++incrementalFrames;
                fewerPixels += incremental.lastReprojectedPixels() < std::size_t(w * h) / 2;
            }
        }
        const std::string diff =
            differingPixel(epiIncremental.pointArrays(), epiWhole.pointArrays());
        ASSERT_EQ(diff, "") << "frame " << frame << " (incremental "
                            << incremental.lastReprojectionIncremental() << ")";
        ASSERT_EQ(incremental.visibleCount(), whole.visibleCount()) << "frame " << frame;
        ASSERT_EQ(incremental.pixelPoints(), whole.pixelPoints()) << "frame " << frame;
        ASSERT_EQ(incremental.priority(), whole.priority()) << "frame " << frame;
        ASSERT_EQ(incremental.size(), whole.size());
        for (std::size_t i = 0; i < incremental.size(); ++i) {
            ASSERT_EQ(incremental.visible(i), whole.visible(i)) << "frame " << frame << " " << i;
            ASSERT_EQ(incremental.age(i), whole.age(i)) << i;
        }
        // The screen list, built on demand, on some frames only (the others keep the list
        // pending into the next frame's edits).
        if (frame % 3 == 0) {
            const auto& a = incremental.screenPoints();
            const auto& b = whole.screenPoints();
            ASSERT_EQ(a.size(), b.size()) << "frame " << frame;
            for (std::size_t k = 0; k < a.size(); ++k)
                ASSERT_TRUE(a[k].position == b[k].position && a[k].depth == b[k].depth &&
                            a[k].colour == b[k].colour && a[k].age == b[k].age &&
                            a[k].trust == b[k].trust)
                    << "frame " << frame << " point " << k;
        }
        const auto ra = incremental.requestSamples(rays, 200);
        const auto rb = whole.requestSamples(rays, 200);
        ASSERT_EQ(ra.size(), rb.size()) << "frame " << frame;
        for (std::size_t k = 0; k < ra.size(); ++k)
            ASSERT_TRUE(ra[k].pixel == rb[k].pixel) << "frame " << frame << " request " << k;
    }
    // The comparison means something only when the incremental path ran, on few pixels.
    EXPECT_GE(incrementalFrames, stillFrames * 3 / 4);
    EXPECT_GE(fewerPixels, static_cast<std::size_t>(incrementalFrames) / 2);
}

TEST(RenderCacheIncremental, AMovedCameraOrOtherArraysReprojectWhole) {
    const int w = 32, h = 24;
    RenderCache cache(w, h, 4 * w * h);
    EdgePointImage epi(w, h), other(w, h);
    const CameraRays still(cameraAt(Vec3(0, 1, 3), Vec3(0, 1, 0)), w, h);
    const CameraRays moved(cameraAt(Vec3(0.1, 1, 3), Vec3(0, 1, 0)), w, h);
    std::vector<ShadedPoint> batch;
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            ShadedPoint p;
            p.position = still.origin() + 5.0 * still.rayDirection(x + 0.5, y + 0.5);
            p.radiance = Rgb(0.5);
            p.object = 0;
            p.element = x + 100 * y;
            batch.push_back(p);
        }
    cache.insert(batch);
    cache.reproject(still, epi.pointArrays());  // a new view: whole
    EXPECT_FALSE(cache.lastReprojectionIncremental());
    cache.reproject(still, epi.pointArrays());  // still, but nothing kept yet: whole, keeps
    EXPECT_FALSE(cache.lastReprojectionIncremental());
    cache.reproject(still, epi.pointArrays());
    EXPECT_TRUE(cache.lastReprojectionIncremental());
    EXPECT_EQ(cache.lastReprojectedPixels(), 0u);  // nothing changed
    EXPECT_EQ(cache.visibleCount(), static_cast<std::size_t>(w * h));
    cache.reproject(still, other.pointArrays());
    EXPECT_FALSE(cache.lastReprojectionIncremental());
    cache.reproject(moved, other.pointArrays());
    EXPECT_FALSE(cache.lastReprojectionIncremental());
}

TEST(RenderCacheIncremental, CarryAndDropLeaveThePendingScreenListAsTheReprojectionShowedIt) {
    // A reprojection into an EPI leaves the screen point list to be built on demand. A carry
    // (a drag step) then moves points the list shows, and a drop removes some and renumbers
    // the rest: the list built after them must show the points where the reprojection saw
    // them, as the list built before the edits does, bit for bit, also after a merge changed
    // some of the same points first.
    const int w = 40, h = 30;
    const CameraRays rays(cameraAt(Vec3(0, 1, 3), Vec3(0, 1, 0)), w, h);
    std::mt19937 rng(11);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    std::vector<ShadedPoint> batch;
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            // A slab (object 1) before a wall (object 0) over the middle of the view.
            const bool slab = x > 10 && x < 28 && y > 6 && y < 22;
            ShadedPoint p;
            p.pixel = {x + 0.5, y + 0.5};
            p.position = rays.origin() + (slab ? 2.5 : 5.0) * rays.rayDirection(x + 0.5, y + 0.5);
            p.radiance = Rgb(u(rng), u(rng), 0.3);
            p.object = slab ? 1 : 0;
            p.element = (slab ? 100000 : 0) + x + 1000 * y;
            p.shading = 1;
            batch.push_back(p);
        }
    // A later sample of some slab pixels under other lighting: it replaces their record.
    std::vector<ShadedPoint> later;
    for (const ShadedPoint& p : batch)
        if (p.object == 1 && u(rng) < 0.3) {
            ShadedPoint q = p;
            q.radiance = Rgb(0.9, 0.1, 0.1);
            q.shading = 2;
            q.frame = 1;
            later.push_back(q);
        }
    const Mat4 move = glm::translate(Mat4(1.0), Vec3(0.07, 0.03, 0.0));
    RenderCache built(w, h, 4 * w * h), pending(w, h, 4 * w * h);
    EdgePointImage epiBuilt(w, h), epiPending(w, h);
    for (auto [cache, epi] : {std::pair{&built, &epiBuilt}, std::pair{&pending, &epiPending}}) {
        cache->insert(batch);
        cache->reproject(rays, epi->pointArrays());
        cache->insert(later);
    }
    // Then a drop of some points of both objects (a drag's shadow drop), which renumbers the
    // survivors, and a second carry of the renumbered points.
    std::vector<std::uint8_t> drop(built.size(), 0);
    for (auto& d : drop) d = u(rng) < 0.2;
    ASSERT_FALSE(built.screenPoints().empty());  // the list built before the edits
    ASSERT_GT(built.carry(1, 1, move, 0), 0u);
    ASSERT_GT(pending.carry(1, 1, move, 0), 0u);
    const std::size_t dropped = built.invalidatePoints(drop);
    ASSERT_GT(dropped, 0u);
    ASSERT_EQ(pending.invalidatePoints(drop), dropped);
    ASSERT_GT(built.carry(1, 1, move, 0), 0u);
    ASSERT_GT(pending.carry(1, 1, move, 0), 0u);
    const auto& a = built.screenPoints();
    const auto& b = pending.screenPoints();
    ASSERT_EQ(a.size(), b.size());
    for (std::size_t k = 0; k < a.size(); ++k)
        ASSERT_TRUE(a[k].position == b[k].position && a[k].depth == b[k].depth &&
                    a[k].colour == b[k].colour && a[k].age == b[k].age && a[k].trust == b[k].trust)
            << "screen point " << k;
    EXPECT_EQ(built.priority(), pending.priority());
    // And both reproject the moved points alike.
    built.reproject(rays, epiBuilt.pointArrays());
    pending.reproject(rays, epiPending.pointArrays());
    EXPECT_EQ(differingPixel(epiBuilt.pointArrays(), epiPending.pointArrays()), "");
}

}  // namespace
}  // namespace penumbra
