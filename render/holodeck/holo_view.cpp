#include "render/holodeck/holo_view.h"

#include <tbb/enumerable_thread_specific.h>
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

/// decodeDirection's direction before normalizing (its length is between 1/√3 and 1).
glm::vec3 unnormalizedDirection(const std::array<std::int16_t, 2>& e) {
    double u = e[0] / 32767.0, v = e[1] / 32767.0;
    const double z = 1 - std::abs(u) - std::abs(v);
    if (z < 0) octahedralFold(u, v);
    return glm::vec3(float(u), float(v), float(z));
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

/// A view's candidate samples (holodeckViewPoints' beams, or the beams HoloHitIndex finds),
/// as viewPointsOf reads them: `count()` candidates; `forEach(body)` calls body(j, i, section)
/// for every candidate j in [0, count()) with the index i of its sample and its section, from
/// oneTBB's threads; `hit(i)`, `direction(i)` and `radiance(i)` are the sample's decoded hit,
/// ray direction and radiance, `facing(i, n)` has the sign of dot(direction(i), n),
/// `section(i)` is its section and `tolerance(i, section)` how far its decoded hit may lie from
/// the surface point its ray met (hitTolerance). Implemented by StoredSamples and
/// HoloHitIndex::SeenSamples below.

/// Where a candidate's stored hit projects: its pixel (-1: behind the eye or outside the
/// raster) and its depth's float bits (depths are positive: their bits order as they do).
struct Projected {
    std::int32_t pixel = -1;
    std::uint32_t depth = 0;
};

/// Per pixel of `camera` the stored sample to show: of the samples whose stored hit projects
/// into it, those within 2% of the nearest depth stand (a batch-filled holodeck holds many per
/// pixel, of the surface the pixel sees and of those behind it), and of those the one nearest
/// the pixel's centre, the lower index on a tie (the same choice on any number of threads);
/// first among those whose ray went the way the eye's does (dot > 0: they came from the side
/// of the surface the eye sees, where a sample from its other side shows its back). Two passes
/// of atomic minima: the depth's float bits, then a 64-bit key of side, off-centre distance and
/// index; the first keeps each candidate's projection for the second, which reads a sample
/// again only when it stands. Returns per chosen sample its pixel and index, in pixel order;
/// `projected` gets every candidate's projection and `front` every pixel's nearest depth.
template <class Samples>
std::vector<std::pair<std::int32_t, std::int64_t>> choosePerPixel(
    const CameraRays& camera, const Samples& samples, std::vector<Projected>& projected,
    std::vector<std::atomic<std::uint32_t>>& front) {
    const int w = camera.width(), h = camera.height();
    const std::size_t pixels = static_cast<std::size_t>(w) * h;
    const Vec3 eye = camera.origin();
    front = std::vector<std::atomic<std::uint32_t>>(pixels);
    for (auto& f : front) f.store(0x7f800000u, std::memory_order_relaxed);  // +infinity
    auto atomicMin = [](auto& slot, auto value) {
        auto old = slot.load(std::memory_order_relaxed);
        while (value < old && !slot.compare_exchange_weak(old, value, std::memory_order_relaxed)) {
        }
    };
    projected.assign(samples.count(), Projected{});
    samples.forEach([&](std::size_t j, std::size_t i, int) {
        const Vec3 hit = samples.hit(i);
        const double d = glm::dot(hit - eye, camera.forward());
        if (!(d > 0)) return;
        const glm::dvec2 at = camera.projectAtDepth(hit, d);
        if (at.x < 0 || at.y < 0 || at.x >= w || at.y >= h) return;
        const int k = static_cast<int>(at.y) * w + static_cast<int>(at.x);
        const std::uint32_t depth = std::bit_cast<std::uint32_t>(float(d));
        projected[j] = {k, depth};
        atomicMin(front[std::size_t(k)], depth);
    });
    std::vector<std::atomic<std::uint64_t>> best(pixels);
    for (auto& b : best) b.store(~std::uint64_t(0), std::memory_order_relaxed);
    samples.forEach([&](std::size_t j, std::size_t i, int) {
        const Projected p = projected[j];
        if (p.pixel < 0 ||
            std::bit_cast<float>(p.depth) >
                std::bit_cast<float>(front[std::size_t(p.pixel)].load(std::memory_order_relaxed)) *
                    1.02f)
            return;
        const Vec3 hit = samples.hit(i);
        const glm::dvec2 at = camera.projectAtDepth(hit, glm::dot(hit - eye, camera.forward()));
        // Whether the ray went against the eye's in the top bit, off-centre squared (at most
        // 0.5) in the next 23, the index in the low 40.
        const std::uint64_t against = glm::dot(samples.direction(i), hit - eye) <= 0 ? 1 : 0;
        const auto off = static_cast<std::uint64_t>(offCentre(at) * 2 * 0x7fffff);
        atomicMin(best[std::size_t(p.pixel)], (against << 63) | (off << 40) | std::uint64_t(i));
    });
    std::vector<std::pair<std::int32_t, std::int64_t>> chosen;
    for (std::size_t k = 0; k < pixels; ++k) {
        const std::uint64_t key = best[k].load(std::memory_order_relaxed);
        if (key != ~std::uint64_t(0))
            chosen.emplace_back(std::int32_t(k), std::int64_t(key & ((1ull << 40) - 1)));
    }
    return chosen;
}

/// viewPointsOf's merge: each kept point's radiance becomes the mean of its pixel's samples of
/// its surface (within 1% of its depth, on the side shown, within the chosen sample's tolerance
/// `tolerances[c]` of its plane), ShadedPoint::samples how many. Summed in fixed point per
/// thread, then added: integer sums in any order are the same (the same on any number of
/// threads).
template <class Samples>
void mergePixelSamples(const Samples& samples, const CameraRays& camera,
                       const std::vector<Projected>& projected,
                       const std::vector<std::pair<std::int32_t, std::int64_t>>& chosen,
                       const std::vector<std::uint8_t>& keep, const std::vector<float>& tolerances,
                       std::vector<ShadedPoint>& points) {
    constexpr double kScale = 1048576.0;  // 2^20 per W/m²/sr
    const Vec3 eye = camera.origin();
    // Per pixel with a kept point, what the test reads (one record, not the point).
    struct Surface {
        std::int32_t point = -1;
        float depth = 0, tolerance = 0, offset = 0;  ///< plane: dot(normal, x) = offset
        glm::vec3 normal{0.0f};
    };
    std::vector<Surface> surface(std::size_t(camera.width()) * camera.height());
    for (std::size_t c = 0; c < chosen.size(); ++c) {
        if (!keep[c]) continue;
        const ShadedPoint& p = points[c];
        surface[std::size_t(chosen[c].first)] = {
            std::int32_t(c), float(glm::dot(p.position - eye, camera.forward())), tolerances[c],
            float(glm::dot(p.normal, p.position)), glm::vec3(p.normal)};
    }
    struct Sum {
        std::int64_t rgb[3] = {0, 0, 0};
        std::int64_t n = 0;
    };
    tbb::enumerable_thread_specific<std::vector<Sum>> sums(
        [&] { return std::vector<Sum>(chosen.size()); });
    samples.forEach([&](std::size_t j, std::size_t i, int) {
        const Projected q = projected[j];
        if (q.pixel < 0) return;
        const Surface& f = surface[std::size_t(q.pixel)];
        if (f.point < 0 || !(std::abs(std::bit_cast<float>(q.depth) - f.depth) <= 0.01f * f.depth))
            return;
        const glm::vec3 hit(samples.hit(i));
        if (std::abs(glm::dot(f.normal, hit) - f.offset) > f.tolerance ||
            !(samples.facing(i, f.normal) < 0))
            return;
        const Rgb r = samples.radiance(i);
        Sum& sum = sums.local()[std::size_t(f.point)];
        for (int k = 0; k < 3; ++k) sum.rgb[k] += std::llround(double(r[k]) * kScale);
        ++sum.n;
    });
    for (std::size_t c = 0; c < chosen.size(); ++c) {
        if (!keep[c]) continue;
        Sum total;
        for (const std::vector<Sum>& local : sums) {
            for (int k = 0; k < 3; ++k) total.rgb[k] += local[c].rgb[k];
            total.n += local[c].n;
        }
        if (total.n < 1) continue;
        for (int k = 0; k < 3; ++k)
            points[c].radiance[k] = double(total.rgb[k]) / (kScale * double(total.n));
        points[c].samples = int(std::min<std::int64_t>(total.n, 1 << 20));
    }
}

/// The view's points of `samples` (holodeckViewPoints, HoloHitIndex::viewPoints): per pixel
/// the sample choosePerPixel chooses, checked by the eye's ray towards its stored hit, which
/// must end at a surface point within the sample's tolerance of it, on the side of the
/// surface the sample's ray came from (a batch fill's rays also start inside solids and see
/// their insides, black). Otherwise the pixel gets nothing from the holodeck. The sample's
/// own ray is not traced again: in a diffuse scene the radiance of the point it saw does not
/// depend on where it was seen from, and samples whose light or surface an edit changed are
/// the invalidation's (HoloServer::invalidate). The point is where the eye's ray ends, with the
/// mean radiance of the pixel's samples of that surface (RenderCacheOptions::mergeSamples'
/// rule: the pixel's samples within 1% of its depth, on the side shown and within their
/// tolerance of the surface's plane; ShadedPoint::samples how many), and one point a pixel
/// still when a point lands a pixel beside the one its stored hit chose. `cancelled` (may be
/// empty), asked between passes and blocks of work, ends the read early with no points.
template <class Samples>
std::vector<ShadedPoint> viewPointsOf(const Samples& samples, const Discretization& disc,
                                      const RayTracer& tracer, const CameraRays& camera,
                                      std::uint64_t frame, std::uint64_t shading,
                                      const std::function<bool()>& cancelled) {
    const int w = camera.width(), h = camera.height();
    const Vec3 eye = camera.origin();
    std::vector<Projected> projected;
    std::vector<std::atomic<std::uint32_t>> front;
    const auto chosen = choosePerPixel(camera, samples, projected, front);
    if (cancelled && cancelled()) return {};

    // Check each chosen sample with the eye's ray.
    std::vector<ShadedPoint> points(chosen.size());
    std::vector<std::uint8_t> keep(chosen.size(), 0);
    std::vector<float> tolerances(chosen.size(), 0.0f);
    std::atomic<bool> stop{false};
    tbb::parallel_for(std::size_t(0), chosen.size(), [&](std::size_t c) {
        // Asked once a block of 4,096 points.
        if (cancelled && c % 4096 == 0 && cancelled()) stop.store(true, std::memory_order_relaxed);
        if (stop.load(std::memory_order_relaxed)) return;
        const std::size_t i = std::size_t(chosen[c].second);
        const Vec3 hit = samples.hit(i);
        const Vec3 toHit = hit - eye;
        const double length = glm::length(toHit);
        if (!(length > 1e-6)) return;
        const Vec3 along = toHit / length;
        const RayTracer::FirstHit seen = tracer.firstHit(eye, along);
        if (seen.element < 0) return;
        const Element& e = disc.elements()[std::size_t(seen.element)];
        const Vec3 normal = seen.backFace ? -e.normal : e.normal;  // towards the eye
        const Vec3 position = eye + double(seen.t) * along;
        const double tolerance = samples.tolerance(i, samples.section(i));
        tolerances[c] = float(tolerance);
        // The surface the eye sees there holds the stored hit (the eye's ray meets it within
        // the sample's tolerance; a tolerance more along the ray where it meets it obliquely),
        // and the sample's ray arrived on the side the eye sees.
        if (std::abs(glm::dot(hit - position, normal)) > tolerance ||
            glm::length(hit - position) > 4 * tolerance ||
            !(glm::dot(samples.direction(i), normal) < 0))
            return;
        const auto pixel = camera.projectToPixel(position);
        if (!pixel || pixel->x < 0 || pixel->y < 0 || pixel->x >= w || pixel->y >= h) return;
        ShadedPoint& p = points[c];
        p.pixel = *pixel;
        p.position = position;
        p.normal = normal;
        p.radiance = samples.radiance(i);
        p.object = e.object;
        p.element = seen.element;
        p.frame = frame;
        p.shading = shading;
        keep[c] = 1;
    });
    if (stop.load() || (cancelled && cancelled())) return {};

    mergePixelSamples(samples, camera, projected, chosen, keep, tolerances, points);

    // A point may land a pixel beside the one its stored hit chose (the hit is decoded to a few
    // millimetres): one point a pixel still, the nearer its centre.
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

/// The samples of the beams whose box meets a view (viewPointsOf's candidates): beam by beam,
/// candidate j of a beam's samples after those of the beams before it.
struct HoloHitIndex::SeenSamples {
    const HoloHitIndex& index;
    std::vector<std::size_t> seen;
    std::vector<std::size_t> start;  ///< per seen beam, its first candidate
    std::size_t count() const { return start.empty() ? 0 : start.back(); }
    template <class Body>
    void forEach(const Body& body) const {
        tbb::parallel_for(std::size_t(0), seen.size(), [&](std::size_t s) {
            const Bounds& b = index.mBeams[seen[s]];
            for (std::size_t k = 0; k < b.count; ++k) body(start[s] + k, b.first + k, b.section);
        });
    }
    Vec3 hit(std::size_t i) const { return Vec3(index.mHits[i]); }
    Vec3 direction(std::size_t i) const { return decodeDirection(index.mDirections[i]); }
    /// The sign of dot(direction(i), n) (the merge's side test).
    float facing(std::size_t i, const glm::vec3& n) const {
        return glm::dot(unnormalizedDirection(index.mDirections[i]), n);
    }
    Rgb radiance(std::size_t i) const { return decodeRgbe(index.mSamples[i].rgbe); }
    int section(std::size_t i) const {
        // The beam holding sample i: the last whose first sample is at most i.
        const auto after =
            std::upper_bound(index.mBeams.begin(), index.mBeams.end(), i,
                             [](std::size_t at, const Bounds& b) { return at < b.first; });
        return std::prev(after)->section;
    }
    double tolerance(std::size_t i, int section) const {
        return hitTolerance(index.mSections[std::size_t(section)],
                            index.mCodes[std::size_t(section)], index.mSamples[i]);
    }
};

std::vector<ShadedPoint> HoloHitIndex::viewPoints(const Discretization& disc,
                                                  const RayTracer& tracer, const CameraRays& camera,
                                                  std::uint64_t frame, std::uint64_t shading,
                                                  const std::function<bool()>& cancelled) const {
    SeenSamples samples{*this, seenBeams(camera), {}};
    samples.start.reserve(samples.seen.size() + 1);
    samples.start.push_back(0);
    for (std::size_t k : samples.seen)
        samples.start.push_back(samples.start.back() + mBeams[k].count);
    if (cancelled && cancelled()) return {};
    return viewPointsOf(samples, disc, tracer, camera, frame, shading, cancelled);
}

namespace {

/// holodeckViewPoints' beams' samples, decoded: viewPointsOf's candidates in their order.
struct StoredSamples {
    const HoloServer& server;
    const std::vector<HoloSection>& sections;
    std::vector<int> sectionOf;
    std::vector<HoloSample> stored;
    std::vector<DecodedSample> decoded;
    std::size_t count() const { return stored.size(); }
    template <class Body>
    void forEach(const Body& body) const {
        tbb::parallel_for(tbb::blocked_range<std::size_t>(0, stored.size(), 4096),
                          [&](const auto& r) {
                              for (std::size_t i = r.begin(); i != r.end(); ++i)
                                  body(i, i, sectionOf[i]);
                          });
    }
    Vec3 hit(std::size_t i) const { return decoded[i].hit; }
    Vec3 direction(std::size_t i) const { return decoded[i].direction; }
    float facing(std::size_t i, const glm::vec3& n) const {
        return glm::dot(glm::vec3(decoded[i].direction), n);
    }
    Rgb radiance(std::size_t i) const { return decoded[i].radiance; }
    int section(std::size_t i) const { return sectionOf[i]; }
    double tolerance(std::size_t i, int section) const {
        return hitTolerance(sections[std::size_t(section)], server.distanceCode(section),
                            stored[i]);
    }
};

}  // namespace

std::vector<ShadedPoint> holodeckViewPoints(HoloServer& server,
                                            const std::vector<BeamRequest>& view,
                                            const Discretization& disc, const RayTracer& tracer,
                                            const CameraRays& camera, std::uint64_t frame,
                                            std::uint64_t shading) {
    // The beams' samples (read on this thread: the server is not thread-safe), decoded.
    StoredSamples samples{server, server.file().sections(), {}, {}, {}};
    std::vector<std::int64_t> beamOf;
    for (const BeamRequest& r : view)
        for (const HoloSample& sample : server.beam(r.section, r.beam))
            if (sample.distance != 0xffff) {  // a miss: nothing to show
                samples.stored.push_back(sample);
                samples.sectionOf.push_back(r.section);
                beamOf.push_back(r.beam);
            }
    samples.decoded.resize(samples.stored.size());
    tbb::parallel_for(std::size_t(0), samples.stored.size(), [&](std::size_t i) {
        const int s = samples.sectionOf[i];
        samples.decoded[i] = decodeSample(samples.stored[i], samples.sections[std::size_t(s)],
                                          beamOf[i], server.distanceCode(s));
    });
    return viewPointsOf(samples, disc, tracer, camera, frame, shading, {});
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
