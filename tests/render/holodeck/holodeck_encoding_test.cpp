// The holodeck's sections and its ten-byte samples (Ward & Simmons 1999, §2.1, Table I): beam
// indexing against the paper's beam count and a brute-force enumeration, ray location against
// brute-force wall intersection, and each field's encoding within its stated error.

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <set>

#include "core/random.h"
#include "render/holodeck/holo_sample.h"
#include "render/holodeck/holo_section.h"

namespace penumbra {
namespace {

Vec3 randomIn(SplitMix& rng, const Vec3& lo, const Vec3& hi) {
    return {lo.x + rng.next() * (hi.x - lo.x), lo.y + rng.next() * (hi.y - lo.y),
            lo.z + rng.next() * (hi.z - lo.z)};
}

Vec3 randomDirection(SplitMix& rng) {
    const double z = 2 * rng.next() - 1, phi = 2 * M_PI * rng.next();
    const double r = std::sqrt(1 - z * z);
    return {r * std::cos(phi), r * std::sin(phi), z};
}

TEST(HoloSection, BeamCountIsThePapersFormula) {
    for (const std::array<int, 3> g :
         {std::array<int, 3>{1, 1, 1}, {4, 4, 4}, {5, 7, 3}, {24, 4, 9}, {24, 24, 24}}) {
        const HoloSection s(Vec3(0.0), Vec3(1, 2, 3), g);
        EXPECT_EQ(s.beamCount(), paperBeamCount(g[0], g[1], g[2]))
            << s.toString() << " against 2W²D² + 2W²H² + 2D²H² + 8W²DH + 8WD²H + 8WDH²";
    }
}

TEST(HoloSection, BeamIndexIsABijectionOverCellPairsOnDifferentWalls) {
    const HoloSection s(Vec3(-1.0), Vec3(2, 3, 1), {3, 2, 4});
    std::set<std::int64_t> seen;
    for (int a = 0; a < s.cellCount(); ++a) {
        for (int b = 0; b < s.cellCount(); ++b) {
            const std::int64_t beam = s.beamIndex(a, b);
            if (s.wallOf(a) == s.wallOf(b)) {
                EXPECT_EQ(beam, -1) << "cells " << a << ", " << b << " share a wall";
                continue;
            }
            ASSERT_GE(beam, 0);
            ASSERT_LT(beam, s.beamCount());
            EXPECT_TRUE(seen.insert(beam).second) << "beam " << beam << " twice";
            const auto [entry, exit] = s.beamCells(beam);
            EXPECT_EQ(entry, a);
            EXPECT_EQ(exit, b);
        }
    }
    EXPECT_EQ(std::int64_t(seen.size()), s.beamCount());
}

/// The line's crossings found wall by wall: each wall's plane, kept when the crossing lies
/// within the wall's rectangle; entry is the first, exit the last.
std::optional<std::pair<Vec3, Vec3>> bruteCrossings(const HoloSection& s, const Vec3& o,
                                                    const Vec3& d) {
    double tMin = std::numeric_limits<double>::infinity(), tMax = -tMin;
    const Vec3 lo = s.origin(), hi = s.origin() + s.size();
    for (int w = 0; w < 6; ++w) {
        const int a = w / 2;
        if (d[a] == 0) continue;
        const double plane = w % 2 ? hi[a] : lo[a];
        const double t = (plane - o[a]) / d[a];
        const Vec3 x = o + t * d;
        bool inside = true;
        for (int b = 0; b < 3; ++b)
            if (b != a && (x[b] < lo[b] - 1e-12 || x[b] > hi[b] + 1e-12)) inside = false;
        if (!inside) continue;
        tMin = std::min(tMin, t);
        tMax = std::max(tMax, t);
    }
    if (!(tMin < tMax)) return std::nullopt;
    return std::make_pair(o + tMin * d, o + tMax * d);
}

TEST(HoloSection, LocateMatchesBruteForceWallCrossings) {
    const HoloSection s(Vec3(0.5, -1, 2), Vec3(4, 2.5, 3), {8, 5, 6});
    SplitMix rng(7);
    int located = 0;
    for (int i = 0; i < 20000; ++i) {
        const Vec3 o = randomIn(rng, s.origin() - s.size(), s.origin() + 2.0 * s.size());
        const Vec3 d = randomDirection(rng);
        const auto brute = bruteCrossings(s, o, d);
        const auto ray = s.locate(o, d);
        ASSERT_EQ(brute.has_value(), ray.has_value()) << "ray " << i;
        if (!ray) continue;
        ++located;
        const Vec3 entry = s.wallPoint(ray->entry), exit = s.wallPoint(ray->exit);
        EXPECT_LT(glm::length(entry - brute->first), 1e-9) << "ray " << i;
        EXPECT_LT(glm::length(exit - brute->second), 1e-9) << "ray " << i;
        EXPECT_EQ(ray->beam, s.beamIndex(ray->entry.cell, ray->exit.cell));
    }
    EXPECT_GT(located, 2000);
}

TEST(HoloSection, LayoutStaysWithinThePapersRanges) {
    // A room 8 × 3 × 6 and a long corridor.
    for (const auto& [lo, hi] :
         {std::pair{Vec3(-4, 0, -3), Vec3(4, 3, 3)}, std::pair{Vec3(0.0), Vec3(40, 3, 2)}}) {
        const HoloSection s = layoutSection(lo, hi);
        for (int a = 0; a < 3; ++a) {
            EXPECT_GE(s.grid()[a], 4) << s.toString();
            EXPECT_LE(s.grid()[a], 24) << s.toString();
            EXPECT_GT(s.origin()[a], lo[a]) << s.toString();
            EXPECT_LT(s.origin()[a] + s.size()[a], hi[a]) << s.toString();
        }
        EXPECT_GE(s.beamCount(), 50000) << s.toString();
        EXPECT_LE(s.beamCount(), 500000) << s.toString();
    }
}

TEST(HoloSection, NearCubicGridMatchesTheBoxShape) {
    // A box twice as long as it is wide and high gets cells twice as many along its length,
    // and a beam count at least as near the target as every exactly proportional grid.
    const std::array<int, 3> grid = nearCubicGrid(Vec3(8, 4, 4), 200000);
    EXPECT_NEAR(double(grid[0]) / grid[1], 2.0, 0.25);
    EXPECT_EQ(grid[1], grid[2]);
    double bestMiss = std::numeric_limits<double>::infinity();
    for (int k = 4; k <= 12; ++k)
        bestMiss = std::min(bestMiss, std::abs(std::log(paperBeamCount(2 * k, k, k) / 2e5)));
    EXPECT_LE(std::abs(std::log(paperBeamCount(grid[0], grid[1], grid[2]) / 2e5)),
              bestMiss + 1e-12);
}

TEST(HoloSample, RgbeRoundTripWithinHalfAMantissaStep) {
    SplitMix rng(3);
    double worst = 0;
    for (int i = 0; i < 100000; ++i) {
        const double scale = std::pow(10.0, -6 + 12 * rng.next());
        const Rgb c(scale * rng.next(), scale * rng.next(), scale * rng.next());
        const Rgb back = decodeRgbe(encodeRgbe(c));
        const double largest = std::max({c.x, c.y, c.z});
        for (int k = 0; k < 3; ++k) {
            const double error = std::abs(back[k] - c[k]) / largest;
            worst = std::max(worst, error);
            ASSERT_LE(error, std::ldexp(1.0, -8) * (1 + 1e-12))
                << "component " << k << " of (" << c.x << ", " << c.y << ", " << c.z << ")";
        }
    }
    EXPECT_GT(worst, std::ldexp(1.0, -9)) << "the bound is reached, not loose";
    EXPECT_EQ(decodeRgbe(encodeRgbe(Rgb(0.0))), Rgb(0.0));
    EXPECT_EQ(decodeRgbe(encodeRgbe(Rgb(-1, std::nan(""), -5))), Rgb(0.0));
    const Rgb huge = decodeRgbe(encodeRgbe(Rgb(1e300)));
    EXPECT_TRUE(std::isfinite(huge.x) && huge.x > 1e37);
}

TEST(HoloSample, DistanceCodeIsLinearThenLogarithmic) {
    const double diagonal = 7.5;
    const DistanceCode code(diagonal);
    const double step = diagonal / DistanceCode::kLinearCodes;
    // Continuous and monotone at the border, and the paper's range of ~10¹³ diagonals.
    EXPECT_NEAR(code.decode(DistanceCode::kLinearCodes) - code.decode(2047), step, 1e-12);
    for (int c = 1; c < 65536; ++c)
        ASSERT_GT(code.decode(std::uint16_t(c)), code.decode(std::uint16_t(c - 1))) << c;
    EXPECT_GT(code.decode(65535) / diagonal, 1e13);
    SplitMix rng(11);
    for (int i = 0; i < 100000; ++i) {
        const double d = diagonal * std::pow(10.0, -3 + 15 * rng.next());
        const double back = code.decode(code.encode(d));
        if (d < diagonal)
            ASSERT_LE(std::abs(back - d), 0.5 * step * (1 + 1e-9)) << d;
        else
            ASSERT_LE(std::abs(back / d - 1), std::ldexp(1.0, -12) * 1.001) << d;
    }
    EXPECT_EQ(code.encode(0), 0);
    EXPECT_EQ(code.encode(-1), 0);
    EXPECT_EQ(code.encode(std::nan("")), 0);
    EXPECT_EQ(code.encode(1e300), 65535);
}

TEST(HoloSample, SampleRoundTripPlacesTheHitWithinItsBound) {
    const HoloSection s(Vec3(-2, 0, -1), Vec3(4, 3, 2), {10, 8, 6});
    const DistanceCode code(s.diagonal());
    SplitMix rng(5);
    for (int i = 0; i < 20000; ++i) {
        const Vec3 o = randomIn(rng, s.origin(), s.origin() + s.size());
        const Vec3 d = randomDirection(rng);
        const auto ray = s.locate(o, d);
        ASSERT_TRUE(ray.has_value());
        const Vec3 entry = s.wallPoint(ray->entry), exit = s.wallPoint(ray->exit);
        const double distance = glm::length(o - entry) + 3.0 * rng.next() * s.diagonal();
        const Rgb radiance(rng.next(), 2 * rng.next(), 0.5 * rng.next());
        const HoloSample sample = encodeSample(radiance, ray->entry, ray->exit, distance, code);
        const DecodedSample back = decodeSample(sample, s, ray->beam, code);
        // Each end is off by at most half a 256th of its cell's diagonal; the direction turns by
        // at most their sum over the ends' separation.
        const Vec3 cell = s.size() / Vec3(s.grid()[0], s.grid()[1], s.grid()[2]);
        const double endError = 0.5 * glm::length(cell) / 256.0;
        const double separation = glm::length(exit - entry);
        if (separation < 4 * endError) continue;  // a corner clipped: no direction to speak of
        const double distanceError = std::max(0.5 * s.diagonal() / 2048, distance / 4096);
        const double bound = endError + distance * 2 * endError / (separation - 2 * endError) +
                             distanceError + 1e-12;
        EXPECT_LE(glm::length(back.hit - (entry + distance * d)), bound) << "sample " << i;
        EXPECT_LE(glm::length(back.entry - entry), endError + 1e-12);
        EXPECT_LE(glm::length(back.radiance - radiance), std::sqrt(3.0) * 2.0 / 256.0);
    }
}

}  // namespace
}  // namespace penumbra
