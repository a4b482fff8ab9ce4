#pragma once
// The far field of an exact irradiance sample (issue 46, point 2): the reflected light of the
// surfaces beyond the near field, gathered by stratified cosine-distributed rays in passes.
// Each pass after the first has twice the strata per axis of the one before; the passes stop
// once the estimate's standard error is within a tolerance of the sample's whole irradiance, so
// the rays go where the far field's noise would show (a face lit mostly by reflected light: the
// Cornell box's ceiling and the short block's faces) and not where it is a small share (a
// directly lit floor). A finer pass, not a repeat, because a stratified estimate's error falls
// as N^-3/4 where the integrand has edges (silhouettes, elements' edges): four times the rays
// in one pass leave about 0.35 of the error, four passes of the first pattern's size 0.5.
//
// Index: FarFieldRays · FarFieldEstimate · estimateFarField

#include <cstdint>
#include <functional>

#include "solver/scene.h"

namespace penumbra {

/// How many rays a far field takes.
struct FarFieldRays {
    /// Rays of the first pass: an even square (16 × 16 strata by default; rounded to one).
    /// Pass p has 4^p times as many.
    int perPass = 256;
    /// At most this many passes (1: a single pass).
    int maxPasses = 1;
    /// Passes stop once the standard error of the estimate's luminance is at most this
    /// fraction of the sample's irradiance (the caller's gathered part plus the estimate)...
    double relativeError = 0;
    /// ...or at most this (W/m²; dark corners need no more rays).
    double absoluteError = 0;
};

/// The far field found and what it took.
struct FarFieldEstimate {
    Rgb value{0.0};            ///< irradiance (W/m²): the mean over the rays of what they read
    double standardError = 0;  ///< of value's luminance, from the spread of interleaved subsets
    int rays = 0;
    int passes = 0;
};

/// The mean, over cosine-distributed directions about unit normal `n`, of `read(d)` (the
/// reflected radiosity the ray from the point in unit direction d finds, 0 for none): the
/// irradiance it sends, E = ∫ (B/π) cos dω. Directions are stratified on Malley's disc, the
/// first pass jittered by `seed`, pass p by hashPair(seed, p). A pass's error is estimated from
/// four interleaved subgrids of its strata (every other stratum in each axis), each a
/// stratified estimate over the whole hemisphere; passes are combined with weights N^3/2 (their
/// expected precision). `gathered` is the luminance of the rest of the sample's irradiance, for
/// the relative tolerance.
/// With `from` (an estimate of the same point, normal, seed and rays.perPass), its passes are
/// kept and the next ones follow, up to rays.maxPasses in all.
FarFieldEstimate estimateFarField(const Vec3& n, std::uint64_t seed, const FarFieldRays& rays,
                                  double gathered, const std::function<Rgb(const Vec3&)>& read,
                                  const FarFieldEstimate* from = nullptr);

/// What the rays in unit directions dirs[0, count) find, into out[0, count).
using FarFieldBatchRead = std::function<void(const Vec3* dirs, int count, Rgb* out)>;

/// estimateFarField with each pass's rays read at once (a ray tracer's packets): the same
/// directions, sums and estimate.
FarFieldEstimate estimateFarFieldBatched(const Vec3& n, std::uint64_t seed,
                                         const FarFieldRays& rays, double gathered,
                                         const FarFieldBatchRead& read,
                                         const FarFieldEstimate* from = nullptr);

}  // namespace penumbra
