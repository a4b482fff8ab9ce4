#pragma once
// A brute-force path tracer over the same surfaces as the radiosity solution: the independent
// reference the high-fidelity renderer is measured against (what a production path tracer
// such as Cycles computes for a scene of one-sided Lambertian polygons and area lamps).
// Unidirectional paths with next-event estimation on the emitters combined with the
// paths' own hits by multiple importance sampling, and Russian roulette; every ray through
// Embree (RayTracer).
//
// Index: PathTraceOptions · PathTraceResult · pathTrace · comparisons (relativeRmse,
// flatWindowErrors)

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "render/image.h"

namespace penumbra {

class CameraRays;
class Discretization;
class RayTracer;

struct PathTraceOptions {
    int samplesPerPixel = 64;  ///< jittered over each pixel (stratified when a square)
    std::uint64_t seed = 1;
    /// Bounces before Russian roulette may end a path; after it, a path survives with the
    /// probability of its largest throughput channel (at most 0.95).
    int rouletteDepth = 3;
    int maxDepth = 1000;  ///< a hard stop (a closed white room still ends long before)
};

struct PathTraceResult {
    Image image;  ///< radiance (W/m²/sr), linear
    /// Per pixel: the lamp itself and its edge pixels (emitterMask), left out of
    /// comparisons.
    std::vector<std::uint8_t> emitterMask;
    std::uint64_t paths = 0;
    double seconds = 0;
};

/// Renders the view. Deterministic for a seed (each pixel's samples depend on the seed and
/// the pixel only). `progress(fraction)` is called from the calling thread when given.
PathTraceResult pathTrace(const Discretization& disc, const RayTracer& tracer,
                          const CameraRays& rays, const PathTraceOptions& options = {},
                          const std::function<void(double)>& progress = {});

/// Per pixel: 1 when the pixel's centre sees an emitter's front, or a neighbour's does (the
/// lamp's edge pixels, whose values depend on how each image anti-aliases).
std::vector<std::uint8_t> emitterMask(const Discretization& disc, const RayTracer& tracer,
                                      const CameraRays& rays);

/// Relative RMSE of `image` against `reference` over the pixels `mask` leaves in (mask 0;
/// all when empty): sqrt(Σ |a − r|²) / sqrt(Σ |r|²) over the three channels.
double relativeRmse(const Image& image, const Image& reference,
                    const std::vector<std::uint8_t>& mask = {});

/// Per pixel: which flat face its centre sees, as a key (0: nothing, a back face or a lamp);
/// pixels that see the same object in the same plane share it.
std::vector<std::uint64_t> flatFaceKeys(const Discretization& disc, const RayTracer& tracer,
                                        const CameraRays& rays);

/// The low-frequency error of an image on flat surfaces, where a smooth reference is smooth
/// too: over every `window` × `window` square of pixels (on a grid of `stride`) whose pixels
/// all see one flat face (flatFaceKeys), the standard deviation of the relative luminance
/// error (Y(a) − Y(r)) / Y(r) about its mean in the square. A blotch shows as a large value; a
/// brightness offset alike over the square does not. With `cell` > 1 the error is taken
/// between the means of `cell` × `cell` pixels (a path-traced reference's per-pixel noise
/// averaged down; `window` a multiple of it).
struct WindowErrors {
    int windows = 0;               ///< blocks on one flat face
    double maxStd = 0;             ///< the largest block's standard deviation
    double meanStd = 0;            ///< over the blocks
    int worstX = -1, worstY = -1;  ///< top-left pixel of the largest
    std::string toString() const;
};
WindowErrors flatWindowErrors(const Image& image, const Image& reference,
                              const std::vector<std::uint64_t>& faces, int window = 32,
                              int stride = 8, int cell = 1);

}  // namespace penumbra
