#include "render/gouraud_renderer.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <glm/gtc/constants.hpp>
#include <stdexcept>
#include <string>

#include "render/camera_rays.h"
#include "solver/discretization.h"
#include "solver/ray_tracer.h"

namespace penumbra {

namespace {

/// Radiosity at a hit: the element's vertex values blended with the hit's weights.
Rgb interpolateRadiosity(const RayHit& hit, const Element& element,
                         const std::vector<Rgb>& vertexRadiosity,
                         const std::vector<Rgb>& elementRadiosity) {
    // Fall back to the flat element value if the weights do not match the polygon.
    if (hit.weights.size() != element.vertices.size()) return elementRadiosity[hit.element];
    Rgb b(0.0);
    for (size_t i = 0; i < element.vertices.size(); ++i) {
        b += hit.weights[i] * vertexRadiosity[element.vertices[i]];
    }
    return b;
}

}  // namespace

Image renderGouraud(const Discretization& disc, const RayTracer& tracer,
                    const std::vector<Rgb>& elementRadiosity, const Camera& camera, int width,
                    int height, int samplesPerAxis) {
    if (elementRadiosity.size() != disc.elements().size()) {
        throw std::invalid_argument("renderGouraud: " + std::to_string(elementRadiosity.size()) +
                                    " radiosity values for " +
                                    std::to_string(disc.elements().size()) + " elements");
    }
    if (samplesPerAxis < 1) {
        throw std::invalid_argument("renderGouraud: samplesPerAxis must be at least 1, got " +
                                    std::to_string(samplesPerAxis));
    }
    const CameraRays rays(camera, width, height);  // validates the image size

    // Per-vertex radiosity of every object, computed once.
    const auto& objects = disc.objects();
    std::vector<std::vector<Rgb>> vertexRadiosity(objects.size());
    for (size_t o = 0; o < objects.size(); ++o) {
        vertexRadiosity[o] = disc.vertexValues(static_cast<int>(o), elementRadiosity);
    }

    const auto& elements = disc.elements();
    const double invPi = glm::one_over_pi<double>();
    const double step = 1.0 / samplesPerAxis;
    const double sampleWeight = 1.0 / (samplesPerAxis * samplesPerAxis);
    Image image(width, height);

    // Cast samplesPerAxis² stratified primary rays per pixel, rows in parallel.
    tbb::parallel_for(tbb::blocked_range<int>(0, height), [&](const tbb::blocked_range<int>& r) {
        for (int y = r.begin(); y != r.end(); ++y) {
            for (int x = 0; x < width; ++x) {
                Rgb sum(0.0);
                for (int sy = 0; sy < samplesPerAxis; ++sy) {
                    for (int sx = 0; sx < samplesPerAxis; ++sx) {
                        const double px = x + (sx + 0.5) * step;
                        const double py = y + (sy + 0.5) * step;
                        const RayHit hit =
                            tracer.intersect(rays.origin(), rays.rayDirection(px, py));
                        if (hit.object < 0 || hit.element < 0) continue;
                        const Element& element = elements[hit.element];
                        if (hit.backFace && !objects[element.object].twoSided) continue;
                        sum += interpolateRadiosity(hit, element, vertexRadiosity[element.object],
                                                    elementRadiosity);
                    }
                }
                image.at(x, y) = sum * (sampleWeight * invPi);
            }
        }
    });
    return image;
}

}  // namespace penumbra
