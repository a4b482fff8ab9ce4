// ViewCamera against independent truths: render/camera_rays.h's projection of world points,
// distances and angles computed directly.

#include "ui/view_camera.h"

#include <gtest/gtest.h>

#include <cmath>

#include "render/camera_rays.h"

namespace penumbra {
namespace {

constexpr int kW = 640, kH = 480;

glm::dvec2 project(const ViewCamera& v, const Vec3& p) {
    const auto px = CameraRays(v.toCamera(), kW, kH).projectToPixel(p);
    EXPECT_TRUE(px.has_value()) << v.toString();
    return px.value_or(glm::dvec2(NAN));
}

TEST(ViewCamera, RoundTripsASceneCamera) {
    Camera c;
    c.position = {1.5, 1.6, 2.1};
    c.lookAt = {-0.2, 1.15, -0.6};
    c.fovDeg = 70;
    const ViewCamera v = ViewCamera::fromCamera(c);
    const Camera back = v.toCamera();
    EXPECT_NEAR(glm::length(back.position - c.position), 0.0, 1e-12) << v.toString();
    EXPECT_NEAR(glm::length(back.lookAt - c.lookAt), 0.0, 1e-12);
    EXPECT_EQ(back.fovDeg, 70);
    // The camera frame is orthonormal and right-handed like CameraRays'.
    const CameraRays rays(back, kW, kH);
    EXPECT_NEAR(glm::length(v.forward() - rays.forward()), 0.0, 1e-12);
    EXPECT_NEAR(glm::length(v.right() - rays.right()), 0.0, 1e-12);
    EXPECT_NEAR(glm::length(v.up() - rays.up()), 0.0, 1e-12);
}

TEST(ViewCamera, OrbitKeepsTheTargetCentredAndTheDistance) {
    ViewCamera v;
    v.target = {0.3, 1.0, -0.4};
    v.distance = 2.5;
    for (int k = 0; k < 20; ++k) {
        v.orbit(0.37, k % 2 ? 0.21 : -0.33);
        EXPECT_NEAR(glm::length(v.position() - v.target), 2.5, 1e-12);
        const glm::dvec2 p = project(v, v.target);
        EXPECT_NEAR(p.x, kW / 2.0, 1e-9);
        EXPECT_NEAR(p.y, kH / 2.0, 1e-9);
        EXPECT_LE(std::abs(v.pitch), ViewCamera::kMaxPitch);
    }
    v.orbit(0, 10.0);
    EXPECT_DOUBLE_EQ(v.pitch, ViewCamera::kMaxPitch);
}

TEST(ViewCamera, PanKeepsAPointAtTheTargetDepthUnderTheCursor) {
    ViewCamera v;
    v.target = {0, 1, 0};
    v.distance = 3;
    v.yaw = 0.4;
    v.pitch = -0.3;
    v.fovDeg = 55;
    // A point in the plane through the target facing the camera, off-centre.
    const Vec3 p = v.target + 0.7 * v.right() - 0.4 * v.up();
    const glm::dvec2 before = project(v, p);
    v.pan(37.0, -21.0, kH);
    const glm::dvec2 after = project(v, p);
    EXPECT_NEAR(after.x - before.x, 37.0, 1e-9);
    EXPECT_NEAR(after.y - before.y, -21.0, 1e-9);
}

TEST(ViewCamera, ZoomScalesTheDistanceAndStopsAtTheMinimum) {
    ViewCamera v;
    v.distance = 2;
    v.zoom(0.5);
    EXPECT_DOUBLE_EQ(v.distance, 1.0);
    v.zoom(-3);  // ignored
    EXPECT_DOUBLE_EQ(v.distance, 1.0);
    v.zoom(1e-9);
    EXPECT_DOUBLE_EQ(v.distance, ViewCamera::kMinDistance);
}

TEST(ViewCamera, FlyMovesEyeAndTargetAlongTheCameraAxes) {
    ViewCamera v;
    v.yaw = 1.1;
    v.pitch = 0.2;
    const Vec3 eye = v.position(), target = v.target;
    const Vec3 f = v.forward(), r = v.right(), u = v.up();
    v.fly({0.5, -0.25, 2.0});
    const Vec3 expected = 0.5 * r - 0.25 * u + 2.0 * f;
    EXPECT_NEAR(glm::length(v.position() - eye - expected), 0.0, 1e-12);
    EXPECT_NEAR(glm::length(v.target - target - expected), 0.0, 1e-12);
}

TEST(ViewCamera, FrameFitsTheSphereInTheView) {
    for (double aspect : {1.5, 0.6}) {
        ViewCamera v;
        v.yaw = -0.7;
        v.pitch = 0.25;
        v.fovDeg = 50;
        const Vec3 centre{1, 2, 3};
        const double radius = 0.8;
        v.frame(centre, radius, aspect);
        const int w = static_cast<int>(kH * aspect);
        const CameraRays rays(v.toCamera(), w, kH);
        // Every point of the sphere lies in the image; the limiting axis is touched.
        double reachX = 0, reachY = 0;
        for (int i = 0; i <= 40; ++i)
            for (int j = 0; j < 80; ++j) {
                const double th = M_PI * i / 40, ph = 2 * M_PI * j / 80;
                const Vec3 p = centre + radius * Vec3(std::sin(th) * std::cos(ph), std::cos(th),
                                                      std::sin(th) * std::sin(ph));
                const auto px = rays.projectToPixel(p);
                ASSERT_TRUE(px.has_value());
                EXPECT_GE(px->x, -1e-6);
                EXPECT_LE(px->x, w + 1e-6);
                EXPECT_GE(px->y, -1e-6);
                EXPECT_LE(px->y, kH + 1e-6);
                reachX = std::max(reachX, std::abs(px->x - w / 2.0) / (w / 2.0));
                reachY = std::max(reachY, std::abs(px->y - kH / 2.0) / (kH / 2.0));
            }
        EXPECT_GT(std::max(reachX, reachY), 0.97) << "aspect " << aspect;
    }
}

}  // namespace
}  // namespace penumbra
