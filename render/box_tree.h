#pragma once
// Axis-aligned boxes and a static bounding-volume hierarchy over them: what the edge finder's
// event pairs, the exact irradiance's blockers and the interpolant mesher's wedges are found
// through.
//
// Index: Box3 · BoxTree

#include <string>
#include <vector>

#include "core/math.h"

namespace penumbra {

/// Axis-aligned box; empty when lo > hi.
struct Box3 {
    Vec3 lo{1e300};
    Vec3 hi{-1e300};
    void extend(const Vec3& p) {
        lo = glm::min(lo, p);
        hi = glm::max(hi, p);
    }
    void extend(const Box3& b) {
        lo = glm::min(lo, b.lo);
        hi = glm::max(hi, b.hi);
    }
    bool empty() const { return lo.x > hi.x; }
    /// Both non-empty and sharing at least a point.
    bool overlaps(const Box3& b) const {
        return !empty() && !b.empty() && lo.x <= b.hi.x && b.lo.x <= hi.x && lo.y <= b.hi.y &&
               b.lo.y <= hi.y && lo.z <= b.hi.z && b.lo.z <= hi.z;
    }
    /// `b` lies inside this box (an empty `b` always does).
    bool contains(const Box3& b) const {
        return b.empty() || (!empty() && lo.x <= b.lo.x && lo.y <= b.lo.y && lo.z <= b.lo.z &&
                             b.hi.x <= hi.x && b.hi.y <= hi.y && b.hi.z <= hi.z);
    }
    Vec3 centre() const { return 0.5 * (lo + hi); }
    Vec3 corner(int i) const {
        return {(i & 1) ? hi.x : lo.x, (i & 2) ? hi.y : lo.y, (i & 4) ? hi.z : lo.z};
    }
    /// Box of the 8 corners mapped by `m` (affine).
    Box3 transformed(const Mat4& m) const;
    std::string toString() const;
};

/// A bounding-volume hierarchy over a list of boxes, built top down: each node splits its
/// boxes at the median of their centres along the longest axis of the centres' extent,
/// leaves hold up to 8. Empty boxes are left out.
class BoxTree {
public:
    struct Node {
        Box3 box;
        int begin = 0, end = 0;  ///< range of items() below the node
        int child = -1;          ///< children child and child + 1; -1 for a leaf
    };

    BoxTree() = default;
    explicit BoxTree(const std::vector<Box3>& boxes) { build(boxes); }
    void build(const std::vector<Box3>& boxes);

    /// Appends, depth first (the second child first), the indices of the boxes in leaves
    /// whose node boxes all pass `overlaps(const Box3&)`; the boxes themselves are not tested.
    template <class Overlaps>
    void visit(Overlaps&& overlaps, std::vector<int>& out) const {
        walk<false>(overlaps, [&](int begin, int end) {
            for (int i = begin; i < end; ++i) out.push_back(mItems[i]);
        });
    }
    /// Calls `leaf(begin, end)` with the positions [begin, end) in items() of every leaf whose
    /// node boxes all pass `overlaps(const Box3&)`, the first child first (the tree's own
    /// order): a caller that stores its data in tree order (permuted by items()) reads it
    /// front to back.
    template <class Overlaps, class Leaf>
    void visitLeaves(Overlaps&& overlaps, Leaf&& leaf) const {
        walk<true>(overlaps, leaf);
    }
    /// visit() with the nodes that overlap `box`.
    void query(const Box3& box, std::vector<int>& out) const {
        if (box.empty()) return;
        visit([&](const Box3& b) { return b.overlaps(box); }, out);
    }

    const std::vector<Node>& nodes() const { return mNodes; }
    /// Box indices in tree order.
    const std::vector<int>& items() const { return mItems; }

private:
    /// The depth-first walk behind visit() and visitLeaves(): `leaf(begin, end)` for each leaf
    /// whose node boxes all pass `overlaps`, children in order or reversed.
    template <bool kFirstChildFirst, class Overlaps, class Leaf>
    void walk(Overlaps& overlaps, Leaf&& leaf) const {
        if (mNodes.empty()) return;
        int stack[128];  // a median split halves the items: depth ≤ log2(n) + 1
        int top = 0;
        stack[top++] = 0;
        while (top > 0) {
            const Node& node = mNodes[stack[--top]];
            if (!overlaps(node.box)) continue;
            if (node.child < 0) {
                leaf(node.begin, node.end);
            } else {
                stack[top++] = kFirstChildFirst ? node.child + 1 : node.child;
                stack[top++] = kFirstChildFirst ? node.child : node.child + 1;
            }
        }
    }

    std::vector<Node> mNodes;
    std::vector<int> mItems;
};

}  // namespace penumbra
