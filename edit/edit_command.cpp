// Edit commands ↔ log lines.
// Index: names and small helpers · value checks · parsing JSON values · public API ·
//        serializing

#include "edit/edit_command.h"

#include <cmath>
#include <set>
#include <sstream>
#include <string_view>
#include <vector>

#include "core/input_error.h"
#include "edit/io/scene_io.h"

namespace penumbra {

using Json = nlohmann::ordered_json;

namespace {

// ---------------------------------------------------------------------------------------------
// Names and small helpers.

constexpr const char* kOpList =
    "add, remove, transform, move, material, select, unselect, undo, redo, solve, converge";

Json vec3ToJson(const Vec3& v) { return Json::array({v.x, v.y, v.z}); }

bool isFinite(const Vec3& v) {
    return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}

/// Fails naming `source` and `key`.
[[noreturn]] void fail(const EditSource& source, const std::string& key,
                       const std::string& problem) {
    throw InputError(source.file, source.where(key), problem);
}

void checkFinite(const Vec3& v, const EditSource& source, const std::string& key) {
    if (!isFinite(v)) fail(source, key, "not a finite number");
}

void checkId(const std::string& id, const EditSource& source, const std::string& key = "id") {
    if (id.empty()) fail(source, key, "object id must not be empty");
}

// ---------------------------------------------------------------------------------------------
// Value checks (shared by the parser and commands built in code).

void checkTransformValues(const std::optional<Vec3>& translate,
                          const std::optional<Vec3>& rotateDeg, const std::optional<Vec3>& scale,
                          const EditSource& source, const std::string& key) {
    if (translate) checkFinite(*translate, source, key + ".translate");
    if (rotateDeg) checkFinite(*rotateDeg, source, key + ".rotate_deg");
    if (scale) {
        checkFinite(*scale, source, key + ".scale");
        if (scale->x == 0.0 || scale->y == 0.0 || scale->z == 0.0)
            fail(source, key + ".scale", "scale components must be non-zero");
    }
}

void checkMaterialValues(const MaterialCommand& m, const EditSource& source) {
    if (m.reflectance) {
        checkFinite(*m.reflectance, source, "material.reflectance");
        for (int c = 0; c < 3; ++c)
            if (!((*m.reflectance)[c] >= 0.0 && (*m.reflectance)[c] < 1.0))
                fail(source, "material.reflectance", "reflectance must be in [0, 1) per channel");
    }
    if (m.emission) {
        checkFinite(*m.emission, source, "material.emission");
        for (int c = 0; c < 3; ++c)
            if ((*m.emission)[c] < 0.0)
                fail(source, "material.emission", "emission must not be negative");
    }
}

void checkObjectValues(const SceneObject& object, const EditSource& source) {
    checkId(object.id, source, "object.id");
    const Shape& s = object.shape;
    const std::string at = "object.shape";
    switch (s.type) {
        case ShapeType::Quad:
            if (!(std::isfinite(s.size.x) && std::isfinite(s.size.z) && s.size.x > 0 &&
                  s.size.z > 0))
                fail(source, at + ".size", "sizes must be positive and finite");
            break;
        case ShapeType::Box:
            if (!(isFinite(s.size) && s.size.x > 0 && s.size.y > 0 && s.size.z > 0))
                fail(source, at + ".size", "sizes must be positive and finite");
            break;
        case ShapeType::Cylinder:
            if (!(std::isfinite(s.height) && s.height > 0))
                fail(source, at + ".height", "must be positive and finite");
            [[fallthrough]];
        case ShapeType::Sphere:
            if (!(std::isfinite(s.radius) && s.radius > 0))
                fail(source, at + ".radius", "must be positive and finite");
            if (s.segments < 3 || s.segments > 1024)
                fail(source, at + ".segments", "segments must be between 3 and 1024");
            break;
        case ShapeType::Mesh:
            if (s.mesh.triangles.empty()) fail(source, at + ".file", "mesh has no triangles");
            break;
    }
    if (object.material.empty() && !(s.type == ShapeType::Mesh && !s.mesh.triangleMaterial.empty()))
        fail(source, "object.material", "missing required key");
    const Transform& t = object.transform;
    checkTransformValues(t.translate, t.rotateDeg, t.scale, source, "object.transform");
}

// ---------------------------------------------------------------------------------------------
// Parsing JSON values.

/// Typed access to one command's JSON, failing with InputError naming the line and key.
class CommandReader {
public:
    CommandReader(const Json& json, const EditSource& source) : mJson(json), mSource(source) {}

    [[noreturn]] void fail(const std::string& key, const std::string& problem) const {
        penumbra::fail(mSource, key, problem);
    }

    /// Rejects keys other than "op", "t_ms" and `allowed`, naming the first unknown one.
    void checkKeys(std::initializer_list<std::string_view> allowed, const std::string& op) const {
        for (auto it = mJson.begin(); it != mJson.end(); ++it) {
            bool known = it.key() == "op" || it.key() == "t_ms";
            for (std::string_view key : allowed) known = known || key == it.key();
            if (known) continue;
            std::string list = "op";
            for (std::string_view key : allowed) list += ", " + std::string(key);
            fail(it.key(), "unknown key '" + it.key() + "' for op '" + op + "' (allowed: " + list +
                               ", t_ms)");
        }
    }

    const Json& require(const char* key) const {
        auto it = mJson.find(key);
        if (it == mJson.end()) fail(key, "missing required key");
        return *it;
    }

    std::string readString(const char* key) const {
        const Json& value = require(key);
        if (!value.is_string()) fail(key, "expected a string, got " + describeType(value));
        return value.get<std::string>();
    }

    std::string readId() const {
        std::string id = readString("id");
        checkId(id, mSource);
        return id;
    }

    double readNumber(const char* key) const {
        const Json& value = require(key);
        if (!value.is_number()) fail(key, "expected a number, got " + describeType(value));
        double number = value.get<double>();
        if (!std::isfinite(number)) fail(key, "not a finite number");
        return number;
    }

    int readCount(const char* key) const {
        const Json& value = require(key);
        if (!value.is_number_integer())
            fail(key, "expected a non-negative integer, got " +
                          (value.is_number() ? "the number " + value.dump() : describeType(value)));
        if (value.is_number_unsigned()) {
            auto n = value.get<std::uint64_t>();
            if (n > 1000000000ull) fail(key, "integer " + value.dump() + " is too large");
            return static_cast<int>(n);
        }
        auto n = value.get<std::int64_t>();
        if (n < 0) fail(key, "must not be negative, got " + value.dump());
        if (n > 1000000000ll) fail(key, "integer " + value.dump() + " is too large");
        return static_cast<int>(n);
    }

    Vec3 readVec3(const char* key) const {
        const Json& value = require(key);
        if (!value.is_array() || value.size() != 3)
            fail(key, "expected an array of 3 numbers, got " +
                          (value.is_array() ? "an array of " + std::to_string(value.size())
                                            : describeType(value)));
        Vec3 v;
        for (int i = 0; i < 3; ++i) {
            const std::string at = std::string(key) + "[" + std::to_string(i) + "]";
            if (!value[i].is_number()) fail(at, "expected a number, got " + describeType(value[i]));
            v[i] = value[i].get<double>();
            if (!std::isfinite(v[i])) fail(at, "not a finite number");
        }
        return v;
    }

    const Json& readObject(const char* key) const {
        const Json& value = require(key);
        if (!value.is_object()) fail(key, "expected an object, got " + describeType(value));
        return value;
    }

private:
    const Json& mJson;
    const EditSource& mSource;
};

EditOp parseOp(const CommandReader& in, const std::string& op, const EditSource& source,
               const Scene* scene, const std::string& meshBaseDir) {
    if (op == "add") {
        in.checkKeys({"object"}, op);
        const Json& objectJson = in.readObject("object");
        // Without a scene the material is checked by the session when the edit is applied.
        Scene stub;
        if (!scene) {
            auto material = objectJson.find("material");
            if (material != objectJson.end() && material->is_string())
                stub.materials.push_back({material->get<std::string>(), Material{}});
        }
        return AddCommand{objectFromJson(objectJson, scene ? *scene : stub, source.file,
                                         source.where("object"), meshBaseDir)};
    }
    if (op == "remove") {
        in.checkKeys({"id"}, op);
        return RemoveCommand{in.readId()};
    }
    if (op == "transform") {
        in.checkKeys({"id", "transform"}, op);
        TransformCommand c;
        c.id = in.readId();
        const Json& t = in.readObject("transform");
        const Transform parsed = transformFromJson(t, source.file, source.where("transform"));
        if (t.contains("translate")) c.translate = parsed.translate;
        if (t.contains("rotate_deg")) c.rotateDeg = parsed.rotateDeg;
        if (t.contains("scale")) c.scale = parsed.scale;
        return c;
    }
    if (op == "move") {
        in.checkKeys({"id", "by"}, op);
        MoveCommand c;
        c.id = in.readId();
        c.by = in.readVec3("by");
        return c;
    }
    if (op == "material") {
        in.checkKeys({"id", "material"}, op);
        MaterialCommand c;
        c.id = in.readId();
        const Json& m = in.readObject("material");
        const Material parsed = materialFromJson(m, source.file, source.where("material"));
        if (m.contains("reflectance")) c.reflectance = parsed.reflectance;
        if (m.contains("emission")) c.emission = parsed.emission;
        if (m.contains("two_sided")) c.twoSided = parsed.twoSided;
        return c;
    }
    if (op == "select") {
        in.checkKeys({"id"}, op);
        return SelectCommand{in.readId()};
    }
    if (op == "unselect") {
        in.checkKeys({}, op);
        return UnselectCommand{};
    }
    if (op == "undo") {
        in.checkKeys({}, op);
        return UndoCommand{};
    }
    if (op == "redo") {
        in.checkKeys({}, op);
        return RedoCommand{};
    }
    if (op == "solve") {
        in.checkKeys({"shots"}, op);
        return SolveCommand{in.readCount("shots")};
    }
    if (op == "converge") {
        in.checkKeys({"threshold"}, op);
        ConvergeCommand c{in.readNumber("threshold")};
        if (!(c.threshold > 0 && c.threshold < 1))
            in.fail("threshold", "must be in (0, 1), got " + formatNumber(c.threshold));
        return c;
    }
    in.fail("op", "unknown op '" + op + "' (expected " + kOpList + ")");
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// Public API.

TransformCommand fullTransformCommand(const std::string& id, const Transform& transform) {
    TransformCommand c;
    c.id = id;
    c.translate = transform.translate;
    c.rotateDeg = transform.rotateDeg;
    c.scale = transform.scale;
    return c;
}

Transform TransformCommand::appliedTo(const Transform& current) const {
    Transform t = current;
    if (translate) t.translate = *translate;
    if (rotateDeg) t.rotateDeg = *rotateDeg;
    if (scale) t.scale = *scale;
    return t;
}

Material MaterialCommand::appliedTo(const Material& current) const {
    Material m = current;
    if (reflectance) m.reflectance = *reflectance;
    if (emission) m.emission = *emission;
    if (twoSided) m.twoSided = *twoSided;
    return m;
}

const char* EditCommand::opName() const {
    struct Name {
        const char* operator()(const AddCommand&) const { return "add"; }
        const char* operator()(const RemoveCommand&) const { return "remove"; }
        const char* operator()(const TransformCommand&) const { return "transform"; }
        const char* operator()(const MoveCommand&) const { return "move"; }
        const char* operator()(const MaterialCommand&) const { return "material"; }
        const char* operator()(const SelectCommand&) const { return "select"; }
        const char* operator()(const UnselectCommand&) const { return "unselect"; }
        const char* operator()(const UndoCommand&) const { return "undo"; }
        const char* operator()(const RedoCommand&) const { return "redo"; }
        const char* operator()(const SolveCommand&) const { return "solve"; }
        const char* operator()(const ConvergeCommand&) const { return "converge"; }
    };
    return std::visit(Name{}, op);
}

std::string EditCommand::objectId() const {
    if (auto* c = std::get_if<AddCommand>(&op)) return c->object.id;
    if (auto* c = std::get_if<RemoveCommand>(&op)) return c->id;
    if (auto* c = std::get_if<TransformCommand>(&op)) return c->id;
    if (auto* c = std::get_if<MoveCommand>(&op)) return c->id;
    if (auto* c = std::get_if<MaterialCommand>(&op)) return c->id;
    if (auto* c = std::get_if<SelectCommand>(&op)) return c->id;
    return "";
}

bool EditCommand::isSolverWork() const {
    return std::holds_alternative<SolveCommand>(op) || std::holds_alternative<ConvergeCommand>(op);
}

std::string EditCommand::toString() const { return formatEditCommand(*this); }

std::string EditSource::where(const std::string& key) const {
    std::string w = line > 0 ? "line " + std::to_string(line) : "";
    if (!key.empty()) w += (w.empty() ? "" : ": ") + key;
    return w;
}

void checkEditValues(const EditCommand& command, const EditSource& source) {
    if (command.tMs && !(std::isfinite(*command.tMs) && *command.tMs >= 0))
        fail(source, "t_ms", "must be a finite, non-negative number of milliseconds");
    if (auto* c = std::get_if<AddCommand>(&command.op)) {
        checkObjectValues(c->object, source);
    } else if (auto* c = std::get_if<RemoveCommand>(&command.op)) {
        checkId(c->id, source);
    } else if (auto* c = std::get_if<TransformCommand>(&command.op)) {
        checkId(c->id, source);
        checkTransformValues(c->translate, c->rotateDeg, c->scale, source, "transform");
    } else if (auto* c = std::get_if<MoveCommand>(&command.op)) {
        checkId(c->id, source);
        checkFinite(c->by, source, "by");
    } else if (auto* c = std::get_if<MaterialCommand>(&command.op)) {
        checkId(c->id, source);
        checkMaterialValues(*c, source);
    } else if (auto* c = std::get_if<SelectCommand>(&command.op)) {
        checkId(c->id, source);
    } else if (auto* c = std::get_if<SolveCommand>(&command.op)) {
        if (c->shots < 0) fail(source, "shots", "must not be negative");
    } else if (auto* c = std::get_if<ConvergeCommand>(&command.op)) {
        if (!(c->threshold > 0 && c->threshold < 1))
            fail(source, "threshold", "must be in (0, 1), got " + formatNumber(c->threshold));
    }
}

EditCommand editCommandFromJson(const Json& json, const EditSource& source, const Scene* scene,
                                const std::string& meshBaseDir) {
    if (!json.is_object())
        fail(source, "", "expected a JSON object {\"op\": ...}, got " + describeType(json));
    CommandReader in(json, source);
    const std::string op = in.readString("op");
    EditCommand command;
    command.op = parseOp(in, op, source, scene, meshBaseDir);
    if (json.contains("t_ms")) {
        command.tMs = in.readNumber("t_ms");
        if (*command.tMs < 0) in.fail("t_ms", "must not be negative");
    }
    checkEditValues(command, source);
    return command;
}

EditCommand parseEditCommand(const std::string& line, const EditSource& source, const Scene* scene,
                             const std::string& meshBaseDir) {
    std::optional<JsonStructureProblem> problem;
    Json json;
    try {
        json = parseJsonTracked(line, problem);
    } catch (const Json::parse_error& error) {
        const size_t column = error.byte > 0 ? error.byte : 1;
        std::string where = source.where();
        where += (where.empty() ? "column " : ", column ") + std::to_string(column);
        throw InputError(source.file, where, jsonErrorProblem(error.what()));
    } catch (const Json::exception& error) {
        // e.g. out_of_range: "number overflow parsing '1e999'".
        fail(source, "", jsonErrorProblem(error.what()));
    }
    if (problem) {
        if (problem->tooDeep) fail(source, problem->path, "nesting deeper than 64 levels");
        fail(source, problem->path, "repeated key '" + problem->key + "'");
    }
    return editCommandFromJson(json, source, scene, meshBaseDir);
}

// ---------------------------------------------------------------------------------------------
// Serializing.

Json editCommandToJson(const EditCommand& command) {
    Json json;
    json["op"] = command.opName();
    if (auto* c = std::get_if<AddCommand>(&command.op)) {
        json["object"] = objectToJson(c->object);
    } else if (auto* c = std::get_if<RemoveCommand>(&command.op)) {
        json["id"] = c->id;
    } else if (auto* c = std::get_if<TransformCommand>(&command.op)) {
        json["id"] = c->id;
        Json t = Json::object();
        if (c->translate) t["translate"] = vec3ToJson(*c->translate);
        if (c->rotateDeg) t["rotate_deg"] = vec3ToJson(*c->rotateDeg);
        if (c->scale) t["scale"] = vec3ToJson(*c->scale);
        json["transform"] = std::move(t);
    } else if (auto* c = std::get_if<MoveCommand>(&command.op)) {
        json["id"] = c->id;
        json["by"] = vec3ToJson(c->by);
    } else if (auto* c = std::get_if<MaterialCommand>(&command.op)) {
        json["id"] = c->id;
        Json m = Json::object();
        if (c->reflectance) m["reflectance"] = vec3ToJson(*c->reflectance);
        if (c->emission) m["emission"] = vec3ToJson(*c->emission);
        if (c->twoSided) m["two_sided"] = *c->twoSided;
        json["material"] = std::move(m);
    } else if (auto* c = std::get_if<SelectCommand>(&command.op)) {
        json["id"] = c->id;
    } else if (auto* c = std::get_if<SolveCommand>(&command.op)) {
        json["shots"] = c->shots;
    } else if (auto* c = std::get_if<ConvergeCommand>(&command.op)) {
        json["threshold"] = c->threshold;
    }
    if (command.tMs) json["t_ms"] = *command.tMs;
    return json;
}

std::string formatEditCommand(const EditCommand& command) {
    return editCommandToJson(command).dump(-1, ' ', false, Json::error_handler_t::replace);
}

}  // namespace penumbra
