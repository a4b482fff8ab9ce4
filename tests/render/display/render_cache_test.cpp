// The render cache (Walter et al. 1999 as Bala et al. 2003 §4.3 use it): reprojection checked
// against CameraRays::projectToPixel and a brute-force nearest-point search, depth culling of a
// hidden point, invalidation against brute-force filters, the capacity and replacement rule, and
// the priority-driven requests; finally the cache fed by the real point shader.
//
// Index: helpers · reprojection · depth culling · invalidation · capacity · requests ·
//        with the point shader

#include "render/display/render_cache.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <map>
#include <numeric>
#include <random>
#include <set>
#include <unordered_set>
#include <vector>

#include "render/camera_rays.h"
#include "render/display/edge_point_image.h"
#include "render/display/point_shader.h"
#include "solver/discretization.h"
#include "solver/progressive_solver.h"
#include "solver/ray_tracer.h"
#include "test_scenes.h"

namespace penumbra {
namespace {

// ---------------------------------------------------------------------------------------------
// Helpers

Camera cameraAt(Vec3 position, Vec3 lookAt, double fovDeg = 50) {
    Camera c;
    c.name = "test";
    c.position = position;
    c.lookAt = lookAt;
    c.up = Vec3(0, 1, 0);
    c.fovDeg = fovDeg;
    return c;
}

/// A point on the ray through pixel coordinates (px, py) at distance t.
ShadedPoint pointOnRay(const CameraRays& rays, double px, double py, double t, int object = 0,
                       Rgb colour = Rgb(0.5)) {
    ShadedPoint p;
    p.pixel = {px, py};
    p.position = rays.origin() + t * rays.rayDirection(px, py);
    p.radiance = colour;
    p.object = object;
    p.element = object * 1000 + static_cast<int>(px) + 100 * static_cast<int>(py);
    return p;
}

/// One point per pixel centre of a `w` × `h` raster, on a wall 5 m away (object 0).
std::vector<ShadedPoint> wallPoints(const CameraRays& rays) {
    std::vector<ShadedPoint> out;
    for (int y = 0; y < rays.height(); ++y)
        for (int x = 0; x < rays.width(); ++x)
            out.push_back(
                pointOnRay(rays, x + 0.5, y + 0.5,
                           5.0 / glm::dot(rays.rayDirection(x + 0.5, y + 0.5), rays.forward())));
    return out;
}

std::string str(const glm::dvec2& p) {
    return "(" + std::to_string(p.x) + ", " + std::to_string(p.y) + ")";
}

// ---------------------------------------------------------------------------------------------
// Reprojection

TEST(RenderCache, UnchangedCameraPutsEveryPointBackInItsPixel) {
    const CameraRays rays(cameraAt(Vec3(0, 1, 3), Vec3(0, 1, 0)), 40, 30);
    RenderCache cache(40, 30, 4000);
    cache.insert(wallPoints(rays));
    ASSERT_EQ(cache.size(), 1200u);
    for (int frame = 0; frame < 2; ++frame) {
        const auto& screen = cache.reproject(rays);
        ASSERT_EQ(screen.size(), 1200u) << cache.toString();
        for (int y = 0; y < 30; ++y)
            for (int x = 0; x < 40; ++x) {
                const ScreenPoint& s = screen[y * 40 + x];
                EXPECT_NEAR(s.position.x, x + 0.5, 1e-9) << "pixel " << x << ", " << y;
                EXPECT_NEAR(s.position.y, y + 0.5, 1e-9) << "pixel " << x << ", " << y;
                EXPECT_NEAR(s.depth, 5.0, 1e-9);
                EXPECT_EQ(s.age, frame) << "ages grow by one per frame";
                const int i = cache.pixelPoints()[y * 40 + x];
                ASSERT_GE(i, 0);
                EXPECT_NEAR(cache.points()[i].position.z, -2.0, 1e-9) << "on the wall z = -2";
            }
    }
}

TEST(RenderCache, TranslatedCameraMatchesProjectToPixelAndKeepsTheNearest) {
    const CameraRays before(cameraAt(Vec3(0, 1, 3), Vec3(0, 1, 0)), 48, 36);
    RenderCache cache(48, 36, 8000);
    // Two surfaces: the wall, and a nearer box-ish patch of points 2 m in front of it.
    std::vector<ShadedPoint> points = wallPoints(before);
    for (int y = 10; y < 20; ++y)
        for (int x = 14; x < 30; ++x)
            points.push_back(pointOnRay(before, x + 0.5, y + 0.5, 3.0, 1));
    cache.insert(points);
    cache.reproject(before);

    const CameraRays after(cameraAt(Vec3(0.4, 1.2, 3.3), Vec3(0.4, 1.2, 0.3)), 48, 36);
    const auto& screen = cache.reproject(after);
    ASSERT_GT(screen.size(), 800u);
    // Brute force: the nearest point projecting into each pixel.
    std::map<int, double> nearest;
    for (const CachePoint& p : cache.points()) {
        const auto q = after.projectToPixel(p.position);
        if (!q || q->x < 0 || q->y < 0 || q->x >= 48 || q->y >= 36) continue;
        const int k = static_cast<int>(q->y) * 48 + static_cast<int>(q->x);
        const double d = glm::dot(p.position - after.origin(), after.forward());
        if (!nearest.count(k) || d < nearest[k]) nearest[k] = d;
    }
    int checked = 0;
    for (int k = 0; k < 48 * 36; ++k) {
        const int i = cache.pixelPoints()[k];
        if (i < 0) continue;
        const CachePoint& p = cache.points()[i];
        const auto q = after.projectToPixel(p.position);
        ASSERT_TRUE(q.has_value());
        EXPECT_EQ(static_cast<int>(q->y) * 48 + static_cast<int>(q->x), k) << p.toString();
        const double d = glm::dot(p.position - after.origin(), after.forward());
        EXPECT_LE(d, nearest.at(k) * 1.01) << "pixel " << k << " keeps the nearest point";
        ++checked;
    }
    ASSERT_EQ(static_cast<std::size_t>(checked), screen.size());
    for (const ScreenPoint& s : screen) {
        const int k = static_cast<int>(s.position.y) * 48 + static_cast<int>(s.position.x);
        const CachePoint& p = cache.points()[cache.pixelPoints()[k]];
        const auto q = after.projectToPixel(p.position);
        EXPECT_NEAR(glm::length(s.position - *q), 0, 1e-12) << str(s.position);
        EXPECT_NEAR(s.depth, glm::dot(p.position - after.origin(), after.forward()), 1e-12);
    }
    // Wall pixels that show through where the near patch used to be are few: the near points
    // won almost everywhere they project.
    int nearShown = 0;
    for (const ScreenPoint& s : screen) nearShown += s.depth < 4.0;
    EXPECT_GT(nearShown, 100);
}

// ---------------------------------------------------------------------------------------------
// Depth culling

TEST(RenderCache, PointBehindANearerSurfacesPointsIsDiscarded) {
    const CameraRays rays(cameraAt(Vec3(0, 0, 5), Vec3(0, 0, 0)), 32, 32);
    RenderCache cache(32, 32, 4000);
    // A near surface (object 1) with a one-pixel hole at (10, 10) and a far point (object 2)
    // seen through the hole; a second far point (object 3) with only far neighbours.
    std::vector<ShadedPoint> points;
    for (int y = 0; y < 16; ++y)
        for (int x = 0; x < 16; ++x)
            if (x != 10 || y != 10) points.push_back(pointOnRay(rays, x + 0.5, y + 0.5, 2.0, 1));
    points.push_back(pointOnRay(rays, 10.5, 10.5, 4.0, 2));
    for (int y = 20; y < 30; ++y)
        for (int x = 20; x < 30; ++x) points.push_back(pointOnRay(rays, x + 0.5, y + 0.5, 4.0, 3));
    // Far points (object 4) right beside the near surface's silhouette at x = 16.
    for (int y = 0; y < 16; ++y)
        for (int x = 16; x < 19; ++x) points.push_back(pointOnRay(rays, x + 0.5, y + 0.5, 4.0, 4));
    cache.insert(points);
    cache.reproject(rays);
    EXPECT_EQ(cache.pixelPoints()[10 * 32 + 10], -1) << "the hidden far point is culled";
    for (int y = 0; y < 16; ++y)
        EXPECT_GE(cache.pixelPoints()[y * 32 + 16], 0)
            << "background beside a silhouette, row " << y;
    for (std::size_t i = 0; i < cache.size(); ++i)
        if (cache.points()[i].object == 2) {
            EXPECT_FALSE(cache.visible(i)) << cache.points()[i].toString();
        }
    EXPECT_GE(cache.pixelPoints()[25 * 32 + 25], 0) << "far points among far points stay";
    int far = 0;
    for (const ScreenPoint& s : cache.screenPoints()) far += s.depth > 3;
    EXPECT_EQ(far, 100 + 48) << "every object-3 and object-4 point is visible";
    EXPECT_EQ(cache.size(), points.size()) << "culled points stay cached";

    // Without the margin test (margin huge) the hole shows the far point.
    RenderCacheOptions loose;
    loose.depthMargin = 10;
    RenderCache plain(32, 32, 4000, loose);
    plain.insert(points);
    plain.reproject(rays);
    EXPECT_GE(plain.pixelPoints()[10 * 32 + 10], 0);
}

// ---------------------------------------------------------------------------------------------
// Parallel reprojection equals the serial reference

TEST(RenderCache, ParallelReprojectionEqualsSerialBitForBit) {
    // Two surfaces (a wall and a nearer slab, so culling and near-equal depth ties happen),
    // several points per pixel of different ages, points behind the camera and off screen, a
    // full cache (replacement), a moving camera.
    const int w = 96, h = 67;
    const CameraRays first(cameraAt(Vec3(0, 1, 3), Vec3(0, 1, 0)), w, h);
    RenderCacheOptions serialOptions;
    serialOptions.parallel = false;
    RenderCache parallel(w, h, 3 * w * h), serial(w, h, 3 * w * h, serialOptions);
    std::mt19937 rng(11);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    auto batch = [&](const CameraRays& rays, int count) {
        std::vector<ShadedPoint> out;
        for (int k = 0; k < count; ++k) {
            const double px = u(rng) * (w + 20) - 10, py = u(rng) * (h + 20) - 10;
            const double t = u(rng) < 0.3 ? 2.5 + 0.02 * u(rng) : 5.0 + 0.04 * u(rng);
            out.push_back(pointOnRay(rays, px, py, u(rng) < 0.02 ? -1.0 : t, t < 3 ? 1 : 0,
                                     Rgb(u(rng), u(rng), 0.3)));
        }
        return out;
    };
    std::size_t checkedScreen = 0, requests = 0;
    for (int frame = 0; frame < 12; ++frame) {
        const double a = 0.05 * frame;
        const CameraRays rays(
            cameraAt(Vec3(0.3 * std::sin(a), 1 + 0.1 * a, 3 - 0.2 * a), Vec3(0.1 * a, 1, 0)), w, h);
        const std::vector<ShadedPoint> points = batch(frame == 0 ? first : rays, 2 * w * h);
        parallel.insert(points);
        serial.insert(points);
        const auto& sp = parallel.reproject(rays);
        const auto& ss = serial.reproject(rays);
        ASSERT_EQ(sp.size(), ss.size()) << "frame " << frame;
        for (std::size_t k = 0; k < sp.size(); ++k) {
            ASSERT_TRUE(sp[k].position == ss[k].position && sp[k].depth == ss[k].depth &&
                        sp[k].colour == ss[k].colour && sp[k].age == ss[k].age)
                << "frame " << frame << " point " << k << ": " << sp[k].toString() << " vs "
                << ss[k].toString();
        }
        checkedScreen += sp.size();
        ASSERT_EQ(parallel.pixelPoints(), serial.pixelPoints()) << "frame " << frame;
        ASSERT_EQ(parallel.priority(), serial.priority()) << "frame " << frame;
        ASSERT_EQ(parallel.size(), serial.size());
        for (std::size_t i = 0; i < parallel.size(); ++i) {
            ASSERT_EQ(parallel.age(i), serial.age(i)) << i;
            ASSERT_EQ(parallel.visible(i), serial.visible(i)) << i;
        }
        // Requests (tiles in parallel, one random stream): the default budget, then a second
        // call in the same frame (held-back pixels) with a budget over the remaining pixels.
        for (int budget : {-1, frame % 3 == 0 ? 3 * w * h : 97}) {
            const auto rp = parallel.requestSamples(rays, budget);
            const auto rs = serial.requestSamples(rays, budget);
            ASSERT_EQ(rp.size(), rs.size()) << "frame " << frame << " budget " << budget;
            for (std::size_t k = 0; k < rp.size(); ++k) {
                ASSERT_TRUE(rp[k].pixel == rs[k].pixel && rp[k].origin == rs[k].origin &&
                            rp[k].direction == rs[k].direction && rp[k].frame == rs[k].frame)
                    << "frame " << frame << " request " << k << ": " << rp[k].toString() << " vs "
                    << rs[k].toString();
            }
            requests += rs.size();
        }
    }
    EXPECT_GT(requests, static_cast<std::size_t>(w * h));
    EXPECT_GT(checkedScreen, static_cast<std::size_t>(5 * w * h));
}

TEST(RenderCache, ReprojectionIntoTheEpiEqualsPlacingItsScreenPoints) {
    // reproject(camera, EpiPointArrays) against reproject(camera) whose list EdgePointImage::
    // build places: the same EPI (point arrays, classification, reconstruction) bit for bit,
    // parallel and serial; the list built on demand equal to the one written at once, also
    // when an insert then replaces visible points (a cache too small for its hidden points)
    // and after an invalidation; the same priorities.
    const int w = 64, h = 48;
    RenderCacheOptions serialOptions;
    serialOptions.parallel = false;
    const std::size_t capacity = 2 * w * h;
    RenderCache listed(w, h, capacity), intoEpi(w, h, capacity),
        serial(w, h, capacity, serialOptions);
    EdgePointImage epiListed(w, h), epiInto(w, h), epiSerial(w, h);
    std::mt19937 rng(5);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    std::size_t compared = 0, replacedVisible = 0;
    for (int frame = 0; frame < 10; ++frame) {
        const double a = 0.07 * frame;
        const CameraRays rays(
            cameraAt(Vec3(0.4 * std::sin(a), 1 + 0.1 * a, 3 - 0.1 * a), Vec3(0.1 * a, 1, 0)), w, h);
        std::vector<ShadedPoint> batch;
        for (int k = 0; k < w * h; ++k) {
            const double t = u(rng) < 0.3 ? 2.5 + 0.02 * u(rng) : 5.0 + 0.04 * u(rng);
            ShadedPoint p = pointOnRay(rays, u(rng) * (w + 10) - 5, u(rng) * (h + 10) - 5, t,
                                       t < 3 ? 1 : 0, Rgb(u(rng), u(rng), 0.3));
            if (k % 997 == 0) p.radiance.y = std::numeric_limits<double>::quiet_NaN();
            batch.push_back(p);
        }
        for (RenderCache* c : {&listed, &intoEpi, &serial}) c->insert(batch);
        std::vector<ScreenEdge> edges;
        for (int e = 0; e < 20; ++e) {
            ScreenEdge edge;
            edge.a = {u(rng) * w, u(rng) * h};
            edge.b = {u(rng) * w, u(rng) * h};
            edge.depthA = edge.depthB = 2 + 4 * u(rng);
            edges.push_back(edge);
        }
        epiListed.build(edges, listed.reproject(rays));
        intoEpi.reproject(rays, epiInto.pointArrays());
        epiInto.build(edges);
        serial.reproject(rays, epiSerial.pointArrays());
        epiSerial.build(edges);
        ASSERT_EQ(intoEpi.visibleCount(), listed.screenPoints().size());
        ASSERT_EQ(intoEpi.priority(), listed.priority()) << "frame " << frame;
        ASSERT_EQ(serial.priority(), listed.priority()) << "frame " << frame;
        for (int y = 0; y < h; ++y)
            for (int x = 0; x < w; ++x)
                for (const EdgePointImage* epi : {&epiInto, &epiSerial}) {
                    ASSERT_EQ(epi->samplePosition(x, y), epiListed.samplePosition(x, y))
                        << "frame " << frame << " pixel " << x << "," << y;
                    ASSERT_EQ(epi->sampleColour(x, y), epiListed.sampleColour(x, y));
                    ASSERT_EQ(epi->pixelClass(x, y), epiListed.pixelClass(x, y));
                }
        const Image reference = epiListed.reconstruct(true);
        for (EdgePointImage* epi : {&epiInto, &epiSerial}) {
            const Image image = epi->reconstruct(true);
            ASSERT_EQ(image.pixels, reference.pixels) << "frame " << frame;
        }
        // The list on demand: after an insert that replaces hidden points only (the list
        // stays pending), or one that replaces visible points, or after an invalidation.
        const std::vector<ScreenPoint> expected = listed.screenPoints();
        if (frame % 3 == 0) {
            std::vector<ShadedPoint> few(batch.begin(), batch.begin() + 50);
            std::size_t hidden = 0;
            for (std::size_t i = 0; i < intoEpi.size(); ++i) hidden += !intoEpi.visible(i);
            ASSERT_GT(hidden, few.size());
            for (RenderCache* c : {&listed, &intoEpi, &serial}) c->insert(few);
        } else if (frame % 3 == 1) {
            std::vector<ShadedPoint> more = batch;  // hidden and visible points replaced
            more.insert(more.end(), batch.begin(), batch.begin() + capacity / 4);
            std::size_t hidden = 0;
            for (std::size_t i = 0; i < intoEpi.size(); ++i) hidden += !intoEpi.visible(i);
            replacedVisible += more.size() > hidden;
            intoEpi.insert(more);
            listed.insert(more);
            serial.insert(more);
        } else if (frame % 3 == 2) {
            for (RenderCache* c : {&listed, &intoEpi, &serial})
                EXPECT_GT(c->invalidateRegion(Vec3(0, 1, 0), 0.5), 0u);
        }
        if (frame == 9)
            for (RenderCache* c : {&listed, &intoEpi, &serial}) c->clear();
        for (const RenderCache* c : {&intoEpi, &serial}) {
            const std::vector<ScreenPoint>& built = c->screenPoints();
            ASSERT_EQ(built.size(), expected.size()) << "frame " << frame;
            for (std::size_t k = 0; k < built.size(); ++k)
                ASSERT_TRUE(
                    built[k].position == expected[k].position &&
                    built[k].depth == expected[k].depth &&
                    (built[k].colour == expected[k].colour || std::isnan(expected[k].colour.y)) &&
                    built[k].age == expected[k].age)
                    << "frame " << frame << " point " << k << ": " << built[k].toString() << " vs "
                    << expected[k].toString();
            compared += built.size();
        }
        // Bit for bit (the NaN colours make == unfit).
        const Image mine = intoEpi.interpolatedImage(), theirs = listed.interpolatedImage();
        ASSERT_EQ(std::memcmp(mine.pixels.data(), theirs.pixels.data(),
                              mine.pixels.size() * sizeof(Rgb)),
                  0)
            << "frame " << frame;
    }
    EXPECT_GT(compared, static_cast<std::size_t>(10 * w * h));
    EXPECT_GT(replacedVisible, 0u) << "an insert replaced visible points of a pending list";

    // The list version after the EPI one gives the list's points again.
    const CameraRays rays(cameraAt(Vec3(0.1, 1, 3), Vec3(0, 1, 0)), w, h);
    std::vector<ShadedPoint> batch;
    for (int k = 0; k < w * h; ++k)
        batch.push_back(pointOnRay(rays, u(rng) * w, u(rng) * h, 4.0 + u(rng), 0));
    listed.insert(batch);
    intoEpi.insert(batch);
    intoEpi.reproject(rays, epiInto.pointArrays());
    listed.reproject(rays);
    const std::vector<ScreenPoint> a = intoEpi.reproject(rays);
    const std::vector<ScreenPoint> b = listed.reproject(rays);
    ASSERT_EQ(a.size(), b.size());
    for (std::size_t k = 0; k < a.size(); ++k)
        ASSERT_TRUE(a[k].position == b[k].position && a[k].depth == b[k].depth &&
                    a[k].colour == b[k].colour && a[k].age == b[k].age)
            << k;

    // Arrays of another raster are refused.
    EdgePointImage other(w + 1, h);
    EXPECT_THROW(intoEpi.reproject(rays, other.pointArrays()), std::invalid_argument);
}

// ---------------------------------------------------------------------------------------------
// Invalidation

TEST(RenderCache, InvalidationRemovesExactlyTheMatchingPoints) {
    const CameraRays rays(cameraAt(Vec3(0, 0, 5), Vec3(0, 0, 0)), 20, 20);
    std::vector<ShadedPoint> points;
    for (int y = 0; y < 20; ++y)
        for (int x = 0; x < 20; ++x)
            points.push_back(pointOnRay(rays, x + 0.5, y + 0.5, 3.0 + 0.1 * (x % 3), (x + y) % 5));
    RenderCache cache(20, 20, 1000);
    cache.insert(points);

    const std::unordered_set<int> gone{1, 3};
    std::multiset<int> expected;
    for (const ShadedPoint& p : points)
        if (!gone.count(p.object)) expected.insert(p.element);
    EXPECT_EQ(cache.invalidateObjects(gone), points.size() - expected.size());
    std::multiset<int> left;
    for (const CachePoint& p : cache.points()) left.insert(p.element);
    EXPECT_EQ(left, expected);

    // A sphere: brute force over what is left.
    const Vec3 centre = rays.origin() + 3.0 * rays.rayDirection(10, 10);
    std::size_t inside = 0;
    for (const CachePoint& p : cache.points()) inside += glm::length(p.position - centre) <= 0.4;
    ASSERT_GT(inside, 0u);
    EXPECT_EQ(cache.invalidateRegion(centre, 0.4), inside);
    for (const CachePoint& p : cache.points()) EXPECT_GT(glm::length(p.position - centre), 0.4);

    // Elements.
    const int e0 = cache.points()[0].element, e1 = cache.points()[5].element;
    std::size_t matching = 0;
    for (const CachePoint& p : cache.points()) matching += p.element == e0 || p.element == e1;
    EXPECT_EQ(cache.invalidateElements({e0, e1}), matching);

    // The next frame shows only what is left.
    cache.reproject(rays);
    EXPECT_EQ(cache.screenPoints().size(), cache.size());
    cache.clear();
    EXPECT_EQ(cache.size(), 0u);
    EXPECT_TRUE(cache.reproject(rays).empty());
}

TEST(RenderCache, ScreenPointsMatchTheirRecordsAfterInvalidationAndReplacement) {
    // The reprojection reads the cache's per-point arrays (position, birth frame), not the
    // records: after compaction by invalidation and replacement of evicted slots, each screen
    // point must still be its record's projection, colour and age, in the serial reference
    // and the parallel reprojection alike.
    const CameraRays rays(cameraAt(Vec3(0, 0, 5), Vec3(0, 0, 0)), 24, 24);
    auto batch = [&](int seed, int count) {
        std::vector<ShadedPoint> b;
        std::mt19937 rng(static_cast<unsigned>(seed));
        std::uniform_real_distribution<double> u(0.0, 24.0), t(2.0, 4.0), c(0.0, 1.0);
        for (int i = 0; i < count; ++i) {
            ShadedPoint p =
                pointOnRay(rays, u(rng), u(rng), t(rng), i % 7, Rgb(c(rng), c(rng), c(rng)));
            p.element = seed * 10000 + i;
            b.push_back(p);
        }
        return b;
    };
    for (bool parallel : {true, false}) {
        RenderCacheOptions options;
        options.parallel = parallel;
        RenderCache cache(24, 24, 700, options);
        cache.insert(batch(1, 250));  // two frames old by the moved camera's first
        cache.reproject(rays);
        cache.insert(batch(3, 250));  // one frame old then
        cache.reproject(rays);
        ASSERT_GT(cache.invalidateObjects({2, 5}), 0u);  // compacts the arrays
        const std::size_t left = cache.size();
        cache.insert(batch(2, 400));  // fills up, then replaces (the hidden, then the oldest)
        ASSERT_EQ(cache.size(), 700u);
        std::size_t replaced = 0;
        for (std::size_t i = 0; i < left; ++i) {
            const int e = cache.points()[i].element;
            replaced += e >= 20000 && e < 30000;
        }
        ASSERT_GT(replaced, 0u) << "some new points sit in the slots of evicted ones";

        const CameraRays moved(cameraAt(Vec3(0.3, -0.2, 5), Vec3(0.1, 0, 0)), 24, 24);
        for (int frame = 0; frame < 2; ++frame) {
            const auto& screen = cache.reproject(moved);
            ASSERT_FALSE(screen.empty());
            std::vector<char> shown(cache.size(), 0);
            std::size_t checked = 0;
            for (int k = 0; k < 24 * 24; ++k) {
                const int i = cache.pixelPoints()[k];
                if (i < 0) continue;
                const std::size_t pi = static_cast<std::size_t>(i);
                shown[pi] = 1;
                const CachePoint& p = cache.points()[pi];
                const auto expected = moved.projectToPixel(p.position);
                ASSERT_TRUE(expected.has_value());
                const ScreenPoint& s = screen[checked++];
                EXPECT_EQ(static_cast<int>(s.position.y) * 24 + static_cast<int>(s.position.x), k);
                EXPECT_TRUE(s.position == *expected) << p.toString() << " at " << str(s.position);
                EXPECT_TRUE(s.colour == p.colour) << p.toString();
                // Batch 1 saw two frames before these, batch 3 one, batch 2 none.
                const int before = p.element >= 30000 ? 1 : p.element >= 20000 ? 0 : 2;
                EXPECT_EQ(s.age, before + frame) << p.toString();
            }
            EXPECT_EQ(checked, screen.size());
            for (std::size_t i = 0; i < cache.size(); ++i)
                EXPECT_EQ(cache.visible(i), shown[i] != 0) << cache.points()[i].toString();
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Capacity

TEST(RenderCache, NeverExceedsCapacityAndReplacesHiddenThenOldest) {
    const CameraRays rays(cameraAt(Vec3(0, 0, 5), Vec3(0, 0, 0)), 30, 30);
    RenderCache cache(30, 30, 100);
    auto batch = [&](int object, int offset) {
        std::vector<ShadedPoint> b;
        for (int i = 0; i < 60; ++i) {
            const int k = offset + i;
            b.push_back(pointOnRay(rays, k % 30 + 0.5, k / 30 + 0.5, 2.0, object));
        }
        return b;
    };
    auto count = [&](int object) {
        int n = 0;
        for (const CachePoint& p : cache.points()) n += p.object == object;
        return n;
    };
    cache.insert(batch(0, 0));
    cache.reproject(rays);  // A: age 1
    cache.insert(batch(1, 300));
    EXPECT_EQ(cache.size(), 100u);
    EXPECT_EQ(count(0), 40) << "the 20 replaced are the oldest";
    cache.reproject(rays);  // A: age 2, B: age 1
    cache.insert(batch(2, 600));
    EXPECT_EQ(cache.size(), 100u);
    EXPECT_EQ(count(0), 0);
    EXPECT_EQ(count(1), 40);
    EXPECT_EQ(count(2), 60);

    // A point hidden in the last frame goes before an older visible one.
    RenderCache small(30, 30, 3);
    small.insert(pointOnRay(rays, 1.5, 1.5, 2.0, 7));
    small.reproject(rays);
    small.insert(pointOnRay(rays, 2.5, 1.5, 2.0, 8));
    small.insert(pointOnRay(rays, 2.5, 1.5, 2.5, 9));  // behind 8 in the same pixel
    small.reproject(rays);                             // 7: age 2, 8 and 9: age 1, 9 hidden
    small.insert(pointOnRay(rays, 3.5, 1.5, 2.0, 10));
    std::set<int> objects;
    for (const CachePoint& p : small.points()) objects.insert(p.object);
    EXPECT_EQ(objects, (std::set<int>{7, 8, 10})) << small.toString();

    // A batch larger than the cache keeps its last points.
    RenderCache tiny(30, 30, 10);
    tiny.insert(batch(3, 0));
    EXPECT_EQ(tiny.size(), 10u);
    std::set<int> elements;
    for (const CachePoint& p : tiny.points()) elements.insert(p.element);
    const auto b3 = batch(3, 0);
    std::set<int> last;
    for (int i = 50; i < 60; ++i) last.insert(b3[i].element);
    EXPECT_EQ(elements, last);
}

/// Replacement against a brute force over the whole cache: every point sorted by (visible in
/// the last frame, older first, index), the first `victims` replaced, in ascending slot order,
/// by the batch in its order. Random cameras hide points behind nearer ones and off screen.
/// Every `idleEvery`-th step first reprojects `idleFrames` frames without new points, which
/// spreads the ages. Returns (steps that replaced, of which those whose threshold age lay
/// beyond the first histogram, 4,095 frames).
std::pair<int, int> checkReplacementAgainstSort(int W, int H, std::size_t capacity, int steps,
                                                int maxBatch, int idleEvery, int idleFrames) {
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> u(0, 1);
    RenderCache cache(W, H, capacity);
    auto cameraFor = [&](int k) {
        return CameraRays(
            cameraAt(Vec3(0.3 * std::sin(0.7 * k), 0.2 * std::cos(1.1 * k), 5), Vec3(0, 0, 0)), W,
            H);
    };
    int object = 1;
    int replacing = 0, beyond = 0;
    for (int step = 0; step < steps; ++step) {
        const CameraRays rays = cameraFor(step);
        const int frames = idleEvery > 0 && step % idleEvery == idleEvery / 2 ? idleFrames : 1;
        for (int f = 0; f < frames; ++f) cache.reproject(rays);
        const std::size_t n = cache.size();
        std::vector<int> order(n);
        std::iota(order.begin(), order.end(), 0);
        std::sort(order.begin(), order.end(), [&](int a, int b) {
            if (cache.visible(a) != cache.visible(b)) return !cache.visible(a);
            if (cache.age(a) != cache.age(b)) return cache.age(a) > cache.age(b);
            return a < b;
        });
        std::vector<ShadedPoint> batch;
        // The first batch fills the cache.
        const std::size_t size =
            step == 0 ? capacity : 1 + static_cast<std::size_t>(u(rng) * maxBatch);
        for (std::size_t i = 0; i < size; ++i)
            batch.push_back(pointOnRay(rays, u(rng) * W, u(rng) * H, 2 + 4 * u(rng), object));
        const std::size_t free = cache.capacity() - n;
        const std::size_t victims = batch.size() > free ? batch.size() - free : 0;
        const int thresholdAge = victims > 0 ? cache.age(order[victims - 1]) : 0;
        cache.insert(batch);
        EXPECT_EQ(cache.size(), std::min(cache.capacity(), n + batch.size()));
        std::vector<int> expected(order.begin(), order.begin() + victims);
        std::sort(expected.begin(), expected.end());
        for (std::size_t j = 0; j < victims; ++j) {
            const CachePoint& p = cache.points()[expected[j]];
            if (p.object != object || p.position != batch[free + j].position) {
                ADD_FAILURE() << "step " << step << ": slot " << expected[j] << " holds object "
                              << p.object << ", expected the batch's point " << free + j;
                return {replacing, beyond};
            }
        }
        std::size_t placed = 0;
        for (const CachePoint& p : cache.points()) placed += p.object == object;
        EXPECT_EQ(placed, batch.size()) << "step " << step;
        replacing += victims > 0;
        beyond += victims > 0 && thresholdAge >= 4095;
        ++object;
    }
    return {replacing, beyond};
}

TEST(RenderCache, ReplacementEqualsSortingEveryPointByVisibilityAgeAndIndex) {
    // A small cache whose points grow older than the age histogram reaches: the selection
    // refines on birth frames.
    const auto [replacing, beyond] = checkReplacementAgainstSort(12, 10, 150, 60, 40, 20, 4500);
    EXPECT_GT(replacing, 30) << "the cache was full for most steps";
    EXPECT_GT(beyond, 5) << "the threshold age lay beyond the histogram";
}

TEST(RenderCache, ReplacementOfALargeCacheEqualsSortingItsPoints) {
    // More points than one chunk of the parallel selection (65,536), with whole batches of
    // equal age: the tied points are shared out between chunks in index order.
    const auto [replacing, beyond] = checkReplacementAgainstSort(64, 48, 200000, 12, 30000, 0, 0);
    EXPECT_EQ(replacing, 11);
    EXPECT_EQ(beyond, 0);
}

// ---------------------------------------------------------------------------------------------
// Requests

TEST(RenderCache, RequestsConcentrateOnEmptyPixelsAndAreStratified) {
    const int w = 64, h = 48;
    const CameraRays rays(cameraAt(Vec3(0, 0, 5), Vec3(0, 0, 0)), w, h);
    RenderCache cache(w, h, 10000);
    // Left half: fresh points of one colour (priority ~0); right half: empty.
    std::vector<ShadedPoint> points;
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w / 2; ++x) points.push_back(pointOnRay(rays, x + 0.5, y + 0.5, 3.0));
    cache.insert(points);
    cache.reproject(rays);

    const auto requests = cache.requestSamples(rays, 60);
    ASSERT_EQ(requests.size(), 60u);
    std::set<std::pair<int, int>> pixels;
    for (const ShadeRequest& r : requests) {
        EXPECT_GE(r.pixel.x, w / 2) << r.toString() << ": requests go to empty pixels";
        EXPECT_EQ(r.frame, cache.frame());
        EXPECT_NEAR(glm::length(r.direction - rays.rayDirection(r.pixel.x, r.pixel.y)), 0, 1e-12);
        pixels.insert({static_cast<int>(r.pixel.x), static_cast<int>(r.pixel.y)});
    }
    EXPECT_EQ(pixels.size(), requests.size()) << "distinct pixels";
    // Asked again in the same frame, the requested pixels are held back.
    for (const ShadeRequest& r : cache.requestSamples(rays, 60))
        EXPECT_FALSE(pixels.count({static_cast<int>(r.pixel.x), static_cast<int>(r.pixel.y)}))
            << r.toString();

    // An empty image, one request per tile: exactly one in each 8×8 tile.
    RenderCache empty(w, h, 100);
    empty.reproject(rays);
    const auto spread = empty.requestSamples(rays, (w / 8) * (h / 8));
    std::map<int, int> perTile;
    for (const ShadeRequest& r : spread)
        ++perTile[static_cast<int>(r.pixel.y) / 8 * 8 + static_cast<int>(r.pixel.x) / 8];
    EXPECT_EQ(perTile.size(), static_cast<std::size_t>((w / 8) * (h / 8)));
    for (const auto& [tile, n] : perTile) EXPECT_EQ(n, 1) << "tile " << tile;
    // Default budget: sampleFraction of the pixels.
    RenderCache fresh(w, h, 100);
    fresh.reproject(rays);
    EXPECT_EQ(fresh.requestSamples(rays).size(),
              static_cast<std::size_t>(std::lround(0.02 * w * h)));
}

TEST(RenderCache, AChangedBudgetGoesToStalePixelsOnTopOfTheBaseBudget) {
    // A full image of fresh points, a block of 6×5 of them on object 1 (the object an edit
    // changed, marked stale). The changed budget adds up to as many requests as there are
    // stale pixels, and those pixels are all among the requests; the base budget is unchanged.
    const int w = 32, h = 24;
    const CameraRays rays(cameraAt(Vec3(0, 0, 5), Vec3(0, 0, 0)), w, h);
    auto fill = [&](RenderCache& cache) {
        std::vector<ShadedPoint> points;
        for (int y = 0; y < h; ++y)
            for (int x = 0; x < w; ++x) {
                const int object = x >= 10 && x < 16 && y >= 8 && y < 13 ? 1 : 0;
                points.push_back(pointOnRay(rays, x + 0.5, y + 0.5, 3.0, object));
            }
        cache.insert(points);
        cache.reproject(rays);
        EXPECT_EQ(cache.markStale({1}), 30u);
        cache.reproject(rays);
    };
    RenderCache base(w, h, 10000);
    fill(base);
    EXPECT_EQ(base.requestSamples(rays, 8).size(), 8u);

    RenderCache extra(w, h, 10000);
    fill(extra);
    const auto requests = extra.requestSamples(rays, 8, 100);
    ASSERT_EQ(requests.size(), 38u) << "8 + the 30 stale pixels (the changed budget's cap)";
    int stale = 0;
    for (const ShadeRequest& r : requests) {
        const int x = static_cast<int>(r.pixel.x), y = static_cast<int>(r.pixel.y);
        if (x >= 10 && x < 16 && y >= 8 && y < 13) ++stale;
    }
    EXPECT_EQ(stale, 30) << "every stale pixel is requested";

    RenderCache some(w, h, 10000);
    fill(some);
    EXPECT_EQ(some.requestSamples(rays, 8, 12).size(), 20u);
}

TEST(RenderCache, ADragAsksForChangedRegionsButNotForLoneHolesAmongFreshPoints) {
    // Fresh points in every pixel but a scattered set of lone holes (every 7th pixel of every
    // 5th row: no two adjacent) and an emptied 6×5 block (what a drag drops). Asked for
    // changed pixels only, the cache requests the block and none of the lone holes; otherwise
    // the lone holes are asked for too. Checked against the pixels' own neighbourhoods.
    const int w = 40, h = 30;
    const CameraRays rays(cameraAt(Vec3(0, 0, 5), Vec3(0, 0, 0)), w, h);
    auto lone = [](int x, int y) { return y % 5 == 2 && x % 7 == 3; };
    auto block = [](int x, int y) { return x >= 20 && x < 26 && y >= 10 && y < 15; };
    RenderCache cache(w, h, 10000);
    std::vector<ShadedPoint> points;
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x)
            if (!lone(x, y) && !block(x, y))
                points.push_back(pointOnRay(rays, x + 0.5, y + 0.5, 3.0));
    cache.insert(points);
    cache.reproject(rays);
    int loneHoles = 0;
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) loneHoles += lone(x, y) && !block(x, y);
    ASSERT_GT(loneHoles, 20);

    cache.setRequestChangedOnly(true);
    const auto dragging = cache.requestSamples(rays, 1000);
    std::set<std::pair<int, int>> asked;
    for (const ShadeRequest& r : dragging) {
        const int x = static_cast<int>(r.pixel.x), y = static_cast<int>(r.pixel.y);
        EXPECT_TRUE(block(x, y)) << r.toString() << ": only the emptied block is asked for";
        asked.insert({x, y});
    }
    EXPECT_EQ(asked.size(), 30u) << "every pixel of the block";

    RenderCache still(w, h, 10000);
    still.insert(points);
    still.reproject(rays);
    int loneAsked = 0;
    for (const ShadeRequest& r : still.requestSamples(rays, 2000))
        loneAsked += lone(static_cast<int>(r.pixel.x), static_cast<int>(r.pixel.y)) &&
                     !block(static_cast<int>(r.pixel.x), static_cast<int>(r.pixel.y));
    EXPECT_EQ(loneAsked, loneHoles) << "a still view asks for its lone holes";
}

TEST(RenderCache, OldPointsAndHighContrastRaisePriority) {
    const CameraRays rays(cameraAt(Vec3(0, 0, 5), Vec3(0, 0, 0)), 16, 16);
    RenderCache cache(16, 16, 1000);
    std::vector<ShadedPoint> points;
    for (int y = 0; y < 16; ++y)
        for (int x = 0; x < 16; ++x)
            points.push_back(
                pointOnRay(rays, x + 0.5, y + 0.5, 3.0, 0, x < 8 ? Rgb(0.1) : Rgb(0.9)));
    cache.insert(points);
    cache.reproject(rays);
    const auto& p0 = cache.priority();
    EXPECT_GT(p0[3 * 16 + 8], p0[3 * 16 + 12]) << "the colour edge is wanted more";
    EXPECT_LT(p0[3 * 16 + 12], 1.0) << "below an empty pixel";
    const double fresh = p0[3 * 16 + 12];
    for (int i = 0; i < 20; ++i) cache.reproject(rays);
    EXPECT_GT(cache.priority()[3 * 16 + 12], fresh + 0.1) << "old points are wanted more";
}

TEST(RenderCache, PriorityOfAPointIsItsAgeAndTheContrastOfItsClippedNeighbourhood) {
    // Brute force over the screen points: Walter et al. 2002's local contrast (max − min)/
    // (max + min) of the luminances of the points in the pixel's 3×3 neighbourhood, clipped
    // to the image, plus the age term; empty pixels 1.
    const int w = 23, h = 17;
    const CameraRays rays(cameraAt(Vec3(0, 0, 5), Vec3(0, 0, 0)), w, h);
    std::mt19937 rng(5);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    for (bool parallel : {false, true}) {
        RenderCacheOptions options;
        options.parallel = parallel;
        RenderCache cache(w, h, 4 * w * h, options);
        for (int round = 0; round < 3; ++round) {
            std::vector<ShadedPoint> points;
            for (int y = 0; y < h; ++y)
                for (int x = 0; x < w; ++x)
                    if (u(rng) < 0.4)
                        points.push_back(pointOnRay(rays, x + u(rng), y + u(rng), 3.0, 0,
                                                    Rgb(u(rng), u(rng), u(rng))));
            cache.insert(points);
            cache.reproject(rays);
        }
        std::vector<int> screenOf(static_cast<std::size_t>(w) * h, -1);
        const auto& screen = cache.screenPoints();
        for (std::size_t s = 0; s < screen.size(); ++s)
            screenOf[static_cast<int>(screen[s].position.y) * w +
                     static_cast<int>(screen[s].position.x)] = static_cast<int>(s);
        int withPoint = 0;
        for (int y = 0; y < h; ++y)
            for (int x = 0; x < w; ++x) {
                const int s = screenOf[y * w + x];
                const double got = cache.priority()[y * w + x];
                if (s < 0) {
                    EXPECT_EQ(got, 1.0) << x << " " << y;
                    continue;
                }
                double lo = 1e300, hi = -1e300;
                for (int yy = std::max(0, y - 1); yy <= std::min(h - 1, y + 1); ++yy)
                    for (int xx = std::max(0, x - 1); xx <= std::min(w - 1, x + 1); ++xx)
                        if (screenOf[yy * w + xx] >= 0) {
                            const double l = luminance(screen[screenOf[yy * w + xx]].colour);
                            lo = std::min(lo, l);
                            hi = std::max(hi, l);
                        }
                const double contrast = hi > 0 ? (hi - lo) / (hi + lo) : 0.0;
                const double age = screen[s].age;
                const double expected =
                    std::min(0.99, options.ageWeight * age / (age + options.ageScale) +
                                       options.contrastWeight * std::clamp(contrast, 0.0, 1.0));
                EXPECT_DOUBLE_EQ(got, expected) << x << " " << y << " parallel " << parallel;
                ++withPoint;
            }
        EXPECT_GT(withPoint, w * h / 2);
    }
}

TEST(RenderCache, InterpolationFeedbackRanksEmptyPixelsByTheirFilterWeight) {
    // Bala et al. §5.3: an empty pixel's priority falls with the total filter weight its
    // interpolation found; one with no reachable sample stays most wanted.
    const int w = 16, h = 16;
    const CameraRays rays(cameraAt(Vec3(0, 0, 5), Vec3(0, 0, 0)), w, h);
    RenderCacheOptions options;
    options.tileSize = 16;  // one tile: requests follow the priority order alone
    options.parallel = false;
    RenderCache cache(w, h, 1000, options);
    std::vector<ShadedPoint> points;
    for (int y = 0; y < h; y += 2)
        for (int x = 0; x < w; x += 2) points.push_back(pointOnRay(rays, x + 0.5, y + 0.5, 3.0));
    cache.insert(points);
    cache.reproject(rays);
    const std::vector<double> before = cache.priority();

    std::mt19937 rng(7);
    std::uniform_real_distribution<float> weight(0.05f, 2.0f);
    std::vector<float> weights(static_cast<std::size_t>(w) * h);
    for (float& v : weights) v = weight(rng);
    const int unreached = 5 * w + 9, leastWeight = 11 * w + 3;
    weights[unreached] = 0.0f;
    weights[leastWeight] = 0.01f;
    cache.applyInterpolationFeedback(weights);
    for (int k = 0; k < w * h; ++k) {
        const bool hasPoint = cache.pixelPoints()[k] >= 0;
        if (hasPoint) {
            EXPECT_EQ(cache.priority()[k], before[k]) << "pixel " << k << " keeps its priority";
        } else {
            const double expected =
                options.emptyFloor +
                (1.0 - options.emptyFloor) / (1.0 + weights[k] / options.feedbackWeight);
            EXPECT_NEAR(cache.priority()[k], expected, 1e-12) << "pixel " << k;
            EXPECT_GE(cache.priority()[k], options.emptyFloor);
        }
    }
    EXPECT_EQ(cache.priority()[unreached], 1.0);
    // The two least supported empty pixels are requested first, in that order of priority.
    const auto requests = cache.requestSamples(rays, 2);
    ASSERT_EQ(requests.size(), 2u);
    std::set<int> requested;
    for (const ShadeRequest& r : requests)
        requested.insert(static_cast<int>(r.pixel.y) * w + static_cast<int>(r.pixel.x));
    EXPECT_EQ(requested, (std::set<int>{unreached, leastWeight}));
    // The parallel request path reads the same priorities.
    RenderCacheOptions parallelOptions = options;
    parallelOptions.parallel = true;
    RenderCache parallel(w, h, 1000, parallelOptions);
    parallel.insert(points);
    parallel.reproject(rays);
    parallel.applyInterpolationFeedback(weights);
    EXPECT_EQ(parallel.priority(), cache.priority());
    std::set<int> parallelRequested;
    for (const ShadeRequest& r : parallel.requestSamples(rays, 2))
        parallelRequested.insert(static_cast<int>(r.pixel.y) * w + static_cast<int>(r.pixel.x));
    EXPECT_EQ(parallelRequested, requested);

    // Without feedback (feedbackWeight 0) priorities stay; a wrong size is refused.
    RenderCacheOptions off = options;
    off.feedbackWeight = 0;
    RenderCache plain(w, h, 1000, off);
    plain.insert(points);
    plain.reproject(rays);
    const std::vector<double> plainBefore = plain.priority();
    plain.applyInterpolationFeedback(weights);
    EXPECT_EQ(plain.priority(), plainBefore);
    EXPECT_THROW(cache.applyInterpolationFeedback(std::vector<float>(10)), std::invalid_argument);
}

// ---------------------------------------------------------------------------------------------
// With the point shader

TEST(RenderCache, FedByThePointShaderConvergesToFullShading) {
    const Scene scene = test::makeLitRoom("red");
    Discretization disc(scene);
    RayTracer tracer(disc);
    SolverOptions options;
    ProgressiveSolver solver(disc, tracer, options);
    solver.step(30);
    PointShaderOptions shaderOptions;
    shaderOptions.threads = 2;
    PointShader shader(disc, tracer, options, shaderOptions);
    shader.updateSolution(solver);

    const int w = 40, h = 30;
    const CameraRays rays(cameraAt(Vec3(0, 0, 1.4), Vec3(0, -0.6, 0), 80), w, h);
    RenderCache cache(w, h, 4 * w * h);
    for (int frame = 0; frame < 60; ++frame) {
        cache.insert(shader.takeResults());
        cache.reproject(rays);
        shader.submit(cache.requestSamples(rays, w * h / 10));
        shader.waitIdle();
    }
    cache.insert(shader.takeResults());
    const auto& screen = cache.reproject(rays);
    EXPECT_GT(screen.size(), static_cast<std::size_t>(0.97 * w * h)) << cache.toString();

    // Each visible point shows what the shader gives for its 3D point's pixel.
    PointShaderOptions syncOptions;
    syncOptions.threads = 0;
    PointShader reference(disc, tracer, options, syncOptions);
    reference.updateSolution(solver);
    const Image image = cache.interpolatedImage();
    double diff = 0, sum = 0;
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            ShadeRequest r{
                {x + 0.5, y + 0.5}, rays.origin(), rays.rayDirection(x + 0.5, y + 0.5), 1};
            const Rgb truth = reference.shade(r).radiance;
            diff += std::abs(luminance(image.at(x, y)) - luminance(truth));
            sum += luminance(truth);
        }
    EXPECT_LT(diff / sum, 0.08) << "mean relative difference of the interpolated image";
}

}  // namespace
}  // namespace penumbra
