#include "core/math.h"

namespace penumbra {

namespace {

/// Newell's sum over the k corners corner(0), …, corner(k − 1): Σ corner(i) × corner(i + 1).
template <typename Corner>
Vec3 newellSum(std::size_t k, Corner&& corner) {
    Vec3 n(0.0);
    for (std::size_t i = 0; i < k; ++i) n += glm::cross(corner(i), corner((i + 1) % k));
    return n;
}

}  // namespace

Vec3 newellNormal(const std::vector<Vec3>& polygon) {
    return newellSum(polygon.size(), [&](std::size_t i) -> const Vec3& { return polygon[i]; });
}

Vec3 newellNormal(const std::vector<Vec3>& positions, const int* corners, std::size_t count) {
    return newellSum(count,
                     [&](std::size_t i) -> const Vec3& { return positions[corners[i]]; });
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
