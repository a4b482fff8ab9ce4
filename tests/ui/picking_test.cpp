// Picking through Embree against analytic ray-plane intersections, occlusion, and the
// session's object versions (removed and moved objects).

#include "ui/picking.h"

#include <gtest/gtest.h>

#include "edit/edit_session.h"
#include "render/camera_rays.h"
#include "test_scenes.h"

namespace penumbra {
namespace {

constexpr int kW = 64, kH = 48;

SceneObject makeBox(const std::string& id, Vec3 size, Vec3 at) {
    SceneObject o;
    o.id = id;
    o.shape.type = ShapeType::Box;
    o.shape.size = size;
    o.material = "white";
    o.transform.translate = at;
    return o;
}

Scene pickScene() {
    Scene s;
    s.settings.patchSize = 1.0;
    s.settings.elementSize = 1.0;
    test::addMaterial(s, "white", Rgb(0.5));
    test::addClosedRoom(s, 4.0, "white");
    s.objects.push_back(makeBox("crate", {0.4, 0.4, 0.4}, {0, 0, -0.5}));
    s.objects.push_back(makeBox("hidden", {0.2, 0.2, 0.2}, {0, 0, -1.2}));
    return s;
}

Camera pickCamera() {
    Camera c;
    c.position = {0, 0, 1.5};
    c.lookAt = {0, 0, 0};
    c.fovDeg = 60;
    return c;
}

TEST(Picking, HitsTheNearestObjectAtTheAnalyticPoint) {
    EditSession session(pickScene(), SolverOptions{}, "pick-scene");
    const Camera cam = pickCamera();
    const CameraRays rays(cam, kW, kH);
    auto pick = [&](glm::dvec2 px) {
        return pickObject(session.discretization(), session.tracer(), cam, kW, kH, px.x, px.y);
    };

    // The crate's front face (z = -0.3) under a pixel near its centre.
    const glm::dvec2 px = *rays.projectToPixel({0.05, -0.03, -0.3});
    const Pick p = pick(px);
    ASSERT_EQ(p.id, "crate") << p.toString();
    EXPECT_EQ(p.version, session.objectVersion("crate"));
    const Ray r = pixelRay(cam, kW, kH, px.x, px.y);
    const double t = (-0.3 - r.origin.z) / r.direction.z;
    EXPECT_NEAR(glm::length(p.position - r.at(t)), 0.0, 1e-5) << p.toString();
    EXPECT_NEAR(p.t, t, 1e-5);

    // The back wall (z = -2) beside the crate.
    const glm::dvec2 wall = *rays.projectToPixel({1.2, 0.7, -2.0});
    const Pick w = pick(wall);
    EXPECT_EQ(w.id, "back") << w.toString();
    EXPECT_NEAR(w.position.z, -2.0, 1e-5);

    // 'hidden' is behind the crate from every pixel.
    int crate = 0;
    for (int y = 0; y < kH; ++y)
        for (int x = 0; x < kW; ++x) {
            const Pick q = pick({x + 0.5, y + 0.5});
            ASSERT_TRUE(q.hit()) << "closed room: every pixel hits something";
            EXPECT_NE(q.id, "hidden") << x << "," << y;
            crate += q.id == "crate";
        }
    EXPECT_GT(crate, 10);

    // Once the crate is removed, 'hidden' shows; a moved object is picked at its new version.
    session.apply(RemoveCommand{"crate"});
    EXPECT_EQ(pick(*rays.projectToPixel({0, 0, -1.1})).id, "hidden");
    session.apply(MoveCommand{"hidden", {0.9, 0, 0}});
    const Pick moved = pick(*rays.projectToPixel({0.9, 0, -1.1}));
    EXPECT_EQ(moved.id, "hidden");
    EXPECT_EQ(moved.version, session.objectVersion("hidden"));
    EXPECT_EQ(pick(*rays.projectToPixel({0, 0, -1.1})).id, "back");
}

}  // namespace
}  // namespace penumbra
