// InputScript: parsing (one error line naming the file and line for each kind of bad line) and
// playing against a recording EditorControls, tick by tick: a drag's positions one a tick from
// where it began, waits that hold the script until their time or images, marks in order, and
// an object the scene lacks ending the editor with status 2.

#include "ui/input_script.h"

#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "core/input_error.h"
#include "ui/editor_app.h"

namespace penumbra {
namespace {

/// EditorControls that records what the script did (no window, no scene).
class RecordingControls : public EditorControls {
public:
    SessionRunner* runner() override { return nullptr; }
    void select(const std::string& id) override { selected = id; }
    bool beginDrag() override {
        dragging = true;
        return true;
    }
    Transform dragStart() const override { return start; }
    void dragTo(const Transform& to) override { positions.push_back(to.translate); }
    Transform endDrag() override {
        dragging = false;
        ++drops;
        return start;
    }
    std::shared_ptr<const ViewportImage> shownImage() const override { return nullptr; }
    const FrameStats& frameStats() const override { return stats; }
    void resetFrameStats() override { stats = FrameStats{}; }
    int viewportWidth() const override { return 64; }
    int viewportHeight() const override { return 48; }
    int displayDivisor() const override { return 1; }
    ViewMode viewMode() const override { return ViewMode::EdgeAndPoint; }
    const std::string& scenePath() const override { return scene; }
    void quit(int status) override {
        quitted = true;
        exitStatus = status;
    }

    std::string selected, scene;
    bool dragging = false;
    int drops = 0;
    Transform start;
    std::vector<Vec3> positions;
    FrameStats stats;
    bool quitted = false;
    int exitStatus = -1;
};

std::string parseError(const std::string& text) {
    try {
        (void)InputScript::parse(text, "s.txt");
    } catch (const InputError& e) {
        return e.what();
    }
    return "";
}

TEST(InputScript, MalformedLinesAreOneErrorNamingTheFileAndLine) {
    EXPECT_EQ(parseError("wait 1\njump 3\n"), "s.txt: line 2: unknown command 'jump'");
    EXPECT_EQ(parseError("# a comment\n\nselect\n"), "s.txt: line 3: expected select ID");
    EXPECT_EQ(parseError("move 1 2\n"), "s.txt: line 1: expected move DX DY DZ");
    EXPECT_EQ(parseError("move 1 2 x\n"), "s.txt: line 1: 'x' is not a number");
    EXPECT_EQ(parseError("wait nan\n"), "s.txt: line 1: 'nan' is not a number");
    EXPECT_EQ(parseError("wait -1\n"), "s.txt: line 1: wait: a negative value");
    EXPECT_EQ(parseError("wait-images 2 10 3\n"), "s.txt: line 1: expected wait-images N [MAX_S]");
    EXPECT_EQ(parseError("drag now\n"), "s.txt: line 1: 'now' is not a number");
    EXPECT_EQ(parseError("select a # the table\nmove -1 0 0.5\nquit\n"), "");
    try {
        (void)InputScript::load("/nonexistent/script.txt");
        ADD_FAILURE() << "a missing file loads";
    } catch (const InputError& e) {
        EXPECT_EQ(std::string(e.what()), "/nonexistent/script.txt: cannot be read");
    }
}

TEST(InputScript, PlaysADragOnePositionATickAndHoldsAtItsWaits) {
    InputScript script = InputScript::parse(
        "mark start\ndrag\nmove 0.1 0 0\nmove 0.2 0 0\nmove 0.3 0 -1\ndrop\nmark dropped\n"
        "wait 0.5\nwait-images 2 10\nmark end\nquit\n",
        "s.txt");
    std::vector<std::pair<std::string, double>> marks;
    script.onMark = [&](EditorControls&, const std::string& name, double now) {
        marks.emplace_back(name, now);
    };
    RecordingControls editor;
    editor.start.translate = Vec3(1, 2, 3);

    script.tick(editor, 0.0);  // mark, drag, the first position
    ASSERT_EQ(editor.positions.size(), 1u);
    EXPECT_TRUE(editor.dragging);
    EXPECT_TRUE(script.wantsFrames()) << "the gizmo is held";
    EXPECT_LT(glm::length(editor.positions[0] - Vec3(1.1, 2, 3)), 1e-12);
    script.tick(editor, 0.1);
    script.tick(editor, 0.2);
    ASSERT_EQ(editor.positions.size(), 3u);
    EXPECT_LT(glm::length(editor.positions[2] - Vec3(1.3, 2, 2)), 1e-12);
    EXPECT_EQ(script.moves(), 3);
    EXPECT_TRUE(editor.dragging) << "released only at the next tick";

    script.tick(editor, 0.3);  // drop, mark, the wait begins
    EXPECT_FALSE(editor.dragging);
    EXPECT_EQ(editor.drops, 1);
    EXPECT_FALSE(script.wantsFrames());
    script.tick(editor, 0.7);
    EXPECT_EQ(marks.size(), 2u) << "the half second is not over";
    script.tick(editor, 0.8);  // the wait is over; the images wait begins
    script.tick(editor, 0.9);
    EXPECT_TRUE(script.wantsFrames()) << "waiting for images";
    script.shown(editor, nullptr, 0.95);
    script.tick(editor, 1.0);
    EXPECT_EQ(marks.size(), 2u) << "one image of two";
    script.shown(editor, nullptr, 1.05);
    EXPECT_FALSE(editor.quitted);
    script.tick(editor, 1.1);
    ASSERT_EQ(marks.size(), 3u);
    EXPECT_EQ(marks[0].first, "start");
    EXPECT_EQ(marks[1], (std::pair<std::string, double>("dropped", 0.3)));
    EXPECT_EQ(marks[2], (std::pair<std::string, double>("end", 1.1)));
    EXPECT_TRUE(editor.quitted);
    EXPECT_EQ(editor.exitStatus, 0);
    EXPECT_TRUE(script.done());
}

TEST(InputScript, WaitsGiveUpAtTheirLimitAndAMissingObjectEndsTheEditorWithStatus2) {
    InputScript waits = InputScript::parse("wait-images 5 1\nmark after\n", "s.txt");
    bool after = false;
    waits.onMark = [&](EditorControls&, const std::string&, double) { after = true; };
    RecordingControls editor;
    waits.tick(editor, 10.0);
    waits.tick(editor, 10.5);
    EXPECT_FALSE(after);
    waits.tick(editor, 11.0);
    EXPECT_TRUE(after) << "wait-images gives up after its second";

    // No runner: the lighting never settles, and no object is found.
    InputScript lit = InputScript::parse("wait-lit 2\nselect table\nmove 1 0 0\n", "s.txt");
    lit.tick(editor, 0.0);
    lit.tick(editor, 1.0);
    EXPECT_FALSE(editor.quitted);
    lit.tick(editor, 2.5);  // gives up waiting, then the select fails
    EXPECT_TRUE(editor.quitted);
    EXPECT_EQ(editor.exitStatus, 2);
    EXPECT_TRUE(editor.selected.empty());
    EXPECT_TRUE(editor.positions.empty()) << "nothing played after the failure";
    EXPECT_TRUE(lit.done());

    InputScript stray = InputScript::parse("move 1 0 0\n", "s.txt");
    RecordingControls other;
    stray.tick(other, 0.0);
    EXPECT_EQ(other.exitStatus, 2) << "a move without a drag";
}

}  // namespace
}  // namespace penumbra
