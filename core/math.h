#pragma once
// The math types every module shares (glm's double vectors), the luminance of a colour and
// the geometry of planar polygons: Newell's normal and a 2D frame of a polygon's plane.
//
// Index: types · luminance · distanceToSegment · newellNormal · PlaneFrame

#include <algorithm>
#include <glm/glm.hpp>
#include <vector>

namespace penumbra {

using Vec3 = glm::dvec3;
using Rgb = glm::dvec3;  ///< Radiometric RGB triple (W/m² for radiosity and irradiance).
using Mat4 = glm::dmat4;
using Vec2 = glm::dvec2;

/// Luminance Y of a linear RGB triple (Rec. 709 primaries).
inline double luminance(const Rgb& c) { return 0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z; }

/// Distance from p to the segment a–b (2D or 3D; a point when a = b).
template <typename V>
double distanceToSegment(const V& p, const V& a, const V& b) {
    const V d = b - a;
    const double dd = glm::dot(d, d);
    const double t = dd > 0 ? std::clamp(glm::dot(p - a, d) / dd, 0.0, 1.0) : 0.0;
    return glm::length(p - (a + t * d));
}

/// Newell's method: the area vector of a polygon (normal direction, length twice the area),
/// exact for planar polygons and the best-fit normal of nearly planar ones.
Vec3 newellNormal(const std::vector<Vec3>& polygon);
/// newellNormal of an indexed face: the polygon positions[corners[0]], …,
/// positions[corners[count − 1]].
Vec3 newellNormal(const std::vector<Vec3>& positions, const int* corners, std::size_t count);

/// newellNormal normalized; zero for a degenerate polygon.
Vec3 unitNormal(const std::vector<Vec3>& polygon);

/// An orthonormal frame of a plane: origin, axes u and v with u × v = n, so counter-clockwise
/// in 2D is counter-clockwise seen from the side n points to.
struct PlaneFrame {
    Vec3 origin{0.0}, u{1, 0, 0}, v{0, 1, 0}, n{0, 0, 1};
    PlaneFrame() = default;
    /// The plane of `polygon` (normal: Newell's, or `normal` when given), u along its first
    /// edge.
    explicit PlaneFrame(const std::vector<Vec3>& polygon);
    PlaneFrame(const std::vector<Vec3>& polygon, const Vec3& normal);
    Vec2 to2(const Vec3& p) const { return {glm::dot(p - origin, u), glm::dot(p - origin, v)}; }
    Vec3 to3(const Vec2& p) const { return origin + p.x * u + p.y * v; }
};

}  // namespace penumbra
