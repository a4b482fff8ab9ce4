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
///   zero area at single-precision resolution) are dropped; if any were, ONE line
///   `warning: PATH: dropped N degenerate faces (...)` goes to stderr.
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

}  // namespace penumbra
