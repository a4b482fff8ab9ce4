#pragma once
// The interpolant build's exact samples as HifiMesh's build and the far field's pooling share
// them (render/hifi/hifi_mesh.cpp, render/hifi/hifi_samples.cpp): where a sample is taken, the
// cache of samples, the far fields' refinement and the refit of the interpolants with the pooled
// far field. Internal to render/hifi/.
//
// Index: SampleKey · SampleCache · DerivedFarField · planeElementSizes · farFieldByRecords ·
//        fitDeferredFarFields · refineFarFields · refitWithPooledFarField · finishFarFields

#include <tbb/concurrent_hash_map.h>

#include <array>
#include <cmath>
#include <cstdint>
#include <map>
#include <tuple>
#include <vector>

#include "core/random.h"
#include "render/hifi/exact_irradiance.h"
#include "render/hifi/hifi_mesh.h"

namespace penumbra {

/// Where an exact sample is taken. A point off every contact line is shared by the triangles
/// of every element of its object's surface that meet there with the same plane (key without
/// the element); on a contact line irradiance jumps, so each element samples its own side.
struct SampleKey {
    int object = -1, sheet = 0, element = -1;
    std::array<long long, 3> position{}, normal{};
    /// The key of point x (m) with unit normal n, its position on a grid `grid` (m) wide.
    static SampleKey at(int object, int sheet, int element, const Vec3& x, const Vec3& n,
                        double grid) {
        SampleKey key;
        key.object = object;
        key.sheet = sheet;
        key.element = element;
        for (int k = 0; k < 3; ++k) {
            key.position[k] = std::llround(x[k] / grid);
            key.normal[k] = std::llround(n[k] * 1e6);
        }
        return key;
    }
    /// The point (m) and unit normal the key was made of (at()), to the grid's precision.
    Vec3 point(double grid) const {
        return Vec3(position[0] * grid, position[1] * grid, position[2] * grid);
    }
    Vec3 unitNormal() const {
        return glm::normalize(Vec3(normal[0] * 1e-6, normal[1] * 1e-6, normal[2] * 1e-6));
    }
    bool operator==(const SampleKey& o) const {
        return object == o.object && sheet == o.sheet && element == o.element &&
               position == o.position && normal == o.normal;
    }
};

struct SampleKeyHash {
    static std::size_t hash(const SampleKey& k) {
        std::uint64_t h = hashPair(static_cast<std::uint64_t>(k.object),
                                   static_cast<std::uint64_t>(k.sheet) * 2654435761u +
                                       static_cast<std::uint64_t>(k.element + 1));
        for (long long c : k.position) h = hashPair(h, static_cast<std::uint64_t>(c));
        for (long long c : k.normal) h = hashPair(h, static_cast<std::uint64_t>(c));
        return static_cast<std::size_t>(h);
    }
    static bool equal(const SampleKey& a, const SampleKey& b) { return a == b; }
};

using SampleCache = tbb::concurrent_hash_map<SampleKey, ExactIrradiance::Parts, SampleKeyHash>;

/// A sample whose far field is not its own rays' but the quadratic of its element's base
/// triangles (HifiOptions::farFieldFromBase): the far field at the six samples of the base
/// triangle that holds it (vertices and edge midpoints, A, AB, B, BC, C, CA), weighted by the
/// quadratic's basis functions at the sample. Where elements share a point, the smallest
/// element's derivation stands, so the value does not depend on which element reached it first.
struct DerivedFarField {
    int element = -1;
    std::array<SampleKey, 6> base;
    std::array<double, 6> weight{};
};
using DerivedFarFields = tbb::concurrent_hash_map<SampleKey, DerivedFarField, SampleKeyHash>;

/// A sample's plane as the far field's fits group samples: object, sheet and SampleKey's normal.
using SamplePlane = std::tuple<int, int, std::array<long long, 3>>;
SamplePlane planeOf(const SampleKey& key);

/// Per plane of `disc`'s alive elements, the median element size (√area, m): the scale of the
/// plane's own mesh, whatever the scene's other surfaces are split into.
std::map<SamplePlane, double> planeElementSizes(const Discretization& disc);

/// Whether a sample's far field may come from records (fitDeferredFarFields): off contact lines
/// (key.element -1) and with no other surface within the near field's reach — the samples the
/// pooling serves, whose far field is smooth.
inline bool farFieldSharable(const SampleKey& key, const ExactIrradiance::Parts& parts) {
    return key.element < 0 && !(parts.nearShare > 0 || parts.nearSurface);
}

/// Whether the build takes the far field of the samples farFieldSharable finds from records
/// (HifiOptions::farFieldRecordSpacing and farFieldPoolRadius set, and indirect light gathered).
bool farFieldByRecords(const ExactIrradiance& exact, const HifiOptions& options);

/// The far field of the samples that deferred theirs (farFieldSharable, no passes of their own:
/// farPasses 0). Per plane, the deferred sample nearest the centre of each cell `spacing` × the
/// plane's element size (`planeSize`; else `elementSize`) wide is a record and casts `passes`
/// passes; every deferred sample's far field is then the local linear fit of the records
/// within `radius` × that size (fitFarField), marked farFitted. One with fewer than 8 records
/// within reach casts its own first pass instead. Returns the rays cast.
long long fitDeferredFarFields(SampleCache& cache, double grid, const ExactIrradiance& exact,
                               const std::map<SamplePlane, double>& planeSize, double elementSize,
                               double spacing, double radius, int passes);

/// Continues the far field (ExactIrradiance::refineFarField) of the samples in `cache` whose
/// estimated error exceeds `tolerance` of their irradiance, the worst first, pass by pass up
/// to `passes` passes, until `budget` × the rays the cache's far fields cast so far are spent.
/// Fitted far fields (farFitted) are left as they are and their records' rays not counted;
/// `derived` samples (DerivedFarField) count as the first pass they did not cast: the rays
/// they save go to refining the samples they take their far field from. Returns the rays cast.
long long refineFarFields(SampleCache& cache, double grid, const ExactIrradiance& exact,
                          double tolerance, double budget, int passes, long long derived = 0);

/// Fits every triangle's interpolant again (`perElement`, each triangle's six sample keys in
/// `perElementKeys`, in the same order) with the far field of every sample in `cache` off
/// contact lines pooled over its neighbours (poolFarField, render/hifi/far_field_pool.h) in place
/// of its own: over `radius` among samples with no other surface within the near field's reach,
/// over `nearRadius` (0: none) among the others. `grid` is the cache's position grid (m).
/// Samples in `derived` take the far field of their base samples as it stands after the pooling
/// (the pooled value where there is one), weighted as the derivation says.
void refitWithPooledFarField(
    const SampleCache& cache, double grid, std::vector<std::vector<HifiTriangle>>& perElement,
    const std::vector<std::vector<std::array<SampleKey, 6>>>& perElementKeys, double radius,
    double nearRadius, const DerivedFarFields* derived = nullptr);

/// What the build does once every sample is taken: fitDeferredFarFields by `options`'
/// farFieldRecordSpacing, farFieldPoolRadius and farFieldRecordPasses (the samples of `disc`'s
/// planes that deferred their far field), refineFarFields by farFieldRefineTolerance,
/// farFieldRefineBudget and farFieldRefinePasses (budget 0: none), then refitWithPooledFarField
/// over farFieldPoolRadius and farFieldNearPoolRadius × `elementSize` (m). The samples in
/// `derived` (optional) are marked fitted first, so that they cast no rays and feed no pooling,
/// and take their base samples' far field in the refit. Returns the rays cast.
long long finishFarFields(SampleCache& cache, double grid, const ExactIrradiance& exact,
                          const Discretization& disc, const HifiOptions& options,
                          double elementSize, std::vector<std::vector<HifiTriangle>>& perElement,
                          const std::vector<std::vector<std::array<SampleKey, 6>>>& perElementKeys,
                          const DerivedFarFields* derived = nullptr);

}  // namespace penumbra
