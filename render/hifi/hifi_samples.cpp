#include "render/hifi/hifi_samples.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <tuple>
#include <unordered_map>

#include "render/hifi/far_field_pool.h"

namespace penumbra {

namespace {

struct SampleKeyStdHash {
    std::size_t operator()(const SampleKey& k) const { return SampleKeyHash::hash(k); }
};

/// The far field of every sample in `cache` off contact lines, pooled over the other samples
/// of its plane within a radius (poolFarField). What is pooled is the whole reflected light
/// (the far field's rays and the near field's exact part, Parts::nearIndirect), which does not
/// depend on how the two split it, and the sample's own near part is subtracted again. Where
/// no other surface is within the near field's reach (Parts::nearShare 0, Parts::nearSurface
/// false) the reflected light is the light of distant surfaces and smooth: `radius`, among
/// such samples. Where another surface is near it changes faster: `nearRadius`, among such
/// samples (0: each keeps its own value).
std::unordered_map<SampleKey, Rgb, SampleKeyStdHash> pooledFarField(const SampleCache& cache,
                                                                    double grid, double radius,
                                                                    double nearRadius) {
    std::vector<const SampleKey*> keys;
    std::vector<FarFieldSample> samples;
    // A plane id per object, sheet and normal.
    std::map<std::tuple<int, int, std::array<long long, 3>>, int> planes;
    for (const auto& [key, parts] : cache) {
        if (key.element >= 0) continue;
        FarFieldSample s;
        s.open = !(parts.nearShare > 0 || parts.nearSurface);
        if (!s.open && !(nearRadius > 0)) continue;
        s.x = key.point(grid);
        s.n = key.unitNormal();
        s.plane = planes
                      .emplace(std::make_tuple(key.object, key.sheet, key.normal),
                               static_cast<int>(planes.size()))
                      .first->second;
        s.indirect = parts.farField + parts.nearIndirect;
        s.near = parts.nearIndirect;
        keys.push_back(&key);
        samples.push_back(s);
    }
    const PooledFarField pooled = poolFarField(samples, radius, nearRadius);
    std::unordered_map<SampleKey, Rgb, SampleKeyStdHash> out;
    for (std::size_t i = 0; i < samples.size(); ++i)
        if (pooled.fitted[i]) out.emplace(*keys[i], pooled.value[i]);
    return out;
}

}  // namespace

long long refineFarFields(SampleCache& cache, double grid, const ExactIrradiance& exact,
                          double tolerance, double budget, int passes) {
    long long first = 0;
    for (const auto& entry : cache) first += entry.second.farRays;
    long long allowance = std::llround(budget * double(first)), spent = 0;
    const long long perPass = std::max(1, exact.options().farRays);
    for (int pass = 2; pass <= passes; ++pass) {
        // This pass's rays per sample (its strata are 2^(pass - 1) times as fine per axis).
        const long long cost = perPass << (2 * (pass - 1));
        if (allowance < cost) break;
        // The samples still above the tolerance, the worst (relative to their irradiance)
        // first.
        std::vector<std::pair<double, SampleKey>> todo;
        for (const auto& [key, parts] : cache) {
            if (parts.farPasses == 0 || parts.farPasses >= pass) continue;
            const double whole = luminance(parts.total());
            if (whole > 0 && parts.farError > tolerance * whole)
                todo.emplace_back(parts.farError / whole, key);
        }
        const std::size_t take =
            std::min<std::size_t>(todo.size(), static_cast<std::size_t>(allowance / cost));
        std::partial_sort(todo.begin(), todo.begin() + take, todo.end(),
                          [](const auto& a, const auto& b) { return a.first > b.first; });
        tbb::parallel_for(std::size_t(0), take, [&](std::size_t i) {
            const SampleKey& key = todo[i].second;
            SampleCache::accessor found;
            if (!cache.find(found, key)) return;
            exact.refineFarField(key.point(grid), key.unitNormal(), pass, found->second);
        });
        allowance -= static_cast<long long>(take) * cost;
        spent += static_cast<long long>(take) * cost;
    }
    return spent;
}

void refitWithPooledFarField(
    const SampleCache& cache, double grid, std::vector<std::vector<HifiTriangle>>& perElement,
    const std::vector<std::vector<std::array<SampleKey, 6>>>& perElementKeys, double radius,
    double nearRadius) {
    const auto pooled = pooledFarField(cache, grid, radius, nearRadius);
    tbb::parallel_for(0, static_cast<int>(perElement.size()), [&](int e) {
        auto& triangles = perElement[e];
        const auto& keys = perElementKeys[e];
        for (std::size_t k = 0; k < triangles.size() && k < keys.size(); ++k) {
            std::array<Rgb, 6> total;
            for (int v = 0; v < 6; ++v) {
                SampleCache::const_accessor found;
                if (!cache.find(found, keys[k][v])) return;
                const auto it = pooled.find(keys[k][v]);
                total[v] = found->second.gathered +
                           (it != pooled.end() ? it->second : found->second.farField);
            }
            triangles[k].irradiance = QuadraticInterpolant::fromSamples(total);
        }
    });
}

long long finishFarFields(
    SampleCache& cache, double grid, const ExactIrradiance& exact, const HifiOptions& options,
    double elementSize, std::vector<std::vector<HifiTriangle>>& perElement,
    const std::vector<std::vector<std::array<SampleKey, 6>>>& perElementKeys) {
    const long long rays =
        options.farFieldRefineBudget > 0
            ? refineFarFields(cache, grid, exact, options.farFieldRefineTolerance,
                              options.farFieldRefineBudget, options.farFieldRefinePasses)
            : 0;
    refitWithPooledFarField(cache, grid, perElement, perElementKeys,
                            options.farFieldPoolRadius * elementSize,
                            options.farFieldNearPoolRadius * elementSize);
    return rays;
}

}  // namespace penumbra
