#pragma once
// Mesh files → TriMesh: OBJ (+MTL) via tinyobjloader, STL via OpenMesh IO, glTF/GLB via
// tinygltf, OFF and PLY (ASCII and binary) via strict readers of our own, because OpenMesh 9's
// readers for those hang or crash on malformed files.

#include <string>

#include "solver/scene.h"

namespace penumbra {

/// Reads a mesh file into object-space triangles. The format is chosen by the extension
/// (case-insensitive): .obj, .off, .ply, .stl, .gltf, .glb.
/// - Polygons are triangulated (ear clipping in the polygon's plane; fan as a fallback).
/// - Degenerate faces (fewer than 3 vertices, a repeated vertex, a non-finite coordinate, or
///   zero area at single-precision resolution) are dropped; if any were, ONE warning
///   `PATH: dropped N degenerate faces (...)` is logged (spdlog::warn, core/log.h).
/// - Unreferenced vertices are removed, so every position is finite and used.
/// - Materials: OBJ `Kd` / glTF `baseColorFactor` (rgb) become reflectance clamped to
///   [0, 0.99]; OBJ `Ke` / glTF `emissiveFactor` (× KHR_materials_emissive_strength) become
///   emission (W/m², negative clamped to 0). When the file assigns a material to any face,
///   triangleMaterial has one entry per triangle; faces without one get an added material
///   named "default" (Material{} defaults). When it assigns none, the material vectors are
///   empty.
/// - glTF: the default scene (else scene 0, else all root nodes) is flattened with node
///   transforms applied; triangles, strips and fans are read, points and lines ignored.
/// Throws InputError (`PATH: what is wrong`) when the file is missing or unreadable, is not
/// a valid file of its format, has an unsupported extension, or has no valid faces.
/// Not for concurrent use: OpenMesh's global log streams are silenced while it reads.
/// Known gap: OpenMesh's STL reader skips triangles with a repeated vertex itself, so those
/// are not counted in the warning.
TriMesh loadMeshFile(const std::string& path);

/// A material of a scene file as the file states it (edit/io/scene_import.h converts it).
struct MeshFileMaterial {
    std::string name;
    /// glTF baseColorFactor (rgb) × the mean of its baseColorTexture (linear, decoded from
    /// sRGB), or OBJ Kd; not clamped.
    Rgb baseColor{1.0};
    Rgb emissive{0.0};      ///< glTF emissiveFactor × emissive strength or OBJ Ke; not scaled
    bool textured = false;  ///< a base colour texture the reader could not average (OBJ map_Kd)
    bool doubleSided = false;
    std::string extras;  ///< glTF material extras as JSON text; "" when none
};

/// One part of a scene file: a glTF node with a mesh, or an OBJ object or group. Its mesh is
/// built as loadMeshFile builds one (triangulated, cleaned) in the file's scene space (the
/// node's world transform applied); its materials are left empty and `triangleMaterial`
/// (one per triangle) indexes MeshFileScene::materials, -1 where the file assigns none.
struct MeshFilePart {
    std::string name;    ///< node name (else its mesh's name) or OBJ object/group name
    std::string extras;  ///< glTF node extras as JSON text; "" when none
    TriMesh mesh;
    std::vector<int> triangleMaterial;
};

struct MeshFileCamera {
    std::string name;
    Vec3 position{0.0}, forward{0, 0, -1}, up{0, 1, 0};
    double yfovDeg = 40.0;
    bool perspective = true;
};

/// A KHR_lights_punctual light placed by its node.
struct MeshFileLight {
    std::string name;
    std::string type;  ///< "point", "spot" or "directional"
    Rgb colour{1.0};
    double intensity = 1.0;  ///< as the file states it (candela for point and spot lights)
    Vec3 position{0.0}, direction{0, 0, -1};
};

/// A glTF/GLB or OBJ file read as a scene: its parts, materials, cameras and lights (glTF's
/// default scene, else scene 0, else every root node), and the names of features it uses
/// that the reader ignores (skins, animations, morph targets, texture transforms, unknown
/// extensions). Throws InputError as loadMeshFile does, and for a required extension the
/// reader cannot honour (Draco or meshopt compression: the geometry would be wrong).
struct MeshFileScene {
    std::vector<MeshFilePart> parts;
    std::vector<MeshFileMaterial> materials;
    std::vector<MeshFileCamera> cameras;
    std::vector<MeshFileLight> lights;
    std::vector<std::string> ignored;
    std::string assetExtras;  ///< glTF asset extras as JSON text; "" when none
};
MeshFileScene loadMeshFileScene(const std::string& path);

/// Writes `mesh` as an OBJ file; with per-triangle materials also an MTL file beside it
/// (`Kd` the reflectance, `Ke` the emission as loadMeshFile reads it back), named after the
/// OBJ with the extension .mtl. Each written with writeFileAtomically (the .mtl first).
/// Throws InputError naming the file when one cannot be written.
void saveObjMesh(const TriMesh& mesh, const std::string& path);

}  // namespace penumbra
