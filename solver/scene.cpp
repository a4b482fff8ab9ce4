// Small helpers of the plain-data scene model: printing, transforms, lookups.

#include "solver/scene.h"

#include <cmath>
#include <cstdio>

namespace penumbra {

namespace {

std::string formatVec3(const Vec3& v) {
    char buffer[96];
    std::snprintf(buffer, sizeof buffer, "(%.6g, %.6g, %.6g)", v.x, v.y, v.z);
    return buffer;
}

}  // namespace

std::string Material::toString() const {
    return "Material{reflectance=" + formatVec3(reflectance) +
           ", emission=" + formatVec3(emission) + ", two_sided=" + (twoSided ? "true" : "false") +
           "}";
}

Mat4 Transform::worldFromObject() const {
    // M = T · Rz · Ry · Rx · S: scale first, then rotate about X, Y, Z, then translate. The
    // product written out rather than as four 4×4 products (glm is column-major:
    // m[column][row]): it runs for every object at each size the importer's size search tries.
    const Vec3 r = glm::radians(rotateDeg);
    const double ca = std::cos(r.x), sa = std::sin(r.x);
    const double cb = std::cos(r.y), sb = std::sin(r.y);
    const double cc = std::cos(r.z), sc = std::sin(r.z);
    const Vec3 columns[3] = {
        Vec3(cc * cb, sc * cb, -sb),
        Vec3(cc * sb * sa - sc * ca, sc * sb * sa + cc * ca, cb * sa),
        Vec3(cc * sb * ca + sc * sa, sc * sb * ca - cc * sa, cb * ca),
    };
    Mat4 m(1.0);
    for (int j = 0; j < 3; ++j) m[j] = glm::dvec4(columns[j] * scale[j], 0.0);
    m[3] = glm::dvec4(translate, 1.0);
    return m;
}

std::string Transform::toString() const {
    return "Transform{translate=" + formatVec3(translate) +
           ", rotate_deg=" + formatVec3(rotateDeg) + ", scale=" + formatVec3(scale) + "}";
}

const char* shapeTypeName(ShapeType type) {
    switch (type) {
        case ShapeType::Quad:
            return "quad";
        case ShapeType::Box:
            return "box";
        case ShapeType::Sphere:
            return "sphere";
        case ShapeType::Cylinder:
            return "cylinder";
        case ShapeType::Mesh:
            return "mesh";
    }
    return "unknown";
}

const Material* Scene::findMaterial(const std::string& name) const {
    for (const NamedMaterial& entry : materials) {
        if (entry.name == name) return &entry.material;
    }
    return nullptr;
}

int Scene::findObject(const std::string& id) const {
    for (size_t i = 0; i < objects.size(); ++i) {
        if (objects[i].id == id) return static_cast<int>(i);
    }
    return -1;
}

const Camera* Scene::findCamera(const std::string& name) const {
    for (const Camera& camera : cameras) {
        if (camera.name == name) return &camera;
    }
    return nullptr;
}

}  // namespace penumbra
