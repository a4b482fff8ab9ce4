#pragma once
// The indices of a range that satisfy a predicate, gathered in parallel and returned in
// ascending order: a sparse pass over a large per-point array (the render cache's points)
// without a serial scan of all of it.

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cstddef>
#include <vector>

namespace penumbra {

/// The i in [0, n) with pred(i), ascending. `pred` must only read: it runs on several threads.
template <class Pred>
std::vector<int> indicesWhere(std::size_t n, Pred pred) {
    constexpr std::size_t kChunk = 1 << 15;
    const std::size_t chunks = (n + kChunk - 1) / kChunk;
    std::vector<std::vector<int>> found(chunks);
    tbb::parallel_for(std::size_t(0), chunks, [&](std::size_t c) {
        for (std::size_t i = c * kChunk; i < std::min(n, (c + 1) * kChunk); ++i)
            if (pred(i)) found[c].push_back(static_cast<int>(i));
    });
    std::vector<int> out;
    for (const auto& f : found) out.insert(out.end(), f.begin(), f.end());
    return out;
}

}  // namespace penumbra
