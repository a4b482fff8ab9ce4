// renderEdgeRefinedReference: the pixels it refines are those whose samples spread or that the
// caller marks, and a refined pixel is the same pixel shaded at the edge rate throughout; a
// converged render of the lit room stays close to the plain 2 × 2 reference away from edges.

#include <gtest/gtest.h>

#include <limits>

#include "edit/edit_session.h"
#include "render/camera_rays.h"
#include "render/display/interactive_display.h"
#include "test_scenes.h"

namespace penumbra {
namespace {

constexpr int kSize = 48;

TEST(ShaderReference, EdgePixelsTakeTheEdgeRateAndNoOthers) {
    EditSession session(test::makeLitRoom("red"), SolverOptions{});
    session.converge(1e-3);
    ConvergedReferenceOptions options;
    options.samplesPerAxis = 2;
    options.edgeSamplesPerAxis = 5;
    PointShader shader(session.discretization(), session.tracer(), SolverOptions{},
                       convergedReferenceShaderOptions(displayShaderOptions(), options));
    shader.updateSolution(session.solver());
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

}  // namespace
}  // namespace penumbra
