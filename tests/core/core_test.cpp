// The core library against values worked out independently: Newell's normal of known
// polygons (and of an indexed face), the plane frame's round trip and orientation, the sRGB
// curve's published constants and its bytes, file extensions, and SplitMix64's published
// first outputs for seed 0.

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "core/colour.h"
#include "core/file_name.h"
#include "core/math.h"
#include "core/random.h"
#include "core/timing.h"

namespace penumbra {
namespace {

TEST(CoreMath, NewellNormalIsTwiceTheAreaAlongTheNormal) {
    // A 2 × 3 rectangle in the plane x + y = 1 (tilted 45°), counter-clockwise about
    // (1, 1, 0)/√2.
    const double r = std::sqrt(0.5);
    const Vec3 a(1, 0, 0), u(-r * 2, r * 2, 0), w(0, 0, 3);  // |u| = 2, |w| = 3
    const std::vector<Vec3> rect = {a, a + u, a + u + w, a + w};
    const Vec3 n = newellNormal(rect);
    EXPECT_NEAR(glm::length(n), 2 * 6.0, 1e-12);
    EXPECT_NEAR(glm::dot(unitNormal(rect), Vec3(r, r, 0)), 1.0, 1e-12);
    // Reversed winding flips it; a degenerate polygon has none.
    EXPECT_NEAR(glm::dot(unitNormal({a + w, a + u + w, a + u, a}), Vec3(r, r, 0)), -1.0, 1e-12);
    EXPECT_EQ(glm::length(unitNormal({Vec3(0, 0, 0), Vec3(1, 1, 0), Vec3(2, 2, 0)})), 0.0);
}

TEST(CoreMath, NewellNormalOfAnIndexedFaceIsThatOfItsPolygon) {
    const std::vector<Vec3> positions = {{9, 9, 9}, {0, 0, 1}, {2, 0.5, 1}, {2, 2, 1.5}, {0, 2, 1}};
    const int corners[] = {1, 2, 3, 4};
    const Vec3 indexed = newellNormal(positions, corners, 4);
    EXPECT_EQ(indexed, newellNormal({positions[1], positions[2], positions[3], positions[4]}));
    EXPECT_GT(indexed.z, 0) << "counter-clockwise seen from +z";
}

TEST(CoreFileName, LowerExtensionKeepsTheDotAndLowersAscii) {
    EXPECT_EQ(lowerExtension("scenes/Room.GLTF"), ".gltf");
    EXPECT_EQ(lowerExtension("out.Ply"), ".ply");
    EXPECT_EQ(lowerExtension("dir.d/noext"), "");
    EXPECT_EQ(lowerExtension("archive.tar.GZ"), ".gz");
}

TEST(CoreMath, PlaneFrameRoundTripsAndKeepsCounterClockwise) {
    const std::vector<Vec3> tri = {{1, 2, 3}, {2, 2, 3.5}, {1, 3, 3}};
    const PlaneFrame frame(tri);
    for (const Vec3& p : tri) EXPECT_NEAR(glm::length(frame.to3(frame.to2(p)) - p), 0, 1e-12);
    EXPECT_NEAR(glm::dot(frame.u, frame.v), 0, 1e-12);
    EXPECT_NEAR(glm::length(glm::cross(frame.u, frame.v) - frame.n), 0, 1e-12);
    // Counter-clockwise seen from the front stays counter-clockwise in 2D.
    const Vec2 p0 = frame.to2(tri[0]), p1 = frame.to2(tri[1]), p2 = frame.to2(tri[2]);
    const double cross = (p1.x - p0.x) * (p2.y - p0.y) - (p1.y - p0.y) * (p2.x - p0.x);
    EXPECT_GT(cross, 0);
    EXPECT_NEAR(0.5 * cross, 0.5 * glm::length(newellNormal(tri)), 1e-12);
}

TEST(CoreColour, SrgbCurveMatchesTheStandardsConstants) {
    // IEC 61966-2-1: linear segment below 0.0031308 (slope 12.92), 1.055 x^(1/2.4) − 0.055.
    EXPECT_NEAR(srgbEncode(0.001), 0.01292, 1e-12);
    EXPECT_NEAR(srgbEncode(0.5), 1.055 * std::pow(0.5, 1 / 2.4) - 0.055, 1e-12);
    EXPECT_NEAR(srgbEncode(1.0), 1.0, 1e-12);
    for (double v : {0.0, 0.002, 0.01, 0.2, 0.7, 1.0})
        EXPECT_NEAR(srgbDecode(srgbEncode(v)), v, 1e-12);
    EXPECT_EQ(srgbEncodeClipped(2.0), 1.0);
    EXPECT_EQ(srgbEncodeClipped(std::nan("")), 0.0);
    // The table lookup equals rounding the curve away from byte boundaries.
    for (int k = 0; k < 1000; ++k) {
        const double v = (k + 0.37) / 1000.0;
        const double exact = 255 * srgbEncode(v);
        if (std::abs(exact - std::floor(exact) - 0.5) < 1e-6) continue;
        EXPECT_EQ(int(srgbByte(v)), int(std::lround(exact))) << v;
    }
    EXPECT_EQ(srgbByte(-1), 0);
    EXPECT_EQ(srgbByte(7), 255);
    // The exact byte: the curve clipped and rounded, NaN and negatives black, overflow white.
    for (int k = 0; k <= 1000; ++k) {
        const double v = k / 1000.0;
        EXPECT_EQ(int(srgbByteExact(v)), int(std::lround(255 * srgbEncode(v)))) << v;
    }
    EXPECT_EQ(srgbByteExact(std::nan("")), 0);
    EXPECT_EQ(srgbByteExact(-0.5), 0);
    EXPECT_EQ(srgbByteExact(1.5), 255);
    EXPECT_EQ(srgbByteExact(std::numeric_limits<double>::infinity()), 255);
}

TEST(CoreRandom, SplitMix64GivesThePublishedSequenceForSeedZero) {
    // Steele, Lea, Flood 2014 (and every reference implementation): seed 0.
    EXPECT_EQ(splitmix64(0), 0xe220a8397b1dcdafull);
    EXPECT_EQ(splitmix64(0x9e3779b97f4a7c15ull), 0x6e789e6aa1b965f4ull);
    SplitMix stream(0);
    EXPECT_EQ(stream.next(), static_cast<double>(0xe220a8397b1dcdafull >> 11) * 0x1.0p-53);
    EXPECT_EQ(stream.next(), static_cast<double>(0x6e789e6aa1b965f4ull >> 11) * 0x1.0p-53);
    // The pair hash is a function of both and of their order.
    EXPECT_EQ(hashPair(1, 2), hashPair(1, 2));
    EXPECT_NE(hashPair(1, 2), hashPair(2, 1));
}

TEST(CoreTiming, ElapsedTimeIsMonotonicAndInTheRightUnits) {
    const Clock::time_point start = Clock::now() - std::chrono::milliseconds(250);
    const double s = secondsSince(start), ms = msSince(start);
    EXPECT_GE(s, 0.25);
    EXPECT_GE(ms, 250.0);
    EXPECT_LT(ms, 1e3 * secondsSince(start) + 1e-9);
}

}  // namespace
}  // namespace penumbra
