#include "render/gouraud_renderer.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <cstdint>
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
                    int height, int samplesPerAxis, const GouraudExtras& extras) {
    if (elementRadiosity.size() != disc.elements().size()) {
        throw std::invalid_argument("renderGouraud: " + std::to_string(elementRadiosity.size()) +
                                    " radiosity values for " +
                                    std::to_string(disc.elements().size()) + " elements");
    }
    if (samplesPerAxis < 1) {
        throw std::invalid_argument("renderGouraud: samplesPerAxis must be at least 1, got " +
                                    std::to_string(samplesPerAxis));
    }
    if (extras.objectAt && samplesPerAxis != 1) {
        throw std::invalid_argument("renderGouraud: objectAt needs samplesPerAxis 1, got " +
                                    std::to_string(samplesPerAxis));
    }
    const CameraRays rays(camera, width, height);  // validates the image size
    const auto& objects = disc.objects();

    // What can be seen: the alive objects, and the preview version when there is one.
    std::vector<std::uint8_t> world;
    Visibility visibility;
    const int preview = extras.previewVersion;
    const bool hasPreview = preview >= 0 && preview < static_cast<int>(objects.size());
    if (hasPreview) {
        world.resize(objects.size());
        for (std::size_t o = 0; o < objects.size(); ++o) world[o] = objects[o].alive ? 1 : 0;
        world[preview] = 1;
        visibility.world = &world;
    }

    // Per-vertex radiosity of every object that can be seen, computed once (dead versions pile
    // up during drags: they are skipped).
    std::vector<std::vector<Rgb>> vertexRadiosity(objects.size());
    tbb::parallel_for(std::size_t(0), objects.size(), [&](std::size_t o) {
        if (objects[o].alive || (hasPreview && static_cast<int>(o) == preview))
            vertexRadiosity[o] = disc.vertexValues(static_cast<int>(o), elementRadiosity);
    });

    const auto& elements = disc.elements();
    const double invPi = glm::one_over_pi<double>();
    const double step = 1.0 / samplesPerAxis;
    const double sampleWeight = 1.0 / (samplesPerAxis * samplesPerAxis);
    Image image(width, height);
    if (extras.objectAt) extras.objectAt->assign(static_cast<std::size_t>(width) * height, -1);

    // Cast samplesPerAxis² stratified primary rays per pixel, rows in parallel.
    tbb::parallel_for(tbb::blocked_range<int>(0, height), [&](const tbb::blocked_range<int>& r) {
        for (int y = r.begin(); y != r.end(); ++y) {
            for (int x = 0; x < width; ++x) {
                Rgb sum(0.0);
                for (int sy = 0; sy < samplesPerAxis; ++sy) {
                    for (int sx = 0; sx < samplesPerAxis; ++sx) {
                        const double px = x + (sx + 0.5) * step;
                        const double py = y + (sy + 0.5) * step;
                        const RayHit hit = tracer.intersect(
                            rays.origin(), rays.rayDirection(px, py), 0.0, 1e30, visibility);
                        if (hit.object < 0 || hit.element < 0) continue;
                        if (extras.objectAt)
                            (*extras.objectAt)[static_cast<std::size_t>(y) * width + x] =
                                hit.object;
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
