// The far field's passes (render/hifi/far_field.h) against a closed form: a hemisphere whose
// reflected radiosity is 5 on the side x > 0.2 and 0.5 elsewhere sends irradiance
// 0.5 + 4.5 · (acos 0.2 − 0.2 √0.96) / π (Malley: a cosine-distributed direction's x is
// that of a uniform point of the unit disc, so the bright side's share is a disc segment's).

#include "render/hifi/far_field.h"

#include <gtest/gtest.h>

#include <cmath>

namespace penumbra {
namespace {

const Vec3 kNormal(0, 0, 1);

Rgb halfBright(const Vec3& d) { return Rgb(d.x > 0.2 ? 5.0 : 0.5); }

double halfBrightTruth() {
    const double c = 0.2;
    return 0.5 + 4.5 * (std::acos(c) - c * std::sqrt(1 - c * c)) / M_PI;
}

/// The root mean square error over `seeds` seeds of estimates with `rays`, and the mean of
/// the estimates' own standard errors.
struct Spread {
    double rms = 0, meanStandardError = 0, meanRays = 0;
};
Spread spreadOf(const FarFieldRays& rays, int seeds) {
    Spread s;
    for (int seed = 0; seed < seeds; ++seed) {
        const FarFieldEstimate e = estimateFarField(kNormal, 1000 + seed, rays, 0.0, halfBright);
        const double err = e.value.x - halfBrightTruth();
        s.rms += err * err;
        s.meanStandardError += e.standardError;
        s.meanRays += e.rays;
    }
    s.rms = std::sqrt(s.rms / seeds);
    s.meanStandardError /= seeds;
    s.meanRays /= seeds;
    return s;
}

TEST(FarField, AConstantHemisphereTakesOnePassAndIsExact) {
    FarFieldRays rays;
    rays.maxPasses = 3;
    rays.relativeError = 1e-6;
    const FarFieldEstimate e =
        estimateFarField(kNormal, 7, rays, 0.0, [](const Vec3&) { return Rgb(0.25); });
    EXPECT_NEAR(e.value.x, 0.25, 1e-12);
    EXPECT_EQ(e.passes, 1);
    EXPECT_EQ(e.rays, 256);
}

TEST(FarField, FinerPassesFollowTheClosedFormAndTheirErrorEstimate) {
    FarFieldRays one;  // 256 rays, one pass
    FarFieldRays three = one;
    three.maxPasses = 3;
    three.relativeError = 1e-9;  // every pass: 256 + 1,024 + 4,096 rays
    const Spread a = spreadOf(one, 64), c = spreadOf(three, 64);
    EXPECT_EQ(c.meanRays, 256 + 1024 + 4096);
    // Unbiased and far closer with the finer passes (a stratified estimate's error falls
    // about as N^-3/4 across the edge: 5,376 rays leave under a quarter of 256's).
    EXPECT_LT(a.rms, 0.02 * halfBrightTruth()) << "one pass rms " << a.rms;
    EXPECT_LT(c.rms, 0.25 * a.rms) << "three passes rms " << c.rms << ", one " << a.rms;
    // The error estimate is of the error's size: neither far above nor far below it.
    EXPECT_GT(a.meanStandardError, 0.5 * a.rms) << a.meanStandardError << " vs " << a.rms;
    EXPECT_LT(a.meanStandardError, 3.0 * a.rms) << a.meanStandardError << " vs " << a.rms;
}

TEST(FarField, PassesStopOnceWithinTheTolerance) {
    FarFieldRays rays;
    rays.maxPasses = 3;
    rays.relativeError = 0.01;
    int within = 0;
    const int seeds = 64;
    for (int seed = 0; seed < seeds; ++seed) {
        const FarFieldEstimate e = estimateFarField(kNormal, seed, rays, 0.0, halfBright);
        const double err = std::abs(e.value.x - halfBrightTruth()) / halfBrightTruth();
        if (err <= 0.02) ++within;  // two standard errors
        EXPECT_TRUE(e.passes == 3 || e.standardError <= 0.01 * e.value.x)
            << "stopped at pass " << e.passes << " with error " << e.standardError;
    }
    EXPECT_GE(within, seeds * 9 / 10) << within << " of " << seeds << " within 2%";
    // A tolerance as large as the first pass's error needs no second pass.
    rays.relativeError = 0.5;
    EXPECT_EQ(estimateFarField(kNormal, 3, rays, 0.0, halfBright).passes, 1);
}

}  // namespace
}  // namespace penumbra
