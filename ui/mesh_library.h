#pragma once
// The Add menu's library (issue 5 point 5): the primitive shapes and the mesh files found in
// the scene's `meshes/` folder and the repository's `scenes/meshes/`, and where a new object
// goes: on the surface under the view centre (else in front of the camera), uniformly scaled
// so its bounding box fits a given size. No GL, no session: unit-tested in
// tests/ui/mesh_library_test.cpp against the real mesh files.
//
// Index: LibraryEntry · listing meshes · scene-relative paths · shapes and bounds ·
//        placement · ids and materials

#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "solver/scene.h"

namespace penumbra {

// ---------------------------------------------------------------------------------------------
// LibraryEntry.

/// One item of the Add menu.
struct LibraryEntry {
    std::string label;  ///< menu text: "box", or the file's path below its root ("cgal/cow.off")
    ShapeType type = ShapeType::Box;
    std::string path;  ///< meshes: the file's absolute path below its root; "" for primitives
    std::string toString() const;
};

// ---------------------------------------------------------------------------------------------
// Listing meshes.

/// Whether loadMeshFile reads the file by its extension (.obj .off .ply .stl .gltf .glb,
/// case-insensitive).
bool isMeshFile(const std::string& path);

/// The folders searched for meshes: `<folder of scenePath>/meshes` (when scenePath is not "")
/// and `<sourceDir>/scenes/meshes` (when sourceDir is not ""), in that order, absolute but
/// with symlinks kept, without duplicates (compared canonically) and only those that exist.
std::vector<std::string> meshLibraryRoots(const std::string& scenePath,
                                          const std::string& sourceDir);

/// The nearest folder at or above `start` (a file or folder) that holds `scenes/meshes/`: the
/// repository's checkout when the editor runs inside it; "" when there is none.
std::string findSourceDir(const std::string& start);

/// The mesh files below each root, recursively (symlinked folders are followed, each folder
/// entered once, at most 8 levels deep), one entry per file (compared canonically: the first
/// root that reaches a file names it, with the shortest label there), sorted by label within
/// each root.
/// Labels use '/' separators; hidden files and folders ("." prefix) are skipped; unreadable
/// folders are skipped silently. At most `maxEntries` entries.
std::vector<LibraryEntry> listMeshes(const std::vector<std::string>& roots,
                                     std::size_t maxEntries = 500);

/// The primitives of the Add menu: box, sphere, cylinder, quad.
std::vector<LibraryEntry> listPrimitives();

// ---------------------------------------------------------------------------------------------
// Scene-relative paths.

/// `file` as a scene at `scenePath` names it (DESIGN.md: mesh paths are relative to the scene
/// file): relative to the scene's folder with '/' separators ("meshes/cgal/cow.off",
/// "../meshes/x.obj"); absolute when the two share no root.
std::string sceneRelativePath(const std::string& file, const std::string& scenePath);

// ---------------------------------------------------------------------------------------------
// Shapes and bounds.

/// A primitive of `type` with the library's default size (`size` metres across: box and
/// quad sides, sphere and cylinder diameter, cylinder height). Not for ShapeType::Mesh
/// (std::invalid_argument).
Shape makePrimitive(ShapeType type, double size = 0.4);

/// Object-space bounds of a shape (solver/scene.h conventions: box, sphere, cylinder centred;
/// quad in the XZ plane, centred). Meshes: the bounds of `mesh.positions` (std::invalid_argument
/// when empty).
struct Bounds {
    Vec3 lo{0.0}, hi{0.0};
    Vec3 centre() const { return 0.5 * (lo + hi); }
    Vec3 extent() const { return hi - lo; }
};
Bounds shapeBounds(const Shape& shape);

// ---------------------------------------------------------------------------------------------
// Placement.

/// Where the view centre points: a surface point with its normal, or a point in front of the
/// camera in free space.
struct PlacementTarget {
    Vec3 point{0.0};
    Vec3 normal{0, 1, 0};  ///< unit, facing the camera; meaningless when !onSurface
    bool onSurface = false;
    std::string toString() const;
};

/// The target for the view-centre ray (`origin`, unit `direction`): `hit` (the picked point)
/// when given and nearer than `maxDistance`, with the normal estimated from two neighbouring
/// hits (`hitRight`, `hitDown`, points seen a few pixels right of and below the centre; -direction
/// when either is missing or they are degenerate), turned to face the camera. Otherwise the
/// point `freeDistance` along the ray.
PlacementTarget placementTarget(const Vec3& origin, const Vec3& direction,
                                const std::optional<Vec3>& hit, const std::optional<Vec3>& hitRight,
                                const std::optional<Vec3>& hitDown, double freeDistance,
                                double maxDistance = 1e3);

/// The transform (no rotation) that scales `bounds` uniformly so its largest extent is `size`
/// metres and puts it at `target`: on a surface the scaled box touches the surface plane at the
/// target point from the normal's side (its support point along −normal lies on the plane, a
/// millimetre off so it does not share the surface), centred on the point in the plane: a box
/// on a floor stands on it, on a wall it hangs in front of it. In free space the box's centre
/// is at the point. A degenerate extent (flat quad) uses the largest extent; all zero extents
/// keep scale 1.
Transform placeInBox(const Bounds& bounds, double size, const PlacementTarget& target);

// ---------------------------------------------------------------------------------------------
// Ids and materials.

/// The first `<base>-<k>` (k = 1, 2, ...) for which `taken` is false; `base` is the file stem
/// for a path ("meshes/cgal/cow.off" → "cow-1"), with characters other than letters, digits,
/// '-' and '_' replaced by '_'.
std::string uniqueObjectId(const std::string& base,
                           const std::function<bool(const std::string&)>& taken);

/// The scene material a new object gets: the first non-emissive one, else the first; "" when
/// there are none.
std::string defaultMaterial(const std::vector<NamedMaterial>& materials);

}  // namespace penumbra
