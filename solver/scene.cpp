// Small helpers of the plain-data scene model: printing, transforms, lookups.

#include "solver/scene.h"

#include <cstdio>
#include <glm/gtc/matrix_transform.hpp>

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
    // M = T · Rz · Ry · Rx · S: scale first, then rotate about X, Y, Z, then translate.
    const Mat4 identity(1.0);
    const Mat4 translation = glm::translate(identity, translate);
    const Mat4 rotationX = glm::rotate(identity, glm::radians(rotateDeg.x), Vec3(1, 0, 0));
    const Mat4 rotationY = glm::rotate(identity, glm::radians(rotateDeg.y), Vec3(0, 1, 0));
    const Mat4 rotationZ = glm::rotate(identity, glm::radians(rotateDeg.z), Vec3(0, 0, 1));
    const Mat4 scaling = glm::scale(identity, scale);
    return translation * rotationZ * rotationY * rotationX * scaling;
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
