// BoxTree against brute force: over random boxes (some empty, many equal, some degenerate to a
// point), a query returns every box that overlaps the query box, each once, and nothing that
// is empty; the tree's structure holds (leaves of at most 8, every node's box holds its
// items', the items are the non-empty boxes); visit() prunes by its predicate; visitLeaves()
// gives the leaves' ranges of items() in tree order.
#include "render/box_tree.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <set>
#include <vector>

#include "core/random.h"

namespace penumbra {
namespace {

Box3 randomBox(SplitMix& random, double size) {
    const Vec3 lo(random.next(), random.next(), random.next());
    const Vec3 extent = size * Vec3(random.next(), random.next(), random.next());
    return Box3{lo, lo + extent};
}

std::vector<Box3> randomBoxes(std::uint64_t seed, int count) {
    SplitMix random(seed);
    std::vector<Box3> boxes;
    for (int i = 0; i < count; ++i) {
        const double kind = random.next();
        if (kind < 0.05) {
            boxes.push_back(Box3{});  // empty
        } else if (kind < 0.15 && !boxes.empty()) {
            boxes.push_back(boxes.back());  // equal to the one before
        } else if (kind < 0.2) {
            const Vec3 p(random.next(), random.next(), random.next());
            boxes.push_back(Box3{p, p});  // a point
        } else {
            boxes.push_back(randomBox(random, 0.1));
        }
    }
    return boxes;
}

TEST(BoxTree, QueriesFindEveryOverlappingBoxOnce) {
    for (const int count : {0, 1, 8, 9, 100, 2000}) {
        const std::vector<Box3> boxes = randomBoxes(7 + count, count);
        const BoxTree tree(boxes);
        SplitMix random(99);
        for (int q = 0; q < 200; ++q) {
            const Box3 query = randomBox(random, q % 2 ? 0.3 : 0.02);
            std::vector<int> found;
            tree.query(query, found);
            const std::set<int> unique(found.begin(), found.end());
            EXPECT_EQ(unique.size(), found.size()) << "no box twice";
            for (int i = 0; i < count; ++i) {
                if (boxes[i].overlaps(query)) {
                    EXPECT_TRUE(unique.count(i)) << "box " << i << " of " << count;
                }
                if (boxes[i].empty()) {
                    EXPECT_FALSE(unique.count(i)) << "empty box " << i;
                }
            }
        }
        std::vector<int> none;
        tree.query(Box3{}, none);
        EXPECT_TRUE(none.empty()) << "an empty query box";
    }
}

TEST(BoxTree, StructureHoldsItsItems) {
    const std::vector<Box3> boxes = randomBoxes(3, 1000);
    const BoxTree tree(boxes);
    std::vector<int> items = tree.items();
    std::sort(items.begin(), items.end());
    std::vector<int> nonEmpty;
    for (int i = 0; i < static_cast<int>(boxes.size()); ++i)
        if (!boxes[i].empty()) nonEmpty.push_back(i);
    EXPECT_EQ(items, nonEmpty);
    ASSERT_FALSE(tree.nodes().empty());
    int leafItems = 0;
    for (const BoxTree::Node& node : tree.nodes()) {
        for (int i = node.begin; i < node.end; ++i)
            EXPECT_TRUE(node.box.contains(boxes[tree.items()[i]]));
        if (node.child < 0) {
            EXPECT_LE(node.end - node.begin, 8);
            leafItems += node.end - node.begin;
        } else {
            const BoxTree::Node& a = tree.nodes()[node.child];
            const BoxTree::Node& b = tree.nodes()[node.child + 1];
            EXPECT_EQ(a.begin, node.begin);
            EXPECT_EQ(a.end, b.begin);
            EXPECT_EQ(b.end, node.end);
        }
    }
    EXPECT_EQ(leafItems, static_cast<int>(nonEmpty.size())) << "every item in one leaf";
}

TEST(BoxTree, VisitPrunesByItsPredicate) {
    const std::vector<Box3> boxes = randomBoxes(5, 500);
    const BoxTree tree(boxes);
    std::vector<int> out;
    tree.visit([](const Box3&) { return false; }, out);
    EXPECT_TRUE(out.empty());
    tree.visit([](const Box3&) { return true; }, out);
    std::sort(out.begin(), out.end());
    std::vector<int> items = tree.items();
    std::sort(items.begin(), items.end());
    EXPECT_EQ(out, items) << "everything, once";
    // A half-space predicate (x ≤ 0.5) finds every box reaching into it.
    out.clear();
    tree.visit([](const Box3& b) { return b.lo.x <= 0.5; }, out);
    const std::set<int> found(out.begin(), out.end());
    for (int i = 0; i < static_cast<int>(boxes.size()); ++i) {
        if (!boxes[i].empty() && boxes[i].lo.x <= 0.5) {
            EXPECT_TRUE(found.count(i)) << i;
        }
    }
}

TEST(BoxTree, VisitLeavesGivesTreeOrderRangesFrontToBack) {
    const std::vector<Box3> boxes = randomBoxes(9, 700);
    const BoxTree tree(boxes);
    // Everything: the leaves tile items() in order, the first child first.
    int next = 0;
    tree.visitLeaves([](const Box3&) { return true; },
                     [&](int begin, int end) {
                         EXPECT_EQ(begin, next);
                         EXPECT_LT(begin, end);
                         EXPECT_LE(end - begin, 8);
                         next = end;
                     });
    EXPECT_EQ(next, static_cast<int>(tree.items().size()));
    // A box query through the positions finds what brute force finds among the boxes.
    const Box3 query{Vec3(0.2, 0.3, 0.1), Vec3(0.5, 0.6, 0.4)};
    std::set<int> found;
    tree.visitLeaves([&](const Box3& b) { return b.overlaps(query); },
                     [&](int begin, int end) {
                         for (int k = begin; k < end; ++k) {
                             const int i = tree.items()[k];
                             if (boxes[i].overlaps(query)) {
                                 EXPECT_TRUE(found.insert(i).second) << "once";
                             }
                         }
                     });
    std::set<int> expected;
    for (int i = 0; i < static_cast<int>(boxes.size()); ++i)
        if (boxes[i].overlaps(query)) expected.insert(i);
    EXPECT_FALSE(expected.empty());
    EXPECT_EQ(found, expected);
}

}  // namespace
}  // namespace penumbra
