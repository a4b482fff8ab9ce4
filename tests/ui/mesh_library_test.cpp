// The Add menu's library (ui/mesh_library.h): listing a temporary folder tree and the
// repository's real scenes/meshes, scene-relative paths checked by resolving them back (and
// against what the committed scenes write), and placement checked on the transformed vertices
// of real meshes (bounds fit the box, the support point lies on the surface plane).

#include "ui/mesh_library.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <set>

#include "edit/io/mesh_io.h"

namespace penumbra {
namespace {

namespace fs = std::filesystem;

const std::string kSource = PENUMBRA_SOURCE_DIR;

/// A fresh temporary folder, removed with the object.
struct TempTree {
    fs::path root;
    TempTree() {
        root = fs::temp_directory_path() /
               ("penumbra_meshlib_" + std::to_string(::getpid()) + "_" +
                ::testing::UnitTest::GetInstance()->current_test_info()->name());
        fs::remove_all(root);
        fs::create_directories(root);
    }
    ~TempTree() { fs::remove_all(root); }
    void touch(const std::string& relative) const {
        fs::create_directories((root / relative).parent_path());
        std::ofstream(root / relative) << "x\n";
    }
};

std::vector<std::string> labels(const std::vector<LibraryEntry>& entries) {
    std::vector<std::string> out;
    for (const LibraryEntry& e : entries) out.push_back(e.label);
    return out;
}

/// World-space bounds of `mesh` under `t` (every vertex transformed).
Bounds worldBounds(const TriMesh& mesh, const Transform& t) {
    const Mat4 m = t.worldFromObject();
    Bounds b{Vec3(1e300), Vec3(-1e300)};
    for (const Vec3& p : mesh.positions) {
        const Vec3 w = Vec3(m * glm::dvec4(p, 1.0));
        b.lo = glm::min(b.lo, w), b.hi = glm::max(b.hi, w);
    }
    return b;
}

TEST(MeshLibrary, MeshFilesAreRecognisedByExtension) {
    for (const char* yes : {"a.obj", "b.OFF", "dir/c.ply", "d.Stl", "e.gltf", "f.glb"})
        EXPECT_TRUE(isMeshFile(yes)) << yes;
    for (const char* no : {"a.json", "b.mtl", "c", "d.obj.bak", "gltf", ".obj.png"})
        EXPECT_FALSE(isMeshFile(no)) << no;
}

TEST(MeshLibrary, ListsMeshFilesRecursivelySortedWithoutHiddenOrDuplicates) {
    TempTree tree;
    tree.touch("meshes/b.obj");
    tree.touch("meshes/a/z.PLY");
    tree.touch("meshes/a/readme.md");
    tree.touch("meshes/a/scene.mtl");
    tree.touch("meshes/.hidden/c.off");
    tree.touch("meshes/.d.obj");
    tree.touch("meshes/c/d/e.glb");
    tree.touch("other/x.stl");
    const std::string meshes = (tree.root / "meshes").string();
    const std::string other = (tree.root / "other").string();

    // Sub-folders' files labelled with '/', sorted; hidden and non-mesh files left out.
    const auto entries = listMeshes({meshes});
    EXPECT_EQ(labels(entries), (std::vector<std::string>{"a/z.PLY", "b.obj", "c/d/e.glb"}));
    for (const LibraryEntry& e : entries) {
        EXPECT_EQ(e.type, ShapeType::Mesh) << e.toString();
        EXPECT_TRUE(fs::path(e.path).is_absolute()) << e.toString();
        EXPECT_TRUE(fs::equivalent(e.path, tree.root / "meshes" / e.label)) << e.toString();
    }

    // Two roots: the second's files follow; a root inside the first adds nothing twice.
    const auto both = listMeshes({meshes, other, (tree.root / "meshes/a").string()});
    EXPECT_EQ(labels(both), (std::vector<std::string>{"a/z.PLY", "b.obj", "c/d/e.glb", "x.stl"}));
    EXPECT_EQ(listMeshes({meshes, other}, 2).size(), 2u);
    EXPECT_TRUE(listMeshes({(tree.root / "missing").string()}).empty());

    // A symlinked folder is followed (setups link a mesh collection in); a link cycle ends.
    fs::create_directory_symlink(tree.root / "other", tree.root / "meshes/linked");
    fs::create_directory_symlink(tree.root / "meshes", tree.root / "meshes/c/loop");
    const auto linked = labels(listMeshes({meshes}));
    EXPECT_EQ(linked, (std::vector<std::string>{"a/z.PLY", "b.obj", "c/d/e.glb", "linked/x.stl"}));

    // Roots: the scene's meshes/ folder, existing ones only, without duplicates.
    tree.touch("scene.json");
    const std::string scene = (tree.root / "scene.json").string();
    const auto sceneRoots = meshLibraryRoots(scene, "");
    ASSERT_EQ(sceneRoots.size(), 1u);
    EXPECT_TRUE(fs::equivalent(sceneRoots[0], meshes));
    EXPECT_TRUE(meshLibraryRoots((tree.root / "other/s.json").string(), "").empty());

    // The source folder: the nearest ancestor holding scenes/meshes.
    tree.touch("repo/scenes/meshes/m.obj");
    tree.touch("repo/build/tests/x");
    const fs::path repo = tree.root / "repo";
    EXPECT_EQ(fs::path(findSourceDir((repo / "build/tests").string())), repo);
    EXPECT_EQ(fs::path(findSourceDir((repo / "scenes/s.json").string())), repo);
    EXPECT_EQ(fs::path(findSourceDir(repo.string())), repo);
    EXPECT_EQ(findSourceDir(other), "");
    EXPECT_EQ(labels(listMeshes(meshLibraryRoots("", findSourceDir((repo / "build").string())))),
              (std::vector<std::string>{"m.obj"}));
}

TEST(MeshLibrary, TheRepositoryMeshesAreListedAndLoad) {
    const fs::path cgal = fs::path(kSource) / "scenes/meshes/cgal";
    if (!fs::exists(cgal / "cow.off")) GTEST_SKIP() << cgal << " missing: run scripts/setup.sh";
    // From a scene in scenes/ the scene's meshes/ folder and the repository's are the same.
    const auto roots = meshLibraryRoots(kSource + "/scenes/robot-room.json", kSource);
    ASSERT_EQ(roots.size(), 1u);
    EXPECT_TRUE(fs::equivalent(roots[0], fs::path(kSource) / "scenes/meshes"));
    const auto entries = listMeshes(roots);
    const auto names = labels(entries);
    const std::set<std::string> listed(names.begin(), names.end());
    // Every .off file in the folder (listed independently) is in the library.
    std::size_t offFiles = 0;
    for (const auto& f : fs::directory_iterator(cgal))
        if (f.path().extension() == ".off") {
            ++offFiles;
            EXPECT_TRUE(listed.count("cgal/" + f.path().filename().string()))
                << f.path() << " not listed";
        }
    EXPECT_GE(offFiles, 1u);
    EXPECT_GE(entries.size(), offFiles);
    // The entries load (the smallest few, to keep the test fast).
    for (const char* name : {"cgal/cow.off", "cgal/elk.off"}) {
        auto it = std::find(names.begin(), names.end(), name);
        if (it == names.end()) continue;
        const TriMesh mesh = loadMeshFile(entries[it - names.begin()].path);
        EXPECT_GT(mesh.triangles.size(), 1000u) << name;
    }
}

TEST(MeshLibrary, SceneRelativePathsResolveBackToTheFile) {
    const fs::path cow = fs::path(kSource) / "scenes/meshes/cgal/cow.off";
    // What the committed scenes write for the same file.
    std::ifstream in(kSource + "/scenes/robot-room.json");
    const nlohmann::json scene = nlohmann::json::parse(in);
    std::set<std::string> files;
    for (const auto& o : scene["objects"])
        if (o["shape"].contains("file")) files.insert(o["shape"]["file"].get<std::string>());
    ASSERT_TRUE(files.count("meshes/cgal/cow.off"));
    EXPECT_EQ(sceneRelativePath(cow.string(), kSource + "/scenes/robot-room.json"),
              "meshes/cgal/cow.off");

    // A scene elsewhere: the relative path climbs out and resolves back to the same file.
    TempTree tree;
    tree.touch("project/scenes/s.json");
    tree.touch("project/assets/m.obj");
    const std::string scenePath = (tree.root / "project/scenes/s.json").string();
    const std::string relative =
        sceneRelativePath((tree.root / "project/assets/m.obj").string(), scenePath);
    EXPECT_EQ(relative, "../assets/m.obj");
    EXPECT_TRUE(fs::equivalent(fs::path(scenePath).parent_path() / relative,
                               tree.root / "project/assets/m.obj"));
    EXPECT_EQ(sceneRelativePath((tree.root / "project/scenes/sub/n.ply").string(), scenePath),
              "sub/n.ply");
}

TEST(MeshLibrary, PrimitivesHaveTheLibrarySizeAndCentredBounds) {
    const auto primitives = listPrimitives();
    ASSERT_EQ(primitives.size(), 4u);
    for (const LibraryEntry& e : primitives) {
        const Bounds b = shapeBounds(makePrimitive(e.type, 0.4));
        const Vec3 x = b.extent();
        EXPECT_NEAR(std::max({x.x, x.y, x.z}), 0.4, 1e-12) << e.toString();
        EXPECT_NEAR(glm::length(b.centre()), 0.0, 1e-12) << e.toString();
        EXPECT_EQ(e.label, shapeTypeName(e.type));
    }
    EXPECT_EQ(shapeBounds(makePrimitive(ShapeType::Quad)).extent().y, 0.0);
    EXPECT_THROW(makePrimitive(ShapeType::Mesh), std::invalid_argument);
    Shape empty;
    empty.type = ShapeType::Mesh;
    EXPECT_THROW(shapeBounds(empty), std::invalid_argument);
}

TEST(MeshLibrary, TargetNormalsComeFromNeighbouringHitsAndFaceTheCamera) {
    const Vec3 origin(0, 1, 3);
    const Vec3 dir = glm::normalize(Vec3(0, -1, -3));
    // A floor: three points on y = 0 (any order of the neighbours gives +Y towards the camera).
    const Vec3 hit(0, 0, 0);
    for (const auto& [right, down] : {std::pair{Vec3(0.1, 0, 0), Vec3(0, 0, 0.1)},
                                      std::pair{Vec3(0, 0, 0.1), Vec3(0.1, 0, 0)}}) {
        const PlacementTarget t = placementTarget(origin, dir, hit, right, down, 2.0);
        EXPECT_TRUE(t.onSurface);
        EXPECT_NEAR(glm::length(t.normal - Vec3(0, 1, 0)), 0.0, 1e-12) << t.toString();
    }
    // A tilted plane with normal n: the estimate is n.
    const Vec3 n = glm::normalize(Vec3(0.3, 1.0, 0.5));
    const Vec3 u = glm::normalize(glm::cross(n, Vec3(1, 0, 0))), v = glm::cross(n, u);
    const PlacementTarget tilted =
        placementTarget(origin, dir, hit, hit + 0.05 * u, hit + 0.05 * v, 2);
    EXPECT_NEAR(glm::length(tilted.normal - n), 0.0, 1e-9) << tilted.toString();
    // Missing or collinear neighbours: facing the camera.
    const PlacementTarget lone = placementTarget(origin, dir, hit, std::nullopt, hit, 2.0);
    EXPECT_NEAR(glm::length(lone.normal + dir), 0.0, 1e-12);
    const PlacementTarget line =
        placementTarget(origin, dir, hit, Vec3(0.1, 0, 0), Vec3(0.2, 0, 0), 2.0);
    EXPECT_NEAR(glm::length(line.normal + dir), 0.0, 1e-12);
    // No hit, or one too far: free space at the given distance.
    const PlacementTarget free = placementTarget(origin, dir, std::nullopt, {}, {}, 2.0);
    EXPECT_FALSE(free.onSurface);
    EXPECT_NEAR(glm::length(free.point - (origin + 2.0 * dir)), 0.0, 1e-12);
    EXPECT_FALSE(placementTarget(origin, dir, Vec3(0, -100, -300), {}, {}, 2.0, 50.0).onSurface);
}

TEST(MeshLibrary, RealMeshesAreScaledIntoTheBoxAndRestOnTheSurface) {
    const fs::path cgal = fs::path(kSource) / "scenes/meshes/cgal";
    if (!fs::exists(cgal / "cow.off")) GTEST_SKIP() << cgal << " missing: run scripts/setup.sh";
    for (const char* name : {"cow.off", "dino.off", "elk.off"}) {
        const fs::path file = cgal / name;
        if (!fs::exists(file)) continue;
        Shape shape;
        shape.type = ShapeType::Mesh;
        shape.file = file.string();
        shape.mesh = loadMeshFile(file.string());
        const Bounds local = shapeBounds(shape);

        // On a floor at y = 0.2: stands on it, 1 mm above, centred on the point in x and z.
        PlacementTarget floor;
        floor.point = Vec3(1.0, 0.2, -2.0);
        floor.normal = Vec3(0, 1, 0);
        floor.onSurface = true;
        const Transform onFloor = placeInBox(local, 0.5, floor);
        const Bounds w = worldBounds(shape.mesh, onFloor);
        const Vec3 x = w.extent();
        EXPECT_NEAR(std::max({x.x, x.y, x.z}), 0.5, 1e-9) << name << " " << onFloor.toString();
        EXPECT_NEAR(w.lo.y, 0.201, 1e-9) << name;
        EXPECT_NEAR(w.centre().x, 1.0, 1e-9) << name;
        EXPECT_NEAR(w.centre().z, -2.0, 1e-9) << name;

        // On a wall x = -1 facing +X: in front of it.
        PlacementTarget wall{Vec3(-1.0, 1.0, 0.5), Vec3(1, 0, 0), true};
        const Bounds ww = worldBounds(shape.mesh, placeInBox(local, 0.5, wall));
        EXPECT_NEAR(ww.lo.x, -0.999, 1e-9) << name;
        EXPECT_NEAR(ww.centre().y, 1.0, 1e-9) << name;

        // On a tilted plane: every vertex is on the camera side, the nearest 1 mm off.
        const Vec3 n = glm::normalize(Vec3(0.2, 1.0, -0.4));
        PlacementTarget slope{Vec3(0.5, 0.0, 0.5), n, true};
        const Transform onSlope = placeInBox(local, 0.5, slope);
        const Mat4 m = onSlope.worldFromObject();
        double nearest = 1e300;
        for (const Vec3& p : shape.mesh.positions)
            nearest = std::min(nearest, glm::dot(Vec3(m * glm::dvec4(p, 1.0)) - slope.point, n));
        // The box touches the plane; the mesh inside it is no nearer than the box.
        EXPECT_GE(nearest, 1e-3 - 1e-9) << name;
        EXPECT_LT(nearest, 0.25) << name;

        // Free space: the bounding box is centred on the point.
        PlacementTarget air{Vec3(0.0, 1.5, 0.0), Vec3(0, 0, 1), false};
        const Bounds wa = worldBounds(shape.mesh, placeInBox(local, 0.5, air));
        EXPECT_NEAR(glm::length(wa.centre() - air.point), 0.0, 1e-9) << name;
    }
}

TEST(MeshLibrary, IdsAreUniqueAndMaterialsNotEmissive) {
    const std::set<std::string> taken = {"cow-1", "cow-2", "box-1"};
    auto isTaken = [&](const std::string& id) { return taken.count(id) > 0; };
    EXPECT_EQ(uniqueObjectId("/x/meshes/cgal/cow.off", isTaken), "cow-3");
    EXPECT_EQ(uniqueObjectId("box", isTaken), "box-2");
    EXPECT_EQ(uniqueObjectId("my mesh.obj", isTaken), "my_mesh-1");
    EXPECT_EQ(uniqueObjectId("", isTaken), "object-1");

    std::vector<NamedMaterial> materials(3);
    materials[0].name = "lamp";
    materials[0].material.emission = Rgb(5.0);
    materials[1].name = "white";
    materials[2].name = "red";
    EXPECT_EQ(defaultMaterial(materials), "white");
    materials.erase(materials.begin() + 1, materials.end());
    EXPECT_EQ(defaultMaterial(materials), "lamp");
    EXPECT_EQ(defaultMaterial({}), "");
}

}  // namespace
}  // namespace penumbra
