#pragma once
// Picking: the object under a pixel, found by casting the pixel's primary ray through Embree
// (RayTracer::intersect) and mapping the hit object version back to its document id.

#include <string>

#include "solver/scene.h"

namespace penumbra {

class Discretization;
class RayTracer;

/// What a pixel sees.
struct Pick {
    std::string id;      ///< document object id; "" for a miss
    int version = -1;    ///< Discretization object (version) hit, -1 for a miss
    int element = -1;    ///< element hit
    Vec3 position{0.0};  ///< world-space hit point
    double t = 0.0;      ///< ray parameter (metres: unit direction)
    bool hit() const { return version >= 0; }
    std::string toString() const;
};

/// A world-space ray, unit direction.
struct Ray {
    Vec3 origin{0.0};
    Vec3 direction{0, 0, -1};
    Vec3 at(double t) const { return origin + t * direction; }
};

/// The primary ray through pixel coordinates (px, py) of a width × height view of `camera`
/// (render/camera_rays.h conventions: px right, py down, pixel centres at +0.5).
Ray pixelRay(const Camera& camera, int width, int height, double px, double py);

/// The nearest object of the current scene (alive versions) along the pixel's primary ray.
/// Back faces count: a click on the back of a wall picks the wall. `tracer` must be built
/// over `disc` and up to date (hold the session while picking).
Pick pickObject(const Discretization& disc, const RayTracer& tracer, const Camera& camera,
                int width, int height, double px, double py);

}  // namespace penumbra
