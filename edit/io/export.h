#pragma once
// Export of a lit scene: the element meshes of every object in world space with their
// radiosity as vertex colours, for viewing in other tools (MeshLab, Blender, glTF viewers).

#include <array>
#include <string>
#include <vector>

#include "solver/scene.h"

namespace penumbra {

class Discretization;

/// Writes the world-space element meshes of `disc` with per-vertex radiosity (the
/// area-weighted mean of `elementRadiosity` around each vertex, Discretization::vertexValues)
/// to `path`; the format follows the extension, case-insensitive:
///
/// - `.ply`: binary little-endian PLY. Vertices of all objects in object order, each with
///   `float x y z` (metres), `uchar red green blue` = radiance B/π sRGB-encoded and clipped
///   to [0,1], and `float radiosity_r radiosity_g radiosity_b` = B (W/m²). Face i is
///   element i (`list uchar int vertex_indices`, counter-clockwise seen from the front).
/// - `.gltf`: glTF 2.0 JSON with the binary buffer embedded as a base64 data URI (one
///   self-contained file). `.glb`: the same as binary glTF. Valid for the Khronos validator
///   (no errors, no warnings). One node and one mesh per object with faces (named by object
///   id; the node's `extras` hold `penumbra_id`, the scene material's name, reflectance and
///   emission), a primitive per material, with POSITION, NORMAL (area-weighted element
///   normals), COLOR_0 = min(1, exposure × B/π) per channel — linear, display-referred; the
///   exposure maps the 99th percentile of lit surfaces' vertex luminance to 1 and is written in
///   `asset.extras.exposure` — and `_RADIANCE` = B/π (W/m²/sr) exactly; uint32 triangles
///   fan-triangulated from the element polygons. Reflecting surfaces use an unlit white
///   material (KHR_materials_unlit) so viewers show COLOR_0 as it is, doubleSided for
///   two-sided objects; emitters an emissive material on the same exposure: emissiveFactor ×
///   KHR_materials_emissive_strength = exposure × E/π, black base colour.
/// - `.obj`: Wavefront OBJ with a comment header, one `o <id>` group per object, vertex
///   colours as `v x y z r g b` with r g b = radiance B/π sRGB-encoded and clipped to
///   [0,1] (the convention MeshLab and Blender read), polygon faces per element.
///
/// Writes with writeFileAtomically (core/durable_file.h; the .mtl first): a kill leaves the
/// old file or the whole new one. Throws std::invalid_argument naming the extension for an
/// unknown one, or when elementRadiosity does not have one value per element; InputError
/// naming the file and the reason when it cannot be written.
/// `scene`, when given, names each object's material in the glTF nodes' extras, and its
/// cameras become glTF perspective camera nodes.
void exportLitScene(const Discretization& disc, const std::vector<Rgb>& elementRadiosity,
                    const std::string& path, const Scene* scene = nullptr);

/// Throws std::invalid_argument naming `path` unless its extension is one exportLitScene
/// writes: checked before a long solve, not after it.
void checkExportPath(const std::string& path);

/// One triangle of a finer lit mesh than the elements (the high-fidelity mesh of
/// render/hifi/hifi_mesh.h): world-space corners, counter-clockwise seen from the front, and the
/// radiosity B (W/m²) at each.
struct LitTriangle {
    int element = -1;  ///< the element it lies in (object, material, normal)
    std::array<Vec3, 3> p;
    std::array<Rgb, 3> radiosity;
};

/// exportLitScene with `triangles` in place of the element polygons, in the same formats and
/// with the same guarantees. Corners of one object with the same position, normal and
/// radiosity are welded into one vertex, so the mesh stays connected where the light is
/// continuous and splits where it jumps (contact lines). PLY: face i = triangle i of the
/// objects in order. Throws std::invalid_argument for an unknown extension or a triangle
/// naming no element of `disc`.
void exportLitTriangles(const Discretization& disc, const std::vector<LitTriangle>& triangles,
                        const std::string& path, const Scene* scene = nullptr);

}  // namespace penumbra
