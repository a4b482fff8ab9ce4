// renderEdgeRefinedReference: the pixels it refines are those whose samples spread or that the
// caller marks, and a refined pixel is the same pixel shaded at the edge rate throughout; a
// converged render of the lit room stays close to the plain 2 × 2 reference away from edges;
// a lamp's outline is refined where the first samples miss it, against brute-force pixels.

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <memory>

#include "core/colour.h"
#include "edit/edit_session.h"
#include "render/camera_rays.h"
#include "render/display/interactive_display.h"
#include "test_scenes.h"

namespace penumbra {
namespace {

constexpr int kSize = 48;

/// The converged lit room and a reference shader of it with `options`' shadow sampling.
struct LitRoomReference {
    explicit LitRoomReference(const ConvergedReferenceOptions& options)
        : session(test::makeLitRoom("red"), SolverOptions{}) {
        session.converge(1e-3);
        shader = std::make_unique<PointShader>(
            session.discretization(), session.tracer(), SolverOptions{},
            convergedReferenceShaderOptions(displayShaderOptions(), options));
        shader->updateSolution(session.solver());
    }
    EditSession session;
    std::unique_ptr<PointShader> shader;
};

TEST(ShaderReference, EdgePixelsTakeTheEdgeRateAndNoOthers) {
    ConvergedReferenceOptions options;
    options.samplesPerAxis = 2;
    options.edgeSamplesPerAxis = 5;
    options.brightEdgeSamplesPerAxis = 5;  // one refined rate (the next test takes the other)
    LitRoomReference room(options);
    const PointShader& shader = *room.shader;
    const CameraRays rays(test::litRoomTopCamera(), kSize, kSize);

    // Every pixel marked: each is shaded at the edge rate, as with that rate everywhere.
    std::size_t marked = 0;
    const Image all = renderEdgeRefinedReference(
        shader, rays, options, [](int, int) { return true; }, &marked);
    EXPECT_EQ(marked, std::size_t(kSize * kSize));
    ConvergedReferenceOptions fine = options;
    fine.samplesPerAxis = options.edgeSamplesPerAxis;
    const Image everywhere = renderEdgeRefinedReference(shader, rays, fine);
    for (std::size_t i = 0; i < all.pixels.size(); ++i)
        ASSERT_EQ(all.pixels[i], everywhere.pixels[i]) << i;

    // No spread counts and none marked: nothing refined, the first estimate everywhere.
    ConvergedReferenceOptions none = options;
    none.edgeSpread = std::numeric_limits<double>::infinity();
    std::size_t refined = 1;
    const Image coarse = renderEdgeRefinedReference(shader, rays, none, {}, &refined);
    EXPECT_EQ(refined, 0u);
    // By spread alone: some pixels (the slab's and the lamp's outlines), far from all.
    const Image adaptive = renderEdgeRefinedReference(shader, rays, options, {}, &refined);
    EXPECT_GT(refined, 0u);
    EXPECT_LT(refined, std::size_t(kSize * kSize / 3));
    std::size_t same = 0;
    for (std::size_t i = 0; i < adaptive.pixels.size(); ++i)
        same += adaptive.pixels[i] == coarse.pixels[i];
    EXPECT_EQ(same, adaptive.pixels.size() - refined);
    // The plain reference agrees away from the edges, within the shadow rays' noise.
    EXPECT_LT(relativeImageRmse(coarse, renderShaderReference(shader, rays, 2)), 0.1);
}

/// The mean displayed value of pixel (x, y) over a regular s × s grid: a brute-force pixel.
Rgb brutePixel(const PointShader& shader, const CameraRays& rays, int x, int y, int s) {
    Rgb sum(0.0);
    for (int j = 0; j < s; ++j)
        for (int i = 0; i < s; ++i) {
            const glm::dvec2 p(x + (i + 0.5) / s, y + (j + 0.5) / s);
            sum += shader.shade({p, rays.origin(), rays.rayDirection(p.x, p.y), 7}).radiance;
        }
    return sum / double(s * s);
}

TEST(ShaderReference, ALampsOutlineIsRefinedWhereItsFirstSamplesMissIt) {
    ConvergedReferenceOptions options;
    options.samplesPerAxis = 2;
    options.edgeSamplesPerAxis = 8;
    options.brightEdgeSamplesPerAxis = 32;
    LitRoomReference room(options);
    const PointShader& shader = *room.shader;
    // Looking up at the ceiling lamp (12 times white), its outline slanted across the pixels.
    Camera camera;
    camera.position = Vec3(0.35, -0.4, 1.1);
    camera.lookAt = Vec3(0.0, 1.49, 0.05);
    camera.fovDeg = 40;
    constexpr int kView = 40;
    const CameraRays rays(camera, kView, kView);
    const Image refined = renderEdgeRefinedReference(shader, rays, options);
    ConvergedReferenceOptions off = options;
    off.brightEdgeSamplesPerAxis = off.edgeSamplesPerAxis;
    const Image plain = renderEdgeRefinedReference(shader, rays, off);

    // The pixels the lamp partly covers, by brute force near its centre rays' hits: the
    // displayed error of both references there.
    auto onLamp = [&](int x, int y) {
        const glm::dvec2 p(x + 0.5, y + 0.5);
        return shader.shade({p, rays.origin(), rays.rayDirection(p.x, p.y), 7}).radiance.x > 1.0;
    };
    std::vector<std::uint8_t> lamp(kView * kView);
    for (int y = 0; y < kView; ++y)
        for (int x = 0; x < kView; ++x) lamp[y * kView + x] = onLamp(x, y);
    double refinedSq = 0, plainSq = 0;
    int partial = 0;
    for (int y = 1; y + 1 < kView; ++y)
        for (int x = 1; x + 1 < kView; ++x) {
            int near = 0;
            for (int dy = -1; dy <= 1; ++dy)
                for (int dx = -1; dx <= 1; ++dx) near += lamp[(y + dy) * kView + x + dx];
            if (near == 0 || near == 9) continue;
            const Rgb truth = brutePixel(shader, rays, x, y, 48);
            const double shown = srgbEncodeClipped(truth.x);
            if (shown >= 1.0) continue;  // wholly above white: nothing to resolve
            ++partial;
            const double r = srgbEncodeClipped(refined.at(x, y).x) - shown;
            const double q = srgbEncodeClipped(plain.at(x, y).x) - shown;
            refinedSq += r * r;
            plainSq += q * q;
        }
    ASSERT_GT(partial, 10);
    const double refinedRms = std::sqrt(refinedSq / partial);
    const double plainRms = std::sqrt(plainSq / partial);
    EXPECT_LT(refinedRms, 0.02) << partial << " pixels";
    EXPECT_LT(refinedRms, 0.5 * plainRms) << partial << " pixels";
}

}  // namespace
}  // namespace penumbra
