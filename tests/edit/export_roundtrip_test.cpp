// Lit-scene exports read back by independent readers (issue 24, point 3): tinyobjloader for
// OBJ and its .mtl, OpenMesh for PLY, tinygltf for GLB. A floor, a box and a lamp with one
// radiance per object: every vertex read back must carry its object's value.

#include <gtest/gtest.h>
#include <unistd.h>

#include <OpenMesh/Core/IO/MeshIO.hh>
#include <OpenMesh/Core/Mesh/PolyMesh_ArrayKernelT.hh>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <glm/gtc/constants.hpp>
#include <memory>
#include <string>
#include <vector>

// Debian's libtinygltf and libtinyobjloader hold the implementations.
#include <tiny_gltf.h>
#include <tiny_obj_loader.h>

#include "edit/io/export.h"
#include "solver/discretization.h"
#include "test_scenes.h"

namespace penumbra {
namespace {

const double kPi = glm::pi<double>();

/// sRGB encoding written out (IEC 61966-2-1), independent of the exporter's.
double srgb(double v) { return v <= 0.0031308 ? 12.92 * v : 1.055 * std::pow(v, 1 / 2.4) - 0.055; }

class ExportRoundTrip : public ::testing::Test {
protected:
    void SetUp() override {
        Scene scene = test::emptyScene(0.5, 0.25);
        test::addMaterial(scene, "white", Rgb(0.6, 0.5, 0.4));
        test::addMaterial(scene, "red", Rgb(0.7, 0.1, 0.1));
        test::addMaterial(scene, "lamp", Rgb(0.0), Rgb(10.0, 8.0, 6.0));
        SceneObject box;
        box.id = "box";
        box.shape.type = ShapeType::Box;
        box.shape.size = Vec3(0.5);
        box.material = "red";
        box.transform.translate = Vec3(0.2, 0.25, 0.1);
        scene.objects = {test::makeQuad("floor", 2, 2, "white", Vec3(0.0)), box,
                         test::makeQuad("light", 0.5, 0.5, "lamp", {0, 1.5, 0}, {180, 0, 0})};
        disc = std::make_unique<Discretization>(scene);
        this->scene = scene;
        // Radiance per object (B/π), within [0, 1] so no colour is clipped.
        radiance = {Rgb(0.25, 0.2, 0.15), Rgb(0.3, 0.05, 0.04), Rgb(0.9, 0.8, 0.7)};
        for (const Element& e : disc->elements()) b.push_back(kPi * radiance[e.object]);
        const auto* test = ::testing::UnitTest::GetInstance()->current_test_info();
        dir =
            std::filesystem::path(::testing::TempDir()) /
            ("penumbra_roundtrip_" + std::string(test->name()) + "_" + std::to_string(::getpid()));
        std::filesystem::create_directories(dir);
    }
    void TearDown() override { std::filesystem::remove_all(dir); }

    std::size_t totalVertices() const {
        std::size_t n = 0;
        for (const ObjectSurface& s : disc->objects()) n += s.worldPositions.size();
        return n;
    }
    /// The object whose vertex `v` (global, in object order) is.
    int objectOfVertex(std::size_t v) const {
        for (std::size_t o = 0; o < disc->objects().size(); ++o) {
            const std::size_t n = disc->objects()[o].worldPositions.size();
            if (v < n) return static_cast<int>(o);
            v -= n;
        }
        return -1;
    }
    std::string pathFor(const std::string& name) const { return (dir / name).string(); }

    Scene scene;
    std::unique_ptr<Discretization> disc;
    std::vector<Rgb> radiance, b;
    std::filesystem::path dir;
};

TEST_F(ExportRoundTrip, ObjAndItsMtlReadBackWithTinyObjLoader) {
    const std::string path = pathFor("lit.obj");
    exportLitScene(*disc, b, path, &scene);
    ASSERT_TRUE(std::filesystem::exists(pathFor("lit.mtl")));
    tinyobj::ObjReaderConfig config;
    config.triangulate = false;
    config.vertex_color = true;
    tinyobj::ObjReader reader;
    ASSERT_TRUE(reader.ParseFromFile(path, config)) << reader.Error();
    const tinyobj::attrib_t& attrib = reader.GetAttrib();
    ASSERT_EQ(attrib.vertices.size(), 3 * totalVertices());
    ASSERT_EQ(attrib.colors.size(), attrib.vertices.size());
    for (std::size_t v = 0; v < totalVertices(); ++v) {
        const int o = objectOfVertex(v);
        for (int c = 0; c < 3; ++c)
            EXPECT_NEAR(attrib.colors[3 * v + c], srgb(radiance[o][c]), 2e-6)
                << "vertex " << v << " of " << disc->objects()[o].id;
    }
    // One shape per object, one face per element, each face with its object's material.
    const auto& shapes = reader.GetShapes();
    const auto& materials = reader.GetMaterials();
    ASSERT_EQ(shapes.size(), disc->objects().size());
    std::size_t faces = 0;
    for (std::size_t o = 0; o < shapes.size(); ++o) {
        EXPECT_EQ(shapes[o].name, disc->objects()[o].id);
        faces += shapes[o].mesh.num_face_vertices.size();
        const std::string expected = scene.objects[o].material;
        for (int id : shapes[o].mesh.material_ids) {
            ASSERT_GE(id, 0);
            ASSERT_LT(id, static_cast<int>(materials.size()));
            EXPECT_EQ(materials[id].name, expected);
        }
    }
    EXPECT_EQ(faces, disc->elements().size());
    // Kd the reflectance; Ke the lamp's emitted radiance E/π, nothing for the others.
    ASSERT_EQ(materials.size(), 3u);
    for (const tinyobj::material_t& m : materials) {
        const Material* found = scene.findMaterial(m.name);
        ASSERT_NE(found, nullptr) << m.name;
        const Material& source = *found;
        for (int c = 0; c < 3; ++c) {
            EXPECT_NEAR(m.diffuse[c], source.reflectance[c], 1e-6) << m.name;
            EXPECT_NEAR(m.emission[c], source.emission[c] / kPi, 1e-5) << m.name;
        }
    }
}

TEST_F(ExportRoundTrip, PlyReadsBackWithOpenMesh) {
    const std::string path = pathFor("lit.ply");
    exportLitScene(*disc, b, path, &scene);
    OpenMesh::PolyMesh_ArrayKernelT<> mesh;
    mesh.request_vertex_colors();
    OpenMesh::IO::Options options = OpenMesh::IO::Options::VertexColor;
    ASSERT_TRUE(OpenMesh::IO::read_mesh(mesh, path, options));
    ASSERT_TRUE(options.check(OpenMesh::IO::Options::VertexColor));
    ASSERT_EQ(mesh.n_vertices(), totalVertices());
    EXPECT_EQ(mesh.n_faces(), disc->elements().size());
    for (const auto vh : mesh.vertices()) {
        const std::size_t v = static_cast<std::size_t>(vh.idx());
        const int o = objectOfVertex(v);
        const auto colour = mesh.color(vh);
        for (int c = 0; c < 3; ++c)
            EXPECT_NEAR(colour[c], 255.0 * srgb(radiance[o][c]), 0.51)
                << "vertex " << v << " of " << disc->objects()[o].id;
    }
}

TEST_F(ExportRoundTrip, GlbReadsBackWithTinyGltf) {
    const std::string path = pathFor("lit.glb");
    exportLitScene(*disc, b, path, &scene);
    tinygltf::TinyGLTF loader;
    tinygltf::Model model;
    std::string error, warning;
    ASSERT_TRUE(loader.LoadBinaryFromFile(&model, &error, &warning, path)) << error;
    EXPECT_TRUE(warning.empty()) << warning;
    ASSERT_TRUE(model.asset.extras.Has("exposure"));
    const double exposure = model.asset.extras.Get("exposure").GetNumberAsDouble();
    EXPECT_GT(exposure, 0.0);
    // Floats of an accessor (tightly packed or strided VEC3).
    auto floats = [&](int accessorIndex) {
        const tinygltf::Accessor& a = model.accessors.at(accessorIndex);
        const tinygltf::BufferView& view = model.bufferViews.at(a.bufferView);
        const unsigned char* data =
            model.buffers.at(view.buffer).data.data() + view.byteOffset + a.byteOffset;
        const std::size_t stride = view.byteStride ? view.byteStride : 3 * sizeof(float);
        std::vector<float> out(3 * a.count);
        for (std::size_t i = 0; i < a.count; ++i)
            std::memcpy(&out[3 * i], data + i * stride, 3 * sizeof(float));
        return out;
    };
    std::vector<int> seen(disc->objects().size(), 0);
    for (const tinygltf::Node& node : model.nodes) {
        if (node.mesh < 0) continue;
        int o = -1;
        for (std::size_t k = 0; k < disc->objects().size(); ++k)
            if (disc->objects()[k].id == node.name) o = static_cast<int>(k);
        ASSERT_GE(o, 0) << "node " << node.name;
        ++seen[o];
        const bool lamp = scene.findMaterial(scene.objects[o].material)->isEmitter();
        for (const tinygltf::Primitive& p : model.meshes.at(node.mesh).primitives) {
            ASSERT_TRUE(p.attributes.count("_RADIANCE")) << node.name;
            const std::vector<float> exact = floats(p.attributes.at("_RADIANCE"));
            for (std::size_t i = 0; i < exact.size(); ++i)
                EXPECT_NEAR(exact[i], radiance[o][i % 3], 1e-6) << node.name;
            if (lamp) {
                // Lamps: emissive material, black base colour.
                const tinygltf::Material& m = model.materials.at(p.material);
                EXPECT_GT(m.emissiveFactor[0], 0.0) << node.name;
                continue;
            }
            ASSERT_TRUE(p.attributes.count("COLOR_0")) << node.name;
            const std::vector<float> colour = floats(p.attributes.at("COLOR_0"));
            for (std::size_t i = 0; i < colour.size(); ++i)
                EXPECT_NEAR(colour[i], std::min(1.0, exposure * radiance[o][i % 3]), 1e-6)
                    << node.name;
        }
    }
    for (std::size_t o = 0; o < seen.size(); ++o) EXPECT_EQ(seen[o], 1) << disc->objects()[o].id;
}

TEST_F(ExportRoundTrip, TrianglesWeldWhereTheLightIsContinuousAndSplitWhereItJumps) {
    // Three floor triangles (the floor is object 0, y = 0): two share an edge with the same
    // radiosity at both its corners; the third meets them at a corner with another value,
    // as across a contact line.
    int floorElement = -1;
    for (std::size_t e = 0; e < disc->elements().size() && floorElement < 0; ++e)
        if (disc->elements()[e].object == 0) floorElement = static_cast<int>(e);
    ASSERT_GE(floorElement, 0);
    const Vec3 a(0, 0, 0), bb(0.1, 0, 0), c(0.1, 0, -0.1), d(0, 0, -0.1), e(-0.1, 0, 0);
    const Rgb lo(0.2, 0.3, 0.4), hi(0.5, 0.6, 0.7), dark(0.01, 0.02, 0.03);
    const std::vector<LitTriangle> triangles = {
        {floorElement, {a, bb, c}, {lo, hi, lo}},
        {floorElement, {a, c, d}, {lo, lo, hi}},
        {floorElement, {e, a, d}, {dark, dark, dark}},
    };
    const std::string path = pathFor("tri.glb");
    exportLitTriangles(*disc, triangles, path, &scene);
    tinygltf::TinyGLTF loader;
    tinygltf::Model model;
    std::string error, warning;
    ASSERT_TRUE(loader.LoadBinaryFromFile(&model, &error, &warning, path)) << error;
    const tinygltf::Node* floor = nullptr;
    for (const tinygltf::Node& node : model.nodes)
        if (node.name == "floor" && node.mesh >= 0) floor = &node;
    ASSERT_NE(floor, nullptr);
    const tinygltf::Primitive& p = model.meshes.at(floor->mesh).primitives.at(0);
    auto readVec3 = [&](int accessorIndex) {
        const tinygltf::Accessor& acc = model.accessors.at(accessorIndex);
        const tinygltf::BufferView& view = model.bufferViews.at(acc.bufferView);
        const unsigned char* data =
            model.buffers.at(view.buffer).data.data() + view.byteOffset + acc.byteOffset;
        std::vector<Vec3> out(acc.count);
        for (std::size_t i = 0; i < acc.count; ++i) {
            float f[3];
            std::memcpy(f, data + i * 3 * sizeof(float), sizeof f);
            out[i] = Vec3(f[0], f[1], f[2]);
        }
        return out;
    };
    const std::vector<Vec3> positions = readVec3(p.attributes.at("POSITION"));
    const std::vector<Vec3> radianceRead = readVec3(p.attributes.at("_RADIANCE"));
    // a, b, c, d shared by the two lit triangles; e, a, d again for the dark one.
    EXPECT_EQ(positions.size(), 7u);
    const tinygltf::Accessor& indices = model.accessors.at(p.indices);
    EXPECT_EQ(indices.count, 9u);
    // Every corner read back carries its triangle's radiance B/π at its position.
    for (const LitTriangle& t : triangles)
        for (int k = 0; k < 3; ++k) {
            bool found = false;
            for (std::size_t v = 0; v < positions.size(); ++v)
                if (glm::length(positions[v] - t.p[k]) < 1e-6 &&
                    glm::length(radianceRead[v] - t.radiosity[k] / kPi) < 1e-6)
                    found = true;
            EXPECT_TRUE(found) << t.p[k].x << " " << t.p[k].z;
        }
    // An element index out of range is bad input.
    EXPECT_THROW(exportLitTriangles(*disc, {{-1, {a, bb, c}, {lo, lo, lo}}}, path, &scene),
                 std::invalid_argument);
}

}  // namespace
}  // namespace penumbra
