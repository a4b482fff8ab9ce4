#include "render/holodeck/holo_view.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <set>
#include <stdexcept>

#include "core/random.h"
#include "core/timing.h"
#include "render/camera_rays.h"
#include "solver/discretization.h"
#include "solver/ray_tracer.h"
#include "solver/scene.h"

namespace penumbra {

namespace {

/// Whether `eye` sees `point` (nothing in between, the last millimetre aside).
bool seen(const RayTracer& tracer, const Vec3& eye, const Vec3& point) {
    const Vec3 d = point - eye;
    const double length = glm::length(d);
    if (!(length > 1e-6)) return false;
    return !tracer.occluded(eye, point - d * std::min(1e-3 / length, 1e-3));
}

}  // namespace

std::pair<Vec3, Vec3> surfaceBounds(const Discretization& disc) {
    Vec3 lo(std::numeric_limits<double>::infinity()), hi(-lo);
    for (const ObjectSurface& o : disc.objects()) {
        if (!o.alive) continue;
        for (const Vec3& p : o.worldPositions) lo = glm::min(lo, p), hi = glm::max(hi, p);
    }
    return {lo, hi};
}

std::vector<HoloSection> holodeckSections(const Settings& settings, const Discretization& disc) {
    if (settings.holodeck.empty()) {
        const auto [lo, hi] = surfaceBounds(disc);
        return {layoutSection(lo, hi)};
    }
    std::vector<HoloSection> sections;
    for (const HolodeckSectionSetting& s : settings.holodeck) {
        const Vec3 size = s.max - s.min;
        const std::array<int, 3> grid = s.grid[0] > 0 ? s.grid : nearCubicGrid(size);
        sections.emplace_back(s.min, size, grid,
                              s.exterior ? SectionKind::Exterior : SectionKind::Interior);
    }
    return sections;
}

std::vector<ShadedPoint> holodeckViewPoints(HoloServer& server,
                                            const std::vector<BeamRequest>& view,
                                            const Discretization& disc, const RayTracer& tracer,
                                            const CameraRays& camera, std::uint64_t frame,
                                            std::uint64_t shading) {
    const std::vector<HoloSection>& sections = server.file().sections();
    // The beams' samples (read on this thread: the server is not thread-safe), then the rays.
    std::vector<DecodedSample> samples;
    std::vector<double> stored;
    for (const BeamRequest& r : view)
        for (const HoloSample& sample : server.beam(r.section, r.beam)) {
            if (sample.distance == 0xffff) continue;  // a miss: nothing to show
            samples.push_back(
                decodeSample(sample, sections[r.section], r.beam, server.distanceCode(r.section)));
            const double d = server.distanceCode(r.section).decode(sample.distance);
            stored.push_back(std::max(sections[r.section].diagonal() / 4096, d / 4096) * 1.01 +
                             1e-6 * d);
        }
    std::vector<ShadedPoint> points(samples.size());
    std::vector<std::uint8_t> keep(samples.size(), 0);
    tbb::parallel_for(std::size_t(0), samples.size(), [&](std::size_t i) {
        const DecodedSample& s = samples[i];
        const RayTracer::FirstHit hit = tracer.firstHit(s.entry, s.direction);
        if (hit.element < 0) return;
        const Vec3 position = s.entry + double(hit.t) * s.direction;
        // Stale: the ray ends elsewhere than when it was shaded.
        if (glm::length(position - s.hit) > stored[i]) return;
        if (!seen(tracer, camera.origin(), position)) return;
        const auto pixel = camera.projectToPixel(position);
        if (!pixel || pixel->x < 0 || pixel->y < 0 || pixel->x >= camera.width() ||
            pixel->y >= camera.height())
            return;
        const Element& e = disc.elements()[std::size_t(hit.element)];
        ShadedPoint& p = points[i];
        p.pixel = *pixel;
        p.position = position;
        p.normal = hit.backFace ? -e.normal : e.normal;
        p.radiance = s.radiance;
        p.object = e.object;
        p.element = hit.element;
        p.frame = frame;
        p.shading = shading;
        keep[i] = 1;
    });
    // One point per pixel, the nearest its centre: a holodeck filled in batch holds many
    // samples per pixel of a view, and a display's cache keeps a few points per pixel (a
    // larger batch would evict the warm-up's points and keep its own last ones, not an even
    // spread).
    const int w = camera.width(), h = camera.height();
    std::vector<int> best(static_cast<std::size_t>(w) * h, -1);
    auto offCentre = [](const ShadedPoint& p) {
        const double dx = p.pixel.x - std::floor(p.pixel.x) - 0.5;
        const double dy = p.pixel.y - std::floor(p.pixel.y) - 0.5;
        return dx * dx + dy * dy;
    };
    for (std::size_t i = 0; i < points.size(); ++i) {
        if (!keep[i]) continue;
        const int x = static_cast<int>(points[i].pixel.x), y = static_cast<int>(points[i].pixel.y);
        int& b = best[static_cast<std::size_t>(y) * w + x];
        if (b < 0 || offCentre(points[i]) < offCentre(points[std::size_t(b)]))
            b = static_cast<int>(i);
    }
    std::vector<ShadedPoint> out;
    for (int b : best)
        if (b >= 0) out.push_back(points[std::size_t(b)]);
    return out;
}

namespace {

using BeamKey = std::pair<int, std::int64_t>;

/// storeViewPoints, also collecting the beams that got samples in `touched` (may be null).
std::int64_t storeView(HoloServer& server, const std::vector<CachePoint>& points,
                       const RayTracer& tracer, const Vec3& eye, std::set<BeamKey>* touched) {
    const std::vector<HoloSection>& sections = server.file().sections();
    // Each point's sample in the first section its ray from the eye crosses. The stored ray
    // runs between the byte positions of its cells, a few millimetres from the eye's ray: its
    // distance is where that ray meets the surface, and the point is kept when that is within
    // a centimetre of the point shaded.
    struct Stored {
        int section = -1;
        std::int64_t beam = 0;
        HoloSample sample;
    };
    std::vector<Stored> stored(points.size());
    tbb::parallel_for(std::size_t(0), points.size(), [&](std::size_t i) {
        const CachePoint& point = points[i];
        if (point.object < 0 || !seen(tracer, eye, point.position)) return;
        const Vec3 d = glm::normalize(point.position - eye);
        for (int s = 0; s < int(sections.size()); ++s) {
            const auto ray = sections[s].locate(eye, d);
            if (!ray) continue;
            HoloSample sample =
                encodeSample(point.colour, ray->entry, ray->exit, 0, server.distanceCode(s));
            const DecodedSample q =
                decodeSample(sample, sections[s], ray->beam, server.distanceCode(s));
            const RayTracer::FirstHit hit = tracer.firstHit(q.entry, q.direction);
            if (hit.element < 0) return;
            const Vec3 at = q.entry + double(hit.t) * q.direction;
            if (glm::length(at - point.position) > 0.01) return;
            sample.distance = server.distanceCode(s).encode(double(hit.t));
            stored[i] = {s, ray->beam, sample};
            return;
        }
    });
    std::map<BeamKey, std::vector<HoloSample>> beams;
    for (const Stored& s : stored)
        if (s.section >= 0) beams[{s.section, s.beam}].push_back(s.sample);
    std::int64_t added = 0;
    for (const auto& [key, samples] : beams) {
        server.addSamples(key.first, key.second, samples);
        added += std::int64_t(samples.size());
        if (touched) touched->insert(key);
    }
    server.flush();
    return added;
}

}  // namespace

std::int64_t storeViewPoints(HoloServer& server, const std::vector<CachePoint>& points,
                             const RayTracer& tracer, const Vec3& eye) {
    return storeView(server, points, tracer, eye, nullptr);
}

FillStats fillView(HoloServer& server, const PointShader& shader, const RayTracer& tracer,
                   const CameraRays& camera, std::int64_t maxSamples, double seconds,
                   std::uint64_t seed, const std::function<void(double)>& progress) {
    if (maxSamples <= 0 && !(seconds > 0))
        throw std::invalid_argument("holodeck: fill needs a sample count or a time limit");
    const Clock::time_point start = Clock::now();
    const std::int64_t pixels = std::int64_t(camera.width()) * camera.height();
    // A random order of the pixels (Fisher–Yates), the same for every pass.
    std::vector<std::int64_t> order(static_cast<std::size_t>(pixels));
    for (std::int64_t i = 0; i < pixels; ++i) order[std::size_t(i)] = i;
    SplitMix rng(hashPair(seed, 0x686f6c6f));
    for (std::int64_t i = pixels - 1; i > 0; --i)
        std::swap(order[std::size_t(i)],
                  order[std::size_t(std::min<std::int64_t>(i, std::int64_t(rng.next() * (i + 1))))]);
    constexpr std::int64_t kBatch = 32768;
    FillStats stats;
    std::int64_t rays = 0;
    std::set<BeamKey> touched;
    // Rays whose hit is not stored (misses, and the few whose stored ray ends elsewhere) are
    // made up by further rays; a batch that stores nothing (a view of the sky) ends the fill.
    while ((maxSamples <= 0 || stats.samples < maxSamples) &&
           !(seconds > 0 && secondsSince(start) >= seconds)) {
        const std::int64_t n =
            std::min(kBatch, maxSamples > 0 ? maxSamples - stats.samples : kBatch);
        std::vector<CachePoint> points(static_cast<std::size_t>(n));
        tbb::parallel_for(std::int64_t(0), n, [&](std::int64_t k) {
            const std::int64_t ray = rays + k;
            const std::int64_t pixel = order[std::size_t(ray % pixels)];
            // The first pass through the pixels' centres (a pixel's one sample best stands for
            // its mean), later ones jittered by a hash of the ray's number, so passes differ.
            const std::uint64_t h = hashPair(seed, std::uint64_t(ray));
            const bool first = ray < pixels;
            ShadeRequest request;
            request.pixel =
                glm::dvec2(double(pixel % camera.width()) + (first ? 0.5 : double(h >> 40) * 0x1p-24),
                           double(pixel / camera.width()) +
                               (first ? 0.5 : double((h >> 16) & 0xffffff) * 0x1p-24));
            request.origin = camera.origin();
            request.direction = camera.rayDirection(request.pixel.x, request.pixel.y);
            request.frame = h;
            const ShadedPoint p = shader.shade(request);
            points[std::size_t(k)] = {p.position, p.radiance, p.object, p.element, 0};
        });
        rays += n;
        const std::int64_t stored = storeView(server, points, tracer, camera.origin(), &touched);
        stats.samples += stored;
        if (progress) {
            const double bySamples = maxSamples > 0 ? double(stats.samples) / maxSamples : 0;
            const double byTime = seconds > 0 ? secondsSince(start) / seconds : 0;
            progress(std::min(1.0, std::max(bySamples, byTime)));
        }
        if (stored == 0) break;
    }
    stats.beams = std::int64_t(touched.size());
    stats.seconds = secondsSince(start);
    return stats;
}

}  // namespace penumbra
