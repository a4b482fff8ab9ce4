#pragma once
// Edit commands: plain data, one per line of the edit log (DESIGN.md "Edit log").
//
// Index: the commands · EditCommand · where a command came from (EditSource) ·
//        parsing one log line · serializing · value checks
//
// A command holds no interaction state and no reference into a session: EditSession
// validates and applies it, and records another command as its inverse for undo. Partial
// edits (transform, material) keep only the keys given, applied over the object's current
// value when the command is applied.

#include <cstdint>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <type_traits>
#include <utility>
#include <variant>

#include "solver/scene.h"

namespace penumbra {

// ---------------------------------------------------------------------------------------------
// The commands.

/// {"op":"add","object":{...as in the scene file...}}. The object's id must be unused.
struct AddCommand {
    SceneObject object;
};

/// {"op":"remove","id":ID}
struct RemoveCommand {
    std::string id;
};

/// {"op":"transform","id":ID,"transform":{...}}: the keys given replace the object's current
/// ones (absolute); absent keys keep their current value.
struct TransformCommand {
    std::string id;
    std::optional<Vec3> translate;  ///< metres
    std::optional<Vec3> rotateDeg;  ///< degrees about X, then Y, then Z
    std::optional<Vec3> scale;      ///< non-zero components
    /// The object's transform with the given keys replaced.
    Transform appliedTo(const Transform& current) const;
};

/// A transform edit setting all three keys of `transform` on `id`.
TransformCommand fullTransformCommand(const std::string& id, const Transform& transform);

/// {"op":"move","id":ID,"by":[dx,dy,dz]}: translate += by (metres).
struct MoveCommand {
    std::string id;
    Vec3 by{0.0};
};

/// {"op":"material","id":ID,"material":{...}}: the keys given replace the object's current
/// material values; absent keys keep theirs.
struct MaterialCommand {
    std::string id;
    std::optional<Rgb> reflectance;  ///< [0, 1) per channel
    std::optional<Rgb> emission;     ///< W/m², not negative
    std::optional<bool> twoSided;
    Material appliedTo(const Material& current) const;
};

/// {"op":"select","id":ID}: George et al.: the object leaves the solution (kept in the
/// document) while it is changed; transform and move edits then only update a preview.
struct SelectCommand {
    std::string id;
};

/// {"op":"unselect"}: the selected object rejoins the solution where it now is.
struct UnselectCommand {};

/// {"op":"undo"} / {"op":"redo"}: revert or reapply the last document edit; both redistribute
/// like any other edit.
struct UndoCommand {};
struct RedoCommand {};

/// {"op":"solve","shots":N}: N solver shots (N ≥ 0).
struct SolveCommand {
    int shots = 0;
};

/// {"op":"converge","threshold":EPS}: shoot until unshot energy < EPS × emitted and no
/// redistribution is pending (0 < EPS < 1).
struct ConvergeCommand {
    double threshold = 1e-3;
};

// ---------------------------------------------------------------------------------------------
// EditCommand.

using EditOp = std::variant<AddCommand, RemoveCommand, TransformCommand, MoveCommand,
                            MaterialCommand, SelectCommand, UnselectCommand, UndoCommand,
                            RedoCommand, SolveCommand, ConvergeCommand>;

struct EditCommand {
    EditOp op;
    /// Milliseconds since the session started ("t_ms"), when known.
    std::optional<double> tMs;

    EditCommand() = default;
    /// Any of the commands above converts: `EditCommand c = MoveCommand{"crate", {0.1, 0, 0}};`
    template <typename Op,
              typename = std::enable_if_t<!std::is_same_v<std::decay_t<Op>, EditCommand> &&
                                          std::is_constructible_v<EditOp, Op&&>>>
    EditCommand(Op&& o, std::optional<double> t = std::nullopt)  // NOLINT: commands convert
        : op(std::forward<Op>(o)), tMs(t) {}

    /// The log's "op" name: "add", "remove", ..., "converge".
    const char* opName() const;
    /// The object the command names, or "" (unselect, undo, redo, solve, converge).
    std::string objectId() const;
    /// solve and converge: solver work, not a change of the scene or the selection.
    bool isSolverWork() const;
    /// The command as its log line (without newline).
    std::string toString() const;
};

/// Where a command came from, for error messages: `FILE: line N: KEY: problem`.
struct EditSource {
    std::string file = "edit";  ///< the log file as the user named it, or "edit" for the UI
    int line = 0;               ///< 1-based line in `file`; 0 when not from a file
    /// "line N" (or "" when line is 0), followed by ": KEY" when key is not empty.
    std::string where(const std::string& key = "") const;
};

// ---------------------------------------------------------------------------------------------
// Parsing one log line.

/// Parses one log line. Strict: malformed JSON, a value that is not an object, a missing or
/// unknown "op", an unknown or repeated key, a wrong type, a non-finite number or an invalid
/// value (reflectance ≥ 1, zero scale, negative shots...) throw InputError naming
/// `source.file`, `line N` and the key. An "add" object's material must name a material of
/// `scene` when given (pass nullptr to defer that check to the session); mesh files resolve
/// relative to `meshBaseDir` (the scene file's directory).
EditCommand parseEditCommand(const std::string& line, const EditSource& source,
                             const Scene* scene = nullptr, const std::string& meshBaseDir = "");

/// The same from an already parsed JSON value (repeated keys cannot be detected here).
EditCommand editCommandFromJson(const nlohmann::ordered_json& json, const EditSource& source,
                                const Scene* scene = nullptr, const std::string& meshBaseDir = "");

// ---------------------------------------------------------------------------------------------
// Serializing.

/// The command as a JSON object: "op" first, then its fields, then "t_ms" when set.
/// editCommandFromJson(editCommandToJson(c)) reproduces c exactly (numbers round-trip).
nlohmann::ordered_json editCommandToJson(const EditCommand& command);
/// editCommandToJson(command) on one line, no spaces, no newline.
std::string formatEditCommand(const EditCommand& command);

// ---------------------------------------------------------------------------------------------
// Value checks.

/// Checks the values of a command built in code (the parser runs the same checks): finite
/// numbers, reflectance in [0, 1), emission ≥ 0, non-zero scale, non-empty ids, shots ≥ 0,
/// threshold in (0, 1). Throws InputError naming `source` and the key.
void checkEditValues(const EditCommand& command, const EditSource& source);

}  // namespace penumbra
