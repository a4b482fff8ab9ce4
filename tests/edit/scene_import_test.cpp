// glTF and OBJ scene import (edit/io/scene_import.h) against hand-made files: node transforms
// (TRS, matrix, hierarchy) checked with independently written trigonometry, materials,
// emissive surfaces, point lights (power), cameras, OBJ with MTL and units; the furnace and
// Lambert closed forms solved through imported files; Penumbra's own glTF export read back;
// bad files refused with one line naming the file.

#include "edit/io/scene_import.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "core/input_error.h"
#include "edit/io/export.h"
#include "edit/io/scene_io.h"
#include "solver/discretization.h"
#include "solver/progressive_solver.h"
#include "solver/ray_tracer.h"
#include "test_scenes.h"

namespace penumbra {
namespace {

namespace fs = std::filesystem;

fs::path tempDir() {
    const fs::path dir =
        fs::temp_directory_path() /
        ("penumbra-import-" + std::to_string(::testing::UnitTest::GetInstance()->random_seed()) +
         "-" + ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir);
    fs::create_directories(dir);
    return dir;
}

std::string base64(const std::string& bytes) {
    static const char* table = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    std::string out;
    std::size_t i = 0;
    for (; i + 2 < bytes.size(); i += 3) {
        const unsigned v = (static_cast<unsigned char>(bytes[i]) << 16) |
                           (static_cast<unsigned char>(bytes[i + 1]) << 8) |
                           static_cast<unsigned char>(bytes[i + 2]);
        for (int k = 3; k >= 0; --k) out += table[(v >> (6 * k)) & 63];
    }
    if (i + 1 == bytes.size()) {
        const unsigned v = static_cast<unsigned char>(bytes[i]) << 16;
        out += table[(v >> 18) & 63];
        out += table[(v >> 12) & 63];
        out += "==";
    } else if (i + 2 == bytes.size()) {
        const unsigned v = (static_cast<unsigned char>(bytes[i]) << 16) |
                           (static_cast<unsigned char>(bytes[i + 1]) << 8);
        out += table[(v >> 18) & 63];
        out += table[(v >> 12) & 63];
        out += table[(v >> 6) & 63];
        out += '=';
    }
    return out;
}

/// A glTF file written by hand: one buffer (a data URI), one accessor pair per mesh.
struct Gltf {
    nlohmann::json j = {{"asset", {{"version", "2.0"}}}};
    std::string buffer;

    int mesh(const std::vector<Vec3>& positions, const std::vector<unsigned>& indices,
             int material) {
        auto view = [&](const void* data, std::size_t bytes, int target) {
            while (buffer.size() % 4) buffer += '\0';
            const std::size_t offset = buffer.size();
            buffer.append(static_cast<const char*>(data), bytes);
            j["bufferViews"].push_back(
                {{"buffer", 0}, {"byteOffset", offset}, {"byteLength", bytes}, {"target", target}});
            return static_cast<int>(j["bufferViews"].size()) - 1;
        };
        std::vector<float> xyz;
        Vec3 lo(1e30), hi(-1e30);
        for (const Vec3& p : positions) {
            for (int c = 0; c < 3; ++c) xyz.push_back(static_cast<float>(p[c]));
            lo = glm::min(lo, Vec3(glm::vec3(p)));
            hi = glm::max(hi, Vec3(glm::vec3(p)));
        }
        const int pv = view(xyz.data(), xyz.size() * 4, 34962);
        j["accessors"].push_back({{"bufferView", pv},
                                  {"componentType", 5126},
                                  {"count", positions.size()},
                                  {"type", "VEC3"},
                                  {"min", {lo.x, lo.y, lo.z}},
                                  {"max", {hi.x, hi.y, hi.z}}});
        const int pa = static_cast<int>(j["accessors"].size()) - 1;
        const int iv = view(indices.data(), indices.size() * 4, 34963);
        j["accessors"].push_back({{"bufferView", iv},
                                  {"componentType", 5125},
                                  {"count", indices.size()},
                                  {"type", "SCALAR"}});
        nlohmann::json primitive = {{"attributes", {{"POSITION", pa}}},
                                    {"indices", static_cast<int>(j["accessors"].size()) - 1}};
        if (material >= 0) primitive["material"] = material;
        j["meshes"].push_back({{"primitives", {primitive}}});
        return static_cast<int>(j["meshes"].size()) - 1;
    }
    int material(const std::string& name, Rgb base, Rgb emissive = Rgb(0.0), double strength = 1) {
        nlohmann::json m = {
            {"name", name},
            {"pbrMetallicRoughness", {{"baseColorFactor", {base.x, base.y, base.z, 1.0}}}}};
        if (emissive != Rgb(0.0)) m["emissiveFactor"] = {emissive.x, emissive.y, emissive.z};
        if (strength != 1) {
            m["extensions"]["KHR_materials_emissive_strength"]["emissiveStrength"] = strength;
            j["extensionsUsed"].push_back("KHR_materials_emissive_strength");
        }
        j["materials"].push_back(m);
        return static_cast<int>(j["materials"].size()) - 1;
    }
    int node(nlohmann::json n, bool root = true) {
        j["nodes"].push_back(n);
        const int index = static_cast<int>(j["nodes"].size()) - 1;
        if (root) j["scenes"][0]["nodes"].push_back(index);
        j["scene"] = 0;
        return index;
    }
    std::string write(const fs::path& path) {
        j["buffers"] = {{{"byteLength", buffer.size()},
                         {"uri", "data:application/octet-stream;base64," + base64(buffer)}}};
        std::ofstream(path) << j.dump();
        return path.string();
    }
};

/// A unit right triangle in the XY plane.
const std::vector<Vec3> kTriangle = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};

/// A w × d quad in the XZ plane at height 0, normal +Y (counter-clockwise seen from above).
std::vector<Vec3> quadXZ(double w, double d) {
    return {{-w / 2, 0, -d / 2}, {-w / 2, 0, d / 2}, {w / 2, 0, d / 2}, {w / 2, 0, -d / 2}};
}
const std::vector<unsigned> kQuadIndices = {0, 1, 2, 0, 2, 3};

std::vector<Vec3> worldPositions(const SceneObject& o) {
    std::vector<Vec3> out;
    for (const Vec3& p : o.shape.mesh.positions) out.push_back(test::worldPoint(o.transform, p));
    return out;
}

ImportOptions quiet(std::vector<std::string>* warnings = nullptr) {
    ImportOptions o;
    o.warn = [warnings](const std::string& line) {
        if (warnings) warnings->push_back(line);
    };
    return o;
}

TEST(SceneImport, NodeTransformsTrsMatrixAndHierarchyAreBakedIntoTheObjects) {
    const fs::path dir = tempDir();
    Gltf g;
    const int white = g.material("white", Rgb(0.5));
    const int tri = g.mesh(kTriangle, {0, 1, 2}, white);
    // TRS: scale 2, then 90° about +Y (quaternion (0, sin 45°, 0, cos 45°)), then (1, 2, 3).
    const double s = std::sqrt(0.5);
    const int parent = g.node({{"name", "trs"},
                               {"mesh", tri},
                               {"translation", {1, 2, 3}},
                               {"rotation", {0, s, 0, s}},
                               {"scale", {2, 2, 2}}});
    // The same transform as a column-major matrix.
    g.node({{"name", "matrix"},
            {"mesh", tri},
            {"matrix", {0, 0, -2, 0, 0, 2, 0, 0, 2, 0, 0, 0, 1, 2, 3, 1}}});
    // A child of the TRS node, 1 along its parent's X.
    const int child = g.node({{"name", "child"}, {"mesh", tri}, {"translation", {1, 0, 0}}}, false);
    g.j["nodes"][parent]["children"] = {child};
    const Scene scene = importScene(g.write(dir / "t.gltf"), quiet());

    ASSERT_EQ(scene.objects.size(), 3u);
    auto expected = [&](Vec3 p) {  // independent: scale, rotate about Y, translate
        return test::rotateAboutY(2.0 * p, 90) + Vec3(1, 2, 3);
    };
    for (const char* id : {"trs", "matrix"}) {
        const SceneObject& o = scene.objects[scene.findObject(id)];
        const std::vector<Vec3> w = worldPositions(o);
        ASSERT_EQ(w.size(), 3u) << id;
        for (int k = 0; k < 3; ++k)
            EXPECT_NEAR(glm::length(w[k] - expected(kTriangle[k])), 0, 1e-6)
                << id << " vertex " << k;
    }
    const std::vector<Vec3> c = worldPositions(scene.objects[scene.findObject("child")]);
    for (int k = 0; k < 3; ++k)
        EXPECT_NEAR(glm::length(c[k] - expected(kTriangle[k] + Vec3(1, 0, 0))), 0, 1e-6);
    // The object's translation is its bounding box's centre (the gizmo's place).
    const SceneObject& trs = scene.objects[scene.findObject("trs")];
    Vec3 lo(1e30), hi(-1e30);
    for (const Vec3& p : worldPositions(trs)) lo = glm::min(lo, p), hi = glm::max(hi, p);
    EXPECT_NEAR(glm::length(trs.transform.translate - 0.5 * (lo + hi)), 0, 1e-9);
}

TEST(SceneImport, SharedMaterialsNamesEmissionAndUniqueIds) {
    const fs::path dir = tempDir();
    Gltf g;
    const int red = g.material("red", Rgb(0.8, 0.1, 0.1));
    const int lamp = g.material("lamp", Rgb(0.0), Rgb(1.0, 0.5, 0.25), 4.0);
    const int bright = g.material("snow", Rgb(1.2, 1.0, 0.9));
    const int a = g.mesh(kTriangle, {0, 1, 2}, red);
    const int b = g.mesh(quadXZ(1, 1), kQuadIndices, red);
    g.node({{"name", "box"}, {"mesh", a}});
    g.node({{"name", "box"}, {"mesh", b}});
    g.node({{"name", "panel"}, {"mesh", g.mesh(quadXZ(0.5, 0.5), kQuadIndices, lamp)}});
    g.node({{"mesh", g.mesh(kTriangle, {0, 1, 2}, bright)}});
    std::vector<std::string> warnings;
    const Scene scene = importScene(g.write(dir / "m.gltf"), quiet(&warnings));

    ASSERT_EQ(scene.objects.size(), 4u);
    EXPECT_EQ(scene.objects[0].id, "box");
    EXPECT_EQ(scene.objects[1].id, "box-2");
    EXPECT_EQ(scene.objects[2].id, "panel");
    EXPECT_EQ(scene.objects[3].id, "object");
    EXPECT_EQ(scene.objects[0].material, "red");
    EXPECT_EQ(scene.objects[1].material, "red");
    std::size_t named = 0;
    for (const NamedMaterial& m : scene.materials) named += m.name == "red";
    EXPECT_EQ(named, 1u) << "two meshes sharing a material share one scene material";
    const Material* r = scene.findMaterial("red");
    ASSERT_NE(r, nullptr);
    EXPECT_EQ(r->reflectance, Rgb(0.8, 0.1, 0.1));
    // Emissive × strength is radiance: emission (radiosity) = π × it.
    const Material* l = scene.findMaterial("lamp");
    ASSERT_NE(l, nullptr);
    for (int c = 0; c < 3; ++c)
        EXPECT_NEAR(l->emission[c], M_PI * 4.0 * Rgb(1.0, 0.5, 0.25)[c], 1e-9);
    // A base colour above 1 is clamped, with one warning naming the material.
    const Material* snow = scene.findMaterial("snow");
    ASSERT_NE(snow, nullptr);
    EXPECT_EQ(snow->reflectance, Rgb(0.99, 0.99, 0.9));
    int clampWarnings = 0;
    for (const std::string& w : warnings) clampWarnings += w.find("'snow'") != std::string::npos;
    EXPECT_EQ(clampWarnings, 1);
    // The emission scale multiplies.
    ImportOptions scaled = quiet();
    scaled.emissionScale = 10;
    const Scene brighter = importScene((dir / "m.gltf").string(), scaled);
    EXPECT_NEAR(brighter.findMaterial("lamp")->emission.x, 10 * l->emission.x, 1e-9);
}

/// A PNG of `w` × 1 RGB texels (uncompressed deflate blocks are enough for a reader).
std::string tinyPng(const std::vector<std::array<unsigned char, 3>>& texels) {
    auto be32 = [](std::uint32_t v) {
        return std::string{static_cast<char>(v >> 24), static_cast<char>(v >> 16),
                           static_cast<char>(v >> 8), static_cast<char>(v)};
    };
    auto crc = [](const std::string& bytes) {
        std::uint32_t c = 0xffffffffu;
        for (unsigned char b : bytes) {
            c ^= b;
            for (int k = 0; k < 8; ++k) c = (c >> 1) ^ (0xedb88320u & (0u - (c & 1u)));
        }
        return c ^ 0xffffffffu;
    };
    auto chunk = [&](const std::string& type, const std::string& data) {
        return be32(static_cast<std::uint32_t>(data.size())) + type + data + be32(crc(type + data));
    };
    std::string raw(1, '\0');  // filter: none
    for (const auto& t : texels) raw.append(reinterpret_cast<const char*>(t.data()), 3);
    // zlib: header, one stored block, Adler-32.
    std::uint32_t a = 1, b = 0;
    for (unsigned char c : raw) a = (a + c) % 65521, b = (b + a) % 65521;
    const auto n = static_cast<std::uint16_t>(raw.size());
    std::string z = {0x78,
                     0x01,
                     0x01,
                     static_cast<char>(n & 0xff),
                     static_cast<char>(n >> 8),
                     static_cast<char>(~n & 0xff),
                     static_cast<char>((~n >> 8) & 0xff)};
    z += raw + be32((b << 16) | a);
    const std::string header =
        be32(static_cast<std::uint32_t>(texels.size())) + be32(1) + std::string{8, 2, 0, 0, 0};
    return std::string("\x89PNG\r\n\x1a\n", 8) + chunk("IHDR", header) + chunk("IDAT", z) +
           chunk("IEND", "");
}

TEST(SceneImport, ABaseColourTextureScalesTheFactorByItsLinearMean) {
    const fs::path dir = tempDir();
    Gltf g;
    const int m = g.material("tex", Rgb(0.8, 0.6, 0.4));
    g.j["images"] = {
        {{"uri", "data:image/png;base64," + base64(tinyPng({{255, 0, 188}, {0, 255, 188}}))}}};
    g.j["textures"] = {{{"source", 0}}};
    g.j["materials"][m]["pbrMetallicRoughness"]["baseColorTexture"] = {{"index", 0}};
    g.node({{"name", "t"}, {"mesh", g.mesh(kTriangle, {0, 1, 2}, m)}});
    std::vector<std::string> warnings;
    const Scene scene = importScene(g.write(dir / "tex.gltf"), quiet(&warnings));
    // sRGB 188 is linear ((188/255 + 0.055)/1.055)^2.4; 255 is 1 and 0 is 0.
    const double blue = std::pow((188.0 / 255 + 0.055) / 1.055, 2.4);
    const Rgb expected = Rgb(0.8 * 0.5, 0.6 * 0.5, 0.4 * blue);
    EXPECT_NEAR(glm::length(scene.findMaterial("tex")->reflectance - expected), 0, 1e-9);
    for (const std::string& w : warnings) EXPECT_EQ(w.find("texture"), std::string::npos) << w;
}

TEST(SceneImport, APointLightBecomesASphereOfTheSamePowerAndACameraAViewpoint) {
    const fs::path dir = tempDir();
    Gltf g;
    g.node({{"name", "floor"},
            {"mesh", g.mesh(quadXZ(4, 4), kQuadIndices, g.material("w", Rgb(0.5)))}});
    g.j["extensionsUsed"].push_back("KHR_lights_punctual");
    g.j["extensions"]["KHR_lights_punctual"]["lights"] = {
        {{"name", "bulb"}, {"type", "point"}, {"color", {1.0, 0.8, 0.6}}, {"intensity", 3.0}}};
    g.node({{"name", "bulb-node"},
            {"translation", {0.5, 2.0, -0.25}},
            {"extensions", {{"KHR_lights_punctual", {{"light", 0}}}}}});
    // A camera at (0, 1, 5) turned 30° about +Y: it looks along -Z rotated by 30°.
    const double h = 15.0 * M_PI / 180;
    g.j["cameras"] = {{{"name", "view"},
                       {"type", "perspective"},
                       {"perspective", {{"yfov", 0.8}, {"znear", 0.1}}}}};
    g.node({{"name", "cam"},
            {"camera", 0},
            {"translation", {0, 1, 5}},
            {"rotation", {0, std::sin(h), 0, std::cos(h)}}});
    ImportOptions options = quiet();
    options.lightRadius = 0.1;
    const Scene scene = importScene(g.write(dir / "l.gltf"), options);

    const int bulb = scene.findObject("light-bulb");
    ASSERT_GE(bulb, 0);
    const SceneObject& o = scene.objects[bulb];
    EXPECT_EQ(o.shape.type, ShapeType::Sphere);
    EXPECT_EQ(o.shape.radius, 0.1);
    EXPECT_EQ(o.transform.translate, Vec3(0.5, 2.0, -0.25));
    // Its emitted power: 4π × intensity × colour in lumens, over 683 lm/W (the emission makes
    // up for the facets having less area than the sphere).
    Discretization disc(scene);
    Rgb power(0.0);
    for (const Element& e : disc.elements())
        if (e.object == bulb)
            power += disc.elementMaterial(&e - disc.elements().data()).emission * e.area;
    for (int c = 0; c < 3; ++c) {
        const double watts = 4 * M_PI * 3.0 * Rgb(1.0, 0.8, 0.6)[c] / 683;
        EXPECT_NEAR(power[c], watts, 1e-9 * watts);
    }

    ASSERT_EQ(scene.cameras.size(), 1u);
    const Camera& cam = scene.cameras[0];
    EXPECT_EQ(cam.name, "view");
    EXPECT_NEAR(glm::length(cam.position - Vec3(0, 1, 5)), 0, 1e-9);
    const Vec3 forward = glm::normalize(cam.lookAt - cam.position);
    EXPECT_NEAR(glm::length(forward - test::rotateAboutY(Vec3(0, 0, -1), 30)), 0, 1e-9);
    EXPECT_NEAR(cam.fovDeg, 0.8 * 180 / M_PI, 1e-9);
}

TEST(SceneImport, ObjWithMtlGivesOneObjectPerGroupInTheChosenUnits) {
    const fs::path dir = tempDir();
    std::ofstream(dir / "s.mtl") << "newmtl wall\nKd 0.7 0.6 0.5\n"
                                    "newmtl glow\nKd 0 0 0\nKe 2 2 1\n";
    std::ofstream(dir / "s.obj") << "mtllib s.mtl\n"
                                    "v 0 0 0\nv 100 0 0\nv 100 0 100\nv 0 0 100\n"
                                    "v 0 50 0\nv 10 50 0\nv 10 50 10\n"
                                    "o wall\nusemtl wall\nf 1 4 3 2\n"
                                    "o lamp\nusemtl glow\nf 5 7 6\n";
    ImportOptions cm = quiet();
    cm.objUnit = 0.01;
    const Scene scene = importScene((dir / "s.obj").string(), cm);
    ASSERT_EQ(scene.objects.size(), 2u);
    const SceneObject& wall = scene.objects[scene.findObject("wall")];
    EXPECT_EQ(wall.material, "wall");
    EXPECT_NEAR(glm::length(scene.findMaterial("wall")->reflectance - Rgb(0.7, 0.6, 0.5)), 0, 1e-6)
        << "Kd (single precision in the reader)";
    Vec3 hi(-1e30);
    for (const Vec3& p : worldPositions(wall)) hi = glm::max(hi, p);
    EXPECT_NEAR(hi.x, 1.0, 1e-9) << "100 cm";
    const SceneObject& lamp = scene.objects[scene.findObject("lamp")];
    EXPECT_EQ(lamp.material, "glow");
    EXPECT_NEAR(scene.findMaterial("glow")->emission.x, 2 * M_PI, 1e-6) << "Ke is radiance";
    EXPECT_NEAR(worldPositions(lamp)[0].y, 0.5, 1e-9);
}

/// The inward-facing walls of a closed cube of side `size`, one glTF mesh node per wall.
Gltf furnaceGltf(double size, Rgb rho, Rgb emission) {
    Gltf g;
    const int m = g.material("glow", rho, emission / M_PI);
    const double h = size / 2;
    // Each wall: the floor quad (normal +Y) turned as test::addClosedRoom turns its quads.
    const std::vector<std::pair<Vec3, Vec3>> walls = {
        {{0, -h, 0}, {0, 0, 0}},  {{0, h, 0}, {180, 0, 0}}, {{0, 0, -h}, {90, 0, 0}},
        {{0, 0, h}, {-90, 0, 0}}, {{h, 0, 0}, {0, 0, 90}},  {{-h, 0, 0}, {0, 0, -90}}};
    for (const auto& [at, deg] : walls) {
        std::vector<Vec3> q = quadXZ(size, size);
        for (Vec3& p : q) {
            p = test::rotateAboutZ(test::rotateAboutY(test::rotateAboutX(p, deg.x), deg.y), deg.z);
            p += at;
        }
        g.node({{"name", "wall"}, {"mesh", g.mesh(q, kQuadIndices, m)}});
    }
    return g;
}

TEST(SceneImport, TheFurnaceThroughAnImportedGltfConvergesToTheGeometricSeries) {
    const fs::path dir = tempDir();
    const Rgb rho(0.5, 0.4, 0.3), emission(1.0, 0.8, 0.6);
    Scene scene = importScene(furnaceGltf(2.0, rho, emission).write(dir / "f.gltf"), quiet());
    scene.settings.patchSize = 1.0;
    scene.settings.elementSize = 0.5;
    Discretization disc(scene);
    RayTracer tracer(disc);
    ProgressiveSolver solver(disc, tracer);
    solver.converge(1e-6, 200000);
    const Rgb expected = emission / (1.0 - rho);
    for (std::size_t e = 0; e < disc.elements().size(); ++e)
        for (int c = 0; c < 3; ++c)
            ASSERT_NEAR(solver.radiosity()[e][c], expected[c], 5e-3 * expected[c])
                << "element " << e;
}

TEST(SceneImport, AnImportedEmissiveQuadLightsAsTheJsonSceneDoes) {
    // Lambert's closed form through both: the irradiance an unoccluded quad lamp gives points
    // below it is the same from the imported glTF as from the JSON scene's quad.
    const fs::path dir = tempDir();
    const Rgb emission(2.0, 1.0, 0.5);
    Scene json = test::emptyScene(0.5, 0.25);
    test::addMaterial(json, "lamp", Rgb(0.0), emission);
    json.objects.push_back(test::makeQuad("lamp", 1.0, 0.8, "lamp", {0.2, 1.0, -0.1}, {180, 0, 0}));
    Gltf g;
    std::vector<Vec3> q = quadXZ(1.0, 0.8);
    for (Vec3& p : q) p = test::rotateAboutX(p, 180) + Vec3(0.2, 1.0, -0.1);
    g.node({{"name", "lamp"},
            {"mesh", g.mesh(q, kQuadIndices, g.material("lamp", Rgb(0.0), emission / M_PI))}});
    Scene imported = importScene(g.write(dir / "q.gltf"), quiet());
    imported.settings = json.settings;
    Discretization d1(json), d2(imported);
    RayTracer t1(d1), t2(d2);
    ProgressiveSolver s1(d1, t1), s2(d2, t2);
    s1.converge(1e-9, 100);
    s2.converge(1e-9, 100);
    int lit = 0;
    for (double x : {-0.6, 0.0, 0.3, 0.9})
        for (double z : {-0.5, 0.0, 0.4}) {
            const Vec3 p(x, 0.0, z), n(0, 1, 0);
            const Rgb a = s1.irradianceAt(p, n), b = s2.irradianceAt(p, n);
            for (int c = 0; c < 3; ++c) EXPECT_NEAR(b[c], a[c], 1e-9 + 1e-6 * a[c]);
            lit += luminance(a) > 0.01;
        }
    EXPECT_GT(lit, 8);
}

TEST(SceneImport, PenumbrasOwnGlbExportImportsBackWithItsObjectsMaterialsAndLampPower) {
    const fs::path dir = tempDir();
    Scene scene = test::emptyScene(0.5, 0.25);
    test::addMaterial(scene, "grey", Rgb(0.6, 0.5, 0.4));
    test::addMaterial(scene, "lamp", Rgb(0.0), Rgb(8.0, 6.0, 4.0));
    scene.objects.push_back(test::makeQuad("floor", 2, 2, "grey", {0, 0, 0}));
    scene.objects.push_back(test::makeQuad("lamp", 0.5, 0.5, "lamp", {0, 1.5, 0}, {180, 0, 0}));
    Camera camera;
    camera.name = "corner";
    camera.position = Vec3(1.5, 1.2, 2.0);
    camera.lookAt = Vec3(0.0, 0.3, 0.0);
    camera.fovDeg = 55;
    scene.cameras.push_back(camera);
    Discretization disc(scene);
    RayTracer tracer(disc);
    ProgressiveSolver solver(disc, tracer);
    solver.converge(1e-4, 1000);
    const std::string glb = (dir / "lit.glb").string();
    exportLitScene(disc, solver.radiosity(), glb, &scene);
    std::vector<std::string> warnings;
    const Scene back = importScene(glb, quiet(&warnings));
    EXPECT_TRUE(warnings.empty()) << warnings.front();
    ASSERT_EQ(back.objects.size(), 2u);
    for (const SceneObject& o : scene.objects) {
        const int i = back.findObject(o.id);
        ASSERT_GE(i, 0) << o.id;
        EXPECT_EQ(back.objects[i].material, o.material);
        // A primitive shape comes back as itself (from the node's extras), not as triangles.
        EXPECT_EQ(back.objects[i].shape.type, o.shape.type) << o.id;
        EXPECT_EQ(back.objects[i].shape.size, o.shape.size) << o.id;
        EXPECT_EQ(back.objects[i].transform.translate, o.transform.translate) << o.id;
        EXPECT_EQ(back.objects[i].transform.rotateDeg, o.transform.rotateDeg) << o.id;
        const Material* m = back.findMaterial(o.material);
        ASSERT_NE(m, nullptr);
        EXPECT_EQ(m->reflectance, scene.findMaterial(o.material)->reflectance);
        EXPECT_EQ(m->emission, scene.findMaterial(o.material)->emission);
    }
    EXPECT_EQ(back.settings.patchSize, scene.settings.patchSize);
    EXPECT_EQ(back.settings.elementSize, scene.settings.elementSize);
    Discretization again(back);
    EXPECT_EQ(again.elements().size(), disc.elements().size()) << "discretized as before";
    auto emitted = [](const Discretization& d) {
        double w = 0;
        for (std::size_t e = 0; e < d.elements().size(); ++e)
            w += luminance(d.elementMaterial(static_cast<int>(e)).emission) * d.elements()[e].area;
        return w;
    };
    EXPECT_NEAR(emitted(again), emitted(disc), 1e-9 * emitted(disc));
    // The camera comes back: the same place, direction and field of view.
    ASSERT_EQ(back.cameras.size(), 1u);
    EXPECT_EQ(back.cameras[0].name, "corner");
    EXPECT_NEAR(glm::length(back.cameras[0].position - camera.position), 0, 1e-6);
    EXPECT_NEAR(glm::length(glm::normalize(back.cameras[0].lookAt - back.cameras[0].position) -
                            glm::normalize(camera.lookAt - camera.position)),
                0, 1e-6);
    EXPECT_GT(glm::dot(back.cameras[0].up, camera.up), 0.9) << "upright";
    EXPECT_NEAR(back.cameras[0].fovDeg, 55, 1e-6);
}

TEST(SceneImport, AnImportedSceneSavesAsJsonWithItsMeshesBesideIt) {
    const fs::path dir = tempDir();
    Gltf g;
    const int red = g.material("red", Rgb(0.8, 0.1, 0.1));
    const int glow = g.material("glow", Rgb(0.0), Rgb(1.0));
    // One mesh with two primitives of different materials: the object carries both.
    const int mixed = g.mesh(kTriangle, {0, 1, 2}, red);
    nlohmann::json second =
        g.j["meshes"][g.mesh(quadXZ(1, 1), kQuadIndices, glow)]["primitives"][0];
    g.j["meshes"][mixed]["primitives"].push_back(second);
    g.node({{"name", "two materials"}, {"mesh", mixed}});
    const Scene scene = importScene(g.write(dir / "two.gltf"), quiet());
    ASSERT_EQ(scene.objects.size(), 1u);
    EXPECT_TRUE(scene.objects[0].material.empty());
    EXPECT_EQ(scene.objects[0].shape.mesh.materials.size(), 2u);
    const std::string out = (dir / "saved.json").string();
    saveScene(scene, out);
    EXPECT_TRUE(fs::exists(dir / "saved-meshes" / "two_materials.obj"));
    const Scene loaded = loadScene(out);
    ASSERT_EQ(loaded.objects.size(), 1u);
    const TriMesh& a = scene.objects[0].shape.mesh;
    const TriMesh& b = loaded.objects[0].shape.mesh;
    EXPECT_EQ(b.triangles.size(), a.triangles.size());
    EXPECT_EQ(b.triangleMaterial, a.triangleMaterial);
    ASSERT_EQ(b.materials.size(), a.materials.size());
    for (std::size_t m = 0; m < a.materials.size(); ++m) {
        EXPECT_NEAR(glm::length(b.materials[m].reflectance - a.materials[m].reflectance), 0, 1e-6);
        EXPECT_NEAR(glm::length(b.materials[m].emission - a.materials[m].emission), 0, 1e-6);
    }
    for (std::size_t v = 0; v < a.positions.size(); ++v)
        EXPECT_NEAR(glm::length(test::worldPoint(loaded.objects[0].transform, b.positions[v]) -
                                test::worldPoint(scene.objects[0].transform, a.positions[v])),
                    0, 1e-6);
}

TEST(SceneImport, BadFilesAreRefusedWithOneLineNamingTheFileAndIgnoredFeaturesAreNamed) {
    const fs::path dir = tempDir();
    auto refused = [&](const std::string& name, const std::string& text, const std::string& what) {
        const std::string path = (dir / name).string();
        std::ofstream(path) << text;
        try {
            (void)loadScene(path);
            ADD_FAILURE() << name << " was accepted";
        } catch (const InputError& e) {
            const std::string message = e.what();
            EXPECT_EQ(message.rfind(path, 0), 0u) << message;
            EXPECT_NE(message.find(what), std::string::npos) << message;
            EXPECT_EQ(message.find('\n'), std::string::npos);
        }
    };
    refused("broken.gltf", "{\"asset\": {\"version\": \"2.0\"", "not a valid glTF");
    refused("broken.glb", "glTF\x02", "not a valid GLB");
    refused("empty.gltf", "{\"asset\": {\"version\": \"2.0\"}}", "no mesh");
    refused(
        "draco.gltf",
        "{\"asset\": {\"version\": \"2.0\"}, \"extensionsUsed\": [\"KHR_draco_mesh_compression\"],"
        " \"extensionsRequired\": [\"KHR_draco_mesh_compression\"]}",
        "KHR_draco_mesh_compression");
    refused("nothing.obj", "# no faces\n", "no mesh");

    Gltf g;
    g.node({{"name", "t"}, {"mesh", g.mesh(kTriangle, {0, 1, 2}, -1)}});
    g.j["animations"] = {
        {{"channels", nlohmann::json::array()}, {"samplers", nlohmann::json::array()}}};
    std::vector<std::string> warnings;
    const Scene scene = importScene(g.write(dir / "anim.gltf"), quiet(&warnings));
    EXPECT_EQ(scene.objects.size(), 1u);
    bool named = false, dark = false;
    for (const std::string& w : warnings) {
        named = named || w.find("animations") != std::string::npos;
        dark = dark || w.find("nothing emits") != std::string::npos;
        EXPECT_EQ(w.rfind("warning: ", 0), 0u) << w;
    }
    EXPECT_TRUE(named);
    EXPECT_TRUE(dark);
}

// scenes/gltf/blender-room.{gltf,glb} and scenes/obj/blender-room.obj: the room that
// scripts/blender/make_scene.py builds, exported by Blender 3.4.1's own exporters. The numbers
// below restate make_scene.py's; the expected file values are computed from them here. Blender
// is Z-up and both exporters write Y-up: Blender (x, y, z) is (x, z, -y) in the files.

std::string blenderRoom(const std::string& relative) {
    return (fs::path(PENUMBRA_SOURCE_DIR) / "scenes" / relative).string();
}

Vec3 fromBlender(Vec3 p) { return {p.x, p.z, -p.y}; }

/// The Crate's corner `local` (its 1 m cube's, ±0.5) in file coordinates: the Shelf empty's
/// TRS after the Crate's own (Euler XYZ: X first, then Y, then Z), as make_scene.py sets them.
Vec3 blenderCrateCorner(Vec3 local) {
    Vec3 p(local.x * 0.6, local.y * 0.4, local.z * 0.5);
    p = test::rotateAboutZ(test::rotateAboutX(p, 15.0), 40.0) + Vec3(0.2, 0.1, 0.4);
    p = test::rotateAboutZ(1.25 * p, 30.0) + Vec3(0.9, -0.7, 0.0);
    return fromBlender(p);
}

double triangleArea(const std::array<Vec3, 3>& t) {
    return 0.5 * glm::length(glm::cross(t[1] - t[0], t[2] - t[0]));
}

/// World triangles of a mesh object.
std::vector<std::array<Vec3, 3>> worldTriangles(const SceneObject& o) {
    const std::vector<Vec3> p = worldPositions(o);
    std::vector<std::array<Vec3, 3>> out;
    for (const auto& t : o.shape.mesh.triangles) out.push_back({p[t[0]], p[t[1]], p[t[2]]});
    return out;
}

double meshArea(const SceneObject& o) {
    double area = 0;
    for (const auto& t : worldTriangles(o)) area += triangleArea(t);
    return area;
}

/// Σ emission × area over the scene's mesh objects (the lamps that are surfaces), W per channel.
Rgb meshEmittedPower(const Scene& scene) {
    Rgb power(0.0);
    for (const SceneObject& o : scene.objects) {
        if (o.shape.type != ShapeType::Mesh) continue;
        const std::vector<std::array<Vec3, 3>> triangles = worldTriangles(o);
        for (std::size_t t = 0; t < triangles.size(); ++t) {
            // One material for the object, or one per triangle.
            const Material& m = o.material.empty()
                                    ? o.shape.mesh.materials[o.shape.mesh.triangleMaterial[t]]
                                    : *scene.findMaterial(o.material);
            power += m.emission * triangleArea(triangles[t]);
        }
    }
    return power;
}

double distanceToNearest(const std::vector<Vec3>& points, Vec3 p) {
    double best = 1e30;
    for (const Vec3& q : points) best = std::min(best, glm::length(q - p));
    return best;
}

void expectTheBlenderRoomsMeshes(const Scene& scene, const std::string& file) {
    SCOPED_TRACE(file);
    // Baked transforms: every corner of the Crate under its turned, scaled Shelf.
    const SceneObject& crate = scene.objects[scene.findObject("Crate")];
    const std::vector<Vec3> cratePoints = worldPositions(crate);
    for (double x : {-0.5, 0.5})
        for (double y : {-0.5, 0.5})
            for (double z : {-0.5, 0.5}) {
                const Vec3 corner = blenderCrateCorner({x, y, z});
                EXPECT_LT(distanceToNearest(cratePoints, corner), 1e-5)
                    << "Crate corner (" << x << ", " << y << ", " << z << ") expected at ("
                    << corner.x << ", " << corner.y << ", " << corner.z << ")";
            }
    // The known corner Blender itself printed (make_scene.py): (1.031349, -0.059433, 0.866557).
    EXPECT_NEAR(glm::length(blenderCrateCorner({0.5, 0.5, 0.5}) -
                            fromBlender({1.031349, -0.059433, 0.866557})),
                0, 1e-6);
    // Two materials on the Crate (two glTF primitives): its top Wood, its sides Crate.
    const TriMesh& crateMesh = crate.shape.mesh;
    std::vector<std::string> names = crateMesh.materialNames;
    std::sort(names.begin(), names.end());
    ASSERT_EQ(names, (std::vector<std::string>{"Crate", "Wood"}));
    const std::vector<std::array<Vec3, 3>> crateTriangles = worldTriangles(crate);
    int woodTriangles = 0;
    for (std::size_t t = 0; t < crateTriangles.size(); ++t) {
        const auto& c = crateTriangles[t];
        const Vec3 n = glm::normalize(glm::cross(c[1] - c[0], c[2] - c[0]));
        const bool isWood = crateMesh.materialNames[crateMesh.triangleMaterial[t]] == "Wood";
        woodTriangles += isWood;
        // The top's normal is the Crate's +Z (Blender), tilted 15° about X: up by cos 15°.
        EXPECT_EQ(isWood, n.y > 0.9) << "triangle " << t << " normal y " << n.y;
    }
    EXPECT_EQ(woodTriangles, 2);

    // Walls: the 1 m cube scaled (4, 4, 3) at height 1.5, open below, every face inward.
    const SceneObject& walls = scene.objects[scene.findObject("Walls")];
    Vec3 lo(1e30), hi(-1e30);
    for (const Vec3& p : worldPositions(walls)) lo = glm::min(lo, p), hi = glm::max(hi, p);
    EXPECT_LT(glm::length(lo - Vec3(-2, 0, -2)), 1e-6);
    EXPECT_LT(glm::length(hi - Vec3(2, 3, 2)), 1e-6);
    EXPECT_NEAR(meshArea(walls), 4 * 4 + 4 * 4 * 3, 1e-5) << "ceiling and four walls";
    for (const auto& t : worldTriangles(walls)) {
        const Vec3 n = glm::cross(t[1] - t[0], t[2] - t[0]);
        const Vec3 centre = (t[0] + t[1] + t[2]) / 3.0;
        EXPECT_GT(glm::dot(n, Vec3(0, 1.5, 0) - centre), 0) << "a wall faces the room";
    }
    // Floor 4 m × 4 m facing up; Panel 1 × 0.6 m at 2.98 m facing down.
    const SceneObject& floor = scene.objects[scene.findObject("Floor")];
    EXPECT_NEAR(meshArea(floor), 16, 1e-5);
    const SceneObject& panel = scene.objects[scene.findObject("Panel")];
    EXPECT_NEAR(meshArea(panel), 0.6, 1e-6);
    EXPECT_NEAR(panel.transform.translate.y, 2.98, 1e-6);
    for (const auto& t : worldTriangles(panel))
        EXPECT_LT(glm::cross(t[1] - t[0], t[2] - t[0]).y, 0) << "the panel faces down";
    for (const auto& t : worldTriangles(floor))
        EXPECT_GT(glm::cross(t[1] - t[0], t[2] - t[0]).y, 0) << "the floor faces up";

    // One material shared by the two boxes; the panel's emission π × colour × strength 8.
    EXPECT_EQ(scene.objects[scene.findObject("BoxA")].material, "Wood");
    EXPECT_EQ(scene.objects[scene.findObject("BoxB")].material, "Wood");
    const Material* wood = scene.findMaterial("Wood");
    ASSERT_NE(wood, nullptr);
    EXPECT_LT(glm::length(wood->reflectance - Rgb(0.45, 0.3, 0.18)), 1e-6);
    const Material* light = scene.findMaterial(panel.material);
    ASSERT_NE(light, nullptr);
    EXPECT_EQ(panel.material, "PanelLight");
    EXPECT_LT(glm::length(light->emission - M_PI * 8.0 * Rgb(1.0, 0.9, 0.75)), 1e-5)
        << "E = π × emissive × strength (docs/import.md)";
    EXPECT_EQ(light->reflectance, Rgb(0.0));
}

TEST(SceneImport,
     BlendersGltfAndGlbExportsOfARoomImportWithTheirTransformsMaterialsLightAndCamera) {
    for (const std::string file : {"gltf/blender-room.gltf", "gltf/blender-room.glb"}) {
        std::vector<std::string> warnings;
        const Scene scene = importScene(blenderRoom(file), quiet(&warnings));
        SCOPED_TRACE(file);
        EXPECT_TRUE(warnings.empty()) << warnings.front();
        std::vector<std::string> ids;
        for (const SceneObject& o : scene.objects) ids.push_back(o.id);
        EXPECT_EQ(ids, (std::vector<std::string>{"Walls", "Floor", "BoxA", "BoxB", "Crate", "Panel",
                                                 "light-Bulb"}))
            << "ids from node names; the Shelf empty has no mesh";
        expectTheBlenderRoomsMeshes(scene, file);
        // Blender writes doubleSided for every material unless Backface Culling is ticked.
        EXPECT_TRUE(scene.findMaterial("Wood")->twoSided);

        // The 25 W point light: a sphere at its place sending 25 W × its colour.
        const int bulb = scene.findObject("light-Bulb");
        ASSERT_GE(bulb, 0);
        const SceneObject& sphere = scene.objects[bulb];
        EXPECT_EQ(sphere.shape.type, ShapeType::Sphere);
        EXPECT_LT(glm::length(sphere.transform.translate - fromBlender({-1.3, -1.2, 2.2})), 1e-6);
        const Discretization disc(scene);
        Rgb power(0.0);
        for (const Element& e : disc.elements())
            if (e.object == bulb)
                power += disc.elementMaterial(&e - disc.elements().data()).emission * e.area;
        const Rgb watts = 25.0 * Rgb(1.0, 0.8, 0.6);
        for (int c = 0; c < 3; ++c)
            EXPECT_NEAR(power[c], watts[c], 1e-6 * watts[c]) << "channel " << c;

        // The camera at (1.7, -1.7, 1.6) looking at (0, 0, 0.8); 24 mm on 36 mm at 4:3.
        ASSERT_EQ(scene.cameras.size(), 1u);
        const Camera& cam = scene.cameras[0];
        EXPECT_EQ(cam.name, "Camera");
        const Vec3 position = fromBlender({1.7, -1.7, 1.6});
        EXPECT_LT(glm::length(cam.position - position), 1e-6);
        const Vec3 forward = glm::normalize(cam.lookAt - cam.position);
        EXPECT_LT(glm::length(forward - glm::normalize(fromBlender({0, 0, 0.8}) - position)), 1e-6);
        EXPECT_NEAR(glm::dot(cam.up, forward), 0, 1e-6);
        EXPECT_GT(cam.up.y, 0.9) << "upright";
        EXPECT_NEAR(cam.fovDeg, 2 * std::atan(18.0 / 24.0 / (640.0 / 480.0)) * 180 / M_PI, 1e-5);
    }
}

TEST(SceneImport, BlendersObjExportOfTheRoomMatchesItsGltfExport) {
    std::vector<std::string> warnings;
    const Scene obj = importScene(blenderRoom("obj/blender-room.obj"), quiet(&warnings));
    EXPECT_TRUE(warnings.empty()) << warnings.front();
    const Scene gltf = importScene(blenderRoom("gltf/blender-room.glb"), quiet());
    std::vector<std::string> ids;
    for (const SceneObject& o : obj.objects) ids.push_back(o.id);
    EXPECT_EQ(ids, (std::vector<std::string>{"Walls", "Floor", "BoxA", "BoxB", "Crate", "Panel"}))
        << "OBJ has no lights or cameras";
    expectTheBlenderRoomsMeshes(obj, "obj/blender-room.obj");
    EXPECT_FALSE(obj.findMaterial("Wood")->twoSided) << "OBJ has no two-sided flag";

    // The same meshes: object count (the glTF adds the light's sphere), areas, emitted power.
    std::size_t gltfMeshes = 0;
    for (const SceneObject& o : gltf.objects) gltfMeshes += o.shape.type == ShapeType::Mesh;
    EXPECT_EQ(gltfMeshes, obj.objects.size());
    for (const SceneObject& o : obj.objects) {
        const int g = gltf.findObject(o.id);
        ASSERT_GE(g, 0) << o.id;
        EXPECT_NEAR(meshArea(o), meshArea(gltf.objects[g]), 1e-5 * meshArea(o)) << o.id;
    }
    const Rgb objPower = meshEmittedPower(obj), gltfPower = meshEmittedPower(gltf);
    EXPECT_LT(glm::length(objPower - gltfPower), 1e-5 * glm::length(objPower));
    EXPECT_LT(glm::length(objPower - 0.6 * M_PI * 8.0 * Rgb(1.0, 0.9, 0.75)), 1e-4)
        << "Ke = colour × strength, E = π Ke over the panel's 0.6 m²";
    EXPECT_EQ(obj.settings.elementSize, gltf.settings.elementSize);
}

// docs/import.md: a scene without Penumbra's settings is split into about 16,000 elements (the
// fronts of its surfaces), counted here by the solver's own discretization, whatever the
// file's scale and however its meshes are triangulated.
TEST(SceneImport, AnImportedSceneGetsAboutTheTargetNumberOfElements) {
    auto frontElements = [](const Scene& scene) {
        const Discretization disc(scene);
        std::size_t fronts = 0;
        for (const Element& e : disc.elements())
            fronts += !disc.objects()[e.object].isBackFace(e.face);
        return fronts;
    };
    for (const char* file : {"obj/blender-room.obj", "gltf/blender-room.glb",
                             "gltf/studio.gltf", "gltf/cornell.gltf"}) {
        const Scene scene = importScene(blenderRoom(file), quiet());
        const std::size_t fronts = frontElements(scene);
        EXPECT_LE(fronts, 16000u) << file;
        EXPECT_GE(fronts, 12000u) << file << ": element size " << scene.settings.elementSize;
        // One step of the two digits smaller would pass the target.
        Scene finer = scene;
        const double unit = std::pow(10.0, std::floor(std::log10(scene.settings.elementSize)) - 1);
        finer.settings.elementSize = scene.settings.elementSize - unit;
        finer.settings.patchSize = 4 * finer.settings.elementSize;
        EXPECT_GT(frontElements(finer), 16000u)
            << file << ": element size " << scene.settings.elementSize;
    }
}

}  // namespace
}  // namespace penumbra
