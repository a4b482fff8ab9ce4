// Scene files ↔ Scene.
// Index: key paths and typed readers (JsonReader) · materials, transforms, shapes, objects ·
//        settings, cameras, scene · parsing text (duplicate keys, line/column) ·
//        writing JSON · text formatting · atomic save

#include "edit/io/scene_io.h"

#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <map>
#include <optional>
#include <set>
#include <sstream>
#include <string_view>
#include <unordered_map>

#include "core/durable_file.h"
#include "core/input_error.h"
#include "edit/io/mesh_io.h"
#include "edit/io/scene_import.h"

namespace penumbra {

using Json = nlohmann::ordered_json;

namespace {

// ---------------------------------------------------------------------------------------------
// Key paths and typed readers.

/// True when `key` can be written bare in a key path (`materials.white`).
bool isPlainKey(const std::string& key) {
    if (key.empty()) return false;
    for (unsigned char c : key) {
        if (!(std::isalnum(c) || c == '_' || c == '-')) return false;
    }
    return true;
}

/// `parent.key`, or `parent["odd key"]` for keys that need quoting.
std::string joinKey(const std::string& parent, const std::string& key) {
    if (!isPlainKey(key)) {
        return parent + "[" + Json(key).dump(-1, ' ', false, Json::error_handler_t::replace) + "]";
    }
    return parent.empty() ? key : parent + "." + key;
}

std::string joinIndex(const std::string& parent, size_t index) {
    return parent + "[" + std::to_string(index) + "]";
}

std::string formatVec3(const Vec3& v) {
    std::ostringstream out;
    out << '[' << v.x << ", " << v.y << ", " << v.z << ']';
    return out.str();
}

/// Typed access to JSON values of one input, failing with InputError naming the key path.
class JsonReader {
public:
    explicit JsonReader(std::string sourceName) : mSource(std::move(sourceName)) {}

    const std::string& source() const { return mSource; }

    [[noreturn]] void fail(const std::string& where, const std::string& problem) const {
        throw InputError(mSource, where, problem);
    }

    void expectObject(const Json& value, const std::string& where) const {
        if (!value.is_object()) fail(where, "expected an object, got " + describeType(value));
    }

    /// Rejects keys not in `allowed`, naming the first unknown one.
    void checkKeys(const Json& object, const std::string& where,
                   std::initializer_list<std::string_view> allowed,
                   const std::string& context = "") const {
        for (auto it = object.begin(); it != object.end(); ++it) {
            bool known = false;
            for (std::string_view key : allowed) known = known || key == it.key();
            if (known) continue;
            std::string list;
            for (std::string_view key : allowed) {
                list += (list.empty() ? "" : ", ") + std::string(key);
            }
            fail(joinKey(where, it.key()),
                 "unknown key '" + it.key() + "'" + context + " (allowed: " + list + ")");
        }
    }

    /// The value at `key`, failing when absent.
    const Json& require(const Json& object, const char* key, const std::string& where) const {
        const auto it = object.find(key);
        if (it == object.end()) fail(joinKey(where, key), "missing required key");
        return *it;
    }

    /// The value at `key`, or nullptr when absent.
    static const Json* find(const Json& object, const char* key) {
        const auto it = object.find(key);
        return it == object.end() ? nullptr : &*it;
    }

    double readNumber(const Json& value, const std::string& where) const {
        if (!value.is_number()) fail(where, "expected a number, got " + describeType(value));
        const double number = value.get<double>();
        if (!std::isfinite(number)) fail(where, "not a finite number");
        return number;
    }

    double readPositive(const Json& value, const std::string& where) const {
        const double number = readNumber(value, where);
        if (!(number > 0.0)) fail(where, "must be positive, got " + formatNumber(number));
        return number;
    }

    int readInteger(const Json& value, const std::string& where) const {
        if (!value.is_number_integer()) {
            fail(where,
                 "expected an integer, got " +
                     (value.is_number() ? "the number " + value.dump() : describeType(value)));
        }
        if (value.is_number_unsigned()) {
            const auto number = value.get<std::uint64_t>();
            if (number > 1000000000ull) fail(where, "integer " + value.dump() + " is too large");
            return static_cast<int>(number);
        }
        const auto number = value.get<std::int64_t>();
        if (number > 1000000000ll || number < -1000000000ll) {
            fail(where, "integer " + value.dump() + " is out of range");
        }
        return static_cast<int>(number);
    }

    bool readBool(const Json& value, const std::string& where) const {
        if (!value.is_boolean()) fail(where, "expected true or false, got " + describeType(value));
        return value.get<bool>();
    }

    std::string readString(const Json& value, const std::string& where) const {
        if (!value.is_string()) fail(where, "expected a string, got " + describeType(value));
        return value.get<std::string>();
    }

    /// An array of exactly `count` finite numbers.
    std::vector<double> readNumbers(const Json& value, size_t count,
                                    const std::string& where) const {
        if (!value.is_array() || value.size() != count) {
            fail(where, "expected an array of " + std::to_string(count) + " numbers, got " +
                            (value.is_array() ? "an array of " + std::to_string(value.size())
                                              : describeType(value)));
        }
        std::vector<double> numbers;
        for (size_t i = 0; i < count; ++i)
            numbers.push_back(readNumber(value[i], joinIndex(where, i)));
        return numbers;
    }

    Vec3 readVec3(const Json& value, const std::string& where) const {
        const std::vector<double> n = readNumbers(value, 3, where);
        return Vec3(n[0], n[1], n[2]);
    }

private:
    std::string mSource;
};

// ---------------------------------------------------------------------------------------------
// Materials, transforms, shapes, objects.

Material readMaterial(const JsonReader& in, const Json& json, const std::string& where,
                      const Material& base) {
    in.expectObject(json, where);
    in.checkKeys(json, where, {"reflectance", "emission", "two_sided"});
    Material material = base;
    if (const Json* value = JsonReader::find(json, "reflectance")) {
        const std::string at = joinKey(where, "reflectance");
        material.reflectance = in.readVec3(*value, at);
        for (int c = 0; c < 3; ++c) {
            if (!(material.reflectance[c] >= 0.0 && material.reflectance[c] < 1.0)) {
                in.fail(at, "reflectance must be in [0, 1) per channel, got " +
                                formatVec3(material.reflectance));
            }
        }
    }
    if (const Json* value = JsonReader::find(json, "emission")) {
        const std::string at = joinKey(where, "emission");
        material.emission = in.readVec3(*value, at);
        for (int c = 0; c < 3; ++c) {
            if (material.emission[c] < 0.0) {
                in.fail(at, "emission must not be negative, got " + formatVec3(material.emission));
            }
        }
    }
    if (const Json* value = JsonReader::find(json, "two_sided")) {
        material.twoSided = in.readBool(*value, joinKey(where, "two_sided"));
    }
    return material;
}

Transform readTransform(const JsonReader& in, const Json& json, const std::string& where,
                        const Transform& base) {
    in.expectObject(json, where);
    in.checkKeys(json, where, {"translate", "rotate_deg", "scale"});
    Transform transform = base;
    if (const Json* value = JsonReader::find(json, "translate")) {
        transform.translate = in.readVec3(*value, joinKey(where, "translate"));
    }
    if (const Json* value = JsonReader::find(json, "rotate_deg")) {
        transform.rotateDeg = in.readVec3(*value, joinKey(where, "rotate_deg"));
    }
    if (const Json* value = JsonReader::find(json, "scale")) {
        const std::string at = joinKey(where, "scale");
        transform.scale = in.readVec3(*value, at);
        if (transform.scale.x == 0.0 || transform.scale.y == 0.0 || transform.scale.z == 0.0) {
            in.fail(at, "scale components must be non-zero, got " + formatVec3(transform.scale));
        }
    }
    return transform;
}

constexpr int kMaxSegments = 1024;

int readSegments(const JsonReader& in, const Json& value, const std::string& where) {
    const int segments = in.readInteger(value, where);
    if (segments < 3 || segments > kMaxSegments) {
        in.fail(where, "segments must be between 3 and " + std::to_string(kMaxSegments) + ", got " +
                           std::to_string(segments));
    }
    return segments;
}

/// Loaded meshes by resolved path, so a file used by several objects is read once.
using MeshCache = std::unordered_map<std::string, TriMesh>;

Shape readShape(const JsonReader& in, const Json& json, const std::string& where,
                const std::string& baseDir, MeshCache* cache) {
    in.expectObject(json, where);
    const std::string typeName =
        in.readString(in.require(json, "type", where), joinKey(where, "type"));
    Shape shape;
    const std::string context = " for a " + typeName;
    if (typeName == "quad") {
        shape.type = ShapeType::Quad;
        in.checkKeys(json, where, {"type", "size"}, context);
        const std::string at = joinKey(where, "size");
        const std::vector<double> size = in.readNumbers(in.require(json, "size", where), 2, at);
        if (!(size[0] > 0.0 && size[1] > 0.0)) {
            in.fail(at, "sizes must be positive, got [" + formatNumber(size[0]) + ", " +
                            formatNumber(size[1]) + "]");
        }
        shape.size = Vec3(size[0], 0.0, size[1]);
    } else if (typeName == "box") {
        shape.type = ShapeType::Box;
        in.checkKeys(json, where, {"type", "size"}, context);
        const std::string at = joinKey(where, "size");
        shape.size = in.readVec3(in.require(json, "size", where), at);
        if (!(shape.size.x > 0.0 && shape.size.y > 0.0 && shape.size.z > 0.0)) {
            in.fail(at, "sizes must be positive, got " + formatVec3(shape.size));
        }
    } else if (typeName == "sphere") {
        shape.type = ShapeType::Sphere;
        in.checkKeys(json, where, {"type", "radius", "segments"}, context);
        shape.radius = in.readPositive(in.require(json, "radius", where), joinKey(where, "radius"));
        if (const Json* value = JsonReader::find(json, "segments")) {
            shape.segments = readSegments(in, *value, joinKey(where, "segments"));
        }
    } else if (typeName == "cylinder") {
        shape.type = ShapeType::Cylinder;
        in.checkKeys(json, where, {"type", "radius", "height", "segments"}, context);
        shape.radius = in.readPositive(in.require(json, "radius", where), joinKey(where, "radius"));
        shape.height = in.readPositive(in.require(json, "height", where), joinKey(where, "height"));
        if (const Json* value = JsonReader::find(json, "segments")) {
            shape.segments = readSegments(in, *value, joinKey(where, "segments"));
        }
    } else if (typeName == "mesh") {
        shape.type = ShapeType::Mesh;
        in.checkKeys(json, where, {"type", "file"}, context);
        const std::string at = joinKey(where, "file");
        shape.file = in.readString(in.require(json, "file", where), at);
        if (shape.file.empty()) in.fail(at, "mesh file name is empty");
        const std::filesystem::path file(shape.file);
        const std::string resolved =
            (file.is_absolute() || baseDir.empty() ? file : std::filesystem::path(baseDir) / file)
                .lexically_normal()
                .string();
        try {
            if (cache) {
                auto it = cache->find(resolved);
                if (it == cache->end()) it = cache->emplace(resolved, loadMeshFile(resolved)).first;
                shape.mesh = it->second;
            } else {
                shape.mesh = loadMeshFile(resolved);
            }
        } catch (const InputError& error) {
            in.fail(at, error.what());
        }
    } else {
        in.fail(joinKey(where, "type"), "unknown shape type '" + typeName +
                                            "' (expected quad, box, sphere, cylinder or mesh)");
    }
    return shape;
}

SceneObject readObject(const JsonReader& in, const Json& json, const Scene& scene,
                       const std::string& where, const std::string& baseDir, MeshCache* cache) {
    in.expectObject(json, where);
    in.checkKeys(json, where, {"id", "shape", "material", "transform", "patch_size"});
    SceneObject object;
    const std::string idAt = joinKey(where, "id");
    object.id = in.readString(in.require(json, "id", where), idAt);
    if (object.id.empty()) in.fail(idAt, "object id must not be empty");

    // Material name first, so a typo is reported before a possibly slow mesh load.
    const Json* material = JsonReader::find(json, "material");
    const std::string materialAt = joinKey(where, "material");
    if (material) {
        object.material = in.readString(*material, materialAt);
        if (!scene.findMaterial(object.material)) {
            in.fail(materialAt, "unknown material '" + object.material + "'");
        }
    }
    object.shape =
        readShape(in, in.require(json, "shape", where), joinKey(where, "shape"), baseDir, cache);
    if (!material) {
        if (object.shape.type != ShapeType::Mesh) {
            in.fail(materialAt, "missing required key");
        }
        if (object.shape.mesh.triangleMaterial.empty()) {
            in.fail(materialAt, "missing required key (mesh '" + object.shape.file +
                                    "' carries no materials of its own)");
        }
    }
    if (const Json* transform = JsonReader::find(json, "transform")) {
        object.transform = readTransform(in, *transform, joinKey(where, "transform"), Transform{});
    }
    if (const Json* patchSize = JsonReader::find(json, "patch_size")) {
        const std::string at = joinKey(where, "patch_size");
        object.patchSize = in.readPositive(*patchSize, at);
        if (object.patchSize < scene.settings.elementSize)
            in.fail(at, "patch_size " + formatNumber(object.patchSize) +
                            " must not be below the scene's element_size " +
                            formatNumber(scene.settings.elementSize));
    }
    return object;
}

// ---------------------------------------------------------------------------------------------
// Settings, cameras, scene.

HolodeckSectionSetting readHolodeckSection(const JsonReader& in, const Json& json,
                                           const std::string& where) {
    in.expectObject(json, where);
    in.checkKeys(json, where, {"kind", "min", "max", "grid"});
    HolodeckSectionSetting section;
    if (const Json* value = JsonReader::find(json, "kind")) {
        const std::string at = joinKey(where, "kind");
        const std::string kind = in.readString(*value, at);
        if (kind != "interior" && kind != "exterior")
            in.fail(at, "kind must be \"interior\" or \"exterior\", got \"" + kind + "\"");
        section.exterior = kind == "exterior";
    }
    section.min = in.readVec3(in.require(json, "min", where), joinKey(where, "min"));
    section.max = in.readVec3(in.require(json, "max", where), joinKey(where, "max"));
    for (int a = 0; a < 3; ++a)
        if (!(section.max[a] > section.min[a]))
            in.fail(joinKey(where, "max"), "max " + formatVec3(section.max) + " must exceed min " +
                                               formatVec3(section.min) + " along every axis");
    if (const Json* value = JsonReader::find(json, "grid")) {
        const std::string at = joinKey(where, "grid");
        if (!value->is_array() || value->size() != 3)
            in.fail(at, "expected an array of 3 integers, got " + describeType(*value));
        for (int a = 0; a < 3; ++a) {
            const int cells = in.readInteger((*value)[a], joinIndex(at, a));
            if (cells < 1 || cells > 1024)
                in.fail(joinIndex(at, a),
                        "cells must be in [1, 1024], got " + std::to_string(cells));
            section.grid[a] = cells;
        }
    }
    return section;
}

Settings readSettings(const JsonReader& in, const Json& json, const std::string& where) {
    in.expectObject(json, where);
    in.checkKeys(json, where, {"patch_size", "element_size", "holodeck"});
    Settings settings;
    if (const Json* value = JsonReader::find(json, "patch_size")) {
        settings.patchSize = in.readPositive(*value, joinKey(where, "patch_size"));
    }
    if (const Json* value = JsonReader::find(json, "element_size")) {
        settings.elementSize = in.readPositive(*value, joinKey(where, "element_size"));
    }
    if (settings.elementSize > settings.patchSize) {
        in.fail(joinKey(where, "element_size"),
                "element_size " + formatNumber(settings.elementSize) +
                    " must not exceed patch_size " + formatNumber(settings.patchSize));
    }
    if (const Json* value = JsonReader::find(json, "holodeck")) {
        const std::string at = joinKey(where, "holodeck");
        if (!value->is_array() || value->empty())
            in.fail(at, "expected a non-empty array of sections, got " + describeType(*value));
        if (value->size() > 64)
            in.fail(at, "at most 64 sections, got " + std::to_string(value->size()));
        for (size_t i = 0; i < value->size(); ++i)
            settings.holodeck.push_back(readHolodeckSection(in, (*value)[i], joinIndex(at, i)));
    }
    return settings;
}

Camera readCamera(const JsonReader& in, const Json& json, const std::string& name,
                  const std::string& where) {
    in.expectObject(json, where);
    in.checkKeys(json, where, {"position", "look_at", "up", "fov_deg"});
    Camera camera;
    camera.name = name;
    camera.position = in.readVec3(in.require(json, "position", where), joinKey(where, "position"));
    camera.lookAt = in.readVec3(in.require(json, "look_at", where), joinKey(where, "look_at"));
    if (const Json* value = JsonReader::find(json, "up")) {
        camera.up = in.readVec3(*value, joinKey(where, "up"));
    }
    if (const Json* value = JsonReader::find(json, "fov_deg")) {
        const std::string at = joinKey(where, "fov_deg");
        camera.fovDeg = in.readNumber(*value, at);
        if (!(camera.fovDeg > 0.0 && camera.fovDeg < 180.0)) {
            in.fail(at, "fov_deg must be in (0, 180), got " + formatNumber(camera.fovDeg));
        }
    }
    const Vec3 view = camera.lookAt - camera.position;
    if (!(glm::length(view) > 0.0)) in.fail(joinKey(where, "look_at"), "look_at equals position");
    if (!(glm::length(glm::cross(glm::normalize(view), camera.up)) >
          1e-9 * glm::length(camera.up))) {
        in.fail(joinKey(where, "up"),
                "up " + formatVec3(camera.up) + " is zero or parallel to the view direction");
    }
    return camera;
}

Scene readScene(const JsonReader& in, const Json& json, const std::string& baseDir) {
    if (!json.is_object())
        in.fail("", "expected a JSON object at the top level, got " + describeType(json));

    // Format first: a file of another kind should say so, not list unknown keys.
    const std::string format = in.readString(in.require(json, "format", ""), "format");
    if (format != kSceneFormat) {
        in.fail("format", "unsupported format '" + format + "' (expected '" + kSceneFormat + "')");
    }
    in.checkKeys(json, "", {"format", "settings", "materials", "objects", "cameras"});

    Scene scene;
    if (const Json* settings = JsonReader::find(json, "settings")) {
        scene.settings = readSettings(in, *settings, "settings");
    }
    if (const Json* materials = JsonReader::find(json, "materials")) {
        in.expectObject(*materials, "materials");
        for (auto it = materials->begin(); it != materials->end(); ++it) {
            const std::string where = joinKey("materials", it.key());
            if (it.key().empty()) in.fail(where, "material name must not be empty");
            if (scene.findMaterial(it.key())) {
                in.fail(where, "duplicate material name '" + it.key() + "'");
            }
            scene.materials.push_back({it.key(), readMaterial(in, it.value(), where, Material{})});
        }
    }

    const Json& objects = in.require(json, "objects", "");
    if (!objects.is_array()) in.fail("objects", "expected an array, got " + describeType(objects));
    MeshCache cache;
    std::map<std::string, size_t> firstUse;
    for (size_t i = 0; i < objects.size(); ++i) {
        const std::string where = joinIndex("objects", i);
        SceneObject object = readObject(in, objects[i], scene, where, baseDir, &cache);
        const auto [previous, inserted] = firstUse.emplace(object.id, i);
        if (!inserted) {
            in.fail(joinKey(where, "id"), "duplicate object id '" + object.id + "' (also " +
                                              joinIndex("objects", previous->second) + ")");
        }
        scene.objects.push_back(std::move(object));
    }

    if (const Json* cameras = JsonReader::find(json, "cameras")) {
        in.expectObject(*cameras, "cameras");
        for (auto it = cameras->begin(); it != cameras->end(); ++it) {
            const std::string where = joinKey("cameras", it.key());
            if (it.key().empty()) in.fail(where, "camera name must not be empty");
            if (scene.findCamera(it.key()))
                in.fail(where, "duplicate camera name '" + it.key() + "'");
            scene.cameras.push_back(readCamera(in, it.value(), it.key(), where));
        }
    }
    return scene;
}

// ---------------------------------------------------------------------------------------------
// Parsing text: malformed JSON with line and column, duplicate keys.

/// Line and column (1-based) of the byte at 0-based `offset` in `text`.
std::string lineAndColumn(const std::string& text, size_t offset) {
    offset = std::min(offset, text.size());
    size_t line = 1;
    size_t lineStart = 0;
    for (size_t i = 0; i < offset; ++i) {
        if (text[i] == '\n') {
            ++line;
            lineStart = i + 1;
        }
    }
    return "line " + std::to_string(line) + ", column " + std::to_string(offset - lineStart + 1);
}

constexpr int kMaxNesting = 64;

/// Parses `text`, failing on malformed JSON, on nesting deeper than kMaxNesting and on a
/// key repeated within one object (nlohmann would silently keep the last one).
Json parseSceneText(const std::string& text, const std::string& sourceName) {
    if (text.find_first_not_of(" \t\r\n") == std::string::npos) {
        throw InputError(sourceName, "", "file is empty");
    }
    std::optional<JsonStructureProblem> problem;
    Json json;
    try {
        json = parseJsonTracked(text, problem);
    } catch (const Json::parse_error& error) {
        const size_t offset = error.byte > 0 ? error.byte - 1 : 0;
        throw InputError(sourceName, lineAndColumn(text, offset), jsonErrorProblem(error.what()));
    } catch (const Json::exception& error) {
        // out_of_range: a number beyond a double ("number overflow parsing '1e999'").
        throw InputError(sourceName, "", jsonErrorProblem(error.what()));
    }
    if (problem) {
        if (problem->tooDeep)
            throw InputError(sourceName, problem->path,
                             "nesting deeper than " + std::to_string(kMaxNesting) + " levels");
        const std::string kind = problem->parent == "materials" ? "material name"
                                 : problem->parent == "cameras" ? "camera name"
                                                                : "key";
        throw InputError(sourceName, problem->path,
                         "duplicate " + kind + " '" + problem->key + "'");
    }
    return json;
}

// ---------------------------------------------------------------------------------------------
// Writing JSON.

Json vec3ToJson(const Vec3& v) { return Json::array({v.x, v.y, v.z}); }

Json shapeToJson(const Shape& shape) {
    Json json;
    json["type"] = shapeTypeName(shape.type);
    switch (shape.type) {
        case ShapeType::Quad:
            json["size"] = Json::array({shape.size.x, shape.size.z});
            break;
        case ShapeType::Box:
            json["size"] = vec3ToJson(shape.size);
            break;
        case ShapeType::Sphere:
            json["radius"] = shape.radius;
            json["segments"] = shape.segments;
            break;
        case ShapeType::Cylinder:
            json["radius"] = shape.radius;
            json["height"] = shape.height;
            json["segments"] = shape.segments;
            break;
        case ShapeType::Mesh:
            json["file"] = shape.file;
            break;
    }
    return json;
}

Json cameraToJson(const Camera& camera) {
    Json json;
    json["position"] = vec3ToJson(camera.position);
    json["look_at"] = vec3ToJson(camera.lookAt);
    json["up"] = vec3ToJson(camera.up);
    json["fov_deg"] = camera.fovDeg;
    return json;
}

// ---------------------------------------------------------------------------------------------
// Text formatting.

constexpr size_t kLineWidth = 100;

std::string dumpScalar(const Json& value) {
    return value.dump(-1, ' ', false, Json::error_handler_t::replace);
}

/// One-line form with a space after ',' and ':'.
std::string formatInline(const Json& value) {
    if (value.is_object()) {
        if (value.empty()) return "{}";
        std::string text = "{";
        for (auto it = value.begin(); it != value.end(); ++it) {
            if (it != value.begin()) text += ", ";
            text += dumpScalar(Json(it.key())) + ": " + formatInline(it.value());
        }
        return text + "}";
    }
    if (value.is_array()) {
        if (value.empty()) return "[]";
        std::string text = "[";
        for (size_t i = 0; i < value.size(); ++i) {
            if (i > 0) text += ", ";
            text += formatInline(value[i]);
        }
        return text + "]";
    }
    return dumpScalar(value);
}

/// Appends `value` at `indent`, where the current line already holds `used` characters.
void formatBlock(const Json& value, size_t indent, size_t used, std::string& out) {
    const std::string oneLine = formatInline(value);
    if (!value.is_structured() || value.empty() || used + oneLine.size() <= kLineWidth) {
        out += oneLine;
        return;
    }
    const std::string pad(indent + 2, ' ');
    if (value.is_object()) {
        out += "{\n";
        for (auto it = value.begin(); it != value.end(); ++it) {
            const std::string key = dumpScalar(Json(it.key())) + ": ";
            out += pad + key;
            formatBlock(it.value(), indent + 2, pad.size() + key.size(), out);
            out += std::next(it) == value.end() ? "\n" : ",\n";
        }
        out += std::string(indent, ' ') + "}";
    } else {
        out += "[\n";
        for (size_t i = 0; i < value.size(); ++i) {
            out += pad;
            formatBlock(value[i], indent + 2, pad.size(), out);
            out += i + 1 == value.size() ? "\n" : ",\n";
        }
        out += std::string(indent, ' ') + "]";
    }
}

std::string readWholeFile(const std::string& path) {
    std::error_code error;
    if (std::filesystem::is_directory(path, error)) {
        throw InputError(path, "", "cannot read scene file: is a directory");
    }
    std::ifstream file(path, std::ios::binary);
    if (!file) {
        throw InputError(path, "", std::string("cannot read scene file: ") + std::strerror(errno));
    }
    std::ostringstream text;
    text << file.rdbuf();
    if (file.bad()) throw InputError(path, "", "cannot read scene file: read error");
    return text.str();
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// Public API.

Scene loadScene(const std::string& path) { return loadScene(path, ImportOptions{}); }

Scene loadScene(const std::string& path, const ImportOptions& import) {
    if (isImportableScene(path)) return importScene(path, import);
    const std::string text = readWholeFile(path);
    const Json json = parseSceneText(text, path);
    return sceneFromJson(json, path, std::filesystem::path(path).parent_path().string());
}

Scene sceneFromJson(const Json& json, const std::string& sourceName, const std::string& baseDir) {
    return readScene(JsonReader(sourceName), json, baseDir);
}

Scene sceneFromJson(const nlohmann::json& json, const std::string& sourceName,
                    const std::string& baseDir) {
    return sceneFromJson(Json(json), sourceName, baseDir);
}

SceneObject objectFromJson(const Json& json, const Scene& scene, const std::string& sourceName,
                           const std::string& where, const std::string& baseDir) {
    return readObject(JsonReader(sourceName), json, scene, where, baseDir, nullptr);
}

SceneObject objectFromJson(const nlohmann::json& json, const Scene& scene,
                           const std::string& sourceName, const std::string& where,
                           const std::string& baseDir) {
    return objectFromJson(Json(json), scene, sourceName, where, baseDir);
}

Material materialFromJson(const Json& json, const std::string& sourceName, const std::string& where,
                          const Material& base) {
    return readMaterial(JsonReader(sourceName), json, where, base);
}

Transform transformFromJson(const Json& json, const std::string& sourceName,
                            const std::string& where, const Transform& base) {
    return readTransform(JsonReader(sourceName), json, where, base);
}

Json materialToJson(const Material& material) {
    Json json;
    json["reflectance"] = vec3ToJson(material.reflectance);
    if (material.emission != Rgb(0.0)) json["emission"] = vec3ToJson(material.emission);
    if (material.twoSided) json["two_sided"] = true;
    return json;
}

Json transformToJson(const Transform& transform) {
    Json json = Json::object();
    const Transform identity;
    if (transform.translate != identity.translate)
        json["translate"] = vec3ToJson(transform.translate);
    if (transform.rotateDeg != identity.rotateDeg)
        json["rotate_deg"] = vec3ToJson(transform.rotateDeg);
    if (transform.scale != identity.scale) json["scale"] = vec3ToJson(transform.scale);
    return json;
}

Json objectToJson(const SceneObject& object) {
    Json json;
    json["id"] = object.id;
    json["shape"] = shapeToJson(object.shape);
    if (!object.material.empty()) json["material"] = object.material;
    Json transform = transformToJson(object.transform);
    if (!transform.empty()) json["transform"] = std::move(transform);
    if (object.patchSize > 0) json["patch_size"] = object.patchSize;
    return json;
}

Json sceneToJson(const Scene& scene) {
    Json json;
    json["format"] = kSceneFormat;
    json["settings"] = {{"patch_size", scene.settings.patchSize},
                        {"element_size", scene.settings.elementSize}};
    for (const HolodeckSectionSetting& section : scene.settings.holodeck) {
        Json entry = {{"kind", section.exterior ? "exterior" : "interior"},
                      {"min", vec3ToJson(section.min)},
                      {"max", vec3ToJson(section.max)}};
        if (section.grid[0] > 0) entry["grid"] = section.grid;
        json["settings"]["holodeck"].push_back(std::move(entry));
    }
    Json materials = Json::object();
    for (const NamedMaterial& entry : scene.materials) {
        materials[entry.name] = materialToJson(entry.material);
    }
    json["materials"] = std::move(materials);
    Json objects = Json::array();
    for (const SceneObject& object : scene.objects) objects.push_back(objectToJson(object));
    json["objects"] = std::move(objects);
    if (!scene.cameras.empty()) {
        Json cameras = Json::object();
        for (const Camera& camera : scene.cameras) cameras[camera.name] = cameraToJson(camera);
        json["cameras"] = std::move(cameras);
    }
    return json;
}

std::string formatSceneText(const Json& json) {
    std::string text;
    formatBlock(json, 0, 0, text);
    return text + "\n";
}

std::string rebaseMeshPath(const std::string& file, const std::string& fromDir,
                           const std::string& toDir) {
    const std::filesystem::path original(file);
    if (file.empty() || original.is_absolute()) return file;
    const std::filesystem::path from = std::filesystem::absolute(fromDir.empty() ? "." : fromDir);
    const std::filesystem::path to = std::filesystem::absolute(toDir.empty() ? "." : toDir);
    if (from.lexically_normal() == to.lexically_normal()) return file;
    // weakly_canonical resolves symbolic links in the existing part of both paths, so the
    // relative path also holds when the folders are reached through links.
    const std::filesystem::path target = std::filesystem::weakly_canonical(from / original);
    const std::filesystem::path relative =
        target.lexically_relative(std::filesystem::weakly_canonical(to));
    return relative.empty() ? target.string() : relative.generic_string();
}

void rebaseMeshPaths(Scene& scene, const std::string& fromDir, const std::string& toDir) {
    for (SceneObject& object : scene.objects) {
        if (object.shape.type == ShapeType::Mesh)
            object.shape.file = rebaseMeshPath(object.shape.file, fromDir, toDir);
    }
}

void saveScene(const Scene& scene, const std::string& path) {
    const std::filesystem::path target(path);
    const std::filesystem::path directory =
        target.has_parent_path() ? target.parent_path() : std::filesystem::path(".");
    // Meshes without a file (an imported scene's) are written beside the scene first.
    Scene written = scene;
    const std::string meshDir = target.stem().string() + "-meshes";
    for (SceneObject& object : written.objects) {
        if (object.shape.type != ShapeType::Mesh || !object.shape.file.empty()) continue;
        std::string name;
        for (char c : object.id)
            name += std::isalnum(static_cast<unsigned char>(c)) || c == '-' || c == '_' ? c : '_';
        std::error_code error;
        std::filesystem::create_directories(directory / meshDir, error);
        if (error)
            throw InputError(
                path, "",
                "cannot create " + (directory / meshDir).string() + ": " + error.message());
        std::string file = meshDir + "/" + name + ".obj";
        for (int k = 2; std::any_of(written.objects.begin(), written.objects.end(),
                                    [&](const SceneObject& o) { return o.shape.file == file; });
             ++k)
            file = meshDir + "/" + name + "-" + std::to_string(k) + ".obj";
        saveObjMesh(object.shape.mesh, (directory / file).string());
        object.shape.file = file;
    }
    writeFileAtomically(path, formatSceneText(sceneToJson(written)));
}

std::string jsonErrorProblem(const std::string& message) {
    const size_t at = message.find("parse error");
    if (at != std::string::npos) {
        const size_t colon = message.find(": ", at);
        return colon == std::string::npos ? message : message.substr(colon + 2);
    }
    const size_t bracket = message.find("] ");
    if (message.rfind("[json.exception", 0) == 0 && bracket != std::string::npos)
        return message.substr(bracket + 2);
    return message;
}

std::string describeType(const Json& value) {
    if (value.is_number()) return "a number";
    if (value.is_string()) return "a string";
    if (value.is_boolean()) return "a boolean";
    if (value.is_array()) return "an array";
    if (value.is_object()) return "an object";
    return "null";
}

std::string formatNumber(double value) {
    std::ostringstream out;
    out << value;
    return out.str();
}

Json parseJsonTracked(const std::string& text, std::optional<JsonStructureProblem>& problem) {
    // Track the key path of every value as nlohmann's parser reports events.
    struct Frame {
        bool isArray = false;
        size_t nextIndex = 0;
        std::string path;
        std::set<std::string> keys;
        std::string currentKey;
    };
    std::vector<Frame> stack;
    problem.reset();

    // Path of the value that starts now inside the innermost open container.
    auto startChild = [&]() -> std::string {
        if (stack.empty()) return "";
        Frame& top = stack.back();
        if (top.isArray) return joinIndex(top.path, top.nextIndex++);
        return joinKey(top.path, top.currentKey);
    };
    auto callback = [&](int depth, Json::parse_event_t event, Json& parsed) -> bool {
        if (problem) return true;
        switch (event) {
            case Json::parse_event_t::object_start:
            case Json::parse_event_t::array_start: {
                Frame frame;
                frame.isArray = event == Json::parse_event_t::array_start;
                frame.path = startChild();
                if (depth > kMaxNesting) problem = JsonStructureProblem{frame.path, "", "", true};
                stack.push_back(std::move(frame));
                break;
            }
            case Json::parse_event_t::object_end:
            case Json::parse_event_t::array_end:
                if (!stack.empty()) stack.pop_back();
                break;
            case Json::parse_event_t::key: {
                Frame& top = stack.back();
                top.currentKey = parsed.get<std::string>();
                if (!top.keys.insert(top.currentKey).second)
                    problem = JsonStructureProblem{joinKey(top.path, top.currentKey), top.path,
                                                   top.currentKey, false};
                break;
            }
            case Json::parse_event_t::value:
                if (!stack.empty() && stack.back().isArray) ++stack.back().nextIndex;
                break;
        }
        return true;
    };
    return Json::parse(text, callback);
}

}  // namespace penumbra
