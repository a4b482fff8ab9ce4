#include "render/hifi/hifi_samples.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <map>
#include <tuple>
#include <unordered_map>

#include "render/hifi/far_field_pool.h"
#include "solver/discretization.h"

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
    std::map<SamplePlane, int> planes;
    for (const auto& [key, parts] : cache) {
        if (key.element >= 0 || parts.farFitted) continue;
        FarFieldSample s;
        s.open = !(parts.nearShare > 0 || parts.nearSurface);
        if (!s.open && !(nearRadius > 0)) continue;
        s.x = key.point(grid);
        s.n = key.unitNormal();
        s.plane = planes.emplace(planeOf(key), static_cast<int>(planes.size())).first->second;
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

SamplePlane planeOf(const SampleKey& key) {
    return std::make_tuple(key.object, key.sheet, key.normal);
}

std::map<SamplePlane, double> planeElementSizes(const Discretization& disc) {
    std::map<SamplePlane, std::vector<double>> areas;
    for (std::size_t e = 0; e < disc.elements().size(); ++e) {
        if (!disc.elementAlive(static_cast<int>(e))) continue;
        const Element& el = disc.elements()[e];
        const int sheet = disc.objects()[el.object].isBackFace(el.face) ? 1 : 0;
        const SampleKey key = SampleKey::at(el.object, sheet, -1, el.centroid, el.normal, 1.0);
        areas[planeOf(key)].push_back(el.area);
    }
    std::map<SamplePlane, double> out;
    for (auto& [plane, a] : areas) {
        std::nth_element(a.begin(), a.begin() + a.size() / 2, a.end());
        out.emplace(plane, std::sqrt(a[a.size() / 2]));
    }
    return out;
}

bool farFieldByRecords(const ExactIrradiance& exact, const HifiOptions& options) {
    return exact.options().indirect && options.farFieldRecordSpacing > 0 &&
           options.farFieldPoolRadius > 0;
}

long long fitDeferredFarFields(SampleCache& cache, double grid, const ExactIrradiance& exact,
                               const std::map<SamplePlane, double>& planeSize, double elementSize,
                               double spacing, double radius, int passes) {
    // The deferred samples, by plane.
    std::vector<SampleKey> keys;
    std::vector<FarFieldSample> samples;
    std::vector<double> planeScale;  ///< per plane id: its element size (m)
    std::map<SamplePlane, int> planes;
    for (const auto& [key, parts] : cache) {
        if (parts.farPasses > 0 || parts.farFitted || !farFieldSharable(key, parts)) continue;
        FarFieldSample s;
        s.x = key.point(grid);
        s.n = key.unitNormal();
        const SamplePlane plane = planeOf(key);
        const auto [it, added] = planes.emplace(plane, static_cast<int>(planes.size()));
        if (added) {
            const auto size = planeSize.find(plane);
            planeScale.push_back(size != planeSize.end() ? size->second : elementSize);
        }
        s.plane = it->second;
        keys.push_back(key);
        samples.push_back(s);
    }
    if (samples.empty()) return 0;
    // Records: per plane, the sample nearest the centre of each cell (ties to the smaller
    // position, so the choice does not depend on the cache's order).
    using Cell = std::array<long long, 4>;
    std::map<Cell, int> nearest;
    auto squaredToCentre = [&](int i, const Cell& c) {
        const double w = spacing * planeScale[samples[i].plane];
        const Vec3 centre =
            (Vec3(static_cast<double>(c[1]), static_cast<double>(c[2]), static_cast<double>(c[3])) +
             0.5) *
            w;
        const Vec3 d = samples[i].x - centre;
        return glm::dot(d, d);
    };
    for (int i = 0; i < static_cast<int>(samples.size()); ++i) {
        const Vec3 g = glm::floor(samples[i].x / (spacing * planeScale[samples[i].plane]));
        const Cell c{samples[i].plane, std::llround(g.x), std::llround(g.y), std::llround(g.z)};
        const auto [it, added] = nearest.emplace(c, i);
        if (added) continue;
        const double di = squaredToCentre(i, c), dj = squaredToCentre(it->second, c);
        if (di < dj || (di == dj && keys[i].position < keys[it->second].position)) it->second = i;
    }
    std::vector<int> records;
    records.reserve(nearest.size());
    for (const auto& entry : nearest) records.push_back(entry.second);
    // The records' far fields, `passes` passes each.
    std::atomic<long long> rays{0};
    std::vector<FarFieldSample> recorded(records.size());
    tbb::parallel_for(std::size_t(0), records.size(), [&](std::size_t r) {
        const int i = records[r];
        SampleCache::accessor found;
        if (!cache.find(found, keys[i])) return;
        ExactIrradiance::Parts& parts = found->second;
        exact.refineFarField(samples[i].x, samples[i].n, passes, parts);
        rays.fetch_add(parts.farRays, std::memory_order_relaxed);
        recorded[r] = samples[i];
        recorded[r].indirect = parts.farField + parts.nearIndirect;
    });
    // Every deferred sample's far field from the records of its plane.
    std::vector<double> planeRadius(planeScale.size());
    for (std::size_t p = 0; p < planeScale.size(); ++p) planeRadius[p] = radius * planeScale[p];
    for (std::size_t i = 0; i < samples.size(); ++i) {
        SampleCache::const_accessor found;
        if (cache.find(found, keys[i])) samples[i].near = found->second.nearIndirect;
    }
    const PooledFarField fitted = fitFarField(samples, recorded, planeRadius);
    tbb::parallel_for(std::size_t(0), samples.size(), [&](std::size_t i) {
        SampleCache::accessor found;
        if (!cache.find(found, keys[i])) return;
        ExactIrradiance::Parts& parts = found->second;
        if (fitted.fitted[i]) {
            parts.farField = fitted.value[i];
            parts.farFitted = true;
        } else if (parts.farPasses == 0) {
            // Too few records within reach (a narrow strip of open floor): its own rays.
            exact.refineFarField(samples[i].x, samples[i].n, 1, parts);
            rays.fetch_add(parts.farRays, std::memory_order_relaxed);
        }
    });
    return rays.load();
}

long long refineFarFields(SampleCache& cache, double grid, const ExactIrradiance& exact,
                          double tolerance, double budget, int passes, long long derived) {
    long long first = derived * std::max(1, exact.options().farRays);
    for (const auto& entry : cache)
        if (!entry.second.farFitted) first += entry.second.farRays;
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
            if (parts.farPasses == 0 || parts.farPasses >= pass || parts.farFitted) continue;
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

namespace {

/// The far field of every sample in `derived`: its base samples' far field after the pooling
/// (`pooled` where fitted, else their own), weighted as the derivation says. A base sample may
/// be derived itself (an element's corner on the edge of a larger neighbour, which derives
/// it): such chains are followed for a few rounds, each from the one before, so the result
/// depends on the derivations alone.
std::unordered_map<SampleKey, Rgb, SampleKeyStdHash> derivedFarFieldValues(
    const SampleCache& cache, const std::unordered_map<SampleKey, Rgb, SampleKeyStdHash>& pooled,
    const DerivedFarFields& derived) {
    std::vector<const SampleKey*> keys;
    std::vector<const DerivedFarField*> how;
    std::unordered_map<SampleKey, int, SampleKeyStdHash> index;
    for (const auto& [key, d] : derived) {
        index.emplace(key, static_cast<int>(keys.size()));
        keys.push_back(&key);
        how.push_back(&d);
    }
    // The far field of the samples that are not derived, as the pooling left it.
    auto own = [&](const SampleKey& key) {
        const auto it = pooled.find(key);
        if (it != pooled.end()) return it->second;
        SampleCache::const_accessor found;
        return cache.find(found, key) ? found->second.farField : Rgb(0.0);
    };
    std::vector<Rgb> value(keys.size(), Rgb(0.0)), next(keys.size());
    for (int round = 0; round < 3; ++round) {
        tbb::parallel_for(std::size_t(0), keys.size(), [&](std::size_t i) {
            Rgb sum(0.0);
            for (int k = 0; k < 6; ++k) {
                const SampleKey& base = how[i]->base[std::size_t(k)];
                const auto it = index.find(base);
                sum += how[i]->weight[std::size_t(k)] *
                       (it != index.end() ? value[std::size_t(it->second)] : own(base));
            }
            next[i] = sum;
        });
        value.swap(next);
    }
    std::unordered_map<SampleKey, Rgb, SampleKeyStdHash> out;
    out.reserve(keys.size());
    for (std::size_t i = 0; i < keys.size(); ++i) out.emplace(*keys[i], value[i]);
    return out;
}

}  // namespace

void refitWithPooledFarField(
    const SampleCache& cache, double grid, std::vector<std::vector<HifiTriangle>>& perElement,
    const std::vector<std::vector<std::array<SampleKey, 6>>>& perElementKeys, double radius,
    double nearRadius, const DerivedFarFields* derived) {
    auto pooled = pooledFarField(cache, grid, radius, nearRadius);
    if (derived)
        for (auto& [key, value] : derivedFarFieldValues(cache, pooled, *derived))
            pooled.insert_or_assign(key, value);
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

long long finishFarFields(SampleCache& cache, double grid, const ExactIrradiance& exact,
                          const Discretization& disc, const HifiOptions& options,
                          double elementSize, std::vector<std::vector<HifiTriangle>>& perElement,
                          const std::vector<std::vector<std::array<SampleKey, 6>>>& perElementKeys,
                          const DerivedFarFields* derived) {
    // Derived samples cast no rays of their own and feed no pooling, also where another
    // element reached the point first and cast them.
    if (derived)
        for (const auto& entry : *derived) {
            SampleCache::accessor found;
            if (cache.find(found, entry.first)) found->second.farFitted = true;
        }
    long long rays = 0;
    if (farFieldByRecords(exact, options))
        rays += fitDeferredFarFields(cache, grid, exact, planeElementSizes(disc), elementSize,
                                     options.farFieldRecordSpacing, options.farFieldPoolRadius,
                                     options.farFieldRecordPasses);
    if (options.farFieldRefineBudget > 0)
        rays += refineFarFields(cache, grid, exact, options.farFieldRefineTolerance,
                                options.farFieldRefineBudget, options.farFieldRefinePasses,
                                derived ? static_cast<long long>(derived->size()) : 0);
    refitWithPooledFarField(cache, grid, perElement, perElementKeys,
                            options.farFieldPoolRadius * elementSize,
                            options.farFieldNearPoolRadius * elementSize, derived);
    return rays;
}

}  // namespace penumbra
