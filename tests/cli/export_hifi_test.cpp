// `penumbra export --hifi`: the interpolants' triangles, four per triangle of the mesh, welded
// into a connected surface where the light is continuous (a triangle mesh has about half as
// many vertices as faces; unwelded it would have three times as many).

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>

#include "cli/cli_support.h"

namespace penumbra {
namespace {

namespace fs = std::filesystem;

/// The count of `element NAME N` in a PLY header.
long plyCount(const std::string& ply, const std::string& name) {
    const std::string tag = "element " + name + " ";
    const std::size_t at = ply.find(tag);
    if (at == std::string::npos || at > ply.find("end_header")) return -1;
    return std::stol(ply.substr(at + tag.size()));
}

TEST(ExportHifiCli, FourTrianglesPerInterpolantWeldedWhereTheLightIsContinuous) {
    const fs::path dir =
        fs::temp_directory_path() / ("penumbra_cli_export_hifi_" + std::to_string(::getpid()));
    fs::create_directories(dir);
    const fs::path ply = dir / "lit.ply", report = dir / "report.json";
    const std::string command = std::string("timeout 120 '") + PENUMBRA_EXE + "' export '" +
                                PENUMBRA_SOURCE_DIR + "/scenes/cube-room.json' '" + ply.string() +
                                "' --hifi --converge 0.01 --report '" + report.string() +
                                "' 2> /dev/null";
    ASSERT_EQ(test::runShell(command), 0);
    const std::string text = test::readFile(ply);
    const long faces = plyCount(text, "face"), vertices = plyCount(text, "vertex");
    const nlohmann::json r = nlohmann::json::parse(test::readFile(report));
    const long triangles = r.at("hifi").at("triangles").get<long>();
    ASSERT_GT(triangles, 0);
    EXPECT_EQ(faces, 4 * triangles);
    EXPECT_GT(vertices, 0);
    EXPECT_LT(vertices, faces);
    fs::remove_all(dir);
}

}  // namespace
}  // namespace penumbra
