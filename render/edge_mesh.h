#pragma once
// An object-space polygon mesh with OpenMesh edge adjacency, face planes and sharp edges
// (Bala, Walter, Greenberg 2003 §6.2): what the display's edge tree walks for silhouettes and
// what the high-fidelity mesh reads its sharp and contact edges from.
//
// Index: MeshEdge, FacePlane · EdgeMesh

#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "render/box_tree.h"
#include "solver/discretization.h"
#include "solver/scene.h"

namespace penumbra {

/// One mesh edge. f0 is the face whose boundary runs v0 → v1 (counter-clockwise winding);
/// f1 the face on the other side, or -1 for a boundary edge.
struct MeshEdge {
    int v0 = -1, v1 = -1;
    int f0 = -1, f1 = -1;
    bool sharp = false;  ///< dihedral angle above the cutoff, or a boundary edge (§6.2)
    bool boundary() const { return f1 < 0; }
};

/// Supporting plane of a face: unit normal n (front side) and offset d, n·x = d on the face.
/// A point x is in front of the face when n·x − d > 0 (Bala et al. eq. 1's N·V > 0).
struct FacePlane {
    Vec3 n{0, 1, 0};
    double d = 0;
    double eval(const Vec3& x) const { return glm::dot(n, x) - d; }
};

/// A polygon mesh in object space with edge and vertex adjacency from OpenMesh. Vertices that
/// coincide (within 1e-9 of the bounding-box diagonal) are welded when asked, so the separately
/// gridded sides of a box share their edges and those edges get a real dihedral angle.
/// Non-manifold faces keep their own copies of the shared vertices (their edges become
/// boundary edges), as in Discretization.
class EdgeMesh {
public:
    /// `faces` index `positions`, counter-clockwise seen from the front. Faces with fewer than
    /// 3 distinct vertices are dropped. `sharpCutoffDeg`: an interior edge is sharp when the
    /// angle between its two face normals exceeds it (measured in object space).
    EdgeMesh(const std::vector<Vec3>& positions, const std::vector<std::vector<int>>& faces,
             double sharpCutoffDeg = 85.0, bool weld = false);
    /// A mesh file's triangles as they are (no welding).
    static EdgeMesh fromTriMesh(const TriMesh& mesh, double sharpCutoffDeg = 85.0);
    /// A Discretization object's element mesh, welded.
    /// Faces from `faceCount` on are left out (a two-sided object's back sheet: the same
    /// surface, ObjectSurface::firstBackFace).
    static EdgeMesh fromElementMesh(const ElementMesh& mesh, double sharpCutoffDeg = 85.0,
                                    int faceCount = std::numeric_limits<int>::max());

    const std::vector<Vec3>& positions() const { return mPositions; }
    /// Index of each vertex in the input positions.
    const std::vector<int>& sourceVertex() const { return mSourceVertex; }
    int faceCount() const { return static_cast<int>(mFacePlanes.size()); }
    /// Vertices of face f: faceVertices()[faceStart()[f] .. faceStart()[f+1]).
    const std::vector<int>& faceStart() const { return mFaceStart; }
    const std::vector<int>& faceVertices() const { return mFaceVertices; }
    const std::vector<FacePlane>& facePlanes() const { return mFacePlanes; }
    /// Index of each face in the input faces.
    const std::vector<int>& sourceFace() const { return mSourceFace; }
    const std::vector<MeshEdge>& edges() const { return mEdges; }
    /// Edge ids of sharp edges (including boundary edges), and of boundary edges.
    const std::vector<int>& sharpEdges() const { return mSharpEdges; }
    const std::vector<int>& boundaryEdges() const { return mBoundaryEdges; }
    /// One-ring neighbours of vertex v: neighbours()[neighbourStart()[v] .. [v+1]).
    const std::vector<int>& neighbourStart() const { return mNeighbourStart; }
    const std::vector<int>& neighbours() const { return mNeighbours; }
    const Box3& bounds() const { return mBounds; }
    /// No boundary edges: a ray from outside meets a front face before any back face.
    bool closed() const { return mBoundaryEdges.empty(); }
    /// Closed, or open only along cracks: every boundary edge is covered by boundary edges
    /// running the opposite way along the same line (T-junctions of split triangles). Such a
    /// surface still bounds a solid. Checked for up to 4000 boundary edges, else false.
    bool sealed() const { return mSealed; }
    /// Hash of positions and faces: equal meshes (e.g. two versions of a moved object) share
    /// one tree.
    std::uint64_t contentHash() const { return mHash; }

    /// Bala et al. eq. 1 on one edge, brute force: the two faces face opposite ways from
    /// `eye` (object space). Boundary edges are always silhouettes (the surface ends there).
    bool isSilhouette(int edge, const Vec3& eye) const;
    std::string toString() const;

private:
    /// Adds the faces to `om` over the welded vertices (each vertex on first use, its input
    /// index appended to mSourceVertex); a face OpenMesh cannot link (non-manifold there) gets
    /// its own copies of its vertices. Returns the input index of each face added.
    std::vector<int> linkFaces(const std::vector<Vec3>& positions,
                               const std::vector<std::vector<int>>& faces,
                               const std::vector<int>& welded, ElementMesh& om);
    /// Positions, bounds, face vertex lists and face planes (Newell normals) from `om`.
    void copyFacesAndPlanes(const ElementMesh& om, const std::vector<int>& faceSource);
    /// Edges with their two faces from `om`; sharp edges (§6.2, normals further apart than
    /// `cosCutoff`) and boundary edges.
    void collectEdges(const ElementMesh& om, double cosCutoff);
    /// Faces OpenMesh could not link (non-manifold vertices) kept their own vertex copies, so
    /// their edges came out as boundary edges although a face lies across them. Pairs such an
    /// edge with the one boundary edge running the other way between the same input vertices:
    /// one interior edge with both faces (real silhouettes, a real dihedral angle, a closed
    /// mesh when nothing else is open).
    void mergeNonManifoldSeams(double cosCutoff);
    /// sealed(): every boundary edge is covered by boundary edges running the other way along
    /// it (cracks of T-junctions where the Discretization split large triangles). Brute force
    /// over boundary edges, done once per mesh.
    bool computeSealed() const;
    /// Vertex one-rings from `om`.
    void collectOneRings(const ElementMesh& om);

    std::vector<Vec3> mPositions;
    std::vector<int> mSourceVertex;
    std::vector<int> mFaceStart, mFaceVertices, mSourceFace;
    std::vector<FacePlane> mFacePlanes;
    std::vector<MeshEdge> mEdges;
    std::vector<int> mSharpEdges, mBoundaryEdges;
    std::vector<int> mNeighbourStart, mNeighbours;
    Box3 mBounds;
    bool mSealed = false;
    std::uint64_t mHash = 0;
};

}  // namespace penumbra
