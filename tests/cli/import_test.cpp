// `penumbra` on scenes made elsewhere: an OBJ + MTL scene in centimetres solves with the
// emitted power its lamp's Ke gives (pi x Ke x area, the closed form), saves as a Penumbra
// scene that solves the same, and a broken GLB exits 2 with one line naming the file.

#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <nlohmann/json.hpp>

#include "cli_support.h"
#include "render/image.h"

namespace penumbra {
namespace {

namespace fs = std::filesystem;

fs::path freshDir(const std::string& name) {
    const fs::path dir =
        fs::temp_directory_path() / ("penumbra_cli_import_" + name + "_" + std::to_string(::getpid()));
    fs::remove_all(dir);
    fs::create_directories(dir);
    return dir;
}

std::string exe() { return std::string("timeout 120 '") + PENUMBRA_EXE + "' "; }

TEST(ImportCli, AnObjSceneInCentimetresSolvesWithItsLampsPowerAndSavesAsAPenumbraScene) {
    const fs::path dir = freshDir("obj");
    test::writeFile(dir / "room.mtl", "newmtl floor\nKd 0.5 0.5 0.5\nnewmtl lamp\nKd 0 0 0\nKe 2 2 2\n");
    // A 2 m floor and a 20 cm lamp 1.5 m above it facing down, in centimetres.
    test::writeFile(dir / "room.obj",
                    "mtllib room.mtl\n"
                    "v -100 0 -100\nv -100 0 100\nv 100 0 100\nv 100 0 -100\n"
                    "v -10 150 -10\nv 10 150 -10\nv 10 150 10\nv -10 150 10\n"
                    "o floor\nusemtl floor\nf 1 2 3 4\n"
                    "o lamp\nusemtl lamp\nf 5 6 7 8\n");
    const std::string run = exe() + "solve '" + (dir / "room.obj").string() +
                            "' --units cm --max-shots 5 --save-scene '" + (dir / "room.json").string() +
                            "' --report '" + (dir / "r.json").string() + "' 2> '" +
                            (dir / "err.txt").string() + "'";
    ASSERT_EQ(test::runShell(run), 0) << test::readFile(dir / "err.txt");
    const auto report = nlohmann::json::parse(test::readFile(dir / "r.json"));
    // Emission pi x Ke over 0.04 m^2, summed over the three channels (the report's measure).
    const double expected = 3 * M_PI * 2.0 * 0.2 * 0.2;
    EXPECT_NEAR(report["emitted_energy_w"].get<double>(), expected, 1e-6 * expected);

    ASSERT_TRUE(fs::exists(dir / "room.json"));
    ASSERT_TRUE(fs::exists(dir / "room-meshes" / "floor.obj"));
    const std::string again = exe() + "solve '" + (dir / "room.json").string() + "' --max-shots 5 --report '" +
                              (dir / "r2.json").string() + "' 2> '" + (dir / "err2.txt").string() +
                              "'";
    ASSERT_EQ(test::runShell(again), 0) << test::readFile(dir / "err2.txt");
    const auto report2 = nlohmann::json::parse(test::readFile(dir / "r2.json"));
    EXPECT_NEAR(report2["emitted_energy_w"].get<double>(), expected, 1e-6 * expected);
    fs::remove_all(dir);
}

TEST(ImportCli, TheBundledGltfStudioSolvesAndRendersFromItsCamera) {
    // scenes/gltf/studio.gltf (written by make_studio.py beside it) is laid out as Blender's
    // exporter does: a collection node, TRS and matrix nodes, two chairs instancing one mesh,
    // an emissive panel, a point light on its own node, a camera.
    const fs::path dir = freshDir("studio");
    const std::string scene = std::string(PENUMBRA_SOURCE_DIR) + "/scenes/gltf/studio.gltf";
    const std::string save = exe() + "solve '" + scene + "' --max-shots 1 --save-scene '" +
                             (dir / "studio.json").string() + "' 2> '" +
                             (dir / "err.txt").string() + "'";
    ASSERT_EQ(test::runShell(save), 0) << test::readFile(dir / "err.txt");
    const auto json = nlohmann::json::parse(test::readFile(dir / "studio.json"));
    std::vector<std::string> ids;
    for (const auto& o : json["objects"]) ids.push_back(o["id"].get<std::string>());
    EXPECT_EQ(ids, (std::vector<std::string>{"Room", "Table", "Chair", "Chair.001", "Panel",
                                             "light-Bulb"}));
    EXPECT_EQ(json["objects"][2]["material"], "Fabric");
    EXPECT_EQ(json["objects"][3]["material"], "Fabric");
    EXPECT_TRUE(json["cameras"].contains("Camera"));
    EXPECT_TRUE(json["materials"]["PanelLight"].contains("emission"));

    const fs::path png = dir / "studio.png";
    const std::string render = exe() + "render '" + scene + "' --camera Camera --max-shots 60 " +
                               "--width 96 --height 64 --out '" + png.string() + "' 2> '" +
                               (dir / "err2.txt").string() + "'";
    ASSERT_EQ(test::runShell(render), 0) << test::readFile(dir / "err2.txt");
    const Image image = readPng(png.string());
    ASSERT_EQ(image.width, 96);
    double mean = 0;
    for (int y = 0; y < image.height; ++y)
        for (int x = 0; x < image.width; ++x) mean += luminance(image.at(x, y));
    mean /= image.width * image.height;
    EXPECT_GT(mean, 0.1) << "the room is lit";
    EXPECT_LT(mean, 0.95) << "not washed out";
    fs::remove_all(dir);
}

TEST(ImportCli, TheRoomBlenderExportedSolvesWithItsPanelsAndBulbsPowerAndRendersLit) {
    // scenes/gltf/blender-room.glb: made in Blender 3.4.1 by scripts/blender/make_scene.py.
    // Emitted power: the panel's π × 8 × (1, 0.9, 0.75) W/m² over 0.6 m² and the 25 W bulb
    // × (1, 0.8, 0.6), summed over R, G, B (the report's measure).
    const fs::path dir = freshDir("blender");
    const std::string scene = std::string(PENUMBRA_SOURCE_DIR) + "/scenes/gltf/blender-room.glb";
    const std::string solve = exe() + "solve '" + scene + "' --max-shots 40 --report '" +
                              (dir / "r.json").string() + "' 2> '" + (dir / "err.txt").string() +
                              "'";
    ASSERT_EQ(test::runShell(solve), 0) << test::readFile(dir / "err.txt");
    EXPECT_EQ(test::readFile(dir / "err.txt").find("warning"), std::string::npos)
        << test::readFile(dir / "err.txt");
    const auto report = nlohmann::json::parse(test::readFile(dir / "r.json"));
    const double expected = M_PI * 8.0 * 0.6 * (1.0 + 0.9 + 0.75) + 25.0 * (1.0 + 0.8 + 0.6);
    EXPECT_NEAR(report["emitted_energy_w"].get<double>(), expected, 1e-5 * expected);
    EXPECT_LT(report["unshot_fraction"].get<double>(), 1.0);

    const fs::path png = dir / "room.png";
    const std::string render = exe() + "render '" + scene + "' --camera Camera --max-shots 40 " +
                               "--width 64 --height 48 --out '" + png.string() + "' 2> '" +
                               (dir / "err2.txt").string() + "'";
    ASSERT_EQ(test::runShell(render), 0) << test::readFile(dir / "err2.txt");
    const Image image = readPng(png.string());
    ASSERT_EQ(image.width, 64);
    double mean = 0;
    for (int y = 0; y < image.height; ++y)
        for (int x = 0; x < image.width; ++x) mean += luminance(image.at(x, y));
    mean /= image.width * image.height;
    EXPECT_GT(mean, 0.1) << "the room is lit";
    EXPECT_LT(mean, 0.95) << "not washed out";
    fs::remove_all(dir);
}

TEST(ImportCli, ABrokenGlbExitsWith2AndOneLineNamingIt) {
    const fs::path dir = freshDir("glb");
    const fs::path glb = dir / "broken.glb";
    test::writeFile(glb, std::string("glTF\x02\x00\x00\x00", 8));
    const std::string run = exe() + "render '" + glb.string() + "' --out '" +
                            (dir / "x.png").string() + "' > /dev/null 2> '" +
                            (dir / "err.txt").string() + "'";
    EXPECT_EQ(test::runShell(run), 2);
    const std::string err = test::readFile(dir / "err.txt");
    EXPECT_EQ(std::count(err.begin(), err.end(), '\n'), 1) << err;
    const std::string prefix = "penumbra: " + glb.string() + ": not a valid GLB";
    EXPECT_EQ(err.rfind(prefix, 0), 0u) << err;
    fs::remove_all(dir);
}

}  // namespace
}  // namespace penumbra
