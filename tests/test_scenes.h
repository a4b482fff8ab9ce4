#pragma once
// Scenes built in code for tests: closed rooms of inward-facing quads, emitters, occluders.

#include <cmath>
#include <string>
#include <vector>

#include "solver/scene.h"

namespace penumbra::test {

inline SceneObject makeQuad(const std::string& id, double sx, double sz,
                            const std::string& material, Vec3 translate,
                            Vec3 rotateDeg = Vec3(0.0)) {
    SceneObject o;
    o.id = id;
    o.shape.type = ShapeType::Quad;
    o.shape.size = Vec3(sx, 0.0, sz);
    o.material = material;
    o.transform.translate = translate;
    o.transform.rotateDeg = rotateDeg;
    return o;
}

/// A closed cube of side `size` centred at the origin, six inward-facing quads.
inline void addClosedRoom(Scene& scene, double size, const std::string& material) {
    double h = size / 2;
    scene.objects.push_back(makeQuad("floor", size, size, material, {0, -h, 0}));
    scene.objects.push_back(makeQuad("ceiling", size, size, material, {0, h, 0}, {180, 0, 0}));
    scene.objects.push_back(makeQuad("back", size, size, material, {0, 0, -h}, {90, 0, 0}));
    scene.objects.push_back(makeQuad("front", size, size, material, {0, 0, h}, {-90, 0, 0}));
    scene.objects.push_back(makeQuad("right", size, size, material, {h, 0, 0}, {0, 0, 90}));
    scene.objects.push_back(makeQuad("left", size, size, material, {-h, 0, 0}, {0, 0, -90}));
}

inline void addMaterial(Scene& scene, const std::string& name, Rgb reflectance,
                        Rgb emission = Rgb(0.0)) {
    Material m;
    m.reflectance = reflectance;
    m.emission = emission;
    scene.materials.push_back({name, m});
}

}  // namespace penumbra::test

// ---------------------------------------------------------------------------------------------
// Independent geometry for truths: the scene file's transform (scale, then rotate about X, Y,
// Z in degrees, then translate) written out with explicit trigonometry, not through glm or
// Transform::worldFromObject, and the world corners of a quad object.

namespace penumbra::test {

inline Vec3 rotateAboutX(Vec3 p, double deg) {
    double a = deg * M_PI / 180, c = std::cos(a), s = std::sin(a);
    return {p.x, c * p.y - s * p.z, s * p.y + c * p.z};
}
inline Vec3 rotateAboutY(Vec3 p, double deg) {
    double a = deg * M_PI / 180, c = std::cos(a), s = std::sin(a);
    return {c * p.x + s * p.z, p.y, -s * p.x + c * p.z};
}
inline Vec3 rotateAboutZ(Vec3 p, double deg) {
    double a = deg * M_PI / 180, c = std::cos(a), s = std::sin(a);
    return {c * p.x - s * p.y, s * p.x + c * p.y, p.z};
}

/// World position of object-space point `p` under the scene-file transform contract.
inline Vec3 worldPoint(const Transform& t, Vec3 p) {
    p = Vec3(p.x * t.scale.x, p.y * t.scale.y, p.z * t.scale.z);
    p = rotateAboutZ(rotateAboutY(rotateAboutX(p, t.rotateDeg.x), t.rotateDeg.y), t.rotateDeg.z);
    return p + t.translate;
}

/// World direction of object-space direction `d` (rotation only; no scale, no translate).
inline Vec3 worldDirection(const Transform& t, Vec3 d) {
    return rotateAboutZ(rotateAboutY(rotateAboutX(d, t.rotateDeg.x), t.rotateDeg.y), t.rotateDeg.z);
}

/// World corners of a quad object, counter-clockwise seen from its front (+Y in object space).
inline std::vector<Vec3> quadCorners(const SceneObject& quad) {
    double hx = quad.shape.size.x / 2, hz = quad.shape.size.z / 2;
    std::vector<Vec3> c;
    for (Vec3 p : {Vec3(-hx, 0, hz), Vec3(hx, 0, hz), Vec3(hx, 0, -hz), Vec3(-hx, 0, -hz)})
        c.push_back(worldPoint(quad.transform, p));
    return c;
}

/// A scene with the given element and patch sizes and no objects.
inline Scene emptyScene(double patchSize, double elementSize) {
    Scene scene;
    scene.settings.patchSize = patchSize;
    scene.settings.elementSize = elementSize;
    return scene;
}

/// A closed 3 m room lit by a ceiling lamp, with a slab (table top) of `slabMaterial`; the
/// scene of the redistribution and edit-session tests. Materials: white, red, lamp.
inline Scene makeLitRoom(const std::string& slabMaterial) {
    Scene scene = emptyScene(0.75, 0.375);
    addMaterial(scene, "white", Rgb(0.6));
    addMaterial(scene, "red", Rgb(0.7, 0.2, 0.15));
    addMaterial(scene, "lamp", Rgb(0.5), Rgb(12.0, 11.0, 9.0));
    addClosedRoom(scene, 3.0, "white");
    scene.objects.push_back(makeQuad("lamp", 0.6, 0.6, "lamp", {0, 1.49, 0}, {180, 0, 0}));
    SceneObject slab;
    slab.id = "slab";
    slab.shape.type = ShapeType::Box;
    slab.shape.size = Vec3(1.2, 0.1, 0.8);
    slab.material = slabMaterial;
    slab.transform.translate = Vec3(0.2, -0.8, 0.1);
    scene.objects.push_back(slab);
    return scene;
}

/// Where the drag tests move makeLitRoom's slab (its translation after the drag).
inline const Vec3 kLitRoomSlabDragTarget{-0.55, -0.35, -0.35};

/// A camera high in makeLitRoom looking down on the floor, the slab and the drag target.
inline Camera litRoomTopCamera() {
    Camera c;
    c.position = Vec3(0.0, 1.2, 1.4);
    c.lookAt = Vec3(-0.2, -1.2, -0.2);
    c.fovDeg = 75;
    return c;
}

}  // namespace penumbra::test
