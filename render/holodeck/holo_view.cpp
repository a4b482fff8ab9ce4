#include "render/holodeck/holo_view.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <bit>
#include <cmath>
#include <functional>
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

/// The octahedral map's fold of its lower half over the upper (its own inverse): (u, v) of a
/// point with z < 0 to the square's corner triangle it covers.
void octahedralFold(double& u, double& v) {
    const double fu = (1 - std::abs(v)) * (u >= 0 ? 1 : -1);
    v = (1 - std::abs(u)) * (v >= 0 ? 1 : -1);
    u = fu;
}

/// A unit vector in two 16-bit numbers (the octahedral map: the sphere onto the octahedron
/// |x| + |y| + |z| = 1, its lower half folded over the upper), within about 1e-4 rad.
std::array<std::int16_t, 2> encodeDirection(const Vec3& d) {
    const double l1 = std::abs(d.x) + std::abs(d.y) + std::abs(d.z);
    double u = d.x / l1, v = d.y / l1;
    if (d.z < 0) octahedralFold(u, v);
    return {std::int16_t(std::lround(u * 32767)), std::int16_t(std::lround(v * 32767))};
}

Vec3 decodeDirection(const std::array<std::int16_t, 2>& e) {
    double u = e[0] / 32767.0, v = e[1] / 32767.0;
    const double z = 1 - std::abs(u) - std::abs(v);
    if (z < 0) octahedralFold(u, v);
    return glm::normalize(Vec3(u, v, z));
}

/// Squared distance of pixel coordinates from their pixel's centre.
double offCentre(const glm::dvec2& p) {
    const double dx = p.x - std::floor(p.x) - 0.5, dy = p.y - std::floor(p.y) - 0.5;
    return dx * dx + dy * dy;
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

namespace {

/// The points of the chosen stored samples (holodeckViewPoints): `sampleOf(i)` the decoded
/// sample i and the distance within which its ray must still end at its stored hit (the
/// distance code's resolution). The sample's ray is traced again: a sample whose ray now ends
/// elsewhere (geometry moved into it, or its surface moved) is stale. Then the eye's ray
/// towards the hit must end there, on the side of the surface the sample saw (a batch fill's
/// rays also start inside solids and see their insides). Otherwise the sample gives no point.
template <class SampleOf>
std::vector<ShadedPoint> tracedPoints(const std::vector<std::int64_t>& chosen,
                                      const SampleOf& sampleOf, const Discretization& disc,
                                      const RayTracer& tracer, const CameraRays& camera,
                                      std::uint64_t frame, std::uint64_t shading,
                                      const std::function<bool()>& cancelled = {}) {
    const int w = camera.width(), h = camera.height();
    const Vec3 eye = camera.origin();
    std::vector<ShadedPoint> points(chosen.size());
    std::vector<std::uint8_t> keep(chosen.size(), 0);
    std::atomic<bool> stop{false};
    tbb::parallel_for(std::size_t(0), chosen.size(), [&](std::size_t c) {
        // Asked once a block of 4,096 points.
        if (cancelled && c % 4096 == 0 && cancelled()) stop.store(true, std::memory_order_relaxed);
        if (stop.load(std::memory_order_relaxed)) return;
        const auto [s, tolerance] = sampleOf(std::size_t(chosen[c]));
        const RayTracer::FirstHit hit = tracer.firstHit(s.entry, s.direction);
        if (hit.element < 0) return;
        const Vec3 position = s.entry + double(hit.t) * s.direction;
        if (glm::length(position - s.hit) > tolerance) return;
        const Vec3 toPoint = position - eye;
        const double length = glm::length(toPoint);
        if (!(length > 1e-6)) return;
        const RayTracer::FirstHit seen = tracer.firstHit(eye, toPoint / length);
        if (seen.element != hit.element || seen.backFace != hit.backFace ||
            std::abs(double(seen.t) - length) > std::max(1e-3, 1e-6 * length))
            return;
        const auto pixel = camera.projectToPixel(position);
        if (!pixel || pixel->x < 0 || pixel->y < 0 || pixel->x >= w || pixel->y >= h) return;
        const Element& e = disc.elements()[std::size_t(hit.element)];
        ShadedPoint& p = points[c];
        p.pixel = *pixel;
        p.position = position;
        p.normal = hit.backFace ? -e.normal : e.normal;
        p.radiance = s.radiance;
        p.object = e.object;
        p.element = hit.element;
        p.frame = frame;
        p.shading = shading;
        keep[c] = 1;
    });
    if (stop.load()) return {};
    // A traced point may land a pixel beside the one its stored hit chose (the hit is decoded
    // to a few millimetres): one point a pixel still, the nearer its centre.
    std::vector<int> taken(static_cast<std::size_t>(w) * h, -1);
    for (std::size_t c = 0; c < points.size(); ++c) {
        if (!keep[c]) continue;
        int& t = taken[static_cast<std::size_t>(points[c].pixel.y) * w +
                       static_cast<std::size_t>(points[c].pixel.x)];
        if (t >= 0 && offCentre(points[std::size_t(t)].pixel) <= offCentre(points[c].pixel)) {
            keep[c] = 0;
            continue;
        }
        if (t >= 0) keep[std::size_t(t)] = 0;
        t = static_cast<int>(c);
    }
    std::vector<ShadedPoint> out;
    out.reserve(points.size());
    for (std::size_t c = 0; c < points.size(); ++c)
        if (keep[c]) out.push_back(points[c]);
    return out;
}

/// Per pixel of `camera` the stored sample to show: of the samples whose stored hit projects
/// into it, those within 2% of the nearest depth stand (a batch-filled holodeck holds many per
/// pixel, of the surface the pixel sees and of those behind it), and of those the one nearest
/// the pixel's centre, the lower index on a tie (the same choice on any number of threads);
/// first among those whose ray went the way the eye's does (dot > 0: they came from the side
/// of the surface the eye sees, where a sample from its other side shows its back).
/// `forEach(body)` calls body(i, hit, direction) for every candidate sample, from oneTBB's
/// threads. Returns the chosen indices in pixel order.
template <class ForEach>
std::vector<std::int64_t> choosePerPixel(const CameraRays& camera, const ForEach& forEach) {
    const int w = camera.width(), h = camera.height();
    const std::size_t pixels = static_cast<std::size_t>(w) * h;
    // Depths are positive: their float bits order as they do.
    std::vector<std::atomic<std::uint32_t>> front(pixels);
    for (auto& f : front) f.store(0x7f800000u, std::memory_order_relaxed);  // +infinity
    auto project = [&](const Vec3& hit, float& depth, glm::dvec2& at) {
        const double d = glm::dot(hit - camera.origin(), camera.forward());
        if (!(d > 0)) return -1;
        at = camera.projectAtDepth(hit, d);
        if (at.x < 0 || at.y < 0 || at.x >= w || at.y >= h) return -1;
        depth = float(d);
        return static_cast<int>(at.y) * w + static_cast<int>(at.x);
    };
    auto atomicMin = [](auto& slot, auto value) {
        auto old = slot.load(std::memory_order_relaxed);
        while (value < old && !slot.compare_exchange_weak(old, value, std::memory_order_relaxed)) {
        }
    };
    forEach([&](std::size_t, const Vec3& hit, const Vec3&) {
        float depth;
        glm::dvec2 at;
        const int k = project(hit, depth, at);
        if (k >= 0) atomicMin(front[k], std::bit_cast<std::uint32_t>(depth));
    });
    std::vector<std::atomic<std::uint64_t>> best(pixels);
    for (auto& b : best) b.store(~std::uint64_t(0), std::memory_order_relaxed);
    forEach([&](std::size_t i, const Vec3& hit, const Vec3& direction) {
        float depth;
        glm::dvec2 at;
        const int k = project(hit, depth, at);
        if (k < 0 || depth > std::bit_cast<float>(front[k].load(std::memory_order_relaxed)) * 1.02f)
            return;
        // Whether the ray went against the eye's in the top bit, off-centre squared (at most
        // 0.5) in the next 23, the index in the low 40.
        const std::uint64_t against = glm::dot(direction, hit - camera.origin()) <= 0 ? 1 : 0;
        const auto off = static_cast<std::uint64_t>(offCentre(at) * 2 * 0x7fffff);
        atomicMin(best[k], (against << 63) | (off << 40) | std::uint64_t(i));
    });
    std::vector<std::int64_t> chosen;
    for (const auto& b : best) {
        const std::uint64_t key = b.load(std::memory_order_relaxed);
        if (key != ~std::uint64_t(0)) chosen.push_back(std::int64_t(key & ((1ull << 40) - 1)));
    }
    return chosen;
}

/// How far from its stored hit a sample's ray may now end and still be the same: the distance
/// code's resolution at its distance, and a little.
double hitTolerance(const HoloSection& section, const DistanceCode& code, const HoloSample& s) {
    const double d = code.decode(s.distance);
    return std::max(section.diagonal() / 4096, d / 4096) * 1.01 + 1e-6 * d;
}

}  // namespace

HoloHitIndex::HoloHitIndex(HoloServer& server) : mSections(server.file().sections()) {
    for (std::size_t s = 0; s < mSections.size(); ++s)
        mCodes.push_back(server.distanceCode(int(s)));
    // Read on this thread (the server is not thread-safe), misses left out; decoded in
    // parallel.
    for (const auto& [section, beam] : server.file().storedBeams()) {
        Bounds b;
        b.section = section;
        b.beam = beam;
        b.first = mSamples.size();
        for (const HoloSample& sample : server.beam(section, beam))
            if (sample.distance != 0xffff) mSamples.push_back(sample);
        b.count = mSamples.size() - b.first;
        if (b.count > 0) mBeams.push_back(b);
    }
    mHits.resize(mSamples.size());
    mDirections.resize(mSamples.size());
    tbb::parallel_for(std::size_t(0), mBeams.size(), [&](std::size_t k) {
        Bounds& b = mBeams[k];
        glm::vec3 lo(std::numeric_limits<float>::infinity()), hi(-lo);
        for (std::size_t i = b.first; i < b.first + b.count; ++i) {
            const DecodedSample d =
                decodeSample(mSamples[i], mSections[b.section], b.beam, mCodes[b.section]);
            mHits[i] = glm::vec3(d.hit);
            mDirections[i] = encodeDirection(d.direction);
            lo = glm::min(lo, mHits[i]);
            hi = glm::max(hi, mHits[i]);
        }
        b.lo = lo;
        b.hi = hi;
    });
}

std::vector<std::size_t> HoloHitIndex::seenBeams(const CameraRays& camera) const {
    // The frustum's side planes through the eye, normals inward, and the eye's plane. A box is
    // outside when its farthest corner along a normal lies behind a plane (a box's tolerance
    // of a millimetre: hit points are decoded to about that).
    const int w = camera.width(), h = camera.height();
    const std::array<Vec3, 4> corner = {camera.rayDirection(0, 0), camera.rayDirection(w, 0),
                                        camera.rayDirection(w, h), camera.rayDirection(0, h)};
    std::array<Vec3, 5> normals;
    normals[4] = camera.forward();
    for (int k = 0; k < 4; ++k) {
        normals[k] = glm::cross(corner[k], corner[(k + 1) % 4]);
        if (glm::dot(normals[k], camera.forward()) < 0) normals[k] = -normals[k];
    }
    const Vec3 eye = camera.origin();
    std::vector<std::size_t> seen;
    for (std::size_t k = 0; k < mBeams.size(); ++k) {
        const Vec3 lo = Vec3(mBeams[k].lo) - Vec3(1e-3), hi = Vec3(mBeams[k].hi) + Vec3(1e-3);
        const bool outside = std::any_of(normals.begin(), normals.end(), [&](const Vec3& n) {
            const Vec3 far(n.x > 0 ? hi.x : lo.x, n.y > 0 ? hi.y : lo.y, n.z > 0 ? hi.z : lo.z);
            return glm::dot(far - eye, n) < 0;
        });
        if (!outside) seen.push_back(k);
    }
    return seen;
}

std::vector<BeamRequest> HoloHitIndex::beamsSeenBy(const CameraRays& camera) const {
    std::vector<BeamRequest> seen;
    for (std::size_t k : seenBeams(camera))
        seen.push_back({mBeams[k].section, mBeams[k].beam, double(mBeams[k].count)});
    return seen;
}

std::vector<ShadedPoint> HoloHitIndex::viewPoints(const Discretization& disc,
                                                  const RayTracer& tracer, const CameraRays& camera,
                                                  std::uint64_t frame, std::uint64_t shading,
                                                  const std::function<bool()>& cancelled) const {
    const std::vector<std::size_t> seen = seenBeams(camera);
    if (cancelled && cancelled()) return {};
    const std::vector<std::int64_t> chosen = choosePerPixel(camera, [&](const auto& body) {
        tbb::parallel_for(std::size_t(0), seen.size(), [&](std::size_t s) {
            const Bounds& b = mBeams[seen[s]];
            for (std::size_t i = b.first; i < b.first + b.count; ++i)
                body(i, Vec3(mHits[i]), decodeDirection(mDirections[i]));
        });
    });
    return tracedPoints(
        chosen,
        [&](std::size_t i) {
            // The beam holding sample i: the last whose first sample is at most i.
            const auto after = std::upper_bound(
                mBeams.begin(), mBeams.end(), i,
                [](std::size_t index, const Bounds& b) { return index < b.first; });
            const Bounds& b = *std::prev(after);
            const HoloSample& s = mSamples[i];
            return std::pair(decodeSample(s, mSections[b.section], b.beam, mCodes[b.section]),
                             hitTolerance(mSections[b.section], mCodes[b.section], s));
        },
        disc, tracer, camera, frame, shading, cancelled);
}

std::vector<ShadedPoint> holodeckViewPoints(HoloServer& server,
                                            const std::vector<BeamRequest>& view,
                                            const Discretization& disc, const RayTracer& tracer,
                                            const CameraRays& camera, std::uint64_t frame,
                                            std::uint64_t shading) {
    const std::vector<HoloSection>& sections = server.file().sections();
    // The beams' samples (read on this thread: the server is not thread-safe), decoded.
    struct Stored {
        int section = 0;
        std::int64_t beam = 0;
        HoloSample sample;
    };
    std::vector<Stored> stored;
    for (const BeamRequest& r : view)
        for (const HoloSample& sample : server.beam(r.section, r.beam))
            if (sample.distance != 0xffff)  // a miss: nothing to show
                stored.push_back({r.section, r.beam, sample});
    std::vector<DecodedSample> samples(stored.size());
    tbb::parallel_for(std::size_t(0), stored.size(), [&](std::size_t i) {
        const Stored& s = stored[i];
        samples[i] =
            decodeSample(s.sample, sections[s.section], s.beam, server.distanceCode(s.section));
    });
    const std::vector<std::int64_t> chosen = choosePerPixel(camera, [&](const auto& body) {
        tbb::parallel_for(tbb::blocked_range<std::size_t>(0, samples.size(), 4096),
                          [&](const auto& r) {
                              for (std::size_t i = r.begin(); i != r.end(); ++i)
                                  body(i, samples[i].hit, samples[i].direction);
                          });
    });
    return tracedPoints(
        chosen,
        [&](std::size_t i) {
            const Stored& s = stored[i];
            return std::pair(samples[i], hitTolerance(sections[s.section],
                                                      server.distanceCode(s.section), s.sample));
        },
        disc, tracer, camera, frame, shading);
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
