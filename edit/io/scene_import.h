#pragma once
// Scenes from other tools: a glTF 2.0 (.gltf, .glb) or OBJ (+MTL) file → Scene, so every
// command and the editor open what Blender, SketchUp or a CAD tool exports (docs/import.md).
//
// Each glTF node with a mesh (each OBJ object or group) becomes one mesh object: the node
// hierarchy's transforms are baked into its vertices, which are then centred on the object's
// bounding box with the centre as its translation (the editor's gizmo sits on the object).
// Ids come from node names (Penumbra's own export: the `penumbra_id` in the node's extras),
// made unique. Materials, lights and cameras map as docs/import.md states.

#include <functional>
#include <string>

#include "solver/scene.h"

namespace penumbra {

struct ImportOptions {
    /// Multiplies every emission read from the file (after the π that turns the file's
    /// radiance-like emissive values into Penumbra's emitted radiosity, W/m²).
    double emissionScale = 1.0;
    /// Radius (m) of the emitting sphere that stands for a glTF point or spot light.
    double lightRadius = 0.05;
    /// OBJ files: metres per file unit (--units mm 0.001, cm 0.01, m 1). glTF is in metres.
    double objUnit = 1.0;
    /// Receives each warning line (`warning: FILE: ...`); null logs them (spdlog::warn,
    /// `FILE: ...`).
    std::function<void(const std::string&)> warn;
};

/// Whether `path` names a file importScene reads (by extension, case-insensitive).
bool isImportableScene(const std::string& path);

/// Reads a glTF/GLB or OBJ scene. Unsupported features that are safe to ignore (animations,
/// skins, morph targets, OBJ texture maps, directional lights, orthographic cameras, unknown
/// optional extensions) get one warning line each; a required extension that changes the geometry
/// (Draco, meshopt) and malformed files throw InputError (`FILE: what is wrong`).
Scene importScene(const std::string& path, const ImportOptions& options = {});

}  // namespace penumbra
