// The settling overlay's colours and blending (render/settling_overlay.h): nothing below the
// settled threshold, a heat that grows with the relative change up to full red, blending that
// leaves settled pixels exactly as they were, and sizes that must match.

#include "render/settling_overlay.h"

#include <gtest/gtest.h>

#include <stdexcept>

namespace penumbra {
namespace {

TEST(SettlingOverlay, HeatIsTransparentWhenSettledAndGrowsToRed) {
    EXPECT_EQ(settlingHeat(0.0).alpha, 0.0);
    EXPECT_EQ(settlingHeat(0.5 * kSettledRelative).alpha, 0.0);
    EXPECT_EQ(settlingHeat(-1.0).alpha, 0.0) << "no change below zero";
    double lastAlpha = 0;
    int lastGreen = 256;
    for (double change = kSettledRelative; change <= kHotRelative; change *= 1.5) {
        const SettlingHeat h = settlingHeat(change);
        EXPECT_GT(h.alpha, lastAlpha - 1e-12) << change;
        EXPECT_LE(h.g, lastGreen) << change;
        EXPECT_EQ(h.r, 255);
        EXPECT_EQ(h.b, 0);
        lastAlpha = h.alpha;
        lastGreen = h.g;
    }
    const SettlingHeat hot = settlingHeat(10 * kHotRelative);
    EXPECT_EQ(hot.g, 0) << "full red from kHotRelative on";
    EXPECT_DOUBLE_EQ(hot.alpha, settlingHeat(kHotRelative).alpha);
}

TEST(SettlingOverlay, BlendingLeavesSettledPixelsAndTintsTheOthers) {
    Image picture(3, 1), change(3, 1);
    for (Rgb& p : picture.pixels) p = Rgb(0.2);
    change.at(0, 0) = Rgb(0.0);                           // settled
    change.at(1, 0) = Rgb(0.1 * kSettledRelative * 0.2);  // within the threshold
    change.at(2, 0) = Rgb(kHotRelative * 0.2);            // hot
    const Image out = blendSettling(picture, change, 0.0);
    EXPECT_EQ(out.at(0, 0), picture.at(0, 0));
    EXPECT_EQ(out.at(1, 0), picture.at(1, 0));
    EXPECT_GT(out.at(2, 0).x, picture.at(2, 0).x);
    EXPECT_LT(out.at(2, 0).y, picture.at(2, 0).y);
    EXPECT_LT(out.at(2, 0).z, picture.at(2, 0).z);

    // The 8-bit form tints the same pixels.
    std::vector<std::uint8_t> rgba(3 * 4, 100);
    blendSettling(rgba, picture, change, 0.0);
    EXPECT_EQ(rgba[0], 100);
    EXPECT_EQ(rgba[4], 100);
    EXPECT_GT(rgba[8], 100);
    EXPECT_EQ(rgba[9], 100 - static_cast<int>(std::lround(settlingHeat(kHotRelative).alpha * 100)));

    // A dark pixel's change is measured against the floor: no glow from noise in black.
    Image dark(1, 1), small(1, 1);
    dark.at(0, 0) = Rgb(0.0);
    small.at(0, 0) = Rgb(1e-4);
    EXPECT_EQ(blendSettling(dark, small, 1.0).at(0, 0), Rgb(0.0));
}

TEST(SettlingOverlay, SizesMustMatch) {
    Image a(2, 2), b(3, 2);
    EXPECT_THROW(blendSettling(a, b, 0.0), std::invalid_argument);
    std::vector<std::uint8_t> rgba(3 * 4, 0);
    EXPECT_THROW(blendSettling(rgba, a, a, 0.0), std::invalid_argument);
}

}  // namespace
}  // namespace penumbra
