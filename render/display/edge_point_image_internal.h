#pragma once
// The edge-and-point image's internals shared by its two translation units (edge_point_image.cpp:
// points, edges, classification, reachability; epi_reconstruction.cpp: the filters and the
// reconstruction): the §5.3 filter weights, the 5×5 propagation order, the fused reachability
// table, SIMD quads, row loops, bands and edge codes. Include only from those two files.

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <array>
#include <bit>
#include <cmath>
#include <cstdint>

#include "render/display/edge_point_image.h"
#include "render/display/reachability.h"

#if defined(__SSE2__)
#include <immintrin.h>
#endif

namespace penumbra::epi_detail {

// ---- Filter weights and 5×5 propagation order ---------------------------------------------

/// §5.3 interpolation filter: separable and sharply peaked, w(dx, dy) = g(dx)·g(dy) with
/// g(k) = 4^−|k| (the paper's exact weights are in its Figure 6, which we do not have; it
/// notes that reconstruction is insensitive to them as long as the filter is peaked).
constexpr float kFilter[6] = {1.0f, 0.25f, 0.0625f, 0.015625f, 0.00390625f, 0.0009765625f};
inline float filterWeight(int dx, int dy) { return kFilter[std::abs(dx)] * kFilter[std::abs(dy)]; }

constexpr uint32_t kAllNeighbours = (1u << 24) - 1;
/// Set in a pixel's reachability word when its whole 5×5 neighbourhood is empty: the plain
/// interpolation is then exact and reused.
constexpr uint32_t kAllEmptyFlag = 1u << 24;

/// Bit of the 8-bit 3×3 mask for offset (dx, dy) ≠ (0, 0).
constexpr int ringBit(int dx, int dy) {
    int k = (dy + 1) * 3 + (dx + 1);
    return k < 4 ? k : k - 1;
}

/// 5×5 cell index ((dy + 2)·5 + dx + 2) of each bit of the 24-bit mask, and of the 8-bit ring.
constexpr std::array<int8_t, 24> kBitCell = {0,  1,  2,  3,  4,  5,  6,  7,  8,  9,  10, 11,
                                             13, 14, 15, 16, 17, 18, 19, 20, 21, 22, 23, 24};
constexpr std::array<int8_t, 8> kRingCell = {6, 7, 8, 11, 13, 16, 17, 18};

/// One step of §5.2's outward propagation: the target offset and its one or two
/// predecessors one step closer to the centre (always moving away from the centre).
struct PropagationStep {
    int8_t target = 0;
    int8_t count = 0;
    std::array<int8_t, 2> pred{};
    std::array<NeighbourDirection, 2> dir{};
};

constexpr std::array<PropagationStep, 24> makePropagationOrder() {
    std::array<PropagationStep, 24> steps{};
    int n = 0;
    for (int distance = 1; distance <= 4; ++distance) {
        for (int dy = -2; dy <= 2; ++dy) {
            for (int dx = -2; dx <= 2; ++dx) {
                if ((dx < 0 ? -dx : dx) + (dy < 0 ? -dy : dy) != distance) continue;
                PropagationStep step{};
                step.target = static_cast<int8_t>((dy + 2) * 5 + dx + 2);
                if (dx != 0) {
                    int px = dx - (dx > 0 ? 1 : -1);
                    step.pred[step.count] = static_cast<int8_t>((dy + 2) * 5 + px + 2);
                    step.dir[step.count++] =
                        dx > 0 ? NeighbourDirection::Right : NeighbourDirection::Left;
                }
                if (dy != 0) {
                    int py = dy - (dy > 0 ? 1 : -1);
                    step.pred[step.count] = static_cast<int8_t>((py + 2) * 5 + dx + 2);
                    step.dir[step.count++] =
                        dy > 0 ? NeighbourDirection::Down : NeighbourDirection::Up;
                }
                steps[n++] = step;
            }
        }
    }
    return steps;
}

/// The 24 steps, by increasing distance from the centre.
constexpr std::array<PropagationStep, 24> kPropagationOrder = makePropagationOrder();

/// §5.2 neighbour lookup and chaining fused into one 16 KB table:
/// [direction << 12 | (mask centre→q) << 8 | code(q) << 4 | code(p)] → mask centre→p through q.
inline const std::array<uint8_t, 16384>& fusedHopTable() {
    static const std::array<uint8_t, 16384> table = [] {
        std::array<uint8_t, 16384> t{};
        for (int d = 0; d < 4; ++d) {
            for (int via = 0; via < 16; ++via) {
                for (int codes = 0; codes < 256; ++codes) {
                    const uint8_t hop = neighbourReachabilityTable()[d][codes];
                    t[(d << 12) | (via << 8) | codes] =
                        chainReachability(static_cast<uint8_t>(via), hop);
                }
            }
        }
        return t;
    }();
    return table;
}

/// 4-wide float (colour·w, w) arithmetic for the filters: SSE where available.
#if defined(__SSE2__)
using Quad = __m128;
inline Quad loadQuad(const glm::vec4& v) { return _mm_loadu_ps(&v.x); }
inline void storeQuad(glm::vec4& v, Quad q) { _mm_storeu_ps(&v.x, q); }
inline Quad addQuad(Quad a, Quad b) { return _mm_add_ps(a, b); }
inline Quad scaleQuad(Quad a, float w) { return _mm_mul_ps(a, _mm_set1_ps(w)); }
inline glm::vec4 toVec4(Quad q) {
    glm::vec4 v;
    _mm_storeu_ps(&v.x, q);
    return v;
}
#else
using Quad = glm::vec4;
inline Quad loadQuad(const glm::vec4& v) { return v; }
inline void storeQuad(glm::vec4& v, Quad q) { v = q; }
inline Quad addQuad(Quad a, Quad b) { return a + b; }
inline Quad scaleQuad(Quad a, float w) { return a * w; }
inline glm::vec4 toVec4(Quad q) { return q; }
#endif

/// body(y) for y in [0, height): rows in parallel, or in order when !parallel.
template <typename F>
void forRows(bool parallel, int height, F&& body) {
    if (!parallel) {
        for (int y = 0; y < height; ++y) body(y);
        return;
    }
    tbb::parallel_for(tbb::blocked_range<int>(0, height, 8), [&](const tbb::blocked_range<int>& r) {
        for (int y = r.begin(); y < r.end(); ++y) body(y);
    });
}

inline bool finite2(const glm::dvec2& p) { return std::isfinite(p.x) && std::isfinite(p.y); }

/// First row of band b of `bands` over `height` rows.
inline int bandStart(int height, int bands, int b) {
    return static_cast<int>(static_cast<long long>(height) * b / bands);
}

/// The band holding row y (clamped to the image).
inline int bandOfRow(int height, int bands, double y) {
    if (!(y > 0.0)) return 0;  // also NaN
    if (!(y < height)) return bands - 1;
    const int row = static_cast<int>(y);
    int b = static_cast<int>(static_cast<long long>(row) * bands / height);
    while (b + 1 < bands && row >= bandStart(height, bands, b + 1)) ++b;
    while (b > 0 && row < bandStart(height, bands, b)) --b;
    return b;
}

/// Edge code from the four boundary masks of a cell with n pieces per side (top and bottom
/// bits along +x, left and right along +y), §4.5 "edge reconstruction": no intersection →
/// empty; exactly two on different sides → simple; otherwise complex.
/// Bits set in a byte (a table: without -mpopcnt std::popcount is a library call).
constexpr std::array<uint8_t, 256> kBitCount = [] {
    std::array<uint8_t, 256> t{};
    for (int i = 0; i < 256; ++i) t[i] = static_cast<uint8_t>((i & 1) + t[i / 2]);
    return t;
}();

inline uint16_t codeFromMasks(unsigned top, unsigned right, unsigned bottom, unsigned left, int n) {
    // Masks have at most 8 bits (n ≤ 8).
    const int total = kBitCount[top & 255] + kBitCount[right & 255] + kBitCount[bottom & 255] +
                      kBitCount[left & 255];
    if (total == 0) return kEdgeCodeEmpty;
    if (total != 2) return kEdgeCodeComplex;
    int positions[2];
    int found = 0;
    // Boundary positions run clockwise: bottom and left masks count against it.
    if (top) positions[found++] = std::countr_zero(top);
    if (right) positions[found++] = n + std::countr_zero(right);
    if (bottom) positions[found++] = 2 * n + (n - 1 - std::countr_zero(bottom));
    if (left) positions[found++] = 3 * n + (n - 1 - std::countr_zero(left));
    if (found != 2) return kEdgeCodeComplex;  // both on one side
    return makeEdgeCode(positions[0], positions[1], n);
}

}  // namespace penumbra::epi_detail
