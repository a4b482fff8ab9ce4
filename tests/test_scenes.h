#pragma once
// Scenes built in code for tests: closed rooms of inward-facing quads, emitters, occluders.

#include <string>

#include "solver/scene.h"

namespace penumbra::test {

inline SceneObject makeQuad(const std::string& id, double sx, double sz, const std::string& material,
                            Vec3 translate, Vec3 rotateDeg = Vec3(0.0)) {
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
