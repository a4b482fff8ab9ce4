// Export of lit scenes: each format is parsed back here independently of the writer and its
// vertex count, face count, geometry and colours checked against the input.

#include "edit/io/export.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <glm/gtc/constants.hpp>
#include <memory>
#include <nlohmann/json.hpp>
#include <sstream>
#include <stdexcept>
#include <string>

#include "solver/discretization.h"

namespace penumbra {
namespace {

using nlohmann::json;

const double kPi = glm::pi<double>();

double srgb(double l) { return l <= 0.0031308 ? 12.92 * l : 1.055 * std::pow(l, 1 / 2.4) - 0.055; }
double unsrgb(double v) { return v <= 0.04045 ? v / 12.92 : std::pow((v + 0.055) / 1.055, 2.4); }

std::string readFile(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    EXPECT_TRUE(in.good()) << "cannot open " << path;
    std::ostringstream s;
    s << in.rdbuf();
    return s.str();
}

template <typename T>
T readLittleEndian(const std::string& bytes, size_t offset) {
    static_assert(sizeof(T) == 4);
    std::uint32_t bits = 0;
    for (int i = 0; i < 4; ++i)
        bits |= std::uint32_t(std::uint8_t(bytes.at(offset + i))) << (8 * i);
    T value;
    std::memcpy(&value, &bits, 4);
    return value;
}

std::string base64Decode(const std::string& text) {
    auto value = [](char c) -> int {
        if (c >= 'A' && c <= 'Z') return c - 'A';
        if (c >= 'a' && c <= 'z') return c - 'a' + 26;
        if (c >= '0' && c <= '9') return c - '0' + 52;
        if (c == '+') return 62;
        if (c == '/') return 63;
        return -1;
    };
    std::string out;
    std::uint32_t accumulator = 0;
    int bits = 0;
    for (char c : text) {
        if (c == '=') break;
        int v = value(c);
        if (v < 0) throw std::runtime_error("bad base64");
        accumulator = (accumulator << 6) | std::uint32_t(v);
        bits += 6;
        if (bits >= 8) {
            bits -= 8;
            out.push_back(static_cast<char>((accumulator >> bits) & 0xff));
        }
    }
    return out;
}

/// Fixture: a floor quad and a two-sided box with uniform radiosity per object, so every
/// vertex value is exactly that object's radiosity.
class ExportTest : public ::testing::Test {
protected:
    void SetUp() override {
        Scene scene;
        scene.settings.patchSize = 0.5;
        scene.settings.elementSize = 0.25;
        Material white;
        Material shiny;
        shiny.twoSided = true;
        scene.materials = {{"white", white}, {"shiny", shiny}};
        SceneObject floor;
        floor.id = "floor";
        floor.shape.type = ShapeType::Quad;
        floor.shape.size = Vec3(1, 0, 1);
        floor.material = "white";
        SceneObject crate;
        crate.id = "crate";
        crate.shape.type = ShapeType::Box;
        crate.shape.size = Vec3(0.5);
        crate.material = "shiny";
        crate.transform.translate = Vec3(0.1, 0.25, -0.2);
        crate.transform.rotateDeg = Vec3(0, 30, 0);
        scene.objects = {floor, crate};
        disc = std::make_unique<Discretization>(scene);

        objectRadiance = {Rgb(0.2, 0.4, 0.6), Rgb(0.05, 0.1, 0.9)};
        for (const Element& e : disc->elements()) b.push_back(kPi * objectRadiance[e.object]);

        // One directory per test process: CTest runs the tests of this fixture in parallel
        // processes, whose random seeds (from the clock) can coincide.
        const auto* test = ::testing::UnitTest::GetInstance()->current_test_info();
        dir = std::filesystem::path(::testing::TempDir()) /
              ("penumbra_export_" + std::string(test->name()) + "_" + std::to_string(::getpid()));
        std::filesystem::create_directories(dir);
    }
    void TearDown() override { std::filesystem::remove_all(dir); }

    size_t totalVertices() const {
        size_t n = 0;
        for (const ObjectSurface& s : disc->objects()) n += s.worldPositions.size();
        return n;
    }
    size_t firstVertexOf(int object) const {
        size_t n = 0;
        for (int o = 0; o < object; ++o) n += disc->objects()[o].worldPositions.size();
        return n;
    }
    std::string pathFor(const std::string& name) const { return (dir / name).string(); }

    /// Checks a parsed glTF document and its binary buffer.
    void checkGltf(const json& doc, const std::string& bin) {
        ASSERT_EQ(doc["asset"]["version"], "2.0");
        const auto& objects = disc->objects();
        ASSERT_EQ(doc["meshes"].size(), objects.size());
        ASSERT_EQ(doc["nodes"].size(), objects.size());
        ASSERT_EQ(doc["scenes"][0]["nodes"].size(), objects.size());
        ASSERT_GE(doc["buffers"][0]["byteLength"].get<size_t>(), 1u);
        ASSERT_LE(doc["buffers"][0]["byteLength"].get<size_t>(), bin.size());
        const double exposure = doc["asset"]["extras"]["exposure"].get<double>();
        ASSERT_GT(exposure, 0.0);

        // Read an accessor as floats (VEC3 float or SCALAR uint32).
        auto accessor = [&](size_t index, size_t components, int componentType) {
            const json& a = doc["accessors"][index];
            EXPECT_EQ(a["componentType"].get<int>(), componentType);
            const json& view = doc["bufferViews"][a["bufferView"].get<size_t>()];
            const size_t offset =
                view.value("byteOffset", size_t{0}) + a.value("byteOffset", size_t{0});
            const size_t count = a["count"].get<size_t>();
            EXPECT_LE(count * components * 4, view["byteLength"].get<size_t>());
            std::vector<double> values;
            for (size_t i = 0; i < count * components; ++i) {
                values.push_back(
                    componentType == 5126
                        ? double(readLittleEndian<float>(bin, offset + 4 * i))
                        : double(readLittleEndian<std::uint32_t>(bin, offset + 4 * i)));
            }
            return values;
        };

        size_t triangles = 0;
        size_t expectedTriangles = 0;
        for (const Element& e : disc->elements()) expectedTriangles += e.vertices.size() - 2;
        for (size_t o = 0; o < objects.size(); ++o) {
            const json& mesh = doc["meshes"][o];
            EXPECT_EQ(mesh["name"], objects[o].id);
            EXPECT_EQ(doc["nodes"][o]["mesh"].get<size_t>(), o);
            const json& primitive = mesh["primitives"][0];
            const json& attributes = primitive["attributes"];
            const size_t nv = objects[o].worldPositions.size();

            const auto positions = accessor(attributes["POSITION"].get<size_t>(), 3, 5126);
            const auto normals = accessor(attributes["NORMAL"].get<size_t>(), 3, 5126);
            const auto colors = accessor(attributes["COLOR_0"].get<size_t>(), 3, 5126);
            const auto radiance = accessor(attributes["_RADIANCE"].get<size_t>(), 3, 5126);
            EXPECT_EQ(doc["accessors"][attributes["COLOR_0"].get<size_t>()]["type"], "VEC3");
            ASSERT_EQ(positions.size(), 3 * nv) << objects[o].id;
            ASSERT_EQ(normals.size(), 3 * nv);
            ASSERT_EQ(colors.size(), 3 * nv);
            ASSERT_EQ(radiance.size(), 3 * nv);
            for (size_t v = 0; v < nv; ++v) {
                const Vec3 p(positions[3 * v], positions[3 * v + 1], positions[3 * v + 2]);
                EXPECT_NEAR(glm::length(p - objects[o].worldPositions[v]), 0, 1e-6);
                const Vec3 n(normals[3 * v], normals[3 * v + 1], normals[3 * v + 2]);
                EXPECT_NEAR(glm::length(n), 1, 1e-5);
                for (int c = 0; c < 3; ++c) {
                    EXPECT_NEAR(radiance[3 * v + c], objectRadiance[o][c], 1e-6)
                        << objects[o].id << " vertex " << v << " channel " << c;
                    EXPECT_NEAR(colors[3 * v + c], std::min(1.0, exposure * objectRadiance[o][c]),
                                1e-6)
                        << objects[o].id << " vertex " << v << " channel " << c;
                }
            }
            if (objects[o].id == "floor") {
                for (size_t v = 0; v < nv; ++v) EXPECT_NEAR(normals[3 * v + 1], 1, 1e-6);
            }
            // One primitive per material (a two-sided object's back sheet has its own), all
            // over the object's vertices.
            for (const json& each : mesh["primitives"]) {
                EXPECT_EQ(each["attributes"], attributes);
                const auto indices = accessor(each["indices"].get<size_t>(), 1, 5125);
                ASSERT_EQ(indices.size() % 3, 0u);
                triangles += indices.size() / 3;
                for (double i : indices) EXPECT_LT(i, double(nv));
                // Triangles are not degenerate and keep the element winding: counter-clockwise
                // seen from the side the (flat per box face) vertex normals point to.
                for (size_t t = 0; t < indices.size(); t += 3) {
                    const size_t ia = size_t(indices[t]);
                    const Vec3& a = objects[o].worldPositions[ia];
                    const Vec3& b2 = objects[o].worldPositions[size_t(indices[t + 1])];
                    const Vec3& c = objects[o].worldPositions[size_t(indices[t + 2])];
                    const Vec3 n = glm::cross(b2 - a, c - a);
                    EXPECT_GT(glm::length(n), 1e-9) << "degenerate triangle";
                    const Vec3 vertexNormal(normals[3 * ia], normals[3 * ia + 1],
                                            normals[3 * ia + 2]);
                    EXPECT_GT(glm::dot(n, vertexNormal), 0)
                        << objects[o].id << " triangle " << t / 3;
                }
                const json& material = doc["materials"][each["material"].get<size_t>()];
                // Two-sided objects carry their back sheet as geometry: single-sided materials.
                EXPECT_EQ(material.value("doubleSided", false),
                          objects[o].twoSided && objects[o].faceTwin.empty());
            }
        }
        EXPECT_EQ(triangles, expectedTriangles);
    }

    std::unique_ptr<Discretization> disc;
    std::vector<Rgb> objectRadiance;  ///< B/π per object
    std::vector<Rgb> b;               ///< per element
    std::filesystem::path dir;
};

TEST_F(ExportTest, PlyHasElementsAsFacesAndColours) {
    const std::string path = pathFor("lit.ply");
    exportLitScene(*disc, b, path);
    EXPECT_FALSE(std::filesystem::exists(path + ".tmp"));
    const std::string bytes = readFile(path);

    // Parse the header.
    const size_t headerEnd = bytes.find("end_header\n");
    ASSERT_NE(headerEnd, std::string::npos);
    std::istringstream header(bytes.substr(0, headerEnd));
    std::string line, format;
    size_t vertices = 0, faces = 0;
    std::vector<std::string> vertexProperties;
    std::string currentElement;
    while (std::getline(header, line)) {
        std::istringstream words(line);
        std::string keyword;
        words >> keyword;
        if (keyword == "format") words >> format;
        if (keyword == "element") {
            words >> currentElement;
            (currentElement == "vertex" ? vertices : faces) = 0;
            words >> (currentElement == "vertex" ? vertices : faces);
        }
        if (keyword == "property" && currentElement == "vertex") {
            std::string type, name;
            words >> type >> name;
            vertexProperties.push_back(type + " " + name);
        }
    }
    EXPECT_EQ(format, "binary_little_endian");
    const std::vector<std::string> expectedProperties = {
        "float x",    "float y",           "float z",           "uchar red",        "uchar green",
        "uchar blue", "float radiosity_r", "float radiosity_g", "float radiosity_b"};
    EXPECT_EQ(vertexProperties, expectedProperties);
    ASSERT_EQ(vertices, totalVertices());
    ASSERT_EQ(faces, disc->elements().size());

    // Vertices: 3 floats, 3 bytes, 3 floats.
    size_t offset = headerEnd + std::strlen("end_header\n");
    const auto& objects = disc->objects();
    for (size_t o = 0; o < objects.size(); ++o) {
        for (const Vec3& expected : objects[o].worldPositions) {
            const Vec3 p(readLittleEndian<float>(bytes, offset),
                         readLittleEndian<float>(bytes, offset + 4),
                         readLittleEndian<float>(bytes, offset + 8));
            EXPECT_NEAR(glm::length(p - expected), 0, 1e-6);
            for (int c = 0; c < 3; ++c) {
                const int byte = std::uint8_t(bytes.at(offset + 12 + c));
                EXPECT_EQ(byte, int(std::lround(255 * srgb(objectRadiance[o][c]))))
                    << objects[o].id << " channel " << c;
                EXPECT_NEAR(readLittleEndian<float>(bytes, offset + 15 + 4 * c),
                            kPi * objectRadiance[o][c], 1e-5);
            }
            offset += 27;
        }
    }

    // Faces: face i is element i with global vertex indices.
    for (size_t e = 0; e < disc->elements().size(); ++e) {
        const Element& element = disc->elements()[e];
        const int count = std::uint8_t(bytes.at(offset++));
        ASSERT_EQ(count, int(element.vertices.size())) << "face " << e;
        for (int k = 0; k < count; ++k) {
            const auto index = readLittleEndian<std::int32_t>(bytes, offset);
            offset += 4;
            EXPECT_EQ(size_t(index), firstVertexOf(element.object) + element.vertices[k]);
        }
    }
    EXPECT_EQ(offset, bytes.size()) << "trailing bytes after the last face";
}

TEST_F(ExportTest, GltfEmbedsItsBufferAsDataUri) {
    const std::string path = pathFor("lit.gltf");
    exportLitScene(*disc, b, path);
    const json doc = json::parse(readFile(path));
    const std::string uri = doc["buffers"][0]["uri"];
    const std::string prefix = "data:application/octet-stream;base64,";
    ASSERT_EQ(uri.rfind(prefix, 0), 0u) << uri.substr(0, 60);
    const std::string bin = base64Decode(uri.substr(prefix.size()));
    EXPECT_EQ(bin.size(), doc["buffers"][0]["byteLength"].get<size_t>());
    checkGltf(doc, bin);
}

TEST_F(ExportTest, GlbHasHeaderJsonAndBinChunks) {
    const std::string path = pathFor("lit.GLB");  // extensions are case-insensitive
    exportLitScene(*disc, b, path);
    const std::string bytes = readFile(path);
    ASSERT_GE(bytes.size(), 28u);
    EXPECT_EQ(bytes.substr(0, 4), "glTF");
    EXPECT_EQ(readLittleEndian<std::uint32_t>(bytes, 4), 2u);
    EXPECT_EQ(readLittleEndian<std::uint32_t>(bytes, 8), bytes.size());

    const std::uint32_t jsonLength = readLittleEndian<std::uint32_t>(bytes, 12);
    EXPECT_EQ(bytes.substr(16, 4), "JSON");
    EXPECT_EQ(jsonLength % 4, 0u);
    const json doc = json::parse(bytes.substr(20, jsonLength));
    EXPECT_FALSE(doc["buffers"][0].contains("uri"));

    const size_t binHeader = 20 + jsonLength;
    const std::uint32_t binLength = readLittleEndian<std::uint32_t>(bytes, binHeader);
    EXPECT_EQ(bytes.substr(binHeader + 4, 4), std::string("BIN\0", 4));
    EXPECT_EQ(binLength % 4, 0u);
    EXPECT_EQ(binHeader + 8 + binLength, bytes.size());
    checkGltf(doc, bytes.substr(binHeader + 8, binLength));
}

TEST_F(ExportTest, ObjHasVertexColoursAndElementFaces) {
    const std::string path = pathFor("lit.obj");
    exportLitScene(*disc, b, path);
    std::istringstream in(readFile(path));
    std::string line;
    std::vector<std::array<double, 6>> vertices;
    std::vector<std::vector<int>> faces;
    std::vector<std::string> groups;
    bool sawComment = false;
    while (std::getline(in, line)) {
        std::istringstream words(line);
        std::string keyword;
        words >> keyword;
        if (keyword == "#") sawComment = true;
        if (keyword == "o") {
            std::string name;
            words >> name;
            groups.push_back(name);
        } else if (keyword == "v") {
            std::array<double, 6> v{};
            for (double& x : v) ASSERT_TRUE(words >> x) << line;
            vertices.push_back(v);
        } else if (keyword == "f") {
            std::vector<int> face;
            int index;
            while (words >> index) face.push_back(index);
            faces.push_back(face);
        }
    }
    EXPECT_TRUE(sawComment);
    ASSERT_EQ(groups, (std::vector<std::string>{"floor", "crate"}));
    ASSERT_EQ(vertices.size(), totalVertices());
    ASSERT_EQ(faces.size(), disc->elements().size());

    const auto& objects = disc->objects();
    size_t v = 0;
    for (size_t o = 0; o < objects.size(); ++o) {
        for (const Vec3& expected : objects[o].worldPositions) {
            const auto& row = vertices[v++];
            EXPECT_NEAR(glm::length(Vec3(row[0], row[1], row[2]) - expected), 0, 1e-12);
            for (int c = 0; c < 3; ++c) {
                EXPECT_NEAR(unsrgb(row[3 + c]), objectRadiance[o][c], 2e-6)
                    << objects[o].id << " channel " << c;
            }
        }
    }
    // Faces are the elements, grouped by object in element order, 1-based global indices.
    size_t f = 0;
    for (size_t o = 0; o < objects.size(); ++o) {
        for (const Element& e : disc->elements()) {
            if (e.object != int(o)) continue;
            std::vector<int> expected;
            for (int k : e.vertices) expected.push_back(int(firstVertexOf(int(o)) + k + 1));
            EXPECT_EQ(faces.at(f++), expected);
        }
    }
}

TEST_F(ExportTest, VaryingAndOverbrightRadiosity) {
    // A ramp over the floor reaching 3× white and an emitter-level box.
    std::vector<Rgb> ramp;
    for (const Element& e : disc->elements()) {
        ramp.push_back(e.object == 0 ? Rgb(kPi * (1.5 + 3 * e.centroid.x), 1.0, 2.0) : Rgb(50.0));
    }
    const std::string ply = pathFor("ramp.ply"), gltf = pathFor("ramp.gltf");
    exportLitScene(*disc, ramp, ply);
    exportLitScene(*disc, ramp, gltf);

    // glTF: _RADIANCE holds the unclipped linear B/π of the vertex values, COLOR_0 the same
    // times the exposure, clipped to [0, 1].
    const json doc = json::parse(readFile(gltf));
    const std::string uri = doc["buffers"][0]["uri"];
    const std::string bin = base64Decode(uri.substr(uri.find(',') + 1));
    const std::vector<Rgb> floorValues = disc->vertexValues(0, ramp);
    const json& attributes = doc["meshes"][0]["primitives"][0]["attributes"];
    auto offsetOf = [&](const char* attribute) {
        const json& a = doc["accessors"][attributes[attribute].get<size_t>()];
        return doc["bufferViews"][a["bufferView"].get<size_t>()].value("byteOffset", size_t{0});
    };
    const size_t exact = offsetOf("_RADIANCE"), shown = offsetOf("COLOR_0");
    const double exposure = doc["asset"]["extras"]["exposure"].get<double>();
    double maxRed = 0, maxShown = 0;
    for (size_t v = 0; v < floorValues.size(); ++v) {
        for (int c = 0; c < 3; ++c) {
            const double value = readLittleEndian<float>(bin, exact + 12 * v + 4 * c);
            EXPECT_NEAR(value, floorValues[v][c] / kPi, 1e-5 * std::max(1.0, value));
            const double display = readLittleEndian<float>(bin, shown + 12 * v + 4 * c);
            EXPECT_NEAR(display, std::min(1.0, exposure * floorValues[v][c] / kPi), 1e-6);
            maxShown = std::max(maxShown, display);
        }
        maxRed = std::max(maxRed, double(readLittleEndian<float>(bin, exact + 12 * v)));
    }
    EXPECT_GT(maxRed, 2.5) << "_RADIANCE must not be clipped";
    EXPECT_LE(maxShown, 1.0) << "COLOR_0 is display-referred";

    // PLY bytes of the box are clipped to white; the float radiosity is not.
    const std::string bytes = readFile(ply);
    size_t p = bytes.find("end_header\n") + std::strlen("end_header\n") + 27 * firstVertexOf(1);
    EXPECT_EQ(std::uint8_t(bytes.at(p + 12)), 255);
    EXPECT_NEAR(readLittleEndian<float>(bytes, p + 15), 50.0, 1e-4);
}

TEST_F(ExportTest, RejectsUnknownExtensionsAndBadInput) {
    try {
        exportLitScene(*disc, b, pathFor("lit.stl"));
        FAIL() << "expected std::invalid_argument";
    } catch (const std::invalid_argument& e) {
        EXPECT_NE(std::string(e.what()).find(".stl"), std::string::npos) << e.what();
    }
    EXPECT_THROW(exportLitScene(*disc, b, pathFor("noextension")), std::invalid_argument);
    EXPECT_THROW(exportLitScene(*disc, std::vector<Rgb>(2), pathFor("lit.ply")),
                 std::invalid_argument);
    EXPECT_THROW(exportLitScene(*disc, b, pathFor("missing/dir/lit.obj")), std::runtime_error);
    EXPECT_FALSE(std::filesystem::exists(pathFor("lit.stl")));
}

}  // namespace
}  // namespace penumbra
