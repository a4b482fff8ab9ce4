// The real `penumbra` executable on bad scene files: exit status 2 and exactly one line on
// stderr, `penumbra: FILE: KEY: what is wrong` (DESIGN.md "Command line"). One case per class
// of bad input; never a crash.

#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "cli/cli_support.h"

namespace {

using penumbra::test::readFile;
using penumbra::test::runShell;
using penumbra::test::writeFile;

namespace fs = std::filesystem;

struct BadInput {
    const char* name;
    std::string scene;    ///< scene file text
    std::string where;    ///< expected key path or "line L, column C" after the file name
    std::string problem;  ///< expected substring of the message
};

void PrintTo(const BadInput& bad, std::ostream* out) { *out << bad.name; }

const char* kTetraOff =
    "OFF\n4 4 0\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n"
    "3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3\n";

std::string sceneWith(const std::string& objects,
                      const std::string& materials = R"("white": {"reflectance": [0.5, 0.5, 0.5]})",
                      const std::string& extra = "") {
    return R"({"format": "penumbra-scene/1", "materials": {)" + materials + R"(}, "objects": [)" +
           objects + "]" + extra + "}";
}

const std::string kBox =
    R"({"id": "a", "shape": {"type": "box", "size": [1, 1, 1]}, "material": "white"})";
const std::string kWhite = R"("white": {"reflectance": [0.5, 0.5, 0.5]})";

std::vector<BadInput> badInputs() {
    return {
        {"UnknownKey", sceneWith(kBox, kWhite, R"(, "lights": [])"), "lights",
         "unknown key 'lights'"},
        {"UnknownNestedKey",
         sceneWith(
             R"({"id": "a", "shape": {"type": "box", "size": [1, 1, 1], "colour": 1}, "material": "white"})"),
         "objects[0].shape.colour", "unknown key 'colour'"},
        {"WrongType",
         sceneWith(
             R"({"id": "a", "shape": {"type": "sphere", "radius": "big"}, "material": "white"})"),
         "objects[0].shape.radius", "expected a number"},
        {"MissingRequiredKey",
         sceneWith(kBox +
                   R"(, {"shape": {"type": "box", "size": [1, 1, 1]}, "material": "white"})"),
         "objects[1].id", "missing required key"},
        {"MissingMeshFile",
         sceneWith(
             R"({"id": "m", "shape": {"type": "mesh", "file": "meshes/none.obj"}, "material": "white"})"),
         "objects[0].shape.file", "does not exist"},
        {"UnreadableMeshFile",
         sceneWith(
             R"({"id": "m", "shape": {"type": "mesh", "file": "garbage.ply"}, "material": "white"})"),
         "objects[0].shape.file", "garbage.ply: line 2: expected 'format"},
        {"MeshWithoutMaterials",
         sceneWith(R"({"id": "m", "shape": {"type": "mesh", "file": "plain.off"}})"),
         "objects[0].material", "carries no materials"},
        {"ReflectanceOutOfRange", sceneWith(kBox, R"("white": {"reflectance": [1.0, 0.5, 0.5]})"),
         "materials.white.reflectance", "must be in [0, 1)"},
        {"NegativeEmission",
         sceneWith(kBox, R"("white": {"reflectance": [0.5, 0.5, 0.5], "emission": [1, -2, 0]})"),
         "materials.white.emission", "must not be negative"},
        {"DuplicateObjectId", sceneWith(kBox + ", " + kBox), "objects[1].id",
         "duplicate object id 'a'"},
        {"DuplicateMaterialName", sceneWith(kBox, kWhite + ", " + kWhite), "materials.white",
         "duplicate material name 'white'"},
        {"UnknownMaterial",
         sceneWith(
             R"({"id": "a", "shape": {"type": "box", "size": [1, 1, 1]}, "material": "red"})"),
         "objects[0].material", "unknown material 'red'"},
        {"NonPositiveSize",
         sceneWith(
             R"({"id": "a", "shape": {"type": "quad", "size": [1, 0]}, "material": "white"})"),
         "objects[0].shape.size", "must be positive"},
        {"NonPositiveRadius",
         sceneWith(
             R"({"id": "a", "shape": {"type": "sphere", "radius": -1}, "material": "white"})"),
         "objects[0].shape.radius", "must be positive"},
        {"NonPositiveHeight",
         sceneWith(
             R"({"id": "a", "shape": {"type": "cylinder", "radius": 1, "height": 0}, "material": "white"})"),
         "objects[0].shape.height", "must be positive"},
        {"TooFewSegments",
         sceneWith(
             R"({"id": "a", "shape": {"type": "cylinder", "radius": 1, "height": 1, "segments": 2}, "material": "white"})"),
         "objects[0].shape.segments", "segments must be between 3 and"},
        {"ZeroScale",
         sceneWith(
             R"({"id": "a", "shape": {"type": "box", "size": [1, 1, 1]}, "material": "white", "transform": {"scale": [1, 1, 0]}})"),
         "objects[0].transform.scale", "non-zero"},
        {"UnsupportedFormat", R"({"format": "penumbra-scene/2", "objects": []})", "format",
         "unsupported format"},
        {"MissingFormat", R"({"objects": []})", "format", "missing required key"},
        {"MalformedJson", "{\n  \"format\": \"penumbra-scene/1\",\n  \"objects\": [\n}\n",
         "line 4, column 1", "syntax error"},
        {"EmptyFile", "  \n", "", "file is empty"},
        {"TopLevelNotObject", "[1, 2]", "", "expected a JSON object"},
    };
}

/// A temp directory name that concurrent runs (several build trees, ctest -j) do not share.
fs::path uniqueTempDir(const std::string& name) {
    return fs::temp_directory_path() / ("penumbra_cli_" + name + "_" + std::to_string(::getpid()));
}

struct RunResult {
    int exitStatus = -1;
    std::string stderrText;
};

/// Runs `penumbra solve SCENE --max-shots 1` with stderr captured (60 s limit).
RunResult runSolve(const fs::path& scene, const fs::path& workDir) {
    const fs::path errPath = workDir / "stderr.txt";
    const std::string command = std::string("timeout 60 '") + PENUMBRA_EXE + "' solve '" +
                                scene.string() + "' --max-shots 1 > /dev/null 2> '" +
                                errPath.string() + "'";
    RunResult result;
    result.exitStatus = runShell(command);
    result.stderrText = readFile(errPath);
    return result;
}

class BadInputCli : public ::testing::TestWithParam<BadInput> {};

TEST_P(BadInputCli, ExitsWithStatus2AndOneLine) {
    const BadInput& bad = GetParam();
    const fs::path dir = uniqueTempDir(bad.name);
    fs::remove_all(dir);
    fs::create_directories(dir);
    std::ofstream(dir / "garbage.ply") << "ply\nthis is not a ply header\n";
    std::ofstream(dir / "plain.off") << kTetraOff;
    const fs::path scene = dir / "bad.json";
    std::ofstream(scene) << bad.scene;

    const RunResult run = runSolve(scene, dir);
    const std::string& err = run.stderrText;
    EXPECT_EQ(run.exitStatus, 2) << "stderr: " << err;
    EXPECT_EQ(std::count(err.begin(), err.end(), '\n'), 1) << "stderr must be one line:\n" << err;
    EXPECT_TRUE(!err.empty() && err.back() == '\n') << err;
    const std::string prefix =
        "penumbra: " + scene.string() + ": " + (bad.where.empty() ? "" : bad.where + ": ");
    EXPECT_EQ(err.compare(0, prefix.size(), prefix), 0)
        << "expected prefix '" << prefix << "' in:\n"
        << err;
    EXPECT_NE(err.find(bad.problem), std::string::npos) << "expected '" << bad.problem << "' in:\n"
                                                        << err;
    fs::remove_all(dir);
}

INSTANTIATE_TEST_SUITE_P(EveryClass, BadInputCli, ::testing::ValuesIn(badInputs()),
                         [](const auto& info) { return std::string(info.param.name); });

TEST(BadInputCliFile, MissingSceneFile) {
    const fs::path dir = uniqueTempDir("missing");
    fs::remove_all(dir);
    fs::create_directories(dir);
    const fs::path scene = dir / "absent.json";
    const RunResult run = runSolve(scene, dir);
    EXPECT_EQ(run.exitStatus, 2) << run.stderrText;
    EXPECT_EQ(std::count(run.stderrText.begin(), run.stderrText.end(), '\n'), 1) << run.stderrText;
    EXPECT_EQ(run.stderrText.rfind("penumbra: " + scene.string() + ": ", 0), 0u) << run.stderrText;
    fs::remove_all(dir);
}

TEST(BadInputCliFile, UnknownExportExtensionIsRefusedBeforeSolving) {
    const fs::path dir = uniqueTempDir("export_ext");
    fs::remove_all(dir);
    fs::create_directories(dir);
    const fs::path errPath = dir / "stderr.txt", out = dir / "lit.xyz";
    // --hifi would mesh and sample for seconds first; the error must come before any of it
    // (nothing written, one line naming the file).
    const std::string command = std::string("timeout 60 '") + PENUMBRA_EXE + "' export '" +
                                PENUMBRA_SOURCE_DIR + "/scenes/cornell-box.json' '" + out.string() +
                                "' --hifi 2> '" + errPath.string() + "'";
    const int status = runShell(command);
    const std::string err = readFile(errPath);
    EXPECT_EQ(status, 2) << err;
    EXPECT_EQ(std::count(err.begin(), err.end(), '\n'), 1) << err;
    EXPECT_NE(err.find(out.string() + ": unknown extension '.xyz'"), std::string::npos) << err;
    EXPECT_EQ(err.find("shots"), std::string::npos) << err;  // no solve ran
    EXPECT_FALSE(fs::exists(out));
    fs::remove_all(dir);
}

}  // namespace
