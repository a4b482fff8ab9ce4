// EdgePointImage::holes(): the pixels whose value came from no point, which the display fills
// from its fallback. Against brute force over random sparse points: without edges and without
// smoothing a pixel is a hole exactly when no point lies in its 5×5 neighbourhood; with the
// edge-free smoothing (radius R, far from every edge) exactly when, besides, its box of radius
// R holds fewer than two points; with edges, a hole never has a point reachable within 5×5 and
// every pixel without any point within the smoothing's reach is one, and every other pixel
// has a value; a pixel beside an edge whose only points lie across it is a hole, not the
// other side's colour.

#include <gtest/gtest.h>

#include <random>
#include <vector>

#include "render/display/edge_point_image.h"

namespace penumbra {
namespace {

constexpr int kW = 64, kH = 48;

std::vector<ScreenPoint> sparsePoints(std::uint32_t seed, int count) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> x(0, kW), y(0, kH);
    std::vector<ScreenPoint> points;
    for (int i = 0; i < count; ++i) {
        ScreenPoint p;
        p.position = {x(rng), y(rng)};
        p.depth = 5;
        p.colour = Rgb(0.3, 0.4, 0.5);
        points.push_back(p);
    }
    return points;
}

/// Points (after the EPI's one-per-pixel rule) within Chebyshev radius r of (x, y).
int pointsWithin(const EdgePointImage& epi, int x, int y, int r) {
    int n = 0;
    for (int dy = -r; dy <= r; ++dy)
        for (int dx = -r; dx <= r; ++dx) {
            const int px = x + dx, py = y + dy;
            if (px < 0 || py < 0 || px >= kW || py >= kH) continue;
            n += epi.samplePosition(px, py) >= 0;
        }
    return n;
}

TEST(EpiHoles, WithoutEdgesAHoleHasNoPointInItsFilterOrSmoothingBox) {
    for (int smooth : {0, 6}) {
        EpiOptions o;
        o.smoothRadius = smooth;
        EdgePointImage epi(kW, kH, o);
        epi.build({}, sparsePoints(7 + smooth, 60));
        const Image image = epi.reconstruct(true);
        std::size_t holes = 0;
        for (int y = 0; y < kH; ++y)
            for (int x = 0; x < kW; ++x) {
                const bool expected = pointsWithin(epi, x, y, 2) == 0 &&
                                      (smooth == 0 || pointsWithin(epi, x, y, smooth) < 2);
                const bool hole = epi.holes()[y * kW + x] != 0;
                EXPECT_EQ(hole, expected) << "pixel " << x << ", " << y << ", smooth " << smooth;
                if (hole) {
                    EXPECT_EQ(luminance(image.at(x, y)), 0.0);
                }
                holes += hole;
            }
        EXPECT_EQ(epi.holeCount(), holes);
        EXPECT_GT(holes, 50u) << "the points should be sparse enough to leave holes";
        EXPECT_LT(holes, std::size_t(kW * kH)) << "and dense enough to fill some pixels";
    }
}

TEST(EpiHoles, WithEdgesHolesHaveNoPointWithinReachAndTheRestHaveValues) {
    EpiOptions o;
    o.smoothRadius = 6;
    EdgePointImage epi(kW, kH, o);
    std::vector<ScreenEdge> edges;
    for (int k = 0; k < 6; ++k) {
        ScreenEdge e;
        e.a = {3.3 + 10 * k, -1.0};
        e.b = {8.7 + 9 * k, kH + 1.0};
        e.depthA = e.depthB = 1.0;
        edges.push_back(e);
    }
    epi.build(edges, sparsePoints(11, 90));
    const Image image = epi.reconstruct(true);
    std::size_t holes = 0, farFromAll = 0;
    for (int y = 0; y < kH; ++y)
        for (int x = 0; x < kW; ++x) {
            const bool hole = epi.holes()[y * kW + x] != 0;
            if (hole) {
                // (Its value, if any, is a neighbour's colour the anti-aliasing mixed into
                // its secondary region: the display replaces it whole.)
                EXPECT_EQ(epi.interpolationWeights()[y * kW + x], 0.0f);
                // No point within 5×5, or only points across an edge (then not a complex
                // pixel, which keeps the plain estimate for its filter).
                if (pointsWithin(epi, x, y, 2) > 0) {
                    EXPECT_NE(epi.pixelClass(x, y), PixelClass::Complex)
                        << "pixel " << x << ", " << y;
                }
            } else {
                EXPECT_GT(luminance(image.at(x, y)), 0.0) << "pixel " << x << ", " << y;
            }
            // No point within the smoothing box's reach at all: a hole whatever the edges.
            if (pointsWithin(epi, x, y, 6) == 0) {
                ++farFromAll;
                EXPECT_TRUE(hole) << "pixel " << x << ", " << y;
            }
            holes += hole;
        }
    EXPECT_EQ(epi.holeCount(), holes);
    EXPECT_GT(holes, 0u);
    std::printf("%zu holes, %zu pixels with no point within 6\n", holes, farFromAll);
}

TEST(EpiHoles, APixelWhosePointsLieAcrossAnEdgeIsAHoleNotTheOtherSidesColour) {
    // A vertical edge at x = 20.5; red points fill the left side, the right side has points
    // only from x = 26 on. The pixels just right of the edge reach no point on their side
    // within 5×5, though red ones lie 1–2 pixels away across the edge: they are holes (the
    // display fills them from their own surface), and no pixel right of the edge shows red.
    EpiOptions o;
    EdgePointImage epi(kW, kH, o);
    ScreenEdge edge;
    edge.a = {20.5, -1.0};
    edge.b = {20.5, kH + 1.0};
    edge.depthA = edge.depthB = 1.0;
    std::vector<ScreenPoint> points;
    for (int y = 0; y < kH; ++y)
        for (int x = 0; x < kW; ++x) {
            if (x > 20 && x < 26) continue;
            ScreenPoint p;
            p.position = {x + 0.5, y + 0.5};
            p.depth = 5;
            p.colour = x <= 20 ? Rgb(1.0, 0.0, 0.0) : Rgb(0.0, 0.0, 1.0);
            points.push_back(p);
        }
    epi.build({edge}, points);
    const Image image = epi.reconstruct(true);
    int holesBesideTheEdge = 0;
    for (int y = 2; y < kH - 2; ++y)
        for (int x = 21; x < kW; ++x) {
            const bool hole = epi.holes()[y * kW + x] != 0;
            if (x == 21 || x == 22) {
                EXPECT_GT(pointsWithin(epi, x, y, 2), 0) << "red points within 5x5";
                EXPECT_TRUE(hole) << "pixel " << x << ", " << y;
            }
            holesBesideTheEdge += hole;
            if (!hole) {
                EXPECT_LT(image.at(x, y).x, 1e-9) << "pixel " << x << ", " << y;
            }
        }
    EXPECT_GT(holesBesideTheEdge, 0);
}

}  // namespace
}  // namespace penumbra
