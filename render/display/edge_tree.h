#pragma once
// The interval-vector edge tree that finds silhouettes and shadow-event candidates over an
// EdgeMesh (Bala, Walter, Greenberg 2003 §6.4).

#include <array>
#include <cstdint>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "render/edge_mesh.h"

namespace penumbra {

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
