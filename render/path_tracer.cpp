#include "render/path_tracer.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <sstream>
#include <thread>

#include "core/math.h"
#include "core/random.h"
#include "render/camera_rays.h"
#include "solver/discretization.h"
#include "solver/form_factor.h"
#include "solver/ray_tracer.h"

namespace penumbra {

namespace {

/// One emitting triangle (a fan triangle of an emitting element's front).
struct EmitterTriangle {
    Vec3 a, b, c, normal;
    double area = 0;
    Rgb emission{0.0};
};

/// Emitters chosen with probability proportional to area × luminance of emission.
struct Emitters {
    std::vector<EmitterTriangle> triangles;
    std::vector<double> cumulative;  ///< of area × luminance
    double total = 0;

    explicit Emitters(const Discretization& disc) {
        for (std::size_t e = 0; e < disc.elements().size(); ++e) {
            const int ei = static_cast<int>(e);
            if (!disc.elementAlive(ei)) continue;
            const Element& el = disc.elements()[e];
            if (disc.objects()[el.object].isBackFace(el.face)) continue;  // emission is front-only
            const Material& m = disc.elementMaterial(ei);
            if (!m.isEmitter()) continue;
            const std::vector<Vec3> poly = disc.elementPolygon(ei);
            for (std::size_t k = 1; k + 1 < poly.size(); ++k) {
                const Vec3 c = glm::cross(poly[k] - poly[0], poly[k + 1] - poly[0]);
                const double area = 0.5 * glm::length(c);
                if (!(area > 0)) continue;
                triangles.push_back(
                    {poly[0], poly[k], poly[k + 1], c / (2 * area), area, m.emission});
                total += area * luminance(m.emission);
                cumulative.push_back(total);
            }
        }
    }
    /// A triangle by power and a uniform point on it; `pdfArea` the density per unit area.
    const EmitterTriangle& sample(SplitMix& rng, Vec3& point, double& pdfArea) const {
        const double u = rng.next() * total;
        std::size_t i =
            std::upper_bound(cumulative.begin(), cumulative.end(), u) - cumulative.begin();
        i = std::min(i, triangles.size() - 1);
        const EmitterTriangle& t = triangles[i];
        double r0 = rng.next(), r1 = rng.next();
        if (r0 + r1 > 1) r0 = 1 - r0, r1 = 1 - r1;
        point = t.a + r0 * (t.b - t.a) + r1 * (t.c - t.a);
        pdfArea = luminance(t.emission) / total;
        return t;
    }
};

/// A unit vector distributed by cos θ about n (Malley's method).
Vec3 cosineDirection(const Vec3& n, SplitMix& rng) {
    const double r = std::sqrt(rng.next()), phi = 2 * M_PI * rng.next();
    const Vec3 t = std::abs(n.x) > 0.5 ? glm::normalize(glm::cross(n, Vec3(0, 1, 0)))
                                       : glm::normalize(glm::cross(n, Vec3(1, 0, 0)));
    const Vec3 b = glm::cross(n, t);
    return glm::normalize(r * std::cos(phi) * t + r * std::sin(phi) * b +
                          std::sqrt(std::max(0.0, 1 - r * r)) * n);
}

/// The power heuristic (Veach 1997, β = 2): the weight of the strategy with density `a`
/// against the other's `b`.
double powerHeuristic(double a, double b) {
    const double a2 = a * a, b2 = b * b;
    return a2 + b2 > 0 ? a2 / (a2 + b2) : 0.0;
}

/// Radiance along one camera ray. Light reaches each vertex two ways, combined by multiple
/// importance sampling: a point sampled on an emitter (next-event estimation) and the next
/// cosine-sampled direction happening to hit an emitter. Either alone is unbiased; the
/// combination keeps the variance finite where an emitter meets the surface (a lamp's
/// corner, a glowing wall), where area sampling alone has heavy tails.
Rgb tracePath(const Discretization& disc, const RayTracer& tracer, const Emitters& emitters,
              Vec3 origin, Vec3 dir, SplitMix& rng, const PathTraceOptions& o) {
    const double eps = tracer.epsilon();
    Rgb radiance(0.0), throughput(1.0);
    double directionPdf = 0;  ///< solid-angle density of `dir` (0: a camera ray)
    for (int depth = 0; depth < o.maxDepth; ++depth) {
        const RayTracer::FirstHit hit = tracer.firstHit(origin, dir);
        if (hit.element < 0 || hit.backFace) break;  // a one-sided surface's back is black
        const Element& el = disc.elements()[hit.element];
        const Material& m = disc.elementMaterial(hit.element);
        const bool back = disc.objects()[el.object].isBackFace(el.face);
        const Vec3 n = el.normal;
        if (!back && m.isEmitter()) {
            double weight = 1;
            if (depth > 0 && emitters.total > 0) {
                const double cosHit = -glm::dot(n, dir);
                const double t = hit.t;
                const double lightPdf =
                    luminance(m.emission) / emitters.total * t * t / std::max(cosHit, 1e-300);
                weight = powerHeuristic(directionPdf, lightPdf);
            }
            radiance += throughput * m.emission * (weight / M_PI);
        }
        const Vec3 x = origin + static_cast<double>(hit.t) * dir;
        const Rgb rho = m.reflectance;
        if (rho.x <= 0 && rho.y <= 0 && rho.z <= 0) break;
        const Vec3 from = x + n * eps;
        if (emitters.total > 0) {
            Vec3 y;
            double pdfArea = 0;
            const EmitterTriangle& t = emitters.sample(rng, y, pdfArea);
            const Vec3 d = y - x;
            const double r2 = glm::dot(d, d);
            const double cx = glm::dot(n, d), cy = -glm::dot(t.normal, d);
            if (r2 > 0 && cx > 0 && cy > 0 && pdfArea > 0 &&
                !tracer.occluded(from, y + t.normal * eps)) {
                const double r = std::sqrt(r2);
                const double lightPdf = pdfArea * r2 / (cy / r);  // per solid angle
                const double bsdfPdf = cx / r / M_PI;
                // (ρ/π)(E/π) cos θx cos θy / r² / pdf, the cosines carrying |d| each.
                const double g = cx * cy / (r2 * r2);
                radiance += throughput * rho * t.emission *
                            (g / (M_PI * M_PI * pdfArea) * powerHeuristic(lightPdf, bsdfPdf));
            }
        }
        throughput *= rho;  // (ρ/π) cos θ / (cos θ / π)
        if (depth + 1 >= o.rouletteDepth) {
            const double survive =
                std::min(0.95, std::max({throughput.x, throughput.y, throughput.z}));
            if (!(rng.next() < survive)) break;
            throughput /= survive;
        }
        origin = from;
        dir = cosineDirection(n, rng);
        directionPdf = std::max(glm::dot(n, dir), 0.0) / M_PI;
    }
    return radiance;
}

/// Calls f(k, element) for each pixel k (row-major) of `rays` whose primary ray first meets the
/// front of an element (rows in parallel).
template <typename F>
void forEachPixelElement(const RayTracer& tracer, const CameraRays& rays, F&& f) {
    tbb::parallel_for(0, rays.height(), [&](int y) {
        for (int x = 0; x < rays.width(); ++x) {
            const RayTracer::FirstHit hit =
                tracer.firstHit(rays.origin(), rays.rayDirection(x + 0.5, y + 0.5));
            if (hit.element < 0 || hit.backFace) continue;
            f(static_cast<std::size_t>(y) * rays.width() + x, hit.element);
        }
    });
}

}  // namespace

std::vector<std::uint8_t> emitterMask(const Discretization& disc, const RayTracer& tracer,
                                      const CameraRays& rays) {
    std::vector<std::uint8_t> mask(static_cast<std::size_t>(rays.width()) * rays.height(), 0);
    forEachPixelElement(tracer, rays, [&](std::size_t k, int element) {
        const Element& el = disc.elements()[element];
        if (disc.elementMaterial(element).isEmitter() &&
            !disc.objects()[el.object].isBackFace(el.face))
            mask[k] = 1;
    });
    // Grown by a pixel: pixels a lamp's edge crosses mix its radiance (tens of times the
    // room's) into theirs by their coverage, which anti-aliasing of either image decides.
    std::vector<std::uint8_t> grown = mask;
    const int w = rays.width(), h = rays.height();
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            if (!mask[static_cast<std::size_t>(y) * w + x]) continue;
            for (int dy = -1; dy <= 1; ++dy)
                for (int dx = -1; dx <= 1; ++dx) {
                    const int nx = x + dx, ny = y + dy;
                    if (nx >= 0 && ny >= 0 && nx < w && ny < h)
                        grown[static_cast<std::size_t>(ny) * w + nx] = 1;
                }
        }
    return grown;
}

PathTraceResult pathTrace(const Discretization& disc, const RayTracer& tracer,
                          const CameraRays& rays, const PathTraceOptions& options,
                          const std::function<void(double)>& progress) {
    const auto start = std::chrono::steady_clock::now();
    const Emitters emitters(disc);
    PathTraceResult result;
    result.image = Image(rays.width(), rays.height());
    const int spp = std::max(1, options.samplesPerPixel);
    const int strata = static_cast<int>(std::lround(std::sqrt(double(spp))));
    const bool stratified = strata * strata == spp;
    std::atomic<int> rowsDone{0};
    auto renderRows = [&] {
        tbb::parallel_for(0, rays.height(), [&](int y) {
            for (int x = 0; x < rays.width(); ++x) {
                const std::uint64_t pixel = static_cast<std::uint64_t>(y) * rays.width() + x;
                SplitMix rng(hashPair(options.seed, pixel));
                Rgb sum(0.0);
                for (int s = 0; s < spp; ++s) {
                    double jx = rng.next(), jy = rng.next();
                    if (stratified) {
                        jx = ((s % strata) + jx) / strata;
                        jy = ((s / strata) + jy) / strata;
                    }
                    sum += tracePath(disc, tracer, emitters, rays.origin(),
                                     rays.rayDirection(x + jx, y + jy), rng, options);
                }
                result.image.at(x, y) = sum / static_cast<double>(spp);
            }
            rowsDone.fetch_add(1, std::memory_order_relaxed);
        });
    };
    if (progress) {
        std::thread worker(renderRows);
        while (rowsDone.load() < rays.height()) {
            progress(double(rowsDone.load()) / rays.height());
            std::this_thread::sleep_for(std::chrono::milliseconds(200));
        }
        worker.join();
        progress(1.0);
    } else {
        renderRows();
    }
    result.emitterMask = emitterMask(disc, tracer, rays);
    result.paths = static_cast<std::uint64_t>(rays.width()) * rays.height() * spp;
    result.seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    return result;
}

double relativeRmse(const Image& image, const Image& reference,
                    const std::vector<std::uint8_t>& mask) {
    double err = 0, norm = 0;
    for (std::size_t i = 0; i < reference.pixels.size() && i < image.pixels.size(); ++i) {
        if (!mask.empty() && mask[i]) continue;
        const Rgb d = image.pixels[i] - reference.pixels[i];
        err += glm::dot(d, d);
        norm += glm::dot(reference.pixels[i], reference.pixels[i]);
    }
    return norm > 0 ? std::sqrt(err / norm) : 0.0;
}

std::vector<std::uint64_t> flatFaceKeys(const Discretization& disc, const RayTracer& tracer,
                                        const CameraRays& rays) {
    std::vector<std::uint64_t> keys(static_cast<std::size_t>(rays.width()) * rays.height(), 0);
    forEachPixelElement(tracer, rays, [&](std::size_t k, int element) {
        const Element& el = disc.elements()[element];
        if (disc.elementMaterial(element).isEmitter()) return;
        // The object and its plane (normal and offset, to a thousandth).
        std::uint64_t key = hashPair(0x9e3779b97f4a7c15ull, std::uint64_t(el.object));
        for (double c : {el.normal.x, el.normal.y, el.normal.z, glm::dot(el.normal, el.centroid)})
            key = hashPair(key, static_cast<std::uint64_t>(std::llround(c * 1e3)));
        keys[k] = key | 1;
    });
    return keys;
}

WindowErrors flatWindowErrors(const Image& image, const Image& reference,
                              const std::vector<std::uint64_t>& faces, int window, int stride,
                              int cell) {
    WindowErrors out;
    const int w = reference.width, h = reference.height;
    cell = std::max(1, cell);
    if (image.width != w || image.height != h || int(faces.size()) != w * h || window < cell)
        return out;
    // The relative error of each cell's mean luminance, at the cell's top-left pixel.
    auto at = [w](int x, int y) { return static_cast<std::size_t>(y) * w + x; };
    auto cellError = [&](int x0, int y0) {
        double a = 0, r = 0;
        for (int y = y0; y < y0 + cell; ++y)
            for (int x = x0; x < x0 + cell; ++x) {
                a += luminance(image.pixels[at(x, y)]);
                r += luminance(reference.pixels[at(x, y)]);
            }
        return (a - r) / r;
    };
    double sumStd = 0;
    for (int y0 = 0; y0 + window <= h; y0 += std::max(1, stride))
        for (int x0 = 0; x0 + window <= w; x0 += std::max(1, stride)) {
            const std::uint64_t face = faces[at(x0, y0)];
            if (face == 0) continue;
            bool one = true;
            for (int y = y0; y < y0 + window && one; ++y)
                for (int x = x0; x < x0 + window && one; ++x)
                    one = faces[at(x, y)] == face && luminance(reference.pixels[at(x, y)]) > 0;
            if (!one) continue;
            double sum = 0, sum2 = 0, n = 0;
            for (int y = y0; y + cell <= y0 + window; y += cell)
                for (int x = x0; x + cell <= x0 + window; x += cell) {
                    const double e = cellError(x, y);
                    sum += e;
                    sum2 += e * e;
                    n += 1;
                }
            const double mean = sum / n;
            const double sd = std::sqrt(std::max(0.0, sum2 / n - mean * mean));
            ++out.windows;
            sumStd += sd;
            if (sd > out.maxStd) {
                out.maxStd = sd;
                out.worstX = x0;
                out.worstY = y0;
            }
        }
    if (out.windows > 0) out.meanStd = sumStd / out.windows;
    return out;
}

std::string WindowErrors::toString() const {
    std::ostringstream s;
    s << "WindowErrors{windows=" << windows << ", maxStd=" << maxStd << ", meanStd=" << meanStd
      << ", worst=(" << worstX << ", " << worstY << ")}";
    return s.str();
}

}  // namespace penumbra
