#pragma once
// PointShader's internals shared by its two translation units (point_shader.cpp and
// point_shader_preview.cpp, the drag preview's direct light): the lights, the published
// state, and the job that estimates the preview's H_direct change. Include only from those
// two files.

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <memory>
#include <utility>
#include <vector>

#include "render/display/point_shader.h"

namespace penumbra {

namespace point_shader_detail {

inline bool isZero(const Rgb& c) { return c.x == 0 && c.y == 0 && c.z == 0; }

/// Whether a visibility filter admits anything (a subset, or a world filter).
inline bool admitsSomething(const Visibility& v) { return v.subset >= 0 || v.world != nullptr; }

struct BoundingSphere {
    Vec3 centre{0.0};
    double radius = -1;  ///< < 0: none
};

}  // namespace point_shader_detail

/// An area light: one or more planar polygons of one emitter object with one emission.
struct PointShader::Light {
    int object = -1;
    Rgb emission{0.0};
    std::vector<std::vector<Vec3>> polygons;  ///< counter-clockwise seen from the front
    /// Fan triangles of all polygons, for uniform area sampling.
    struct Triangle {
        Vec3 a, b, c, normal;
        double area;
    };
    std::vector<Triangle> triangles;
    double area = 0;
    bool planar = true;          ///< every polygon in one plane: cannot light its own object
    bool parallelogram = false;  ///< one polygon p0..p3 with p0 + p2 = p1 + p3: a 2D grid

    void finish() {
        triangles.clear();
        area = 0;
        for (const auto& poly : polygons) {
            for (std::size_t k = 1; k + 1 < poly.size(); ++k) {
                Vec3 c = glm::cross(poly[k] - poly[0], poly[k + 1] - poly[0]);
                double a = 0.5 * glm::length(c);
                if (!(a > 0)) continue;
                triangles.push_back({poly[0], poly[k], poly[k + 1], c / (2 * a), a});
                area += a;
            }
        }
        planar = true;
        for (const auto& t : triangles)
            if (glm::dot(t.normal, triangles[0].normal) < 1 - 1e-9 ||
                std::abs(glm::dot(t.a - triangles[0].a, triangles[0].normal)) >
                    1e-9 * (1 + glm::length(t.a - triangles[0].a)))
                planar = false;
        parallelogram = false;
        if (polygons.size() == 1 && polygons[0].size() == 4) {
            const auto& p = polygons[0];
            double scale = glm::length(p[2] - p[0]);
            parallelogram = glm::length(p[0] + p[2] - p[1] - p[3]) <= 1e-9 * scale;
        }
    }

    /// Point of stratum (i, N) with jitter (r0, r1); writes the surface normal there.
    Vec3 sample(int i, int n, int perAxis, double r0, double r1, Vec3& normal) const {
        if (parallelogram) {
            const auto& p = polygons[0];
            double u = (i % perAxis + r0) / perAxis, v = (i / perAxis + r1) / perAxis;
            normal = triangles[0].normal;
            return p[0] + u * (p[1] - p[0]) + v * (p[3] - p[0]);
        }
        // Stratified over the cumulative area of the fan triangles; the stratum's leftover
        // fraction drives one triangle coordinate (sqrt warp), r1 the other.
        double pick = (i + r0) / n * area;
        std::size_t k = 0;
        while (k + 1 < triangles.size() && pick > triangles[k].area) pick -= triangles[k++].area;
        const Triangle& t = triangles[k];
        double s = std::sqrt(std::clamp(pick / t.area, 0.0, 1.0));
        normal = t.normal;
        return (1 - s) * t.a + s * (1 - r1) * t.b + s * r1 * t.c;
    }
};

struct PointShader::State {
    std::uint64_t serial = 0;  ///< set by publish
    std::vector<Light> lights;
    std::vector<std::vector<Rgb>> vertexIndirect;  ///< per object, per mesh vertex
    std::vector<Rgb> elementIndirect;              ///< per element
    /// Per object, per mesh vertex: H_direct in the displayed world (the preview's change
    /// included), blended as vertexIndirect, for shadeFallback(): with it the whole
    /// irradiance as the Gouraud view shows it.
    std::vector<std::vector<Rgb>> vertexDirect;
    // Drag preview.
    int previewObject = -1;
    Visibility previewOnly;                  ///< subset admitting only the preview object
    std::vector<std::uint8_t> previewWorld;  ///< alive objects + the preview (no subset)
    /// Rays see the scene plus the preview object.
    Visibility worldVisibility() const {
        Visibility v;
        v.world = &previewWorld;
        return v;
    }
};

/// One estimate of the preview's H_direct change, per element (George et al.'s temporary
/// buffer for the direct light the point shading traces per sample): on the preview object's
/// elements its H_direct in the preview world, elsewhere the change relative to H_direct(e)
/// (mElementDirect): − what the preview blocks, + what the drag origin blocked, + the
/// preview's own light, − the origin's. Computed in chunks (inline or on the workers).
struct PointShader::DirectJob {
    std::shared_ptr<const State> state;
    int preview = -1, origin = -1;
    int ignore = -1;  ///< version left out of the scene's rays (endDrag: the added preview)
    Visibility previewOnly, originOnly;
    std::vector<std::uint8_t> previewWorld, originWorld;  ///< filters when there is no subset
    std::vector<Light> others;  ///< lights of neither the preview nor the origin
    std::vector<Light> previewLights, originLights;
    std::vector<std::pair<Vec3, double>> lightSpheres;  ///< of `others`
    point_shader_detail::BoundingSphere previewSphere, originSphere;
    std::size_t elements = 0, chunkSize = 256, chunks = 0;
    /// The preview is the drag's origin where it started: nothing changed.
    bool atOrigin = false;
    std::vector<Rgb> value;
    std::vector<std::uint8_t> kind;  ///< 0 nothing, 1 own element (value = H_direct), 2 change
    // Workers (under mQueueMutex): chunks handed out and finished.
    std::size_t nextChunk = 0, doneChunks = 0;
    bool complete() const { return doneChunks == chunks; }
};

}  // namespace penumbra
