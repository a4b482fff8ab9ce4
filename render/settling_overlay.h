#pragma once
// The settling overlay (issue 44): a heat map of how much the light may still change
// (ProgressiveSolver::computeSettling) over a picture, for `render --overlay settling` and
// the editor's View ▸ Overlay ▸ Settling. Pure image operations: no GL, no threads.
//
// Index: thresholds · heat colour · blending

#include <cstdint>
#include <vector>

#include "render/image.h"
#include "solver/discretization.h"
#include "solver/progressive_solver.h"

namespace penumbra {

/// A pixel whose light may still change by less than this fraction of its luminance counts
/// as settled: the overlay leaves it alone.
constexpr double kSettledRelative = 0.01;
/// At this relative change and above the heat map is fully red.
constexpr double kHotRelative = 0.3;
/// The lighting counts as settled when the settling estimate's relative RMS against the
/// reflected light (SettlingEstimate::reflectedRms) is below this.
constexpr double kSettledRms = 0.01;

/// The estimate's per-element change as values a Gouraud render interpolates (the luminance in
/// every channel, radiosity units).
std::vector<Rgb> settlingChangeValues(const SettlingEstimate& estimate);
/// The radiosity luminance below which a pixel's relative change is not measured: a hundredth
/// of the alive elements' mean (dark pixels would glow with noise).
double settlingFloorRadiosity(const Discretization& disc, const std::vector<Rgb>& radiosity);

/// The heat map's colour (linear-free 8-bit sRGB) and opacity in [0, 0.75] for a relative
/// change: transparent below kSettledRelative, yellow to red on a log scale up to
/// kHotRelative.
struct SettlingHeat {
    std::uint8_t r = 0, g = 0, b = 0;
    double alpha = 0;
};
SettlingHeat settlingHeat(double relativeChange);

/// Per pixel, the relative change of `change` (the settling estimate's change interpolated
/// like the picture, same units) against `radiance`'s luminance, at least `floorLuminance`
/// (so black pixels do not glow with noise).
double relativeChangeAt(const Image& change, const Image& radiance, std::size_t pixel,
                        double floorLuminance);

/// `picture` (linear radiance) with the heat map blended over it in display space (sRGB),
/// returned as linear radiance again so writeImage writes what the editor shows. Sizes must
/// match (std::invalid_argument).
Image blendSettling(const Image& picture, const Image& change, double floorLuminance);

/// The same over 8-bit sRGB RGBA pixels (the editor's viewport), `radiance` the picture they
/// show.
void blendSettling(std::vector<std::uint8_t>& rgba, const Image& radiance, const Image& change,
                   double floorLuminance);

}  // namespace penumbra
