#pragma once
// Reference display of a radiosity solution: ray-cast primary visibility, Gouraud
// interpolation of per-vertex radiosity, radiance = B/π. Used for stills, tests and as the
// ground truth that faster display paths are compared against.

#include <vector>

#include "render/image.h"
#include "solver/scene.h"

namespace penumbra {

class Discretization;
class RayTracer;

/// What the editor's viewport asks of renderGouraud beyond the plain image.
struct GouraudExtras {
    /// A dead object version shown as if alive, seen and blocking: the solver's preview
    /// version during a drag (George et al.'s temporary buffer); -1 none.
    int previewVersion = -1;
    /// When set: per pixel (row-major, width × height), the object version its sample hit,
    /// front or back, -1 for a miss. Needs samplesPerAxis = 1.
    std::vector<int>* objectAt = nullptr;
};

/// Renders `width` × `height` pixels of radiance (W/m²/sr, linear) seen from `camera`.
///
/// Per sample: the nearest hit of RayTracer::intersect; its radiosity is the hit element's
/// per-vertex values (Discretization::vertexValues, the area-weighted mean of
/// `elementRadiosity` around each vertex) blended with RayHit::weights; radiance is B/π.
/// Misses are black. A hit on the back of a surface is black unless its object is
/// two-sided (ObjectSurface::twoSided), which shows the same radiosity on both sides.
/// Each pixel averages samplesPerAxis² samples at the centres of a regular sub-pixel grid
/// (box filter). Rows run in parallel with oneTBB; the result does not depend on the
/// thread count.
///
/// `elementRadiosity` has one value (W/m²) per element of `disc`; `tracer` must be built
/// over `disc` and up to date. `extras`: a preview version and the objects seen (above).
/// Throws std::invalid_argument on a size mismatch, a non-positive image size,
/// samplesPerAxis < 1, or extras.objectAt with samplesPerAxis > 1.
Image renderGouraud(const Discretization& disc, const RayTracer& tracer,
                    const std::vector<Rgb>& elementRadiosity, const Camera& camera, int width,
                    int height, int samplesPerAxis = 2, const GouraudExtras& extras = {});

}  // namespace penumbra
