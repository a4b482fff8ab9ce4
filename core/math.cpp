#include "core/math.h"

namespace penumbra {

Vec3 newellNormal(const std::vector<Vec3>& polygon) {
    Vec3 n(0.0);
    for (std::size_t i = 0, k = polygon.size(); i < k; ++i)
        n += glm::cross(polygon[i], polygon[(i + 1) % k]);
    return n;
}

Vec3 unitNormal(const std::vector<Vec3>& polygon) {
    const Vec3 n = newellNormal(polygon);
    const double length = glm::length(n);
    return length > 0 ? n / length : n;
}

PlaneFrame::PlaneFrame(const std::vector<Vec3>& polygon)
    : PlaneFrame(polygon, unitNormal(polygon)) {}

PlaneFrame::PlaneFrame(const std::vector<Vec3>& polygon, const Vec3& normal)
    : origin(polygon[0]), n(normal) {
    u = glm::normalize(polygon[1] - polygon[0]);
    v = glm::cross(n, u);
}

}  // namespace penumbra
