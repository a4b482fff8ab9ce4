// The EPI's shortcuts against their references, bit for bit: edges edgeMayMark() rejects
// mark nothing (each alone, and a dense scene built with and without them), the rasterizer's
// floor equals std::floor, and the complex filter's shortcut for pixels without points equals
// the general filter; with EpiOptions::denseComplexLimit, complex pixels in dense clusters keep
// their estimate and every other pixel is as without it.

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <random>
#include <vector>

#include "render/display/edge_point_image.h"

namespace penumbra {
namespace {

ScreenEdge makeEdge(glm::dvec2 a, glm::dvec2 b, double depthA = 1.0, double depthB = 1.0) {
    ScreenEdge e;
    e.a = a;
    e.b = b;
    e.depthA = depthA;
    e.depthB = depthB;
    return e;
}

ScreenPoint makePoint(glm::dvec2 p, Rgb colour, double depth) {
    ScreenPoint s;
    s.position = p;
    s.colour = colour;
    s.depth = depth;
    return s;
}

/// Edges that test edgeMayMark's boundaries: sub-pixel edges anywhere (also on and just off
/// the half-pixel lines), edges hugging the image's sides from outside and inside by tiny
/// amounts, huge and non-finite coordinates, degenerate edges.
std::vector<ScreenEdge> adversarialEdges(int W, int H, unsigned seed, int count) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    const double inf = std::numeric_limits<double>::infinity();
    auto snap = [&](double v) {  // often exactly on a half-pixel line, or one ulp beside it
        const double r = u(rng);
        if (r < 0.2) return std::round(2.0 * v) / 2.0;
        if (r < 0.3) return std::nextafter(std::round(2.0 * v) / 2.0, inf);
        if (r < 0.4) return std::nextafter(std::round(2.0 * v) / 2.0, -inf);
        return v;
    };
    std::vector<ScreenEdge> edges;
    for (int k = 0; k < count; ++k) {
        const int kind = static_cast<int>(u(rng) * 6);
        glm::dvec2 a{snap(-3.0 + u(rng) * (W + 6)), snap(-3.0 + u(rng) * (H + 6))};
        glm::dvec2 b;
        if (kind <= 2) {  // tiny to a pixel or so
            const double len = kind == 0 ? 0.05 : kind == 1 ? 0.5 : 1.5;
            b = {snap(a.x + (u(rng) - 0.5) * len), snap(a.y + (u(rng) - 0.5) * len)};
        } else if (kind == 3) {  // along a side, just outside or inside
            const double eps = std::ldexp(u(rng), -static_cast<int>(u(rng) * 50));
            const int side = static_cast<int>(u(rng) * 4);
            const double s = (u(rng) < 0.5 ? -1.0 : 1.0) * eps;
            if (side == 0) a.x = s, b = {s - eps * u(rng), a.y + (u(rng) - 0.5) * 8};
            if (side == 1) a.x = W + s, b = {W + s + eps * u(rng), a.y + (u(rng) - 0.5) * 8};
            if (side == 2) a.y = s, b = {a.x + (u(rng) - 0.5) * 8, s - eps * u(rng)};
            if (side == 3) a.y = H + s, b = {a.x + (u(rng) - 0.5) * 8, H + s + eps * u(rng)};
        } else if (kind == 4) {  // far away or huge
            const double big = std::ldexp(1.0, static_cast<int>(u(rng) * 1000));
            b = {a.x + (u(rng) - 0.5) * big, a.y + (u(rng) - 0.5) * big};
            if (u(rng) < 0.3) a = {a.x - big, a.y - big * u(rng)};
        } else {  // degenerate, non-finite or on a pixel corner
            const double r = u(rng);
            b = r < 0.3 ? a : r < 0.5 ? glm::dvec2(std::nan(""), a.y) : glm::dvec2(a.x, inf);
            if (r > 0.8) a = {std::floor(a.x), std::floor(a.y)}, b = a + glm::dvec2(0.5, 0.25);
        }
        edges.push_back(makeEdge(a, b, 0.5 + 4 * u(rng), 0.5 + 4 * u(rng)));
    }
    return edges;
}

/// Every mask (pixel boundaries and half-pixel lines), code and sample state, and the number
/// of pixels where any of them differ.
int differingPixels(const EdgePointImage& a, const EdgePointImage& b) {
    int differing = 0;
    for (int y = 0; y < a.height(); ++y)
        for (int x = 0; x < a.width(); ++x)
            differing += !(a.boundaryMasks(x, y) == b.boundaryMasks(x, y) &&
                           a.halfLineMasks(x, y) == b.halfLineMasks(x, y) &&
                           a.edgeCode(x, y) == b.edgeCode(x, y) &&
                           a.neighbourCode(x, y) == b.neighbourCode(x, y) &&
                           a.sampleUsable(x, y) == b.sampleUsable(x, y));
    return differing;
}

bool marksNothing(const EdgePointImage& epi) {
    for (int y = 0; y < epi.height(); ++y)
        for (int x = 0; x < epi.width(); ++x) {
            for (uint8_t m : epi.boundaryMasks(x, y))
                if (m) return false;
            for (uint8_t m : epi.halfLineMasks(x, y))
                if (m) return false;
        }
    return true;
}

TEST(EdgePointImage, EdgesThatCannotMarkAreDroppedWithoutChange) {
    // Each rejected edge alone marks nothing (serial rasterizer, an image small enough that
    // most edges are near a side).
    const int w = 13, h = 9;
    EpiOptions serialOptions;
    serialOptions.parallel = false;
    EdgePointImage small(w, h, serialOptions);
    int rejected = 0, kept = 0;
    for (const ScreenEdge& e : adversarialEdges(w, h, 3, 6000)) {
        if (edgeMayMark(e, w, h)) {
            ++kept;
            continue;
        }
        ++rejected;
        small.build({e}, {});
        ASSERT_TRUE(marksNothing(small))
            << "edgeMayMark rejected an edge that marks: " << e.toString() << " on " << w << "x"
            << h;
    }
    EXPECT_GT(rejected, 2000) << "kept " << kept;
    EXPECT_GT(kept, 1000) << "rejected " << rejected;

    // A dense scene with and without the rejected edges, parallel and serial: every mask,
    // code, the culled count and the reconstructed images equal bit for bit.
    const int W = 256, H = 197;
    std::mt19937 rng(11);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    std::vector<ScreenEdge> all = adversarialEdges(W, H, 5, 40000);
    std::vector<ScreenPoint> points;
    for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x)
            if (u(rng) < 0.6)
                points.push_back(makePoint({x + u(rng), y + u(rng)}, Rgb(u(rng), 0.5, u(rng)),
                                           1.0 + 3 * u(rng)));
    std::vector<ScreenEdge> dropped;
    for (const ScreenEdge& e : all)
        if (edgeMayMark(e, W, H)) dropped.push_back(e);
    ASSERT_LT(dropped.size(), all.size() * 3 / 4);
    for (bool parallel : {true, false}) {
        EpiOptions options;
        options.parallel = parallel;
        EdgePointImage full(W, H, options), fast(W, H, options);
        full.build(all, points);
        fast.build(dropped, points);
        EXPECT_GT(full.countPixels(PixelClass::Complex), 1000u) << full.toString();
        EXPECT_GT(full.culledIntersections(), 0u);
        EXPECT_EQ(full.culledIntersections(), fast.culledIntersections());
        EXPECT_EQ(differingPixels(full, fast), 0) << "parallel " << parallel;
        EXPECT_EQ(full.reconstruct(true).pixels, fast.reconstruct(true).pixels);
    }
}

TEST(EdgePointImage, FloorExactEqualsStdFloor) {
    std::vector<double> values = {0.0,
                                  -0.0,
                                  0.5,
                                  -0.5,
                                  1.0,
                                  -1.0,
                                  4503599627370495.5,
                                  -4503599627370495.5,
                                  4503599627370496.0,
                                  -4503599627370496.0,
                                  9007199254740993.0,
                                  1e300,
                                  -1e300,
                                  std::numeric_limits<double>::denorm_min(),
                                  -std::numeric_limits<double>::denorm_min(),
                                  std::numeric_limits<double>::infinity(),
                                  -std::numeric_limits<double>::infinity(),
                                  std::numeric_limits<double>::max(),
                                  std::numeric_limits<double>::lowest()};
    std::mt19937_64 rng(17);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    for (int k = 0; k < 200000; ++k) {
        // The rasterizer's range (8·x over a few thousand pixels, 2·y) and every scale.
        const double v = k % 2 ? u(rng) * 8.0 * 4096.0 : std::ldexp(u(rng), (k / 2) % 120 - 60);
        values.push_back(v);
        const double n = std::round(v * 8.0) / 8.0;  // on and next to 1/8 steps and integers
        values.push_back(n);
        values.push_back(std::nextafter(n, 1e300));
        values.push_back(std::nextafter(n, -1e300));
    }
    for (int i = -70000; i <= 70000; ++i) {
        const double v = i / 8.0;
        values.push_back(std::nextafter(v, 1e300));
        values.push_back(std::nextafter(v, -1e300));
    }
    for (double v : values) {
        const double a = detail::floorExact(v), b = std::floor(v);
        ASSERT_EQ(std::memcmp(&a, &b, sizeof a), 0)
            << "floorExact(" << v << ") = " << a << ", std::floor = " << b;
    }
    EXPECT_TRUE(std::isnan(detail::floorExact(std::nan(""))));
}

TEST(EdgePointImage, ComplexFilterShortcutEqualsTheGeneralFilter) {
    // Dense short edges (complex pixels everywhere) and sparse points in clumps, so many
    // complex pixels have no point in their 3×3 neighbourhood and many do.
    const int W = 160, H = 131;
    std::mt19937 rng(23);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    std::vector<ScreenEdge> edges;
    for (int k = 0; k < 12000; ++k) {
        const glm::dvec2 a{u(rng) * W, u(rng) * H};
        edges.push_back(makeEdge(a, a + glm::dvec2(u(rng) * 3 - 1.5, u(rng) * 3 - 1.5)));
    }
    std::vector<ScreenPoint> points;
    for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x)
            if (((x / 8 + y / 8) % 3 == 0 && u(rng) < 0.7) || u(rng) < 0.01)
                points.push_back(
                    makePoint({x + u(rng), y + u(rng)}, Rgb(u(rng), 0.3, u(rng)), 1.0 + u(rng)));
    for (bool parallel : {true, false}) {
        EpiOptions fastOptions, referenceOptions;
        fastOptions.parallel = referenceOptions.parallel = parallel;
        referenceOptions.complexFilterShortcut = false;
        EdgePointImage fast(W, H, fastOptions), reference(W, H, referenceOptions);
        fast.build(edges, points);
        reference.build(edges, points);
        int withoutPoints = 0, complex = 0;
        for (int y = 0; y < H; ++y)
            for (int x = 0; x < W; ++x) {
                if (fast.pixelClass(x, y) != PixelClass::Complex) continue;
                ++complex;
                bool any = false;
                for (int v = std::max(0, y - 1); v <= std::min(H - 1, y + 1); ++v)
                    for (int w = std::max(0, x - 1); w <= std::min(W - 1, x + 1); ++w)
                        any |= fast.samplePosition(w, v) >= 0;
                withoutPoints += !any;
            }
        EXPECT_GT(withoutPoints, 1000) << "of " << complex << " complex pixels";
        EXPECT_GT(complex - withoutPoints, 1000);
        const Image a = fast.reconstruct(true), b = reference.reconstruct(true);
        ASSERT_EQ(a.pixels.size(), b.pixels.size());
        int differing = 0;
        for (size_t k = 0; k < a.pixels.size(); ++k) differing += a.pixels[k] != b.pixels[k];
        EXPECT_EQ(differing, 0) << "parallel " << parallel;
    }
}

TEST(EdgePointImage, DenseComplexClustersKeepTheirEstimate) {
    // Dense short edges over the left half (clusters of complex pixels), sparse ones over the
    // right (isolated complex pixels), points everywhere.
    const int W = 120, H = 90;
    std::mt19937 rng(29);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    std::vector<ScreenEdge> edges;
    for (int k = 0; k < 4000; ++k) {
        const bool dense = k < 3600;
        const glm::dvec2 a{(dense ? 0.0 : 0.5 * W) + u(rng) * 0.5 * W, u(rng) * H};
        edges.push_back(makeEdge(a, a + glm::dvec2(u(rng) * 3 - 1.5, u(rng) * 3 - 1.5)));
    }
    std::vector<ScreenPoint> points;
    for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x)
            if (u(rng) < 0.5)
                points.push_back(
                    makePoint({x + u(rng), y + u(rng)}, Rgb(u(rng), 0.3, u(rng)), 1.0 + u(rng)));
    for (bool parallel : {true, false}) {
        EpiOptions denseOptions, paperOptions;
        denseOptions.parallel = paperOptions.parallel = parallel;
        denseOptions.denseComplexLimit = 5;
        EdgePointImage dense(W, H, denseOptions), paper(W, H, paperOptions);
        dense.build(edges, points);
        paper.build(edges, points);
        const Image a = dense.reconstruct(true), b = paper.reconstruct(true);
        int clustered = 0, filtered = 0, changed = 0;
        for (int y = 0; y < H; ++y)
            for (int x = 0; x < W; ++x) {
                int around = 0;
                for (int v = std::max(0, y - 1); v <= std::min(H - 1, y + 1); ++v)
                    for (int w = std::max(0, x - 1); w <= std::min(W - 1, x + 1); ++w)
                        around += dense.pixelClass(w, v) == PixelClass::Complex;
                const bool inCluster = dense.pixelClass(x, y) == PixelClass::Complex && around >= 5;
                if (inCluster) {
                    ++clustered;
                    ASSERT_EQ(a.at(x, y), dense.primaryColour(x, y)) << x << " " << y;
                    changed += a.at(x, y) != b.at(x, y);
                } else {
                    filtered += dense.pixelClass(x, y) == PixelClass::Complex;
                    ASSERT_EQ(a.at(x, y), b.at(x, y)) << x << " " << y;
                }
            }
        EXPECT_GT(clustered, 1000);
        EXPECT_GT(filtered, 100) << "complex pixels outside clusters, filtered as in §5.4";
        EXPECT_GT(changed, clustered / 2) << "the filter changes most clustered pixels";
        // A second frame on the same image (the clusters moved): as a fresh image's, so no
        // subpixel code of the first frame is read.
        std::vector<ScreenEdge> moved = edges;
        for (ScreenEdge& e : moved) {
            e.a.x = W - e.a.x;
            e.b.x = W - e.b.x;
        }
        EdgePointImage fresh(W, H, denseOptions);
        dense.build(moved, points);
        fresh.build(moved, points);
        const Image second = dense.reconstruct(true), expected = fresh.reconstruct(true);
        int differing = 0;
        for (size_t k = 0; k < second.pixels.size(); ++k)
            differing += second.pixels[k] != expected.pixels[k];
        EXPECT_EQ(differing, 0) << "parallel " << parallel;
    }
}

}  // namespace
}  // namespace penumbra
