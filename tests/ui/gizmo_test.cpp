// Gizmo maths against independent truths: brute-force closest points, analytic ray-plane
// hits, explicit-trigonometry rotations (tests/test_scenes.h), and the gizmo's result
// projected back through render/camera_rays.h.

#include "ui/gizmo.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "render/camera_rays.h"
#include "test_scenes.h"

namespace penumbra {
namespace {

constexpr int kW = 800, kH = 600;

Camera viewCamera() {
    Camera c;
    c.position = {2.2, 1.9, 3.1};
    c.lookAt = {0.1, 0.6, -0.2};
    c.fovDeg = 50;
    return c;
}

glm::dvec2 project(const Camera& c, const Vec3& p) {
    return *CameraRays(c, kW, kH).projectToPixel(p);
}

Ray rayThrough(const Camera& c, glm::dvec2 px) { return pixelRay(c, kW, kH, px.x, px.y); }

Transform startTransform() {
    Transform t;
    t.translate = {0.1, 0.6, -0.2};
    t.rotateDeg = {10, 35, -20};
    t.scale = {0.5, 1.2, 0.8};
    return t;
}

TEST(GizmoGeometry, ClosestLineParameterMatchesBruteForce) {
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> u(-1, 1);
    for (int k = 0; k < 50; ++k) {
        const Vec3 point(u(rng), u(rng), u(rng));
        const Vec3 axis = glm::normalize(Vec3(u(rng), u(rng), u(rng)));
        const Ray ray{Vec3(u(rng), u(rng), u(rng)) * 3.0,
                      glm::normalize(Vec3(u(rng), u(rng), u(rng)))};
        const auto s = closestLineParameter(point, axis, ray);
        ASSERT_TRUE(s.has_value());
        // Distance from a line point to the ray's (infinite) line, minimised on a grid.
        auto lineDistance = [&](double sv) {
            const Vec3 q = point + sv * axis;
            const Vec3 w = q - ray.origin;
            return glm::length(w - glm::dot(w, ray.direction) * ray.direction);
        };
        double best = 1e30, bestS = 0;
        for (double sv = -20; sv <= 20; sv += 1e-3)
            if (lineDistance(sv) < best) best = lineDistance(sv), bestS = sv;
        EXPECT_NEAR(*s, bestS, 2e-3) << "case " << k;
    }
    EXPECT_FALSE(closestLineParameter({0, 0, 0}, {1, 0, 0}, Ray{{0, 1, 0}, {1, 0, 0}}));
}

TEST(GizmoGeometry, IntersectPlaneIsTheAnalyticHit) {
    const Ray ray{{0, 3, 0}, glm::normalize(Vec3(1, -1, 0))};
    const auto p = intersectPlane(ray, {5, 1, -7}, {0, 1, 0});
    ASSERT_TRUE(p.has_value());
    EXPECT_NEAR(glm::length(*p - Vec3(2, 1, 0)), 0.0, 1e-12);
    EXPECT_FALSE(intersectPlane(ray, {0, 4, 0}, {0, 1, 0}));              // behind
    EXPECT_FALSE(intersectPlane(ray, {0, 0, 0}, {0, 0, 1}));              // parallel
    EXPECT_TRUE(intersectPlane(ray, {0, 1, 0}, {0, -1, 0}).has_value());  // either side
}

TEST(GizmoGeometry, EulerAnglesRoundTripAndMatchTheSceneConvention) {
    std::mt19937 rng(3);
    std::uniform_real_distribution<double> a(-179, 179), b(-89, 89);
    for (int k = 0; k < 200; ++k) {
        const Vec3 deg(a(rng), b(rng), a(rng));
        const glm::dmat3 r = rotationFromEulerDeg(deg);
        // Same as the scene-file convention written with explicit trigonometry.
        Transform t;
        t.rotateDeg = deg;
        for (const Vec3& d : {Vec3(1, 0, 0), Vec3(0, 1, 0), Vec3(0.3, -0.5, 0.8)})
            EXPECT_NEAR(glm::length(r * d - test::worldDirection(t, d)), 0.0, 1e-12);
        const Vec3 back = eulerDegFromRotation(r);
        EXPECT_NEAR(glm::length(back - deg), 0.0, 1e-9) << k;
    }
    // Gimbal lock: angles are not unique but the rotation is reproduced.
    for (const Vec3 deg : {Vec3(30, 90, 40), Vec3(-70, -90, 10)}) {
        const glm::dmat3 r = rotationFromEulerDeg(deg);
        const glm::dmat3 back = rotationFromEulerDeg(eulerDegFromRotation(r));
        for (int c = 0; c < 3; ++c) EXPECT_NEAR(glm::length(back[c] - r[c]), 0.0, 1e-9);
    }
}

TEST(Gizmo, TranslateAlongAnAxisFollowsTheCursorOnTheAxis) {
    const Camera cam = viewCamera();
    const Transform start = startTransform();
    Gizmo g(GizmoMode::Translate, start, 0.5);
    const Vec3 x(1, 0, 0);
    const glm::dvec2 grab = project(cam, start.translate + 0.6 * 0.5 * x);
    ASSERT_EQ(g.hitTest(cam, kW, kH, grab), GizmoHandle::X) << g.toString();
    ASSERT_TRUE(g.begin(GizmoHandle::X, rayThrough(cam, grab)));
    // Move the cursor to where the grabbed point would be after moving 0.37 m along X.
    const glm::dvec2 to = project(cam, start.translate + (0.3 + 0.37) * x);
    const Transform moved = g.drag(rayThrough(cam, to));
    EXPECT_NEAR(glm::length(moved.translate - (start.translate + 0.37 * x)), 0.0, 1e-9);
    EXPECT_EQ(moved.rotateDeg, start.rotateDeg);
    EXPECT_EQ(moved.scale, start.scale);
    // Snapping rounds the move to 0.25 m steps.
    const Transform snapped = g.drag(rayThrough(cam, to), GizmoSnap{true, 0.25, 15, 0.1});
    EXPECT_NEAR(glm::length(snapped.translate - (start.translate + 0.25 * x)), 0.0, 1e-9);
    // An arbitrary cursor: the result is the closest approach to the cursor's ray, so the
    // moved grab point and the ray are joined by a segment perpendicular to both.
    const Ray r = rayThrough(cam, {512.3, 97.8});
    const Vec3 q = g.drag(r).translate + 0.3 * x;
    const Vec3 w = q - r.origin;
    const Vec3 onRay = r.origin + glm::dot(w, r.direction) * r.direction;
    EXPECT_NEAR(glm::dot(q - onRay, x), 0.0, 1e-9);
}

TEST(Gizmo, TranslateInAPlaneMovesByTheAnalyticRayPlaneHits) {
    const Camera cam = viewCamera();
    const Transform start = startTransform();
    Gizmo g(GizmoMode::Translate, start, 0.5);
    // The XZ-plane handle's centre (0.4 size along X and Z).
    const Vec3 grabWorld = start.translate + 0.5 * Vec3(0.4, 0, 0.4);
    const glm::dvec2 grab = project(cam, grabWorld);
    ASSERT_EQ(g.hitTest(cam, kW, kH, grab), GizmoHandle::PlaneZX);
    ASSERT_TRUE(g.begin(GizmoHandle::PlaneZX, rayThrough(cam, grab)));
    const glm::dvec2 to{233.0, 455.0};
    const Ray r = rayThrough(cam, to);
    // Hit of the plane y = pivot.y, by hand.
    const double t = (start.translate.y - r.origin.y) / r.direction.y;
    const Vec3 hit = r.origin + t * r.direction;
    const Transform moved = g.drag(r);
    EXPECT_NEAR(glm::length(moved.translate - (start.translate + (hit - grabWorld))), 0.0, 1e-9);
    EXPECT_EQ(moved.translate.y, start.translate.y);
    // And the grabbed point lands under the cursor.
    const glm::dvec2 back = project(cam, grabWorld + (moved.translate - start.translate));
    EXPECT_NEAR(glm::length(back - to), 0.0, 1e-6);
}

TEST(Gizmo, RotateTurnsTheObjectAboutThePivot) {
    const Camera cam = viewCamera();
    const Transform start = startTransform();
    const double size = 0.5;
    Gizmo g(GizmoMode::Rotate, start, size);
    const Vec3 c = start.translate;
    // A point on the Y ring (the XZ plane), and the same point turned 37° about +Y.
    const Vec3 p0 = c + size * Vec3(std::cos(0.3), 0, std::sin(0.3));
    const Vec3 p1 = c + test::rotateAboutY(p0 - c, 37.0);
    ASSERT_EQ(g.hitTest(cam, kW, kH, project(cam, p0)), GizmoHandle::Y);
    ASSERT_TRUE(g.begin(GizmoHandle::Y, rayThrough(cam, project(cam, p0))));
    for (const auto& [snap, angle] :
         {std::pair{GizmoSnap{}, 37.0}, std::pair{GizmoSnap{true, 0.1, 15, 0.1}, 30.0}}) {
        const Transform turned = g.drag(rayThrough(cam, project(cam, p1)), snap);
        EXPECT_EQ(turned.translate, start.translate);
        // Every object point turns about the pivot by `angle` about +Y.
        for (const Vec3 q : {Vec3(0.5, 0.5, 0.5), Vec3(-0.2, 0.4, 0.1)}) {
            const Vec3 expected = c + test::rotateAboutY(test::worldPoint(start, q) - c, angle);
            EXPECT_NEAR(glm::length(test::worldPoint(turned, q) - expected), 0.0, 1e-7)
                << turned.toString() << " angle " << angle;
        }
    }
}

TEST(Gizmo, ScaleAlongALocalAxisAndUniformly) {
    const Camera cam = viewCamera();
    const Transform start = startTransform();
    const double size = 0.5;
    Gizmo g(GizmoMode::Scale, start, size);
    // The local X axis is the object's rotated +X.
    const Vec3 ux = test::worldDirection(start, {1, 0, 0});
    EXPECT_NEAR(glm::length(g.axis(0) - ux), 0.0, 1e-12);
    const Vec3 c = start.translate;
    const glm::dvec2 grab = project(cam, c + 0.5 * size * ux);
    ASSERT_EQ(g.hitTest(cam, kW, kH, grab), GizmoHandle::X);
    ASSERT_TRUE(g.begin(GizmoHandle::X, rayThrough(cam, grab)));
    const Transform scaled = g.drag(rayThrough(cam, project(cam, c + 1.3 * size * ux)));
    EXPECT_NEAR(scaled.scale.x, start.scale.x * 2.6, 1e-9);
    EXPECT_EQ(scaled.scale.y, start.scale.y);
    EXPECT_EQ(scaled.scale.z, start.scale.z);
    // The object's local +X point stretches along the local axis.
    EXPECT_NEAR(glm::length(test::worldPoint(scaled, {1, 0, 0}) - (c + 2.6 * start.scale.x * ux)),
                0.0, 1e-9);
    // Uniform: the centre handle, measured in the plane facing the camera.
    Gizmo u(GizmoMode::Scale, start, size);
    const glm::dvec2 centre = project(cam, c);
    ASSERT_EQ(u.hitTest(cam, kW, kH, centre + glm::dvec2(3, -2)), GizmoHandle::Uniform);
    const glm::dvec2 from = centre + glm::dvec2(4, 0);
    ASSERT_TRUE(u.begin(GizmoHandle::Uniform, rayThrough(cam, from)));
    const Transform grown = u.drag(rayThrough(cam, centre + glm::dvec2(12, 0)));
    const double f = grown.scale.x / start.scale.x;
    EXPECT_NEAR(f, 3.0, 0.02);  // distances in a plane through the pivot: ≈ pixel ratio
    EXPECT_NEAR(grown.scale.y / start.scale.y, f, 1e-12);
    EXPECT_NEAR(grown.scale.z / start.scale.z, f, 1e-12);
    // Snapped factors, and never zero.
    EXPECT_NEAR(u.drag(rayThrough(cam, centre + glm::dvec2(12, 0)), {true, 0.1, 15, 0.5}).scale.x /
                    start.scale.x,
                3.0, 1e-12);
    EXPECT_GT(u.drag(rayThrough(cam, centre + glm::dvec2(-4, 0.01))).scale.x, 0.0);
}

TEST(Gizmo, HitTestFindsEachHandleAndMissesElsewhere) {
    const Camera cam = viewCamera();
    const Transform start = startTransform();
    const Vec3 c = start.translate;
    const double s = 0.5;
    Gizmo t(GizmoMode::Translate, start, s);
    EXPECT_EQ(t.hitTest(cam, kW, kH, project(cam, c + 0.7 * s * Vec3(0, 1, 0))), GizmoHandle::Y);
    EXPECT_EQ(t.hitTest(cam, kW, kH, project(cam, c + 0.7 * s * Vec3(0, 0, 1))), GizmoHandle::Z);
    EXPECT_EQ(t.hitTest(cam, kW, kH, project(cam, c + 0.4 * s * Vec3(1, 1, 0))),
              GizmoHandle::PlaneXY);
    EXPECT_EQ(t.hitTest(cam, kW, kH, project(cam, c + 0.4 * s * Vec3(0, 1, 1))),
              GizmoHandle::PlaneYZ);
    EXPECT_EQ(t.hitTest(cam, kW, kH, {5, 5}), GizmoHandle::None);
    Gizmo r(GizmoMode::Rotate, start, s);
    const double h = std::sqrt(0.5);
    EXPECT_EQ(r.hitTest(cam, kW, kH, project(cam, c + s * Vec3(0, h, h))), GizmoHandle::X);
    EXPECT_EQ(r.hitTest(cam, kW, kH, project(cam, c + s * Vec3(h, h, 0))), GizmoHandle::Z);
    EXPECT_EQ(r.hitTest(cam, kW, kH, project(cam, c)), GizmoHandle::None);
}

}  // namespace
}  // namespace penumbra
