// The EPI tables (Bala et al. 2003 §4.2–4.3, §5.2) against brute force: every entry of the
// four 256-entry neighbour reachability tables against a flood fill of the two pixels
// rasterized on a fine subpixel grid; chaining against path enumeration on that same flood
// fill; region areas and edge-ambiguous sample cells against dense point sampling.

#include "render/display/reachability.h"

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <iostream>
#include <queue>
#include <random>
#include <sstream>
#include <string>
#include <vector>

namespace penumbra {
namespace {

// The boundary convention written out independently of the library: clockwise from the
// top-left corner, top → right → bottom → left, x right and y down.
glm::dvec2 referenceBoundaryPoint(int side, double t) {
    if (side == 0) return {t, 0.0};
    if (side == 1) return {1.0, t};
    if (side == 2) return {1.0 - t, 1.0};
    return {0.0, 1.0 - t};
}

double cross(const glm::dvec2& u, const glm::dvec2& v) { return u.x * v.y - u.y * v.x; }

double distanceToSegment(const glm::dvec2& p, const glm::dvec2& a, const glm::dvec2& b) {
    glm::dvec2 ab = b - a;
    double t = glm::clamp(glm::dot(p - a, ab) / glm::dot(ab, ab), 0.0, 1.0);
    glm::dvec2 q = a + t * ab - p;
    return std::sqrt(glm::dot(q, q));
}

/// One pixel's configuration: empty, complex, or an edge between boundary parameters on two
/// sides (in the pixel's own local frame).
struct PixelEdge {
    int type = 0;  // neighbour type 0..7
    int side0 = -1, side1 = -1;
    double t0 = 0, t1 = 0;
    bool primaryIsRegion1 = false;
};

/// Two unit pixels side by side on a fine grid, each with its edge drawn as a barrier;
/// 4-connected components of the free cells.
class FloodFill {
public:
    static constexpr int kRes = 64;  // cells per pixel side

    FloodFill(NeighbourDirection direction, const PixelEdge& a, const PixelEdge& b) {
        // Pixel b's offset from a.
        glm::ivec2 offset = direction == NeighbourDirection::Right  ? glm::ivec2(1, 0)
                            : direction == NeighbourDirection::Down ? glm::ivec2(0, 1)
                            : direction == NeighbourDirection::Left ? glm::ivec2(-1, 0)
                                                                    : glm::ivec2(0, -1);
        mOriginA = glm::dvec2(offset.x < 0 ? 1 : 0, offset.y < 0 ? 1 : 0);
        mOriginB = mOriginA + glm::dvec2(offset);
        mW = (offset.x != 0 ? 2 : 1) * kRes;
        mH = (offset.y != 0 ? 2 : 1) * kRes;
        mLabel.assign(static_cast<size_t>(mW) * mH, -1);
        std::vector<bool> blocked(mLabel.size(), false);
        for (const auto& [pixel, origin] : {std::pair{a, mOriginA}, std::pair{b, mOriginB}}) {
            if (pixel.type < 1 || pixel.type > 6) continue;
            glm::dvec2 p = origin + referenceBoundaryPoint(pixel.side0, pixel.t0);
            glm::dvec2 q = origin + referenceBoundaryPoint(pixel.side1, pixel.t1);
            for (int y = 0; y < mH; ++y) {
                for (int x = 0; x < mW; ++x) {
                    glm::dvec2 c{(x + 0.5) / kRes, (y + 0.5) / kRes};
                    if (distanceToSegment(c, p, q) < 0.75 / kRes) blocked[y * mW + x] = true;
                }
            }
        }
        int next = 0;
        for (int start = 0; start < mW * mH; ++start) {
            if (blocked[start] || mLabel[start] >= 0) continue;
            std::queue<int> queue;
            queue.push(start);
            mLabel[start] = next;
            while (!queue.empty()) {
                int cell = queue.front();
                queue.pop();
                int x = cell % mW;
                int y = cell / mW;
                const int nx[4] = {x + 1, x - 1, x, x};
                const int ny[4] = {y, y, y + 1, y - 1};
                for (int k = 0; k < 4; ++k) {
                    if (nx[k] < 0 || ny[k] < 0 || nx[k] >= mW || ny[k] >= mH) continue;
                    int n = ny[k] * mW + nx[k];
                    if (blocked[n] || mLabel[n] >= 0) continue;
                    mLabel[n] = next;
                    queue.push(n);
                }
            }
            ++next;
        }
    }

    /// Labels of the free cells of pixel region r (0/1) of a pixel: region 0 is the side of
    /// the edge where the clockwise boundary arc from the first to the second endpoint lies.
    std::vector<int> regionLabels(const PixelEdge& pixel, bool isA, int region) const {
        glm::dvec2 origin = isA ? mOriginA : mOriginB;
        std::vector<int> labels;
        glm::dvec2 p = referenceBoundaryPoint(pixel.side0, pixel.t0);
        glm::dvec2 q = referenceBoundaryPoint(pixel.side1, pixel.t1);
        // A point on the arc: the corner where side0 ends.
        double arcSign = cross(q - p, referenceBoundaryPoint(pixel.side0, 1.0) - p);
        for (int y = 0; y < kRes; ++y) {
            for (int x = 0; x < kRes; ++x) {
                glm::dvec2 local{(x + 0.5) / kRes, (y + 0.5) / kRes};
                int gx = static_cast<int>(origin.x) * kRes + x;
                int gy = static_cast<int>(origin.y) * kRes + y;
                int label = mLabel[gy * mW + gx];
                if (label < 0) continue;
                if (pixel.type >= 1 && pixel.type <= 6) {
                    bool inRegion0 = cross(q - p, local - p) * arcSign > 0.0;
                    if (inRegion0 != (region == 0)) continue;
                } else if (region != 0) {
                    continue;
                }
                labels.push_back(label);
            }
        }
        return labels;
    }

private:
    glm::dvec2 mOriginA, mOriginB;
    int mW = 0, mH = 0;
    std::vector<int> mLabel;
};

bool shareLabel(const std::vector<int>& a, const std::vector<int>& b) {
    std::vector<bool> seen;
    for (int l : a) {
        if (l >= static_cast<int>(seen.size())) seen.resize(l + 1, false);
        seen[l] = true;
    }
    for (int l : b) {
        if (l < static_cast<int>(seen.size()) && seen[l]) return true;
    }
    return false;
}

constexpr std::array<std::array<int, 2>, 7> kSidesOfType{
    {{-1, -1}, {0, 1}, {0, 2}, {0, 3}, {1, 2}, {1, 3}, {2, 3}}};

/// A random concrete pixel for a 4-bit neighbour code. `sharedSide` is the pixel's side on
/// the common boundary; `sharedT` the crossing parameter there (clockwise on that side).
PixelEdge concretePixel(uint8_t code, int sharedSide, double sharedT, std::mt19937& rng) {
    PixelEdge pixel;
    pixel.type = code & 7;
    pixel.primaryIsRegion1 = (code & 8) != 0 && pixel.type >= 1 && pixel.type <= 6;
    if (pixel.type < 1 || pixel.type > 6) return pixel;
    std::uniform_real_distribution<double> u(0.1, 0.9);
    pixel.side0 = kSidesOfType[pixel.type][0];
    pixel.side1 = kSidesOfType[pixel.type][1];
    pixel.t0 = pixel.side0 == sharedSide ? sharedT : u(rng);
    pixel.t1 = pixel.side1 == sharedSide ? sharedT : u(rng);
    return pixel;
}

// Every entry of the four neighbour tables against flood fill on a fine grid (§5.2).
TEST(NeighbourReachability, EveryEntryMatchesFloodFill) {
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> crossing(0.15, 0.85);
    int checked = 0;
    for (int d = 0; d < 4; ++d) {
        const auto direction = static_cast<NeighbourDirection>(d);
        const int sharedA = (d + 1) % 4;  // right, bottom, left, top side of a
        const int sharedB = (sharedA + 2) % 4;
        for (int codeA = 0; codeA < 16; ++codeA) {
            for (int codeB = 0; codeB < 16; ++codeB) {
                const uint8_t got = neighbourReachability(direction, static_cast<uint8_t>(codeA),
                                                          static_cast<uint8_t>(codeB));
                // Two random geometries per entry; the crossing on the shared boundary is
                // one point seen from both pixels (clockwise parameters t and 1 − t).
                for (int trial = 0; trial < 2; ++trial) {
                    double c = crossing(rng);
                    PixelEdge a = concretePixel(static_cast<uint8_t>(codeA), sharedA, c, rng);
                    PixelEdge b = concretePixel(static_cast<uint8_t>(codeB), sharedB, 1.0 - c, rng);
                    FloodFill fill(direction, a, b);
                    uint8_t expected = 0;
                    if (a.type != 7 && b.type != 7) {
                        const bool simpleA = a.type != 0;
                        const bool simpleB = b.type != 0;
                        const int pa = a.primaryIsRegion1 ? 1 : 0;
                        const int pb = b.primaryIsRegion1 ? 1 : 0;
                        auto reach = [&](int ra, int rb) {
                            auto la = fill.regionLabels(a, true, ra);
                            auto lb = fill.regionLabels(b, false, rb);
                            EXPECT_FALSE(la.empty() || lb.empty()) << "region without cells";
                            return shareLabel(la, lb);
                        };
                        if (reach(pa, pb)) expected |= kReachPP;
                        if (simpleB && reach(pa, 1 - pb)) expected |= kReachPS;
                        if (simpleA && reach(1 - pa, pb)) expected |= kReachSP;
                        if (simpleA && simpleB && reach(1 - pa, 1 - pb)) expected |= kReachSS;
                    }
                    ASSERT_EQ(got, expected)
                        << "direction " << d << " codeA " << codeA << " codeB " << codeB
                        << ": table " << reachabilityMaskToString(got) << ", flood fill "
                        << reachabilityMaskToString(expected) << " (crossing " << c << ")";
                    ++checked;
                }
            }
        }
    }
    EXPECT_EQ(checked, 4 * 256 * 2);
}

// The table is symmetric: a ↔ b seen from the other pixel is the transposed mask.
TEST(NeighbourReachability, OppositeDirectionsAreTransposes) {
    auto transpose = [](uint8_t m) {
        return static_cast<uint8_t>((m & (kReachPP | kReachSS)) | ((m & kReachPS) ? kReachSP : 0) |
                                    ((m & kReachSP) ? kReachPS : 0));
    };
    for (int d = 0; d < 2; ++d) {
        for (int a = 0; a < 16; ++a) {
            for (int b = 0; b < 16; ++b) {
                auto forward =
                    neighbourReachability(static_cast<NeighbourDirection>(d),
                                          static_cast<uint8_t>(a), static_cast<uint8_t>(b));
                auto backward =
                    neighbourReachability(static_cast<NeighbourDirection>(d + 2),
                                          static_cast<uint8_t>(b), static_cast<uint8_t>(a));
                EXPECT_EQ(forward, transpose(backward)) << d << " " << a << " " << b;
            }
        }
    }
}

// Chaining (§5.2) against explicit enumeration of the four two-step region paths.
TEST(Chaining, EveryEntryMatchesPathEnumeration) {
    for (int ab = 0; ab < 16; ++ab) {
        for (int bd = 0; bd < 16; ++bd) {
            // Region graph a{P,S} — b{P,S} — d{P,S}.
            auto edgeAB = [&](int ra, int rb) { return (ab >> (ra * 2 + rb)) & 1; };
            auto edgeBD = [&](int rb, int rd) { return (bd >> (rb * 2 + rd)) & 1; };
            uint8_t expected = 0;
            for (int ra = 0; ra < 2; ++ra) {
                for (int rd = 0; rd < 2; ++rd) {
                    for (int rb = 0; rb < 2; ++rb) {
                        if (edgeAB(ra, rb) && edgeBD(rb, rd)) expected |= 1 << (ra * 2 + rd);
                    }
                }
            }
            EXPECT_EQ(chainReachability(static_cast<uint8_t>(ab), static_cast<uint8_t>(bd)),
                      expected)
                << reachabilityMaskToString(static_cast<uint8_t>(ab)) << " then "
                << reachabilityMaskToString(static_cast<uint8_t>(bd));
        }
    }
}

// Edge codes: 10 bits, canonical order, disallowed same-side pairs give empty/complex.
TEST(EdgeCode, EncodingAndClassification) {
    EXPECT_EQ(makeEdgeCode(3, 2, 8), kEdgeCodeComplex);  // both on the top side
    uint16_t code = makeEdgeCode(30, 5, 8);
    EXPECT_EQ(edgeCodeStart(code), 5);
    EXPECT_EQ(edgeCodeEnd(code), 30);
    EXPECT_LT(code, 1024);
    EXPECT_TRUE(isSimpleEdgeCode(code, 8));
    EXPECT_FALSE(isSimpleEdgeCode(kEdgeCodeEmpty, 8));
    EXPECT_FALSE(isSimpleEdgeCode(kEdgeCodeComplex, 8));
    EXPECT_EQ(neighbourType(code, 8), 3);  // top (0) and left (3)
    EXPECT_EQ(makeNeighbourCode(code, 8, true), 3 | kNeighbourPrimaryIsRegion1);
    EXPECT_EQ(makeNeighbourCode(kEdgeCodeComplex, 8, true), kNeighbourTypeComplex);
    int simple = 0;
    for (int c = 0; c < 1024; ++c) simple += isSimpleEdgeCode(static_cast<uint16_t>(c), 8);
    EXPECT_EQ(simple, 6 * 64);  // 6 side pairs × 8 × 8 pieces
}

/// Brute-force check of region areas and edge-ambiguous cells for one table resolution.
void checkCodeTables(const EdgeCodeTables& tables) {
    const int n = tables.piecesPerSide;
    const int m = tables.cellsPerSide;
    std::mt19937 rng(11);
    std::uniform_real_distribution<double> unit(0.0, 1.0);
    int ambiguous = 0;
    int decided = 0;
    for (int c = 0; c < 1024; ++c) {
        const auto code = static_cast<uint16_t>(c);
        if (!isSimpleEdgeCode(code, n)) continue;
        const int p0 = edgeCodeStart(code);
        const int p1 = edgeCodeEnd(code);
        const int s0 = p0 / n, s1 = p1 / n;
        // Area of region 0 of the edge through the piece centres, by dense sampling.
        glm::dvec2 a = referenceBoundaryPoint(s0, (p0 % n + 0.5) / n);
        glm::dvec2 b = referenceBoundaryPoint(s1, (p1 % n + 0.5) / n);
        double arcSign = cross(b - a, referenceBoundaryPoint(s0, 1.0) - a);
        const int kGrid = 200;
        int inside = 0;
        for (int y = 0; y < kGrid; ++y) {
            for (int x = 0; x < kGrid; ++x) {
                glm::dvec2 p{(x + 0.5) / kGrid, (y + 0.5) / kGrid};
                inside += cross(b - a, p - a) * arcSign > 0.0;
            }
        }
        EXPECT_NEAR(tables.region0Area[c], inside / double(kGrid * kGrid), 0.01)
            << edgeCodeToString(code, n);
        // Sample sides: random true edges with endpoints inside the two pieces and random
        // points inside each cell. A decided cell must never be contradicted; an ambiguous
        // cell must be contradicted by some edge (found by the extreme edges and corners).
        for (int cell = 0; cell < m * m; ++cell) {
            const int cx = cell % m, cy = cell / m;
            const SampleSide side = tables.side(code, cell);
            bool seen0 = false, seen1 = false;
            for (int k = 0; k < 300; ++k) {
                // Half the trials at the extremes of pieces and cells, half uniformly inside.
                auto pick = [&]() { return k < 150 ? double(rng() & 1) : unit(rng); };
                glm::dvec2 u = referenceBoundaryPoint(s0, (p0 % n + pick()) / n);
                glm::dvec2 v = referenceBoundaryPoint(s1, (p1 % n + pick()) / n);
                glm::dvec2 x{(cx + pick()) / m, (cy + pick()) / m};
                // Region 0 keeps its orientation over the family (the arc never meets
                // an edge of it), so the centre edge's orientation decides the sign.
                double s = cross(v - u, x - u) * (arcSign > 0.0 ? 1.0 : -1.0);
                if (s > 1e-12) seen0 = true;
                if (s < -1e-12) seen1 = true;
            }
            if (side == SampleSide::Region0) {
                EXPECT_FALSE(seen1) << edgeCodeToString(code, n) << " cell " << cell;
            } else if (side == SampleSide::Region1) {
                EXPECT_FALSE(seen0) << edgeCodeToString(code, n) << " cell " << cell;
            } else {
                EXPECT_TRUE(seen0 && seen1) << edgeCodeToString(code, n) << " cell " << cell;
            }
            (side == SampleSide::Ambiguous ? ambiguous : decided)++;
        }
    }
    // The ambiguous cells are those the family of edges may cross: at most about half.
    std::cout << "pieces " << n << ": " << decided << " decided, " << ambiguous
              << " ambiguous sample cells\n";
    EXPECT_GT(decided, ambiguous * 2 / 3);
}

TEST(EdgeCodeTables, PixelAreasAndSampleSidesMatchSampling) {
    checkCodeTables(EdgeCodeTables::pixel());
}

TEST(EdgeCodeTables, SubpixelAreasAndSampleSidesMatchSampling) {
    checkCodeTables(EdgeCodeTables::subpixel());
}

// Anti-aliasing neighbours lie on the secondary side: for a near-horizontal edge through the
// middle, the region containing the top side is best approximated by the pixel above.
TEST(EdgeCodeTables, AntiAliasNeighbourFollowsTheEdgeNormal) {
    const auto& tables = EdgeCodeTables::pixel();
    // Left side piece 4 from the bottom (y ≈ 0.44) to right side piece 3 (y ≈ 0.44).
    uint16_t code = makeEdgeCode(boundaryPosition(3, 4, 8), boundaryPosition(1, 3, 8), 8);
    // Region 0 is the arc right(1) → left(3) clockwise through the bottom: the lower part.
    EXPECT_NEAR(tables.region0Area[code], 0.5625, 1e-6);
    const auto& upper = tables.antiAliasNeighbours[code * 2 + 1];  // region 1 secondary
    ASSERT_GE(upper.count, 1);
    EXPECT_EQ(upper.dx[0], 0);
    EXPECT_EQ(upper.dy[0], -1);
    const auto& lower = tables.antiAliasNeighbours[code * 2 + 0];
    ASSERT_GE(lower.count, 1);
    EXPECT_EQ(lower.dx[0], 0);
    EXPECT_EQ(lower.dy[0], 1);
}

}  // namespace
}  // namespace penumbra
