#pragma once
// The viewport's image of the lit scene: the Gouraud radiosity view (renderGouraud,
// render/gouraud_renderer.h: Embree primary rays, per-vertex radiosity blended with the hit's
// barycentric weights, radiance B/π, black backs of one-sided surfaces) at one sample per pixel,
// with what the editor needs on top: the object being dragged, which has left the solution and
// exists only as the solver's preview version (George et al.'s temporary buffer), which object
// each pixel shows, and an outline of the selected object. Stays here until the edge-and-point
// display (render/) replaces it.

#include <cstdint>
#include <vector>

#include "render/image.h"
#include "solver/ray_tracer.h"
#include "solver/scene.h"

namespace penumbra {

class Discretization;

struct ViewportRender {
    Image radiance;                  ///< linear radiance (W/m²/sr), width × height
    std::vector<int> objectAt;       ///< per pixel: object version seen, -1 for none
    std::vector<std::uint8_t> rgba;  ///< display: sRGB-encoded, clipped, with the outline
};

/// Renders `camera`'s width × height view. `radiosity` has one value per element of `disc`
/// (ProgressiveSolver::displayRadiosity). `previewVersion` ≥ 0: that dead version is shown
/// too (it blocks and is seen like an alive object). `highlightVersion` ≥ 0: pixels of that
/// version bordering other pixels are drawn in the selection colour in `rgba` (not in
/// `radiance`). Rows run in parallel with oneTBB. Throws std::invalid_argument like
/// renderGouraud.
ViewportRender renderViewport(const Discretization& disc, const RayTracer& tracer,
                              const std::vector<Rgb>& radiosity, const Camera& camera, int width,
                              int height, int previewVersion = -1, int highlightVersion = -1);

/// Draws the selection outline: pixels of `version` in `objectAt` (per pixel, the version
/// seen) that border a pixel of anything else get the selection colour in `rgba`.
void drawSelectionOutline(std::vector<std::uint8_t>& rgba, const std::vector<int>& objectAt,
                          int width, int height, int version);

/// The selection outline over any width × height image of `camera`'s view (the display
/// modes' images): primary rays through the pixel centres inside the screen rectangle of the
/// version's bounding box (the whole image when a corner is behind the eye) find which pixels
/// show `version`, then drawSelectionOutline. The scene is the alive objects plus
/// `previewVersion` when ≥ 0, tested through `previewOnly` when it is a RayTracer subset of
/// it alone (else through a Visibility::world filter). Returns the pixels of `version` found.
std::size_t outlineSelection(const Discretization& disc, const RayTracer& tracer,
                             const Camera& camera, int width, int height, int version,
                             std::vector<std::uint8_t>& rgba, int previewVersion = -1,
                             const Visibility& previewOnly = {});
/// outlineSelection's first step: per pixel, the version seen (-1 none or outside the
/// version's screen rectangle); empty when the version is not on screen. `versionPixels`
/// receives how many pixels show `version`.
std::vector<int> selectionPixels(const Discretization& disc, const RayTracer& tracer,
                                 const Camera& camera, int width, int height, int version,
                                 int previewVersion = -1, const Visibility& previewOnly = {},
                                 std::size_t* versionPixels = nullptr);

}  // namespace penumbra
