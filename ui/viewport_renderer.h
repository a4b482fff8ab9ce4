#pragma once
// The viewport's image of the lit scene: the Gouraud radiosity view (render/gouraud_renderer.h's
// shading: Embree primary rays, per-vertex radiosity blended with the hit's barycentric
// weights, radiance B/π, black backs of one-sided surfaces) at one sample per pixel, plus what
// the editor needs on top: the object being dragged, which has left the solution and exists
// only as the solver's preview version (George et al.'s temporary buffer), and an outline of
// the selected object. Stays here until the edge-and-point display (render/) replaces it.

#include <cstdint>
#include <vector>

#include "render/image.h"
#include "solver/scene.h"

namespace penumbra {

class Discretization;
class RayTracer;

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

}  // namespace penumbra
