// Index: EdgeTree build · EdgeTree traversal (point eye, polygon eye)
#include "render/display/edge_tree.h"

#include <algorithm>
#include <cmath>
#include <sstream>

namespace penumbra {

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
