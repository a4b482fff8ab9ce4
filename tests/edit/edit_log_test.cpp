// The edit log (DESIGN.md "Edit log"): every op round-trips through its JSON line; a malformed
// line is reported with its line number; a final line cut off by a crash is reported and
// skipped without losing the lines before it; every committed edit is on disk at once.
#include "edit/edit_log.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "core/input_error.h"
#include "edit/edit_command.h"
#include "edit/edit_session.h"
#include "edit/io/scene_io.h"
#include "log_capture.h"
#include "test_scenes.h"

namespace penumbra {
namespace {

namespace fs = std::filesystem;

fs::path tempDir(const std::string& name) {
    fs::path dir =
        fs::temp_directory_path() / ("penumbra_log_" + name + "_" + std::to_string(::getpid()));
    fs::remove_all(dir);
    fs::create_directories(dir);
    return dir;
}

void writeFile(const fs::path& path, const std::string& text) {
    std::ofstream(path, std::ios::binary) << text;
}

/// One command of every op, with awkward values (fractions that need 17 digits).
std::vector<EditCommand> everyOp() {
    SceneObject box;
    box.id = "crate";
    box.shape.type = ShapeType::Box;
    box.shape.size = Vec3(0.4, 0.1 / 3, 0.4);
    box.material = "red";
    box.transform.translate = Vec3(0.1, -0.55, 1.0 / 3);
    box.transform.rotateDeg = Vec3(0, 25, 0);
    SceneObject ball;
    ball.id = "ball";
    ball.shape.type = ShapeType::Sphere;
    ball.shape.radius = 0.3;
    ball.shape.segments = 12;
    ball.material = "white";
    TransformCommand transform;
    transform.id = "crate";
    transform.translate = Vec3(0.5, 0, 0.2);
    transform.scale = Vec3(2.0 / 3, 1, 1);
    MaterialCommand material;
    material.id = "crate";
    material.reflectance = Rgb(0.8, 0.2, 0.2);
    material.emission = Rgb(1e-7, 0, 3.25);
    material.twoSided = true;
    MaterialCommand reflectanceOnly;
    reflectanceOnly.id = "ball";
    reflectanceOnly.reflectance = Rgb(0.1);
    return {
        EditCommand(AddCommand{box}, 12.5),
        AddCommand{ball},
        RemoveCommand{"crate"},
        transform,
        MoveCommand{"crate", {0.1, 0, -1e-3}},
        material,
        reflectanceOnly,
        SelectCommand{"crate"},
        UnselectCommand{},
        UndoCommand{},
        RedoCommand{},
        SolveCommand{200},
        ConvergeCommand{0.001},
    };
}

TEST(EditLog, EveryOpRoundTrips) {
    for (const EditCommand& command : everyOp()) {
        const std::string line = formatEditCommand(command);
        EXPECT_EQ(line.find('\n'), std::string::npos) << line;
        const EditCommand parsed = parseEditCommand(line, EditSource{"test.jsonl", 1});
        EXPECT_EQ(formatEditCommand(parsed), line);
        EXPECT_STREQ(parsed.opName(), command.opName());
        EXPECT_EQ(parsed.objectId(), command.objectId());
        EXPECT_EQ(parsed.tMs, command.tMs) << line;
    }
    // Field by field for the ones with values.
    const auto commands = everyOp();
    auto add =
        std::get<AddCommand>(parseEditCommand(formatEditCommand(commands[0]), EditSource{}).op);
    EXPECT_EQ(add.object.shape.size, Vec3(0.4, 0.1 / 3, 0.4));
    EXPECT_EQ(add.object.transform.translate, Vec3(0.1, -0.55, 1.0 / 3));
    EXPECT_EQ(add.object.material, "red");
    auto t = std::get<TransformCommand>(
        parseEditCommand(formatEditCommand(commands[3]), EditSource{}).op);
    EXPECT_EQ(t.translate, Vec3(0.5, 0, 0.2));
    EXPECT_FALSE(t.rotateDeg.has_value()) << "absent keys stay absent";
    EXPECT_EQ(t.scale, Vec3(2.0 / 3, 1, 1));
    auto m = std::get<MaterialCommand>(
        parseEditCommand(formatEditCommand(commands[5]), EditSource{}).op);
    EXPECT_EQ(m.emission, Rgb(1e-7, 0, 3.25));
    EXPECT_EQ(m.twoSided, true);
    auto r = std::get<MaterialCommand>(
        parseEditCommand(formatEditCommand(commands[6]), EditSource{}).op);
    EXPECT_FALSE(r.emission.has_value());
    EXPECT_FALSE(r.twoSided.has_value());
}

TEST(EditLog, DesignExamplesParse) {
    const char* lines[] = {
        R"({"op":"add","object":{"id":"crate","shape":{"type":"box","size":[0.4,0.4,0.4]},"material":"white"}})",
        R"({"op":"remove","id":"crate"})",
        R"({"op":"transform","id":"crate","transform":{"translate":[0.5,0,0.2]}})",
        R"({"op":"move","id":"crate","by":[0.1,0,0]})",
        R"({"op":"material","id":"crate","material":{"reflectance":[0.8,0.2,0.2]}})",
        R"({"op":"select","id":"crate"})",
        R"({"op":"unselect"})",
        R"({"op":"solve","shots":200})",
        R"({"op":"converge","threshold":0.001})",
        R"({"op":"undo","t_ms":1234})",
        R"({"op":"redo","t_ms":1234.5})",
    };
    for (const char* line : lines) EXPECT_NO_THROW(parseEditCommand(line, EditSource{})) << line;
}

TEST(EditLog, WriterAndReaderRoundTripAFile) {
    const fs::path dir = tempDir("roundtrip");
    const fs::path log = dir / "edits.jsonl";
    {
        EditLogWriter writer(log.string());
        for (const EditCommand& command : everyOp()) writer.append(command);
        EXPECT_EQ(writer.linesWritten(), static_cast<int>(everyOp().size()));
    }
    const auto edits = readEditLog(log.string());
    const auto commands = everyOp();
    ASSERT_EQ(edits.size(), commands.size());
    for (std::size_t i = 0; i < edits.size(); ++i) {
        EXPECT_EQ(edits[i].line, static_cast<int>(i) + 1);
        ASSERT_TRUE(edits[i].command.tMs.has_value()) << "the writer stamps t_ms";
        EXPECT_GE(*edits[i].command.tMs, 0.0);
        EditCommand withoutTime = edits[i].command;
        withoutTime.tMs.reset();
        EditCommand expected = commands[i];
        expected.tMs.reset();
        EXPECT_EQ(formatEditCommand(withoutTime), formatEditCommand(expected));
    }
    // Reopening appends.
    {
        EditLogWriter writer(log.string());
        writer.append(SolveCommand{5});
    }
    EXPECT_EQ(readEditLog(log.string()).size(), commands.size() + 1);
    fs::remove_all(dir);
}

struct Malformed {
    const char* name;
    std::string line;
    std::string key;      ///< expected after "line 2" ("" for none)
    std::string problem;  ///< expected substring
};

TEST(EditLog, MalformedLineReportsItsLineNumberAndKey) {
    const Malformed cases[] = {
        {"syntax", R"({"op":"move","id":"crate" "by":[1,0,0]})", "column", "syntax error"},
        {"not an object", R"(["op","move"])", "", "expected a JSON object"},
        {"missing op", R"({"id":"crate"})", "op", "missing required key"},
        {"unknown op", R"({"op":"teleport","id":"crate"})", "op", "unknown op 'teleport'"},
        {"unknown key", R"({"op":"remove","id":"crate","force":true})", "force",
         "unknown key 'force'"},
        {"repeated key", R"({"op":"remove","id":"crate","id":"box"})", "id", "repeated key"},
        {"wrong type", R"({"op":"move","id":"crate","by":"left"})", "by",
         "expected an array of 3 numbers"},
        {"short vector", R"({"op":"move","id":"crate","by":[1,0]})", "by", "array of 2"},
        {"null in vector", R"({"op":"move","id":"crate","by":[1,null,0]})", "by[1]",
         "expected a number"},
        {"overflow", R"({"op":"move","id":"crate","by":[1e999,0,0]})", "", "overflow"},
        {"id not a string", R"({"op":"select","id":7})", "id", "expected a string"},
        {"empty id", R"({"op":"select","id":""})", "id", "must not be empty"},
        {"fractional shots", R"({"op":"solve","shots":2.5})", "shots", "integer"},
        {"negative shots", R"({"op":"solve","shots":-3})", "shots", "negative"},
        {"threshold", R"({"op":"converge","threshold":0})", "threshold", "(0, 1)"},
        {"bad t_ms", R"({"op":"undo","t_ms":"soon"})", "t_ms", "expected a number"},
        {"transform key", R"({"op":"transform","id":"a","transform":{"shear":[1,0,0]}})",
         "transform.shear", "unknown key 'shear'"},
        {"zero scale", R"({"op":"transform","id":"a","transform":{"scale":[1,0,1]}})",
         "transform.scale", "non-zero"},
        {"reflectance", R"({"op":"material","id":"a","material":{"reflectance":[1,0,0]}})",
         "material.reflectance", "[0, 1)"},
        {"emission", R"({"op":"material","id":"a","material":{"emission":[0,-1,0]}})",
         "material.emission", "negative"},
        {"object", R"({"op":"add","object":{"id":"a","shape":{"type":"cone"},"material":"w"}})",
         "object.shape.type", "unknown shape type"},
        {"object id",
         R"({"op":"add","object":{"shape":{"type":"box","size":[1,1,1]},"material":"w"}})",
         "object.id", "missing required key"},
    };
    const fs::path dir = tempDir("malformed");
    const fs::path log = dir / "edits.jsonl";
    for (const Malformed& m : cases) {
        writeFile(log, "{\"op\":\"solve\",\"shots\":1}\n" + m.line + "\n{\"op\":\"unselect\"}\n");
        try {
            readEditLog(log.string());
            ADD_FAILURE() << m.name << ": accepted " << m.line;
        } catch (const InputError& e) {
            EXPECT_EQ(e.file(), log.string()) << m.name;
            if (m.key == "column")
                EXPECT_EQ(e.where().rfind("line 2, column ", 0), 0u) << m.name << ": " << e.what();
            else
                EXPECT_EQ(e.where(), m.key.empty() ? "line 2" : "line 2: " + m.key)
                    << m.name << ": " << e.what();
            EXPECT_NE(std::string(e.what()).find(m.problem), std::string::npos)
                << m.name << ": " << e.what();
            EXPECT_EQ(std::string(e.what()).find('\n'), std::string::npos);
        }
    }
    fs::remove_all(dir);
}

TEST(EditLog, TruncatedFinalLineIsReportedAndSkipped) {
    const fs::path dir = tempDir("truncated");
    const fs::path log = dir / "edits.jsonl";
    writeFile(log,
              "{\"op\":\"select\",\"id\":\"crate\"}\n\n{\"op\":\"move\",\"id\":\"crate\",\"by\":[0."
              "1,0,0]}\n"
              "{\"op\":\"move\",\"id\":\"cr");
    std::vector<LoggedEdit> edits;
    std::string err;
    {
        test::LogCapture capture;
        edits = readEditLog(log.string());
        err = capture.text();
    }
    ASSERT_EQ(edits.size(), 2u);
    EXPECT_EQ(edits[0].line, 1);
    EXPECT_EQ(edits[1].line, 3) << "blank lines count";
    EXPECT_STREQ(edits[1].command.opName(), "move");
    EXPECT_EQ(std::count(err.begin(), err.end(), '\n'), 1) << err;
    EXPECT_EQ(err.rfind("warning: " + log.string() + ": line 4: truncated", 0), 0u) << err;

    // A complete final line without newline is kept.
    writeFile(log, "{\"op\":\"unselect\"}\n{\"op\":\"solve\",\"shots\":3}");
    {
        test::LogCapture capture;
        EXPECT_EQ(readEditLog(log.string()).size(), 2u);
        EXPECT_EQ(capture.text(), "");
    }

    // A truncated line that is not the last is malformed, not skipped.
    writeFile(log, "{\"op\":\"unselect\"}\n{\"op\":\"solve\",\"sh\n{\"op\":\"undo\"}\n");
    try {
        readEditLog(log.string());
        ADD_FAILURE() << "accepted a malformed middle line";
    } catch (const InputError& e) {
        EXPECT_EQ(e.where().rfind("line 2", 0), 0u) << e.what();
    }

    // Reopening a log that ends in a cut-off line removes it before appending.
    writeFile(log, "{\"op\":\"unselect\"}\n{\"op\":\"solve\",\"sh");
    std::vector<LoggedEdit> reopened;
    {
        test::LogCapture capture;
        {
            EditLogWriter writer(log.string());
            writer.append(UndoCommand{});
        }
        EXPECT_NE(capture.text().find("warning: " + log.string() + ": line 2: truncated"),
                  std::string::npos)
            << capture.text();
    }
    {
        test::LogCapture capture;
        reopened = readEditLog(log.string());
        EXPECT_EQ(capture.text(), "");
    }
    ASSERT_EQ(reopened.size(), 2u);
    EXPECT_STREQ(reopened[1].command.opName(), "undo");
    EXPECT_EQ(reopened[1].line, 2);
    fs::remove_all(dir);
}

TEST(EditLog, EveryCommittedEditIsOnDiskAtOnce) {
    const fs::path dir = tempDir("flush");
    const fs::path log = dir / "edits.jsonl";
    Scene scene = test::emptyScene(1.5, 0.75);
    test::addMaterial(scene, "white", Rgb(0.6));
    test::addMaterial(scene, "lamp", Rgb(0.5), Rgb(10.0));
    test::addClosedRoom(scene, 3.0, "white");
    scene.objects.push_back(test::makeQuad("lamp", 0.6, 0.6, "lamp", {0, 1.49, 0}, {180, 0, 0}));
    EditSession session(scene, SolverOptions{}, "room");
    session.openLog(log.string());

    auto lines = [&] {
        std::ifstream in(log);  // a separate reader while the writer is open
        std::vector<std::string> out;
        for (std::string line; std::getline(in, line);) out.push_back(line);
        return out;
    };
    SceneObject box;
    box.id = "box";
    box.shape.type = ShapeType::Box;
    box.shape.size = Vec3(0.5);
    box.material = "white";
    box.transform.translate = Vec3(0, -1.25, 0);
    session.apply(AddCommand{box});
    ASSERT_EQ(lines().size(), 1u);
    EXPECT_EQ(lines()[0].rfind("{\"op\":\"add\",\"object\":{\"id\":\"box\"", 0), 0u) << lines()[0];
    EXPECT_NE(lines()[0].find("\"t_ms\":"), std::string::npos) << lines()[0];
    session.apply(SolveCommand{4});
    session.apply(MoveCommand{"box", {0.25, 0, 0}});
    ASSERT_EQ(lines().size(), 3u);
    EXPECT_EQ(
        lines()[2].rfind("{\"op\":\"move\",\"id\":\"box\",\"by\":[0.25,0.0,0.0],\"t_ms\":", 0), 0u)
        << lines()[2];
    session.apply(UndoCommand{});
    ASSERT_EQ(lines().size(), 4u);
    EXPECT_EQ(lines()[3].rfind("{\"op\":\"undo\",\"t_ms\":", 0), 0u) << lines()[3];
    // A refused edit writes nothing.
    EXPECT_THROW(session.apply(RemoveCommand{"ghost"}), InputError);
    EXPECT_EQ(lines().size(), 4u);

    // The log replays into the same document.
    const auto edits = readEditLog(log.string());
    EditSession replayed(scene, SolverOptions{}, "room");
    for (const LoggedEdit& e : edits) replayed.apply(e.command, EditSource{log.string(), e.line});
    EXPECT_EQ(sceneToJson(replayed.scene()).dump(), sceneToJson(session.scene()).dump());
    fs::remove_all(dir);
}

}  // namespace
}  // namespace penumbra
