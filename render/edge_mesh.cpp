#include "render/edge_mesh.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <sstream>
#include <unordered_map>

namespace penumbra {

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

}  // namespace penumbra
