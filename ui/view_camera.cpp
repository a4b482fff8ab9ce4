#include "ui/view_camera.h"

#include <algorithm>
#include <cmath>
#include <sstream>

namespace penumbra {

ViewCamera ViewCamera::fromCamera(const Camera& camera) {
    ViewCamera v;
    v.target = camera.lookAt;
    const Vec3 d = camera.lookAt - camera.position;
    v.distance = std::max(glm::length(d), kMinDistance);
    const Vec3 f = glm::length(d) > 0 ? d / glm::length(d) : Vec3(0, 0, -1);
    v.pitch = std::clamp(std::asin(std::clamp(f.y, -1.0, 1.0)), -kMaxPitch, kMaxPitch);
    v.yaw = std::atan2(f.x, -f.z);
    v.fovDeg = camera.fovDeg;
    return v;
}

Camera ViewCamera::toCamera() const {
    Camera c;
    c.name = "view";
    c.position = position();
    c.lookAt = target;
    c.up = Vec3(0, 1, 0);
    c.fovDeg = fovDeg;
    return c;
}

Vec3 ViewCamera::forward() const {
    return {std::sin(yaw) * std::cos(pitch), std::sin(pitch), -std::cos(yaw) * std::cos(pitch)};
}

Vec3 ViewCamera::right() const { return {std::cos(yaw), 0.0, std::sin(yaw)}; }

Vec3 ViewCamera::up() const { return glm::cross(right(), forward()); }

Vec3 ViewCamera::position() const { return target - distance * forward(); }

void ViewCamera::orbit(double dYaw, double dPitch) {
    yaw = std::remainder(yaw + dYaw, 2.0 * M_PI);
    pitch = std::clamp(pitch + dPitch, -kMaxPitch, kMaxPitch);
}

void ViewCamera::pan(double dxPixels, double dyPixels, int viewportHeight) {
    // World size of one pixel at the target's depth.
    const double pixel =
        2.0 * distance * std::tan(glm::radians(fovDeg) * 0.5) / std::max(viewportHeight, 1);
    // The scene follows the cursor: the camera moves the other way.
    target += pixel * (-dxPixels * right() + dyPixels * up());
}

void ViewCamera::zoom(double factor) {
    if (factor > 0 && std::isfinite(factor)) distance = std::max(distance * factor, kMinDistance);
}

void ViewCamera::fly(const Vec3& delta) {
    target += delta.x * right() + delta.y * up() + delta.z * forward();
}

void ViewCamera::frame(const Vec3& centre, double radius, double aspect) {
    target = centre;
    double halfFov = glm::radians(fovDeg) * 0.5;
    if (aspect > 0 && aspect < 1) halfFov = std::atan(std::tan(halfFov) * aspect);
    distance = std::max(radius / std::sin(halfFov), kMinDistance);
}

std::string ViewCamera::toString() const {
    std::ostringstream s;
    s << "ViewCamera{target (" << target.x << ", " << target.y << ", " << target.z << "), distance "
      << distance << ", yaw " << yaw << ", pitch " << pitch << ", fov " << fovDeg << "}";
    return s.str();
}

}  // namespace penumbra
