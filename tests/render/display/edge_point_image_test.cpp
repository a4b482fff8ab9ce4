// The edge-and-point image (Bala et al. 2003 §4–5): rasterization and classification
// against analytic crossings, the paper's Figure 6 reachability example, two-colour scenes
// against their exact (area-coverage) images with and without edges, depth culling, the
// complex filter, edge cases, and a timing printout at 512×512.

#include "render/display/edge_point_image.h"

#include <gtest/gtest.h>
#include <time.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <iostream>
#include <limits>
#include <queue>
#include <random>
#include <sstream>
#include <stdexcept>
#include <vector>

namespace penumbra {
namespace {

double cross(const glm::dvec2& u, const glm::dvec2& v) { return u.x * v.y - u.y * v.x; }

ScreenEdge makeEdge(glm::dvec2 a, glm::dvec2 b, double depth = 1.0) {
    ScreenEdge e;
    e.a = a;
    e.b = b;
    e.depthA = e.depthB = depth;
    return e;
}

ScreenPoint makePoint(glm::dvec2 p, Rgb colour, double depth = 1.0) {
    ScreenPoint s;
    s.position = p;
    s.colour = colour;
    s.depth = depth;
    return s;
}

// ---- Rasterization and classification (§4.1, §4.2, §4.5) ----------------------------------

TEST(EdgePointImage, VerticalEdgeGivesSimplePixelsWithAnalyticCode) {
    EdgePointImage epi(4, 4);
    epi.build({makeEdge({2.3, -1.0}, {2.3, 5.0})}, {});
    for (int y = 0; y < 4; ++y) {
        for (int x = 0; x < 4; ++x) {
            if (x != 2) {
                EXPECT_EQ(epi.pixelClass(x, y), PixelClass::Empty) << x << "," << y;
                continue;
            }
            ASSERT_EQ(epi.pixelClass(x, y), PixelClass::Simple) << epi.toString();
            // x = 2.3 lies in the third eighth (piece 2) of the top and bottom segments;
            // clockwise, the bottom side's piece 2 is position 16 + 7 − 2.
            EXPECT_EQ(epi.edgeCode(x, y), makeEdgeCode(2, 21, 8))
                << edgeCodeToString(epi.edgeCode(x, y), 8);
            auto masks = epi.boundaryMasks(x, y);
            EXPECT_EQ(masks[0], 1 << 2);
            EXPECT_EQ(masks[2], 1 << 2);
            EXPECT_EQ(masks[1], 0);
            EXPECT_EQ(masks[3], 0);
        }
    }
}

TEST(EdgePointImage, SlopedEdgeCrossingsMatchAnalyticIntersections) {
    // Every recorded bit must be the 1/8 piece of an exact crossing and vice versa.
    const int W = 12, H = 9;
    const glm::dvec2 a{-0.7, 1.3}, b{12.9, 7.45};
    EdgePointImage epi(W, H);
    epi.build({makeEdge(a, b)}, {});
    for (int y = 0; y < H; ++y) {
        for (int x = 0; x < W; ++x) {
            auto masks = epi.boundaryMasks(x, y);
            // Top segment: y = const line crossing.
            auto expectedHorizontal = [&](double lineY) {
                double t = (lineY - a.y) / (b.y - a.y);
                double cx = a.x + t * (b.x - a.x);
                if (t < 0 || t > 1 || cx < x || cx >= x + 1) return 0;
                return 1 << static_cast<int>((cx - x) * 8);
            };
            auto expectedVertical = [&](double lineX) {
                double t = (lineX - a.x) / (b.x - a.x);
                double cy = a.y + t * (b.y - a.y);
                if (t < 0 || t > 1 || cy < y || cy >= y + 1) return 0;
                return 1 << static_cast<int>((cy - y) * 8);
            };
            EXPECT_EQ(masks[0], expectedHorizontal(y)) << x << "," << y;
            EXPECT_EQ(masks[2], expectedHorizontal(y + 1)) << x << "," << y;
            EXPECT_EQ(masks[3], expectedVertical(x)) << x << "," << y;
            EXPECT_EQ(masks[1], expectedVertical(x + 1)) << x << "," << y;
            const int count = __builtin_popcount(masks[0]) + __builtin_popcount(masks[1]) +
                              __builtin_popcount(masks[2]) + __builtin_popcount(masks[3]);
            EXPECT_EQ(epi.pixelClass(x, y), count == 0 ? PixelClass::Empty : PixelClass::Simple);
        }
    }
}

TEST(EdgePointImage, EndpointsAndCrossingsMakeComplexPixels) {
    EdgePointImage epi(8, 8);
    // An edge ending inside pixel (3, 2): one boundary intersection.
    // Two edges crossing inside pixel (5, 5): four intersections.
    epi.build({makeEdge({-1.0, 2.5}, {3.5, 2.5}), makeEdge({4.2, 4.2}, {6.8, 6.7}),
               makeEdge({4.2, 6.7}, {6.8, 4.2})},
              {});
    EXPECT_EQ(epi.pixelClass(3, 2), PixelClass::Complex);
    EXPECT_EQ(epi.pixelClass(2, 2), PixelClass::Simple);
    EXPECT_EQ(epi.pixelClass(5, 5), PixelClass::Complex);
    EXPECT_EQ(epi.edgeCode(5, 5), kEdgeCodeComplex);
    // A crossing of two edges on both sides of one pixel side: two bits on one side.
    EXPECT_EQ(epi.countPixels(PixelClass::Complex) >= 2, true) << epi.toString();
}

TEST(EdgePointImage, EdgeThroughPixelCornersStaysSimpleAndConsistent) {
    // A diagonal through exact pixel corners: the symbolic perturbation keeps every pixel
    // simple (no single-intersection pixels).
    EdgePointImage epi(8, 8);
    epi.build({makeEdge({-2.0, -2.0}, {10.0, 10.0})}, {});
    EXPECT_EQ(epi.countPixels(PixelClass::Complex), 0u) << epi.toString();
    for (int k = 0; k < 8; ++k) EXPECT_EQ(epi.pixelClass(k, k), PixelClass::Simple) << k;
    // The same for an anti-diagonal and for edges along pixel boundaries.
    epi.build({makeEdge({-2.0, 10.0}, {10.0, -2.0}), makeEdge({-1.0, 3.0}, {9.0, 3.0})}, {});
    for (int y = 0; y < 8; ++y) {
        for (int x = 0; x < 8; ++x) {
            if (std::abs(x + y - 7) > 1 && y != 3) {
                EXPECT_NE(epi.pixelClass(x, y), PixelClass::Complex) << x << "," << y;
            }
        }
    }
}

// ---- Points (§4.3) -------------------------------------------------------------------------

TEST(EdgePointImage, KeepsNearestPointAndItsSubpixelCell) {
    EdgePointImage epi(4, 4);
    epi.build({},
              {makePoint({1.1, 2.9}, Rgb(1, 0, 0), 3.0), makePoint({1.6, 2.3}, Rgb(0, 1, 0), 2.0),
               makePoint({1.9, 2.0}, Rgb(0, 0, 1), 2.5)});
    EXPECT_EQ(epi.samplePosition(1, 2), 2 + 4 * 1);  // (0.6, 0.3) → cell (2, 1)
    EXPECT_EQ(epi.sampleColour(1, 2), Rgb(0, 1, 0));
    EXPECT_EQ(epi.samplePosition(0, 0), -1);
}

// ---- Figure 6 (§5.2) -----------------------------------------------------------------------

TEST(EdgePointImage, Figure6ReachabilityExample) {
    // Pixels a = (3,3), b = (4,3) right of a, c = (3,4) below a, d = (4,4). A near-horizontal
    // edge crosses c and d close to their tops; d's sample lies below it, so the lower
    // (gray) region is d's primary; c has no sample and its larger (lower) region is primary.
    EdgePointImage epi(8, 8);
    epi.build({makeEdge({-1.0, 4.2}, {9.0, 4.2})}, {makePoint({4.5, 4.7}, Rgb(0.5))});
    const int ax = 3, ay = 3;
    ASSERT_EQ(epi.pixelClass(ax, ay), PixelClass::Empty);
    ASSERT_EQ(epi.pixelClass(ax + 1, ay), PixelClass::Empty);
    ASSERT_EQ(epi.pixelClass(ax, ay + 1), PixelClass::Simple);
    ASSERT_EQ(epi.pixelClass(ax + 1, ay + 1), PixelClass::Simple);
    ASSERT_TRUE(epi.sampleUsable(ax + 1, ay + 1));

    const uint8_t a = epi.neighbourCode(ax, ay), b = epi.neighbourCode(ax + 1, ay);
    const uint8_t c = epi.neighbourCode(ax, ay + 1), d = epi.neighbourCode(ax + 1, ay + 1);
    const uint8_t ab = neighbourReachability(NeighbourDirection::Right, a, b);
    const uint8_t ac = neighbourReachability(NeighbourDirection::Down, a, c);
    const uint8_t cd = neighbourReachability(NeighbourDirection::Right, c, d);
    const uint8_t bd = neighbourReachability(NeighbourDirection::Down, b, d);
    // The paper: a↔b = (1,0,0,0), a↔c = (0,1,0,0), c↔d = (1,0,0,1), b↔d = (0,1,0,0).
    EXPECT_EQ(reachabilityMaskToString(ab), "(1,0,0,0)");
    EXPECT_EQ(reachabilityMaskToString(ac), "(0,1,0,0)");
    EXPECT_EQ(reachabilityMaskToString(cd), "(1,0,0,1)");
    EXPECT_EQ(reachabilityMaskToString(bd), "(0,1,0,0)");
    // Chaining: a↔d through b and through c are both (0,1,0,0); combined (0,1,0,0).
    EXPECT_EQ(reachabilityMaskToString(chainReachability(ab, bd)), "(0,1,0,0)");
    EXPECT_EQ(reachabilityMaskToString(chainReachability(ac, cd)), "(0,1,0,0)");
    const auto reach = epi.computeReachability(ax, ay);
    EXPECT_EQ(reachabilityMaskToString(reach[(1 + 2) * 5 + (1 + 2)]), "(0,1,0,0)");
    // So the gray sample in d is unreachable from a and a keeps its own (black) colour.
    Image image = epi.reconstruct(true);
    EXPECT_EQ(epi.primaryReachability(ax, ay) & (1u << (3 * 5 + 3 - 1)), 0u);
    // No sample lies above the edge: a reaches none (highest sampling priority, §5.3).
    EXPECT_EQ(epi.interpolationWeights()[ay * 8 + ax], 0.0f);
    EXPECT_GT(epi.interpolationWeights()[(ay + 1) * 8 + ax + 1], 0.0f);
}

// Soundness of the whole chain (rasterization, codes, primaries, propagation): whenever
// computeReachability says two primary regions reach each other, they are connected on a
// fine grid where each simple pixel's approximated edge (between piece centres) is a wall
// and each complex pixel is solid.
TEST(EdgePointImage, ReachablePrimariesAreConnectedOnAFineGrid) {
    const int W = 14, H = 14, R = 32;
    std::mt19937 rng(21);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    for (int trial = 0; trial < 6; ++trial) {
        std::vector<ScreenEdge> edges;
        for (int k = 0; k < 3; ++k) {
            edges.push_back(
                makeEdge({u(rng) * 20 - 3, u(rng) * 20 - 3}, {u(rng) * 20 - 3, u(rng) * 20 - 3}));
        }
        std::vector<ScreenPoint> points;
        for (int y = 0; y < H; ++y) {
            for (int x = 0; x < W; ++x) {
                if (u(rng) < 0.6) points.push_back(makePoint({x + u(rng), y + u(rng)}, Rgb(1)));
            }
        }
        EdgePointImage epi(W, H);
        epi.build(edges, points);
        // Walls on the fine grid.
        const int FW = W * R, FH = H * R;
        std::vector<bool> blocked(static_cast<size_t>(FW) * FH, false);
        for (int y = 0; y < H; ++y) {
            for (int x = 0; x < W; ++x) {
                if (epi.pixelClass(x, y) == PixelClass::Empty) continue;
                const bool complex = epi.pixelClass(x, y) == PixelClass::Complex;
                const uint16_t code = epi.edgeCode(x, y);
                glm::dvec2 a = positionCentre(edgeCodeStart(code), 8);
                glm::dvec2 b = positionCentre(edgeCodeEnd(code), 8);
                for (int cy = 0; cy < R; ++cy) {
                    for (int cx = 0; cx < R; ++cx) {
                        glm::dvec2 p{(cx + 0.5) / R, (cy + 0.5) / R};
                        glm::dvec2 ab = b - a;
                        double t = glm::clamp(glm::dot(p - a, ab) / glm::dot(ab, ab), 0.0, 1.0);
                        bool wall = complex || glm::length(a + t * ab - p) < 0.6 / R;
                        if (wall) blocked[static_cast<size_t>(y * R + cy) * FW + x * R + cx] = true;
                    }
                }
            }
        }
        std::vector<int> label(blocked.size(), -1);
        int next = 0;
        for (size_t start = 0; start < label.size(); ++start) {
            if (blocked[start] || label[start] >= 0) continue;
            std::queue<size_t> queue;
            queue.push(start);
            label[start] = next;
            while (!queue.empty()) {
                size_t c = queue.front();
                queue.pop();
                const int cx = static_cast<int>(c % FW), cy = static_cast<int>(c / FW);
                const int nx[4] = {cx + 1, cx - 1, cx, cx}, ny[4] = {cy, cy, cy + 1, cy - 1};
                for (int k = 0; k < 4; ++k) {
                    if (nx[k] < 0 || ny[k] < 0 || nx[k] >= FW || ny[k] >= FH) continue;
                    size_t n = static_cast<size_t>(ny[k]) * FW + nx[k];
                    if (blocked[n] || label[n] >= 0) continue;
                    label[n] = next;
                    queue.push(n);
                }
            }
            ++next;
        }
        // Labels of a pixel's primary region (cells on the primary side of its edge).
        auto primaryLabels = [&](int x, int y) {
            std::vector<bool> seen(next, false);
            const uint16_t code = epi.edgeCode(x, y);
            const bool simple = epi.pixelClass(x, y) == PixelClass::Simple;
            glm::dvec2 a = positionCentre(edgeCodeStart(code), 8);
            glm::dvec2 b = positionCentre(edgeCodeEnd(code), 8);
            const int s0 = edgeCodeStart(code) / 8;
            const glm::dvec2 arcCorner = s0 == 0   ? glm::dvec2(1, 0)
                                         : s0 == 1 ? glm::dvec2(1, 1)
                                                   : glm::dvec2(0, 1);
            const double region0Sign = cross(b - a, arcCorner - a);
            for (int cy = 0; cy < R; ++cy) {
                for (int cx = 0; cx < R; ++cx) {
                    int l = label[static_cast<size_t>(y * R + cy) * FW + x * R + cx];
                    if (l < 0) continue;
                    if (simple) {
                        glm::dvec2 p{(cx + 0.5) / R, (cy + 0.5) / R};
                        bool inRegion0 = cross(b - a, p - a) * region0Sign > 0;
                        if (inRegion0 == epi.primaryIsRegion1(x, y)) continue;
                    }
                    seen[l] = true;
                }
            }
            return seen;
        };
        int checked = 0;
        for (int y = 0; y < H; ++y) {
            for (int x = 0; x < W; ++x) {
                if (epi.pixelClass(x, y) == PixelClass::Complex) continue;
                const auto reach = epi.computeReachability(x, y);
                const auto mine = primaryLabels(x, y);
                for (int k = 0; k < 25; ++k) {
                    if (k == 12 || !(reach[k] & kReachPP)) continue;
                    const int px = x + k % 5 - 2, py = y + k / 5 - 2;
                    const auto theirs = primaryLabels(px, py);
                    bool connected = false;
                    for (int l = 0; l < next; ++l) connected = connected || (mine[l] && theirs[l]);
                    ASSERT_TRUE(connected)
                        << "trial " << trial << ": (" << x << ", " << y << ") reaches (" << px
                        << ", " << py << ") but the fine grid separates them; "
                        << edgeCodeToString(epi.edgeCode(x, y), 8) << " / "
                        << edgeCodeToString(epi.edgeCode(px, py), 8);
                    ++checked;
                }
            }
        }
        EXPECT_GT(checked, W * H * 5);
    }
}

// The per-frame reachability map (with its all-empty fast path, and in the parallel build the
// §5.2 reuse of prior scanlines' reachability) equals the full 5×5 propagation for every pixel:
// primary-to-primary over 5×5 and secondary-to-primary over the 3×3 ring.
void expectReachabilityMapMatchesFullPropagation(const EdgePointImage& epi) {
    const int W = epi.width(), H = epi.height();
    int nearEdge = 0, withSecondary = 0;
    for (int y = 0; y < H; ++y) {
        for (int x = 0; x < W; ++x) {
            const auto full = epi.computeReachability(x, y);
            uint32_t expected = 0;
            for (int k = 0, bit = 0; k < 25; ++k) {
                if (k == 12) continue;
                const int px = x + k % 5 - 2, py = y + k / 5 - 2;
                const bool inside = px >= 0 && py >= 0 && px < W && py < H;
                // Outside pixels hold no samples; the fast path may mark them reachable.
                if ((full[k] & kReachPP) ||
                    (!inside && (epi.primaryReachability(x, y) >> bit & 1))) {
                    expected |= 1u << bit;
                }
                ++bit;
            }
            ASSERT_EQ(epi.primaryReachability(x, y), expected) << x << "," << y;
            uint8_t secondary = 0;
            const int ring[8] = {6, 7, 8, 11, 13, 16, 17, 18};
            for (int k = 0; k < 8; ++k) secondary |= ((full[ring[k]] & kReachSP) ? 1 : 0) << k;
            ASSERT_EQ(epi.secondaryReachability(x, y), secondary) << x << "," << y;
            nearEdge += expected != 0xFFFFFFu;
            withSecondary += secondary != 0;
        }
    }
    EXPECT_GT(nearEdge, W * H / 20) << "the scene must have edges";
    EXPECT_GT(withSecondary, W * H / 50) << "the scene must exercise secondary reachability";
}

TEST(EdgePointImage, ReachabilityMapMatchesFullPropagation) {
    const int W = 40, H = 30;
    std::mt19937 rng(5);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    std::vector<ScreenEdge> edges;
    for (int k = 0; k < 12; ++k) {
        edges.push_back(makeEdge({u(rng) * W, u(rng) * H}, {u(rng) * W, u(rng) * H}));
    }
    std::vector<ScreenPoint> points;
    for (int k = 0; k < W * H / 2; ++k)
        points.push_back(makePoint({u(rng) * W, u(rng) * H}, Rgb(1)));
    for (bool parallel : {true, false}) {
        EpiOptions options;
        options.parallel = parallel;
        EdgePointImage epi(W, H, options);
        epi.build(edges, points);
        epi.reconstruct(true);
        expectReachabilityMapMatchesFullPropagation(epi);
    }
}

// ---- Two-colour scenes (§5.3) --------------------------------------------------------------

const Rgb kColourA(1.0, 0.2, 0.0);
const Rgb kColourB(0.0, 0.3, 1.0);

struct TwoColourScene {
    int width = 64, height = 64;
    glm::dvec2 origin, direction;  // the edge line; side A where cross(direction, p − o) > 0

    bool sideA(const glm::dvec2& p) const { return cross(direction, p - origin) > 0.0; }
    Rgb colourAt(const glm::dvec2& p) const { return sideA(p) ? kColourA : kColourB; }

    /// Pixel fully on one side (its closed square does not touch the line): that side's
    /// colour; otherwise nullopt.
    std::optional<Rgb> clearColour(int x, int y) const {
        int a = 0, b = 0;
        for (int k = 0; k < 4; ++k) {
            double s = cross(direction, glm::dvec2(x + (k & 1), y + (k >> 1)) - origin);
            if (s > 1e-9) ++a;
            if (s < -1e-9) ++b;
        }
        if (a == 4) return kColourA;
        if (b == 4) return kColourB;
        return std::nullopt;
    }
    /// The exact image: area coverage of each side (32×32 supersampling).
    Image exact() const {
        Image image(width, height);
        for (int y = 0; y < height; ++y) {
            for (int x = 0; x < width; ++x) {
                Rgb sum(0.0);
                for (int sy = 0; sy < 32; ++sy) {
                    for (int sx = 0; sx < 32; ++sx) {
                        sum += colourAt({x + (sx + 0.5) / 32, y + (sy + 0.5) / 32});
                    }
                }
                image.at(x, y) = sum / 1024.0;
            }
        }
        return image;
    }
    std::vector<ScreenEdge> edges() const {
        return {makeEdge(origin - 1000.0 * direction, origin + 1000.0 * direction)};
    }
    /// One random point in each pixel with probability `density`, coloured by its side.
    std::vector<ScreenPoint> points(double density, unsigned seed) const {
        std::mt19937 rng(seed);
        std::uniform_real_distribution<double> u(0.0, 1.0);
        std::vector<ScreenPoint> pts;
        for (int y = 0; y < height; ++y) {
            for (int x = 0; x < width; ++x) {
                if (u(rng) >= density) continue;
                glm::dvec2 p{x + u(rng), y + u(rng)};
                pts.push_back(makePoint(p, colourAt(p)));
            }
        }
        return pts;
    }
    std::string toString() const {
        std::ostringstream out;
        out << "line through (" << origin.x << ", " << origin.y << ") direction (" << direction.x
            << ", " << direction.y << ")";
        return out.str();
    }
};

std::vector<TwoColourScene> twoColourScenes() {
    std::vector<TwoColourScene> scenes;
    for (double deg : {0.0, 9.0, 33.0, 45.0, 61.0, 90.0, 107.0, 135.0, 172.0, 251.0}) {
        TwoColourScene s;
        double r = deg * M_PI / 180.0;
        s.origin = {32.37, 31.21};
        s.direction = {std::cos(r), std::sin(r)};
        scenes.push_back(s);
    }
    // Exactly on pixel boundaries and through pixel corners.
    TwoColourScene h;
    h.origin = {32.0, 32.0};
    h.direction = {1.0, 0.0};
    scenes.push_back(h);
    TwoColourScene v = h;
    v.direction = {0.0, -1.0};
    scenes.push_back(v);
    TwoColourScene d = h;
    d.direction = {1.0, 1.0};
    scenes.push_back(d);
    TwoColourScene ad = h;
    ad.direction = {-1.0, 1.0};
    scenes.push_back(ad);
    return scenes;
}

double rmsError(const Image& a, const Image& b) {
    double sum = 0.0;
    for (size_t i = 0; i < a.pixels.size(); ++i) {
        Rgb d = a.pixels[i] - b.pixels[i];
        sum += glm::dot(d, d) / 3.0;
    }
    return std::sqrt(sum / a.pixels.size());
}

double maxAbs(const Rgb& d) { return std::max({std::abs(d.x), std::abs(d.y), std::abs(d.z)}); }

TEST(EdgePointImage, TwoColourScenesDoNotBleedAcrossTheEdge) {
    for (const TwoColourScene& scene : twoColourScenes()) {
        SCOPED_TRACE(scene.toString());
        EdgePointImage epi(scene.width, scene.height);
        epi.build(scene.edges(), scene.points(0.7, 5));
        Image image = epi.reconstruct(true);
        Image exact = scene.exact();
        double worstCrossed = 0.0;
        double sumCrossed = 0.0;
        int crossed = 0;
        for (int y = 0; y < scene.height; ++y) {
            for (int x = 0; x < scene.width; ++x) {
                const Rgb got = image.at(x, y);
                if (auto clear = scene.clearColour(x, y)) {
                    ASSERT_LT(maxAbs(got - *clear), 1e-5)
                        << "pixel (" << x << ", " << y << ") fully on one side got (" << got.x
                        << ", " << got.y << ", " << got.z << "); " << epi.toString();
                } else {
                    // Pixels the edge crosses: anti-aliased towards the exact coverage.
                    double e = maxAbs(got - exact.at(x, y));
                    worstCrossed = std::max(worstCrossed, e);
                    sumCrossed += e;
                    ++crossed;
                }
            }
        }
        ASSERT_GT(crossed, 0);
        EXPECT_LT(sumCrossed / crossed, 0.08) << "mean error on crossed pixels";
        EXPECT_LT(worstCrossed, 0.6) << "worst crossed pixel";
    }
}

TEST(EdgePointImage, CacheModeBleedsAndEdgesReduceTheError) {
    for (const TwoColourScene& scene : twoColourScenes()) {
        SCOPED_TRACE(scene.toString());
        EdgePointImage epi(scene.width, scene.height);
        epi.build(scene.edges(), scene.points(0.7, 9));
        Image withEdges = epi.reconstruct(true);
        Image cache = epi.reconstruct(false);
        Image exact = scene.exact();
        int bleeding = 0;
        for (int y = 0; y < scene.height; ++y) {
            for (int x = 0; x < scene.width; ++x) {
                auto clear = scene.clearColour(x, y);
                if (clear && maxAbs(cache.at(x, y) - *clear) > 0.01) ++bleeding;
            }
        }
        // Without edges the no-bleed check of the test above fails.
        EXPECT_GT(bleeding, scene.width / 2) << "cache mode should blur across the edge";
        const double epiError = rmsError(withEdges, exact);
        const double cacheError = rmsError(cache, exact);
        EXPECT_LT(epiError, 0.35 * cacheError) << "epi " << epiError << " cache " << cacheError;
    }
}

TEST(EdgePointImage, SparsePointsStillRespectTheEdge) {
    // At 20% density (the paper's Figure 11) some pixels have no reachable sample; those fall
    // back to the unconstrained estimate, but the error stays well below the cache's.
    TwoColourScene scene = twoColourScenes()[2];
    EdgePointImage epi(scene.width, scene.height);
    epi.build(scene.edges(), scene.points(0.2, 3));
    Image withEdges = epi.reconstruct(true);
    Image cache = epi.reconstruct(false);
    // Compare where the cache has any point within 5×5 (both leave the rest black).
    const std::vector<float> cacheWeight = epi.interpolationWeights();
    const Image exact = scene.exact();
    double epiSum = 0.0, cacheSum = 0.0;
    for (size_t i = 0; i < exact.pixels.size(); ++i) {
        if (cacheWeight[i] == 0.0f) continue;
        epiSum +=
            glm::dot(withEdges.pixels[i] - exact.pixels[i], withEdges.pixels[i] - exact.pixels[i]);
        cacheSum += glm::dot(cache.pixels[i] - exact.pixels[i], cache.pixels[i] - exact.pixels[i]);
    }
    EXPECT_LT(epiSum, 0.1 * cacheSum) << "squared error epi " << epiSum << " cache " << cacheSum;
}

// ---- Depth culling (§4.5) ------------------------------------------------------------------

TEST(EdgePointImage, OccludedEdgesAreCulledByFilteredPointDepth) {
    const int W = 16, H = 16;
    std::vector<ScreenPoint> points;
    for (int y = 0; y < H; ++y) {
        for (int x = 0; x < W / 2; ++x)
            points.push_back(makePoint({x + 0.5, y + 0.5}, Rgb(1), 2.0));
    }
    EdgePointImage epi(W, H);
    // Behind the points (left half): culled. In front: kept. Right half has no points: kept.
    epi.build({makeEdge({-1.0, 3.5}, {7.5, 3.5}, 3.0)}, points);
    EXPECT_EQ(epi.countPixels(PixelClass::Simple), 0u) << epi.toString();
    EXPECT_GT(epi.culledIntersections(), 0u);
    epi.build({makeEdge({-1.0, 3.5}, {7.5, 3.5}, 2.01)}, points);
    EXPECT_EQ(epi.countPixels(PixelClass::Simple), 7u) << epi.toString();
    epi.build({makeEdge({8.5, 3.5}, {17.0, 3.5}, 3.0)}, points);
    EXPECT_EQ(epi.countPixels(PixelClass::Simple), 7u) << epi.toString();
    // Culling off keeps everything.
    EdgePointImage noCull(W, H, EpiOptions{.cullOccludedEdges = false});
    noCull.build({makeEdge({-1.0, 3.5}, {7.5, 3.5}, 3.0)}, points);
    EXPECT_EQ(noCull.countPixels(PixelClass::Simple), 7u) << noCull.toString();
}

// ---- Complex filter (§5.4) -----------------------------------------------------------------

TEST(EdgePointImage, ComplexFilterImprovesCrossingPixels) {
    // Two crossing edges split the plane into four colours; the pixels around the crossing
    // are complex. The subpixel filter must bring them closer to the exact coverage.
    const int W = 24, H = 24;
    const glm::dvec2 centre{12.3, 11.6};
    const glm::dvec2 d1{std::cos(0.3), std::sin(0.3)}, d2{std::cos(1.9), std::sin(1.9)};
    const Rgb colours[4] = {Rgb(1, 0, 0), Rgb(0, 1, 0), Rgb(0, 0, 1), Rgb(1, 1, 0)};
    auto colourAt = [&](glm::dvec2 p) {
        int q = (cross(d1, p - centre) > 0 ? 1 : 0) + (cross(d2, p - centre) > 0 ? 2 : 0);
        return colours[q];
    };
    std::vector<ScreenEdge> edges{makeEdge(centre - 100.0 * d1, centre + 100.0 * d1),
                                  makeEdge(centre - 100.0 * d2, centre + 100.0 * d2)};
    double errorOn = 0.0, errorOff = 0.0;
    int complexPixels = 0;
    for (unsigned seed = 1; seed <= 6; ++seed) {
        std::mt19937 rng(seed);
        std::uniform_real_distribution<double> u(0.0, 1.0);
        std::vector<ScreenPoint> points;
        for (int y = 0; y < H; ++y) {
            for (int x = 0; x < W; ++x) {
                glm::dvec2 p{x + u(rng), y + u(rng)};
                points.push_back(makePoint(p, colourAt(p)));
            }
        }
        EdgePointImage on(W, H);
        EdgePointImage off(W, H, EpiOptions{.complexFilter = false});
        on.build(edges, points);
        off.build(edges, points);
        Image a = on.reconstruct(true), b = off.reconstruct(true);
        for (int y = 0; y < H; ++y) {
            for (int x = 0; x < W; ++x) {
                if (on.pixelClass(x, y) != PixelClass::Complex) continue;
                ++complexPixels;
                Rgb exact(0.0);
                for (int k = 0; k < 256; ++k) {
                    exact += colourAt({x + (k % 16 + 0.5) / 16, y + (k / 16 + 0.5) / 16});
                }
                exact /= 256.0;
                errorOn += glm::length(a.at(x, y) - exact);
                errorOff += glm::length(b.at(x, y) - exact);
            }
        }
    }
    ASSERT_GT(complexPixels, 0);
    std::cout << "complex pixels " << complexPixels << ": mean error with filter "
              << errorOn / complexPixels << ", without " << errorOff / complexPixels << "\n";
    EXPECT_LT(errorOn, 0.8 * errorOff);
}

// ---- Edge cases ----------------------------------------------------------------------------

TEST(EdgePointImage, EmptyPointSetGivesBlackImage) {
    EdgePointImage epi(16, 16);
    epi.build({makeEdge({-3.0, 2.2}, {20.0, 13.7})}, {});
    Image image = epi.reconstruct(true);
    for (const Rgb& c : image.pixels) EXPECT_EQ(c, Rgb(0.0));
    for (float w : epi.interpolationWeights()) EXPECT_EQ(w, 0.0f);
    Image cache = epi.reconstruct(false);
    for (const Rgb& c : cache.pixels) EXPECT_EQ(c, Rgb(0.0));
}

TEST(EdgePointImage, PointsOutsideTheImageAreIgnored) {
    const double nan = std::numeric_limits<double>::quiet_NaN();
    const double inf = std::numeric_limits<double>::infinity();
    EdgePointImage epi(8, 8);
    epi.build({}, {makePoint({-0.5, 3.0}, Rgb(1)), makePoint({8.0, 3.0}, Rgb(1)),
                   makePoint({3.0, 8.0}, Rgb(1)), makePoint({3.0, -1e-9}, Rgb(1)),
                   makePoint({nan, 3.0}, Rgb(1)), makePoint({inf, 3.0}, Rgb(1)),
                   makePoint({3.5, 3.5}, Rgb(1), nan), makePoint({2.5, 2.5}, Rgb(nan, 0, 0)),
                   makePoint({7.999, 7.999}, Rgb(0.25))});
    int kept = 0;
    for (int y = 0; y < 8; ++y) {
        for (int x = 0; x < 8; ++x) kept += epi.samplePosition(x, y) >= 0;
    }
    EXPECT_EQ(kept, 1);
    EXPECT_EQ(epi.samplePosition(7, 7), 15);
    Image image = epi.reconstruct(true);
    EXPECT_NEAR(image.at(7, 7).x, 0.25, 1e-6);
    EXPECT_NEAR(image.at(5, 5).x, 0.25, 1e-6);  // within 5×5 of the only point
    EXPECT_EQ(image.at(0, 0), Rgb(0.0));
}

TEST(EdgePointImage, DegenerateAndOutsideEdgesChangeNothing) {
    const double nan = std::numeric_limits<double>::quiet_NaN();
    EdgePointImage epi(10, 10);
    epi.build({makeEdge({4.5, 4.5}, {4.5, 4.5}), makeEdge({3.0, 3.0}, {3.0, 3.0}),
               makeEdge({-5.0, -1.0}, {-1.0, -5.0}), makeEdge({11.0, 0.0}, {30.0, 20.0}),
               makeEdge({-3.0, 10.5}, {13.0, 10.5}), makeEdge({nan, 1.0}, {5.0, 5.0}),
               makeEdge({1e300, -1e300}, {1e300, 1e300}), makeEdge({0.5, -1e300}, {3.0, -1e299}),
               makeEdge({-1e300, 2.0}, {-1e299, 3.0}), makeEdge({1e300, 2.0}, {1e301, 3.0})},
              {makePoint({5.5, 5.5}, Rgb(0.5))});
    EXPECT_EQ(epi.countPixels(PixelClass::Empty), 100u) << epi.toString();
    Image image = epi.reconstruct(true);
    EXPECT_NEAR(image.at(5, 5).y, 0.5, 1e-6);
    // Huge but finite coordinates crossing the image rasterize normally.
    epi.build({makeEdge({-1e12, 5.5}, {1e12, 5.5})}, {});
    EXPECT_EQ(epi.countPixels(PixelClass::Simple), 10u) << epi.toString();
}

TEST(EdgePointImage, TinyImagesAndBadSizes) {
    EXPECT_THROW(EdgePointImage(0, 5), std::invalid_argument);
    EXPECT_THROW(EdgePointImage(5, -1), std::invalid_argument);
    EdgePointImage one(1, 1);
    one.build({makeEdge({-1.0, 0.3}, {2.0, 0.6})}, {makePoint({0.5, 0.9}, Rgb(0.7))});
    EXPECT_EQ(one.pixelClass(0, 0), PixelClass::Simple);
    Image image = one.reconstruct(true);
    EXPECT_TRUE(std::isfinite(image.at(0, 0).x));
    Image classes = one.classificationImage();
    EXPECT_EQ(classes.width, 1);
}

// ---- Timing printout (not a pass/fail criterion) --------------------------------------------

/// Edge soup resembling a scene's silhouettes and shadows: closed polygons (circles) and long
/// straight edges, ~8% simple pixels at 512×512.
std::vector<ScreenEdge> syntheticEdges(int W, int H, unsigned seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    std::vector<ScreenEdge> edges;
    for (int c = 0; c < 60; ++c) {
        glm::dvec2 centre{u(rng) * W, u(rng) * H};
        double radius = 8.0 + u(rng) * 70.0;
        const int segments = 48;
        for (int k = 0; k < segments; ++k) {
            double a0 = 2 * M_PI * k / segments, a1 = 2 * M_PI * (k + 1) / segments;
            edges.push_back(makeEdge(centre + radius * glm::dvec2(std::cos(a0), std::sin(a0)),
                                     centre + radius * glm::dvec2(std::cos(a1), std::sin(a1))));
        }
    }
    for (int k = 0; k < 40; ++k) {
        edges.push_back(makeEdge({u(rng) * W, u(rng) * H}, {u(rng) * W, u(rng) * H}));
    }
    return edges;
}

// ---- Parallel stages equal the serial reference --------------------------------------------

/// Dense, adversarial input: many small edges (tiny-triangle silhouettes), long and nearly
/// horizontal ones crossing every band, edges on pixel corners and half-pixel lines, far
/// outside the image and non-finite; points at random depths with ties in a pixel.
void denseScene(int W, int H, unsigned seed, std::vector<ScreenEdge>& edges,
                std::vector<ScreenPoint>& points) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    edges = syntheticEdges(W, H, seed);
    for (int k = 0; k < 20000; ++k) {  // short edges, a pixel or two long, various depths
        glm::dvec2 a{u(rng) * W, u(rng) * H};
        ScreenEdge e =
            makeEdge(a, a + glm::dvec2(u(rng) * 3 - 1.5, u(rng) * 3 - 1.5), 0.5 + 4 * u(rng));
        e.depthB = 0.5 + 4 * u(rng);
        edges.push_back(e);
    }
    edges.push_back(makeEdge({-50.0, 100.25}, {W + 50.0, 100.25 + 1e-12}));  // near-horizontal
    edges.push_back(makeEdge({-50.0, 3.5}, {W + 50.0, H - 3.5}));
    edges.push_back(makeEdge({10.0, 10.0}, {20.0, 20.0}));       // through pixel corners
    edges.push_back(makeEdge({30.5, -10.0}, {30.5, H + 10.0}));  // on a half-pixel line
    edges.push_back(makeEdge({0.0, H - 0.0}, {W * 1.0, 0.0}));
    edges.push_back(makeEdge({-1e30, 5.0}, {1e30, 7.0}));
    edges.push_back(makeEdge({5.0, -1e30}, {7.0, 1e30}));
    edges.push_back(makeEdge({std::nan(""), 5.0}, {7.0, 9.0}));
    for (int y = 0; y < H; ++y) {
        for (int x = 0; x < W; ++x) {
            if (u(rng) < 0.3) continue;
            const double depth = u(rng) < 0.2 ? 2.0 : 1.0 + 3 * u(rng);
            points.push_back(makePoint({x + u(rng), y + u(rng)}, Rgb(u(rng), 0.5, u(rng)), depth));
            if (u(rng) < 0.1)  // a second point, same depth: the first must win
                points.push_back(makePoint({x + u(rng), y + u(rng)}, Rgb(0.9, 0.1, 0.1), depth));
        }
    }
    points.push_back(makePoint({std::nan(""), 3.0}, Rgb(1.0)));
}

TEST(EdgePointImage, ParallelStagesEqualSerialBitForBit) {
    const int W = 256, H = 197;  // rows not a multiple of the band count
    std::vector<ScreenEdge> edges;
    std::vector<ScreenPoint> points;
    denseScene(W, H, 5, edges, points);
    EpiOptions serialOptions;
    serialOptions.parallel = false;
    EdgePointImage parallel(W, H), serial(W, H, serialOptions);
    parallel.build(edges, points);
    serial.build(edges, points);
    EXPECT_EQ(parallel.culledIntersections(), serial.culledIntersections());
    EXPECT_GT(serial.culledIntersections(), 0u) << "the scene must exercise depth culling";
    EXPECT_GT(serial.countPixels(PixelClass::Complex), 1000u) << serial.toString();
    int differing = 0;
    for (int y = 0; y < H; ++y) {
        for (int x = 0; x < W; ++x) {
            const bool same = parallel.boundaryMasks(x, y) == serial.boundaryMasks(x, y) &&
                              parallel.edgeCode(x, y) == serial.edgeCode(x, y) &&
                              parallel.samplePosition(x, y) == serial.samplePosition(x, y) &&
                              parallel.sampleColour(x, y) == serial.sampleColour(x, y) &&
                              parallel.neighbourCode(x, y) == serial.neighbourCode(x, y);
            differing += !same;
        }
    }
    EXPECT_EQ(differing, 0) << "pixels whose EPI state differs";
    for (bool useEdges : {true, false}) {
        const Image a = parallel.reconstruct(useEdges);
        const Image b = serial.reconstruct(useEdges);
        ASSERT_EQ(a.pixels.size(), b.pixels.size());
        int diff = 0;
        for (size_t k = 0; k < a.pixels.size(); ++k) diff += a.pixels[k] != b.pixels[k];
        EXPECT_EQ(diff, 0) << "pixels differing, useEdges " << useEdges;
        EXPECT_EQ(parallel.interpolationWeights(), serial.interpolationWeights());
    }
    // The §5.2 reuse of prior scanlines on the dense scene (complex pixels, image borders).
    parallel.reconstruct(true);
    expectReachabilityMapMatchesFullPropagation(parallel);
    // Points in no particular order (bands then read every chunk of points).
    std::vector<ScreenPoint> shuffled = points;
    std::shuffle(shuffled.begin(), shuffled.end(), std::mt19937(9));
    parallel.build(edges, shuffled);
    serial.build(edges, shuffled);
    {
        const Image a = parallel.reconstruct(true), b = serial.reconstruct(true);
        EXPECT_EQ(a.pixels, b.pixels) << "shuffled points";
    }
    // The band split must not matter either: an image whose height is below the band count.
    EdgePointImage thinParallel(W, 5), thinSerial(W, 5, serialOptions);
    thinParallel.build(edges, points);
    thinSerial.build(edges, points);
    const Image a = thinParallel.reconstruct(true), b = thinSerial.reconstruct(true);
    EXPECT_EQ(a.pixels, b.pixels);
}

// The render cache's points (one per pixel, in pixel order) take placement's scatter fast
// path; any order violation, also one straddling two chunks of points, must fall back to the
// general rule. Each input against the serial reference, pixel by pixel and image by image.
TEST(EdgePointImage, SortedPointsFastPathEqualsSerial) {
    const int W = 256, H = 197;
    std::vector<ScreenEdge> edges;
    std::vector<ScreenPoint> dense;
    denseScene(W, H, 7, edges, dense);
    // One point per pixel in pixel order (the first of each pixel), with a non-finite point
    // and one outside the image in between (ignored by both paths).
    std::vector<ScreenPoint> sorted;
    long long last = -1;
    for (const ScreenPoint& p : dense) {
        if (!(p.position.x >= 0 && p.position.y >= 0)) continue;
        const long long i =
            static_cast<long long>(p.position.y) * W + static_cast<long long>(p.position.x);
        if (i <= last) continue;
        last = i;
        sorted.push_back(p);
        if (sorted.size() == 5000) sorted.push_back(makePoint({std::nan(""), 1.0}, Rgb(1.0)));
        if (sorted.size() == 7000) sorted.push_back(makePoint({W + 1.0, 1.0}, Rgb(1.0)));
    }
    ASSERT_GT(sorted.size(), 3u * 4096);
    // A farther point in the pixel of point 4095 as the first of the second chunk: the first
    // point must keep the pixel (a scatter would let the later one overwrite it).
    std::vector<ScreenPoint> straddling = sorted;
    ScreenPoint farther = straddling[4095];
    farther.depth *= 2.0;
    farther.colour = Rgb(0.0, 1.0, 0.0);
    straddling.insert(straddling.begin() + 4096, farther);
    // The same inside a chunk.
    std::vector<ScreenPoint> within = sorted;
    farther = within[99];
    farther.depth *= 2.0;
    farther.colour = Rgb(0.0, 1.0, 0.0);
    within.insert(within.begin() + 100, farther);

    EpiOptions serialOptions;
    serialOptions.parallel = false;
    for (const auto* points : {&sorted, &straddling, &within}) {
        EdgePointImage parallel(W, H), serial(W, H, serialOptions);
        // A previous frame's state must not leak into the scatter.
        parallel.build(edges, dense);
        parallel.build(edges, *points);
        serial.build(edges, *points);
        int differing = 0, withPoint = 0;
        for (int y = 0; y < H; ++y) {
            for (int x = 0; x < W; ++x) {
                differing += !(parallel.samplePosition(x, y) == serial.samplePosition(x, y) &&
                               parallel.sampleColour(x, y) == serial.sampleColour(x, y) &&
                               parallel.edgeCode(x, y) == serial.edgeCode(x, y) &&
                               parallel.neighbourCode(x, y) == serial.neighbourCode(x, y) &&
                               parallel.sampleUsable(x, y) == serial.sampleUsable(x, y));
                withPoint += serial.samplePosition(x, y) >= 0;
            }
        }
        EXPECT_EQ(differing, 0);
        EXPECT_GT(withPoint, W * H / 2);
        const Image a = parallel.reconstruct(true), b = serial.reconstruct(true);
        EXPECT_EQ(a.pixels, b.pixels);
    }
    // The first point keeps its pixel (so the fallback really ran).
    for (const auto* points : {&straddling, &within}) {
        EdgePointImage check(W, H);
        check.build(edges, *points);
        const int n = points == &straddling ? 4095 : 99;
        const glm::dvec2 q = (*points)[n].position;
        const Rgb kept = check.sampleColour(static_cast<int>(q.x), static_cast<int>(q.y));
        EXPECT_LT(glm::length(kept - (*points)[n].colour), 1e-6) << kept.y;
    }
}

TEST(EdgePointImage, TimingPrintout512) {
    const int W = 512, H = 512;
    const auto edges = syntheticEdges(W, H, 17);
    for (double density : {0.02, 1.0}) {
        std::mt19937 rng(3);
        std::uniform_real_distribution<double> u(0.0, 1.0);
        std::vector<ScreenPoint> points;
        for (int y = 0; y < H; ++y) {
            for (int x = 0; x < W; ++x) {
                if (density < 1.0 && u(rng) >= density) continue;
                points.push_back(makePoint({x + u(rng), y + u(rng)}, Rgb(u(rng), 0.5, 0.2)));
            }
        }
        EdgePointImage epi(W, H);
        EpiStageTimes best;
        best.reachabilityMs = best.interpolateMs = best.antiAliasMs = 1e9;
        double bestReconstruct = 1e9;
        // Process CPU time (all threads) of reconstruct(): robust to other load on the machine.
        auto cpuMs = [] {
            timespec t;
            clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
            return t.tv_sec * 1e3 + t.tv_nsec * 1e-6;
        };
        double bestCpu = 1e9;
        for (int run = 0; run < 5; ++run) {
            epi.build(edges, points);
            const double c0 = cpuMs();
            Image image = epi.reconstruct(true);
            bestCpu = std::min(bestCpu, cpuMs() - c0);
            if (epi.stageTimes().reconstructMs() < bestReconstruct) {
                bestReconstruct = epi.stageTimes().reconstructMs();
                best = epi.stageTimes();
            }
        }
        std::cout << "512x512, " << density * 100 << "% points, " << edges.size()
                  << " edges: " << epi.toString() << "\n  best of 5 (wall): " << best.toString()
                  << "\n  reconstruct() CPU time, all threads, incl. complex filter: " << bestCpu
                  << " ms\n";
        EXPECT_GT(epi.countPixels(PixelClass::Simple), 0u);
    }
}

}  // namespace
}  // namespace penumbra
