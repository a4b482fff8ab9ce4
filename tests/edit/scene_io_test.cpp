// Scene and mesh file input/output: round trips, transform order, mesh formats, and one test
// per class of bad input (each error must name the file and the offending key).
// Index: helpers · round trip · transform order · mesh formats · degenerate faces ·
//        bad scene input · API pieces for the edit log · saving

#include "edit/io/scene_io.h"

#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>
#include <string>
#include <vector>

#include "core/input_error.h"
#include "edit/io/mesh_io.h"
#include "log_capture.h"

namespace penumbra {
namespace {

namespace fs = std::filesystem;

// ---------------------------------------------------------------------------------------------
// Helpers.

/// A fresh directory under the system temp dir, removed when the test ends.
class TempDir {
public:
    TempDir() {
        const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
        std::string name =
            std::string("penumbra_io_") + info->test_suite_name() + "_" + info->name();
        for (char& c : name) {
            if (c == '/') c = '_';
        }
        // The process id keeps concurrent runs (several build trees, ctest -j) apart.
        mPath = fs::temp_directory_path() / (name + "_" + std::to_string(::getpid()));
        fs::remove_all(mPath);
        fs::create_directories(mPath);
    }
    ~TempDir() {
        std::error_code ignored;
        fs::remove_all(mPath, ignored);
    }
    std::string file(const std::string& name) const { return (mPath / name).string(); }
    const fs::path& path() const { return mPath; }

    std::string write(const std::string& name, const std::string& text) const {
        const std::string full = file(name);
        fs::create_directories(fs::path(full).parent_path());
        std::ofstream(full, std::ios::binary) << text;
        return full;
    }

private:
    fs::path mPath;
};

void appendFloats(std::string& bytes, std::initializer_list<float> values) {
    for (float v : values) bytes.append(reinterpret_cast<const char*>(&v), sizeof v);
}

void appendUint16s(std::string& bytes, std::initializer_list<uint16_t> values) {
    for (uint16_t v : values) bytes.append(reinterpret_cast<const char*>(&v), sizeof v);
}

void appendUint32(std::string& bytes, uint32_t value) {
    bytes.append(reinterpret_cast<const char*>(&value), sizeof value);
}

/// glTF JSON for one triangle (positions then uint16 indices in buffer 0) on a node with
/// `nodeTransform` (e.g. `"translation":[1,2,3]`), using material 0.
std::string triangleGltfJson(const std::string& bufferEntry, size_t positionBytes,
                             const std::string& nodeTransform) {
    std::ostringstream json;
    json
        << R"({"asset":{"version":"2.0"},"scene":0,"scenes":[{"nodes":[0]}],)"
        << R"("nodes":[{"mesh":0)" << (nodeTransform.empty() ? "" : "," + nodeTransform) << "}],"
        << R"("meshes":[{"primitives":[{"attributes":{"POSITION":0},"indices":1,"material":0}]}],)"
        << R"("materials":[{"name":"glow","pbrMetallicRoughness":{"baseColorFactor":[0.2,0.4,1.5,1]},)"
        << R"("emissiveFactor":[1,0.5,0]}],)"
        << R"("buffers":[)" << bufferEntry << "],"
        << R"("bufferViews":[{"buffer":0,"byteOffset":0,"byteLength":)" << positionBytes << "},"
        << R"({"buffer":0,"byteOffset":)" << positionBytes << R"(,"byteLength":6}],)"
        << R"("accessors":[{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3",)"
        << R"("min":[0,0,0],"max":[1,1,0]},)"
        << R"({"bufferView":1,"componentType":5123,"count":3,"type":"SCALAR"}]})";
    return json.str();
}

/// Buffer for triangleGltfJson: three positions (x, y, z per vertex) and indices 0 1 2.
std::string triangleBuffer(std::initializer_list<float> positions) {
    std::string bytes;
    appendFloats(bytes, positions);
    appendUint16s(bytes, {0, 1, 2});
    return bytes;
}

/// Writes `name`.gltf with an external `name`.bin holding one triangle.
std::string writeTriangleGltf(const TempDir& dir, const std::string& name,
                              std::initializer_list<float> positions,
                              const std::string& nodeTransform) {
    const std::string buffer = triangleBuffer(positions);
    dir.write(name + ".bin", buffer);
    const std::string entry = R"({"uri":")" + fs::path(name).filename().string() +
                              R"(.bin","byteLength":)" + std::to_string(buffer.size()) + "}";
    return dir.write(name + ".gltf", triangleGltfJson(entry, positions.size() * 4, nodeTransform));
}

/// Writes `name`.glb: the same triangle with the buffer in the BIN chunk.
std::string writeTriangleGlb(const TempDir& dir, const std::string& name,
                             std::initializer_list<float> positions,
                             const std::string& nodeTransform) {
    std::string bin = triangleBuffer(positions);
    std::string json = triangleGltfJson(R"({"byteLength":)" + std::to_string(bin.size()) + "}",
                                        positions.size() * 4, nodeTransform);
    while (json.size() % 4) json += ' ';
    while (bin.size() % 4) bin += '\0';
    std::string glb;
    appendUint32(glb, 0x46546C67);  // "glTF"
    appendUint32(glb, 2);
    appendUint32(glb, static_cast<uint32_t>(12 + 8 + json.size() + 8 + bin.size()));
    appendUint32(glb, static_cast<uint32_t>(json.size()));
    appendUint32(glb, 0x4E4F534A);  // "JSON"
    glb += json;
    appendUint32(glb, static_cast<uint32_t>(bin.size()));
    appendUint32(glb, 0x004E4942);  // "BIN\0"
    glb += bin;
    return dir.write(name + ".glb", glb);
}

const char* kCubeObj = R"(# unit cube, outward faces, two materials
mtllib cube.mtl
v -0.5 -0.5 -0.5
v  0.5 -0.5 -0.5
v  0.5  0.5 -0.5
v -0.5  0.5 -0.5
v -0.5 -0.5  0.5
v  0.5 -0.5  0.5
v  0.5  0.5  0.5
v -0.5  0.5  0.5
usemtl red
f 1 4 3 2
f 5 6 7 8
f 1 5 8 4
f 2 3 7 6
usemtl lamp
f 4 8 7 3
f 1 2 6 5
)";

const char* kCubeMtl = R"(newmtl red
Kd 0.8 0.1 0.1
newmtl lamp
Kd 1.5 0.5 -0.2
Ke 10 8 6
)";

const char* kTetraOff = R"(OFF
4 4 0
0 0 0
1 0 0
0 1 0
0 0 1
3 0 2 1
3 0 1 3
3 0 3 2
3 1 2 3
)";

const char* kQuadPly = R"(ply
format ascii 1.0
element vertex 4
property float x
property float y
property float z
element face 1
property list uchar int vertex_indices
end_header
0 0 0
0 0 1
1 0 1
1 0 0
4 0 1 2 3
)";

const char* kTriangleStl = R"(solid two
facet normal 0 0 1
outer loop
vertex 0 0 0
vertex 1 0 0
vertex 0 1 0
endloop
endfacet
facet normal 0 0 1
outer loop
vertex 1 0 0
vertex 1 1 0
vertex 0 1 0
endloop
endfacet
endsolid two
)";

/// Writes every test mesh into `dir` (meshes/ subfolder) and returns the scene file path.
std::string writeEveryShapeScene(const TempDir& dir) {
    dir.write("meshes/cube.obj", kCubeObj);
    dir.write("meshes/cube.mtl", kCubeMtl);
    dir.write("meshes/tetra.off", kTetraOff);
    dir.write("meshes/quad.ply", kQuadPly);
    dir.write("meshes/two.stl", kTriangleStl);
    writeTriangleGltf(dir, "meshes/tri", {0, 0, 0, 1, 0, 0, 0, 1, 0}, R"("translation":[1,2,3])");
    writeTriangleGlb(dir, "meshes/tri", {0, 0, 0, 1, 0, 0, 0, 1, 0}, R"("scale":[2,2,2])");
    return dir.write("scene.json", R"({
  "format": "penumbra-scene/1",
  "settings": {"patch_size": 0.4, "element_size": 0.05},
  "materials": {
    "white": {"reflectance": [0.73, 0.73, 0.73]},
    "lamp": {"reflectance": [0.78, 0.78, 0.78], "emission": [17.0, 12.0, 4.0]},
    "card": {"reflectance": [0.5, 0.25, 0.125], "two_sided": true}
  },
  "objects": [
    {"id": "floor", "shape": {"type": "quad", "size": [2.0, 3.0]}, "material": "white",
     "transform": {"translate": [0, 0, 0], "rotate_deg": [0, 0, 0], "scale": [1, 1, 1]}},
    {"id": "light", "shape": {"type": "quad", "size": [0.5, 0.5]}, "material": "lamp",
     "transform": {"translate": [0, 1.98, 0], "rotate_deg": [180, 0, 0]}, "patch_size": 1.0},
    {"id": "crate", "shape": {"type": "box", "size": [0.4, 0.5, 0.6]}, "material": "white",
     "transform": {"rotate_deg": [0, 30, 0], "scale": [1, 2, -1]}},
    {"id": "ball", "shape": {"type": "sphere", "radius": 0.25, "segments": 16}, "material": "card"},
    {"id": "pipe", "shape": {"type": "cylinder", "radius": 0.1, "height": 0.8}, "material": "white",
     "transform": {"translate": [0.5, 0.4, -0.3]}},
    {"id": "cube", "shape": {"type": "mesh", "file": "meshes/cube.obj"}},
    {"id": "cube-white", "shape": {"type": "mesh", "file": "meshes/cube.obj"}, "material": "white"},
    {"id": "tetra", "shape": {"type": "mesh", "file": "meshes/tetra.off"}, "material": "white"},
    {"id": "plyquad", "shape": {"type": "mesh", "file": "meshes/quad.ply"}, "material": "white"},
    {"id": "stl", "shape": {"type": "mesh", "file": "meshes/two.stl"}, "material": "card"},
    {"id": "gltf", "shape": {"type": "mesh", "file": "meshes/tri.gltf"}},
    {"id": "glb", "shape": {"type": "mesh", "file": "meshes/tri.glb"}, "material": "lamp"}
  ],
  "cameras": {
    "side": {"position": [3, 1, 0], "look_at": [0, 1, 0]},
    "default": {"position": [0, 1, 3], "look_at": [0, 1, 0], "up": [0, 1, 0], "fov_deg": 40}
  }
})");
}

void expectVec3Eq(const Vec3& a, const Vec3& b, const std::string& what) {
    EXPECT_EQ(a.x, b.x) << what;
    EXPECT_EQ(a.y, b.y) << what;
    EXPECT_EQ(a.z, b.z) << what;
}

void expectMaterialsEq(const Material& a, const Material& b, const std::string& what) {
    EXPECT_EQ(a.toString(), b.toString()) << what;
    expectVec3Eq(a.reflectance, b.reflectance, what + ".reflectance");
    expectVec3Eq(a.emission, b.emission, what + ".emission");
    EXPECT_EQ(a.twoSided, b.twoSided) << what;
}

/// Field-by-field equality of two scenes, meshes included.
void expectScenesEqual(const Scene& a, const Scene& b) {
    EXPECT_EQ(a.settings.patchSize, b.settings.patchSize);
    EXPECT_EQ(a.settings.elementSize, b.settings.elementSize);
    ASSERT_EQ(a.materials.size(), b.materials.size());
    for (size_t i = 0; i < a.materials.size(); ++i) {
        EXPECT_EQ(a.materials[i].name, b.materials[i].name);
        expectMaterialsEq(a.materials[i].material, b.materials[i].material, a.materials[i].name);
    }
    ASSERT_EQ(a.objects.size(), b.objects.size());
    for (size_t i = 0; i < a.objects.size(); ++i) {
        const SceneObject& x = a.objects[i];
        const SceneObject& y = b.objects[i];
        const std::string what = "object " + x.id;
        EXPECT_EQ(x.id, y.id);
        EXPECT_EQ(x.material, y.material) << what;
        EXPECT_EQ(x.patchSize, y.patchSize) << what;
        EXPECT_EQ(x.transform.toString(), y.transform.toString()) << what;
        expectVec3Eq(x.transform.translate, y.transform.translate, what);
        expectVec3Eq(x.transform.rotateDeg, y.transform.rotateDeg, what);
        expectVec3Eq(x.transform.scale, y.transform.scale, what);
        EXPECT_EQ(x.shape.type, y.shape.type) << what;
        expectVec3Eq(x.shape.size, y.shape.size, what + " size");
        EXPECT_EQ(x.shape.radius, y.shape.radius) << what;
        EXPECT_EQ(x.shape.height, y.shape.height) << what;
        EXPECT_EQ(x.shape.segments, y.shape.segments) << what;
        EXPECT_EQ(x.shape.file, y.shape.file) << what;
        const TriMesh& m = x.shape.mesh;
        const TriMesh& n = y.shape.mesh;
        EXPECT_EQ(m.positions, n.positions) << what;
        EXPECT_EQ(m.triangles, n.triangles) << what;
        EXPECT_EQ(m.triangleMaterial, n.triangleMaterial) << what;
        EXPECT_EQ(m.materialNames, n.materialNames) << what;
        ASSERT_EQ(m.materials.size(), n.materials.size()) << what;
        for (size_t k = 0; k < m.materials.size(); ++k) {
            expectMaterialsEq(m.materials[k], n.materials[k], what + " mesh material");
        }
    }
    ASSERT_EQ(a.cameras.size(), b.cameras.size());
    for (size_t i = 0; i < a.cameras.size(); ++i) {
        EXPECT_EQ(a.cameras[i].name, b.cameras[i].name);
        expectVec3Eq(a.cameras[i].position, b.cameras[i].position, a.cameras[i].name);
        expectVec3Eq(a.cameras[i].lookAt, b.cameras[i].lookAt, a.cameras[i].name);
        expectVec3Eq(a.cameras[i].up, b.cameras[i].up, a.cameras[i].name);
        EXPECT_EQ(a.cameras[i].fovDeg, b.cameras[i].fovDeg);
    }
}

/// Runs `load` and returns the InputError message, failing the test when nothing is thrown.
template <typename F>
std::string inputErrorOf(F&& load) {
    try {
        load();
    } catch (const InputError& error) {
        return error.what();
    } catch (const std::exception& error) {
        ADD_FAILURE() << "expected InputError, got another exception: " << error.what();
        return "";
    }
    ADD_FAILURE() << "expected InputError, nothing was thrown";
    return "";
}

bool startsWith(const std::string& text, const std::string& prefix) {
    return text.compare(0, prefix.size(), prefix) == 0;
}

Vec3 triangleNormal(const TriMesh& mesh, size_t t) {
    const auto& tri = mesh.triangles[t];
    const Vec3& a = mesh.positions[tri[0]];
    return glm::cross(mesh.positions[tri[1]] - a, mesh.positions[tri[2]] - a);
}

double meshArea(const TriMesh& mesh) {
    double area = 0.0;
    for (size_t t = 0; t < mesh.triangles.size(); ++t)
        area += 0.5 * glm::length(triangleNormal(mesh, t));
    return area;
}

// ---------------------------------------------------------------------------------------------
// Round trip.

TEST(SceneIo, LoadsEveryShapeTypeInFileOrder) {
    TempDir dir;
    const Scene scene = loadScene(writeEveryShapeScene(dir));

    EXPECT_EQ(scene.settings.patchSize, 0.4);
    EXPECT_EQ(scene.settings.elementSize, 0.05);
    ASSERT_EQ(scene.materials.size(), 3u);
    EXPECT_EQ(scene.materials[0].name, "white");  // file order, not alphabetical
    EXPECT_EQ(scene.materials[1].name, "lamp");
    EXPECT_EQ(scene.materials[2].name, "card");
    EXPECT_TRUE(scene.materials[1].material.isEmitter());
    EXPECT_TRUE(scene.materials[2].material.twoSided);
    ASSERT_EQ(scene.cameras.size(), 2u);
    EXPECT_EQ(scene.cameras[0].name, "side");
    EXPECT_EQ(scene.cameras[0].fovDeg, 40.0);  // default
    ASSERT_EQ(scene.objects.size(), 12u);

    const SceneObject& floor = scene.objects[0];
    EXPECT_EQ(floor.shape.type, ShapeType::Quad);
    EXPECT_EQ(floor.patchSize, 0.0) << "no override: the scene's patch_size";
    EXPECT_EQ(scene.objects[1].patchSize, 1.0) << "the light is one shooter";
    expectVec3Eq(floor.shape.size, Vec3(2.0, 0.0, 3.0), "quad size is x, -, z");
    const SceneObject& crate = scene.objects[2];
    EXPECT_EQ(crate.shape.type, ShapeType::Box);
    expectVec3Eq(crate.transform.scale, Vec3(1, 2, -1), "crate scale");
    expectVec3Eq(crate.transform.translate, Vec3(0.0), "crate translate default");
    EXPECT_EQ(scene.objects[3].shape.segments, 16);
    EXPECT_EQ(scene.objects[4].shape.segments, 24);  // default
    EXPECT_EQ(scene.objects[4].shape.height, 0.8);

    // OBJ: 6 quads → 12 triangles, per-triangle MTL materials with Kd clamped, Ke emission.
    const TriMesh& cube = scene.objects[5].shape.mesh;
    EXPECT_EQ(scene.objects[5].material, "");
    ASSERT_EQ(cube.triangles.size(), 12u);
    EXPECT_EQ(cube.positions.size(), 8u);
    ASSERT_EQ(cube.triangleMaterial.size(), 12u);
    ASSERT_EQ(cube.materialNames, (std::vector<std::string>{"red", "lamp"}));
    EXPECT_EQ(cube.triangleMaterial[0], 0);
    EXPECT_EQ(cube.triangleMaterial[11], 1);
    expectVec3Eq(cube.materials[1].reflectance, Vec3(0.99, 0.5, 0.0), "Kd clamped to [0, 0.99]");
    expectVec3Eq(cube.materials[1].emission, Vec3(10, 8, 6), "Ke");
    EXPECT_NEAR(meshArea(cube), 6.0, 1e-9);
    // Outward winding survives triangulation: every normal points away from the centre.
    for (size_t t = 0; t < cube.triangles.size(); ++t) {
        const Vec3 centroid =
            (cube.positions[cube.triangles[t][0]] + cube.positions[cube.triangles[t][1]] +
             cube.positions[cube.triangles[t][2]]) /
            3.0;
        EXPECT_GT(glm::dot(triangleNormal(cube, t), centroid), 0.0) << "triangle " << t;
    }

    EXPECT_EQ(scene.objects[7].shape.mesh.triangles.size(), 4u);  // OFF
    const TriMesh& plyQuad = scene.objects[8].shape.mesh;         // PLY quad → 2 triangles, +Y
    ASSERT_EQ(plyQuad.triangles.size(), 2u);
    for (size_t t = 0; t < 2; ++t) EXPECT_GT(triangleNormal(plyQuad, t).y, 0.0);
    EXPECT_EQ(scene.objects[9].shape.mesh.triangles.size(), 2u);  // STL
    EXPECT_TRUE(scene.objects[9].shape.mesh.triangleMaterial.empty());

    // glTF: node translation applied, baseColorFactor → reflectance, emissiveFactor → emission.
    const TriMesh& gltf = scene.objects[10].shape.mesh;
    ASSERT_EQ(gltf.triangles.size(), 1u);
    expectVec3Eq(gltf.positions[gltf.triangles[0][1]], Vec3(2, 2, 3), "translated vertex");
    ASSERT_EQ(gltf.materials.size(), 1u);
    EXPECT_EQ(gltf.materialNames[0], "glow");
    EXPECT_NEAR(gltf.materials[0].reflectance.x, 0.2, 1e-12);
    EXPECT_NEAR(gltf.materials[0].reflectance.z, 0.99, 1e-12);
    expectVec3Eq(gltf.materials[0].emission, Vec3(1, 0.5, 0), "emissiveFactor");
    const TriMesh& glb = scene.objects[11].shape.mesh;  // GLB: node scale 2
    ASSERT_EQ(glb.triangles.size(), 1u);
    EXPECT_NEAR(meshArea(glb), 2.0, 1e-12);
    EXPECT_GT(triangleNormal(glb, 0).z, 0.0);
}

TEST(SceneIo, RoundTripGivesIdenticalScene) {
    TempDir dir;
    const Scene first = loadScene(writeEveryShapeScene(dir));

    // Through JSON values.
    const Scene fromJson = sceneFromJson(sceneToJson(first), "memory", dir.path().string());
    expectScenesEqual(first, fromJson);

    // Through a saved file next to the original (mesh paths stay relative to it).
    const std::string saved = dir.file("saved.json");
    saveScene(first, saved);
    const Scene second = loadScene(saved);
    expectScenesEqual(first, second);
    EXPECT_EQ(sceneToJson(first), sceneToJson(second));

    // Saving is a fixed point.
    const std::string again = dir.file("again.json");
    saveScene(second, again);
    std::ifstream a(saved), b(again);
    std::stringstream textA, textB;
    textA << a.rdbuf();
    textB << b.rdbuf();
    EXPECT_EQ(textA.str(), textB.str());
}

TEST(SceneIo, RoundTripKeepsFullPrecision) {
    Scene scene;
    scene.settings.patchSize = 0.1 + 0.2;  // 0.30000000000000004
    scene.settings.elementSize = 1.0 / 30.0;
    Material material;
    material.reflectance = Rgb(1.0 / 7.0, 0.999999999, 1e-300);
    material.emission = Rgb(1e30, 0.0, 3.0e-5);
    scene.materials.push_back({"odd name.with \"quotes\"", material});
    SceneObject object;
    object.id = "π-object";
    object.shape.type = ShapeType::Sphere;
    object.shape.radius = std::nextafter(0.5, 1.0);
    object.material = scene.materials[0].name;
    object.transform.rotateDeg = Vec3(-0.0, 359.99999999999, 1e-12);
    scene.objects.push_back(object);
    const Scene back = sceneFromJson(sceneToJson(scene), "memory", "");
    expectScenesEqual(scene, back);
}

TEST(SceneIo, SavedTextPutsOneObjectPerLine) {
    TempDir dir;
    Scene scene = loadScene(writeEveryShapeScene(dir));
    const std::string text = formatSceneText(sceneToJson(scene));
    EXPECT_NE(text.find(R"(    {"id": "floor", "shape": {"type": "quad", "size": [2.0, 3.0]}, )"
                        R"("material": "white"},)"),
              std::string::npos)
        << text;
    EXPECT_EQ(text.back(), '\n');
}

// ---------------------------------------------------------------------------------------------
// Transform order.

/// Rotation about one axis by `degrees`, written out element by element (not via glm::rotate).
Mat4 axisRotation(int axis, double degrees) {
    const double r = degrees * M_PI / 180.0;
    const double c = std::cos(r), s = std::sin(r);
    Mat4 m(1.0);  // glm is column-major: m[column][row]
    const int i = (axis + 1) % 3, j = (axis + 2) % 3;
    m[i][i] = c;
    m[j][i] = -s;
    m[i][j] = s;
    m[j][j] = c;
    return m;
}

TEST(Transform, WorldFromObjectIsTranslateRotateZYXScale) {
    Transform transform;
    transform.translate = Vec3(1.5, -2.0, 0.25);
    transform.rotateDeg = Vec3(30.0, -45.0, 110.0);
    transform.scale = Vec3(2.0, 0.5, -3.0);

    Mat4 scale(1.0), translate(1.0);
    scale[0][0] = 2.0;
    scale[1][1] = 0.5;
    scale[2][2] = -3.0;
    translate[3] = glm::dvec4(1.5, -2.0, 0.25, 1.0);
    const Mat4 expected =
        translate * axisRotation(2, 110.0) * axisRotation(1, -45.0) * axisRotation(0, 30.0) * scale;
    const Mat4 actual = transform.worldFromObject();
    for (int c = 0; c < 4; ++c) {
        for (int r = 0; r < 4; ++r) {
            EXPECT_NEAR(actual[c][r], expected[c][r], 1e-12)
                << "column " << c << " row " << r << " of " << transform.toString();
        }
    }
}

TEST(Transform, RotationsAreRightHandedAndApplyXThenYThenZ) {
    auto apply = [](const Transform& t, Vec3 p) {
        return Vec3(t.worldFromObject() * glm::dvec4(p, 1.0));
    };
    auto expectNear = [](Vec3 a, Vec3 b, const std::string& what) {
        EXPECT_NEAR(glm::length(a - b), 0.0, 1e-12)
            << what << ": got (" << a.x << ", " << a.y << ", " << a.z << ")";
    };
    Transform t;
    t.rotateDeg = Vec3(90, 0, 0);
    expectNear(apply(t, Vec3(0, 1, 0)), Vec3(0, 0, 1), "Rx(90) maps +Y to +Z");
    t.rotateDeg = Vec3(0, 90, 0);
    expectNear(apply(t, Vec3(0, 0, 1)), Vec3(1, 0, 0), "Ry(90) maps +Z to +X");
    t.rotateDeg = Vec3(0, 0, 90);
    expectNear(apply(t, Vec3(1, 0, 0)), Vec3(0, 1, 0), "Rz(90) maps +X to +Y");
    // X first, then Y: +Y →Rx→ +Z →Ry→ +X (the other order would give +Z).
    t.rotateDeg = Vec3(90, 90, 0);
    expectNear(apply(t, Vec3(0, 1, 0)), Vec3(1, 0, 0), "Rx then Ry");
    // Scale before rotation, translation last.
    t.rotateDeg = Vec3(0, 0, 90);
    t.scale = Vec3(2, 1, 1);
    t.translate = Vec3(0, 0, 5);
    expectNear(apply(t, Vec3(1, 0, 0)), Vec3(0, 2, 5), "S, then Rz, then T");
}

// ---------------------------------------------------------------------------------------------
// Mesh formats.

TEST(MeshIo, TriangulatesConcavePolygonsExactly) {
    TempDir dir;
    // An L-shaped hexagon (area 3) in the XZ plane, counter-clockwise seen from +Y, whose fan
    // from vertex 1 would cover the notch.
    const std::string path = dir.write("l.obj", R"(v 0 0 0
v 0 0 2
v 2 0 2
v 2 0 1
v 1 0 1
v 1 0 0
f 1 2 3 4 5 6
)");
    const TriMesh mesh = loadMeshFile(path);
    ASSERT_EQ(mesh.triangles.size(), 4u);
    EXPECT_NEAR(meshArea(mesh), 3.0, 1e-12);
    for (size_t t = 0; t < mesh.triangles.size(); ++t) {
        EXPECT_GT(triangleNormal(mesh, t).y, 0.0) << "triangle " << t << " flipped";
    }
    EXPECT_TRUE(mesh.triangleMaterial.empty());
}

TEST(MeshIo, ObjFacesWithoutMaterialGetDefault) {
    TempDir dir;
    dir.write("m.mtl", "newmtl blue\nKd 0.1 0.2 0.9\n");
    const std::string path = dir.write("m.obj", R"(mtllib m.mtl
v 0 0 0
v 1 0 0
v 0 1 0
v 1 1 0
f 1 2 3
usemtl blue
f 2 4 3
)");
    const TriMesh mesh = loadMeshFile(path);
    ASSERT_EQ(mesh.triangleMaterial.size(), 2u);
    ASSERT_EQ(mesh.materialNames, (std::vector<std::string>{"blue", "default"}));
    EXPECT_EQ(mesh.triangleMaterial[0], 1);
    EXPECT_EQ(mesh.triangleMaterial[1], 0);
}

TEST(MeshIo, GltfMirroringNodeKeepsFrontFace) {
    TempDir dir;
    // Triangle facing +Z, mirrored in X: still facing +Z after the winding fix.
    const std::string path =
        writeTriangleGltf(dir, "mirror", {0, 0, 0, 1, 0, 0, 0, 1, 0}, R"("scale":[-1,1,1])");
    const TriMesh mesh = loadMeshFile(path);
    ASSERT_EQ(mesh.triangles.size(), 1u);
    EXPECT_GT(triangleNormal(mesh, 0).z, 0.0);
}

TEST(MeshIo, MissingUnreadableAndUnsupportedFilesThrow) {
    TempDir dir;
    const std::string missing = dir.file("nope.obj");
    std::string message = inputErrorOf([&] { loadMeshFile(missing); });
    EXPECT_TRUE(startsWith(message, missing + ": ")) << message;
    EXPECT_NE(message.find("does not exist"), std::string::npos) << message;

    const std::string garbage = dir.write("garbage.off", "this is not an OFF file\n");
    message = inputErrorOf([&] { loadMeshFile(garbage); });
    EXPECT_TRUE(startsWith(message, garbage + ": ")) << message;

    const std::string badGltf = dir.write("bad.gltf", "{ not json");
    message = inputErrorOf([&] { loadMeshFile(badGltf); });
    EXPECT_TRUE(startsWith(message, badGltf + ": not a valid glTF file")) << message;
    EXPECT_EQ(message.find('\n'), std::string::npos) << message;

    const std::string unsupported = dir.write("mesh.3ds", "x");
    message = inputErrorOf([&] { loadMeshFile(unsupported); });
    EXPECT_NE(message.find("unsupported mesh format '.3ds'"), std::string::npos) << message;

    const std::string outOfRange = dir.write("range.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n");
    message = inputErrorOf([&] { loadMeshFile(outOfRange); });
    EXPECT_TRUE(startsWith(message, outOfRange + ": ")) << message;

    EXPECT_TRUE(startsWith(inputErrorOf([&] { loadMeshFile(dir.path().string()); }),
                           dir.path().string() + ": "));
}

/// A binary PLY quad (two triangles, area 1, facing +Y) with extra properties and elements
/// that the reader must skip.
std::string binaryPly(bool bigEndian) {
    std::string bytes = std::string("ply\nformat ") +
                        (bigEndian ? "binary_big_endian" : "binary_little_endian") +
                        " 1.0\ncomment made by a test\nelement vertex 4\nproperty float x\n"
                        "property float y\nproperty float z\nproperty uchar red\n"
                        "element face 1\nproperty list uchar int vertex_indices\n"
                        "property short flags\nelement edge 1\nproperty int a\nproperty int b\n"
                        "end_header\n";
    auto put = [&](const void* data, size_t size) {
        std::string raw(static_cast<const char*>(data), size);
        if (bigEndian) std::reverse(raw.begin(), raw.end());
        bytes += raw;
    };
    const float positions[4][3] = {{0, 0, 0}, {0, 0, 1}, {1, 0, 1}, {1, 0, 0}};
    for (const auto& p : positions) {
        for (float c : p) put(&c, 4);
        const uint8_t red = 200;
        put(&red, 1);
    }
    const uint8_t n = 4;
    put(&n, 1);
    for (int32_t i : {0, 1, 2, 3}) put(&i, 4);
    const int16_t flags = -1;
    put(&flags, 2);
    for (int32_t i : {0, 1}) put(&i, 4);
    return bytes;
}

TEST(MeshIo, ReadsBinaryPlyOfBothByteOrders) {
    TempDir dir;
    for (bool bigEndian : {false, true}) {
        const std::string path = dir.write(bigEndian ? "be.ply" : "le.ply", binaryPly(bigEndian));
        const TriMesh mesh = loadMeshFile(path);
        ASSERT_EQ(mesh.triangles.size(), 2u) << path;
        EXPECT_NEAR(meshArea(mesh), 1.0, 1e-12) << path;
        for (size_t t = 0; t < 2; ++t) EXPECT_GT(triangleNormal(mesh, t).y, 0.0) << path;
    }
}

TEST(MeshIo, ReadsOffVariants) {
    TempDir dir;
    // Counts on the header line, comments, per-vertex and per-face colours.
    const std::string path = dir.write("c.off", R"(COFF 4 1 0  # counts here
# a comment line

0 0 0 255 0 0 255
0 0 1 255 0 0 255
1 0 1 255 0 0 255   # trailing comment
1 0 0 255 0 0 255
4 0 1 2 3 0.5 0.5 0.5
)");
    const TriMesh mesh = loadMeshFile(path);
    ASSERT_EQ(mesh.triangles.size(), 2u);
    EXPECT_NEAR(meshArea(mesh), 1.0, 1e-12);
}

TEST(MeshIo, MalformedOffAndPlyFailCleanly) {
    TempDir dir;
    const std::string truncatedBinary = binaryPly(false).substr(0, binaryPly(false).size() - 12);
    const std::vector<std::pair<std::string, std::string>> cases = {
        {"negative.off", "OFF\n4 -04 0 0\n0 1 0\n"},
        {"huge.off", "OFF\n4000000000 1 0\n0 0 0\n"},
        {"short.off", "OFF\n4 1 0\n0 0 0\n1 0 0\n"},
        {"badvertex.off", "OFF\n3 1 0\n0 0 0\n1 x 0\n0 1 0\n3 0 1 2\n"},
        {"facecount.off", "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n5 0 1 2\n"},
        {"header.off", "OFX\n3 1 0\n"},
        {"empty.off", ""},
        {"header1.ply", "ply\nformat ascii 1.0\nelement vertex property float x\nend_header\n"},
        {"header2.ply", "ply\nformat ascii 1.0\nelemen]t vertex 4\nend_header\n"},
        {"header3.ply", "ply\nformat ascii 1.0\nelement vertex 4\nproperty floatf x\nend_header\n"},
        {"noend.ply", "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n"},
        {"noxyz.ply", "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nend_header\n1\n"},
        {"truncated.ply", truncatedBinary},
        {"listlength.ply",
         "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
         "property float z\nelement face 1\nproperty list uint int vertex_indices\nend_header\n"
         "0 0 0\n1 0 0\n0 1 0\n4000000000 0 1 2\n"},
        {"garbage.ply",
         "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
         "property float z\nend_header\n0 0 0\n1 0 1f\n"},
    };
    for (const auto& [name, text] : cases) {
        const std::string path = dir.write(name, text);
        const std::string message = inputErrorOf([&] { loadMeshFile(path); });
        EXPECT_TRUE(startsWith(message, path + ": ")) << name << ": " << message;
        EXPECT_EQ(message.find('\n'), std::string::npos) << message;
    }
}

// ---------------------------------------------------------------------------------------------
// Degenerate faces.

TEST(MeshIo, DropsDegenerateFacesWithOneWarning) {
    TempDir dir;
    // Two good triangles, one with a repeated vertex, one with three collinear vertices.
    const std::string path = dir.write("degenerate.obj", R"(v 0 0 0
v 1 0 0
v 0 1 0
v 1 1 0
v 2 2 0
f 1 2 3
f 2 4 3
f 1 1 2
f 1 4 5
)");
    test::LogCapture capture;
    const TriMesh mesh = loadMeshFile(path);
    const std::string warning = capture.text();
    EXPECT_EQ(mesh.triangles.size(), 2u);
    EXPECT_EQ(mesh.positions.size(), 4u) << "the unused vertex 5 is dropped";
    EXPECT_EQ(std::count(warning.begin(), warning.end(), '\n'), 1) << warning;
    EXPECT_EQ(warning.rfind("warning: " + path + ": dropped 2 degenerate faces", 0), 0u)
        << warning;
}

TEST(MeshIo, DropsDegenerateFacesInOpenMeshFormats) {
    TempDir dir;
    const std::string path = dir.write("degenerate.off", R"(OFF
4 3 0
0 0 0
1 0 0
0 1 0
1 1 0
3 0 1 2
3 1 3 2
3 0 0 3
)");
    test::LogCapture capture;
    const TriMesh mesh = loadMeshFile(path);
    const std::string warning = capture.text();
    EXPECT_EQ(mesh.triangles.size(), 2u);
    EXPECT_EQ(std::count(warning.begin(), warning.end(), '\n'), 1) << warning;
    EXPECT_NE(warning.find(path + ": dropped 1 degenerate face "), std::string::npos) << warning;
}

TEST(MeshIo, DropsFacesWithNonFiniteCoordinates) {
    TempDir dir;
    const float nan = std::numeric_limits<float>::quiet_NaN();
    const std::string buffer = [&] {
        std::string bytes;
        appendFloats(bytes, {0, 0, 0, 1, 0, 0, 0, 1, 0, nan, 0, 0});
        appendUint16s(bytes, {0, 1, 2, 1, 3, 2});
        return bytes;
    }();
    dir.write("nan.bin", buffer);
    std::string json = triangleGltfJson(R"({"uri":"nan.bin","byteLength":60})", 48, "");
    // Four positions and six indices instead of three and three.
    json.replace(json.find(R"("byteLength":6})"), 15, R"("byteLength":12})");
    json.replace(json.find(R"("count":3,"type":"VEC3")"), 9, R"("count":4)");
    json.replace(json.find(R"("count":3,"type":"SCALAR")"), 9, R"("count":6)");
    const std::string path = dir.write("nan.gltf", json);
    test::LogCapture capture;
    const TriMesh mesh = loadMeshFile(path);
    const std::string warning = capture.text();
    EXPECT_EQ(mesh.triangles.size(), 1u);
    for (const Vec3& p : mesh.positions) EXPECT_TRUE(std::isfinite(p.x));
    EXPECT_NE(warning.find("dropped 1 degenerate face"), std::string::npos) << warning;
}

TEST(MeshIo, MeshWithOnlyDegenerateFacesThrows) {
    TempDir dir;
    const std::string path = dir.write("flat.obj", "v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n");
    const std::string message = inputErrorOf([&] { loadMeshFile(path); });
    EXPECT_TRUE(startsWith(message, path + ": mesh has no valid faces")) << message;
}

// ---------------------------------------------------------------------------------------------
// Bad scene input: one case per class; each message must be `FILE: KEY: problem`.

struct BadScene {
    const char* name;
    std::string text;     ///< scene file text
    std::string where;    ///< expected key path (or line/column) right after the file name
    std::string problem;  ///< expected substring of the problem
};

/// A valid scene with `objects` spliced in, plus extra top-level text.
std::string sceneWith(const std::string& objects,
                      const std::string& materials = R"("white": {"reflectance": [0.5, 0.5, 0.5]})",
                      const std::string& extra = "") {
    return R"({"format": "penumbra-scene/1", "materials": {)" + materials + R"(}, "objects": [)" +
           objects + "]" + extra + "}";
}

const std::string kBox =
    R"({"id": "a", "shape": {"type": "box", "size": [1, 1, 1]}, "material": "white"})";

std::vector<BadScene> badScenes() {
    return {
        {"UnknownTopLevelKey",
         sceneWith(kBox, R"("white": {"reflectance": [0.5, 0.5, 0.5]})", R"(, "lights": [])"),
         "lights", "unknown key 'lights'"},
        {"UnknownNestedKey",
         sceneWith(
             R"({"id": "a", "shape": {"type": "box", "size": [1, 1, 1], "colour": 1}, "material": "white"})"),
         "objects[0].shape.colour", "unknown key 'colour' for a box"},
        {"KeyOfOtherShapeType",
         sceneWith(
             R"({"id": "a", "shape": {"type": "quad", "size": [1, 1], "radius": 1}, "material": "white"})"),
         "objects[0].shape.radius", "unknown key 'radius' for a quad"},
        {"WrongType",
         sceneWith(
             R"({"id": "a", "shape": {"type": "sphere", "radius": "big"}, "material": "white"})"),
         "objects[0].shape.radius", "expected a number, got a string"},
        {"WrongArrayLength",
         sceneWith(R"({"id": "a", "shape": {"type": "box", "size": [1, 1]}, "material": "white"})"),
         "objects[0].shape.size", "expected an array of 3 numbers"},
        {"WrongTypeId",
         sceneWith(
             R"({"id": 7, "shape": {"type": "box", "size": [1, 1, 1]}, "material": "white"})"),
         "objects[0].id", "expected a string, got a number"},
        {"MissingRequiredKey",
         sceneWith(kBox +
                   R"(, {"shape": {"type": "box", "size": [1, 1, 1]}, "material": "white"})"),
         "objects[1].id", "missing required key"},
        {"MissingMaterial",
         sceneWith(R"({"id": "a", "shape": {"type": "box", "size": [1, 1, 1]}})"),
         "objects[0].material", "missing required key"},
        {"MissingFormat", R"({"objects": []})", "format", "missing required key"},
        {"ObjectPatchSizeBelowElementSize",
         sceneWith(
             R"({"id": "a", "shape": {"type": "box", "size": [1, 1, 1]}, "material": "white", "patch_size": 0.001})"),
         "objects[0].patch_size", "must not be below the scene's element_size"},
        {"ObjectPatchSizeNotPositive",
         sceneWith(
             R"({"id": "a", "shape": {"type": "box", "size": [1, 1, 1]}, "material": "white", "patch_size": -1})"),
         "objects[0].patch_size", "positive"},
        {"MissingMeshFile",
         sceneWith(
             R"({"id": "m", "shape": {"type": "mesh", "file": "meshes/none.obj"}, "material": "white"})"),
         "objects[0].shape.file", "none.obj: mesh file does not exist"},
        {"UnreadableMeshFile",
         sceneWith(
             R"({"id": "m", "shape": {"type": "mesh", "file": "garbage.ply"}, "material": "white"})"),
         "objects[0].shape.file", "garbage.ply: line 2: expected 'format"},
        {"MeshWithoutOwnMaterials",
         sceneWith(R"({"id": "m", "shape": {"type": "mesh", "file": "plain.off"}})"),
         "objects[0].material", "carries no materials"},
        {"ReflectanceOne", sceneWith(kBox, R"("white": {"reflectance": [1.0, 0.5, 0.5]})"),
         "materials.white.reflectance", "must be in [0, 1)"},
        {"ReflectanceNegative", sceneWith(kBox, R"("white": {"reflectance": [0.5, -0.1, 0.5]})"),
         "materials.white.reflectance", "must be in [0, 1)"},
        {"NegativeEmission",
         sceneWith(kBox, R"("white": {"reflectance": [0.5, 0.5, 0.5], "emission": [1, -2, 0]})"),
         "materials.white.emission", "must not be negative"},
        {"DuplicateObjectId", sceneWith(kBox + ", " + kBox), "objects[1].id",
         "duplicate object id 'a' (also objects[0])"},
        {"DuplicateMaterialName",
         sceneWith(
             kBox,
             R"("white": {"reflectance": [0.5, 0.5, 0.5]}, "white": {"reflectance": [0.2, 0.2, 0.2]})"),
         "materials.white", "duplicate material name 'white'"},
        {"UnknownMaterial",
         sceneWith(
             R"({"id": "a", "shape": {"type": "box", "size": [1, 1, 1]}, "material": "red"})"),
         "objects[0].material", "unknown material 'red'"},
        {"ZeroSize",
         sceneWith(
             R"({"id": "a", "shape": {"type": "quad", "size": [1, 0]}, "material": "white"})"),
         "objects[0].shape.size", "sizes must be positive"},
        {"NegativeRadius",
         sceneWith(
             R"({"id": "a", "shape": {"type": "sphere", "radius": -1}, "material": "white"})"),
         "objects[0].shape.radius", "must be positive"},
        {"ZeroHeight",
         sceneWith(
             R"({"id": "a", "shape": {"type": "cylinder", "radius": 1, "height": 0}, "material": "white"})"),
         "objects[0].shape.height", "must be positive"},
        {"TooFewSegments",
         sceneWith(
             R"({"id": "a", "shape": {"type": "sphere", "radius": 1, "segments": 2}, "material": "white"})"),
         "objects[0].shape.segments", "segments must be between 3 and"},
        {"ZeroScale",
         sceneWith(
             R"({"id": "a", "shape": {"type": "box", "size": [1, 1, 1]}, "material": "white", "transform": {"scale": [1, 0, 1]}})"),
         "objects[0].transform.scale", "scale components must be non-zero"},
        {"UnsupportedFormat", R"({"format": "penumbra-scene/2", "objects": []})", "format",
         "unsupported format 'penumbra-scene/2'"},
        {"MalformedJson", "{\n  \"format\": \"penumbra-scene/1\",\n  \"objects\": [\n}\n",
         "line 4, column 1", "syntax error"},
        {"UnknownShapeType",
         sceneWith(R"({"id": "a", "shape": {"type": "cone"}, "material": "white"})"),
         "objects[0].shape.type", "unknown shape type 'cone'"},
        {"EmptyId",
         sceneWith(
             R"({"id": "", "shape": {"type": "box", "size": [1, 1, 1]}, "material": "white"})"),
         "objects[0].id", "must not be empty"},
        {"ElementLargerThanPatch",
         sceneWith(kBox, R"("white": {"reflectance": [0.5, 0.5, 0.5]})",
                   R"(, "settings": {"patch_size": 0.1, "element_size": 0.2})"),
         "settings.element_size", "must not exceed patch_size"},
        {"HolodeckSectionInsideOut",
         sceneWith(kBox, R"("white": {"reflectance": [0.5, 0.5, 0.5]})",
                   R"(, "settings": {"holodeck": [{"min": [0, 0, 0], "max": [1, -1, 1]}]})"),
         "settings.holodeck[0].max", "must exceed min"},
        {"HolodeckSectionUnknownKind",
         sceneWith(
             kBox, R"("white": {"reflectance": [0.5, 0.5, 0.5]})",
             R"(, "settings": {"holodeck": [{"kind": "outer", "min": [0, 0, 0], "max": [1, 1, 1]}]})"),
         "settings.holodeck[0].kind", "kind must be \"interior\" or \"exterior\""},
        {"HolodeckGridOutOfRange",
         sceneWith(
             kBox, R"("white": {"reflectance": [0.5, 0.5, 0.5]})",
             R"(, "settings": {"holodeck": [{"min": [0, 0, 0], "max": [1, 1, 1], "grid": [4, 0, 4]}]})"),
         "settings.holodeck[0].grid[1]", "cells must be in [1, 1024]"},
        {"HolodeckNotAnArray",
         sceneWith(kBox, R"("white": {"reflectance": [0.5, 0.5, 0.5]})",
                   R"(, "settings": {"holodeck": {"min": [0, 0, 0]}})"),
         "settings.holodeck", "expected a non-empty array of sections"},
        {"BadCameraFov",
         sceneWith(
             kBox, R"("white": {"reflectance": [0.5, 0.5, 0.5]})",
             R"(, "cameras": {"main": {"position": [0, 0, 1], "look_at": [0, 0, 0], "fov_deg": 180}})"),
         "cameras.main.fov_deg", "fov_deg must be in (0, 180)"},
        {"TopLevelNotObject", "[1, 2]", "", "expected a JSON object at the top level"},
        {"EmptyFile", "\n", "", "file is empty"},
        {"TrailingGarbage", sceneWith(kBox) + " x", "line 1, column 182", "syntax error"},
        {"DuplicateKeyInObject",
         sceneWith(
             R"({"id": "a", "id": "b", "shape": {"type": "box", "size": [1, 1, 1]}, "material": "white"})"),
         "objects[0].id", "duplicate key 'id'"},
        {"DeepNesting",
         sceneWith(kBox, R"("white": {"reflectance": [0.5, 0.5, 0.5]})",
                   ", \"x\": " + std::string(100, '[') + std::string(100, ']')),
         [] {
             std::string where = "x";
             for (int i = 0; i < 64; ++i) where += "[0]";
             return where;
         }(),
         "nesting deeper than 64 levels"},
    };
}

void PrintTo(const BadScene& bad, std::ostream* out) { *out << bad.name; }

class BadSceneTest : public ::testing::TestWithParam<BadScene> {};

TEST_P(BadSceneTest, ErrorNamesFileAndKey) {
    const BadScene& bad = GetParam();
    TempDir dir;
    dir.write("garbage.ply", "ply\nthis is not a ply header\n");
    dir.write("plain.off", kTetraOff);
    const std::string path = dir.write("bad.json", bad.text);
    const std::string message = inputErrorOf([&] { loadScene(path); });
    const std::string prefix = path + ": " + (bad.where.empty() ? "" : bad.where + ": ");
    EXPECT_TRUE(startsWith(message, prefix)) << "expected prefix '" << prefix << "' in\n"
                                             << message;
    EXPECT_NE(message.find(bad.problem), std::string::npos)
        << "expected '" << bad.problem << "' in\n"
        << message;
    EXPECT_EQ(message.find('\n'), std::string::npos) << message;
}

INSTANTIATE_TEST_SUITE_P(EveryClass, BadSceneTest, ::testing::ValuesIn(badScenes()),
                         [](const auto& info) { return std::string(info.param.name); });

TEST(SceneIo, HolodeckSectionsRoundTrip) {
    TempDir dir;
    const std::string path = dir.write(
        "holo.json",
        sceneWith(kBox, R"("white": {"reflectance": [0.5, 0.5, 0.5]})",
                  R"(, "settings": {"holodeck": [{"min": [-1, 0, -2], "max": [1, 3, 2]},)"
                  R"( {"kind": "exterior", "min": [0, 0, 0], "max": [0.5, 0.5, 0.5], "grid": [6, 5, 4]}]})"));
    const Scene scene = loadScene(path);
    ASSERT_EQ(scene.settings.holodeck.size(), 2u);
    const HolodeckSectionSetting& room = scene.settings.holodeck[0];
    EXPECT_FALSE(room.exterior);
    EXPECT_EQ(room.min, Vec3(-1, 0, -2));
    EXPECT_EQ(room.max, Vec3(1, 3, 2));
    EXPECT_EQ(room.grid, (std::array<int, 3>{0, 0, 0}));
    const HolodeckSectionSetting& object = scene.settings.holodeck[1];
    EXPECT_TRUE(object.exterior);
    EXPECT_EQ(object.grid, (std::array<int, 3>{6, 5, 4}));
    // Saved and read again: the same sections, and the same text.
    const std::string saved = dir.file("saved.json");
    saveScene(scene, saved);
    const Scene again = loadScene(saved);
    ASSERT_EQ(again.settings.holodeck.size(), 2u);
    for (std::size_t i = 0; i < 2; ++i) {
        EXPECT_EQ(again.settings.holodeck[i].exterior, scene.settings.holodeck[i].exterior);
        EXPECT_EQ(again.settings.holodeck[i].min, scene.settings.holodeck[i].min);
        EXPECT_EQ(again.settings.holodeck[i].max, scene.settings.holodeck[i].max);
        EXPECT_EQ(again.settings.holodeck[i].grid, scene.settings.holodeck[i].grid);
    }
    EXPECT_EQ(sceneToJson(scene), sceneToJson(again));
    // A scene without them writes none.
    EXPECT_FALSE(sceneToJson(Scene{})["settings"].contains("holodeck"));
}

TEST(SceneIo, MissingSceneFileThrows) {
    TempDir dir;
    const std::string path = dir.file("absent.json");
    const std::string message = inputErrorOf([&] { loadScene(path); });
    EXPECT_TRUE(startsWith(message, path + ": cannot read scene file")) << message;
}

TEST(SceneIo, NonFiniteNumbersAreRejected) {
    // JSON text cannot hold NaN or infinity, but a JSON value built in code can.
    for (double bad :
         {std::numeric_limits<double>::quiet_NaN(), std::numeric_limits<double>::infinity()}) {
        nlohmann::ordered_json json = nlohmann::ordered_json::parse(sceneWith(kBox));
        json["objects"][0]["transform"] = {{"translate", {0.0, bad, 0.0}}};
        const std::string message = inputErrorOf([&] { sceneFromJson(json, "memory.json", ""); });
        EXPECT_TRUE(startsWith(
            message, "memory.json: objects[0].transform.translate[1]: not a finite number"))
            << message;
    }
}

TEST(SceneIo, UnorderedJsonOverloadAccepted) {
    const nlohmann::json json = nlohmann::json::parse(sceneWith(kBox));
    const Scene scene = sceneFromJson(json, "memory.json", "");
    ASSERT_EQ(scene.objects.size(), 1u);
    EXPECT_EQ(scene.objects[0].id, "a");
}

// ---------------------------------------------------------------------------------------------
// API pieces for the edit log.

TEST(SceneIo, ObjectFromJsonReportsEditLogLocation) {
    const Scene scene = sceneFromJson(nlohmann::ordered_json::parse(sceneWith(kBox)), "s.json", "");
    const nlohmann::json add = nlohmann::json::parse(
        R"({"id": "b", "shape": {"type": "sphere", "radius": 0}, "material": "white"})");
    const std::string message =
        inputErrorOf([&] { objectFromJson(add, scene, "edits.jsonl", "line 7: object", ""); });
    EXPECT_EQ(message, "edits.jsonl: line 7: object.shape.radius: must be positive, got 0");

    const SceneObject ok = objectFromJson(
        nlohmann::json::parse(
            R"({"id": "b", "shape": {"type": "sphere", "radius": 1}, "material": "white"})"),
        scene, "edits.jsonl", "line 8: object", "");
    EXPECT_EQ(ok.shape.type, ShapeType::Sphere);
}

TEST(SceneIo, PartialMaterialAndTransformKeepBase) {
    Material base;
    base.emission = Rgb(5.0);
    const Material edited =
        materialFromJson(nlohmann::ordered_json::parse(R"({"reflectance": [0.8, 0.2, 0.2]})"),
                         "log", "line 1: material", base);
    expectVec3Eq(edited.reflectance, Rgb(0.8, 0.2, 0.2), "edited");
    expectVec3Eq(edited.emission, Rgb(5.0), "kept");

    Transform start;
    start.scale = Vec3(2.0);
    const Transform moved =
        transformFromJson(nlohmann::ordered_json::parse(R"({"translate": [0.5, 0, 0.2]})"), "log",
                          "line 2: transform", start);
    expectVec3Eq(moved.translate, Vec3(0.5, 0, 0.2), "edited");
    expectVec3Eq(moved.scale, Vec3(2.0), "kept");
}

// ---------------------------------------------------------------------------------------------
// Saving.

TEST(SceneIo, SaveIsAtomicAndKeepsPermissions) {
    TempDir dir;
    Scene scene;
    scene.materials.push_back({"white", Material{}});
    const std::string path = dir.write("out.json", "old contents");
    ::chmod(path.c_str(), 0640);
    saveScene(scene, path);
    struct stat info {};
    ASSERT_EQ(::stat(path.c_str(), &info), 0);
    EXPECT_EQ(info.st_mode & 0777, 0640u);
    // Only the target remains: the temporary file was renamed, not left behind.
    size_t files = 0;
    for (const auto& entry : fs::directory_iterator(dir.path())) {
        ++files;
        EXPECT_EQ(entry.path().filename(), "out.json");
    }
    EXPECT_EQ(files, 1u);
    EXPECT_EQ(loadScene(path).materials.size(), 1u);

    // A new file: 0666 less the umask, as any file the user's programs create.
    const std::string fresh = dir.file("new.json");
    const mode_t mask = ::umask(022);
    saveScene(scene, fresh);
    ::umask(mask);
    ASSERT_EQ(::stat(fresh.c_str(), &info), 0);
    EXPECT_EQ(info.st_mode & 0777, 0644u);
}

TEST(SceneIo, SaveIntoMissingDirectoryThrows) {
    TempDir dir;
    const std::string path = dir.file("no/such/dir/out.json");
    const std::string message = inputErrorOf([&] { saveScene(Scene{}, path); });
    EXPECT_TRUE(startsWith(message, path + ": cannot write")) << message;
    EXPECT_NE(message.find(std::strerror(ENOENT)), std::string::npos) << message;
}

}  // namespace
}  // namespace penumbra
