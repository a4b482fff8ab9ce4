#include "ui/picking.h"

#include <sstream>

#include "render/camera_rays.h"
#include "solver/discretization.h"
#include "solver/ray_tracer.h"

namespace penumbra {

std::string Pick::toString() const {
    std::ostringstream s;
    s << "Pick{id '" << id << "', version " << version << ", element " << element << ", t " << t
      << ", at (" << position.x << ", " << position.y << ", " << position.z << ")}";
    return s.str();
}

Ray pixelRay(const Camera& camera, int width, int height, double px, double py) {
    const CameraRays rays(camera, width, height);
    return {rays.origin(), rays.rayDirection(px, py)};
}

Pick pickObject(const Discretization& disc, const RayTracer& tracer, const Camera& camera,
                int width, int height, double px, double py) {
    const Ray ray = pixelRay(camera, width, height, px, py);
    const RayHit hit = tracer.intersect(ray.origin, ray.direction);
    Pick pick;
    if (hit.object < 0) return pick;
    pick.version = hit.object;
    pick.id = disc.objects()[hit.object].id;
    pick.element = hit.element;
    pick.position = hit.position;
    pick.t = hit.t;
    return pick;
}

}  // namespace penumbra
