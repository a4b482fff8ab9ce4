// Mesh files → TriMesh.
// Index: triangulation · cleanup into TriMesh · OBJ (tinyobjloader) · STL (OpenMesh IO) ·
//        glTF/GLB (tinygltf) · dispatch by extension (the polygon soup: mesh_io_internal.h;
//        OFF and PLY, our own strict readers: mesh_io_off_ply.cpp)

#include "edit/io/mesh_io.h"

// OpenMesh requires IO/MeshIO.hh before the mesh kernel header (sorted order keeps it so).

#include <OpenMesh/Core/IO/MeshIO.hh>
#include <OpenMesh/Core/IO/importer/ImporterT.hh>
#include <OpenMesh/Core/Mesh/PolyMesh_ArrayKernelT.hh>
#include <OpenMesh/Core/System/omstream.hh>
#include <algorithm>
#include <bit>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <glm/gtc/matrix_transform.hpp>
#include <glm/gtc/type_ptr.hpp>
#include <limits>
#include <numeric>
#include <sstream>
#include <string_view>

// Debian's libtinygltf and libtinyobjloader contain the implementations: include the plain
// headers here and define no *_IMPLEMENTATION macros.
#include <tiny_gltf.h>
#include <tiny_obj_loader.h>

#include "core/colour.h"
#include "core/durable_file.h"
#include "core/file_name.h"
#include "core/input_error.h"
#include "core/log.h"
#include "edit/io/mesh_io_internal.h"

namespace penumbra {

using namespace mesh_io_detail;

namespace {

double clampUnit(double value, double high) {
    if (!std::isfinite(value)) return 0.0;
    return std::clamp(value, 0.0, high);
}

double clampEmission(double value) {
    if (!std::isfinite(value)) return 0.0;
    return std::max(value, 0.0);
}

constexpr double kMaxMeshReflectance = 0.99;

// ---------------------------------------------------------------------------------------------
// Triangulation of one polygon.

/// Twice the triangle's area is below single-precision resolution relative to its longest
/// edge: the triangle has no usable area.
bool isZeroArea(const Vec3& a, const Vec3& b, const Vec3& c) {
    const double twiceArea = glm::length(glm::cross(b - a, c - a));
    const double longestSq =
        std::max({glm::dot(b - a, b - a), glm::dot(c - b, c - b), glm::dot(a - c, a - c)});
    return !(twiceArea > 1e-6 * longestSq) || longestSq == 0.0;
}

/// Appends triangles (as vertex indices) covering polygon `vertices[0..n)`. Ear clipping in
/// the plane of the Newell normal, which handles concave polygons; a triangle fan when the
/// polygon is too large or no ear can be found (self-intersecting or degenerate outline).
void triangulatePolygon(const std::vector<Vec3>& positions, const int* vertices, size_t n,
                        std::vector<std::array<int, 3>>& triangles) {
    auto appendFan = [&](const std::vector<size_t>& ring) {
        for (size_t i = 1; i + 1 < ring.size(); ++i) {
            triangles.push_back({vertices[ring[0]], vertices[ring[i]], vertices[ring[i + 1]]});
        }
    };
    std::vector<size_t> ring(n);
    std::iota(ring.begin(), ring.end(), size_t{0});
    if (n == 3) {
        appendFan(ring);
        return;
    }

    // Project onto the coordinate plane most perpendicular to the Newell normal.
    const Vec3 normal = newellNormal(positions, vertices, n);
    constexpr size_t kMaxEarClippingVertices = 1024;
    const Vec3 absNormal = glm::abs(normal);
    if (n > kMaxEarClippingVertices || !(absNormal.x + absNormal.y + absNormal.z > 0.0)) {
        appendFan(ring);
        return;
    }
    const int axis = absNormal.x >= absNormal.y && absNormal.x >= absNormal.z ? 0
                     : absNormal.y >= absNormal.z                             ? 1
                                                                              : 2;
    const int uAxis = (axis + 1) % 3;
    const int vAxis = (axis + 2) % 3;
    const double orientation = normal[axis] >= 0.0 ? 1.0 : -1.0;
    std::vector<glm::dvec2> flat(n);
    for (size_t i = 0; i < n; ++i) {
        const Vec3& p = positions[vertices[i]];
        flat[i] = glm::dvec2(p[uAxis], p[vAxis]);
    }
    auto cross2 = [&](size_t a, size_t b, size_t c) {
        const glm::dvec2 ab = flat[b] - flat[a];
        const glm::dvec2 ac = flat[c] - flat[a];
        return orientation * (ab.x * ac.y - ab.y * ac.x);
    };

    // Clip convex ears that contain no other remaining vertex.
    while (ring.size() > 3) {
        const size_t m = ring.size();
        bool clipped = false;
        for (size_t i = 0; i < m && !clipped; ++i) {
            const size_t a = ring[(i + m - 1) % m];
            const size_t b = ring[i];
            const size_t c = ring[(i + 1) % m];
            if (!(cross2(a, b, c) > 0.0)) continue;
            bool containsOther = false;
            for (size_t k = 0; k < m && !containsOther; ++k) {
                const size_t p = ring[k];
                if (p == a || p == b || p == c) continue;
                if (flat[p] == flat[a] || flat[p] == flat[b] || flat[p] == flat[c]) continue;
                containsOther =
                    cross2(a, b, p) >= 0.0 && cross2(b, c, p) >= 0.0 && cross2(c, a, p) >= 0.0;
            }
            if (containsOther) continue;
            triangles.push_back({vertices[a], vertices[b], vertices[c]});
            ring.erase(ring.begin() + static_cast<std::ptrdiff_t>(i));
            clipped = true;
        }
        if (!clipped) break;
    }
    appendFan(ring);
}

// ---------------------------------------------------------------------------------------------
// Cleanup: validate, triangulate, drop degenerate faces, compact vertices.

TriMesh buildTriMesh(const PolygonSoup& soup, const std::string& path) {
    const size_t vertexCount = soup.positions.size();
    const size_t faceCount = soup.faceCount();

    // A face pointing past the vertex list is a broken file, not a degenerate face.
    for (size_t f = 0; f < faceCount; ++f) {
        for (size_t k = soup.faceStart[f]; k < soup.faceStart[f + 1]; ++k) {
            const int v = soup.indices[k];
            if (v < 0 || static_cast<size_t>(v) >= vertexCount) {
                throw InputError(path, "",
                                 "face " + std::to_string(f + 1) + " refers to vertex " +
                                     std::to_string(v) + " but the file has " +
                                     std::to_string(vertexCount) + " vertices");
            }
        }
    }

    const bool anyMaterial = std::any_of(
        soup.faceMaterial.begin(), soup.faceMaterial.end(),
        [&](int m) { return m >= 0 && static_cast<size_t>(m) < soup.materials.size(); });
    int defaultMaterial = -1;

    std::vector<std::array<int, 3>> triangles;
    std::vector<int> triangleMaterial;
    std::vector<std::array<int, 3>> faceTriangles;
    size_t degenerate = 0;
    for (size_t f = 0; f < faceCount; ++f) {
        const int* vertices = soup.indices.data() + soup.faceStart[f];
        const size_t n = soup.faceStart[f + 1] - soup.faceStart[f];

        // Drop faces with too few vertices, a repeated vertex or a non-finite coordinate.
        bool bad = n < 3;
        for (size_t i = 0; i < n && !bad; ++i) {
            const Vec3& p = soup.positions[vertices[i]];
            bad = !(std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z));
            for (size_t j = i + 1; j < n && !bad; ++j) bad = vertices[i] == vertices[j];
        }
        if (bad) {
            ++degenerate;
            continue;
        }

        // Triangulate; a face is degenerate when none of its triangles has area.
        faceTriangles.clear();
        triangulatePolygon(soup.positions, vertices, n, faceTriangles);
        const size_t before = triangles.size();
        for (const auto& t : faceTriangles) {
            if (isZeroArea(soup.positions[t[0]], soup.positions[t[1]], soup.positions[t[2]])) {
                continue;
            }
            triangles.push_back(t);
        }
        if (triangles.size() == before) {
            ++degenerate;
            continue;
        }
        if (anyMaterial) {
            int material = soup.faceMaterial[f];
            if (material < 0 || static_cast<size_t>(material) >= soup.materials.size()) {
                if (defaultMaterial < 0) defaultMaterial = static_cast<int>(soup.materials.size());
                material = defaultMaterial;
            }
            triangleMaterial.insert(triangleMaterial.end(), triangles.size() - before, material);
        }
    }

    if (triangles.empty()) {
        throw InputError(path, "",
                         faceCount == 0 ? std::string("mesh has no faces")
                                        : "mesh has no valid faces (all " +
                                              std::to_string(faceCount) + " are degenerate)");
    }
    if (degenerate > 0) {
        spdlog::warn(
            "{}: dropped {} degenerate face{} (zero area, repeated vertex or non-finite "
            "coordinate)",
            path, degenerate, degenerate == 1 ? "" : "s");
    }

    // Keep only referenced vertices, in first-use order.
    TriMesh mesh;
    std::vector<int> remap(vertexCount, -1);
    mesh.triangles.reserve(triangles.size());
    for (auto t : triangles) {
        for (int& v : t) {
            if (remap[v] < 0) {
                remap[v] = static_cast<int>(mesh.positions.size());
                mesh.positions.push_back(soup.positions[v]);
            }
            v = remap[v];
        }
        mesh.triangles.push_back(t);
    }
    if (anyMaterial) {
        mesh.triangleMaterial = std::move(triangleMaterial);
        mesh.materials = soup.materials;
        mesh.materialNames = soup.materialNames;
        if (defaultMaterial >= 0) {
            mesh.materials.push_back(Material{});
            mesh.materialNames.push_back("default");
        }
    }
    return mesh;
}

// ---------------------------------------------------------------------------------------------
// OBJ + MTL through tinyobjloader.

PolygonSoup readObj(const std::string& path) {
    tinyobj::ObjReaderConfig config;
    config.triangulate = false;  // triangulated by buildTriMesh, like every other format
    config.vertex_color = false;
    tinyobj::ObjReader reader;
    if (!reader.ParseFromFile(path, config)) {
        throw InputError(path, "", "not a valid OBJ file: " + reader.Error());
    }

    PolygonSoup soup;
    const std::vector<tinyobj::real_t>& coordinates = reader.GetAttrib().vertices;
    soup.positions.reserve(coordinates.size() / 3);
    for (size_t i = 0; i + 2 < coordinates.size(); i += 3) {
        soup.positions.emplace_back(coordinates[i], coordinates[i + 1], coordinates[i + 2]);
    }
    for (const tinyobj::material_t& source : reader.GetMaterials()) {
        Material material;
        material.reflectance = Rgb(clampUnit(source.diffuse[0], kMaxMeshReflectance),
                                   clampUnit(source.diffuse[1], kMaxMeshReflectance),
                                   clampUnit(source.diffuse[2], kMaxMeshReflectance));
        material.emission =
            Rgb(clampEmission(source.emission[0]), clampEmission(source.emission[1]),
                clampEmission(source.emission[2]));
        soup.materials.push_back(material);
        soup.materialNames.push_back(source.name);
    }
    std::vector<int> face;
    for (const tinyobj::shape_t& shape : reader.GetShapes()) {
        size_t next = 0;
        for (size_t f = 0; f < shape.mesh.num_face_vertices.size(); ++f) {
            const size_t n = shape.mesh.num_face_vertices[f];
            face.clear();
            for (size_t k = 0; k < n && next + k < shape.mesh.indices.size(); ++k) {
                face.push_back(shape.mesh.indices[next + k].vertex_index);
            }
            next += n;
            const int material =
                f < shape.mesh.material_ids.size() ? shape.mesh.material_ids[f] : -1;
            soup.addFace(face.data(), face.size(), material);
        }
    }
    return soup;
}

// ---------------------------------------------------------------------------------------------
// STL through OpenMesh IO.

struct DoubleTraits : OpenMesh::DefaultTraits {
    typedef OpenMesh::Vec3d Point;
    typedef OpenMesh::Vec3d Normal;
};
using OpenMeshPolyMesh = OpenMesh::PolyMesh_ArrayKernelT<DoubleTraits>;

/// OpenMesh's importer, recording every face it is handed before the importer's own checks
/// (which silently refuse faces with repeated vertices), so those are counted as degenerate.
/// The STL reader itself already skips triangles whose corners merge; those go uncounted.
class RecordingImporter : public OpenMesh::IO::ImporterT<OpenMeshPolyMesh> {
public:
    RecordingImporter(OpenMeshPolyMesh& mesh, PolygonSoup& soup)
        : OpenMesh::IO::ImporterT<OpenMeshPolyMesh>(mesh), mSoup(soup) {}

    OpenMesh::FaceHandle add_face(const VHandles& handles) override {
        mFace.clear();
        for (const OpenMesh::VertexHandle& handle : handles) mFace.push_back(handle.idx());
        mSoup.addFace(mFace.data(), mFace.size(), -1);
        return OpenMesh::IO::ImporterT<OpenMeshPolyMesh>::add_face(handles);
    }

private:
    PolygonSoup& mSoup;
    std::vector<int> mFace;
};

/// Silences OpenMesh's global log streams while alive (its readers print to std::cerr).
class QuietOpenMesh {
public:
    QuietOpenMesh()
        : mErr(omerr().is_enabled()), mLog(omlog().is_enabled()), mOut(omout().is_enabled()) {
        omerr().disable();
        omlog().disable();
        omout().disable();
    }
    ~QuietOpenMesh() {
        if (mErr) omerr().enable();
        if (mLog) omlog().enable();
        if (mOut) omout().enable();
    }
    QuietOpenMesh(const QuietOpenMesh&) = delete;
    QuietOpenMesh& operator=(const QuietOpenMesh&) = delete;

private:
    bool mErr, mLog, mOut;
};

PolygonSoup readWithOpenMesh(const std::string& path, const std::string& formatName) {
    PolygonSoup soup;
    OpenMeshPolyMesh mesh;
    RecordingImporter importer(mesh, soup);
    OpenMesh::IO::Options options;
    bool ok = false;
    {
        QuietOpenMesh quiet;
        ok = OpenMesh::IO::IOManager().read(path, importer, options);
    }
    if (!ok) throw InputError(path, "", "not a valid " + formatName + " file");
    soup.positions.reserve(mesh.n_vertices());
    for (size_t i = 0; i < mesh.n_vertices(); ++i) {
        const OpenMesh::Vec3d& p = mesh.point(OpenMesh::VertexHandle(static_cast<int>(i)));
        soup.positions.emplace_back(p[0], p[1], p[2]);
    }
    return soup;
}

// ---------------------------------------------------------------------------------------------
// glTF / GLB through tinygltf.

/// Skips image decoding: only geometry and material factors are used.
bool ignoreImage(tinygltf::Image*, const int, std::string*, std::string*, int, int,
                 const unsigned char*, int, void*) {
    return true;
}

Mat4 localFromNode(const tinygltf::Node& node) {
    if (node.matrix.size() == 16) return glm::make_mat4(node.matrix.data());  // column-major
    Mat4 result(1.0);
    if (node.translation.size() == 3) {
        result = glm::translate(
            result, Vec3(node.translation[0], node.translation[1], node.translation[2]));
    }
    if (node.rotation.size() == 4) {
        // glTF stores the unit quaternion as (x, y, z, w).
        const double x = node.rotation[0], y = node.rotation[1], z = node.rotation[2],
                     w = node.rotation[3];
        Mat4 rotation(1.0);
        rotation[0] =
            glm::dvec4(1 - 2 * (y * y + z * z), 2 * (x * y + z * w), 2 * (x * z - y * w), 0);
        rotation[1] =
            glm::dvec4(2 * (x * y - z * w), 1 - 2 * (x * x + z * z), 2 * (y * z + x * w), 0);
        rotation[2] =
            glm::dvec4(2 * (x * z + y * w), 2 * (y * z - x * w), 1 - 2 * (x * x + y * y), 0);
        result = result * rotation;
    }
    if (node.scale.size() == 3) {
        result = glm::scale(result, Vec3(node.scale[0], node.scale[1], node.scale[2]));
    }
    return result;
}

/// Byte range of accessor element `i`, bounds-checked against its buffer view and buffer.
const unsigned char* accessorElement(const tinygltf::Model& model,
                                     const tinygltf::Accessor& accessor, size_t i,
                                     size_t elementBytes, const std::string& path) {
    const tinygltf::BufferView& view = model.bufferViews[accessor.bufferView];
    const tinygltf::Buffer& buffer = model.buffers[view.buffer];
    const int stride = accessor.ByteStride(view);
    if (stride <= 0) throw InputError(path, "", "invalid accessor byte stride");
    const size_t offset = accessor.byteOffset + i * static_cast<size_t>(stride);
    if (offset + elementBytes > view.byteLength ||
        view.byteOffset + offset + elementBytes > buffer.data.size()) {
        throw InputError(path, "", "accessor reads past the end of its buffer");
    }
    return buffer.data.data() + view.byteOffset + offset;
}

void checkAccessor(const tinygltf::Model& model, int index, const std::string& path) {
    if (index < 0 || static_cast<size_t>(index) >= model.accessors.size()) {
        throw InputError(path, "", "accessor " + std::to_string(index) + " does not exist");
    }
    const tinygltf::Accessor& accessor = model.accessors[index];
    if (accessor.sparse.isSparse) {
        throw InputError(path, "", "sparse accessors are not supported");
    }
    if (accessor.bufferView < 0 ||
        static_cast<size_t>(accessor.bufferView) >= model.bufferViews.size() ||
        model.bufferViews[accessor.bufferView].buffer < 0 ||
        static_cast<size_t>(model.bufferViews[accessor.bufferView].buffer) >=
            model.buffers.size()) {
        throw InputError(path, "",
                         "accessor " + std::to_string(index) + " has no valid buffer view");
    }
    // Every element takes at least one byte: rejects absurd counts before anything is sized
    // by them (and keeps count × stride from overflowing).
    const tinygltf::Buffer& buffer = model.buffers[model.bufferViews[accessor.bufferView].buffer];
    if (accessor.count > buffer.data.size()) {
        throw InputError(path, "",
                         "accessor " + std::to_string(index) + " count " +
                             std::to_string(accessor.count) + " exceeds its buffer");
    }
}

void appendPrimitive(const tinygltf::Model& model, const tinygltf::Primitive& primitive,
                     const Mat4& worldFromNode, const std::string& path, PolygonSoup& soup) {
    const int mode = primitive.mode < 0 ? TINYGLTF_MODE_TRIANGLES : primitive.mode;
    if (mode != TINYGLTF_MODE_TRIANGLES && mode != TINYGLTF_MODE_TRIANGLE_STRIP &&
        mode != TINYGLTF_MODE_TRIANGLE_FAN) {
        return;  // points and lines have no area
    }
    const auto positionAttribute = primitive.attributes.find("POSITION");
    if (positionAttribute == primitive.attributes.end()) return;

    // Positions, transformed into the file's scene space.
    checkAccessor(model, positionAttribute->second, path);
    const tinygltf::Accessor& positions = model.accessors[positionAttribute->second];
    if (positions.type != TINYGLTF_TYPE_VEC3 ||
        positions.componentType != TINYGLTF_COMPONENT_TYPE_FLOAT) {
        throw InputError(path, "", "POSITION accessor must hold float VEC3 values");
    }
    const int base = static_cast<int>(soup.positions.size());
    for (size_t i = 0; i < positions.count; ++i) {
        float xyz[3];
        std::memcpy(xyz, accessorElement(model, positions, i, sizeof xyz, path), sizeof xyz);
        soup.positions.push_back(Vec3(worldFromNode * glm::dvec4(xyz[0], xyz[1], xyz[2], 1.0)));
    }

    // Vertex order: the index accessor, or 0..count-1 without one.
    std::vector<int> order;
    if (primitive.indices >= 0) {
        checkAccessor(model, primitive.indices, path);
        const tinygltf::Accessor& indices = model.accessors[primitive.indices];
        size_t bytes = 0;
        switch (indices.componentType) {
            case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE:
                bytes = 1;
                break;
            case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT:
                bytes = 2;
                break;
            case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT:
                bytes = 4;
                break;
            default:
                throw InputError(path, "", "index accessor must hold unsigned integers");
        }
        if (indices.type != TINYGLTF_TYPE_SCALAR) {
            throw InputError(path, "", "index accessor must hold scalars");
        }
        order.reserve(indices.count);
        for (size_t i = 0; i < indices.count; ++i) {
            const unsigned char* element = accessorElement(model, indices, i, bytes, path);
            uint32_t value = 0;
            if (bytes == 1) value = element[0];
            if (bytes == 2) {
                uint16_t v16;
                std::memcpy(&v16, element, 2);
                value = v16;
            }
            if (bytes == 4) std::memcpy(&value, element, 4);
            if (value >= positions.count) {
                throw InputError(path, "",
                                 "vertex index " + std::to_string(value) + " is out of range (" +
                                     std::to_string(positions.count) + " vertices)");
            }
            order.push_back(base + static_cast<int>(value));
        }
    } else {
        order.resize(positions.count);
        std::iota(order.begin(), order.end(), base);
    }

    // Triangles per glTF mode; a mirroring node transform reverses the winding.
    const bool mirrored = glm::determinant(glm::dmat3(worldFromNode)) < 0.0;
    const int material = primitive.material;
    auto addTriangle = [&](int a, int b, int c) {
        const int face[3] = {a, mirrored ? c : b, mirrored ? b : c};
        soup.addFace(face, 3, material);
    };
    const size_t n = order.size();
    if (mode == TINYGLTF_MODE_TRIANGLES) {
        for (size_t i = 0; i + 2 < n; i += 3) addTriangle(order[i], order[i + 1], order[i + 2]);
    } else if (mode == TINYGLTF_MODE_TRIANGLE_STRIP) {
        for (size_t i = 0; i + 2 < n; ++i) {
            if (i % 2 == 0)
                addTriangle(order[i], order[i + 1], order[i + 2]);
            else
                addTriangle(order[i], order[i + 2], order[i + 1]);
        }
    } else {
        for (size_t i = 1; i + 1 < n; ++i) addTriangle(order[i], order[i + 1], order[0]);
    }
}

/// Loads a glTF or GLB model; its images are decoded (tinygltf's own PNG/JPEG decoder) only
/// when `decodeImages` (the scene importer's texture means).
tinygltf::Model loadGltfModel(const std::string& path, bool binary, bool decodeImages) {
    tinygltf::TinyGLTF loader;
    if (!decodeImages) loader.SetImageLoader(&ignoreImage, nullptr);
    loader.SetStoreOriginalJSONForExtrasAndExtensions(true);
    tinygltf::Model model;
    std::string error;
    std::string warning;
    const bool ok = binary ? loader.LoadBinaryFromFile(&model, &error, &warning, path)
                           : loader.LoadASCIIFromFile(&model, &error, &warning, path);
    if (!ok) {
        throw InputError(path, "",
                         std::string("not a valid ") + (binary ? "GLB" : "glTF") +
                             " file: " + (error.empty() ? warning : error));
    }
    return model;
}

/// Calls `visit(node, identity)` for each root node: the default scene's (else scene 0's),
/// or every node that is nobody's child when the file has no scene.
void visitRootNodes(const tinygltf::Model& model,
                    const std::function<void(int, const Mat4&)>& visit) {
    const Mat4 identity(1.0);
    if (!model.scenes.empty()) {
        const size_t sceneIndex =
            model.defaultScene >= 0 && static_cast<size_t>(model.defaultScene) < model.scenes.size()
                ? static_cast<size_t>(model.defaultScene)
                : 0;
        for (int root : model.scenes[sceneIndex].nodes) visit(root, identity);
        return;
    }
    std::vector<bool> isChild(model.nodes.size(), false);
    for (const tinygltf::Node& node : model.nodes)
        for (int child : node.children)
            if (child >= 0 && static_cast<size_t>(child) < isChild.size()) isChild[child] = true;
    for (size_t i = 0; i < model.nodes.size(); ++i)
        if (!isChild[i]) visit(static_cast<int>(i), identity);
}

PolygonSoup readGltf(const std::string& path, bool binary) {
    const tinygltf::Model model = loadGltfModel(path, binary, false);

    PolygonSoup soup;
    for (const tinygltf::Material& source : model.materials) {
        Material material;
        const std::vector<double>& base = source.pbrMetallicRoughness.baseColorFactor;
        if (base.size() >= 3) {
            material.reflectance = Rgb(clampUnit(base[0], kMaxMeshReflectance),
                                       clampUnit(base[1], kMaxMeshReflectance),
                                       clampUnit(base[2], kMaxMeshReflectance));
        }
        double strength = 1.0;
        const auto extension = source.extensions.find("KHR_materials_emissive_strength");
        if (extension != source.extensions.end() && extension->second.Has("emissiveStrength") &&
            extension->second.Get("emissiveStrength").IsNumber()) {
            strength = extension->second.Get("emissiveStrength").GetNumberAsDouble();
        }
        if (source.emissiveFactor.size() >= 3) {
            material.emission = Rgb(clampEmission(source.emissiveFactor[0] * strength),
                                    clampEmission(source.emissiveFactor[1] * strength),
                                    clampEmission(source.emissiveFactor[2] * strength));
        }
        soup.materials.push_back(material);
        soup.materialNames.push_back(source.name.empty()
                                         ? "material" + std::to_string(soup.materials.size() - 1)
                                         : source.name);
    }

    // Walk the node hierarchy, refusing cycles.
    std::vector<bool> onPath(model.nodes.size(), false);
    std::function<void(int, const Mat4&)> visit = [&](int index, const Mat4& worldFromParent) {
        if (index < 0 || static_cast<size_t>(index) >= model.nodes.size()) {
            throw InputError(path, "", "node " + std::to_string(index) + " does not exist");
        }
        if (onPath[index]) {
            throw InputError(path, "", "node " + std::to_string(index) + " is its own ancestor");
        }
        onPath[index] = true;
        const tinygltf::Node& node = model.nodes[index];
        const Mat4 worldFromNode = worldFromParent * localFromNode(node);
        if (node.mesh >= 0) {
            if (static_cast<size_t>(node.mesh) >= model.meshes.size()) {
                throw InputError(path, "", "mesh " + std::to_string(node.mesh) + " does not exist");
            }
            for (const tinygltf::Primitive& primitive : model.meshes[node.mesh].primitives) {
                appendPrimitive(model, primitive, worldFromNode, path, soup);
            }
        }
        for (int child : node.children) visit(child, worldFromNode);
        onPath[index] = false;
    };

    if (!model.scenes.empty() || !model.nodes.empty()) {
        visitRootNodes(model, visit);
    } else {
        for (const tinygltf::Mesh& mesh : model.meshes)
            for (const tinygltf::Primitive& primitive : mesh.primitives)
                appendPrimitive(model, primitive, Mat4(1.0), path, soup);
    }
    return soup;
}

// ---------------------------------------------------------------------------------------------
// Scene files for import: parts per glTF mesh node or OBJ object.

/// The part of a face list that `soup` holds, built into a MeshFilePart (materials by index).
MeshFilePart buildPart(PolygonSoup& soup, std::size_t fileMaterials, const std::string& where) {
    // Placeholder materials keep the file's indices through buildTriMesh; faces without one
    // get index fileMaterials ("default"), which is -1 here.
    soup.materials.assign(fileMaterials, Material{});
    soup.materialNames.assign(fileMaterials, "");
    MeshFilePart part;
    part.mesh = buildTriMesh(soup, where);
    part.triangleMaterial.assign(part.mesh.triangles.size(), -1);
    for (std::size_t t = 0; t < part.mesh.triangleMaterial.size(); ++t) {
        const int m = part.mesh.triangleMaterial[t];
        part.triangleMaterial[t] = m >= 0 && static_cast<std::size_t>(m) < fileMaterials ? m : -1;
    }
    part.mesh.triangleMaterial.clear();
    part.mesh.materials.clear();
    part.mesh.materialNames.clear();
    return part;
}

/// Refuses a file that requires an extension the reader cannot honour (the geometry would be
/// wrong) and lists in `scene.ignored` what it reads past: other used extensions, skins,
/// animations. (KHR_materials_unlit: a shading-model hint the radiosity solution replaces.)
void checkGltfExtensions(const tinygltf::Model& model, const std::string& path,
                         MeshFileScene& scene) {
    const std::vector<std::string> known = {
        "KHR_lights_punctual", "KHR_materials_emissive_strength", "KHR_materials_unlit"};
    for (const std::string& e : model.extensionsRequired)
        if (std::find(known.begin(), known.end(), e) == known.end())
            throw InputError(path, "", "requires the extension " + e + ", which is not supported");
    for (const std::string& e : model.extensionsUsed)
        if (std::find(known.begin(), known.end(), e) == known.end())
            scene.ignored.push_back("extension " + e);
    if (!model.skins.empty()) scene.ignored.push_back("skins (the bind pose is used)");
    if (!model.animations.empty()) scene.ignored.push_back("animations");
}

/// A glTF material as the importer sees it: base colour (scaled by its texture's mean when the
/// texture's image is decoded, 8-bit RGB or RGBA), emission with its strength, sidedness.
MeshFileMaterial importGltfMaterial(const tinygltf::Model& model,
                                    const tinygltf::Material& source) {
    MeshFileMaterial material;
    material.name = source.name;
    const std::vector<double>& base = source.pbrMetallicRoughness.baseColorFactor;
    if (base.size() >= 3) material.baseColor = Rgb(base[0], base[1], base[2]);
    material.textured = source.pbrMetallicRoughness.baseColorTexture.index >= 0;
    // The texture's mean (its texels are sRGB-encoded) scales the factor.
    const int texture = source.pbrMetallicRoughness.baseColorTexture.index;
    if (material.textured && static_cast<size_t>(texture) < model.textures.size()) {
        const int imageIndex = model.textures[texture].source;
        if (imageIndex >= 0 && static_cast<size_t>(imageIndex) < model.images.size()) {
            const tinygltf::Image& image = model.images[imageIndex];
            const std::size_t texels = static_cast<std::size_t>(std::max(image.width, 0)) *
                                       static_cast<std::size_t>(std::max(image.height, 0));
            const int channels = image.component;
            if (texels > 0 && image.bits == 8 && channels >= 3 &&
                image.image.size() >= texels * static_cast<std::size_t>(channels)) {
                Rgb sum(0.0);
                for (std::size_t t = 0; t < texels; ++t)
                    for (int c = 0; c < 3; ++c) {
                        const double v = image.image[t * channels + c] / 255.0;
                        sum[c] += srgbDecode(v);
                    }
                material.baseColor *= sum / static_cast<double>(texels);
                material.textured = false;  // read
            }
        }
    }
    material.doubleSided = source.doubleSided;
    double strength = 1.0;
    const auto extension = source.extensions.find("KHR_materials_emissive_strength");
    if (extension != source.extensions.end() && extension->second.Has("emissiveStrength") &&
        extension->second.Get("emissiveStrength").IsNumber())
        strength = extension->second.Get("emissiveStrength").GetNumberAsDouble();
    if (source.emissiveFactor.size() >= 3)
        material.emissive =
            Rgb(source.emissiveFactor[0], source.emissiveFactor[1], source.emissiveFactor[2]) *
            strength;
    material.extras = source.extras_json_string;
    return material;
}

/// Adds the mesh of node `index` (if it has one with faces) as a part in world space;
/// `morphs` is set when a primitive has morph targets (only the base shape is read).
void importNodeMesh(const tinygltf::Model& model, int index, const Mat4& worldFromNode,
                    const std::string& path, std::size_t fileMaterials, MeshFileScene& scene,
                    bool& morphs) {
    const tinygltf::Node& node = model.nodes[index];
    const std::string where = path + " (node " + std::to_string(index) + ")";
    if (node.mesh >= 0) {
        if (static_cast<size_t>(node.mesh) >= model.meshes.size())
            throw InputError(path, "", "mesh " + std::to_string(node.mesh) + " does not exist");
        const tinygltf::Mesh& mesh = model.meshes[node.mesh];
        PolygonSoup soup;
        for (const tinygltf::Primitive& primitive : mesh.primitives) {
            morphs = morphs || !primitive.targets.empty();
            appendPrimitive(model, primitive, worldFromNode, path, soup);
        }
        if (soup.faceCount() > 0) {
            MeshFilePart part = buildPart(soup, fileMaterials, where);
            part.name = !node.name.empty() ? node.name : mesh.name;
            part.extras = node.extras_json_string;
            scene.parts.push_back(std::move(part));
        }
    }
}

/// Adds the node's camera, if it has a valid one, placed by the node (a glTF camera looks
/// along its −Z with +Y up).
void importNodeCamera(const tinygltf::Model& model, const tinygltf::Node& node,
                      const Mat4& worldFromNode, MeshFileScene& scene) {
    const auto at = [&](const glm::dvec4& v) { return Vec3(worldFromNode * v); };
    if (node.camera >= 0 && static_cast<size_t>(node.camera) < model.cameras.size()) {
        const tinygltf::Camera& source = model.cameras[node.camera];
        MeshFileCamera camera;
        camera.name = !source.name.empty() ? source.name : node.name;
        camera.position = at(glm::dvec4(0, 0, 0, 1));
        camera.forward = at(glm::dvec4(0, 0, -1, 0));
        camera.up = at(glm::dvec4(0, 1, 0, 0));
        camera.perspective = source.type != "orthographic";
        if (camera.perspective && source.perspective.yfov > 0)
            camera.yfovDeg = source.perspective.yfov * 180.0 / M_PI;
        scene.cameras.push_back(camera);
    }
}

/// Adds the node's KHR_lights_punctual light, if it names one, placed by the node (a glTF
/// light shines along its −Z).
void importNodeLight(const tinygltf::Model& model, const tinygltf::Node& node,
                     const Mat4& worldFromNode, const std::string& path, MeshFileScene& scene) {
    const auto at = [&](const glm::dvec4& v) { return Vec3(worldFromNode * v); };
    const auto lightExtension = node.extensions.find("KHR_lights_punctual");
    if (lightExtension != node.extensions.end() && lightExtension->second.Has("light") &&
        lightExtension->second.Get("light").IsInt()) {
        const int l = lightExtension->second.Get("light").GetNumberAsInt();
        if (l < 0 || static_cast<size_t>(l) >= model.lights.size())
            throw InputError(path, "", "light " + std::to_string(l) + " does not exist");
        const tinygltf::Light& source = model.lights[l];
        MeshFileLight light;
        light.name = !source.name.empty() ? source.name : node.name;
        light.type = source.type;
        if (source.color.size() >= 3)
            light.colour = Rgb(source.color[0], source.color[1], source.color[2]);
        light.intensity = source.intensity;
        light.position = at(glm::dvec4(0, 0, 0, 1));
        light.direction = at(glm::dvec4(0, 0, -1, 0));
        scene.lights.push_back(light);
    }
}

MeshFileScene readGltfScene(const std::string& path, bool binary) {
    const tinygltf::Model model = loadGltfModel(path, binary, true);
    MeshFileScene scene;
    scene.assetExtras = model.asset.extras_json_string;
    checkGltfExtensions(model, path, scene);
    for (const tinygltf::Material& source : model.materials)
        scene.materials.push_back(importGltfMaterial(model, source));
    const std::size_t fileMaterials = scene.materials.size();
    bool morphs = false;

    // Walk the node hierarchy, refusing cycles: mesh parts, cameras and lights per node.
    std::vector<bool> onPath(model.nodes.size(), false);
    std::function<void(int, const Mat4&)> visit = [&](int index, const Mat4& worldFromParent) {
        if (index < 0 || static_cast<size_t>(index) >= model.nodes.size())
            throw InputError(path, "", "node " + std::to_string(index) + " does not exist");
        if (onPath[index])
            throw InputError(path, "", "node " + std::to_string(index) + " is its own ancestor");
        onPath[index] = true;
        const tinygltf::Node& node = model.nodes[index];
        const Mat4 worldFromNode = worldFromParent * localFromNode(node);
        importNodeMesh(model, index, worldFromNode, path, fileMaterials, scene, morphs);
        importNodeCamera(model, node, worldFromNode, scene);
        importNodeLight(model, node, worldFromNode, path, scene);
        for (int child : node.children) visit(child, worldFromNode);
        onPath[index] = false;
    };
    visitRootNodes(model, visit);
    if (morphs) scene.ignored.push_back("morph targets (the base shape is used)");
    return scene;
}

MeshFileScene readObjScene(const std::string& path) {
    tinyobj::ObjReaderConfig config;
    config.triangulate = false;
    config.vertex_color = false;
    tinyobj::ObjReader reader;
    if (!reader.ParseFromFile(path, config))
        throw InputError(path, "", "not a valid OBJ file: " + reader.Error());
    MeshFileScene scene;
    std::vector<Vec3> positions;
    const std::vector<tinyobj::real_t>& coordinates = reader.GetAttrib().vertices;
    for (size_t i = 0; i + 2 < coordinates.size(); i += 3)
        positions.emplace_back(coordinates[i], coordinates[i + 1], coordinates[i + 2]);
    for (const tinyobj::material_t& source : reader.GetMaterials()) {
        MeshFileMaterial material;
        material.name = source.name;
        material.baseColor = Rgb(source.diffuse[0], source.diffuse[1], source.diffuse[2]);
        material.emissive = Rgb(source.emission[0], source.emission[1], source.emission[2]);
        material.textured = !source.diffuse_texname.empty();
        scene.materials.push_back(material);
    }
    std::vector<int> face;
    for (const tinyobj::shape_t& shape : reader.GetShapes()) {
        PolygonSoup soup;
        soup.positions = positions;
        size_t next = 0;
        for (size_t f = 0; f < shape.mesh.num_face_vertices.size(); ++f) {
            const size_t n = shape.mesh.num_face_vertices[f];
            face.clear();
            for (size_t k = 0; k < n && next + k < shape.mesh.indices.size(); ++k)
                face.push_back(shape.mesh.indices[next + k].vertex_index);
            next += n;
            const int material =
                f < shape.mesh.material_ids.size() ? shape.mesh.material_ids[f] : -1;
            soup.addFace(face.data(), face.size(), material);
        }
        if (soup.faceCount() == 0) continue;
        MeshFilePart part =
            buildPart(soup, scene.materials.size(), path + " (object " + shape.name + ")");
        part.name = shape.name;
        scene.parts.push_back(std::move(part));
    }
    return scene;
}

/// Reads the file with the reader its (lower-case) extension names.
PolygonSoup readByExtension(const std::string& path, const std::string& extension) {
    if (extension == ".obj") return readObj(path);
    if (extension == ".off") return readOff(path);
    if (extension == ".ply") return readPly(path);
    if (extension == ".stl") return readWithOpenMesh(path, "STL");
    if (extension == ".gltf") return readGltf(path, false);
    if (extension == ".glb") return readGltf(path, true);
    throw InputError(path, "",
                     "unsupported mesh format '" + extension +
                         "' (expected .obj, .off, .ply, .stl, .gltf or .glb)");
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// Dispatch by extension.

TriMesh loadMeshFile(const std::string& path) {
    // Report a missing or unreadable file the same way for every format.
    std::error_code error;
    if (!std::filesystem::exists(path, error)) {
        throw InputError(path, "", "mesh file does not exist");
    }
    if (std::filesystem::is_directory(path, error)) {
        throw InputError(path, "", "mesh file is a directory");
    }
    if (!std::ifstream(path, std::ios::binary).good()) {
        throw InputError(path, "", std::string("cannot read mesh file: ") + std::strerror(errno));
    }

    const std::string extension = lowerExtension(path);
    PolygonSoup soup;
    try {
        soup = readByExtension(path, extension);
    } catch (const InputError&) {
        throw;
    } catch (const std::exception& error) {
        // E.g. an allocation failure for a header that announces billions of vertices.
        throw InputError(path, "", std::string("cannot read mesh file: ") + error.what());
    }
    return buildTriMesh(soup, path);
}

MeshFileScene loadMeshFileScene(const std::string& path) {
    std::error_code error;
    if (!std::filesystem::exists(path, error)) throw InputError(path, "", "file does not exist");
    if (std::filesystem::is_directory(path, error))
        throw InputError(path, "", "is a directory, not a scene file");
    if (!std::ifstream(path, std::ios::binary).good())
        throw InputError(path, "", std::string("cannot read file: ") + std::strerror(errno));
    const std::string extension = lowerExtension(path);
    MeshFileScene scene;
    try {
        if (extension == ".gltf" || extension == ".glb")
            scene = readGltfScene(path, extension == ".glb");
        else if (extension == ".obj")
            scene = readObjScene(path);
        else
            throw InputError(path, "",
                             "unsupported scene format '" + extension +
                                 "' (expected .json, .gltf, .glb or .obj)");
    } catch (const InputError&) {
        throw;
    } catch (const std::exception& e) {
        throw InputError(path, "", std::string("cannot read file: ") + e.what());
    }
    if (scene.parts.empty()) throw InputError(path, "", "no mesh with faces in the file");
    return scene;
}

void saveObjMesh(const TriMesh& mesh, const std::string& path) {
    const bool materials = !mesh.triangleMaterial.empty() && !mesh.materials.empty();
    const std::filesystem::path mtlPath = std::filesystem::path(path).replace_extension(".mtl");
    if (materials) {
        writeFileAtomically(mtlPath.string(), [&](std::ostream& mtl) {
            mtl.precision(9);
            for (std::size_t m = 0; m < mesh.materials.size(); ++m) {
                const Material& material = mesh.materials[m];
                mtl << "newmtl m" << m << "\n";
                if (m < mesh.materialNames.size()) mtl << "# " << mesh.materialNames[m] << "\n";
                mtl << "Kd " << material.reflectance.x << ' ' << material.reflectance.y << ' '
                    << material.reflectance.z << "\n";
                mtl << "Ke " << material.emission.x << ' ' << material.emission.y << ' '
                    << material.emission.z << "\n";
            }
        });
    }
    writeFileAtomically(path, [&](std::ostream& obj) {
        obj.precision(9);
        obj << "# penumbra mesh\n";
        if (materials) obj << "mtllib " << mtlPath.filename().string() << "\n";
        for (const Vec3& p : mesh.positions) obj << "v " << p.x << ' ' << p.y << ' ' << p.z << "\n";
        int current = -1;
        for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
            if (materials && mesh.triangleMaterial[t] != current) {
                current = mesh.triangleMaterial[t];
                obj << "usemtl m" << current << "\n";
            }
            const auto& f = mesh.triangles[t];
            obj << "f " << f[0] + 1 << ' ' << f[1] + 1 << ' ' << f[2] + 1 << "\n";
        }
    });
}

}  // namespace penumbra
