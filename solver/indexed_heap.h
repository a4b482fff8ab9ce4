#pragma once
// A binary max-heap over indices 0..n-1 with keys that can be raised or lowered in place:
// the priority structure for "the patch with the largest unshot energy".

#include <cstddef>
#include <vector>

namespace penumbra {

class IndexedMaxHeap {
public:
    IndexedMaxHeap() = default;
    explicit IndexedMaxHeap(std::size_t n) { reset(n); }

    void reset(std::size_t n) {
        mKey.assign(n, 0.0);
        mHeap.resize(n);
        mPos.resize(n);
        for (std::size_t i = 0; i < n; ++i) mHeap[i] = static_cast<int>(i), mPos[i] = i;
    }
    std::size_t size() const { return mHeap.size(); }
    /// Index with the largest key; ties go to the smaller index (deterministic).
    int top() const { return mHeap.empty() ? -1 : mHeap[0]; }
    double key(int index) const { return mKey[index]; }

    /// Sets the key of `index` and restores heap order: O(log n).
    void update(int index, double key) {
        double old = mKey[index];
        mKey[index] = key;
        if (key > old)
            siftUp(mPos[index]);
        else
            siftDown(mPos[index]);
    }
    /// Appends a new index (== previous size) with `key`.
    void push(double key) {
        int index = static_cast<int>(mKey.size());
        mKey.push_back(key);
        mHeap.push_back(index);
        mPos.push_back(mHeap.size() - 1);
        siftUp(mHeap.size() - 1);
    }

private:
    bool before(int a, int b) const { return mKey[a] > mKey[b] || (mKey[a] == mKey[b] && a < b); }
    void place(std::size_t slot, int index) { mHeap[slot] = index, mPos[index] = slot; }
    void siftUp(std::size_t slot) {
        int index = mHeap[slot];
        while (slot > 0) {
            std::size_t parent = (slot - 1) / 2;
            if (!before(index, mHeap[parent])) break;
            place(slot, mHeap[parent]);
            slot = parent;
        }
        place(slot, index);
    }
    void siftDown(std::size_t slot) {
        int index = mHeap[slot];
        std::size_t n = mHeap.size();
        for (;;) {
            std::size_t child = 2 * slot + 1;
            if (child >= n) break;
            if (child + 1 < n && before(mHeap[child + 1], mHeap[child])) ++child;
            if (!before(mHeap[child], index)) break;
            place(slot, mHeap[child]);
            slot = child;
        }
        place(slot, index);
    }

    std::vector<double> mKey;
    std::vector<int> mHeap;
    std::vector<std::size_t> mPos;
};

}  // namespace penumbra
