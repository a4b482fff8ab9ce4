// The scene importer under hostile input: seeded random mutations (bit flips, overwritten and
// deleted runs, truncation, duplicated runs) of valid glTF, GLB and OBJ scenes are either
// imported or refused with InputError, never another exception or a crash (the suite also
// runs under AddressSanitizer and UndefinedBehaviorSanitizer).

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>

#include "core/input_error.h"
#include "edit/io/export.h"
#include "edit/io/scene_import.h"
#include "solver/discretization.h"
#include "test_scenes.h"

namespace penumbra {
namespace {

namespace fs = std::filesystem;

std::string readBytes(const fs::path& path) {
    std::ifstream in(path, std::ios::binary);
    std::stringstream s;
    s << in.rdbuf();
    return s.str();
}

std::string mutate(std::string bytes, std::mt19937& rng) {
    const int edits = 1 + static_cast<int>(rng() % 4);
    for (int k = 0; k < edits && !bytes.empty(); ++k) {
        const std::size_t at = rng() % bytes.size();
        const std::size_t run = std::min<std::size_t>(1 + rng() % 16, bytes.size() - at);
        switch (rng() % 5) {
            case 0:
                bytes[at] = static_cast<char>(bytes[at] ^ (1u << (rng() % 8)));
                break;
            case 1:
                for (std::size_t i = 0; i < run; ++i) bytes[at + i] = static_cast<char>(rng());
                break;
            case 2:
                bytes.erase(at, run);
                break;
            case 3:
                bytes.resize(at);
                break;
            default:
                bytes.insert(at, bytes.substr(at, run));
                break;
        }
    }
    return bytes;
}

void fuzz(const std::string& name, const std::string& original, int cases) {
    const fs::path dir = fs::temp_directory_path() /
                         ("penumbra-import-fuzz-" + std::to_string(::getpid()) + "-" + name);
    fs::create_directories(dir);
    const fs::path path = dir / name;
    std::mt19937 rng(12345);
    ImportOptions quiet;
    quiet.warn = [](const std::string&) {};
    int imported = 0, refused = 0;
    for (int c = 0; c < cases; ++c) {
        const std::string bytes = mutate(original, rng);
        std::ofstream(path, std::ios::binary | std::ios::trunc) << bytes;
        try {
            const Scene scene = importScene(path.string(), quiet);
            ++imported;
        } catch (const InputError&) {
            ++refused;
        } catch (const std::exception& e) {
            ADD_FAILURE() << name << " case " << c << ": " << e.what();
        }
    }
    EXPECT_GT(refused, 0) << name << ": some mutations must break the file";
    std::printf("%s: %d imported, %d refused\n", name.c_str(), imported, refused);
    fs::remove_all(dir);
}

TEST(SceneImportFuzz, MutatedGltfIsImportedOrRefused) {
    const std::string studio =
        readBytes(fs::path(PENUMBRA_SOURCE_DIR) / "scenes" / "gltf" / "studio.gltf");
    ASSERT_FALSE(studio.empty());
    fuzz("studio.gltf", studio, 300);
}

TEST(SceneImportFuzz, MutatedGlbIsImportedOrRefused) {
    Scene scene = test::emptyScene(0.5, 0.5);
    test::addMaterial(scene, "grey", Rgb(0.5));
    test::addMaterial(scene, "lamp", Rgb(0.0), Rgb(5.0));
    scene.objects.push_back(test::makeQuad("floor", 1, 1, "grey", {0, 0, 0}));
    scene.objects.push_back(test::makeQuad("lamp", 0.5, 0.5, "lamp", {0, 1, 0}, {180, 0, 0}));
    Discretization disc(scene);
    const fs::path glb =
        fs::temp_directory_path() / ("penumbra-import-fuzz-" + std::to_string(::getpid()) + ".glb");
    exportLitScene(disc, std::vector<Rgb>(disc.elements().size(), Rgb(0.5)), glb.string(), &scene);
    const std::string bytes = readBytes(glb);
    fs::remove(glb);
    ASSERT_FALSE(bytes.empty());
    fuzz("lit.glb", bytes, 300);
}

TEST(SceneImportFuzz, MutatedObjIsImportedOrRefused) {
    const std::string obj =
        "o floor\nv -1 0 -1\nv -1 0 1\nv 1 0 1\nv 1 0 -1\nf 1 2 3 4\n"
        "o lamp\nv -0.2 1 -0.2\nv 0.2 1 -0.2\nv 0.2 1 0.2\nv -0.2 1 0.2\nf 5 6 7 8\n"
        "g extra\nf 1 3 2\nf -1 -2 -3\n";
    fuzz("room.obj", obj, 300);
}

}  // namespace
}  // namespace penumbra
