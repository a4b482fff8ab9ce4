// EdgePointImage::reconstructWindow against a whole build() and reconstruct() of the same
// points and edges: after a change confined to a window (points replaced, edges added and
// removed there), the windowed update gives the whole raster's image, holes, filter weights
// and classes as a fresh EPI does, for the display's options and for the dense-region ones,
// with edges and without.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include "render/display/edge_point_image.h"
#include "render/display/interactive_display.h"

namespace penumbra {
namespace {

constexpr int kW = 173, kH = 131;

struct Scene {
    std::vector<ScreenPoint> pixels;  ///< per pixel; depth +inf for none
    std::vector<ScreenEdge> edges;
};

ScreenPoint randomPoint(std::mt19937& rng, int x, int y) {
    std::uniform_real_distribution<double> u(0.0, 1.0);
    ScreenPoint p;
    p.position = {x + u(rng), y + u(rng)};
    // Two depth layers, so that edges behind the near one are culled (§4.5).
    p.depth = (x + y) % 37 < 9 ? 2.0 + u(rng) : 6.0 + u(rng);
    p.colour = Rgb(0.2 + 0.5 * std::sin(0.05 * x) * std::sin(0.07 * y) + 0.3 * u(rng),
                   0.4 + 0.3 * u(rng), 0.1 + 0.8 * u(rng) * u(rng));
    const double r = u(rng);
    p.trust = r < 0.3 ? 0 : r < 0.5 ? kEpiTrustExact : static_cast<std::uint8_t>(1 + 20 * u(rng));
    return p;
}

ScreenEdge randomEdge(std::mt19937& rng, const PixelWindow& box, double maxLength) {
    std::uniform_real_distribution<double> u(0.0, 1.0);
    ScreenEdge e;
    e.a = {box.x0 + u(rng) * (box.x1 - box.x0), box.y0 + u(rng) * (box.y1 - box.y0)};
    const double angle = 6.283185307179586 * u(rng), length = maxLength * u(rng);
    e.b = e.a + length * glm::dvec2(std::cos(angle), std::sin(angle));
    e.b = glm::clamp(e.b, glm::dvec2(box.x0, box.y0), glm::dvec2(box.x1, box.y1) - 1e-3);
    e.depthA = 1.5 + 6 * u(rng);
    e.depthB = 1.5 + 6 * u(rng);
    e.kind = static_cast<ScreenEdge::Kind>(static_cast<int>(3 * u(rng)) % 3);
    return e;
}

Scene randomScene(std::mt19937& rng) {
    std::uniform_real_distribution<double> u(0.0, 1.0);
    Scene s;
    s.pixels.resize(static_cast<size_t>(kW) * kH);
    for (int y = 0; y < kH; ++y)
        for (int x = 0; x < kW; ++x) {
            ScreenPoint& p = s.pixels[static_cast<size_t>(y) * kW + x];
            if (u(rng) < 0.6) {
                p = randomPoint(rng, x, y);
            } else {
                p.depth = std::numeric_limits<double>::infinity();
                p.position = {-1.0, -1.0};
            }
        }
    // Edges of every length, some leaving the raster.
    const PixelWindow all{-10, -10, kW + 10, kH + 10};
    for (int k = 0; k < 90; ++k) s.edges.push_back(randomEdge(rng, all, k < 10 ? 300.0 : 25.0));
    return s;
}

/// The scene changed inside `window` only: its points redrawn, a third of the edges lying
/// wholly inside it removed and new ones added there.
Scene changedInside(const Scene& before, const PixelWindow& window, std::mt19937& rng) {
    std::uniform_real_distribution<double> u(0.0, 1.0);
    Scene s = before;
    for (int y = window.y0; y < window.y1; ++y)
        for (int x = window.x0; x < window.x1; ++x) {
            if (u(rng) < 0.5) continue;
            ScreenPoint& p = s.pixels[static_cast<size_t>(y) * kW + x];
            if (u(rng) < 0.15) {
                p.depth = std::numeric_limits<double>::infinity();
                p.position = {-1.0, -1.0};
            } else {
                p = randomPoint(rng, x, y);
            }
        }
    auto inside = [&](const ScreenEdge& e) {
        return std::min(e.a.x, e.b.x) >= window.x0 && std::max(e.a.x, e.b.x) < window.x1 &&
               std::min(e.a.y, e.b.y) >= window.y0 && std::max(e.a.y, e.b.y) < window.y1;
    };
    std::erase_if(s.edges, [&](const ScreenEdge& e) { return inside(e) && u(rng) < 0.35; });
    for (int k = 0; k < 12; ++k) s.edges.push_back(randomEdge(rng, window, 12.0));
    return s;
}

void place(EdgePointImage& epi, const Scene& s) {
    const EpiPointArrays arrays = epi.pointArrays();
    for (size_t k = 0; k < s.pixels.size(); ++k) arrays.place(k, &s.pixels[k]);
}

void expectWindowEqualsWhole(const EpiOptions& options, bool useEdges, unsigned seed) {
    std::mt19937 rng(seed);
    const Scene before = randomScene(rng);
    EdgePointImage updated(kW, kH, options);
    place(updated, before);
    updated.build(before.edges);
    Image image = updated.reconstruct(useEdges);
    const Image first = image;

    // A window inside the raster and one on its border.
    const PixelWindow windows[] = {{61, 40, 97, 71}, {0, 100, 30, kH}};
    Scene now = before;
    for (const PixelWindow& window : windows) {
        now = changedInside(now, window, rng);
        place(updated, now);
        updated.reconstructWindow(now.edges, window, useEdges, image);

        EdgePointImage whole(kW, kH, options);
        place(whole, now);
        whole.build(now.edges);
        const Image reference = whole.reconstruct(useEdges);

        int imageDiffs = 0, classDiffs = 0, weightDiffs = 0, holeDiffs = 0, changedPixels = 0;
        for (int y = 0; y < kH; ++y)
            for (int x = 0; x < kW; ++x) {
                const size_t i = static_cast<size_t>(y) * kW + x;
                const Rgb a = image.at(x, y), b = reference.at(x, y);
                const double scale = std::max(1.0, glm::length(b));
                imageDiffs += glm::length(a - b) > 1e-9 * scale;
                changedPixels += glm::length(first.at(x, y) - b) > 1e-9 * scale;
                classDiffs += updated.pixelClass(x, y) != whole.pixelClass(x, y);
                weightDiffs += updated.interpolationWeights()[i] != whole.interpolationWeights()[i];
                holeDiffs += updated.holes()[i] != whole.holes()[i];
            }
        EXPECT_EQ(imageDiffs, 0) << window.toString();
        EXPECT_EQ(classDiffs, 0) << window.toString();
        EXPECT_EQ(weightDiffs, 0) << window.toString();
        EXPECT_EQ(holeDiffs, 0) << window.toString();
        EXPECT_EQ(updated.holeCount(), whole.holeCount());
        for (PixelClass c : {PixelClass::Empty, PixelClass::Simple, PixelClass::Complex})
            EXPECT_EQ(updated.countPixels(c), whole.countPixels(c));
        // The change was real: the pixels around it differ from the first image.
        EXPECT_GT(changedPixels, window.area() / 4) << window.toString();
    }
}

TEST(EpiWindow, DisplayOptionsEqualAWholeReconstruction) {
    for (unsigned seed : {1u, 2u, 3u}) expectWindowEqualsWhole(displayEpiOptions(), true, seed);
}

TEST(EpiWindow, WithoutEdgesEqualsAWholeReconstruction) {
    expectWindowEqualsWhole(displayEpiOptions(), false, 4u);
}

TEST(EpiWindow, DenseRegionsAndThePapersFiltersEqualAWholeReconstruction) {
    EpiOptions dense = displayEpiOptions();
    dense.denseComplexLimit = 4;
    dense.denseRadius = 3;
    expectWindowEqualsWhole(dense, true, 5u);
    expectWindowEqualsWhole(EpiOptions{}, true, 6u);
}

TEST(EpiWindow, ReachCoversTheSmoothing) {
    EpiOptions wide = displayEpiOptions();
    wide.smoothRadius = 12;
    EXPECT_GT(EdgePointImage(8, 8, wide).reconstructionReach(),
              EdgePointImage(8, 8, displayEpiOptions()).reconstructionReach());
    expectWindowEqualsWhole(wide, true, 7u);
}

}  // namespace
}  // namespace penumbra
