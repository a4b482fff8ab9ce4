#pragma once
// The interpolants' smooth far field (issue 46, point 2): each exact sample's reflected light
// fitted again from its neighbours' on the same plane, so that the far field's ray noise
// averages out over a neighbourhood instead of freezing into each triangle's interpolant
// (HifiOptions::farFieldPoolRadius). Used by HifiMesh's build once every sample is taken.
//
// Index: FarFieldSample · PoolSearch · poolFarField · fitFarField

#include <cstdint>
#include <vector>

#include "solver/scene.h"

namespace penumbra {

/// One exact sample's reflected light, as the pooling reads it.
struct FarFieldSample {
    Vec3 x{0.0};  ///< position (m)
    Vec3 n{0.0};  ///< unit normal
    /// Samples pool only with others of the same plane id (the caller's: object, sheet and
    /// normal) that lie in the sample's plane.
    int plane = -1;
    /// No other surface within the near field's reach: pooled over `radius` among such
    /// samples; else over `nearRadius` among the others.
    bool open = true;
    Rgb indirect{0.0};  ///< the far field's rays and the near field's reflected light
    Rgb near{0.0};      ///< the near field's reflected light (ExactIrradiance::Parts)
};

/// How neighbours are found: through a grid of cells per plane (what builds use), or by
/// testing every sample against every other (its reference).
enum class PoolSearch { Grid, Every };

/// Per sample, its far field fitted from its neighbours'.
struct PooledFarField {
    std::vector<Rgb> value;            ///< the fit less the sample's own near part, ≥ 0
    std::vector<std::uint8_t> fitted;  ///< 0: too few neighbours (or all on a line)
};

/// Over the samples of a sample's plane and kind (open or not) within `radius` (open) or
/// `nearRadius` (the others; 0: none fitted) of it, a weighted local linear fit
/// F ≈ c0 + c1 u + c2 v of `indirect` (weights (1 − d²/r²)², the sample itself included),
/// evaluated at the sample, less its own `near`: a gradient across the neighbourhood stays
/// and only the rays' noise averages out (n neighbours with independent rays leave about
/// 1/√n of it). A sample with fewer than 8 neighbours, or all of them on a line, is not fitted.
PooledFarField poolFarField(const std::vector<FarFieldSample>& samples, double radius,
                            double nearRadius, PoolSearch search = PoolSearch::Grid);

/// Per sample of `at`, the same weighted local linear fit (of `indirect`, less the sample's
/// own `near`) over the samples of `records` with its plane id that lie in its plane within
/// `planeRadius[plane]` (m) of it: the far field of points that cast no rays of their own
/// from the records' that did (HifiOptions::farFieldRecordSpacing). A sample with fewer than
/// 8 records within reach, or all of them on a line, is not fitted.
PooledFarField fitFarField(const std::vector<FarFieldSample>& at,
                           const std::vector<FarFieldSample>& records,
                           const std::vector<double>& planeRadius,
                           PoolSearch search = PoolSearch::Grid);

}  // namespace penumbra
