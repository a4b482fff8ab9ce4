#include "edit/io/export.h"

// Index: helpers (sRGB, numbers, bytes, files) · lit objects · PLY · glTF/GLB · OBJ · dispatch

#include <algorithm>
#include <array>
#include <bit>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <glm/gtc/constants.hpp>
#include <limits>
#include <map>
#include <nlohmann/json.hpp>
#include <set>
#include <stdexcept>
#include <tuple>

#include "core/colour.h"
#include "core/durable_file.h"
#include "core/file_name.h"
#include "edit/io/scene_io.h"
#include "solver/discretization.h"

namespace penumbra {

namespace {

// ---------------------------------------------------------------------------------------
// Helpers

/// Appends a space and the shortest round-trip decimal form of `value` (locale-independent).
template <typename T>
void appendNumber(std::string& out, T value) {
    char buffer[64];
    auto result = std::to_chars(buffer, buffer + sizeof(buffer), value);
    out.push_back(' ');
    out.append(buffer, result.ptr);
}

/// Appends a space and `value` with `decimals` fixed decimals (locale-independent).
void appendFixed(std::string& out, double value, int decimals) {
    char buffer[64];
    auto result =
        std::to_chars(buffer, buffer + sizeof(buffer), value, std::chars_format::fixed, decimals);
    out.push_back(' ');
    out.append(buffer, result.ptr);
}

/// Appends the little-endian bytes of a 4-byte value.
template <typename T>
void appendLittleEndian(std::string& out, T value) {
    static_assert(sizeof(T) == 4);
    auto bits = std::bit_cast<std::uint32_t>(value);
    for (int i = 0; i < 4; ++i) out.push_back(static_cast<char>((bits >> (8 * i)) & 0xffu));
}

/// An object id as one token on a text line: whitespace and control characters become '_'.
std::string lineToken(const std::string& id) {
    std::string out = id.empty() ? std::string("_") : id;
    for (char& c : out) {
        if (std::isspace(static_cast<unsigned char>(c)) ||
            std::iscntrl(static_cast<unsigned char>(c)))
            c = '_';
    }
    return out;
}

std::string base64Encode(const std::string& bytes) {
    static const char kAlphabet[] =
        "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    std::string out;
    out.reserve((bytes.size() + 2) / 3 * 4);
    size_t i = 0;
    for (; i + 2 < bytes.size(); i += 3) {
        std::uint32_t v = (std::uint32_t(std::uint8_t(bytes[i])) << 16) |
                          (std::uint32_t(std::uint8_t(bytes[i + 1])) << 8) |
                          std::uint32_t(std::uint8_t(bytes[i + 2]));
        out.push_back(kAlphabet[(v >> 18) & 63]);
        out.push_back(kAlphabet[(v >> 12) & 63]);
        out.push_back(kAlphabet[(v >> 6) & 63]);
        out.push_back(kAlphabet[v & 63]);
    }
    if (i < bytes.size()) {
        std::uint32_t v = std::uint32_t(std::uint8_t(bytes[i])) << 16;
        if (i + 1 < bytes.size()) v |= std::uint32_t(std::uint8_t(bytes[i + 1])) << 8;
        out.push_back(kAlphabet[(v >> 18) & 63]);
        out.push_back(kAlphabet[(v >> 12) & 63]);
        out.push_back(i + 1 < bytes.size() ? kAlphabet[(v >> 6) & 63] : '=');
        out.push_back('=');
    }
    return out;
}

// ---------------------------------------------------------------------------------------
// Lit objects: what every format writes

struct LitObject {
    std::string id;
    std::string materialName;  ///< the scene material's name ("" when unknown)
    bool twoSided = false;
    std::vector<Vec3> positions;  ///< world space, per mesh vertex
    std::vector<Vec3> normals;    ///< unit, area-weighted over the elements around a vertex
    std::vector<Rgb> radiosity;   ///< per mesh vertex, W/m²
    /// Element polygons of this object (indices into positions), in element order.
    std::vector<std::vector<int>> polygons;
    std::vector<int> polygonMaterial;  ///< per polygon, index into Discretization::materials()
    /// The scene object as the scene file writes it, for a primitive shape (box, quad, sphere,
    /// cylinder): a re-import rebuilds it instead of its element triangles. Null otherwise.
    nlohmann::json source;
};

std::vector<LitObject> collectLitObjects(const Discretization& disc,
                                         const std::vector<Rgb>& elementRadiosity,
                                         const Scene* scene) {
    const auto& surfaces = disc.objects();
    std::vector<LitObject> lit(surfaces.size());
    for (size_t o = 0; o < surfaces.size(); ++o) {
        lit[o].id = surfaces[o].id;
        if (scene)
            for (const SceneObject& so : scene->objects)
                if (so.id == surfaces[o].id) {
                    lit[o].materialName = so.material;
                    if (so.shape.type != ShapeType::Mesh) lit[o].source = objectToJson(so);
                }
        // A two-sided object's back is explicit geometry (the twin sheet, its own light), so
        // the material stays single-sided; only an object without twins relies on it.
        lit[o].twoSided = surfaces[o].twoSided && surfaces[o].faceTwin.empty();
        lit[o].positions = surfaces[o].worldPositions;
        lit[o].normals.assign(lit[o].positions.size(), Vec3(0.0));
        lit[o].radiosity = disc.vertexValues(static_cast<int>(o), elementRadiosity);
        lit[o].radiosity.resize(lit[o].positions.size(), Rgb(0.0));
    }

    // Accumulate Newell normals (length = 2 × area) of each element onto its vertices.
    const auto& elements = disc.elements();
    for (size_t e = 0; e < elements.size(); ++e) {
        const Element& element = elements[e];
        LitObject& object = lit[element.object];
        object.polygons.push_back(element.vertices);
        object.polygonMaterial.push_back(disc.patches()[element.patch].material);
        const Vec3 newell =
            newellNormal(object.positions, element.vertices.data(), element.vertices.size());
        for (int v : element.vertices) object.normals[v] += newell;
    }
    for (LitObject& object : lit) {
        for (Vec3& normal : object.normals) {
            const double length = glm::length(normal);
            normal = length > 0.0 ? normal / length : Vec3(0, 0, 1);
        }
    }
    return lit;
}

/// Fan triangles of a convex element polygon, starting at a corner vertex so that edge
/// midpoints inserted by subdivision do not produce degenerate triangles.
void appendFanTriangles(const std::vector<int>& polygon, const std::vector<Vec3>& positions,
                        std::vector<std::uint32_t>& indices) {
    const size_t n = polygon.size();
    if (n < 3) return;
    size_t start = 0;
    double bestTurn = -1.0;
    for (size_t i = 0; i < n; ++i) {
        const Vec3& prev = positions[polygon[(i + n - 1) % n]];
        const Vec3& here = positions[polygon[i]];
        const Vec3& next = positions[polygon[(i + 1) % n]];
        const Vec3 a = prev - here, b = next - here;
        const double scale = glm::length(a) * glm::length(b);
        const double turn = scale > 0.0 ? glm::length(glm::cross(a, b)) / scale : 0.0;
        if (turn > bestTurn + 1e-9) {
            bestTurn = turn;
            start = i;
        }
    }
    for (size_t k = 1; k + 1 < n; ++k) {
        indices.push_back(static_cast<std::uint32_t>(polygon[start]));
        indices.push_back(static_cast<std::uint32_t>(polygon[(start + k) % n]));
        indices.push_back(static_cast<std::uint32_t>(polygon[(start + k + 1) % n]));
    }
}

// ---------------------------------------------------------------------------------------
// PLY (binary little-endian)

/// `faces`: (object, polygon) in the order the faces are written; `faceNote` says what face i
/// is in the header's comment.
std::string encodePly(const std::vector<LitObject>& lit,
                      const std::vector<std::pair<int, int>>& faces, const std::string& faceNote) {
    size_t vertexCount = 0;
    std::vector<size_t> firstVertex(lit.size());
    for (size_t o = 0; o < lit.size(); ++o) {
        firstVertex[o] = vertexCount;
        vertexCount += lit[o].positions.size();
    }

    std::string out =
        "ply\n"
        "format binary_little_endian 1.0\n"
        "comment Penumbra lit scene: world space metres; red green blue = radiance B/pi, "
        "sRGB-encoded, clipped; radiosity_* = B in W/m^2; " +
        faceNote + "\n";
    for (const LitObject& object : lit) {
        out.append("comment object ").append(lineToken(object.id)).push_back('\n');
    }
    out += "element vertex " + std::to_string(vertexCount) +
           "\n"
           "property float x\nproperty float y\nproperty float z\n"
           "property uchar red\nproperty uchar green\nproperty uchar blue\n"
           "property float radiosity_r\nproperty float radiosity_g\nproperty float radiosity_b\n"
           "element face " +
           std::to_string(faces.size()) +
           "\n"
           "property list uchar int vertex_indices\n"
           "end_header\n";

    const double invPi = glm::one_over_pi<double>();
    for (const LitObject& object : lit) {
        for (size_t v = 0; v < object.positions.size(); ++v) {
            const Vec3& p = object.positions[v];
            const Rgb& b = object.radiosity[v];
            appendLittleEndian(out, static_cast<float>(p.x));
            appendLittleEndian(out, static_cast<float>(p.y));
            appendLittleEndian(out, static_cast<float>(p.z));
            out.push_back(static_cast<char>(srgbByte(b.x * invPi)));
            out.push_back(static_cast<char>(srgbByte(b.y * invPi)));
            out.push_back(static_cast<char>(srgbByte(b.z * invPi)));
            appendLittleEndian(out, static_cast<float>(b.x));
            appendLittleEndian(out, static_cast<float>(b.y));
            appendLittleEndian(out, static_cast<float>(b.z));
        }
    }
    for (const auto& [o, f] : faces) {
        const std::vector<int>& polygon = lit[o].polygons[f];
        if (polygon.size() > 255) {
            throw std::runtime_error("element with " + std::to_string(polygon.size()) +
                                     " vertices does not fit a PLY uchar list");
        }
        out.push_back(static_cast<char>(polygon.size()));
        for (int v : polygon) {
            appendLittleEndian(out, static_cast<std::int32_t>(firstVertex[o] + v));
        }
    }
    return out;
}

// ---------------------------------------------------------------------------------------
// glTF 2.0 (JSON with a data-URI buffer, or GLB)

constexpr int kFloat = 5126;
constexpr int kUnsignedInt = 5125;
constexpr int kArrayBuffer = 34962;
constexpr int kElementArrayBuffer = 34963;

/// The exposure that maps the 99th percentile of lit (non-emitting) surfaces' vertex radiance
/// luminance to 1: COLOR_0 = min(1, exposure × radiance), display-referred, linear.
double gltfExposure(const std::vector<LitObject>& lit, const std::vector<Material>& materials) {
    std::vector<double> values;
    const double invPi = glm::one_over_pi<double>();
    for (const LitObject& object : lit) {
        std::vector<std::uint8_t> emits(object.positions.size(), 0);
        for (size_t k = 0; k < object.polygons.size(); ++k)
            if (materials[object.polygonMaterial[k]].isEmitter())
                for (int v : object.polygons[k]) emits[v] = 1;
        for (size_t v = 0; v < object.radiosity.size(); ++v)
            if (!emits[v] && !object.polygons.empty()) {
                const double y = luminance(object.radiosity[v] * invPi);
                if (y > 0) values.push_back(y);
            }
    }
    if (values.empty()) return 1.0;
    const size_t k = std::min(values.size() - 1, values.size() * 99 / 100);
    std::nth_element(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(k), values.end());
    return values[k] > 0 ? 1.0 / values[k] : 1.0;
}

/// glTF's unit quaternion (x, y, z, w) of a camera node looking along `forward` with `up`
/// (a glTF camera looks along its −Z with +Y up).
std::array<double, 4> cameraRotation(const Vec3& forward, const Vec3& up) {
    const Vec3 z = -glm::normalize(forward);
    const Vec3 x = glm::normalize(glm::cross(up, z));
    const Vec3 y = glm::cross(z, x);
    // The rotation matrix with columns x, y, z to a quaternion (Shepperd's method).
    const double trace = x.x + y.y + z.z;
    std::array<double, 4> q{};
    if (trace > 0) {
        const double s = 2 * std::sqrt(1 + trace);
        q = {(y.z - z.y) / s, (z.x - x.z) / s, (x.y - y.x) / s, s / 4};
    } else if (x.x > y.y && x.x > z.z) {
        const double s = 2 * std::sqrt(1 + x.x - y.y - z.z);
        q = {s / 4, (y.x + x.y) / s, (z.x + x.z) / s, (y.z - z.y) / s};
    } else if (y.y > z.z) {
        const double s = 2 * std::sqrt(1 + y.y - x.x - z.z);
        q = {(y.x + x.y) / s, s / 4, (z.y + y.z) / s, (z.x - x.z) / s};
    } else {
        const double s = 2 * std::sqrt(1 + z.z - x.x - y.y);
        q = {(z.x + x.z) / s, (z.y + y.z) / s, s / 4, (x.y - y.x) / s};
    }
    const double n = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    for (double& c : q) c /= n;
    return q;
}

/// The glTF document under construction: the arrays that index one another, the binary buffer
/// their accessors read (owned by the caller), and the materials primitives share.
class GltfBuilder {
public:
    /// `exposure` scales radiance to COLOR_0 and lamp emission (gltfExposure).
    GltfBuilder(const std::vector<Material>& materials, double exposure, std::string& buffer)
        : mMaterials(materials), mExposure(exposure), mBuffer(buffer) {}

    /// Adds `object` as a mesh and a scene node carrying its Penumbra extras; an object with
    /// nothing to draw adds neither.
    void addObject(const LitObject& object) {
        using nlohmann::json;
        if (object.positions.empty()) return;
        const double invPi = glm::one_over_pi<double>();
        std::vector<Vec3> radiance(object.radiosity.size()), shown(object.radiosity.size());
        for (size_t v = 0; v < radiance.size(); ++v) {
            radiance[v] = object.radiosity[v] * invPi;
            shown[v] = glm::clamp(radiance[v] * mExposure, Rgb(0.0), Rgb(1.0));
        }
        json primitives = addPrimitives(object, shown, radiance);
        if (primitives.empty()) return;  // nothing to draw
        mMeshes.push_back({{"name", object.id}, {"primitives", primitives}});
        json extras = {{"penumbra_id", object.id}};
        if (!object.materialName.empty()) extras["material"] = object.materialName;
        const Material& m = mMaterials[object.polygonMaterial.front()];
        extras["reflectance"] = rgbJson(m.reflectance);
        if (m.isEmitter()) extras["emission"] = rgbJson(m.emission);
        if (!object.source.is_null()) extras["object"] = object.source;
        mNodes.push_back({{"name", object.id}, {"mesh", mMeshes.size() - 1}, {"extras", extras}});
        mSceneNodes.push_back(mNodes.size() - 1);
    }

    /// Adds the scene's cameras (none without a scene) as perspective camera nodes, an
    /// importer's viewpoints; a camera without a direction is skipped.
    void addCameras(const Scene* scene) {
        for (const Camera& camera : scene ? scene->cameras : std::vector<Camera>{}) {
            const Vec3 forward = camera.lookAt - camera.position;
            if (!(glm::length(forward) > 0) || !(glm::length(glm::cross(forward, camera.up)) > 0))
                continue;  // no direction: not a viewpoint
            mGltfCameras.push_back(
                {{"name", camera.name},
                 {"type", "perspective"},
                 {"perspective", {{"yfov", camera.fovDeg * M_PI / 180.0}, {"znear", 0.01}}}});
            const std::array<double, 4> q = cameraRotation(forward, camera.up);
            mNodes.push_back(
                {{"name", camera.name},
                 {"camera", mGltfCameras.size() - 1},
                 {"translation", {camera.position.x, camera.position.y, camera.position.z}},
                 {"rotation", {q[0], q[1], q[2], q[3]}}});
            mSceneNodes.push_back(mNodes.size() - 1);
        }
    }

    /// The document: asset (with the exposure, and the scene's settings when there is one),
    /// the one scene, and each array that is not empty (glTF forbids empty ones).
    nlohmann::json finish(const Scene* scene) const {
        using nlohmann::json;
        json extensionsUsed = json::array();
        if (!mReflectorMaterial.empty()) extensionsUsed.push_back("KHR_materials_unlit");
        if (mEmissiveStrength) extensionsUsed.push_back("KHR_materials_emissive_strength");
        json doc = {
            {"asset",
             {{"version", "2.0"},
              {"generator", "Penumbra"},
              {"extras",
               {{"description",
                 "Penumbra lit scene: world space metres, one mesh per object. COLOR_0 = "
                 "min(1, exposure x radiance): linear, display-referred (glTF viewers encode it "
                 "as sRGB); _RADIANCE = radiance B/pi in W/m^2/sr, exact; lamps are emissive "
                 "materials on the same exposure (emission = pi x emissive x strength / "
                 "exposure)"},
                {"exposure", mExposure}}}}},
            {"scene", 0},
            {"scenes", json::array({{{"nodes", mSceneNodes}}})},
        };
        if (!extensionsUsed.empty()) doc["extensionsUsed"] = extensionsUsed;
        if (!mNodes.empty()) doc["nodes"] = mNodes;
        if (!mMeshes.empty()) doc["meshes"] = mMeshes;
        if (!mGltfMaterials.empty()) doc["materials"] = mGltfMaterials;
        if (!mGltfCameras.empty()) doc["cameras"] = mGltfCameras;
        if (scene)
            doc["asset"]["extras"]["settings"] = {{"patch_size", scene->settings.patchSize},
                                                  {"element_size", scene->settings.elementSize}};
        if (!mBuffer.empty()) {
            // glTF forbids zero-length buffers: a scene without faces has no binary data.
            doc["buffers"] = json::array({{{"byteLength", mBuffer.size()}}});
            doc["bufferViews"] = mBufferViews;
            doc["accessors"] = mAccessors;
        }
        return doc;
    }

private:
    /// A colour as a JSON array [r, g, b].
    static nlohmann::json rgbJson(const Rgb& c) { return nlohmann::json::array({c.x, c.y, c.z}); }

    /// One triangle primitive per material of `object` (meshes may carry several); the
    /// vertex attributes are written once, with the first primitive that has triangles.
    nlohmann::json addPrimitives(const LitObject& object, const std::vector<Vec3>& shown,
                                 const std::vector<Vec3>& radiance) {
        using nlohmann::json;
        std::map<int, std::vector<std::uint32_t>> byMaterial;
        for (size_t k = 0; k < object.polygons.size(); ++k)
            appendFanTriangles(object.polygons[k], object.positions,
                               byMaterial[object.polygonMaterial[k]]);
        json primitives = json::array();
        size_t position = 0, normal = 0, color = 0, exact = 0;
        bool attributes = false;
        for (const auto& [material, indices] : byMaterial) {
            if (indices.empty()) continue;
            if (!attributes) {
                position = addVec3(object.positions, true);
                normal = addVec3(object.normals, false);
                color = addVec3(shown, false);
                exact = addVec3(radiance, false);
                attributes = true;
            }
            const bool emitter = mMaterials[material].isEmitter();
            primitives.push_back(
                {{"attributes",
                  {{"POSITION", position},
                   {"NORMAL", normal},
                   {"COLOR_0", color},
                   {"_RADIANCE", exact}}},
                 {"indices", addIndices(indices)},
                 {"material", emitter ? lamp(material, object.twoSided, object.materialName)
                                      : reflector(object.twoSided, object.materialName)},
                 {"mode", 4}});
        }
        return primitives;
    }

    /// Appends a buffer view over the buffer's bytes from `offset` to its end; returns it.
    size_t addView(size_t offset, int target) {
        mBufferViews.push_back({{"buffer", 0},
                                {"byteOffset", offset},
                                {"byteLength", mBuffer.size() - offset},
                                {"target", target}});
        return mBufferViews.size() - 1;
    }

    /// Appends `values` as float VEC3 (with min and max when `withBounds`, as POSITION needs)
    /// in a buffer view and an accessor; returns the accessor.
    size_t addVec3(const std::vector<Vec3>& values, bool withBounds) {
        const size_t offset = mBuffer.size();
        Vec3 lo(std::numeric_limits<double>::max()), hi(std::numeric_limits<double>::lowest());
        for (const Vec3& v : values) {
            const glm::vec3 f(v);
            for (int c = 0; c < 3; ++c) appendLittleEndian(mBuffer, f[c]);
            lo = glm::min(lo, Vec3(f));
            hi = glm::max(hi, Vec3(f));
        }
        nlohmann::json accessor = {{"bufferView", addView(offset, kArrayBuffer)},
                                   {"componentType", kFloat},
                                   {"count", values.size()},
                                   {"type", "VEC3"}};
        if (withBounds) {
            accessor["min"] = {static_cast<float>(lo.x), static_cast<float>(lo.y),
                               static_cast<float>(lo.z)};
            accessor["max"] = {static_cast<float>(hi.x), static_cast<float>(hi.y),
                               static_cast<float>(hi.z)};
        }
        mAccessors.push_back(accessor);
        return mAccessors.size() - 1;
    }

    /// Appends uint32 SCALAR triangle indices in a buffer view and an accessor; returns the
    /// accessor.
    size_t addIndices(const std::vector<std::uint32_t>& indices) {
        const size_t offset = mBuffer.size();
        for (std::uint32_t i : indices) appendLittleEndian(mBuffer, i);
        mAccessors.push_back({{"bufferView", addView(offset, kElementArrayBuffer)},
                              {"componentType", kUnsignedInt},
                              {"count", indices.size()},
                              {"type", "SCALAR"}});
        return mAccessors.size() - 1;
    }

    /// The material of surfaces that only reflect, made on first use: unlit white, the
    /// displayed colour is COLOR_0.
    size_t reflector(bool doubleSided, const std::string& name) {
        using nlohmann::json;
        const auto key = std::make_pair(doubleSided, name);
        if (auto it = mReflectorMaterial.find(key); it != mReflectorMaterial.end())
            return it->second;
        mGltfMaterials.push_back({{"name", name.empty() ? std::string("penumbra_radiance") : name},
                                  {"pbrMetallicRoughness",
                                   {{"baseColorFactor", {1.0, 1.0, 1.0, 1.0}},
                                    {"metallicFactor", 0.0},
                                    {"roughnessFactor", 1.0}}},
                                  {"doubleSided", doubleSided},
                                  {"extensions", {{"KHR_materials_unlit", json::object()}}}});
        return mReflectorMaterial[key] = mGltfMaterials.size() - 1;
    }

    /// The material of a lamp, made on first use: its emission as glTF's emissive colour on
    /// the same exposure (emissiveFactor scaled to a largest channel of 1,
    /// KHR_materials_emissive_strength for the rest), over a black base.
    size_t lamp(int material, bool doubleSided, const std::string& name) {
        using nlohmann::json;
        const auto key = std::make_tuple(material, doubleSided, name);
        if (auto it = mLampMaterial.find(key); it != mLampMaterial.end()) return it->second;
        const double invPi = glm::one_over_pi<double>();
        const Material& m = mMaterials[material];
        const Rgb shown = m.emission * invPi * mExposure;
        const double strength = std::max({shown.x, shown.y, shown.z});
        json g = {
            {"name", name.empty() ? std::string("penumbra_lamp") : name},
            {"pbrMetallicRoughness",
             {{"baseColorFactor", {0.0, 0.0, 0.0, 1.0}},
              {"metallicFactor", 0.0},
              {"roughnessFactor", 1.0}}},
            {"emissiveFactor", rgbJson(strength > 0 ? shown / std::max(strength, 1.0) : Rgb(0.0))},
            {"doubleSided", doubleSided},
            {"extras", {{"emission", rgbJson(m.emission)}}}};
        if (strength > 1) {
            g["extensions"] = {
                {"KHR_materials_emissive_strength", {{"emissiveStrength", strength}}}};
            mEmissiveStrength = true;
        }
        mGltfMaterials.push_back(g);
        return mLampMaterial[key] = mGltfMaterials.size() - 1;
    }

    const std::vector<Material>& mMaterials;
    double mExposure;
    std::string& mBuffer;
    nlohmann::json mBufferViews = nlohmann::json::array();
    nlohmann::json mAccessors = nlohmann::json::array();
    nlohmann::json mMeshes = nlohmann::json::array();
    nlohmann::json mNodes = nlohmann::json::array();
    nlohmann::json mSceneNodes = nlohmann::json::array();
    nlohmann::json mGltfMaterials = nlohmann::json::array();
    nlohmann::json mGltfCameras = nlohmann::json::array();
    bool mEmissiveStrength = false;  ///< some lamp needs KHR_materials_emissive_strength
    /// Materials made so far, by what distinguishes them: index into mGltfMaterials.
    std::map<std::pair<bool, std::string>, size_t> mReflectorMaterial;
    std::map<std::tuple<int, bool, std::string>, size_t> mLampMaterial;
};

/// Builds the glTF document and its binary buffer; the buffer's `uri` is left to the caller.
/// With `scene`: its cameras become perspective camera nodes (an importer's viewpoints) and
/// its settings go into asset.extras (a re-import discretizes as the scene did).
nlohmann::json buildGltf(const std::vector<LitObject>& lit, const std::vector<Material>& materials,
                         const Scene* scene, std::string& buffer) {
    GltfBuilder builder(materials, gltfExposure(lit, materials), buffer);
    for (const LitObject& object : lit) builder.addObject(object);
    builder.addCameras(scene);
    return builder.finish(scene);
}

std::string encodeGltf(const std::vector<LitObject>& lit, const std::vector<Material>& materials,
                       const Scene* scene) {
    std::string buffer;
    nlohmann::json doc = buildGltf(lit, materials, scene, buffer);
    if (!buffer.empty())
        doc["buffers"][0]["uri"] = "data:application/octet-stream;base64," + base64Encode(buffer);
    return doc.dump(1) + "\n";
}

std::string encodeGlb(const std::vector<LitObject>& lit, const std::vector<Material>& materials,
                      const Scene* scene) {
    std::string buffer;
    const nlohmann::json doc = buildGltf(lit, materials, scene, buffer);

    // Chunks are 4-byte aligned: JSON padded with spaces, BIN with zeros.
    std::string jsonChunk = doc.dump();
    while (jsonChunk.size() % 4 != 0) jsonChunk.push_back(' ');
    while (buffer.size() % 4 != 0) buffer.push_back('\0');

    std::string out;
    const size_t total = 12 + 8 + jsonChunk.size() + (buffer.empty() ? 0 : 8 + buffer.size());
    if (total > std::numeric_limits<std::uint32_t>::max()) {
        throw std::runtime_error("lit scene too large for GLB (" + std::to_string(total) +
                                 " bytes)");
    }
    appendLittleEndian(out, std::uint32_t{0x46546C67});  // "glTF"
    appendLittleEndian(out, std::uint32_t{2});
    appendLittleEndian(out, static_cast<std::uint32_t>(total));
    appendLittleEndian(out, static_cast<std::uint32_t>(jsonChunk.size()));
    appendLittleEndian(out, std::uint32_t{0x4E4F534A});  // "JSON"
    out += jsonChunk;
    if (!buffer.empty()) {
        appendLittleEndian(out, static_cast<std::uint32_t>(buffer.size()));
        appendLittleEndian(out, std::uint32_t{0x004E4942});  // "BIN\0"
        out += buffer;
    }
    return out;
}

// ---------------------------------------------------------------------------------------
// OBJ with vertex colours, and its .mtl

/// One name per material the objects use: the scene material's name when an object using it
/// knows it, else "material_<index>"; unique, one token.
std::vector<std::string> objMaterialNames(const Discretization& disc,
                                          const std::vector<LitObject>& lit) {
    std::vector<std::string> names(disc.materials().size());
    for (const LitObject& object : lit)
        for (int m : object.polygonMaterial)
            if (m >= 0 && m < static_cast<int>(names.size()) && names[m].empty() &&
                !object.materialName.empty())
                names[m] = lineToken(object.materialName);
    std::set<std::string> taken;
    for (std::size_t m = 0; m < names.size(); ++m) {
        if (names[m].empty() || taken.count(names[m]))
            names[m] = (names[m].empty() ? "material" : names[m]) + "_" + std::to_string(m);
        taken.insert(names[m]);
    }
    return names;
}

std::string encodeObj(const std::vector<LitObject>& lit, const std::vector<std::string>& names,
                      const std::string& mtlFile, const std::string& facesNote) {
    std::string out =
        "# Penumbra lit scene\n"
        "# v x y z r g b: world space metres; r g b = radiance B/pi, sRGB-encoded, clipped to "
        "[0,1]\n"
        "# one object group per scene object, one face per " +
        facesNote + " (counter-clockwise from the front)\n";
    std::size_t faces = 0;
    for (const LitObject& object : lit) faces += object.polygons.size();
    out += "# objects " + std::to_string(lit.size()) + ", " + facesNote + "s " +
           std::to_string(faces) + "\n";
    out += "mtllib " + mtlFile + "\n";

    const double invPi = glm::one_over_pi<double>();
    size_t firstVertex = 1;  // OBJ indices are 1-based and global
    for (const LitObject& object : lit) {
        out.append("o ").append(lineToken(object.id)).push_back('\n');
        for (size_t v = 0; v < object.positions.size(); ++v) {
            const Vec3& p = object.positions[v];
            const Rgb& b = object.radiosity[v];
            out.push_back('v');
            for (int c = 0; c < 3; ++c) appendNumber(out, p[c]);
            // Six decimals keep the colour exact to well below one 8-bit step.
            for (int c = 0; c < 3; ++c) appendFixed(out, srgbEncodeClipped(b[c] * invPi), 6);
            out.push_back('\n');
        }
        int current = -1;
        for (size_t f = 0; f < object.polygons.size(); ++f) {
            const int m = f < object.polygonMaterial.size() ? object.polygonMaterial[f] : -1;
            if (m != current && m >= 0 && m < static_cast<int>(names.size())) {
                out.append("usemtl ").append(names[m]).push_back('\n');
                current = m;
            }
            out.push_back('f');
            for (int v : object.polygons[f]) appendNumber(out, firstVertex + v);
            out.push_back('\n');
        }
        firstVertex += object.positions.size();
    }
    return out;
}

/// The materials the objects use: Kd the reflectance (linear), Ke the emitted radiance E/pi
/// (linear, W/m^2/sr; lamps only), Ka 0, illum 1 (no specular).
std::string encodeMtl(const Discretization& disc, const std::vector<LitObject>& lit,
                      const std::vector<std::string>& names) {
    std::string out =
        "# Penumbra lit scene materials\n"
        "# Kd: reflectance (linear); Ke: emitted radiance E/pi in W/m^2/sr (linear, not "
        "clipped), lamps only\n";
    std::vector<std::uint8_t> used(names.size(), 0);
    for (const LitObject& object : lit)
        for (int m : object.polygonMaterial)
            if (m >= 0 && m < static_cast<int>(used.size())) used[m] = 1;
    const double invPi = glm::one_over_pi<double>();
    for (std::size_t m = 0; m < names.size(); ++m) {
        if (!used[m]) continue;
        const Material& material = disc.materials()[m];
        out.append("newmtl ").append(names[m]).push_back('\n');
        out += "Ka 0 0 0\n";
        out += "Kd";
        for (int c = 0; c < 3; ++c) appendNumber(out, material.reflectance[c]);
        out.push_back('\n');
        if (material.isEmitter()) {
            out += "Ke";
            for (int c = 0; c < 3; ++c) appendNumber(out, material.emission[c] * invPi);
            out.push_back('\n');
        }
        out += "illum 1\n";
    }
    return out;
}

}  // namespace

// ---------------------------------------------------------------------------------------
// Dispatch

void checkExportPath(const std::string& path) {
    const std::string ext = lowerExtension(path);
    if (ext != ".ply" && ext != ".gltf" && ext != ".glb" && ext != ".obj") {
        throw std::invalid_argument("cannot export " + path + ": unknown extension '" + ext +
                                    "' (expected .ply, .gltf, .glb or .obj)");
    }
}

namespace {

/// Writes `lit` in the format of `path`'s extension; `faces` and `faceNote` as encodePly's,
/// `faceName` what an OBJ face is.
void writeLit(const Discretization& disc, const std::vector<LitObject>& lit,
              const std::vector<std::pair<int, int>>& faces, const std::string& faceNote,
              const std::string& faceName, const std::string& path, const Scene* scene) {
    const std::string ext = lowerExtension(path);
    std::string contents;
    if (ext == ".ply") {
        contents = encodePly(lit, faces, faceNote);
    } else if (ext == ".gltf") {
        contents = encodeGltf(lit, disc.materials(), scene);
    } else if (ext == ".glb") {
        contents = encodeGlb(lit, disc.materials(), scene);
    } else {
        // The .mtl beside it (same stem), written first: the .obj names it.
        const std::filesystem::path mtl = std::filesystem::path(path).replace_extension(".mtl");
        const std::vector<std::string> names = objMaterialNames(disc, lit);
        writeFileAtomically(mtl.string(), encodeMtl(disc, lit, names));
        contents = encodeObj(lit, names, mtl.filename().string(), faceName);
    }
    writeFileAtomically(path, contents);
}

}  // namespace

void exportLitScene(const Discretization& disc, const std::vector<Rgb>& elementRadiosity,
                    const std::string& path, const Scene* scene) {
    checkExportPath(path);
    if (elementRadiosity.size() != disc.elements().size()) {
        throw std::invalid_argument(
            "cannot export " + path + ": " + std::to_string(elementRadiosity.size()) +
            " radiosity values for " + std::to_string(disc.elements().size()) + " elements");
    }
    const std::vector<LitObject> lit = collectLitObjects(disc, elementRadiosity, scene);
    // Face i is element i: the k-th element of an object is its k-th polygon.
    std::vector<std::pair<int, int>> faces;
    std::vector<int> seen(lit.size(), 0);
    for (const Element& element : disc.elements())
        faces.emplace_back(element.object, seen[element.object]++);
    writeLit(disc, lit, faces, "face i = element i", "element", path, scene);
}

void exportLitTriangles(const Discretization& disc, const std::vector<LitTriangle>& triangles,
                        const std::string& path, const Scene* scene) {
    checkExportPath(path);
    const int elementCount = static_cast<int>(disc.elements().size());
    // The objects as the element export names them, with their geometry replaced.
    std::vector<LitObject> lit =
        collectLitObjects(disc, std::vector<Rgb>(disc.elements().size(), Rgb(0.0)), scene);
    for (LitObject& object : lit) {
        object.positions.clear();
        object.normals.clear();
        object.radiosity.clear();
        object.polygons.clear();
        object.polygonMaterial.clear();
    }
    // Welding: one vertex per object, position, normal and radiosity, on grids far finer
    // than any element or visible difference (neighbours' corners come from different
    // element frames and interpolants: equal up to rounding, not bit for bit).
    Vec3 lo(std::numeric_limits<double>::max()), hi(std::numeric_limits<double>::lowest());
    for (const LitTriangle& tri : triangles)
        for (const Vec3& p : tri.p) {
            lo = glm::min(lo, p);
            hi = glm::max(hi, p);
        }
    const double grid = 1e-9 * std::max(1.0, glm::length(hi - lo));
    using Key = std::array<long long, 9>;
    std::vector<std::map<Key, int>> welded(lit.size());
    std::vector<std::pair<int, int>> faces;
    for (std::size_t t = 0; t < triangles.size(); ++t) {
        const LitTriangle& tri = triangles[t];
        if (tri.element < 0 || tri.element >= elementCount) {
            throw std::invalid_argument(
                "cannot export " + path + ": triangle " + std::to_string(t) + " names element " +
                std::to_string(tri.element) + " of " + std::to_string(elementCount));
        }
        const Element& element = disc.elements()[tri.element];
        LitObject& object = lit[element.object];
        std::vector<int> polygon;
        for (int k = 0; k < 3; ++k) {
            Key key;
            for (int c = 0; c < 3; ++c) {
                key[c] = std::llround(tri.p[k][c] / grid);
                key[3 + c] = std::llround(element.normal[c] * 1e6);
                // Radiosity to float precision: what the files store.
                const float b = static_cast<float>(tri.radiosity[k][c]);
                std::int32_t bits;
                std::memcpy(&bits, &b, sizeof bits);
                key[6 + c] = bits;
            }
            auto [it, added] =
                welded[element.object].emplace(key, static_cast<int>(object.positions.size()));
            if (added) {
                object.positions.push_back(tri.p[k]);
                object.normals.push_back(element.normal);
                object.radiosity.push_back(tri.radiosity[k]);
            }
            polygon.push_back(it->second);
        }
        object.polygons.push_back(std::move(polygon));
        object.polygonMaterial.push_back(disc.patches()[element.patch].material);
    }
    for (std::size_t o = 0; o < lit.size(); ++o)
        for (std::size_t f = 0; f < lit[o].polygons.size(); ++f)
            faces.emplace_back(static_cast<int>(o), static_cast<int>(f));
    writeLit(disc, lit, faces, "face i = triangle i of the objects in order", "triangle", path,
             scene);
}

}  // namespace penumbra
