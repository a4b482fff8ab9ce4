// What scripts/fuzz.sh found, as regression tests: each input in tests/edit/fuzz_findings/
// (named TARGET-what.EXT) goes through the parser its target fuzzes and must be taken or
// refused with InputError; and the limits the findings led to hold on their own.

#include <gtest/gtest.h>

#include <filesystem>
#include <string>

#include "core/input_error.h"
#include "edit/edit_log.h"
#include "edit/io/mesh_io.h"
#include "edit/io/scene_import.h"
#include "edit/io/scene_io.h"
#include "solver/discretization.h"
#include "test_scenes.h"

namespace penumbra {
namespace {

namespace fs = std::filesystem;

/// Runs the parser of fuzz target `target` (the file name's prefix) on `path`.
void parseAs(const std::string& target, const std::string& path) {
    if (target == "scene") {
        (void)loadScene(path);
    } else if (target == "log") {
        (void)readEditLog(path);
    } else if (target.rfind("import_", 0) == 0) {
        (void)importScene(path);
    } else {
        (void)loadMeshFile(path);
    }
}

TEST(FuzzFindings, EveryFindingIsTakenOrRefusedWithOneInputError) {
    const fs::path dir = fs::path(PENUMBRA_SOURCE_DIR) / "tests/edit/fuzz_findings";
    int findings = 0;
    for (const auto& entry : fs::directory_iterator(dir)) {
        const std::string name = entry.path().filename().string();
        const std::string target = name.substr(0, name.find('-'));
        ++findings;
        try {
            parseAs(target, entry.path().string());
        } catch (const InputError& e) {
            EXPECT_NE(std::string(e.what()).find(entry.path().string()), std::string::npos)
                << name << ": the error names the file: " << e.what();
        } catch (const std::exception& e) {
            ADD_FAILURE() << name << ": " << e.what();
        }
    }
    EXPECT_GE(findings, 1);
}

/// The elements the solver makes of an imported scene's point-light spheres.
std::size_t lightElements(const Scene& scene) {
    std::size_t count = 0;
    for (const SceneObject& o : scene.objects) {
        if (o.id.rfind("light-", 0) != 0) continue;
        Scene one;
        one.settings = scene.settings;
        one.materials = scene.materials;
        one.objects.push_back(o);
        count += Discretization(one).elements().size();
    }
    return count;
}

TEST(FuzzFindings, APointLightBesideMeshesFarSmallerThanItStaysASphereOfFewElements) {
    // Three findings, one cause: meshes whose total area is tiny (a GLB whose misaligned buffer
    // view gives its triangle an area near 1e-40 m², which overflowed the cell count; a glTF
    // and a GLB whose corrupted buffers shrank their triangles, which ran past the fuzzer's
    // timeout) set an element size that split the point light's sphere into millions of
    // elements. The light's sphere now counts among the elements the element size is chosen
    // for, so it stays within the import's 16,000 (docs/import.md).
    for (const char* name :
         {"import_glb-tiny-area-light.glb", "import_gltf-mesh-smaller-than-light.gltf",
          "import_glb-mesh-smaller-than-light.glb"}) {
        const fs::path file = fs::path(PENUMBRA_SOURCE_DIR) / "tests/edit/fuzz_findings" / name;
        const Scene scene = importScene(file.string());
        const std::size_t elements = lightElements(scene);
        EXPECT_GT(elements, 0u) << name;
        EXPECT_LE(elements, 16000u) << name << ": element size " << scene.settings.elementSize;
    }
}

TEST(FuzzFindings, ADiscretizationOutOfScaleIsRefusedNotAttempted) {
    // A box a million times its element size along each side, and a mesh triangle as long:
    // std::invalid_argument naming the object, before any element is made.
    for (int kind = 0; kind < 2; ++kind) {
        Scene scene = test::emptyScene(0.5, 0.1);
        test::addMaterial(scene, "white", Rgb(0.5));
        SceneObject o;
        o.id = "huge";
        o.material = "white";
        if (kind == 0) {
            o.shape.type = ShapeType::Box;
            o.shape.size = Vec3(1e5, 1e5, 1e5);
        } else {
            o.shape.type = ShapeType::Mesh;
            o.shape.mesh.positions = {Vec3(0.0), Vec3(1e5, 0, 0), Vec3(0, 0, 1e5)};
            o.shape.mesh.triangles = {{0, 1, 2}};
        }
        scene.objects.push_back(o);
        try {
            const Discretization disc(scene);
            ADD_FAILURE() << "kind " << kind << ": " << disc.elements().size() << " elements";
        } catch (const std::invalid_argument& e) {
            EXPECT_NE(std::string(e.what()).find("object 'huge'"), std::string::npos) << e.what();
        }
    }
}

}  // namespace
}  // namespace penumbra
