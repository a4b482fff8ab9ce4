#pragma once
// The viewport's display modes (issue 5 point 2) and the pure image operations that draw them:
// display encoding, overlays, the false-colour difference ramp and the out-of-date tint. No GL,
// no threads: unit-tested in tests/ui/view_mode_test.cpp.
//
// Index: ViewMode · names · encodeDisplay · blendEdges · markSamples · falseColour ·
//        differenceImage · tintPending

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "render/image.h"

namespace penumbra {

enum class ViewMode {
    Gouraud,         ///< per-vertex radiosity, one primary ray per pixel (viewport_renderer.h)
    EdgeAndPoint,    ///< Bala et al. 2003: render cache points + edges (InteractiveDisplay)
    Cache,           ///< the same points reconstructed without edges (render-cache baseline)
    EdgesOverlay,    ///< edge-and-point with the EPI pixel classes blended over it
    SamplesOverlay,  ///< edge-and-point with this frame's new samples as dots
    Difference,      ///< |edge-and-point − reference| as false colour
    OutOfDate,       ///< Gouraud tinted where unshot / redistribution energy is pending
    /// Hardt & Teller 1996: quadratic interpolants over the discontinuity mesh (hifi_mesh.h),
    /// built in the background once the lighting is still; Gouraud meanwhile
    Interpolant,
};

constexpr int kViewModeCount = 8;

/// Menu label ("Edge-and-point", ...).
const char* viewModeLabel(ViewMode mode);
/// Command-line name: gouraud, epi, cache, edges, samples, difference, outofdate,
/// interpolant.
const char* toString(ViewMode mode);
/// Inverse of toString (case-sensitive); nullopt for an unknown name.
std::optional<ViewMode> parseViewMode(const std::string& name);
/// Whether the mode is drawn by the edge-and-point display.
bool usesInteractiveDisplay(ViewMode mode);

/// sRGB-encoded, clipped to [0, 1], 8-bit RGBA (alpha 255), as writePng stores values.
std::vector<std::uint8_t> encodeDisplay(const Image& radiance);

/// Blends `classes` (EdgePointImage::classificationImage: simple purple, complex green) over
/// `rgba` with weight `alpha` in pixels classed simple or complex (max channel > 0.3); empty
/// and point pixels are left alone. Sizes must match (std::invalid_argument).
void blendEdges(std::vector<std::uint8_t>& rgba, const Image& classes, double alpha = 0.6);

/// Sets pixels whose flag is set to `colour` (8-bit RGB). `flags` has width × height entries.
void markSamples(std::vector<std::uint8_t>& rgba, const std::vector<std::uint8_t>& flags,
                 std::uint8_t r = 255, std::uint8_t g = 230, std::uint8_t b = 0);

/// The false-colour ramp: t ≤ 0 black-blue, 0.25 blue, 0.5 green, 0.75 yellow, ≥ 1 red
/// (8-bit RGB, alpha 255).
void falseColour(double t, std::uint8_t* rgba);

/// Per pixel of `reference` (w × h): the mean over channels of |sRGB(a) − sRGB(reference)|
/// where `a` (any size that is an integer multiple f of the reference's in both axes, f ≥ 1) is
/// box-filtered down by f; mapped through falseColour(d / fullScale) and upsampled back to a's
/// size (nearest). Returns the rgba at a's size; `meanDifference` receives the mean of d.
/// Throws std::invalid_argument when the sizes are not such a multiple.
std::vector<std::uint8_t> differenceImage(const Image& a, const Image& reference, double fullScale,
                                          double* meanDifference = nullptr);

/// Out-of-date tint: rgba' = rgba + w·(red − rgba), w = 0.75·clamp(pending / scale, 0, 1), per
/// pixel luminance of `pending` (the pending |ΔB| radiance interpolated like the image).
/// Sizes must match (std::invalid_argument).
void tintPending(std::vector<std::uint8_t>& rgba, const Image& pending, double scale);

}  // namespace penumbra
