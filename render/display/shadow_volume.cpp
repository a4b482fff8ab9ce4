#include "render/display/shadow_volume.h"

#include <cmath>

namespace penumbra {

ShaftLight::ShaftLight(const Light& light) : polygon(light.polygon) {
    if (polygon.empty()) return;
    lo = hi = polygon[0];
    for (const Vec3& p : polygon) {
        lo = glm::min(lo, p);
        hi = glm::max(hi, p);
        centroid += p;
    }
    centroid /= static_cast<double>(polygon.size());
    normal = newellNormal(polygon);
    area = 0.5 * glm::length(normal);
    samples.push_back(centroid);
    if (polygon.size() > 1)
        for (const Vec3& p : polygon) samples.push_back(p + 0.25 * (centroid - p));
}

namespace {

/// Whether the segment a→b meets the box [lo, hi] (slab test).
bool segmentMeetsBox(const Vec3& a, const Vec3& b, const Vec3& lo, const Vec3& hi) {
    const Vec3 d = b - a;
    double t0 = 0, t1 = 1;
    for (int k = 0; k < 3; ++k) {
        if (std::abs(d[k]) < 1e-300) {
            if (a[k] < lo[k] || a[k] > hi[k]) return false;
            continue;
        }
        double ta = (lo[k] - a[k]) / d[k], tb = (hi[k] - a[k]) / d[k];
        if (ta > tb) std::swap(ta, tb);
        t0 = std::max(t0, ta);
        t1 = std::min(t1, tb);
        if (t0 > t1) return false;
    }
    return true;
}

/// Whether the whole box (centre c, half extents h) lies strictly on the negative side of the
/// plane through `through` with normal m.
bool boxOutside(const Vec3& m, const Vec3& through, const Vec3& c, const Vec3& h) {
    return glm::dot(c - through, m) + std::abs(m.x) * h.x + std::abs(m.y) * h.y +
               std::abs(m.z) * h.z <
           0;
}

}  // namespace

bool shaftMeetsBox(const Vec3& x, const ShaftLight& light, const Vec3& lo, const Vec3& hi) {
    const std::size_t n = light.polygon.size();
    if (n == 0) return false;
    // The shaft's bounding box against the object's.
    const Vec3 slo = glm::min(x, light.lo), shi = glm::max(x, light.hi);
    if (!(lo.x <= shi.x && slo.x <= hi.x && lo.y <= shi.y && slo.y <= hi.y && lo.z <= shi.z &&
          slo.z <= hi.z))
        return false;
    const Vec3 c = 0.5 * (lo + hi), h = 0.5 * (hi - lo);
    // A point light: the segment against the box.
    if (n == 1) return segmentMeetsBox(x, light.polygon[0], lo, hi);
    // Behind the emitting plane: no light from it reaches x.
    const double side = glm::dot(x - light.centroid, light.normal);
    if (!(side > 0)) return false;
    // The pyramid's faces: the light's plane (inward: towards x) and a side plane through x and
    // each edge (inward: towards the light's centroid).
    if (boxOutside(light.normal, light.centroid, c, h)) return false;
    for (std::size_t i = 0; i < n; ++i) {
        Vec3 m = glm::cross(light.polygon[i] - x, light.polygon[(i + 1) % n] - x);
        if (glm::dot(m, light.centroid - x) < 0) m = -m;
        if (boxOutside(m, x, c, h)) return false;
    }
    return true;
}

double blockedFraction(const Vec3& x, const ShaftLight& light, const Vec3& lo, const Vec3& hi) {
    if (light.samples.empty() || !shaftMeetsBox(x, light, lo, hi)) return 0;
    int blocked = 0;
    for (const Vec3& s : light.samples) blocked += segmentMeetsBox(x, s, lo, hi) ? 1 : 0;
    return double(blocked) / double(light.samples.size());
}

double lightWeight(const Vec3& x, const Vec3& n, const ShaftLight& light) {
    if (light.polygon.empty()) return 0;
    const Vec3 d = light.centroid - x;
    const double dd = glm::dot(d, d);
    if (!(dd > 0)) return 0;
    const double r = std::sqrt(dd);
    const double cosX = glm::dot(n, d) / r;
    if (!(cosX > 0)) return 0;
    if (light.polygon.size() == 1) return cosX / (M_PI * dd);
    // The Newell normal's length is twice the area.
    const double cosL = -glm::dot(light.normal, d) / (r * 2 * light.area);
    if (!(cosL > 0)) return 0;
    return cosX * cosL * light.area / (M_PI * dd);
}

}  // namespace penumbra
