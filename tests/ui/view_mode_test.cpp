// The viewport modes' image operations (ui/view_mode.h), against values worked out by hand.

#include "ui/view_mode.h"

#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>

namespace penumbra {
namespace {

TEST(ViewMode, NamesRoundTripAndUnknownNamesAreRejected) {
    for (int m = 0; m < kViewModeCount; ++m) {
        const ViewMode mode = static_cast<ViewMode>(m);
        ASSERT_TRUE(parseViewMode(toString(mode)).has_value()) << toString(mode);
        EXPECT_EQ(*parseViewMode(toString(mode)), mode);
    }
    EXPECT_FALSE(parseViewMode("Gouraud").has_value());
    EXPECT_FALSE(parseViewMode("").has_value());
    EXPECT_FALSE(usesInteractiveDisplay(ViewMode::Gouraud));
    EXPECT_FALSE(usesInteractiveDisplay(ViewMode::OutOfDate));
    EXPECT_FALSE(usesInteractiveDisplay(ViewMode::Interpolant));
    EXPECT_TRUE(usesInteractiveDisplay(ViewMode::EdgeAndPoint));
    EXPECT_TRUE(usesInteractiveDisplay(ViewMode::Difference));
}

TEST(ViewMode, EncodeDisplayIsSrgbClipped) {
    Image image(2, 1);
    image.at(0, 0) = Rgb(0.0, 0.5, 2.0);
    image.at(1, 0) = Rgb(-1.0, 1.0, 0.2140);  // sRGB(0.214) ≈ 0.5
    const auto rgba = encodeDisplay(image);
    ASSERT_EQ(rgba.size(), 8u);
    EXPECT_EQ(rgba[0], 0);
    EXPECT_EQ(rgba[1], static_cast<int>(std::lround(srgbEncode(0.5) * 255)));
    EXPECT_EQ(rgba[2], 255);
    EXPECT_EQ(rgba[3], 255);
    EXPECT_EQ(rgba[4], 0);
    EXPECT_EQ(rgba[5], 255);
    EXPECT_NEAR(rgba[6], 127.5, 1.0);
}

TEST(ViewMode, FalseColourRampEndsAndMiddle) {
    std::uint8_t c[4];
    falseColour(0.0, c);
    EXPECT_EQ(c[0], 0);
    EXPECT_EQ(c[1], 0);
    EXPECT_LT(c[2], 64);
    falseColour(0.5, c);
    EXPECT_EQ(c[0], 0);
    EXPECT_GT(c[1], 200);
    EXPECT_LT(c[2], 64);
    falseColour(1.0, c);
    EXPECT_EQ(c[0], 255);
    EXPECT_EQ(c[1], 0);
    EXPECT_EQ(c[2], 0);
    falseColour(7.0, c);  // clamped
    EXPECT_EQ(c[0], 255);
    EXPECT_EQ(c[1], 0);
}

TEST(ViewMode, DifferenceImageBoxFiltersAndMeasuresTheSrgbDifference) {
    // Reference 2 × 1; image 4 × 2 (factor 2). Left block equals the reference; the right
    // block's mean is the reference in linear terms but sRGB differs by a known amount.
    Image reference(2, 1);
    reference.at(0, 0) = Rgb(0.25);
    reference.at(1, 0) = Rgb(0.5);
    Image a(4, 2);
    for (int y = 0; y < 2; ++y)
        for (int x = 0; x < 2; ++x) a.at(x, y) = Rgb(0.25);
    for (int y = 0; y < 2; ++y)
        for (int x = 2; x < 4; ++x) a.at(x, y) = Rgb(0.3);  // box mean 0.3 vs 0.5
    double mean = -1;
    const auto rgba = differenceImage(a, reference, 0.1, &mean);
    const double expected = 0.5 * (srgbEncode(0.5) - srgbEncode(0.3));
    EXPECT_NEAR(mean, expected, 1e-12);
    ASSERT_EQ(rgba.size(), 4u * 8u);
    std::uint8_t zero[4], right[4];
    falseColour(0.0, zero);
    falseColour((srgbEncode(0.5) - srgbEncode(0.3)) / 0.1, right);
    for (int y = 0; y < 2; ++y)
        for (int x = 0; x < 4; ++x)
            for (int c = 0; c < 3; ++c)
                EXPECT_EQ(rgba[4 * (y * 4 + x) + c], x < 2 ? zero[c] : right[c]) << x << "," << y;
    EXPECT_THROW(differenceImage(Image(3, 2), reference, 0.1), std::invalid_argument);
    EXPECT_THROW(differenceImage(Image(4, 4), reference, 0.1), std::invalid_argument);
}

TEST(ViewMode, EdgesBlendOnlyOverSimpleAndComplexPixels) {
    Image classes(3, 1);
    classes.at(0, 0) = Rgb(0.05);           // a point: untouched
    classes.at(1, 0) = Rgb(0.6, 0.1, 0.8);  // simple
    classes.at(2, 0) = Rgb(0.1, 0.8, 0.1);  // complex
    std::vector<std::uint8_t> rgba(12, 100);
    blendEdges(rgba, classes, 1.0);
    EXPECT_EQ(rgba[0], 100);
    EXPECT_EQ(rgba[1], 100);
    EXPECT_EQ(rgba[2], 100);
    EXPECT_EQ(rgba[4], static_cast<int>(std::lround(srgbEncode(0.6) * 255)));
    EXPECT_EQ(rgba[9], static_cast<int>(std::lround(srgbEncode(0.8) * 255)));
    std::vector<std::uint8_t> wrong(8, 0);
    EXPECT_THROW(blendEdges(wrong, classes), std::invalid_argument);
}

TEST(ViewMode, SamplesAndPendingTint) {
    std::vector<std::uint8_t> rgba(8, 10);
    markSamples(rgba, {0, 1});
    EXPECT_EQ(rgba[0], 10);
    EXPECT_EQ(rgba[4], 255);
    EXPECT_EQ(rgba[5], 230);
    EXPECT_EQ(rgba[6], 0);

    std::vector<std::uint8_t> grey(12, 128);
    Image pending(3, 1);
    pending.at(0, 0) = Rgb(0.0);   // nothing pending: unchanged
    pending.at(1, 0) = Rgb(0.05);  // half the scale: half the full weight (0.375)
    pending.at(2, 0) = Rgb(10.0);  // beyond: full weight 0.75
    tintPending(grey, pending, 0.1);
    EXPECT_EQ(grey[0], 128);
    EXPECT_EQ(grey[1], 128);
    EXPECT_NEAR(grey[4], std::lround(255 * (128 / 255.0 + 0.375 * (1.0 - 128 / 255.0))), 1);
    EXPECT_NEAR(grey[9], std::lround(255 * (128 / 255.0 + 0.75 * (0.05 - 128 / 255.0))), 1);
    EXPECT_GT(grey[8], grey[4]);
    EXPECT_LT(grey[9], 128);
}

}  // namespace
}  // namespace penumbra
