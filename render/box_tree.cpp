// Box3 and BoxTree (box_tree.h).
#include "render/box_tree.h"

#include <algorithm>
#include <sstream>

namespace penumbra {

Box3 Box3::transformed(const Mat4& m) const {
    Box3 out;
    if (empty()) return out;
    for (int i = 0; i < 8; ++i) out.extend(Vec3(m * glm::dvec4(corner(i), 1.0)));
    return out;
}

std::string Box3::toString() const {
    std::ostringstream s;
    s << "Box3{(" << lo.x << ' ' << lo.y << ' ' << lo.z << ") - (" << hi.x << ' ' << hi.y << ' '
      << hi.z << ")}";
    return s.str();
}

void BoxTree::build(const std::vector<Box3>& boxes) {
    mNodes.clear();
    mItems.clear();
    for (int i = 0; i < static_cast<int>(boxes.size()); ++i)
        if (!boxes[i].empty()) mItems.push_back(i);
    if (mItems.empty()) return;
    mNodes.reserve(2 * mItems.size() / 4 + 2);
    // Top-down, median split of the box centres on the longest axis; leaves of up to 8.
    struct Task {
        int node, begin, end;
    };
    std::vector<Task> stack = {{0, 0, static_cast<int>(mItems.size())}};
    mNodes.push_back({});
    while (!stack.empty()) {
        Task t = stack.back();
        stack.pop_back();
        Box3 box, centres;
        for (int i = t.begin; i < t.end; ++i) {
            box.extend(boxes[mItems[i]]);
            centres.extend(boxes[mItems[i]].centre());
        }
        mNodes[t.node] = {box, t.begin, t.end, -1};
        if (t.end - t.begin <= 8) continue;
        Vec3 ext = centres.hi - centres.lo;
        int axis = ext.x > ext.y ? (ext.x > ext.z ? 0 : 2) : (ext.y > ext.z ? 1 : 2);
        int mid = t.begin + (t.end - t.begin) / 2;
        std::nth_element(mItems.begin() + t.begin, mItems.begin() + mid, mItems.begin() + t.end,
                         [&](int a, int b) {
                             return boxes[a].lo[axis] + boxes[a].hi[axis] <
                                    boxes[b].lo[axis] + boxes[b].hi[axis];
                         });
        int child = static_cast<int>(mNodes.size());
        mNodes[t.node].child = child;
        mNodes.push_back({});
        mNodes.push_back({});
        stack.push_back({child, t.begin, mid});
        stack.push_back({child + 1, mid, t.end});
    }
}

}  // namespace penumbra
