#pragma once
// Object-space edge structure for edge finding (Bala, Walter, Greenberg 2003 §6): a welded
// polygon mesh with OpenMesh edge adjacency (EdgeMesh) and the interval-vector edge tree that
// finds silhouettes and shadow-event candidates (EdgeTree, §6.4).
//
// Index: Interval helpers · MeshEdge, FacePlane · EdgeMesh · EdgeTree

#include <array>
#include <cstdint>
#include <limits>
#include <memory>
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

/// Counters of one traversal, for measurements.
struct EdgeTreeStats {
    long long nodesVisited = 0;
    long long edgesTested = 0;
};

/// Bala et al. §6.4: a tree over an EdgeMesh's interior edges whose nodes bound the normals of
/// all faces adjacent to their edges by an interval vector. Built top-down, splitting each
/// node on the normal axis (or the longest axis of edge positions) that minimises the children's
/// combined extent (normal extent × mesh size + position extent); an edge
/// whose normals span more than half the node's normal range is stored at the node ("sharp
/// edges higher in the tree"). Boundary edges are kept aside and always reported.
///
/// Node test (eq. 1 with intervals): for faces f below a node, N_f·V_f = N_f·(e − c) −
/// (d_f − N_f·c), c the node centre. The node keeps the interval vector [N] and the interval
/// [d_f − N_f·c]; when [N]·(e − c) − [d] excludes zero every face below faces the same way and
/// the subtree holds no silhouette. (The paper forms [N]·(e − [p]) from a position interval
/// vector; the plane-offset interval is the same bound made tighter for nearly coplanar faces.)
/// Queries are in object space: callers map the eye into the object, so a move rebuilds
/// nothing.
class EdgeTree {
public:
    explicit EdgeTree(std::shared_ptr<const EdgeMesh> mesh, int leafSize = 8);

    /// Appends to `out` the ids of every edge that is a silhouette from `eye` (object space)
    /// by eq. 1, boundary edges included; order unspecified.
    void findSilhouettes(const Vec3& eye, std::vector<int>& out,
                         EdgeTreeStats* stats = nullptr) const;
    /// The same edges in the same order, each with its object-space end points (v0, v1)
    /// appended to `ends`: read beside the tree's records, in their order, rather than
    /// through the mesh's edge and vertex arrays at random.
    void findSilhouettes(const Vec3& eye, std::vector<int>& out, std::vector<Vec3>& ends,
                         EdgeTreeStats* stats = nullptr) const;
    /// Appends the ids of edges that may be a silhouette from some point of the convex
    /// polygon `region` (object space): internal nodes use the polygon's bounding box as an
    /// interval eye, leaves keep an edge unless both faces have every polygon vertex strictly
    /// in front or every vertex on or behind (a conservative superset; exact for one point).
    /// Boundary edges are included.
    void findSilhouetteCandidates(const std::vector<Vec3>& region, std::vector<int>& out,
                                  EdgeTreeStats* stats = nullptr) const;

    const EdgeMesh& mesh() const { return *mMesh; }
    const std::shared_ptr<const EdgeMesh>& meshPtr() const { return mMesh; }
    int nodeCount() const { return static_cast<int>(mNodes.size()); }
    std::string toString() const;

private:
    struct Node {
        double nLo[3]{}, nHi[3]{};  ///< interval vector of face normals below
        double c[3]{};              ///< centre
        double dLo = 0, dHi = 0;    ///< interval of d_f − N_f·c below
        int begin = 0;              ///< first record of this node
        int stored = 0;             ///< records [begin, begin + stored) stored here
        int end = 0;                ///< one past the last record of the subtree
        int child = -1;             ///< children child, child + 1; -1 for a leaf
    };
    /// An interior edge's two face planes, in tree order.
    struct Record {
        double n0[3], d0;
        double n1[3], d1;
        int edge;
    };
    /// An interior edge while the tree is built: the interval vector of its face normals.
    struct BuildItem {
        double lo[3], hi[3];
        Vec3 mid;  ///< edge midpoint
        double span() const { return (hi[0] - lo[0]) + (hi[1] - lo[1]) + (hi[2] - lo[2]); }
        double centre(int k) const { return lo[k] + hi[k]; }
    };
    /// Builds node `slot` over the edges order[begin, end): its bounds, the edges it stores,
    /// and its children (recursively) over the rest.
    void buildNode(int slot, std::vector<int>& order, int begin, int end);
    /// Node `slot`'s bounds over order[begin, end): the normal interval vector, the centre of
    /// the edges' position box, and the plane-offset interval about that centre; its first
    /// record is the next one appended.
    void computeNodeBounds(int slot, const std::vector<int>& order, int begin, int end);
    /// Appends the records (both face planes) of the edges order[from, to).
    void appendRecords(const std::vector<int>& order, int from, int to);
    /// Splits order[mid, end) at its median on the axis whose halves bound eq. 1 most tightly,
    /// leaving it partitioned there; returns the median index.
    int splitAtBestAxis(std::vector<int>& order, int mid, int end) const;
    /// A split half's cost: its normal extent × the root's size plus its midpoints' extent.
    double splitCost(const std::vector<int>& order, int from, int to) const;
    /// Depth-first walk from the root: a node for which `culled(node)` holds is skipped with
    /// everything below it; otherwise `visit(begin, last)` gets the records it stores
    /// [begin, last) and its children are walked. Counts into `stats` when given.
    template <typename Culled, typename Visit>
    void walk(Culled&& culled, Visit&& visit, EdgeTreeStats* stats) const;
    /// Eq. 1 over the tree: the record indices of the interior silhouette edges in
    /// records[0, returned count) (`records` only grows; entries past the count are scratch).
    std::size_t silhouetteRecords(const Vec3& eye, std::vector<int>& records,
                                  EdgeTreeStats* stats) const;
    std::vector<BuildItem> mItems;  ///< by edge id, during construction only
    double mRootSize = 0;           ///< mesh diagonal, during construction only

    std::shared_ptr<const EdgeMesh> mMesh;
    int mLeafSize;
    std::vector<Node> mNodes;
    std::vector<Record> mRecords;
    std::vector<Vec3> mRecordEnds;  ///< per record: its edge's v0 and v1, object space
};

}  // namespace penumbra
