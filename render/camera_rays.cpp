#include "render/camera_rays.h"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>

namespace penumbra {

CameraRays::CameraRays(const Camera& camera, int width, int height)
    : mOrigin(camera.position), mWidth(width), mHeight(height) {
    if (width <= 0 || height <= 0) {
        throw std::invalid_argument("camera '" + camera.name +
                                    "': image size must be positive, got " + std::to_string(width) +
                                    "x" + std::to_string(height));
    }
    if (!(camera.fovDeg > 0.0 && camera.fovDeg < 180.0)) {
        throw std::invalid_argument("camera '" + camera.name +
                                    "': fov_deg must be in (0, 180), got " +
                                    std::to_string(camera.fovDeg));
    }
    const Vec3 view = camera.lookAt - camera.position;
    const double viewLength = glm::length(view);
    if (!(viewLength > 0.0) || !std::isfinite(viewLength)) {
        throw std::invalid_argument("camera '" + camera.name +
                                    "': look_at must differ from position");
    }
    mForward = view / viewLength;

    // Build an orthonormal frame; replace an up vector parallel to the view direction.
    Vec3 upHint = camera.up;
    Vec3 right = glm::cross(mForward, upHint);
    if (glm::length(right) < 1e-9 * std::max(1.0, glm::length(upHint))) {
        upHint = std::abs(mForward.y) < 0.9 ? Vec3(0, 1, 0) : Vec3(1, 0, 0);
        right = glm::cross(mForward, upHint);
    }
    mRight = glm::normalize(right);
    mUp = glm::cross(mRight, mForward);

    mTanHalfY = std::tan(glm::radians(camera.fovDeg) * 0.5);
    mTanHalfX = mTanHalfY * static_cast<double>(width) / static_cast<double>(height);
    mPixelRight = mRight * (0.5 * width / mTanHalfX);
    mPixelUp = mUp * (0.5 * height / mTanHalfY);
}

Vec3 CameraRays::rayDirection(double px, double py) const {
    // Map pixel coordinates to the image plane at unit distance.
    const double x = (2.0 * px / mWidth - 1.0) * mTanHalfX;
    const double y = (1.0 - 2.0 * py / mHeight) * mTanHalfY;
    return glm::normalize(mForward + x * mRight + y * mUp);
}

std::string CameraRays::toString() const {
    std::ostringstream out;
    out << "CameraRays{origin (" << mOrigin.x << ", " << mOrigin.y << ", " << mOrigin.z
        << "), forward (" << mForward.x << ", " << mForward.y << ", " << mForward.z << "), up ("
        << mUp.x << ", " << mUp.y << ", " << mUp.z << "), " << mWidth << "x" << mHeight
        << ", tanHalfY " << mTanHalfY << "}";
    return out.str();
}

Camera orbitCamera(const Camera& camera, double deg) {
    if (deg == 0) return camera;
    const double angle = glm::radians(deg);
    const Vec3 axis = glm::length(camera.up) > 0 ? glm::normalize(camera.up) : Vec3(0, 1, 0);
    const Vec3 r = camera.position - camera.lookAt;
    Camera out = camera;
    out.position = camera.lookAt + r * std::cos(angle) + glm::cross(axis, r) * std::sin(angle) +
                   axis * glm::dot(axis, r) * (1 - std::cos(angle));
    return out;
}

}  // namespace penumbra
