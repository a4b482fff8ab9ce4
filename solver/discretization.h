#pragma once
// Patches (shooters) and elements (receivers) of every object, with OpenMesh connectivity.
//
// Index: Patch · Element · ObjectSurface · Discretization

#include <OpenMesh/Core/Mesh/PolyMesh_ArrayKernelT.hh>
#include <limits>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "solver/scene.h"

namespace penumbra {

class RayTracer;

/// Double-precision points, so world positions and areas are exact to ~1e-15.
struct ElementMeshTraits : OpenMesh::DefaultTraits {
    using Point = OpenMesh::Vec3d;
    using Normal = OpenMesh::Vec3d;
};
/// Object-space element mesh: one face per element, shared vertices within a smooth surface.
using ElementMesh = OpenMesh::PolyMesh_ArrayKernelT<ElementMeshTraits>;

/// A shooter: a coarse piece of one object's surface made of whole elements.
struct Patch {
    int object = -1;
    int material = -1;  ///< index into Discretization::materials()
    double area = 0;    ///< m², world space
    Vec3 centroid{0};
    Vec3 normal{0};     ///< area-weighted mean unit normal
    double radius = 0;  ///< bounding-sphere radius about centroid
    std::vector<int> elements;
    /// For a planar patch, its boundary polygon (world space, counter-clockwise seen from the
    /// front): form factors integrate one polygon instead of every element. Empty otherwise.
    std::vector<Vec3> outline;
    /// The outline's fan triangles (outline[0], outline[i+1], outline[i+2]): cumulative
    /// doubled areas (accumulateFanAreas), for sampling points of it.
    std::vector<double> outlineFans;
    /// The outline is a parallelogram (outline[0] + a·(outline[1] − outline[0]) +
    /// b·(outline[3] − outline[0]), a, b ∈ [0, 1]): a uniform point of it takes no search.
    bool parallelogram = false;
    std::string toString() const;
};

/// Cumulative doubled areas of the fan triangles (poly[0], poly[i+1], poly[i+2]) of a convex
/// polygon: the table that picks a fan triangle by area for a uniform point of the polygon.
void accumulateFanAreas(const std::vector<Vec3>& poly, std::vector<double>& cumulative);

/// A receiver. Vertices index ObjectSurface::worldPositions of its object, counter-clockwise
/// seen from the front (the side `normal` points to).
struct Element {
    int patch = -1;
    int object = -1;
    int face = -1;  ///< face index in the object's ElementMesh
    double area = 0;
    Vec3 centroid{0};
    Vec3 normal{0};
    std::vector<int> vertices;
    std::string toString() const;
};

/// One object's element mesh and its placement.
struct ObjectSurface {
    std::string id;
    ElementMesh mesh;                  ///< object space; face i is element faceElement[i]
    std::vector<int> faceElement;      ///< face index -> element index
    std::vector<Vec3> worldPositions;  ///< per mesh vertex, world space
    Mat4 worldFromObject{1.0};
    bool twoSided = false;
    /// Two-sided materials: faces from firstBackFace on are the back sheet (twins with
    /// reversed winding, own vertices; not in the ray tracer's geometry). faceTwin maps each
    /// face to its twin, -1 without one; empty when the object has no back sheet.
    int firstBackFace = std::numeric_limits<int>::max();
    std::vector<int> faceTwin;
    bool isBackFace(int face) const { return face >= firstBackFace; }
    /// False once removed from the scene: its patches and elements keep their indices (pair
    /// seeds stay valid) and its geometry stays available for redistribution, but it neither
    /// shoots, receives nor blocks in the current scene.
    bool alive = true;
};

/// How a Discretization groups its elements into patches (shooters). The elements are the
/// same either way, and so are the faces of each object's front (ObjectSurface::mesh) and
/// their elements' indices; a two-sided material's back-sheet twins come in the order of
/// their patches (ObjectSurface::faceTwin finds them).
enum class PatchGrouping {
    /// Patches of about the scene's patch_size (an object's own, when it has one).
    Patches,
    /// Patches of about one element (the interpolants' leaf solve, in which every element
    /// shoots its own radiosity): every cell of a gridded shape is a patch of its own, and mesh
    /// faces grow into patches of about element_size² (faces far smaller, as on a finely
    /// tessellated mesh, still share one). An object with a patch_size of its own keeps it.
    Elements,
};

/// Splits a scene into patches and elements (Cohen et al. 1988 §3.4). Primitives are gridded
/// parametrically; meshes keep their triangles as elements (split when larger than
/// element_size) and group them into patches by region growing over OpenMesh adjacency.
class Discretization {
public:
    /// Throws std::invalid_argument naming the object when an object has no valid faces.
    /// `grouping` holds for the objects added later too.
    explicit Discretization(const Scene& scene, PatchGrouping grouping = PatchGrouping::Patches);

    /// The front elements the constructor would split `scene`'s objects into (before it drops
    /// degenerate faces; back sheets not counted), planned without building them. Throws
    /// std::invalid_argument as the constructor does when an object would be too many.
    static double countElements(const Scene& scene);

    /// Appends a new object version (patches and elements after all existing ones) built
    /// from `object`, with materials looked up in `scene`. Returns its object index. Throws
    /// std::invalid_argument as the constructor does.
    int addObject(const Scene& scene, const SceneObject& object);
    /// Marks an object removed (or restored). Indices stay valid.
    void setAlive(int object, bool alive);
    bool elementAlive(int element) const { return mObjects[mElements[element].object].alive; }
    /// The alive elements' indices, ascending.
    std::vector<int> aliveElements() const;
    /// Moves the receiver of every alive element whose centroid lies inside another object's
    /// solid (every ray of a small fan about its normal meets that object from inside) to the
    /// point of the element in the open nearest the mean of its open sample points; the
    /// others receive at their centroids (SolverOptions::placeReceivers). Returns how many
    /// receivers are not at their centroids.
    int placeReceivers(const RayTracer& tracer);
    /// Where the solver takes the light element e receives: its centroid, or, when the
    /// centroid lies inside a solid resting on it (a floor element a box's foot crosses), the
    /// point of the element in the open that placeReceivers chose.
    const Vec3& receiver(int e) const {
        return static_cast<std::size_t>(e) < mReceivers.size() ? mReceivers[e]
                                                               : mElements[e].centroid;
    }
    bool patchAlive(int patch) const { return mObjects[mPatches[patch].object].alive; }
    /// Replaces the material of every patch of `object` (a material edit).
    void setObjectMaterial(int object, const Material& material);

    const std::vector<Patch>& patches() const { return mPatches; }
    const std::vector<Element>& elements() const { return mElements; }
    const std::vector<ObjectSurface>& objects() const { return mObjects; }
    const std::vector<Material>& materials() const { return mMaterials; }
    const Material& patchMaterial(int patch) const { return mMaterials[mPatches[patch].material]; }
    const Material& elementMaterial(int e) const { return patchMaterial(mElements[e].patch); }

    /// World-space polygon of an element.
    std::vector<Vec3> elementPolygon(int element) const;

    /// Elements sharing a vertex with `element` (OpenMesh vertex-face circulation).
    std::vector<int> elementNeighbours(int element) const;

    /// Per-vertex value of an object: the area-weighted mean of `elementValue` over the
    /// elements around each vertex (for Gouraud display and export).
    std::vector<Rgb> vertexValues(int object, const std::vector<Rgb>& elementValue) const;
    /// The elements of an object version, [first, first + count) (a version's elements are
    /// appended together); {0, 0} for none.
    std::pair<int, int> elementRange(int object) const;
    /// Whether versions `a` and `b` are the same mesh of one document object, element for
    /// element (a move or a rotation; not a scale that changed the elements): element
    /// first(a) + k of one is element first(b) + k of the other.
    bool sameElements(int a, int b) const;

    /// Splits an element into four (quads into quads, triangles into triangles), keeping the
    /// mesh conforming by inserting edge midpoints into neighbours. Returns the new element
    /// indices; the first reuses the parent's index.
    std::vector<int> subdivideElement(int element);

    double totalArea() const { return mTotalArea; }
    std::string toString() const;

private:
    void buildObject(const Scene& scene, const SceneObject& object);
    /// The patches of object objIdx's faces (elements firstElement on, one per face): faces of
    /// a group (a grid's patch) make one patch; the others grow patches of about patchSize²
    /// over OpenMesh adjacency, one material and within 45° of their seed's normal. Returns
    /// group → patch.
    std::map<int, int> makePatches(int objIdx, int firstElement, const std::vector<int>& faceGroup,
                                   const std::vector<int>& faceMaterial, double patchSize);
    /// Gives each planar gridded patch its outline (groupOutline, object space) in world space,
    /// straight runs merged, when it is convex (the contour integral's polygon).
    void outlinePlanarPatches(const std::map<int, int>& groupPatch,
                              std::map<int, std::vector<Vec3>>& groupOutline,
                              const Mat4& worldFromObject, bool mirrored);
    int addMaterial(const Material& m);
    void finishElement(int element);
    void finishPatch(int patch);
    /// Twin elements and patches for the two-sided faces of object objIdx (patches from
    /// firstPatch on are the object's).
    void addBackSheet(int objIdx, int firstPatch);
    /// The back sheet's material for a front material.
    static Material backMaterial(const Material& front);

    std::vector<Patch> mPatches;
    std::vector<Element> mElements;
    /// Per element, its receiving point (receiver()), held only once placeReceivers has moved
    /// one off its centroid: most solves never do, and then it holds nothing. Elements past
    /// its end receive at their centroids.
    std::vector<Vec3> mReceivers;
    std::vector<ObjectSurface> mObjects;
    std::vector<Material> mMaterials;
    double mTotalArea = 0;
    PatchGrouping mGrouping = PatchGrouping::Patches;
};

}  // namespace penumbra
