#pragma once
// Scene files (`*.json`, format "penumbra-scene/1", DESIGN.md "Scene file") ↔ Scene.
//
// JSON values are nlohmann::ordered_json so that materials and cameras, which are JSON
// objects, keep their file order. nlohmann::json converts to and from ordered_json
// implicitly; the nlohmann::json overloads below exist for callers that parse with it (their
// object keys are sorted, so material and camera order is alphabetical there).
//
// Every validation failure throws InputError with one line `FILE: KEY-PATH: what is wrong`,
// KEY-PATH like `objects[3].transform.scale` or `materials.white.reflectance`.

#include <nlohmann/json.hpp>
#include <optional>
#include <string>

#include "solver/scene.h"

namespace penumbra {

struct ImportOptions;  // edit/io/scene_import.h

/// The only scene format this version reads and writes.
inline constexpr const char* kSceneFormat = "penumbra-scene/1";

/// Reads, validates and returns the scene at `path`, with every mesh shape's file (relative to
/// the scene file's directory) loaded into Shape::mesh. Shape::file keeps the path as written.
/// Duplicate keys anywhere (e.g. two materials named "white") and malformed JSON
/// (`FILE: line L, column C: ...`) are errors. Throws InputError.
Scene loadScene(const std::string& path);
/// The same; a .gltf, .glb or .obj path is imported (edit/io/scene_import.h) with `import`.
Scene loadScene(const std::string& path, const ImportOptions& import);

/// Validates an already parsed scene. `sourceName` names the input in error messages;
/// mesh files are resolved relative to `baseDir` ("" = the working directory), and each
/// distinct mesh file is read once. Throws InputError.
Scene sceneFromJson(const nlohmann::ordered_json& json, const std::string& sourceName,
                    const std::string& baseDir);
Scene sceneFromJson(const nlohmann::json& json, const std::string& sourceName,
                    const std::string& baseDir);

/// Validates one object as in the scene file's "objects" array (also the edit log's "add"),
/// resolving its material against `scene` and loading a mesh file relative to `baseDir`.
/// Errors read `sourceName: where.KEY: ...`, e.g. sourceName "edits.jsonl" with where
/// "line 7: object", or "scene.json" with "objects[2]". Does not check that the id is unused
/// in `scene` (the caller decides whether that is an error). Throws InputError.
SceneObject objectFromJson(const nlohmann::ordered_json& json, const Scene& scene,
                           const std::string& sourceName, const std::string& where,
                           const std::string& baseDir);
SceneObject objectFromJson(const nlohmann::json& json, const Scene& scene,
                           const std::string& sourceName, const std::string& where,
                           const std::string& baseDir);

/// Validates a material {reflectance, emission, two_sided}. Keys that are absent keep their
/// value from `base` (Material{} for a new material; the current one for a partial edit).
Material materialFromJson(const nlohmann::ordered_json& json, const std::string& sourceName,
                          const std::string& where, const Material& base = Material{});

/// Validates a transform {translate, rotate_deg, scale}. Keys that are absent keep their value
/// from `base`.
Transform transformFromJson(const nlohmann::ordered_json& json, const std::string& sourceName,
                            const std::string& where, const Transform& base = Transform{});

/// The scene as a scene-file JSON value. Defaults are omitted where the reader restores them
/// (zero emission, one-sided, identity transform components), so
/// sceneFromJson(sceneToJson(s)) == s for every scene sceneFromJson returns.
/// Mesh shapes write `file` only; meshes are not embedded.
nlohmann::ordered_json sceneToJson(const Scene& scene);
nlohmann::ordered_json objectToJson(const SceneObject& object);
nlohmann::ordered_json materialToJson(const Material& material);
nlohmann::ordered_json transformToJson(const Transform& transform);

/// Scene-file text: two-space indentation, with any array or object that fits in 100
/// columns on one line (an object per line for typical scenes). Ends with a newline.
std::string formatSceneText(const nlohmann::ordered_json& json);

/// Writes formatSceneText(sceneToJson(scene)) to `path` with writeFileAtomically (durable; an
/// existing file keeps its permission bits). Mesh shapes without a `file`
/// (an imported scene's) are first written as OBJ (+MTL) files into `STEM-meshes/` beside
/// it, and the scene file names them. Mesh `file` paths are written
/// as stored, i.e. relative to the directory the scene was loaded from: save next to it (or
/// into a directory with the same relative mesh paths). Throws InputError
/// `PATH: cannot write (STEP): REASON` when the file cannot be written.
void saveScene(const Scene& scene, const std::string& path);

/// A mesh shape's `file`, written relative to `fromDir`, rewritten relative to `toDir` so it
/// names the same file (Save as into another folder). Absolute paths and paths into the same
/// directory come back unchanged; "" for either directory means the working directory.
std::string rebaseMeshPath(const std::string& file, const std::string& fromDir,
                           const std::string& toDir);
/// rebaseMeshPath applied to every mesh shape of `scene`.
void rebaseMeshPaths(Scene& scene, const std::string& fromDir, const std::string& toDir);

/// "a number", "a string", … for error messages about a JSON value of the wrong type.
std::string describeType(const nlohmann::ordered_json& value);
/// A number as error messages print it (shortest round-trip-ish form of operator<<).
std::string formatNumber(double value);

/// The first structural problem met while parsing JSON text: a key repeated within one
/// object (nlohmann would silently keep the last one), or nesting deeper than 64 levels.
struct JsonStructureProblem {
    std::string path;    ///< key path of the offending value, e.g. `objects[2].id`
    std::string parent;  ///< key path of the object holding a repeated key
    std::string key;     ///< the repeated key
    bool tooDeep = false;
};
/// An nlohmann exception's message as the readers report it: without its
/// "[json.exception.KIND.N] " prefix, and for a parse error without "parse error at line L,
/// column C: " too (the readers state the position themselves).
std::string jsonErrorProblem(const std::string& message);
/// Parses `text` (nlohmann's exceptions propagate) and reports the first structural problem
/// in `problem`; the scene loader and the edit-log reader turn it into their own messages.
nlohmann::ordered_json parseJsonTracked(const std::string& text,
                                        std::optional<JsonStructureProblem>& problem);

}  // namespace penumbra
