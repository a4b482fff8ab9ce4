// `penumbra replay` end to end (DESIGN.md "Command line"): the real executable on a small room
// and an edit log. Report fields per line, bit-identical reruns, --check against a golden,
// exit 2 with one line for an unknown id, and a truncated final line that is skipped.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>

#include "cli/cli_support.h"

namespace {

using penumbra::test::readFile;
using penumbra::test::runShell;
using penumbra::test::writeFile;

namespace fs = std::filesystem;
using nlohmann::json;

/// A closed 3 m room with a ceiling lamp and a slab (about 450 elements): fast to solve.
const char* kRoom = R"({
  "format": "penumbra-scene/1",
  "settings": {"patch_size": 0.75, "element_size": 0.375},
  "materials": {
    "white": {"reflectance": [0.6, 0.6, 0.6]},
    "red": {"reflectance": [0.7, 0.2, 0.15]},
    "lamp": {"reflectance": [0.5, 0.5, 0.5], "emission": [12, 11, 9]}
  },
  "objects": [
    {"id": "floor", "shape": {"type": "quad", "size": [3, 3]}, "material": "white", "transform": {"translate": [0, -1.5, 0]}},
    {"id": "ceiling", "shape": {"type": "quad", "size": [3, 3]}, "material": "white", "transform": {"translate": [0, 1.5, 0], "rotate_deg": [180, 0, 0]}},
    {"id": "back", "shape": {"type": "quad", "size": [3, 3]}, "material": "white", "transform": {"translate": [0, 0, -1.5], "rotate_deg": [90, 0, 0]}},
    {"id": "front", "shape": {"type": "quad", "size": [3, 3]}, "material": "white", "transform": {"translate": [0, 0, 1.5], "rotate_deg": [-90, 0, 0]}},
    {"id": "right", "shape": {"type": "quad", "size": [3, 3]}, "material": "white", "transform": {"translate": [1.5, 0, 0], "rotate_deg": [0, 0, 90]}},
    {"id": "left", "shape": {"type": "quad", "size": [3, 3]}, "material": "white", "transform": {"translate": [-1.5, 0, 0], "rotate_deg": [0, 0, -90]}},
    {"id": "lamp", "shape": {"type": "quad", "size": [0.6, 0.6]}, "material": "lamp", "transform": {"translate": [0, 1.49, 0], "rotate_deg": [180, 0, 0]}},
    {"id": "slab", "shape": {"type": "box", "size": [1.2, 0.1, 0.8]}, "material": "white", "transform": {"translate": [0.2, -0.8, 0.1]}}
  ]
}
)";

/// Every op, a drag, undo and redo.
const char* kLog =
    R"({"op":"add","object":{"id":"crate","shape":{"type":"box","size":[0.4,0.4,0.4]},"material":"red","transform":{"translate":[0.1,-0.55,0]}},"t_ms":10}
{"op":"solve","shots":5}
{"op":"move","id":"crate","by":[-0.6,-0.75,0.3]}
{"op":"transform","id":"crate","transform":{"rotate_deg":[0,30,0]}}
{"op":"material","id":"slab","material":{"reflectance":[0.3,0.5,0.7]}}
{"op":"select","id":"crate"}
{"op":"move","id":"crate","by":[0.3,0,0]}
{"op":"move","id":"crate","by":[0.3,0,0]}
{"op":"unselect"}
{"op":"undo"}
{"op":"redo"}
{"op":"remove","id":"crate"}
{"op":"converge","threshold":0.01}
)";
constexpr int kLogLines = 13;

struct RunResult {
    int exitStatus = -1;
    std::string out, err;
};

class ReplayCli : public ::testing::Test {
protected:
    void SetUp() override {
        const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
        mDir = fs::temp_directory_path() /
               (std::string("penumbra_replay_") + info->name() + "_" + std::to_string(::getpid()));
        fs::remove_all(mDir);
        fs::create_directories(mDir);
        writeFile(scene(), kRoom);
        writeFile(log(), kLog);
    }
    void TearDown() override { fs::remove_all(mDir); }

    fs::path scene() const { return mDir / "room.json"; }
    fs::path log() const { return mDir / "edits.jsonl"; }
    fs::path path(const std::string& name) const { return mDir / name; }

    /// Runs `penumbra replay ARGS` with stdout and stderr captured (120 s limit).
    RunResult replay(const std::string& args) const {
        const fs::path out = mDir / "stdout.txt", err = mDir / "stderr.txt";
        const std::string command = std::string("timeout 120 '") + PENUMBRA_EXE + "' replay " +
                                    args + " > '" + out.string() + "' 2> '" + err.string() + "'";
        RunResult run;
        run.exitStatus = runShell(command);
        run.out = readFile(out);
        run.err = readFile(err);
        return run;
    }
    std::string quoted(const fs::path& p) const {
        std::string q = "'";
        q += p.string();
        q += "'";
        return q;
    }
    std::string sceneAndLog(const fs::path& logPath) const {
        return quoted(scene()) + " " + quoted(logPath) + " --converge 1e-2 ";
    }

    fs::path mDir;
};

/// The report without wall-clock fields ("ms", "seconds", and the settling estimate's
/// "estimate_ms", "estimate_seconds"), which vary between runs.
json withoutTimes(json j) {
    if (j.is_object()) {
        for (const char* key : {"ms", "seconds", "estimate_ms", "estimate_seconds"}) j.erase(key);
        for (auto& [key, value] : j.items()) value = withoutTimes(value);
    } else if (j.is_array()) {
        for (auto& value : j) value = withoutTimes(value);
    }
    return j;
}

int lineCount(const std::string& text) {
    return static_cast<int>(std::count(text.begin(), text.end(), '\n'));
}

TEST_F(ReplayCli, ReportHasOneEntryPerLineWithTheFields) {
    writeFile(path("points.txt"), "0 -1.5 0 0 1 0\n# a comment\n0.2 -0.74 0.1 0 1 0\n");
    const RunResult run =
        replay(sceneAndLog(log()) + "--budget-shots 3 --reference --report " +
               quoted(path("report.json")) + " --save-scene " + quoted(path("edited.json")) +
               " --export " + quoted(path("lit.ply")) + " --points " + quoted(path("points.txt")));
    ASSERT_EQ(run.exitStatus, 0) << run.err;
    const json report = json::parse(readFile(path("report.json")));
    for (const char* key : {"shots", "rays", "seconds", "unshot_fraction", "elements", "patches"})
        EXPECT_TRUE(report.contains(key)) << key;
    ASSERT_EQ(report["edits"].size(), static_cast<std::size_t>(kLogLines));
    const char* ops[] = {"add",  "solve",    "move", "transform", "material", "select",  "move",
                         "move", "unselect", "undo", "redo",      "remove",   "converge"};
    for (int i = 0; i < kLogLines; ++i) {
        const json& e = report["edits"][i];
        EXPECT_EQ(e["line"], i + 1);
        EXPECT_EQ(e["op"], ops[i]);
        for (const char* key : {"shots", "rays", "ms", "checksum", "error_rms", "error_top1",
                                "error_estimate", "estimate_ms", "estimate_coverage"})
            EXPECT_TRUE(e.contains(key)) << "line " << i + 1 << ": " << key;
        EXPECT_GE(e["error_rms"].get<double>(), 0.0);
        EXPECT_GE(e["error_estimate"].get<double>(), 0.0);
        if (e["op"] != "solve" && e["op"] != "converge") {
            EXPECT_GE(e["shots"].get<int>(), 3) << "the budget is spent after every edit line";
        }
    }
    EXPECT_EQ(report["edits"][1]["shots"], 5);
    // Converged at the end: close to the from-scratch reference.
    EXPECT_LT(report["edits"][kLogLines - 1]["error_rms"].get<double>(), 0.02);

    // --points: one line of three numbers per point; --export and --save-scene files.
    EXPECT_EQ(lineCount(run.out), 2) << run.out;
    std::istringstream points(run.out);
    double r, g, b;
    ASSERT_TRUE(points >> r >> g >> b) << run.out;
    EXPECT_GT(r, 0.0);
    EXPECT_TRUE(fs::exists(path("lit.ply")));
    const json edited = json::parse(readFile(path("edited.json")));
    EXPECT_EQ(edited["objects"].size(), 8u) << "crate removed at the end";
    bool slabEdited = false;
    for (const json& o : edited["objects"])
        if (o["id"] == "slab")
            slabEdited = edited["materials"][o["material"].get<std::string>()]["reflectance"] ==
                         json::array({0.3, 0.5, 0.7});
    EXPECT_TRUE(slabEdited) << edited.dump();
    EXPECT_EQ(edited["materials"]["white"]["reflectance"], json::array({0.6, 0.6, 0.6}));
}

TEST_F(ReplayCli, ReferencesConvergeToReferenceEpsAndAgreeWithATighterOne) {
    // The references solve as the session does (stochastic tail): one converged loosely and
    // one ten times tighter describe the same lighting, and the converged end of the log is
    // close to both.
    auto lastError = [&](const std::string& eps) {
        const std::string report = path("ref-" + eps + ".json");
        const RunResult run = replay(sceneAndLog(log()) + "--reference --reference-eps " + eps +
                                     " --report " + quoted(report));
        EXPECT_EQ(run.exitStatus, 0) << run.err;
        const json j = json::parse(readFile(report));
        EXPECT_DOUBLE_EQ(j["reference_eps"].get<double>(), std::stod(eps));
        return j["edits"][kLogLines - 1]["error_rms"].get<double>();
    };
    const double loose = lastError("0.01"), tight = lastError("0.001");
    EXPECT_LT(tight, 0.02);
    EXPECT_LT(loose, 0.03);
    EXPECT_GT(loose, 0.0);
    // A bad value is refused with one line.
    const RunResult bad = replay(sceneAndLog(log()) + "--reference --reference-eps 2");
    EXPECT_EQ(bad.exitStatus, 2);
    EXPECT_EQ(lineCount(bad.err), 1) << bad.err;
}

TEST_F(ReplayCli, SameSeedAndThreadsGiveBitIdenticalReports) {
    const std::string args = sceneAndLog(log()) + "--budget-shots 2 --seed 7 --threads 2 ";
    const RunResult a = replay(args + "--report " + quoted(path("a.json")));
    const RunResult b = replay(args + "--report " + quoted(path("b.json")));
    ASSERT_EQ(a.exitStatus, 0) << a.err;
    ASSERT_EQ(b.exitStatus, 0) << b.err;
    const json ja = withoutTimes(json::parse(readFile(path("a.json"))));
    const json jb = withoutTimes(json::parse(readFile(path("b.json"))));
    EXPECT_EQ(ja["edits"].size(), static_cast<std::size_t>(kLogLines));
    EXPECT_EQ(ja.dump(), jb.dump());
}

TEST_F(ReplayCli, CheckAgainstAGoldenReport) {
    const std::string args = sceneAndLog(log()) + "--budget-shots 2 ";
    const RunResult first = replay(args + "--report " + quoted(path("golden.json")));
    ASSERT_EQ(first.exitStatus, 0) << first.err;

    const RunResult same = replay(args + "--check " + quoted(path("golden.json")));
    EXPECT_EQ(same.exitStatus, 0) << same.err;

    // A changed checksum on line 4 is named.
    json golden = json::parse(readFile(path("golden.json")));
    golden["edits"][3]["checksum"] = golden["edits"][3]["checksum"].get<double>() * (1 + 1e-6);
    writeFile(path("changed.json"), golden.dump(2));
    const RunResult changed = replay(args + "--check " + quoted(path("changed.json")));
    EXPECT_EQ(changed.exitStatus, 1) << changed.err;
    EXPECT_EQ(lineCount(changed.err), 1) << changed.err;
    EXPECT_NE(changed.err.find("line 4 (transform crate)"), std::string::npos) << changed.err;
    EXPECT_NE(changed.err.find("checksum"), std::string::npos) << changed.err;
    // --tolerance admits it (a floating-point difference is no regression); a tighter one not.
    const RunResult tolerated =
        replay(args + "--check " + quoted(path("changed.json")) + " --tolerance 1e-5");
    EXPECT_EQ(tolerated.exitStatus, 0) << tolerated.err;
    const RunResult tighter =
        replay(args + "--check " + quoted(path("changed.json")) + " --tolerance 1e-7");
    EXPECT_EQ(tighter.exitStatus, 1) << tighter.err;
    EXPECT_NE(tighter.err.find("relative tolerance 1e-07"), std::string::npos) << tighter.err;

    // Per object: the report's sums add up to the checksum, and a check that fails on a
    // checksum names the objects whose lighting changed, with the relative change.
    const json original = json::parse(readFile(path("golden.json")));
    for (const json& e : original["edits"]) {
        double sum = 0;
        for (const auto& [id, value] : e["objects"].items()) sum += value.get<double>();
        EXPECT_NEAR(sum, e["checksum"].get<double>(), 1e-9 * e["checksum"].get<double>())
            << "line " << e["line"];
    }
    ASSERT_TRUE(golden["edits"][3]["objects"].contains("crate"));
    golden["edits"][3]["objects"]["crate"] =
        golden["edits"][3]["objects"]["crate"].get<double>() * 1.1;
    writeFile(path("changed.json"), golden.dump(2));
    const RunResult named = replay(args + "--check " + quoted(path("changed.json")));
    EXPECT_EQ(named.exitStatus, 1) << named.err;
    EXPECT_EQ(lineCount(named.err), 1) << named.err;
    EXPECT_NE(named.err.find("; lighting changed on crate -9.1%"), std::string::npos) << named.err;

    // So are different shots, and the first difference wins.
    golden["edits"][1]["shots"] = 6;
    writeFile(path("changed.json"), golden.dump(2));
    const RunResult shots = replay(args + "--check " + quoted(path("changed.json")));
    EXPECT_EQ(shots.exitStatus, 1) << shots.err;
    EXPECT_EQ(lineCount(shots.err), 1) << shots.err;
    EXPECT_NE(shots.err.find("line 2 (solve): shots: 5 here, 6 in the golden report"),
              std::string::npos)
        << shots.err;
}

TEST_F(ReplayCli, UnknownIdExitsWith2AndOneLine) {
    writeFile(path("bad.jsonl"),
              "{\"op\":\"solve\",\"shots\":2}\n{\"op\":\"move\",\"id\":\"ghost\",\"by\":[1,0,0]}\n"
              "{\"op\":\"solve\",\"shots\":2}\n");
    const RunResult run =
        replay(sceneAndLog(path("bad.jsonl")) + "--report " + quoted(path("report.json")));
    EXPECT_EQ(run.exitStatus, 2) << run.err;
    EXPECT_EQ(lineCount(run.err), 1) << run.err;
    EXPECT_EQ(run.err,
              "penumbra: " + path("bad.jsonl").string() + ": line 2: id: unknown object 'ghost'\n");
    EXPECT_FALSE(fs::exists(path("report.json")));

    writeFile(path("malformed.jsonl"), "{\"op\":\"solve\",\"shots\":2}\n{\"op\":\"jump\"}\n");
    const RunResult malformed = replay(sceneAndLog(path("malformed.jsonl")));
    EXPECT_EQ(malformed.exitStatus, 2) << malformed.err;
    EXPECT_EQ(lineCount(malformed.err), 1) << malformed.err;
    EXPECT_EQ(
        malformed.err.rfind(
            "penumbra: " + path("malformed.jsonl").string() + ": line 2: op: unknown op 'jump'", 0),
        0u)
        << malformed.err;
}

TEST_F(ReplayCli, TruncatedFinalLineStillReplaysTheEarlierLines) {
    writeFile(path("crashed.jsonl"),
              "{\"op\":\"add\",\"object\":{\"id\":\"crate\",\"shape\":{\"type\":\"box\",\"size\":"
              "[0.4,0.4,0.4]},\"material\":\"red\"}}\n{\"op\":\"solve\",\"shots\":3}\n"
              "{\"op\":\"move\",\"id\":\"crate\",\"by\":[0.1,");
    const RunResult run =
        replay(sceneAndLog(path("crashed.jsonl")) + "--report " + quoted(path("report.json")));
    ASSERT_EQ(run.exitStatus, 0) << run.err;
    // One warning line (core/log.h: "penumbra warning: [TIME] ...").
    EXPECT_NE(run.err.find("penumbra warning: "), std::string::npos) << run.err;
    EXPECT_NE(run.err.find(path("crashed.jsonl").string() + ": line 3: truncated"),
              std::string::npos)
        << run.err;
    const json report = json::parse(readFile(path("report.json")));
    ASSERT_EQ(report["edits"].size(), 2u);
    EXPECT_EQ(report["edits"][0]["op"], "add");
    EXPECT_EQ(report["edits"][1]["op"], "solve");
}

}  // namespace
