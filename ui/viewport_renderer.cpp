#include "ui/viewport_renderer.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <stdexcept>

#include "core/colour.h"
#include "render/camera_rays.h"
#include "render/gouraud_renderer.h"
#include "solver/discretization.h"
#include "solver/ray_tracer.h"

namespace penumbra {

ViewportRender renderViewport(const Discretization& disc, const RayTracer& tracer,
                              const std::vector<Rgb>& radiosity, const Camera& camera, int width,
                              int height, int previewVersion, int highlightVersion) {
    // The Gouraud view at one sample per pixel, with the preview version and what each pixel
    // shows.
    ViewportRender out;
    GouraudExtras extras;
    extras.previewVersion = previewVersion;
    extras.objectAt = &out.objectAt;
    out.radiance = renderGouraud(disc, tracer, radiosity, camera, width, height, 1, extras);

    // Display: sRGB, clipped; the selected object's border in orange.
    out.rgba.resize(static_cast<std::size_t>(width) * height * 4);
    tbb::parallel_for(0, height, [&](int y) {
        for (int x = 0; x < width; ++x) {
            const std::size_t i = static_cast<std::size_t>(y) * width + x;
            std::uint8_t* p = &out.rgba[4 * i];
            const Rgb& c = out.radiance.at(x, y);
            p[0] = srgbByteExact(c.x), p[1] = srgbByteExact(c.y), p[2] = srgbByteExact(c.z);
            p[3] = 255;
        }
    });
    if (highlightVersion >= 0)
        drawSelectionOutline(out.rgba, out.objectAt, width, height, highlightVersion);
    return out;
}

void drawSelectionOutline(std::vector<std::uint8_t>& rgba, const std::vector<int>& objectAt,
                          int width, int height, int version) {
    const std::size_t pixels = static_cast<std::size_t>(width) * height;
    if (version < 0 || objectAt.size() != pixels || rgba.size() != 4 * pixels)
        throw std::invalid_argument("drawSelectionOutline: image sizes differ");
    tbb::parallel_for(0, height, [&](int y) {
        for (int x = 0; x < width; ++x) {
            const std::size_t i = static_cast<std::size_t>(y) * width + x;
            if (objectAt[i] != version) continue;
            const bool border = x == 0 || y == 0 || x + 1 == width || y + 1 == height ||
                                objectAt[i - 1] != version || objectAt[i + 1] != version ||
                                objectAt[i - width] != version || objectAt[i + width] != version;
            if (border) {
                std::uint8_t* p = &rgba[4 * i];
                p[0] = 255, p[1] = 150, p[2] = 20;
            }
        }
    });
}

std::size_t outlineSelection(const Discretization& disc, const RayTracer& tracer,
                             const Camera& camera, int width, int height, int version,
                             std::vector<std::uint8_t>& rgba, int previewVersion,
                             const Visibility& previewOnly) {
    std::size_t found = 0;
    const std::vector<int> objectAt = selectionPixels(disc, tracer, camera, width, height, version,
                                                      previewVersion, previewOnly, &found);
    if (!objectAt.empty()) drawSelectionOutline(rgba, objectAt, width, height, version);
    return found;
}

std::vector<int> selectionPixels(const Discretization& disc, const RayTracer& tracer,
                                 const Camera& camera, int width, int height, int version,
                                 int previewVersion, const Visibility& previewOnly,
                                 std::size_t* versionPixels) {
    if (versionPixels) *versionPixels = 0;
    const auto& objects = disc.objects();
    if (version < 0 || version >= static_cast<int>(objects.size())) return {};
    const auto& ws = objects[version].worldPositions;
    if (ws.empty()) return {};
    const CameraRays rays(camera, width, height);

    // Screen rectangle of the bounding box, two pixels wider for the border.
    Vec3 lo = ws[0], hi = ws[0];
    for (const Vec3& p : ws) lo = glm::min(lo, p), hi = glm::max(hi, p);
    int x0 = 0, y0 = 0, x1 = width, y1 = height;
    bool inFront = true;
    double minX = 1e30, minY = 1e30, maxX = -1e30, maxY = -1e30;
    for (int c = 0; c < 8 && inFront; ++c) {
        const Vec3 corner((c & 1) ? hi.x : lo.x, (c & 2) ? hi.y : lo.y, (c & 4) ? hi.z : lo.z);
        const auto p = rays.projectToPixel(corner);
        if (!p) {
            inFront = false;
            break;
        }
        minX = std::min(minX, p->x), maxX = std::max(maxX, p->x);
        minY = std::min(minY, p->y), maxY = std::max(maxY, p->y);
    }
    if (inFront) {
        if (maxX < 0 || maxY < 0 || minX > width || minY > height) return {};
        x0 = std::clamp(static_cast<int>(std::floor(minX)) - 2, 0, width);
        y0 = std::clamp(static_cast<int>(std::floor(minY)) - 2, 0, height);
        x1 = std::clamp(static_cast<int>(std::ceil(maxX)) + 2, 0, width);
        y1 = std::clamp(static_cast<int>(std::ceil(maxY)) + 2, 0, height);
    }

    // The world the image shows: the scene plus the preview version.
    std::vector<std::uint8_t> world;
    Visibility filter;
    const bool preview = previewVersion >= 0 && previewVersion < static_cast<int>(objects.size());
    const bool subset = preview && previewOnly.subset >= 0;
    if (preview && !subset) {
        world.resize(objects.size());
        for (std::size_t o = 0; o < objects.size(); ++o) world[o] = objects[o].alive ? 1 : 0;
        world[previewVersion] = 1;
        filter.world = &world;
    }
    std::vector<int> objectAt(static_cast<std::size_t>(width) * height, -1);
    std::atomic<std::size_t> found{0};
    tbb::parallel_for(tbb::blocked_range<int>(y0, y1), [&](const tbb::blocked_range<int>& r) {
        std::size_t n = 0;
        for (int y = r.begin(); y != r.end(); ++y)
            for (int x = x0; x < x1; ++x) {
                const Vec3 d = rays.rayDirection(x + 0.5, y + 0.5);
                RayHit hit = tracer.intersect(rays.origin(), d, 0.0, 1e30, filter);
                if (subset) {
                    RayHit p = tracer.intersect(rays.origin(), d, 0.0,
                                                hit.object >= 0 ? hit.t : 1e30, previewOnly);
                    if (p.object >= 0) hit = std::move(p);
                }
                objectAt[static_cast<std::size_t>(y) * width + x] = hit.object;
                n += hit.object == version ? 1 : 0;
            }
        found += n;
    });
    if (versionPixels) *versionPixels = found;
    return objectAt;
}

}  // namespace penumbra
