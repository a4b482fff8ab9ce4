#include "ui/input_script.h"

#include <cmath>
#include <fstream>
#include <iostream>
#include <sstream>

#include "core/input_error.h"
#include "ui/session_runner.h"

namespace penumbra {

namespace {

struct Grammar {
    const char* verb;
    bool takesName;  ///< a word first (select's id, mark's name)
    int minNumbers;  ///< numbers after it
    int maxNumbers;
    const char* usage;
};

constexpr Grammar kGrammar[] = {
    {"wait-lit", false, 0, 1, "wait-lit [MAX_S]"},
    {"select", true, 0, 0, "select ID"},
    {"wait-images", false, 1, 2, "wait-images N [MAX_S]"},
    {"drag", false, 0, 0, "drag"},
    {"move", false, 3, 3, "move DX DY DZ"},
    {"drop", false, 0, 0, "drop"},
    {"wait", false, 1, 1, "wait S"},
    {"wait-settled", false, 0, 1, "wait-settled [MAX_S]"},
    {"mark", true, 0, 0, "mark NAME"},
    {"quit", false, 0, 0, "quit"},
};

}  // namespace

InputScript InputScript::parse(const std::string& text, const std::string& source) {
    InputScript script;
    script.mSource = source;
    std::istringstream lines(text);
    std::string raw;
    int number = 0;
    while (std::getline(lines, raw)) {
        ++number;
        const std::string line = raw.substr(0, raw.find('#'));
        std::istringstream words(line);
        Command c;
        c.line = number;
        if (!(words >> c.verb)) continue;  // blank or comment
        const std::string where = "line " + std::to_string(number);
        const Grammar* g = nullptr;
        for (const Grammar& candidate : kGrammar)
            if (c.verb == candidate.verb) g = &candidate;
        if (!g) throw InputError(source, where, "unknown command '" + c.verb + "'");
        if (g->takesName && !(words >> c.name))
            throw InputError(source, where, std::string("expected ") + g->usage);
        std::string word;
        while (words >> word) {
            std::size_t used = 0;
            double v = 0;
            try {
                v = std::stod(word, &used);
            } catch (const std::exception&) {
                used = 0;
            }
            if (used != word.size() || !std::isfinite(v))
                throw InputError(source, where, "'" + word + "' is not a number");
            c.values.push_back(v);
        }
        const int n = static_cast<int>(c.values.size());
        if (n < g->minNumbers || n > g->maxNumbers)
            throw InputError(source, where, std::string("expected ") + g->usage);
        for (double v : c.values)
            if (v < 0 && c.verb != "move")
                throw InputError(source, where, c.verb + ": a negative value");
        script.mCommands.push_back(std::move(c));
    }
    return script;
}

InputScript InputScript::load(const std::string& path) {
    std::ifstream in(path);
    if (!in) throw InputError(path, "", "cannot be read");
    std::ostringstream text;
    text << in.rdbuf();
    return parse(text.str(), path);
}

void InputScript::shown(EditorControls&, const std::shared_ptr<const ViewportImage>&, double) {
    ++mImages;
}

bool InputScript::wantsFrames() const { return mHolding || mWaitingImages; }

void InputScript::tick(EditorControls& editor, double now) {
    while (mNext < mCommands.size()) {
        const Command& c = mCommands[mNext];
        if (!mStarted) {
            mStarted = true;
            mStartedAt = now;
            mImagesAtStart = mImages;
        }
        if (!step(c, editor, now)) return;
        mStarted = false;
        ++mNext;
        // One gizmo position a tick, as a pointer moves; quit ends the tick.
        if (c.verb == "move" || c.verb == "quit") return;
    }
}

bool InputScript::step(const Command& c, EditorControls& editor, double now) {
    SessionRunner* runner = editor.runner();
    const double waited = now - mStartedAt;
    auto warn = [&](const std::string& what) {
        std::cerr << "penumbra-editor: " << mSource << ": line " << c.line << ": " << what << "\n";
    };
    auto fail = [&](const std::string& what) {
        warn(what);
        mNext = mCommands.size();
        editor.quit(2);
        return false;
    };
    if (c.verb == "wait-lit" || c.verb == "wait-settled") {
        const double max = c.values.empty() ? (c.verb == "wait-lit" ? 120.0 : 60.0) : c.values[0];
        const bool lit = runner && runner->quiescent();
        const bool settled =
            lit && (c.verb == "wait-lit" ||
                    (editor.shownImage() && editor.shownImage() == runner->image()));
        if (settled) return true;
        if (waited < max) return false;
        warn(std::string(c.verb == "wait-lit" ? "not lit" : "not settled") + " after " +
             std::to_string(static_cast<int>(max)) + " s");
        return true;
    }
    if (c.verb == "select") {
        const auto doc = runner ? runner->document() : nullptr;
        if (!doc || !doc->find(c.name)) return fail("no object '" + c.name + "'");
        editor.select(c.name);
        return true;
    }
    if (c.verb == "wait-images") {
        const double max = c.values.size() > 1 ? c.values[1] : 10.0;
        mWaitingImages = mImages - mImagesAtStart < static_cast<long>(c.values[0]) && waited < max;
        return !mWaitingImages;
    }
    if (c.verb == "drag") {
        if (!editor.beginDrag()) return fail("drag: nothing selected");
        mHolding = true;
        mMoves = 0;
        return true;
    }
    if (c.verb == "move") {
        if (!mHolding) return fail("move: no drag");
        Transform t = editor.dragStart();
        t.translate += Vec3(c.values[0], c.values[1], c.values[2]);
        editor.dragTo(t);
        ++mMoves;
        return true;
    }
    if (c.verb == "drop") {
        if (!mHolding) return fail("drop: no drag");
        (void)editor.endDrag();
        mHolding = false;
        return true;
    }
    if (c.verb == "wait") return waited >= c.values[0];
    if (c.verb == "mark") {
        if (onMark) onMark(editor, c.name, now);
        return true;
    }
    if (c.verb == "quit") {
        editor.quit(0);
        return true;
    }
    return true;
}

}  // namespace penumbra
