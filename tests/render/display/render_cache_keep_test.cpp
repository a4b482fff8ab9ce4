// The render cache keeping its points across an edit instead of dropping them (the drag
// issue): relight adds each element's change and marks stale points, which the priority ranks
// first and a fresh point replaces in the z-buffer; carry moves an object's points rigidly
// onto its new version; setHidden leaves points out of the reprojection without dropping
// them. Each against a brute-force expectation over every point.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <glm/gtc/matrix_transform.hpp>
#include <vector>

#include "render/camera_rays.h"
#include "render/display/render_cache.h"

namespace penumbra {
namespace {

Camera frontCamera() {
    Camera c;
    c.position = Vec3(0, 0, 5);
    c.lookAt = Vec3(0, 0, 0);
    c.up = Vec3(0, 1, 0);
    c.fovDeg = 50;
    return c;
}

/// One point per pixel centre at distance `t` along its ray, element = pixel index + offset.
std::vector<ShadedPoint> layer(const CameraRays& rays, double t, int object, int elementOffset,
                               Rgb colour) {
    std::vector<ShadedPoint> out;
    for (int y = 0; y < rays.height(); ++y)
        for (int x = 0; x < rays.width(); ++x) {
            ShadedPoint p;
            p.pixel = {x + 0.5, y + 0.5};
            p.position = rays.origin() + t * rays.rayDirection(x + 0.5, y + 0.5);
            p.radiance = colour;
            p.object = object;
            p.element = elementOffset + y * rays.width() + x;
            out.push_back(p);
        }
    return out;
}

TEST(RenderCacheKeep, RelightAddsEachElementsChangeAndStalePixelsComeFirst) {
    const CameraRays rays(frontCamera(), 16, 16);
    RenderCache cache(16, 16, 1024);
    cache.insert(layer(rays, 5.0, 0, 0, Rgb(0.5)));
    cache.reproject(rays);
    // Every tenth element changes by +0.1 in red, every seventh is stale.
    std::vector<Rgb> delta(256, Rgb(0.0));
    std::vector<std::uint8_t> stale(256, 0);
    std::size_t expectedStale = 0;
    for (int e = 0; e < 256; ++e) {
        if (e % 10 == 0) delta[e] = Rgb(0.1, 0.0, 0.0);
        stale[e] = e % 7 == 0;
        expectedStale += stale[e];
    }
    EXPECT_EQ(cache.relight(delta, stale), expectedStale);
    for (std::size_t i = 0; i < cache.size(); ++i) {
        const CachePoint& p = cache.points()[i];
        EXPECT_NEAR(p.colour.x, p.element % 10 == 0 ? 0.6 : 0.5, 1e-12) << p.toString();
        EXPECT_EQ(cache.stale(i), p.element % 7 == 0) << p.toString();
    }
    // The next frame: stale pixels have priority 1, like empty ones; the others less.
    cache.reproject(rays);
    for (int y = 0; y < 16; ++y)
        for (int x = 0; x < 16; ++x) {
            const double priority = cache.priority()[y * 16 + x];
            if ((y * 16 + x) % 7 == 0) {
                EXPECT_EQ(priority, 1.0) << "stale pixel " << x << ", " << y;
            } else {
                EXPECT_LT(priority, 1.0) << "fresh pixel " << x << ", " << y;
            }
        }
    // A fresh point at the same depth replaces a stale one in the z-buffer; a stale one does
    // not replace a fresh one.
    std::vector<ShadedPoint> fresh = layer(rays, 5.0, 0, 0, Rgb(0.9));
    cache.insert({fresh[0], fresh[1]});  // pixel 0 is stale, pixel 1 is not
    const std::vector<ScreenPoint>& shown = cache.reproject(rays);
    ASSERT_FALSE(shown.empty());
    EXPECT_NEAR(shown[0].colour.x, 0.9, 1e-12) << "the fresh point wins over the stale one";
    EXPECT_NEAR(shown[1].colour.x, 0.9, 1e-12) << "the younger point wins as before";
    EXPECT_LT(cache.priority()[0], 1.0) << "its pixel is no longer first";
}

TEST(RenderCacheKeep, APointDarkerThanItsElementsLossTakesItsShareAndIsReshadedFirst) {
    // Element 0 held 0.5 and loses 0.3: a point at 0.5 follows it to 0.2; a point in a shadow
    // at 0.1 cannot lose 0.3 and keeps the element's share, 0.1 × 0.2 / 0.5 = 0.04, stale.
    // Without the element's colour before, it goes to 0; with no loss, nothing changes.
    const CameraRays rays(frontCamera(), 4, 1);
    for (const bool known : {true, false}) {
        RenderCache cache(4, 1, 16);
        std::vector<ShadedPoint> points = layer(rays, 5.0, 0, 0, Rgb(0.5));
        for (ShadedPoint& p : points) p.element = p.pixel.x < 2 ? 0 : 1;
        points[1].radiance = Rgb(0.1, 0.1, 0.4);  // darker in red and green
        cache.insert(points);
        cache.reproject(rays);
        const std::vector<Rgb> delta{Rgb(-0.3, -0.3, 0.0), Rgb(0.0)};
        const std::vector<std::uint8_t> stale(2, 0);
        const std::vector<Rgb> before =
            known ? std::vector<Rgb>{Rgb(0.5), Rgb(0.5)} : std::vector<Rgb>{};
        EXPECT_EQ(cache.relight(delta, stale, before), 1u);
        for (std::size_t i = 0; i < cache.size(); ++i) {
            const CachePoint& p = cache.points()[i];
            if (p.element == 1) {
                EXPECT_EQ(p.colour, Rgb(0.5));
                EXPECT_FALSE(cache.stale(i));
            } else if (p.colour.z > 0.45) {  // the first point: follows its element
                EXPECT_NEAR(p.colour.x, 0.2, 1e-12);
                EXPECT_NEAR(p.colour.z, 0.5, 1e-12);
                EXPECT_FALSE(cache.stale(i));
            } else {  // the dark one
                EXPECT_NEAR(p.colour.x, known ? 0.04 : 0.0, 1e-12);
                EXPECT_NEAR(p.colour.y, known ? 0.04 : 0.0, 1e-12);
                EXPECT_NEAR(p.colour.z, 0.4, 1e-12);
                EXPECT_TRUE(cache.stale(i));
            }
        }
    }
}

TEST(RenderCacheKeep, APointShadedSinceTheSceneLastChangedTakesOnlyTheChangeItLacks) {
    // Element 0 loses 0.3, of which 0.25 is its direct light's estimate catching up with the
    // scene (exactPart). A point shaded before the scene's last change (state 3 < 5) takes the
    // whole change; one shaded since (state 7) already holds the direct light and takes 0.05.
    const CameraRays rays(frontCamera(), 2, 1);
    RenderCache cache(2, 1, 16);
    std::vector<ShadedPoint> points = layer(rays, 5.0, 0, 0, Rgb(0.5));
    points[0].element = points[1].element = 0;
    points[0].shading = 3;
    points[1].shading = 7;
    cache.insert(points);
    cache.reproject(rays);
    const std::vector<Rgb> delta{Rgb(-0.3)}, exactPart{Rgb(-0.25)}, before{Rgb(0.5)};
    cache.relight(delta, std::vector<std::uint8_t>(1, 0), before, exactPart, 5);
    for (std::size_t i = 0; i < cache.size(); ++i) {
        const CachePoint& p = cache.points()[i];
        EXPECT_NEAR(p.colour.x, p.shading >= 5 ? 0.45 : 0.2, 1e-12) << p.toString();
    }
}

/// The pixel a request falls in.
int requestPixel(const ShadeRequest& r, int width) {
    return static_cast<int>(std::floor(r.pixel.y)) * width +
           static_cast<int>(std::floor(r.pixel.x));
}

TEST(RenderCacheKeep, CarriedThenStalePixelsAreRequestedBeforeAnyOther) {
    // 32×32 pixels: the left columns show an object carried to a new version, a band of the
    // wall behind is stale (relit), the rest fresh. Budgets below, between and above the
    // tiers' sizes; the serial and parallel request drawers agree.
    const int W = 32;
    const CameraRays rays(frontCamera(), W, W);
    std::vector<std::vector<ShadeRequest>> drawn[2];  // serial, parallel
    for (bool parallel : {false, true}) {
        RenderCacheOptions options;
        options.parallel = parallel;
        for (int budget : {40, 300, 400}) {
            RenderCache cache(W, W, 4096, options);
            std::vector<ShadedPoint> wall = layer(rays, 6.0, 1, 0, Rgb(0.3));
            std::vector<ShadedPoint> object;
            for (const ShadedPoint& p : layer(rays, 4.0, 2, 2000, Rgb(0.6)))
                if (p.pixel.x < 8) object.push_back(p);  // 8 columns: 256 pixels
            cache.insert(wall);
            cache.insert(object);
            cache.reproject(rays);
            cache.reproject(rays);  // the points age: fresh pixels rank below 1
            EXPECT_EQ(cache.carry(2, 5, Mat4(1.0), 100), object.size());
            std::vector<Rgb> delta(2 * W * W, Rgb(0.0));
            std::vector<std::uint8_t> stale(2 * W * W, 0);
            std::size_t staleWall = 0;
            for (int y = 20; y < 24; ++y)  // rows 20–23 beside the object: 96 pixels
                for (int x = 8; x < W; ++x) stale[y * W + x] = 1, ++staleWall;
            cache.relight(delta, stale);
            cache.reproject(rays);
            auto tier = [&](int k) {
                const int x = k % W, y = k / W;
                return x < 8 ? 2 : (y >= 20 && y < 24 ? 1 : 0);
            };
            const std::vector<ShadeRequest> requests = cache.requestSamples(rays, budget);
            EXPECT_EQ(requests.size(), static_cast<std::size_t>(budget));
            std::vector<int> perTier(3, 0);
            for (const ShadeRequest& r : requests) ++perTier[tier(requestPixel(r, W))];
            const int carried = static_cast<int>(object.size());
            const int staleCount = static_cast<int>(staleWall);
            EXPECT_EQ(perTier[2], std::min(budget, carried)) << "budget " << budget;
            EXPECT_EQ(perTier[1], std::clamp(budget - carried, 0, staleCount))
                << "budget " << budget;
            EXPECT_EQ(perTier[0], std::max(0, budget - carried - staleCount))
                << "budget " << budget;
            drawn[parallel].push_back(requests);
        }
    }
    ASSERT_EQ(drawn[0].size(), drawn[1].size());
    for (std::size_t b = 0; b < drawn[0].size(); ++b) {
        ASSERT_EQ(drawn[0][b].size(), drawn[1][b].size());
        for (std::size_t i = 0; i < drawn[0][b].size(); ++i)
            EXPECT_EQ(drawn[0][b][i].pixel, drawn[1][b][i].pixel) << "request " << i;
    }
}

TEST(RenderCacheKeep, CarryMovesAnObjectsPointsRigidlyOntoItsNewVersion) {
    const CameraRays rays(frontCamera(), 12, 12);
    // Points shaded for this view (requested in a frame of it): trusted as their pixels' own.
    auto shadedForView = [&](RenderCache& c, std::vector<ShadedPoint> points) {
        for (ShadedPoint& p : points) p.frame = c.frame();
        c.insert(points);
    };
    RenderCache cache(12, 12, 1024);
    cache.reproject(rays);
    shadedForView(cache, layer(rays, 4.0, 3, 1000, Rgb(0.4)));  // the object, version 3
    shadedForView(cache, layer(rays, 6.0, 1, 0, Rgb(0.2)));     // the wall behind it
    const std::vector<CachePoint> before = cache.points();
    // The trust the wall's points are shown with (the object hides it all before the move).
    RenderCache wallOnly(12, 12, 1024);
    wallOnly.reproject(rays);
    shadedForView(wallOnly, layer(rays, 6.0, 1, 0, Rgb(0.2)));
    const std::uint8_t wallTrust = wallOnly.reproject(rays).front().trust;
    ASSERT_GT(wallTrust, 0);
    const Mat4 move = glm::translate(Mat4(1.0), Vec3(0.3, -0.2, 0.5)) *
                      glm::rotate(Mat4(1.0), 0.4, Vec3(0, 1, 0));
    EXPECT_EQ(cache.carry(3, 7, move, 500), 144u);
    ASSERT_EQ(cache.size(), before.size());
    for (std::size_t i = 0; i < cache.size(); ++i) {
        const CachePoint& was = before[i];
        const CachePoint& now = cache.points()[i];
        if (was.object != 3) {
            EXPECT_EQ(now.position, was.position);
            EXPECT_EQ(now.object, was.object);
            EXPECT_FALSE(cache.stale(i));
            continue;
        }
        const Vec3 expected = Vec3(move * glm::dvec4(was.position, 1.0));
        EXPECT_LT(glm::length(now.position - expected), 1e-12);
        EXPECT_EQ(now.object, 7);
        EXPECT_EQ(now.element, was.element + 500);
        EXPECT_EQ(now.colour, was.colour) << "the colour stays until re-shaded";
        EXPECT_TRUE(cache.stale(i));
    }
    // The reprojection sees the moved points where they are now, not trusted as their pixels'
    // own values (their colour is what they showed where they were); the wall's as before.
    const std::vector<ScreenPoint>& shown = cache.reproject(rays);
    std::size_t moved = 0, wall = 0;
    for (const ScreenPoint& p : shown) {
        if (p.colour.x == 0.4) {
            ++moved;
            EXPECT_EQ(p.trust, 0) << p.toString();
        } else if (p.trust == wallTrust) {
            ++wall;
        }
    }
    EXPECT_GT(moved, 0u);
    EXPECT_EQ(moved + wall, shown.size());
}

TEST(RenderCacheKeep, HiddenPointsSkipTheReprojectionAndComeBack) {
    const CameraRays rays(frontCamera(), 10, 10);
    RenderCache cache(10, 10, 1024);
    cache.insert(layer(rays, 6.0, 1, 0, Rgb(0.2)));
    // Hide the left half (x < 0 in world space) of the wall.
    const std::size_t hidden =
        cache.setHidden([](const Vec3& position, int) { return position.x < 0; });
    std::size_t expected = 0;
    for (const CachePoint& p : cache.points()) expected += p.position.x < 0;
    EXPECT_EQ(hidden, expected);
    ASSERT_GT(hidden, 0u);
    const std::vector<ScreenPoint>& shown = cache.reproject(rays);
    EXPECT_EQ(shown.size(), cache.size() - hidden);
    for (const ScreenPoint& p : shown) EXPECT_GE(p.position.x, 5.0) << "left half hidden";
    for (std::size_t i = 0; i < cache.size(); ++i)
        EXPECT_EQ(cache.hidden(i), cache.points()[i].position.x < 0);
    // The serial reference agrees.
    RenderCacheOptions serial;
    serial.parallel = false;
    RenderCache reference(10, 10, 1024, serial);
    reference.insert(layer(rays, 6.0, 1, 0, Rgb(0.2)));
    reference.setHidden([](const Vec3& position, int) { return position.x < 0; });
    EXPECT_EQ(reference.reproject(rays).size(), shown.size());
    // Nothing was dropped: an empty function shows every point again.
    EXPECT_EQ(cache.setHidden({}), 0u);
    EXPECT_EQ(cache.reproject(rays).size(), cache.size());
}

}  // namespace
}  // namespace penumbra
