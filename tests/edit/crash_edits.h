#pragma once
// The crash-safety test's session (tests/edit/crash_safety_test.cpp, tests/edit/crash_child.cpp):
// an endless, deterministic sequence of edits over makeLitRoom, with every op of the log, a
// drag among them, and a save after each box is added.

#include <string>

#include "edit/edit_command.h"
#include "test_scenes.h"

namespace penumbra::test {

/// Edits per round; round k (1-based) adds "box-k", so a save after it holds box-1 … box-k.
constexpr int kCrashRound = 8;

inline std::string crashBoxId(int round) { return "box-" + std::to_string(round); }

/// Edit i (1-based) of the session.
inline EditCommand crashEdit(int i) {
    const int round = (i - 1) / kCrashRound + 1;
    const int step = (i - 1) % kCrashRound;
    const std::string box = crashBoxId(round);
    // Boxes on a 4 × 4 grid over the floor, each new one elsewhere.
    const int cell = (round * 7) % 16;
    const Vec3 at(-1.1 + 0.7 * (cell % 4), -1.4, -1.1 + 0.7 * (cell / 4));
    switch (step) {
        case 0: {
            SceneObject o;
            o.id = box;
            o.shape.type = ShapeType::Box;
            o.shape.size = Vec3(0.2, 0.2, 0.2);
            o.material = round % 2 ? "red" : "white";
            o.transform.translate = at;
            return AddCommand{o};
        }
        case 1:
            return SolveCommand{3};
        case 2:
            return MoveCommand{box, {0.05, 0.0, -0.05}};
        case 3:
            return SelectCommand{"slab"};
        case 4:
            return MoveCommand{"slab", {0.05 * (round % 3), 0.0, 0.02}};
        case 5:
            return MoveCommand{"slab", {-0.05 * (round % 3), 0.0, -0.02}};
        case 6:
            return UnselectCommand{};
        default: {
            MaterialCommand m;
            m.id = box;
            m.reflectance = Rgb(0.1 * (round % 8), 0.5, 0.3);
            return m;
        }
    }
}

}  // namespace penumbra::test
