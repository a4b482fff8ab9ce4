// Index: LibraryEntry · listing meshes · scene-relative paths · shapes and bounds ·
//        placement · ids and materials

#include "ui/mesh_library.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <map>
#include <set>
#include <sstream>
#include <stdexcept>
#include <system_error>

#include "ui/file_dialog.h"

namespace penumbra {

namespace fs = std::filesystem;

namespace {

std::string vecText(const Vec3& v) {
    std::ostringstream out;
    out << "[" << v.x << ", " << v.y << ", " << v.z << "]";
    return out.str();
}

/// Canonical form of an existing path, or "" when it does not exist or cannot be resolved.
std::string canonicalOrEmpty(const fs::path& p) {
    std::error_code ec;
    const fs::path c = fs::canonical(p, ec);
    return ec ? std::string() : c.string();
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// LibraryEntry.

std::string LibraryEntry::toString() const {
    return "LibraryEntry{" + label + ", " + shapeTypeName(type) +
           (path.empty() ? std::string() : ", " + path) + "}";
}

// ---------------------------------------------------------------------------------------------
// Listing meshes.

bool isMeshFile(const std::string& path) {
    static const std::vector<std::string> kExtensions = {".obj", ".off",  ".ply",
                                                         ".stl", ".gltf", ".glb"};
    return matchesExtension(path, kExtensions);
}

std::vector<std::string> meshLibraryRoots(const std::string& scenePath,
                                          const std::string& sourceDir) {
    std::vector<fs::path> candidates;
    if (!scenePath.empty()) candidates.push_back(fs::path(scenePath).parent_path() / "meshes");
    if (!sourceDir.empty()) candidates.push_back(fs::path(sourceDir) / "scenes" / "meshes");
    // Roots keep the caller's spelling (made absolute), so scene-relative paths computed from
    // them match the scene's; duplicates are found by canonical path.
    std::vector<std::string> roots, canonicalRoots;
    for (const fs::path& c : candidates) {
        std::error_code ec;
        if (!fs::is_directory(c, ec)) continue;
        const std::string canonical = canonicalOrEmpty(c);
        if (canonical.empty()) continue;
        if (std::find(canonicalRoots.begin(), canonicalRoots.end(), canonical) !=
            canonicalRoots.end())
            continue;
        canonicalRoots.push_back(canonical);
        roots.push_back(fs::absolute(c, ec).lexically_normal().string());
    }
    return roots;
}

std::string findSourceDir(const std::string& start) {
    std::error_code ec;
    fs::path p = fs::absolute(start, ec).lexically_normal();
    if (ec) return "";
    while (true) {
        if (fs::is_directory(p / "scenes" / "meshes", ec)) return p.string();
        if (p == p.root_path() || !p.has_parent_path()) return "";
        p = p.parent_path();
    }
}

constexpr int kMaxDepth = 8;  ///< folder levels below a root that listMeshes enters

std::vector<LibraryEntry> listMeshes(const std::vector<std::string>& roots,
                                     std::size_t maxEntries) {
    std::vector<LibraryEntry> entries;
    std::set<std::string> seenFiles, seenFolders;  // canonical paths
    for (const std::string& root : roots) {
        const fs::path rootPath = fs::absolute(root).lexically_normal();
        if (const std::string c = canonicalOrEmpty(rootPath); !c.empty()) seenFolders.insert(c);
        // Per file (canonical): the entry with the shortest label under this root.
        std::map<std::string, LibraryEntry> found;
        std::error_code ec;
        fs::recursive_directory_iterator it(rootPath,
                                            fs::directory_options::skip_permission_denied |
                                                fs::directory_options::follow_directory_symlink,
                                            ec);
        for (; !ec && it != fs::recursive_directory_iterator(); it.increment(ec)) {
            const fs::path& p = it->path();
            const std::string name = p.filename().string();
            std::error_code typeError;
            const bool folder = it->is_directory(typeError);
            // Hidden files and folders; folders seen before (symlink cycles, links to a
            // folder already listed) and folders too deep.
            if (!name.empty() && name[0] == '.') {
                if (folder) it.disable_recursion_pending();
                continue;
            }
            if (folder) {
                const std::string c = canonicalOrEmpty(p);
                if (c.empty() || !seenFolders.insert(c).second || it.depth() + 1 >= kMaxDepth)
                    it.disable_recursion_pending();
                continue;
            }
            if (!it->is_regular_file(typeError) || !isMeshFile(name)) continue;
            const std::string canonical = canonicalOrEmpty(p);
            if (canonical.empty() || seenFiles.count(canonical)) continue;
            LibraryEntry e;
            e.label = p.lexically_relative(rootPath).generic_string();
            e.type = ShapeType::Mesh;
            e.path = p.lexically_normal().string();
            auto [at, inserted] = found.emplace(canonical, e);
            if (!inserted && e.label.size() < at->second.label.size()) at->second = std::move(e);
        }
        std::vector<LibraryEntry> sorted;
        for (auto& [canonical, e] : found) {
            seenFiles.insert(canonical);
            sorted.push_back(std::move(e));
        }
        std::sort(sorted.begin(), sorted.end(),
                  [](const LibraryEntry& a, const LibraryEntry& b) { return a.label < b.label; });
        for (LibraryEntry& e : sorted) {
            if (entries.size() >= maxEntries) return entries;
            entries.push_back(std::move(e));
        }
    }
    return entries;
}

std::vector<LibraryEntry> listPrimitives() {
    std::vector<LibraryEntry> entries;
    for (ShapeType t : {ShapeType::Box, ShapeType::Sphere, ShapeType::Cylinder, ShapeType::Quad})
        entries.push_back(LibraryEntry{shapeTypeName(t), t, ""});
    return entries;
}

// ---------------------------------------------------------------------------------------------
// Scene-relative paths.

std::string sceneRelativePath(const std::string& file, const std::string& scenePath) {
    // Lexical: a path through a symlinked folder stays as the scene would spell it.
    const fs::path absoluteFile = fs::absolute(file).lexically_normal();
    const fs::path sceneDir = fs::absolute(scenePath).parent_path().lexically_normal();
    const fs::path relative = absoluteFile.lexically_relative(sceneDir);
    if (relative.empty()) return absoluteFile.generic_string();
    return relative.generic_string();
}

// ---------------------------------------------------------------------------------------------
// Shapes and bounds.

Shape makePrimitive(ShapeType type, double size) {
    if (type == ShapeType::Mesh)
        throw std::invalid_argument("makePrimitive: a mesh is not a primitive");
    Shape s;
    s.type = type;
    s.size = Vec3(size);
    s.radius = 0.5 * size;
    s.height = size;
    return s;
}

Bounds shapeBounds(const Shape& shape) {
    switch (shape.type) {
        case ShapeType::Quad:
            return {Vec3(-0.5 * shape.size.x, 0.0, -0.5 * shape.size.z),
                    Vec3(0.5 * shape.size.x, 0.0, 0.5 * shape.size.z)};
        case ShapeType::Box:
            return {-0.5 * shape.size, 0.5 * shape.size};
        case ShapeType::Sphere:
            return {Vec3(-shape.radius), Vec3(shape.radius)};
        case ShapeType::Cylinder:
            return {Vec3(-shape.radius, -0.5 * shape.height, -shape.radius),
                    Vec3(shape.radius, 0.5 * shape.height, shape.radius)};
        case ShapeType::Mesh:
            break;
    }
    if (shape.mesh.positions.empty())
        throw std::invalid_argument("shapeBounds: mesh '" + shape.file + "' has no vertices");
    Bounds b{shape.mesh.positions.front(), shape.mesh.positions.front()};
    for (const Vec3& p : shape.mesh.positions) b.lo = glm::min(b.lo, p), b.hi = glm::max(b.hi, p);
    return b;
}

// ---------------------------------------------------------------------------------------------
// Placement.

std::string PlacementTarget::toString() const {
    return "PlacementTarget{" + vecText(point) +
           (onSurface ? ", surface normal " + vecText(normal) : std::string(", free space")) + "}";
}

PlacementTarget placementTarget(const Vec3& origin, const Vec3& direction,
                                const std::optional<Vec3>& hit, const std::optional<Vec3>& hitRight,
                                const std::optional<Vec3>& hitDown, double freeDistance,
                                double maxDistance) {
    const Vec3 d = glm::normalize(direction);
    PlacementTarget t;
    if (!hit || glm::length(*hit - origin) > maxDistance) {
        t.point = origin + freeDistance * d;
        t.normal = -d;
        return t;
    }
    t.point = *hit;
    t.onSurface = true;
    t.normal = -d;
    if (hitRight && hitDown) {
        // The plane through the three hits (a pixel's neighbours see the same surface).
        const Vec3 n = glm::cross(*hitRight - *hit, *hitDown - *hit);
        const double span = glm::length(*hitRight - *hit) * glm::length(*hitDown - *hit);
        if (span > 0 && glm::length(n) > 1e-3 * span) t.normal = glm::normalize(n);
    }
    if (glm::dot(t.normal, d) > 0) t.normal = -t.normal;
    return t;
}

Transform placeInBox(const Bounds& bounds, double size, const PlacementTarget& target) {
    const Vec3 extent = bounds.extent();
    const double largest = std::max({extent.x, extent.y, extent.z});
    const double s = largest > 0 ? size / largest : 1.0;
    const Vec3 half = 0.5 * s * extent;
    Vec3 centre = target.point;
    if (target.onSurface) {
        // The scaled box's support distance along the normal: it touches the plane there.
        const Vec3 n = target.normal;
        const double support =
            std::abs(n.x) * half.x + std::abs(n.y) * half.y + std::abs(n.z) * half.z;
        centre = target.point + (support + 1e-3) * n;
    }
    Transform t;
    t.scale = Vec3(s);
    t.translate = centre - s * bounds.centre();
    return t;
}

// ---------------------------------------------------------------------------------------------
// Ids and materials.

std::string uniqueObjectId(const std::string& base,
                           const std::function<bool(const std::string&)>& taken) {
    std::string stem = fs::path(base).stem().string();
    if (stem.empty()) stem = "object";
    for (char& c : stem)
        if (!std::isalnum(static_cast<unsigned char>(c)) && c != '-' && c != '_') c = '_';
    for (int k = 1;; ++k) {
        const std::string id = stem + "-" + std::to_string(k);
        if (!taken(id)) return id;
    }
}

std::string defaultMaterial(const std::vector<NamedMaterial>& materials) {
    for (const NamedMaterial& m : materials)
        if (m.material.emission == Rgb(0.0)) return m.name;
    return materials.empty() ? std::string() : materials.front().name;
}

}  // namespace penumbra
