// Index: EdgeMesh (welding, OpenMesh adjacency, planes, sharp edges) · EdgeTree build ·
//        EdgeTree traversal (point eye, polygon eye)
#include "render/edge_tree.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <sstream>
#include <unordered_map>

namespace penumbra {

// ---------------------------------------------------------------------------------------------
// EdgeMesh

namespace {

std::uint64_t hashMix(std::uint64_t h, std::uint64_t v) {
    // FNV-1a over the 8 bytes of v.
    for (int i = 0; i < 8; ++i) {
        h ^= (v >> (8 * i)) & 0xffu;
        h *= 1099511628211ull;
    }
    return h;
}

std::uint64_t bitsOf(double x) {
    std::uint64_t b;
    std::memcpy(&b, &x, sizeof b);
    return b;
}

struct CellKey {
    long long x, y, z;
    bool operator==(const CellKey& o) const { return x == o.x && y == o.y && z == o.z; }
};
struct CellKeyHash {
    std::size_t operator()(const CellKey& k) const {
        return std::hash<long long>()(k.x * 73856093LL ^ k.y * 19349663LL ^ k.z * 83492791LL);
    }
};

/// Per input vertex, the input vertex it is welded to: itself unless `weld` and an earlier
/// vertex lies within 1e-9 of the bounding-box diagonal (hash grid, cells of the tolerance,
/// 27-cell search).
std::vector<int> weldVertices(const std::vector<Vec3>& positions, bool weld) {
    Box3 inputBounds;
    for (const Vec3& p : positions) inputBounds.extend(p);

    std::vector<int> welded(positions.size());
    for (std::size_t i = 0; i < positions.size(); ++i) welded[i] = static_cast<int>(i);
    if (weld && !inputBounds.empty()) {
        double tol = 1e-9 * std::max(glm::length(inputBounds.hi - inputBounds.lo), 1e-300);
        std::unordered_map<CellKey, int, CellKeyHash> grid;
        grid.reserve(positions.size() * 2);
        auto keyOf = [&](const Vec3& p) {
            return CellKey{static_cast<long long>(std::floor(p.x / tol)),
                           static_cast<long long>(std::floor(p.y / tol)),
                           static_cast<long long>(std::floor(p.z / tol))};
        };
        for (std::size_t i = 0; i < positions.size(); ++i) {
            CellKey k = keyOf(positions[i]);
            int found = -1;
            for (long long dx = -1; dx <= 1 && found < 0; ++dx)
                for (long long dy = -1; dy <= 1 && found < 0; ++dy)
                    for (long long dz = -1; dz <= 1 && found < 0; ++dz) {
                        auto it = grid.find({k.x + dx, k.y + dy, k.z + dz});
                        if (it != grid.end() &&
                            glm::length(positions[it->second] - positions[i]) <= tol)
                            found = it->second;
                    }
            if (found >= 0)
                welded[i] = found;
            else
                grid.emplace(k, static_cast<int>(i));
        }
    }
    return welded;
}

/// FNV-1a over positions, face starts, face vertices and the cutoff: equal meshes hash
/// equal, so they share one tree.
std::uint64_t hashContent(const std::vector<Vec3>& positions, const std::vector<int>& faceStart,
                          const std::vector<int>& faceVertices, double sharpCutoffDeg) {
    std::uint64_t h = 1469598103934665603ull;
    for (const Vec3& p : positions)
        h = hashMix(hashMix(hashMix(h, bitsOf(p.x)), bitsOf(p.y)), bitsOf(p.z));
    for (int v : faceStart) h = hashMix(h, static_cast<std::uint64_t>(v));
    for (int v : faceVertices) h = hashMix(h, static_cast<std::uint64_t>(v));
    h = hashMix(h, bitsOf(sharpCutoffDeg));
    return h;
}

}  // namespace

EdgeMesh::EdgeMesh(const std::vector<Vec3>& positions, const std::vector<std::vector<int>>& faces,
                   double sharpCutoffDeg, bool weld) {
    const std::vector<int> welded = weldVertices(positions, weld);
    ElementMesh om;
    const std::vector<int> faceSource = linkFaces(positions, faces, welded, om);
    copyFacesAndPlanes(om, faceSource);
    double cosCutoff = std::cos(sharpCutoffDeg * M_PI / 180.0);
    collectEdges(om, cosCutoff);
    mergeNonManifoldSeams(cosCutoff);
    mSealed = computeSealed();
    collectOneRings(om);
    mHash = hashContent(mPositions, mFaceStart, mFaceVertices, sharpCutoffDeg);
}

std::vector<int> EdgeMesh::linkFaces(const std::vector<Vec3>& positions,
                                     const std::vector<std::vector<int>>& faces,
                                     const std::vector<int>& welded, ElementMesh& om) {
    // Vertices are added on first use.
    std::vector<int> vertexOf(positions.size(), -1);
    auto handleOf = [&](int input) {
        int w = welded[input];
        if (vertexOf[w] < 0) {
            const Vec3& p = positions[w];
            vertexOf[w] = om.add_vertex(ElementMesh::Point(p.x, p.y, p.z)).idx();
            mSourceVertex.push_back(w);
        }
        return ElementMesh::VertexHandle(vertexOf[w]);
    };
    std::vector<int> faceSource;
    for (std::size_t f = 0; f < faces.size(); ++f) {
        std::vector<ElementMesh::VertexHandle> vs;
        for (int v : faces[f]) {
            if (v < 0 || v >= static_cast<int>(positions.size())) continue;
            ElementMesh::VertexHandle h = handleOf(v);
            if (std::find(vs.begin(), vs.end(), h) == vs.end()) vs.push_back(h);
        }
        if (vs.size() < 3) continue;
        ElementMesh::FaceHandle fh = om.add_face(vs);
        if (!fh.is_valid()) {
            // Non-manifold here: the face keeps its own vertices.
            std::vector<ElementMesh::VertexHandle> copy;
            for (auto h : vs) {
                copy.push_back(om.add_vertex(om.point(h)));
                mSourceVertex.push_back(mSourceVertex[h.idx()]);
            }
            fh = om.add_face(copy);
            if (!fh.is_valid()) continue;
        }
        faceSource.push_back(static_cast<int>(f));
    }
    return faceSource;
}

void EdgeMesh::copyFacesAndPlanes(const ElementMesh& om, const std::vector<int>& faceSource) {
    mPositions.resize(om.n_vertices());
    for (auto vh : om.vertices()) {
        const auto& p = om.point(vh);
        mPositions[vh.idx()] = Vec3(p[0], p[1], p[2]);
        mBounds.extend(mPositions[vh.idx()]);
    }
    mSourceFace = faceSource;
    mFaceStart.reserve(om.n_faces() + 1);
    mFacePlanes.resize(om.n_faces());
    mFaceStart.push_back(0);
    for (auto fh : om.faces()) {
        int first = static_cast<int>(mFaceVertices.size());
        for (auto vh : om.fv_range(fh)) mFaceVertices.push_back(vh.idx());
        int count = static_cast<int>(mFaceVertices.size()) - first;
        const Vec3 n = newellNormal(mPositions, &mFaceVertices[first], std::size_t(count));
        Vec3 c(0.0);
        for (int i = 0; i < count; ++i) c += mPositions[mFaceVertices[first + i]];
        mFaceStart.push_back(static_cast<int>(mFaceVertices.size()));
        double len = glm::length(n);
        FacePlane& plane = mFacePlanes[fh.idx()];
        plane.n = len > 0 ? n / len : Vec3(0, 1, 0);
        plane.d = glm::dot(plane.n, c / double(count));
    }
}

void EdgeMesh::collectEdges(const ElementMesh& om, double cosCutoff) {
    mEdges.reserve(om.n_edges());
    for (auto eh : om.edges()) {
        auto h0 = om.halfedge_handle(eh, 0), h1 = om.halfedge_handle(eh, 1);
        if (!om.face_handle(h0).is_valid()) std::swap(h0, h1);
        MeshEdge e;
        e.v0 = om.from_vertex_handle(h0).idx();
        e.v1 = om.to_vertex_handle(h0).idx();
        e.f0 = om.face_handle(h0).idx();
        e.f1 = om.face_handle(h1).is_valid() ? om.face_handle(h1).idx() : -1;
        if (e.f0 < 0) continue;  // an edge of no face cannot happen; be safe
        int id = static_cast<int>(mEdges.size());
        if (e.f1 < 0) {
            e.sharp = true;
            mBoundaryEdges.push_back(id);
        } else {
            e.sharp = glm::dot(mFacePlanes[e.f0].n, mFacePlanes[e.f1].n) < cosCutoff;
        }
        if (e.sharp) mSharpEdges.push_back(id);
        mEdges.push_back(e);
    }
}

void EdgeMesh::mergeNonManifoldSeams(double cosCutoff) {
    std::unordered_map<std::uint64_t, std::vector<int>> open;
    auto key = [&](int a, int b) {
        return (static_cast<std::uint64_t>(mSourceVertex[a]) << 32) |
               static_cast<std::uint32_t>(mSourceVertex[b]);
    };
    for (int id : mBoundaryEdges) open[key(mEdges[id].v0, mEdges[id].v1)].push_back(id);
    std::vector<char> removed(mEdges.size(), 0);
    bool merged = false;
    for (int id : mBoundaryEdges) {
        if (removed[id] || mEdges[id].f1 >= 0) continue;
        const MeshEdge& e = mEdges[id];
        auto same = open.find(key(e.v0, e.v1));
        auto back = open.find(key(e.v1, e.v0));
        if (back == open.end() || back->second.size() != 1 || same->second.size() != 1) continue;
        int other = back->second[0];
        if (other == id || removed[other] || mEdges[other].f0 == e.f0) continue;
        mEdges[id].f1 = mEdges[other].f0;
        mEdges[id].sharp = glm::dot(mFacePlanes[e.f0].n, mFacePlanes[mEdges[id].f1].n) < cosCutoff;
        removed[other] = 1;
        merged = true;
    }
    if (merged) {
        std::vector<MeshEdge> kept;
        mSharpEdges.clear();
        mBoundaryEdges.clear();
        for (std::size_t i = 0; i < mEdges.size(); ++i) {
            if (removed[i]) continue;
            int id = static_cast<int>(kept.size());
            if (mEdges[i].f1 < 0) mBoundaryEdges.push_back(id);
            if (mEdges[i].sharp) mSharpEdges.push_back(id);
            kept.push_back(mEdges[i]);
        }
        mEdges.swap(kept);
    }
}

bool EdgeMesh::computeSealed() const {
    if (mBoundaryEdges.empty()) return true;
    if (mBoundaryEdges.size() > 4000) return false;
    double tol = 1e-9 * glm::length(mBounds.hi - mBounds.lo);
    std::vector<std::pair<double, double>> cover;
    for (int id : mBoundaryEdges) {
        const Vec3& c = mPositions[mEdges[id].v0];
        const Vec3& d = mPositions[mEdges[id].v1];
        Vec3 dir = d - c;
        double len2 = glm::dot(dir, dir);
        if (!(len2 > 0)) continue;
        cover.clear();
        for (int other : mBoundaryEdges) {
            const Vec3& a = mPositions[mEdges[other].v0];
            const Vec3& b = mPositions[mEdges[other].v1];
            double ta = glm::dot(a - c, dir) / len2, tb = glm::dot(b - c, dir) / len2;
            if (!(tb < ta)) continue;  // must run the other way
            if (glm::length(a - (c + ta * dir)) > tol || glm::length(b - (c + tb * dir)) > tol)
                continue;  // not on the line
            cover.push_back({tb, ta});
        }
        std::sort(cover.begin(), cover.end());
        double reach = 0;
        double step = tol / std::sqrt(len2);
        for (const auto& [lo, hi] : cover) {
            if (lo > reach + step) break;
            reach = std::max(reach, hi);
        }
        if (reach < 1 - step) return false;
    }
    return true;
}

void EdgeMesh::collectOneRings(const ElementMesh& om) {
    mNeighbourStart.reserve(om.n_vertices() + 1);
    mNeighbourStart.push_back(0);
    for (auto vh : om.vertices()) {
        for (auto w : om.vv_range(vh)) mNeighbours.push_back(w.idx());
        mNeighbourStart.push_back(static_cast<int>(mNeighbours.size()));
    }
}

EdgeMesh EdgeMesh::fromTriMesh(const TriMesh& mesh, double sharpCutoffDeg) {
    std::vector<std::vector<int>> faces;
    faces.reserve(mesh.triangles.size());
    for (const auto& t : mesh.triangles) faces.push_back({t[0], t[1], t[2]});
    return EdgeMesh(mesh.positions, faces, sharpCutoffDeg, false);
}

EdgeMesh EdgeMesh::fromElementMesh(const ElementMesh& mesh, double sharpCutoffDeg, int faceCount) {
    std::vector<Vec3> positions(mesh.n_vertices());
    for (auto vh : mesh.vertices()) {
        const auto& p = mesh.point(vh);
        positions[vh.idx()] = Vec3(p[0], p[1], p[2]);
    }
    std::vector<std::vector<int>> faces;
    faces.reserve(mesh.n_faces());
    for (auto fh : mesh.faces()) {
        if (fh.idx() >= faceCount) break;
        std::vector<int> f;
        for (auto vh : mesh.fv_range(fh)) f.push_back(vh.idx());
        faces.push_back(std::move(f));
    }
    return EdgeMesh(positions, faces, sharpCutoffDeg, true);
}

bool EdgeMesh::isSilhouette(int edge, const Vec3& eye) const {
    const MeshEdge& e = mEdges[edge];
    if (e.f1 < 0) return true;
    // Bala et al. eq. 1: sign(N_f0·V_f0) != sign(N_f1·V_f1).
    return (mFacePlanes[e.f0].eval(eye) > 0) != (mFacePlanes[e.f1].eval(eye) > 0);
}

std::string EdgeMesh::toString() const {
    std::ostringstream s;
    s << "EdgeMesh{" << mPositions.size() << " vertices, " << faceCount() << " faces, "
      << mEdges.size() << " edges, " << mSharpEdges.size() << " sharp, " << mBoundaryEdges.size()
      << " boundary" << (mSealed ? ", sealed" : "") << "}";
    return s.str();
}

// ---------------------------------------------------------------------------------------------
// EdgeTree build

EdgeTree::EdgeTree(std::shared_ptr<const EdgeMesh> mesh, int leafSize)
    : mMesh(std::move(mesh)), mLeafSize(std::max(1, leafSize)) {
    const EdgeMesh& m = *mMesh;
    std::vector<int> order;
    order.reserve(m.edges().size());
    for (std::size_t i = 0; i < m.edges().size(); ++i)
        if (!m.edges()[i].boundary()) order.push_back(static_cast<int>(i));
    mRecords.reserve(order.size());
    mNodes.reserve(2 * order.size() / mLeafSize + 16);
    mNodes.push_back({});
    if (order.empty()) {
        Node& root = mNodes[0];
        for (int k = 0; k < 3; ++k) root.nLo[k] = root.nHi[k] = root.c[k] = 0;
        root.dLo = root.dHi = 0;
        return;
    }
    // Per-edge normal interval vectors and midpoints.
    mItems.resize(m.edges().size());
    mRootSize = glm::length(m.bounds().hi - m.bounds().lo);
    for (int id : order) {
        const MeshEdge& e = m.edges()[id];
        mItems[id].mid = 0.5 * (m.positions()[e.v0] + m.positions()[e.v1]);
        const Vec3& a = m.facePlanes()[e.f0].n;
        const Vec3& b = m.facePlanes()[e.f1].n;
        for (int k = 0; k < 3; ++k) {
            mItems[id].lo[k] = std::min(a[k], b[k]);
            mItems[id].hi[k] = std::max(a[k], b[k]);
        }
    }
    buildNode(0, order, 0, static_cast<int>(order.size()));
    mItems.clear();
    mItems.shrink_to_fit();
    mRecordEnds.reserve(2 * mRecords.size());
    for (const Record& r : mRecords) {
        const MeshEdge& e = m.edges()[r.edge];
        mRecordEnds.push_back(m.positions()[e.v0]);
        mRecordEnds.push_back(m.positions()[e.v1]);
    }
}

void EdgeTree::buildNode(int slot, std::vector<int>& order, int begin, int end) {
    const auto& items = mItems;
    computeNodeBounds(slot, order, begin, end);
    int count = end - begin;
    if (count <= mLeafSize) {
        appendRecords(order, begin, end);
        mNodes[slot].stored = count;
        mNodes[slot].end = static_cast<int>(mRecords.size());
        return;
    }
    // Edges whose normals span more than half the node's normal range stay here (§6.4,
    // non-smooth surfaces).
    const Node& bounds = mNodes[slot];
    double nodeSpan = (bounds.nHi[0] - bounds.nLo[0]) + (bounds.nHi[1] - bounds.nLo[1]) +
                      (bounds.nHi[2] - bounds.nLo[2]);
    int mid =
        static_cast<int>(std::partition(order.begin() + begin, order.begin() + end,
                                        [&](int id) { return items[id].span() > 0.5 * nodeSpan; }) -
                         order.begin());
    int stored = mid - begin;
    if (end - mid <= mLeafSize) {
        appendRecords(order, begin, end);
        mNodes[slot].stored = count;
        mNodes[slot].end = static_cast<int>(mRecords.size());
        return;
    }
    appendRecords(order, begin, mid);
    mNodes[slot].stored = stored;

    int half = splitAtBestAxis(order, mid, end);
    int child = static_cast<int>(mNodes.size());
    mNodes.push_back({});
    mNodes.push_back({});
    mNodes[slot].child = child;
    buildNode(child, order, mid, half);
    buildNode(child + 1, order, half, end);
    mNodes[slot].end = static_cast<int>(mRecords.size());
}

void EdgeTree::computeNodeBounds(int slot, const std::vector<int>& order, int begin, int end) {
    const EdgeMesh& m = *mMesh;
    const auto& items = mItems;
    // Bounds: normal interval vector, position box, plane-offset interval.
    double nLo[3] = {1e300, 1e300, 1e300}, nHi[3] = {-1e300, -1e300, -1e300};
    Box3 pos;
    for (int i = begin; i < end; ++i) {
        const auto& it = items[order[i]];
        for (int k = 0; k < 3; ++k) {
            nLo[k] = std::min(nLo[k], it.lo[k]);
            nHi[k] = std::max(nHi[k], it.hi[k]);
        }
        const MeshEdge& e = m.edges()[order[i]];
        pos.extend(m.positions()[e.v0]);
        pos.extend(m.positions()[e.v1]);
    }
    Vec3 c = pos.centre();
    double dLo = 1e300, dHi = -1e300;
    for (int i = begin; i < end; ++i) {
        const MeshEdge& e = m.edges()[order[i]];
        for (int f : {e.f0, e.f1}) {
            const FacePlane& p = m.facePlanes()[f];
            double d = p.d - glm::dot(p.n, c);
            dLo = std::min(dLo, d);
            dHi = std::max(dHi, d);
        }
    }
    Node& node = mNodes[slot];
    for (int k = 0; k < 3; ++k) {
        node.nLo[k] = nLo[k];
        node.nHi[k] = nHi[k];
        node.c[k] = c[k];
    }
    node.dLo = dLo;
    node.dHi = dHi;
    node.begin = static_cast<int>(mRecords.size());
}

void EdgeTree::appendRecords(const std::vector<int>& order, int from, int to) {
    const EdgeMesh& m = *mMesh;
    for (int i = from; i < to; ++i) {
        const MeshEdge& e = m.edges()[order[i]];
        const FacePlane& p0 = m.facePlanes()[e.f0];
        const FacePlane& p1 = m.facePlanes()[e.f1];
        mRecords.push_back(
            {{p0.n.x, p0.n.y, p0.n.z}, p0.d, {p1.n.x, p1.n.y, p1.n.z}, p1.d, order[i]});
    }
}

int EdgeTree::splitAtBestAxis(std::vector<int>& order, int mid, int end) const {
    const auto& items = mItems;
    // Split at the median of the axis whose children bound eq. 1 most tightly: a node's
    // interval [N]·(e − c) − [d] is about (normal extent)·|e − c| + 2·(position extent) wide,
    // so a child costs its normal extent times the root's size (a typical eye distance) plus
    // its position extent (the diagonal of its edge midpoints). Candidates: the
    // three normal axes (§6.4) and the longest axis of the edge midpoints (position matters when
    // many separate parts share normals).
    int half = mid + (end - mid) / 2;
    Box3 mids;
    for (int i = mid; i < end; ++i) mids.extend(items[order[i]].mid);
    Vec3 ext = mids.hi - mids.lo;
    int posAxis = ext.x > ext.y ? (ext.x > ext.z ? 0 : 2) : (ext.y > ext.z ? 1 : 2);
    auto partitionOn = [&](int axis) {
        if (axis < 3)
            std::nth_element(
                order.begin() + mid, order.begin() + half, order.begin() + end,
                [&](int a, int b) { return items[a].centre(axis) < items[b].centre(axis); });
        else
            std::nth_element(
                order.begin() + mid, order.begin() + half, order.begin() + end,
                [&](int a, int b) { return items[a].mid[posAxis] < items[b].mid[posAxis]; });
    };
    int bestAxis = 0;
    double bestCost = 1e300;
    for (int axis = 0; axis < 4; ++axis) {
        partitionOn(axis);
        double cost = splitCost(order, mid, half) + splitCost(order, half, end);
        if (cost < bestCost) {
            bestCost = cost;
            bestAxis = axis;
        }
    }
    if (bestAxis != 3) partitionOn(bestAxis);
    return half;
}

double EdgeTree::splitCost(const std::vector<int>& order, int from, int to) const {
    const auto& items = mItems;
    double lo[3] = {1e300, 1e300, 1e300}, hi[3] = {-1e300, -1e300, -1e300};
    Box3 box;
    for (int i = from; i < to; ++i) {
        for (int k = 0; k < 3; ++k) {
            lo[k] = std::min(lo[k], items[order[i]].lo[k]);
            hi[k] = std::max(hi[k], items[order[i]].hi[k]);
        }
        box.extend(items[order[i]].mid);
    }
    double normalSpan = (hi[0] - lo[0]) + (hi[1] - lo[1]) + (hi[2] - lo[2]);
    return normalSpan * mRootSize + glm::length(box.hi - box.lo);
}

// ---------------------------------------------------------------------------------------------
// EdgeTree traversal

template <typename Culled, typename Visit>
void EdgeTree::walk(Culled&& culled, Visit&& visit, EdgeTreeStats* stats) const {
    long long visited = 0, tested = 0;
    int stack[128];
    int top = 0;
    stack[top++] = 0;
    while (top > 0) {
        const Node& node = mNodes[stack[--top]];
        ++visited;
        if (culled(node)) continue;
        const int last = node.child < 0 ? node.end : node.begin + node.stored;
        visit(node.begin, last);
        tested += last - node.begin;
        if (node.child >= 0) {
            stack[top++] = node.child;
            stack[top++] = node.child + 1;
        }
    }
    if (stats) {
        stats->nodesVisited += visited;
        stats->edgesTested += tested;
    }
}

std::size_t EdgeTree::silhouetteRecords(const Vec3& eye, std::vector<int>& records,
                                        EdgeTreeStats* stats) const {
    if (mRecords.empty()) return 0;
    const double e[3] = {eye.x, eye.y, eye.z};
    std::size_t found = 0;
    // Interval form of eq. 1: [N]·(e − c) − [d] over every face below; culled when it excludes
    // zero (all front or all back).
    const auto culled = [&](const Node& node) {
        double lo = 0, hi = 0, mag = 0;
        for (int k = 0; k < 3; ++k) {
            double w = e[k] - node.c[k];
            double a = node.nLo[k] * w, b = node.nHi[k] * w;
            lo += std::min(a, b);
            hi += std::max(a, b);
            mag += std::abs(w) + std::abs(node.c[k]);
        }
        double tol = 1e-12 * (mag + std::abs(node.dLo) + std::abs(node.dHi));
        return lo - node.dHi > tol || hi - node.dLo < -tol;
    };
    const auto visit = [&](int begin, int last) {
        // Every tested record is written and the count advances on silhouettes only: about a
        // third of the tested edges are silhouettes, in no pattern a branch could predict.
        const std::size_t room = found + static_cast<std::size_t>(last - begin);
        if (records.size() < room) records.resize(std::max(room, 2 * records.size()));
        int* out = records.data();
        for (int i = begin; i < last; ++i) {
            const Record& r = mRecords[i];
            bool front0 = r.n0[0] * e[0] + r.n0[1] * e[1] + r.n0[2] * e[2] - r.d0 > 0;
            bool front1 = r.n1[0] * e[0] + r.n1[1] * e[1] + r.n1[2] * e[2] - r.d1 > 0;
            out[found] = i;
            found += front0 != front1;  // eq. 1
        }
    };
    walk(culled, visit, stats);
    return found;
}

void EdgeTree::findSilhouettes(const Vec3& eye, std::vector<int>& out, EdgeTreeStats* stats) const {
    for (int id : mMesh->boundaryEdges()) out.push_back(id);
    thread_local std::vector<int> records;
    const std::size_t n = silhouetteRecords(eye, records, stats);
    for (std::size_t k = 0; k < n; ++k) out.push_back(mRecords[records[k]].edge);
}

void EdgeTree::findSilhouettes(const Vec3& eye, std::vector<int>& out, std::vector<Vec3>& ends,
                               EdgeTreeStats* stats) const {
    const EdgeMesh& m = *mMesh;
    for (int id : m.boundaryEdges()) {
        out.push_back(id);
        ends.push_back(m.positions()[m.edges()[id].v0]);
        ends.push_back(m.positions()[m.edges()[id].v1]);
    }
    thread_local std::vector<int> records;
    const std::size_t n = silhouetteRecords(eye, records, stats);
    for (std::size_t k = 0; k < n; ++k) {
        const std::size_t i = static_cast<std::size_t>(records[k]);
        out.push_back(mRecords[i].edge);
        ends.push_back(mRecordEnds[2 * i]);
        ends.push_back(mRecordEnds[2 * i + 1]);
    }
}

void EdgeTree::findSilhouetteCandidates(const std::vector<Vec3>& region, std::vector<int>& out,
                                        EdgeTreeStats* stats) const {
    for (int id : mMesh->boundaryEdges()) out.push_back(id);
    if (mRecords.empty() || region.empty()) return;
    Box3 box;
    for (const Vec3& p : region) box.extend(p);
    // Interval eye: [N]·([e] − c) − [d].
    const auto culled = [&](const Node& node) {
        double lo = 0, hi = 0, mag = 0;
        for (int k = 0; k < 3; ++k) {
            double w0 = box.lo[k] - node.c[k], w1 = box.hi[k] - node.c[k];
            double p[4] = {node.nLo[k] * w0, node.nLo[k] * w1, node.nHi[k] * w0, node.nHi[k] * w1};
            lo += std::min(std::min(p[0], p[1]), std::min(p[2], p[3]));
            hi += std::max(std::max(p[0], p[1]), std::max(p[2], p[3]));
            mag += std::max(std::abs(w0), std::abs(w1)) + std::abs(node.c[k]);
        }
        double tol = 1e-12 * (mag + std::abs(node.dLo) + std::abs(node.dHi));
        return lo - node.dHi > tol || hi - node.dLo < -tol;
    };
    const auto visit = [&](int begin, int last) {
        for (int i = begin; i < last; ++i) {
            const Record& r = mRecords[i];
            bool allFront = true, allBack = true;
            for (const Vec3& v : region) {
                bool f0 = r.n0[0] * v.x + r.n0[1] * v.y + r.n0[2] * v.z - r.d0 > 0;
                bool f1 = r.n1[0] * v.x + r.n1[1] * v.y + r.n1[2] * v.z - r.d1 > 0;
                allFront = allFront && f0 && f1;
                allBack = allBack && !f0 && !f1;
            }
            if (!allFront && !allBack) out.push_back(r.edge);
        }
    };
    walk(culled, visit, stats);
}

std::string EdgeTree::toString() const {
    std::ostringstream s;
    s << "EdgeTree{" << mMesh->toString() << ", " << mNodes.size() << " nodes, leaf size "
      << mLeafSize << "}";
    return s.str();
}

}  // namespace penumbra
