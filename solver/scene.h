#pragma once
// The scene model: materials, objects with shapes and transforms, cameras.
// Plain data; no files, no GL. edit/ reads and writes it, solver/ discretizes it.

#include <array>
#include <optional>
#include <string>
#include <vector>

#include "core/math.h"

namespace penumbra {

/// A diffuse material. reflectance in [0,1) per channel; emission is emitted radiosity, W/m².
struct Material {
    Rgb reflectance{0.5};
    Rgb emission{0.0};
    bool twoSided = false;  ///< reflect from both sides; emission stays front-only
    bool isEmitter() const { return emission.x > 0 || emission.y > 0 || emission.z > 0; }
    std::string toString() const;
};

/// scale, then rotate (degrees, about X then Y then Z), then translate.
struct Transform {
    Vec3 translate{0.0};
    Vec3 rotateDeg{0.0};
    Vec3 scale{1.0};
    Mat4 worldFromObject() const;
    std::string toString() const;
    /// The same translation, rotation and scale, exactly.
    bool operator==(const Transform&) const = default;
};

/// A triangle mesh in object space, as read from a mesh file.
struct TriMesh {
    std::vector<Vec3> positions;
    std::vector<std::array<int, 3>> triangles;
    /// Optional per-triangle index into `materials` (from MTL or glTF); empty when none.
    std::vector<int> triangleMaterial;
    std::vector<Material> materials;
    std::vector<std::string> materialNames;
};

enum class ShapeType { Quad, Box, Sphere, Cylinder, Mesh };
const char* shapeTypeName(ShapeType type);

/// A shape in object space. quad: XZ plane, normal +Y, `size` x and z. box: centred, `size` xyz.
/// sphere: `radius`, `segments` around the equator. cylinder: axis +Y, centred, `radius`,
/// `height`, `segments`, capped. mesh: `file` relative to the scene file, loaded into `mesh`.
struct Shape {
    ShapeType type = ShapeType::Box;
    Vec3 size{1.0};
    double radius = 0.5;
    double height = 1.0;
    int segments = 24;
    std::string file;
    TriMesh mesh;
};

struct SceneObject {
    std::string id;
    Shape shape;
    /// Name of a scene material; empty only for meshes that carry their own materials.
    std::string material;
    Transform transform;
    /// Shooter size for this object (metres); 0 uses the scene's patch_size. A light is
    /// usually one shooter: its redistribution then takes one shot, not one per element.
    double patchSize = 0;
};

struct Camera {
    std::string name;
    Vec3 position{0, 1, 3};
    Vec3 lookAt{0, 1, 0};
    Vec3 up{0, 1, 0};
    double fovDeg = 40.0;  ///< vertical field of view
};

/// A holodeck section a scene asks for (settings.holodeck; docs/holodeck.md): a box, looked
/// out of (interior) or into (exterior), and its cells along x, y and z (0: the count that
/// brings the section's beams nearest the paper's target).
struct HolodeckSectionSetting {
    bool exterior = false;
    Vec3 min{0.0}, max{0.0};
    std::array<int, 3> grid{0, 0, 0};
};

struct Settings {
    double patchSize = 0.5;    ///< metres, target edge length of a shooter
    double elementSize = 0.1;  ///< metres, target edge length of a receiver
    /// The holodeck's sections; empty: one interior section over the scene's bounds.
    std::vector<HolodeckSectionSetting> holodeck;
};

struct NamedMaterial {
    std::string name;
    Material material;
};

struct Scene {
    Settings settings;
    std::vector<NamedMaterial> materials;  ///< in file order
    std::vector<SceneObject> objects;      ///< in file order
    std::vector<Camera> cameras;           ///< in file order

    const Material* findMaterial(const std::string& name) const;
    int findObject(const std::string& id) const;  ///< index or -1
    const Camera* findCamera(const std::string& name) const;
};

}  // namespace penumbra
