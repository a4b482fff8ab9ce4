// EpiOptions::smoothRadius, the edge-free smoothing of the EPI reconstruction: against a
// brute-force reference (a smoothed pixel 3 or more pixels from every simple or complex pixel
// is the mean of the points in the largest box around it that holds none; one 1 or 2 pixels
// away is the filter-weighted mean of its own and its reachable neighbours' primary colours;
// every other pixel is the unsmoothed reconstruction bit for bit), dense regions of complex
// pixels take their box's mean, never across a straight edge, and less noise on a flat noisy
// field.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include "render/display/edge_point_image.h"

namespace penumbra {
namespace {

ScreenEdge makeEdge(glm::dvec2 a, glm::dvec2 b) {
    ScreenEdge e;
    e.a = a;
    e.b = b;
    e.depthA = e.depthB = 1.0;
    return e;
}

ScreenPoint makePoint(glm::dvec2 p, Rgb colour) {
    ScreenPoint s;
    s.position = p;
    s.colour = colour;
    s.depth = 1.0;
    return s;
}

/// Brute force: the points in the (2r+1)² box around (x, y), clipped to the image.
struct BoxPoints {
    int count = 0;
    Rgb sum{0.0};
};
BoxPoints pointsInBox(const EdgePointImage& epi, int x, int y, int r, int W, int H) {
    BoxPoints b;
    for (int yy = std::max(0, y - r); yy <= std::min(H - 1, y + r); ++yy)
        for (int xx = std::max(0, x - r); xx <= std::min(W - 1, x + r); ++xx)
            if (epi.samplePosition(xx, yy) >= 0) {
                ++b.count;
                b.sum += epi.sampleColour(xx, yy);
            }
    return b;
}

EpiOptions smoothing(int radius) {
    EpiOptions o;
    o.smoothRadius = radius;
    return o;
}

TEST(EdgeFreeSmoothing, SmoothedPixelsAreTheMeanOfTheirLargestEdgeFreeBoxOrOfTheirReach) {
    constexpr int W = 48, H = 40, R = 6;
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    int smoothed = 0, kept = 0, ringed = 0;
    for (int trial = 0; trial < 6; ++trial) {
        std::vector<ScreenEdge> edges;
        for (int k = 0; k < 1 + trial % 3; ++k)
            edges.push_back(makeEdge({u(rng) * W, u(rng) * H}, {u(rng) * W, u(rng) * H}));
        std::vector<ScreenPoint> points;
        for (int y = 0; y < H; ++y)
            for (int x = 0; x < W; ++x)
                if (u(rng) < 0.3 + 0.1 * trial)
                    points.push_back(
                        makePoint({x + u(rng), y + u(rng)}, Rgb(u(rng), u(rng), u(rng))));
        EdgePointImage plainEpi(W, H), smoothEpi(W, H, smoothing(R));
        plainEpi.build(edges, points);
        smoothEpi.build(edges, points);
        const Image plain = plainEpi.reconstruct(true);
        const Image image = smoothEpi.reconstruct(true);
        for (int y = 0; y < H; ++y) {
            for (int x = 0; x < W; ++x) {
                // Brute force: Chebyshev distance to the nearest simple or complex pixel
                // (pixels beyond the image count as empty), capped at R + 1.
                int d = R + 1;
                for (int yy = 0; yy < H; ++yy)
                    for (int xx = 0; xx < W; ++xx)
                        if (smoothEpi.pixelClass(xx, yy) != PixelClass::Empty)
                            d = std::min(d, std::max(std::abs(xx - x), std::abs(yy - y)));
                const Rgb got = image.at(x, y);
                if (d == 1 || d == 2) {
                    // §5.3's filter over primary colours: weight 1 for the pixel, 4^-|dx| ·
                    // 4^-|dy| for a reachable neighbour, each counted when its weight is
                    // positive.
                    const std::vector<float>& w = smoothEpi.interpolationWeights();
                    const uint32_t reach = smoothEpi.primaryReachability(x, y);
                    Rgb sum(0.0);
                    double total = 0;
                    int bit = 0;
                    for (int dy = -2; dy <= 2; ++dy)
                        for (int dx = -2; dx <= 2; ++dx) {
                            const bool centre = dx == 0 && dy == 0;
                            const bool reached = centre || ((reach >> bit) & 1u);
                            if (!centre) ++bit;
                            const int xx = x + dx, yy = y + dy;
                            if (!reached || xx < 0 || yy < 0 || xx >= W || yy >= H) continue;
                            if (!(w[static_cast<std::size_t>(yy) * W + xx] > 0)) continue;
                            const double weight =
                                std::pow(0.25, std::abs(dx)) * std::pow(0.25, std::abs(dy));
                            sum += weight * smoothEpi.primaryColour(xx, yy);
                            total += weight;
                        }
                    const Rgb expected = total > 0 ? sum / total : plain.at(x, y);
                    ASSERT_LT(glm::length(got - expected), 1e-5)
                        << "trial " << trial << " (" << x << ", " << y << ") d " << d;
                    ++ringed;
                    continue;
                }
                const BoxPoints box =
                    d >= 3 ? pointsInBox(smoothEpi, x, y, std::min(d - 1, R), W, H) : BoxPoints{};
                if (box.count >= 2) {
                    const Rgb mean = box.sum / static_cast<double>(box.count);
                    ASSERT_NEAR(got.x, mean.x, 1e-6)
                        << "trial " << trial << " (" << x << ", " << y << ")";
                    ASSERT_NEAR(got.y, mean.y, 1e-6)
                        << "trial " << trial << " (" << x << ", " << y << ")";
                    ASSERT_NEAR(got.z, mean.z, 1e-6)
                        << "trial " << trial << " (" << x << ", " << y << ")";
                    ++smoothed;
                } else {
                    ASSERT_EQ(got, plain.at(x, y))
                        << "trial " << trial << " (" << x << ", " << y << ")";
                    ++kept;
                }
            }
        }
    }
    // Both cases occur often enough for the comparison to mean something.
    EXPECT_GT(smoothed, 1000);
    EXPECT_GT(kept, 300);
    EXPECT_GT(ringed, 1000);
}

TEST(EdgeFreeSmoothing, DenseRegionsTakeTheMeanOfTheirBox) {
    // Clusters of short random edges make regions of complex pixels. A pixel (of any class)
    // with at least denseComplexLimit complex pixels in its 3×3 takes the mean of the points
    // in its (2·denseRadius + 1)² box when the box holds two or more; every other pixel is
    // the reconstruction without dense regions, bit for bit.
    constexpr int W = 56, H = 44;
    std::mt19937 rng(19);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    int dense = 0, other = 0, classes[3] = {0, 0, 0};
    for (int trial = 0; trial < 4; ++trial) {
        // Limit and radius vary apart (2, 3, 4, 2 against 1, 1, 2, 2).
        const int limit = 2 + trial % 3, radius = 1 + (trial / 2) % 3;
        std::vector<ScreenEdge> edges;
        for (int cluster = 0; cluster < 3; ++cluster) {
            const glm::dvec2 c(8 + u(rng) * (W - 16), 8 + u(rng) * (H - 16));
            for (int k = 0; k < 60; ++k) {
                const glm::dvec2 a = c + glm::dvec2(u(rng) - 0.5, u(rng) - 0.5) * 12.0;
                edges.push_back(makeEdge(a, a + glm::dvec2(u(rng) - 0.5, u(rng) - 0.5) * 3.0));
            }
        }
        edges.push_back(makeEdge({u(rng) * W, 0.0}, {u(rng) * W, double(H)}));
        std::vector<ScreenPoint> points;
        for (int y = 0; y < H; ++y)
            for (int x = 0; x < W; ++x)
                if (u(rng) < 0.25 + 0.1 * trial)
                    points.push_back(
                        makePoint({x + u(rng), y + u(rng)}, Rgb(u(rng), u(rng), u(rng))));
        EpiOptions without = smoothing(6);
        without.denseComplexLimit = limit;
        EpiOptions with = without;
        with.denseRadius = radius;
        EdgePointImage plainEpi(W, H, without), denseEpi(W, H, with);
        plainEpi.build(edges, points);
        denseEpi.build(edges, points);
        const Image plain = plainEpi.reconstruct(true);
        const Image image = denseEpi.reconstruct(true);
        for (int y = 0; y < H; ++y) {
            for (int x = 0; x < W; ++x) {
                int around = 0;
                for (int yy = std::max(0, y - 1); yy <= std::min(H - 1, y + 1); ++yy)
                    for (int xx = std::max(0, x - 1); xx <= std::min(W - 1, x + 1); ++xx)
                        around += denseEpi.pixelClass(xx, yy) == PixelClass::Complex;
                const BoxPoints box = pointsInBox(denseEpi, x, y, radius, W, H);
                const Rgb got = image.at(x, y);
                if (around >= limit && box.count >= 2) {
                    const Rgb mean = box.sum / static_cast<double>(box.count);
                    ASSERT_LT(glm::length(got - mean), 1e-6)
                        << "trial " << trial << " (" << x << ", " << y << ")";
                    ++dense;
                    ++classes[static_cast<int>(denseEpi.pixelClass(x, y))];
                } else {
                    ASSERT_EQ(got, plain.at(x, y))
                        << "trial " << trial << " (" << x << ", " << y << ")";
                    ++other;
                }
            }
        }
    }
    EXPECT_GT(dense, 500);
    EXPECT_GT(other, 2000);
    for (int c = 0; c < 3; ++c) EXPECT_GT(classes[c], 20) << "class " << c;
}

TEST(EdgeFreeSmoothing, NoColourCrossesAStraightEdge) {
    // A vertical edge at x = 20.3: every pixel wholly on one side keeps that side's colour
    // exactly, however large the smoothing box.
    constexpr int W = 48, H = 32;
    const Rgb left(0.9, 0.2, 0.1), right(0.1, 0.3, 0.8);
    std::mt19937 rng(3);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    std::vector<ScreenPoint> points;
    for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x)
            if (u(rng) < 0.5) {
                const glm::dvec2 p(x + u(rng), y + u(rng));
                points.push_back(makePoint(p, p.x < 20.3 ? left : right));
            }
    for (int radius : {2, 8, 30}) {
        EdgePointImage epi(W, H, smoothing(radius));
        epi.build({makeEdge({20.3, -1.0}, {20.3, H + 1.0})}, points);
        const Image image = epi.reconstruct(true);
        for (int y = 0; y < H; ++y)
            for (int x = 0; x < W; ++x) {
                if (x + 1 <= 20) {
                    ASSERT_LT(glm::length(image.at(x, y) - left), 1e-5)
                        << radius << " " << x << " " << y;
                } else if (x >= 21) {
                    ASSERT_LT(glm::length(image.at(x, y) - right), 1e-5)
                        << radius << " " << x << " " << y;
                }
            }
    }
}

TEST(EdgeFreeSmoothing, AveragesOutPointNoiseOnAFlatField) {
    // No edges, colour 0.5 with uniform noise of ±0.2 in every point: the peaked filter
    // keeps most of the noise, the smoothed reconstruction averages it out.
    constexpr int W = 64, H = 64;
    std::mt19937 rng(11);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    std::vector<ScreenPoint> points;
    for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x)
            if (u(rng) < 0.8)
                points.push_back(
                    makePoint({x + u(rng), y + u(rng)}, Rgb(0.5 + 0.4 * (u(rng) - 0.5))));
    auto rmse = [&](const Image& image) {
        double s = 0;
        for (int y = 0; y < H; ++y)
            for (int x = 0; x < W; ++x) s += (image.at(x, y).x - 0.5) * (image.at(x, y).x - 0.5);
        return std::sqrt(s / (W * H));
    };
    EdgePointImage plainEpi(W, H), smoothEpi(W, H, smoothing(8));
    plainEpi.build({}, points);
    smoothEpi.build({}, points);
    const double plain = rmse(plainEpi.reconstruct(true));
    const double smooth = rmse(smoothEpi.reconstruct(true));
    // A point's noise has σ = 0.4/√12 ≈ 0.115; the box of 17² × 0.8 points divides it by ~15.
    EXPECT_LT(smooth, 0.25 * plain) << "plain " << plain << " smoothed " << smooth;
    EXPECT_LT(smooth, 0.02);
}

}  // namespace
}  // namespace penumbra
