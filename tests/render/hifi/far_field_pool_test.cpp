// The far field's pooling (render/hifi/far_field_pool.h): the grid of cells per plane finds the
// same neighbours as testing every sample against every other, and the local linear fit
// reproduces a linear field exactly; the same for the fit of samples from records
// (fitFarField).

#include "render/hifi/far_field_pool.h"

#include <gtest/gtest.h>

#include <cmath>

#include "core/random.h"

namespace penumbra {
namespace {

/// Samples scattered over a floor (two objects' planes at y = 0, one of them with a second,
/// parallel face at y = 0.3 sharing its plane id), a wall and a tilted panel, open and near
/// ones mixed, each carrying a linear field plus noise.
std::vector<FarFieldSample> scatteredSamples(double noise, std::uint64_t seed) {
    SplitMix random(seed);
    std::vector<FarFieldSample> samples;
    const Vec3 tilted = glm::normalize(Vec3(0.3, 1, 0.2));
    auto field = [](const Vec3& x) { return Rgb(1 + 0.5 * x.x, 2 - 0.25 * x.z, 0.5 + x.y); };
    for (int i = 0; i < 3000; ++i) {
        FarFieldSample s;
        const double u = 2 * random.next(), v = 2 * random.next();
        switch (i % 4) {
            case 0:
                s.x = Vec3(u, 0, v), s.n = Vec3(0, 1, 0), s.plane = 0;
                break;
            case 1:
                s.x = Vec3(u, i % 8 == 1 ? 0.3 : 0.0, v), s.n = Vec3(0, 1, 0), s.plane = 1;
                break;
            case 2:
                s.x = Vec3(0, u, v), s.n = Vec3(1, 0, 0), s.plane = 2;
                break;
            default: {
                const Vec3 t = glm::normalize(glm::cross(tilted, Vec3(1, 0, 0)));
                const Vec3 b = glm::cross(tilted, t);
                s.x = Vec3(1, 1, 1) + (u - 1) * t + (v - 1) * b;
                s.n = tilted;
                s.plane = 3;
            }
        }
        s.open = random.next() < 0.7;
        s.near = Rgb(0.1 * random.next());
        s.indirect = field(s.x) + Rgb(noise * (random.next() - 0.5));
        samples.push_back(s);
    }
    return samples;
}

/// The samples `pooled` fitted, each checked against its exact far field (its indirect light
/// less its own near part, at least 0: the scattered samples' field is linear on each plane, so
/// the local linear fit must find it to rounding). Returns how many were fitted.
int exactWhereFitted(const std::vector<FarFieldSample>& samples, const PooledFarField& pooled) {
    int fitted = 0;
    for (std::size_t i = 0; i < samples.size(); ++i) {
        if (!pooled.fitted[i]) continue;
        ++fitted;
        const Rgb expected = glm::max(samples[i].indirect - samples[i].near, Rgb(0.0));
        for (int c = 0; c < 3; ++c)
            EXPECT_NEAR(pooled.value[i][c], expected[c], 1e-9)
                << "sample " << i << " channel " << c;
    }
    return fitted;
}

TEST(FarFieldPool, TheGridFindsWhatTestingEverySampleFinds) {
    const std::vector<FarFieldSample> samples = scatteredSamples(0.2, 7);
    for (const auto& [radius, nearRadius] : {std::pair{0.2, 0.1}, {0.35, 0.0}, {0.05, 0.05}}) {
        const PooledFarField grid = poolFarField(samples, radius, nearRadius, PoolSearch::Grid);
        const PooledFarField every = poolFarField(samples, radius, nearRadius, PoolSearch::Every);
        int fitted = 0;
        for (std::size_t i = 0; i < samples.size(); ++i) {
            ASSERT_EQ(grid.fitted[i], every.fitted[i])
                << "sample " << i << " radius " << radius << " near radius " << nearRadius;
            if (!grid.fitted[i]) continue;
            ++fitted;
            for (int c = 0; c < 3; ++c)
                ASSERT_NEAR(grid.value[i][c], every.value[i][c], 1e-9 * (1 + every.value[i][c]))
                    << "sample " << i << " channel " << c << " radius " << radius;
        }
        // Most samples have neighbours enough, except with the smallest radius.
        if (radius > 0.1) {
            EXPECT_GT(fitted, static_cast<int>(samples.size()) / 2) << radius;
        }
    }
}

TEST(FarFieldPool, ALinearFieldIsFittedExactlyAndParallelFacesDoNotMix) {
    // Without noise the fit of each sample's plane is the field at the sample, less its own
    // near part; the face at y = 0.3 shares a plane id with the floor's and its field differs
    // (it holds x.y), so a sample that mixed them would be off.
    const std::vector<FarFieldSample> samples = scatteredSamples(0.0, 11);
    const PooledFarField pooled = poolFarField(samples, 0.3, 0.3);
    EXPECT_GT(exactWhereFitted(samples, pooled), 2000);
}

/// A quarter of `samples` (four in every sixteen: one of each plane) as records, and all of
/// them as the points to fit.
void splitRecords(const std::vector<FarFieldSample>& samples, std::vector<FarFieldSample>& at,
                  std::vector<FarFieldSample>& records) {
    for (std::size_t i = 0; i < samples.size(); ++i) {
        at.push_back(samples[i]);
        if (i % 16 < 4) records.push_back(samples[i]);
    }
}

TEST(FarFieldPool, RecordsFoundThroughTheGridAreThoseTestingEveryRecordFinds) {
    std::vector<FarFieldSample> at, records;
    splitRecords(scatteredSamples(0.2, 5), at, records);
    // A radius per plane, one of them too small for most samples to find 8 records.
    const std::vector<double> planeRadius = {0.3, 0.45, 0.08, 0.25};
    const PooledFarField grid = fitFarField(at, records, planeRadius, PoolSearch::Grid);
    const PooledFarField every = fitFarField(at, records, planeRadius, PoolSearch::Every);
    // Per plane (the second object's split into its faces at y = 0.3 and, as 4, y = 0), the
    // samples and how many of them were fitted.
    int count[5] = {}, fitted[5] = {};
    for (std::size_t i = 0; i < at.size(); ++i) {
        ASSERT_EQ(grid.fitted[i], every.fitted[i]) << "sample " << i;
        const int group = at[i].plane == 1 && at[i].x.y == 0.0 ? 4 : at[i].plane;
        ++count[group];
        if (!grid.fitted[i]) continue;
        ++fitted[group];
        for (int c = 0; c < 3; ++c)
            ASSERT_NEAR(grid.value[i][c], every.value[i][c], 1e-9 * (1 + every.value[i][c]))
                << "sample " << i << " channel " << c;
    }
    // Records are one in four of each plane's samples (about 47 per m²). The floor's (radius 0.3,
    // about 13 records in reach) and the raised face's (0.45, about 30) are fitted but near their
    // edges; the wall's (0.08) reach about one record, so none; the tilted panel's (0.25, about
    // 9) only where 8 fall in reach. The second object's records are all on its face at
    // y = 0.3 (i % 16 == 1 is i % 8 == 1), so its face at y = 0 has none in its plane: not one of
    // its samples is fitted, though records of its plane id lie within reach above it.
    EXPECT_GT(fitted[0], count[0] * 3 / 4);
    EXPECT_GT(fitted[1], count[1] * 9 / 10);
    EXPECT_EQ(fitted[2], 0);
    EXPECT_GT(fitted[3], count[3] / 4);
    EXPECT_LT(fitted[3], count[3]);
    EXPECT_EQ(fitted[4], 0);
}

TEST(FarFieldPool, RecordsOfALinearFieldGiveItAtEverySample) {
    // Without noise, a sample's fit from its plane's records is the field at the sample (not at
    // the records), less its own near part.
    std::vector<FarFieldSample> at, records;
    splitRecords(scatteredSamples(0.0, 13), at, records);
    const std::vector<double> planeRadius(4, 0.4);
    const PooledFarField fitted = fitFarField(at, records, planeRadius);
    EXPECT_GT(exactWhereFitted(at, fitted), 2000);
}

}  // namespace
}  // namespace penumbra
