// The edge-and-point image (Bala, Walter, Greenberg 2003 §4–5); see edge_point_image.h.
//
// Index: filter weights and 5×5 propagation order · toString · construction · points (§4.3) ·
// depth filter (§4.5) · edge rasterization (§4.5) · classification (§4.1, §4.2, §5.1) ·
// reachability (§5.2) · interpolation (§5.3) · anti-aliasing (§5.3) · complex filter (§5.4) ·
// reconstruct · classification image

#include "render/edge_point_image.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <bit>
#include <chrono>
#include <cmath>
#include <limits>
#include <numeric>
#include <sstream>
#include <stdexcept>

#include "core/timing.h"

#if defined(__SSE2__)
#include <immintrin.h>
#endif

namespace penumbra {

namespace {

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
const std::array<uint8_t, 16384>& fusedHopTable() {
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

bool finite2(const glm::dvec2& p) { return std::isfinite(p.x) && std::isfinite(p.y); }

/// First row of band b of `bands` over `height` rows.
int bandStart(int height, int bands, int b) {
    return static_cast<int>(static_cast<long long>(height) * b / bands);
}

/// The band holding row y (clamped to the image).
int bandOfRow(int height, int bands, double y) {
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

uint16_t codeFromMasks(unsigned top, unsigned right, unsigned bottom, unsigned left, int n) {
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

}  // namespace

// ---- toString -------------------------------------------------------------------------------

std::string ScreenEdge::toString() const {
    std::ostringstream out;
    const char* kinds[] = {"silhouette", "sharp", "shadow"};
    out << "ScreenEdge{" << kinds[static_cast<int>(kind)] << " (" << a.x << ", " << a.y
        << ") depth " << depthA << " -> (" << b.x << ", " << b.y << ") depth " << depthB << "}";
    return out.str();
}

std::string ScreenPoint::toString() const {
    std::ostringstream out;
    out << "ScreenPoint{(" << position.x << ", " << position.y << ") depth " << depth << " colour ("
        << colour.x << ", " << colour.y << ", " << colour.z << ") age " << age << " trust "
        << static_cast<int>(trust) << "}";
    return out.str();
}

std::string EpiStageTimes::toString() const {
    std::ostringstream out;
    out.precision(3);
    out << std::fixed << "points " << pointsMs << " ms, depth filter " << depthFilterMs
        << " ms, rasterize " << rasterizeMs << " ms, classify " << classifyMs
        << " ms, reachability " << reachabilityMs << " ms, interpolate " << interpolateMs
        << " ms, anti-alias " << antiAliasMs << " ms, complex filter " << complexFilterMs
        << " ms, smooth " << smoothMs << " ms (reconstruct " << reconstructMs() << " ms)";
    return out.str();
}

std::string EpiOptions::toString() const {
    std::ostringstream out;
    out << "EpiOptions{cull " << cullOccludedEdges << " slack " << depthSlack << "+" << densitySlack
        << " antiAlias " << antiAlias << " complexFilter " << complexFilter << " shortcut "
        << complexFilterShortcut << " dense " << denseComplexLimit << " radius " << denseRadius
        << " smooth " << smoothRadius << " ownPointPrior " << ownPointPrior << "}";
    return out.str();
}

// ---- Construction -------------------------------------------------------------------------

EdgePointImage::EdgePointImage(int width, int height, EpiOptions options)
    : mWidth(width), mHeight(height), mOptions(options) {
    if (width <= 0 || height <= 0) {
        throw std::invalid_argument("EdgePointImage: size must be positive, got " +
                                    std::to_string(width) + "x" + std::to_string(height));
    }
    const size_t n = static_cast<size_t>(width) * height;
    mSampleColour.assign(n, glm::vec3(0.0f));
    mSampleDepth.assign(n, std::numeric_limits<double>::infinity());
    mSamplePos.assign(n, 0xFF);
    mSampleTrust.assign(n, 0);
    mUsable.assign(n, 0);
    mBlocksX = (width + 3) / 4;
    mBlocksY = (height + 3) / 4;
    mBlockDepth.assign(static_cast<size_t>(mBlocksX) * mBlocksY,
                       std::numeric_limits<float>::infinity());
    mHorizontal.assign(static_cast<size_t>(height + 1) * width, 0);
    mVertical.assign(static_cast<size_t>(height) * (width + 1), 0);
    mHorizontalMid.assign(n, 0);
    mVerticalMid.assign(n, 0);
    mEdgeCode.assign(n, kEdgeCodeEmpty);
    mNeighbourCode.assign(n, kNeighbourTypeEmpty);
    const size_t padded = static_cast<size_t>(width + 4) * (height + 4);
    mPaddedCode.assign(padded, kNeighbourTypeComplex);
    mReach.assign(n, kAllNeighbours | kAllEmptyFlag);
    mSecondaryReach.assign(n, 0);
    mReachLower.assign(n, 0);
    mPartnerReach.assign(n, 0);
    mPaddedAll.assign(padded, glm::vec4(0.0f));
    mPaddedUsable.assign(padded, glm::vec4(0.0f));
    mRowSums.assign(static_cast<size_t>(width) * (height + 4), glm::vec4(0.0f));
    mPlain.assign(n, glm::vec3(0.0f));
    mPlainWeight.assign(n, 0.0f);
    mPrimary.assign(n, glm::vec3(0.0f));
    mNearEdge.assign(padded, 0);
    mWeight.assign(n, 0.0f);
    mSubCode.assign(4 * n, kEdgeCodeComplex);
    mSubType.assign(4 * n, 0);
    mRowCounts.assign(height, {width, 0, 0});
    mPixelCounts = {n, 0, 0};
    // Build the shared tables outside any timed stage.
    (void)EdgeCodeTables::pixel();
    (void)EdgeCodeTables::subpixel();
    (void)neighbourReachabilityTable();
    (void)chainingTable();
    (void)fusedHopTable();
}

void EdgePointImage::build(const std::vector<ScreenEdge>& edges,
                           const std::vector<ScreenPoint>& points) {
    const auto start = std::chrono::steady_clock::now();
    placePoints(points);
    const double pointsMs = msSince(start);
    build(edges);
    mTimes.pointsMs = pointsMs;
}

void EdgePointImage::build(const std::vector<ScreenEdge>& edges) {
    mTimes = {};
    auto start = std::chrono::steady_clock::now();
    filterDepth();
    mTimes.depthFilterMs = msSince(start);

    start = std::chrono::steady_clock::now();
    rasterizeEdges(edges);
    mTimes.rasterizeMs = msSince(start);

    start = std::chrono::steady_clock::now();
    classifyPixels();
    mTimes.classifyMs = msSince(start);
}

// ---- Points (§4.3) ------------------------------------------------------------------------

void EdgePointImage::placePoints(const std::vector<ScreenPoint>& points) {
    // Keep the nearest point that reprojects onto each pixel (§4: "the closest point"); of
    // equal depths the first. Bands of rows take their points in input order, so the result
    // does not depend on the split.
    if (mOptions.parallel && placeSortedPoints(points)) return;
    const int bands = mOptions.parallel ? std::min(mHeight, 8) : 1;
    // Per point its band (0xFF: rejected), computed in parallel; each band then reads one byte
    // per point instead of the point.
    mPointBand.resize(points.size());
    // Per chunk of points, the range of bands it holds: a band skips chunks without its rows
    // (the render cache's points come in row order, so each band reads little else).
    constexpr size_t kChunk = 4096;
    const size_t chunks = (points.size() + kChunk - 1) / kChunk;
    mChunkBands.assign(chunks, {0xFF, 0});
    auto classify = [&](size_t i) {
        const ScreenPoint& p = points[i];
        uint8_t b = 0xFF;
        if (epiKeepsPoint(p, mWidth, mHeight)) {
            b = static_cast<uint8_t>(bandOfRow(mHeight, bands, p.position.y));
            auto& range = mChunkBands[i / kChunk];
            range.first = std::min(range.first, b);
            range.second = std::max(range.second, b);
        }
        mPointBand[i] = b;
    };
    auto band = [&](int b) {
        const size_t lo = index(0, bandStart(mHeight, bands, b));
        const size_t hi = index(0, bandStart(mHeight, bands, b + 1));
        std::fill(mSampleColour.begin() + lo, mSampleColour.begin() + hi, glm::vec3(0.0f));
        std::fill(mSampleDepth.begin() + lo, mSampleDepth.begin() + hi,
                  std::numeric_limits<double>::infinity());
        std::fill(mSamplePos.begin() + lo, mSamplePos.begin() + hi, 0xFF);
        std::fill(mSampleTrust.begin() + lo, mSampleTrust.begin() + hi, 0);
        for (size_t n = 0; n < points.size(); ++n) {
            if (n % kChunk == 0) {
                const auto& range = mChunkBands[n / kChunk];
                if (b < range.first || b > range.second) {
                    n += kChunk - 1;
                    continue;
                }
            }
            if (mPointBand[n] != b) continue;
            const ScreenPoint& p = points[n];
            const int x = static_cast<int>(p.position.x);
            const int y = static_cast<int>(p.position.y);
            const size_t i = index(x, y);
            if (!(p.depth < mSampleDepth[i])) continue;
            mSampleDepth[i] = p.depth;
            mSampleColour[i] = glm::vec3(p.colour);
            mSamplePos[i] = epiSampleCode(p.position);
            mSampleTrust[i] = p.trust;
        }
    };
    if (bands == 1) {
        for (size_t i = 0; i < points.size(); ++i) classify(i);
        band(0);
    } else {
        tbb::parallel_for(size_t(0), chunks, [&](size_t c) {
            for (size_t i = c * kChunk; i < std::min(points.size(), (c + 1) * kChunk); ++i)
                classify(i);
        });
        tbb::parallel_for(0, bands, band);
    }
}

bool EdgePointImage::placeSortedPoints(const std::vector<ScreenPoint>& points) {
    // The render cache hands over at most one point per pixel in pixel order. Then every point
    // is the nearest of its pixel and placement is a scatter: clear, place chunks of points in
    // parallel while checking that the accepted points' pixels strictly increase within and
    // across chunks. Any other input returns false and placePoints() redoes everything (its
    // bands clear their rows first), so the result is always the general rule's.
    forRows(true, mHeight, [&](int y) {
        const size_t lo = index(0, y), hi = lo + mWidth;
        std::fill(mSampleColour.begin() + lo, mSampleColour.begin() + hi, glm::vec3(0.0f));
        std::fill(mSampleDepth.begin() + lo, mSampleDepth.begin() + hi,
                  std::numeric_limits<double>::infinity());
        std::fill(mSamplePos.begin() + lo, mSamplePos.begin() + hi, 0xFF);
        std::fill(mSampleTrust.begin() + lo, mSampleTrust.begin() + hi, 0);
    });
    constexpr size_t kChunk = 4096;
    const size_t chunks = (points.size() + kChunk - 1) / kChunk;
    mChunkRanges.assign(chunks, ChunkRange{});
    tbb::parallel_for(size_t(0), chunks, [&](size_t c) {
        ChunkRange range;
        for (size_t n = c * kChunk; n < std::min(points.size(), (c + 1) * kChunk); ++n) {
            const ScreenPoint& p = points[n];
            if (!epiKeepsPoint(p, mWidth, mHeight)) continue;
            const int x = static_cast<int>(p.position.x);
            const int y = static_cast<int>(p.position.y);
            const long long i = static_cast<long long>(index(x, y));
            if (i <= range.last) {
                range.sorted = false;
                break;
            }
            if (range.first < 0) range.first = i;
            range.last = i;
            mSampleDepth[i] = p.depth;
            mSampleColour[i] = glm::vec3(p.colour);
            mSamplePos[i] = epiSampleCode(p.position);
            mSampleTrust[i] = p.trust;
        }
        mChunkRanges[c] = range;
    });
    long long last = -1;
    for (const ChunkRange& range : mChunkRanges) {
        if (!range.sorted) return false;
        if (range.first < 0) continue;
        if (range.first <= last) return false;
        last = range.last;
    }
    return true;
}

// ---- Depth filter (§4.5) ------------------------------------------------------------------

void EdgePointImage::filterDepth() {
    // A fairly conservative depth per 4×4 block: the maximum point depth plus an offset that
    // grows as the block's point density falls; blocks without points cull nothing.
    forRows(mOptions.parallel, mBlocksY, [&](int by) {
        for (int bx = 0; bx < mBlocksX; ++bx) {
            double maxDepth = -std::numeric_limits<double>::infinity();
            int count = 0;
            int pixels = 0;
            // (Without branches: which pixels hold a point follows no pattern.)
            constexpr double kNone = std::numeric_limits<double>::infinity();
            for (int y = by * 4; y < std::min(mHeight, by * 4 + 4); ++y) {
                for (int x = bx * 4; x < std::min(mWidth, bx * 4 + 4); ++x) {
                    ++pixels;
                    const double d = mSampleDepth[index(x, y)];
                    const bool has = d != kNone;
                    maxDepth = std::max(maxDepth, has ? d : -kNone);
                    count += has;
                }
            }
            float filtered = std::numeric_limits<float>::infinity();
            if (count > 0 && maxDepth > 0.0) {
                const double empty = double(pixels - count) / pixels;
                filtered = static_cast<float>(
                    maxDepth * (1.0 + mOptions.depthSlack + mOptions.densitySlack * empty));
            }
            mBlockDepth[static_cast<size_t>(by) * mBlocksX + bx] = filtered;
        }
    });
}

// ---- Edge rasterization (§4.5) ------------------------------------------------------------

bool edgeMayMark(const ScreenEdge& e, int width, int height) {
    // rasterizeEdge returns at once for non-finite endpoints.
    if (!finite2(e.a) || !finite2(e.b)) return false;
    const double xmin = std::min(e.a.x, e.b.x), xmax = std::max(e.a.x, e.b.x);
    const double ymin = std::min(e.a.y, e.b.y), ymax = std::max(e.a.y, e.b.y);
    // Outside the image. Crossings of lines x = c have x exact and y = a.y + t·d.y with
    // t in [0, 1] (the division of numbers ordered as c between the ends), so y lies between
    // a.y and fl(a.y + fl(b.y − a.y)), within 4 ulp of max(|a.y|, |b.y|) of [ymin, ymax];
    // crossings of lines y = c likewise in x. The slack covers that with a wide margin.
    const double mag = std::max(std::max(std::abs(e.a.x), std::abs(e.b.x)),
                                std::max(std::abs(e.a.y), std::abs(e.b.y)));
    const double slack = 1e-6 + 1e-9 * mag;
    // Marks need x in [0, W) on lines y = c (vertical lines k/2 for k in [0, 2W]) and y in
    // [0, H] on lines x = c (horizontal lines k/2 for k in [0, 2H]).
    const bool inside =
        !(xmax < -slack) & !(xmin > width + slack) & !(ymax < -slack) & !(ymin > height + slack);
    // Lines y = k/2 crossed are k in [⌊2·ymin⌋ + 1, ⌊2·ymax⌋] (rasterizeEdge's kFirst, kLast
    // before clamping), lines x = k/2 likewise: none when both ends share a half-pixel cell.
    // (A degenerate edge is such a case.) (floorExact is std::floor bit for bit, without the
    // libm call.)
    constexpr double kSmall = 1125899906842624.0;  // 2^50
    if (mag < 0.5 * kSmall) {
        // Below 2^50, where a truncation to integer is exact, the floors and the whole
        // decision without branches: whether a tiny edge is kept follows no pattern, so each
        // branch here mispredicted often.
        auto floorSmall = [](double v) {
            const double t = static_cast<double>(static_cast<long long>(v));
            return t - (t > v ? 1.0 : 0.0);
        };
        const bool sameColumn = floorSmall(2.0 * xmin) == floorSmall(2.0 * xmax);
        const bool sameRow = floorSmall(2.0 * ymin) == floorSmall(2.0 * ymax);
        return !(sameColumn & sameRow) & inside;
    }
    if (detail::floorExact(2.0 * xmin) == detail::floorExact(2.0 * xmax) &&
        detail::floorExact(2.0 * ymin) == detail::floorExact(2.0 * ymax))
        return false;
    return inside;
}

void EdgePointImage::rasterizeEdges(const std::vector<ScreenEdge>& edges) {
    // Rows are split into bands; each band owns the boundary lines of its rows (horizontal
    // lines y = k/2 with ⌊k/2⌋ in the band, the last band also y = H; vertical crossings in
    // its rows) and records only their intersections, so bands write disjoint bytes and the
    // masks and the culled count equal a single band's (the serial reference) exactly.
    const int bands = mOptions.parallel ? std::min(mHeight, 16) : 1;
    // Each band's edges, in input order: those whose y extent meets the band's rows with a row
    // of slack either side (all bands for a non-finite extent; rasterizeEdge skips such
    // edges). Binned once (chunks of edges in parallel, counts, offsets, fill) instead of every
    // band scanning every edge.
    constexpr size_t kChunk = 4096;
    const size_t chunks = (edges.size() + kChunk - 1) / kChunk;
    if (bands > 1) {
        mEdgeBands.resize(edges.size());
        mChunkBandCount.assign(chunks * bands, 0);
        // The bands' first rows and each row's band, looked up: bandStart and bandOfRow cost
        // 64-bit divisions, about ten per edge in this pass.
        std::array<int, 17> rowStart{};
        mRowBand.resize(static_cast<size_t>(mHeight));
        for (int b = 0; b <= bands; ++b) rowStart[b] = bandStart(mHeight, bands, b);
        for (int b = 0; b < bands; ++b)
            std::fill(mRowBand.begin() + rowStart[b], mRowBand.begin() + rowStart[b + 1],
                      static_cast<uint8_t>(b));
        auto bandOf = [&](double y) {  // bandOfRow(mHeight, bands, y)
            if (!(y > 0.0)) return 0;  // also NaN
            if (!(y < mHeight)) return bands - 1;
            return static_cast<int>(mRowBand[static_cast<size_t>(y)]);
        };
        auto meets = [&](double ymin, double ymax, int b) {
            return !(ymax < rowStart[b] - 1.0 || ymin > rowStart[b + 1] + 1.0);
        };
        tbb::parallel_for(size_t(0), chunks, [&](size_t c) {
            uint32_t* count = &mChunkBandCount[c * bands];
            for (size_t i = c * kChunk; i < std::min(edges.size(), (c + 1) * kChunk); ++i) {
                const ScreenEdge& e = edges[i];
                const double ymin = std::min(e.a.y, e.b.y), ymax = std::max(e.a.y, e.b.y);
                int lo = 0, hi = bands - 1;
                if (!std::isnan(ymin) && !std::isnan(ymax)) {
                    // The bands meeting [ymin − 1, ymax + 1] are contiguous; search from the
                    // bands of rows a little outside it.
                    lo = bandOf(ymin - 2.0);
                    hi = bandOf(ymax + 2.0);
                    while (lo <= hi && !meets(ymin, ymax, lo)) ++lo;
                    while (hi >= lo && !meets(ymin, ymax, hi)) --hi;
                }
                mEdgeBands[i] = {static_cast<uint8_t>(lo), static_cast<uint8_t>(hi)};
                for (int b = lo; b <= hi; ++b) ++count[b];
            }
        });
        // Offsets: band-major, chunks in order.
        mBandEdgeStart.assign(static_cast<size_t>(bands) + 1, 0);
        size_t offset = 0;
        for (int b = 0; b < bands; ++b) {
            mBandEdgeStart[b] = offset;
            for (size_t c = 0; c < chunks; ++c) {
                const uint32_t n = mChunkBandCount[c * bands + b];
                mChunkBandCount[c * bands + b] = static_cast<uint32_t>(offset - mBandEdgeStart[b]);
                offset += n;
            }
        }
        mBandEdgeStart[bands] = offset;
        mBandEdges.resize(offset);
        tbb::parallel_for(size_t(0), chunks, [&](size_t c) {
            uint32_t* next = &mChunkBandCount[c * bands];
            for (size_t i = c * kChunk; i < std::min(edges.size(), (c + 1) * kChunk); ++i) {
                for (int b = mEdgeBands[i].first; b <= mEdgeBands[i].second; ++b)
                    mBandEdges[mBandEdgeStart[b] + next[b]++] = static_cast<uint32_t>(i);
            }
        });
    }
    std::vector<size_t> culled(bands, 0);
    auto band = [&](int b) {
        const int rowLo = bandStart(mHeight, bands, b);
        const int rowHi = bandStart(mHeight, bands, b + 1);
        const int W = mWidth;
        std::fill(mHorizontal.begin() + static_cast<ptrdiff_t>(rowLo) * W,
                  mHorizontal.begin() + static_cast<ptrdiff_t>(rowHi + (b + 1 == bands)) * W, 0);
        std::fill(mVertical.begin() + static_cast<ptrdiff_t>(rowLo) * (W + 1),
                  mVertical.begin() + static_cast<ptrdiff_t>(rowHi) * (W + 1), 0);
        std::fill(mHorizontalMid.begin() + static_cast<ptrdiff_t>(rowLo) * W,
                  mHorizontalMid.begin() + static_cast<ptrdiff_t>(rowHi) * W, 0);
        std::fill(mVerticalMid.begin() + static_cast<ptrdiff_t>(rowLo) * W,
                  mVerticalMid.begin() + static_cast<ptrdiff_t>(rowHi) * W, 0);
        const int kLineHi = b + 1 == bands ? 2 * mHeight : 2 * rowHi - 1;  // last line k
        if (bands == 1) {
            for (const ScreenEdge& e : edges) rasterizeEdge(e, rowLo, rowHi, kLineHi, culled[b]);
            return;
        }
        for (size_t n = mBandEdgeStart[b]; n < mBandEdgeStart[b + 1]; ++n)
            rasterizeEdge(edges[mBandEdges[n]], rowLo, rowHi, kLineHi, culled[b]);
    };
    if (bands == 1) {
        band(0);
    } else {
        tbb::parallel_for(0, bands, band);
    }
    mCulledIntersections = std::accumulate(culled.begin(), culled.end(), size_t(0));
}

void EdgePointImage::rasterizeEdge(const ScreenEdge& e, int rowLo, int rowHi, int kLineHi,
                                   size_t& culled) {
    const int W = mWidth;
    const int H = mHeight;
    if (!finite2(e.a) || !finite2(e.b)) return;
    const glm::dvec2 d = e.b - e.a;
    if (d.x == 0.0 && d.y == 0.0) return;  // degenerate: crosses nothing

    // Perspective-correct depth along the edge: 1/z is affine in screen space, so at t
    // z = zA·zB / (zB + t·(zA − zB)), and z > b exactly when zA·zB > b·(zB + t·(zA − zB))
    // (both sides positive): the test needs no division. (An empty block's depth is +inf,
    // which culls nothing.)
    const bool cull = mOptions.cullOccludedEdges && std::isfinite(e.depthA) &&
                      std::isfinite(e.depthB) && e.depthA > 0.0 && e.depthB > 0.0;
    const double depthProduct = e.depthA * e.depthB;
    const double depthStep = e.depthA - e.depthB;
    // x and y are in [0, W] × [0, H] here (the callers' range checks), so a shift is the
    // division by the block size.
    auto occluded = [&](double t, double x, double y) {
        if (!cull) return false;
        const int bx = std::min(static_cast<int>(x) >> 2, mBlocksX - 1);
        const int by = std::min(static_cast<int>(y) >> 2, mBlocksY - 1);
        const double block = mBlockDepth[static_cast<size_t>(by) * mBlocksX + bx];
        if (depthProduct > block * (e.depthB + t * depthStep)) {
            ++culled;
            return true;
        }
        return false;
    };

    // Ties are broken by a symbolic perturbation of the edge, (x + ε, y + ε') with
    // ε' ≪ ε: a line y = c is crossed when ymin < c ≤ ymax, a line x = c when
    // xmin < c ≤ xmax, and a crossing exactly on a piece boundary of a vertical line
    // moves up when the edge descends to the right. Edges through pixel corners then
    // give consistent, simple pixels.

    // Horizontal lines y = k/2: even k are pixel boundaries, odd k the half-pixel lines.
    if (d.y != 0.0) {
        const double ymin = std::min(e.a.y, e.b.y);
        const double ymax = std::max(e.a.y, e.b.y);
        // Clamped in floating point first: huge coordinates must not overflow int.
        const double kFirst = std::clamp(detail::floorExact(2.0 * ymin) + 1.0, 0.0, 2.0 * H + 1.0);
        const double kLast = std::clamp(detail::floorExact(2.0 * ymax), -1.0, 2.0 * H);
        // This band's lines only.
        const int k0 = std::max(static_cast<int>(kFirst), 2 * rowLo);
        const int k1 = std::min(static_cast<int>(kLast), kLineHi);
        for (int k = k0; k <= k1; ++k) {
            const double c = 0.5 * k;
            const double t = (c - e.a.y) / d.y;
            const double x = e.a.x + t * d.x;
            if (!(x >= 0.0 && x < W)) continue;
            const int q = static_cast<int>(detail::floorExact(x * 8.0));
            const int i = q >> 3;
            if (occluded(t, x, std::min(c, H - 0.5))) continue;
            const uint8_t bit = static_cast<uint8_t>(1u << (q & 7));
            if ((k & 1) == 0) {
                mHorizontal[static_cast<size_t>(k / 2) * W + i] |= bit;
            } else {
                mHorizontalMid[static_cast<size_t>(k / 2) * W + i] |= bit;
            }
        }
    }
    // Vertical lines x = k/2.
    if (d.x != 0.0) {
        const double xmin = std::min(e.a.x, e.b.x);
        const double xmax = std::max(e.a.x, e.b.x);
        const bool descendsRight = d.x * d.y > 0.0;
        // Clamped in floating point first: huge coordinates must not overflow int.
        const double kFirst = std::clamp(detail::floorExact(2.0 * xmin) + 1.0, 0.0, 2.0 * W + 1.0);
        const double kLast = std::clamp(detail::floorExact(2.0 * xmax), -1.0, 2.0 * W);
        int k0 = static_cast<int>(kFirst);
        int k1 = static_cast<int>(kLast);
        if (d.y != 0.0 && (rowLo > 0 || rowHi < H) && std::abs(d.y) > 1e-9 * std::abs(d.x)) {
            // Lines whose crossing may lie in the band's rows (a pixel of slack either side;
            // the row test below is exact).
            const double slope = d.x / d.y;
            const double xa = e.a.x + (rowLo - 1.0 - e.a.y) * slope;
            const double xb = e.a.x + (rowHi + 1.0 - e.a.y) * slope;
            if (std::isfinite(xa) && std::isfinite(xb)) {
                const double lo = std::clamp(detail::floorExact(2.0 * std::min(xa, xb)) - 1.0, -1.0,
                                             2.0 * W + 1.0);
                const double hi = std::clamp(detail::floorExact(2.0 * std::max(xa, xb)) + 2.0, -1.0,
                                             2.0 * W + 1.0);
                k0 = std::max(k0, static_cast<int>(lo));
                k1 = std::min(k1, static_cast<int>(hi));
            }
        }
        for (int k = k0; k <= k1; ++k) {
            const double c = 0.5 * k;
            const double t = (c - e.a.x) / d.x;
            const double y = e.a.y + t * d.y;
            if (!(y >= 0.0 && y <= H)) continue;
            const double q8 = y * 8.0;
            int q = static_cast<int>(detail::floorExact(q8));
            if (descendsRight && q8 == q) --q;
            if (q < 0 || q >= 8 * H) continue;
            const int j = q >> 3;
            if (j < rowLo || j >= rowHi) continue;
            if (occluded(t, std::min(c, W - 0.5), y)) continue;
            const uint8_t bit = static_cast<uint8_t>(1u << (q & 7));
            if ((k & 1) == 0) {
                mVertical[static_cast<size_t>(j) * (W + 1) + k / 2] |= bit;
            } else {
                mVerticalMid[static_cast<size_t>(j) * W + k / 2] |= bit;
            }
        }
    }
}

// ---- Classification (§4.1, §4.2, §5.1) ----------------------------------------------------

void EdgePointImage::classifyPixels() {
    const EdgeCodeTables& tables = EdgeCodeTables::pixel();
    // In the same pass: the pixel counts by class per row, and (colour, 1) per point on a
    // 2-pixel zero border (all points, and the usable ones) so the filters of §5.3 run
    // without bounds checks.
    forRows(mOptions.parallel, mHeight, [&](int y) {
        std::array<int, 3> counts{0, 0, 0};
        for (int x = 0; x < mWidth; ++x) {
            const size_t i = index(x, y);
            const uint16_t code = codeFromMasks(
                mHorizontal[static_cast<size_t>(y) * mWidth + x],
                mVertical[static_cast<size_t>(y) * (mWidth + 1) + x + 1],
                mHorizontal[static_cast<size_t>(y + 1) * mWidth + x],
                mVertical[static_cast<size_t>(y) * (mWidth + 1) + x], kEpiPiecesPerSide);
            mEdgeCode[i] = code;
            const bool hasSample = mSamplePos[i] != 0xFF;
            bool usable = false;
            bool primaryIs1 = false;
            if (code == kEdgeCodeEmpty) {
                usable = hasSample;
                ++counts[0];
            } else if (code != kEdgeCodeComplex) {
                // §5.1: the region holding the sample is primary, else the larger region.
                const SampleSide side =
                    hasSample ? tables.side(code, mSamplePos[i]) : SampleSide::Ambiguous;
                usable = side != SampleSide::Ambiguous;
                primaryIs1 = usable ? side == SampleSide::Region1 : tables.region0Area[code] < 0.5f;
                ++counts[1];
            } else {
                ++counts[2];
            }
            mUsable[i] = usable ? 1 : 0;
            mNeighbourCode[i] = makeNeighbourCode(code, kEpiPiecesPerSide, primaryIs1);
            mPaddedCode[paddedIndex(x, y)] = mNeighbourCode[i];
            const size_t p = paddedIndex(x, y);
            mPaddedAll[p] = hasSample ? glm::vec4(mSampleColour[i], 1.0f) : glm::vec4(0.0f);
            mPaddedUsable[p] = usable ? mPaddedAll[p] : glm::vec4(0.0f);
        }
        mRowCounts[y] = counts;
    });
    mPixelCounts = {0, 0, 0};
    for (const auto& row : mRowCounts)
        for (int c = 0; c < 3; ++c) mPixelCounts[c] += row[c];
}

PixelClass EdgePointImage::pixelClass(int x, int y) const {
    const uint16_t code = mEdgeCode[index(x, y)];
    if (code == kEdgeCodeEmpty) return PixelClass::Empty;
    return code == kEdgeCodeComplex ? PixelClass::Complex : PixelClass::Simple;
}

int EdgePointImage::samplePosition(int x, int y) const {
    const uint8_t p = mSamplePos[index(x, y)];
    return p == 0xFF ? -1 : p;
}

Rgb EdgePointImage::sampleColour(int x, int y) const { return Rgb(mSampleColour[index(x, y)]); }

bool EdgePointImage::primaryIsRegion1(int x, int y) const {
    return (mNeighbourCode[index(x, y)] & kNeighbourPrimaryIsRegion1) != 0;
}

std::array<uint8_t, 4> EdgePointImage::boundaryMasks(int x, int y) const {
    return {mHorizontal[static_cast<size_t>(y) * mWidth + x],
            mVertical[static_cast<size_t>(y) * (mWidth + 1) + x + 1],
            mHorizontal[static_cast<size_t>(y + 1) * mWidth + x],
            mVertical[static_cast<size_t>(y) * (mWidth + 1) + x]};
}

std::array<uint8_t, 2> EdgePointImage::halfLineMasks(int x, int y) const {
    return {mHorizontalMid[static_cast<size_t>(y) * mWidth + x],
            mVerticalMid[static_cast<size_t>(y) * mWidth + x]};
}

size_t EdgePointImage::countPixels(PixelClass c) const { return mPixelCounts[static_cast<int>(c)]; }

std::string EdgePointImage::toString() const {
    std::ostringstream out;
    size_t samples = 0;
    for (uint8_t p : mSamplePos) samples += p != 0xFF;
    out << "EdgePointImage{" << mWidth << "x" << mHeight << ", " << samples << " points, "
        << countPixels(PixelClass::Empty) << " empty, " << countPixels(PixelClass::Simple)
        << " simple, " << countPixels(PixelClass::Complex) << " complex, " << mCulledIntersections
        << " culled intersections, " << mOptions.toString() << "}";
    return out.str();
}

// ---- Reachability (§5.2) ------------------------------------------------------------------

std::array<uint8_t, 25> EdgePointImage::computeReachability(int x, int y) const {
    std::array<uint8_t, 25> reach{};
    if (x < 0 || y < 0 || x >= mWidth || y >= mHeight) return reach;
    // Neighbour codes of the 5×5 window; outside the image counts as complex (unreachable).
    std::array<uint8_t, 25> codes;
    for (int dy = -2; dy <= 2; ++dy) {
        const uint8_t* row = &mPaddedCode[paddedIndex(x - 2, y + dy)];
        for (int k = 0; k < 5; ++k) codes[(dy + 2) * 5 + k] = row[k];
    }
    const uint8_t centre = codes[12];
    if ((centre & 7) == kNeighbourTypeComplex) return reach;
    reach[12] =
        static_cast<uint8_t>(kReachPP | ((centre & 7) != kNeighbourTypeEmpty ? kReachSS : 0));
    const std::array<uint8_t, 16384>& hopTable = fusedHopTable();
    // Outward from the centre: neighbour lookup chained onto each predecessor's mask (one
    // fused lookup), and the paths combined with OR.
    for (const PropagationStep& step : kPropagationOrder) {
        uint8_t combined = 0;
        for (int k = 0; k < step.count; ++k) {
            const int via = reach[step.pred[k]];
            combined |= hopTable[(static_cast<int>(step.dir[k]) << 12) | (via << 8) |
                                 (codes[step.pred[k]] << 4) | codes[step.target]];
        }
        reach[step.target] = combined;
    }
    return reach;
}

void EdgePointImage::markNearEdge() {
    // Pixels whose 5×5 neighbourhood holds any edge: vertical then horizontal OR.
    forRows(mOptions.parallel, mHeight, [&](int y) {
        // (The width in a local: a byte store may alias the member, which kept this scalar.)
        const int W = mWidth;
        uint8_t* __restrict out = &mNearEdge[paddedIndex(0, y)];
        for (int x = 0; x < W; ++x) out[x] = 0;
        for (int dy = -2; dy <= 2; ++dy) {
            const int py = y + dy;
            if (py < 0 || py >= mHeight) continue;
            const uint16_t* __restrict row = &mEdgeCode[index(0, py)];
            for (int x = 0; x < W; ++x) out[x] |= row[x] != kEdgeCodeEmpty;
        }
    });
}

bool EdgePointImage::nearEdge(int x, int y) const {
    const uint8_t* column = &mNearEdge[paddedIndex(0, y)];
    return (column[x - 2] | column[x - 1] | column[x] | column[x + 1] | column[x + 2]) != 0;
}

void EdgePointImage::computeReachabilityMapSerial() {
    // The reference: the full 5×5 propagation for every pixel near an edge.
    for (int y = 0; y < mHeight; ++y) {
        for (int x = 0; x < mWidth; ++x) {
            const size_t i = index(x, y);
            mSecondaryReach[i] = 0;
            if (!nearEdge(x, y)) {
                mReach[i] = kAllNeighbours | kAllEmptyFlag;
                continue;
            }
            const std::array<uint8_t, 25> masks = computeReachability(x, y);
            uint32_t primary = 0;
            for (int k = 0; k < 24; ++k) {
                primary |= static_cast<uint32_t>(masks[kBitCell[k]] & kReachPP) << k;
            }
            uint8_t secondary = 0;
            for (int k = 0; k < 8; ++k) {
                secondary |=
                    static_cast<uint8_t>(((masks[kRingCell[k]] & kReachSP) ? 1u : 0u) << k);
            }
            mReach[i] = primary;
            mSecondaryReach[i] = secondary;
        }
    }
}

void EdgePointImage::propagateLowerReachability() {
    const std::array<uint8_t, 16384>& hopTable = fusedHopTable();
    forRows(true, mHeight, [&](int y) {
        for (int x = 0; x < mWidth; ++x) {
            const size_t i = index(x, y);
            mSecondaryReach[i] = 0;
            mPartnerReach[i] = 0;
            if (!nearEdge(x, y)) {
                mReachLower[i] = kAllNeighbours | kAllEmptyFlag;
                continue;
            }
            // Codes of rows y .. y + 2, columns x − 2 .. x + 2 (outside: complex).
            uint8_t c[3][5];
            for (int dy = 0; dy <= 2; ++dy) {
                const uint8_t* row = &mPaddedCode[paddedIndex(x - 2, y + dy)];
                for (int k = 0; k < 5; ++k) c[dy][k] = row[k];
            }
            const uint8_t centre = c[0][2];
            if ((centre & 7) == kNeighbourTypeComplex) {
                mReachLower[i] = 0;
                continue;
            }
            auto hop = [&](NeighbourDirection d, uint8_t via, uint8_t from, uint8_t to) {
                return hopTable[(static_cast<int>(d) << 12) | (via << 8) | (from << 4) | to];
            };
            constexpr NeighbourDirection R = NeighbourDirection::Right;
            constexpr NeighbourDirection L = NeighbourDirection::Left;
            constexpr NeighbourDirection D = NeighbourDirection::Down;
            uint8_t m[3][5];
            m[0][2] = static_cast<uint8_t>(kReachPP |
                                           ((centre & 7) != kNeighbourTypeEmpty ? kReachSS : 0));
            // Row dy = 0: outward along the row.
            m[0][3] = hop(R, m[0][2], c[0][2], c[0][3]);
            m[0][4] = hop(R, m[0][3], c[0][3], c[0][4]);
            m[0][1] = hop(L, m[0][2], c[0][2], c[0][1]);
            m[0][0] = hop(L, m[0][1], c[0][1], c[0][0]);
            // Rows dy = 1, 2: from above, and from the column nearer the centre.
            for (int dy = 1; dy <= 2; ++dy) {
                m[dy][2] = hop(D, m[dy - 1][2], c[dy - 1][2], c[dy][2]);
                for (int dx = 3; dx <= 4; ++dx) {
                    m[dy][dx] =
                        static_cast<uint8_t>(hop(D, m[dy - 1][dx], c[dy - 1][dx], c[dy][dx]) |
                                             hop(R, m[dy][dx - 1], c[dy][dx - 1], c[dy][dx]));
                }
                for (int dx = 1; dx >= 0; --dx) {
                    m[dy][dx] =
                        static_cast<uint8_t>(hop(D, m[dy - 1][dx], c[dy - 1][dx], c[dy][dx]) |
                                             hop(L, m[dy][dx + 1], c[dy][dx + 1], c[dy][dx]));
                }
            }
            // Bits 10..23 of the 24-bit mask are cells 11..24 (dy ≥ 0 without the centre).
            uint32_t primary = 0;
            for (int k = 10; k < 24; ++k) {
                const int cell = kBitCell[k];
                primary |= static_cast<uint32_t>(m[cell / 5 - 2][cell % 5] & kReachPP) << k;
            }
            // Ring bits 3..7 are cells 11, 13, 16, 17, 18.
            uint8_t secondary = 0;
            for (int k = 3; k < 8; ++k) {
                const int cell = kRingCell[k];
                secondary |=
                    static_cast<uint8_t>(((m[cell / 5 - 2][cell % 5] & kReachSP) ? 1u : 0u) << k);
            }
            // For the pixels below: this primary reaches their secondary (dx = −1, 0, 1).
            uint8_t partner = 0;
            for (int dx = -1; dx <= 1; ++dx) {
                partner |= static_cast<uint8_t>(((m[1][dx + 2] & kReachPS) ? 1u : 0u) << (dx + 1));
            }
            mReachLower[i] = primary;
            mSecondaryReach[i] = secondary;
            mPartnerReach[i] = partner;
        }
    });
}

void EdgePointImage::mirrorUpperReachability() {
    forRows(true, mHeight, [&](int y) {
        for (int x = 0; x < mWidth; ++x) {
            const size_t i = index(x, y);
            const uint32_t own = mReachLower[i];
            mReach[i] = own;
            if (own & kAllEmptyFlag) continue;
            if ((mPaddedCode[paddedIndex(x, y)] & 7) == kNeighbourTypeComplex) continue;
            // Cells with dy < 0 (bits 0..9): the mirrored bit of the pixel there. A pixel far
            // from every edge reaches all of its (empty) neighbourhood.
            uint32_t upper = 0;
            for (int k = 0; k < 10; ++k) {
                const int dx = kBitCell[k] % 5 - 2;
                const int dy = kBitCell[k] / 5 - 2;
                const int px = x + dx;
                const int py = y + dy;
                if (px < 0 || py < 0 || px >= mWidth) continue;
                const uint32_t theirs = mReachLower[index(px, py)];
                // Their cell (−dx, −dy) is bit 23 − k (the 24 cells mirror through the centre).
                upper |= ((theirs >> (23 - k)) & 1u) << k;
            }
            uint8_t secondary = mSecondaryReach[i];
            for (int dx = -1; dx <= 1; ++dx) {
                const int px = x + dx;
                if (px < 0 || px >= mWidth || y == 0) continue;
                // Their primary reaches our secondary from cell (−dx, +1).
                const uint8_t theirs = mPartnerReach[index(px, y - 1)];
                secondary |= static_cast<uint8_t>(((theirs >> (1 - dx)) & 1u) << (dx + 1));
            }
            mReach[i] = own | upper;
            mSecondaryReach[i] = secondary;
        }
    });
}

void EdgePointImage::computeReachabilityMap() {
    markNearEdge();
    if (!mOptions.parallel) {
        computeReachabilityMapSerial();
        return;
    }
    // §5.2: "since reachability is symmetric ... reachability of pixels on prior scanlines is
    // reused". Pass 1 propagates only to the current and the next two scanlines (the 14 cells
    // with dy ≥ 0: monotone paths to them never leave those rows, so 22 lookups instead of
    // 40). Pass 2 takes the 10 cells on prior scanlines from the pixels there: a ↔ d is
    // primary-to-primary for a exactly when it is for d, and a's secondary reaches d's
    // primary exactly when d's primary reaches a's secondary (the hop tables of opposite
    // directions are transposes and the chaining is relational composition, so the union
    // over monotone paths is symmetric). Equal bit for bit to the full propagation (the
    // serial reference, computeReachabilityMapSerial(); tested).
    propagateLowerReachability();
    mirrorUpperReachability();
}

// ---- Interpolation (§5.3) -----------------------------------------------------------------

void EdgePointImage::interpolatePlain() {
    // The render cache's interpolation: the same separable filter over every point of the
    // 5×5 neighbourhood, ignoring edges, in two 1D passes over the padded points.
    const float g1 = kFilter[1];
    const float g2 = kFilter[2];
    forRows(mOptions.parallel, mHeight + 4, [&](int py) {
        const glm::vec4* row = &mPaddedAll[static_cast<size_t>(py) * (mWidth + 4) + 2];
        glm::vec4* out = &mRowSums[static_cast<size_t>(py) * mWidth];
        for (int x = 0; x < mWidth; ++x) {
            const Quad sum = addQuad(
                loadQuad(row[x]),
                addQuad(scaleQuad(addQuad(loadQuad(row[x - 1]), loadQuad(row[x + 1])), g1),
                        scaleQuad(addQuad(loadQuad(row[x - 2]), loadQuad(row[x + 2])), g2)));
            storeQuad(out[x], sum);
        }
    });
    forRows(mOptions.parallel, mHeight, [&](int y) {
        const glm::vec4* r = &mRowSums[static_cast<size_t>(y + 2) * mWidth];
        const ptrdiff_t stride = mWidth;
        for (int x = 0; x < mWidth; ++x) {
            const glm::vec4 sum = toVec4(addQuad(
                loadQuad(r[x]),
                addQuad(scaleQuad(addQuad(loadQuad(r[x - stride]), loadQuad(r[x + stride])), g1),
                        scaleQuad(addQuad(loadQuad(r[x - 2 * stride]), loadQuad(r[x + 2 * stride])),
                                  g2))));
            const size_t i = index(x, y);
            mPlainWeight[i] = sum.w;
            mPlain[i] = sum.w > 0.0f ? glm::vec3(sum) / sum.w : glm::vec3(0.0f);
        }
    });
}

void EdgePointImage::interpolatePrimary(Image& out) {
    // Padded-index offsets and filter weights of the 24 mask bits.
    std::array<ptrdiff_t, 24> offset;
    std::array<float, 24> weight;
    for (int k = 0; k < 24; ++k) {
        const int dx = kBitCell[k] % 5 - 2;
        const int dy = kBitCell[k] / 5 - 2;
        offset[k] = static_cast<ptrdiff_t>(dy) * (mWidth + 4) + dx;
        weight[k] = filterWeight(dx, dy);
    }
    forRows(mOptions.parallel, mHeight, [&](int y) {
        for (int x = 0; x < mWidth; ++x) {
            const size_t i = index(x, y);
            const uint32_t reach = mReach[i];
            glm::vec3 colour;
            float total;
            if ((reach & kAllEmptyFlag) || mEdgeCode[i] == kEdgeCodeComplex) {
                // No edge within 5×5 (the plain result is exact), or a complex pixel, whose
                // first estimate ignores reachability (§5.4).
                colour = mPlain[i];
                total = mPlainWeight[i];
            } else {
                // Renormalized filter over the reachable samples (§5.3).
                const glm::vec4* centre = &mPaddedUsable[paddedIndex(x, y)];
                Quad acc = loadQuad(centre[0]);
                for (uint32_t bits = reach; bits; bits &= bits - 1) {
                    const int k = std::countr_zero(bits);
                    acc = addQuad(acc, scaleQuad(loadQuad(centre[offset[k]]), weight[k]));
                }
                const glm::vec4 sum = toVec4(acc);
                total = sum.w;
                colour = total > 0.0f ? glm::vec3(sum) / total : glm::vec3(0.0f);
            }
            mWeight[i] = total;
            mPrimary[i] = colour;
            out.at(x, y) = Rgb(colour);
        }
    });
    // Pixels near edges with samples in their 5×5 neighbourhood, none of them reachable,
    // take the filtered primary colours of the reachable pixels that have one (one more ring
    // of reach, still edge-respecting); failing that, the plain estimate. (Pixels with no
    // sample within 5×5 at all stay black, as in the render cache's interpolation.) Only
    // zero-weight pixels are written and only positive-weight pixels read, so rows can run in
    // parallel.
    forRows(mOptions.parallel, mHeight, [&](int y) {
        for (int x = 0; x < mWidth; ++x) {
            const size_t i = index(x, y);
            const uint32_t reach = mReach[i];
            if (mWeight[i] > 0.0f || mPlainWeight[i] == 0.0f || (reach & kAllEmptyFlag) ||
                mEdgeCode[i] == kEdgeCodeComplex) {
                continue;
            }
            glm::vec3 sum(0.0f);
            float total = 0.0f;
            for (uint32_t bits = reach; bits; bits &= bits - 1) {
                const int k = std::countr_zero(bits);
                const int px = x + kBitCell[k] % 5 - 2;
                const int py = y + kBitCell[k] / 5 - 2;
                if (px < 0 || py < 0 || px >= mWidth || py >= mHeight) continue;
                const size_t j = index(px, py);
                if (!(mWeight[j] > 0.0f)) continue;
                sum += weight[k] * mPrimary[j];
                total += weight[k];
            }
            mPrimary[i] = total > 0.0f ? sum / total : mPlain[i];
            out.at(x, y) = Rgb(mPrimary[i]);
        }
    });
}

// ---- Anti-aliasing (§5.3) -----------------------------------------------------------------

void EdgePointImage::antiAlias(Image& out) const {
    const EdgeCodeTables& tables = EdgeCodeTables::pixel();
    forRows(mOptions.parallel, mHeight, [&](int y) {
        for (int x = 0; x < mWidth; ++x) {
            const size_t i = index(x, y);
            const uint16_t code = mEdgeCode[i];
            if (code == kEdgeCodeEmpty || code == kEdgeCodeComplex) continue;
            // Area-weighted primary and secondary colours; the secondary colour is the
            // primary colour of the edge-indexed neighbour, the first whose primary region
            // the secondary region reaches.
            const int secondary = (mNeighbourCode[i] & kNeighbourPrimaryIsRegion1) ? 0 : 1;
            const float area0 = tables.region0Area[code];
            const float secondaryArea = secondary == 0 ? area0 : 1.0f - area0;
            const auto& choice =
                tables.antiAliasNeighbours[static_cast<size_t>(code) * 2 + secondary];
            for (int k = 0; k < choice.count; ++k) {
                const int dx = choice.dx[k];
                const int dy = choice.dy[k];
                const int px = x + dx;
                const int py = y + dy;
                if (px < 0 || py < 0 || px >= mWidth || py >= mHeight) continue;
                if (!(mSecondaryReach[i] & (1u << ringBit(dx, dy)))) continue;
                const glm::vec3 c =
                    (1.0f - secondaryArea) * mPrimary[i] + secondaryArea * mPrimary[index(px, py)];
                out.at(x, y) = Rgb(c);
                break;
            }
        }
    });
}

// ---- Complex filter (§5.4) ----------------------------------------------------------------

namespace {

/// §5.4 region adjacency of subpixel neighbour types, to the right (0) and below (1):
/// [direction][type · 8 + neighbour's type].
const std::array<std::array<uint8_t, 64>, 2>& subpixelAdjacency() {
    static const auto adjacency = [] {
        std::array<std::array<uint8_t, 64>, 2> t{};
        for (int d = 0; d < 2; ++d) {
            for (int k = 0; k < 64; ++k) {
                t[d][k] = regionAdjacency(static_cast<NeighbourDirection>(d),
                                          static_cast<uint8_t>(k / 8), static_cast<uint8_t>(k % 8));
            }
        }
        return t;
    }();
    return adjacency;
}

/// §5.4 neighbour type of each subpixel edge code.
const std::array<uint8_t, kEdgeCodeCount>& subpixelTypes() {
    static const std::array<uint8_t, kEdgeCodeCount> subpixelType = [] {
        std::array<uint8_t, kEdgeCodeCount> t{};
        for (int code = 0; code < kEdgeCodeCount; ++code)
            t[code] = neighbourType(static_cast<uint16_t>(code), kSubpixelPiecesPerSide);
        return t;
    }();
    return subpixelType;
}

}  // namespace

/// §5.4 working state of one complex pixel: the subpixel edge codes and types over the 6×6
/// subpixels of its 3×3 pixel neighbourhood, the adjacency of their regions, the connected
/// regions found so far, and the points of the 3×3 pixels placed in their subpixel regions
/// (node = subpixel · 2 + region).
struct EdgePointImage::ComplexNeighbourhood {
    std::array<uint16_t, 36> codes;
    std::array<uint8_t, 36> types;
    /// edges[dir][ra][rb] has bit a set when region ra of subpixel a meets region rb of its
    /// neighbour to the right (dir 0, a + 1) or below (dir 1, a + 6).
    uint64_t edges[2][2][2] = {};
    std::array<int8_t, 72> label;
    std::array<std::array<uint64_t, 2>, 8> component;
    int labels = 0;
    struct SubSample {
        int node, u, v;
        glm::vec3 colour;
    };
    std::array<SubSample, 9> samples;
    int sampleCount = 0;

    /// The region adjacency `edges` from the subpixel types, and no component labelled yet.
    void connectRegions() {
        // Branch-free: adjacency bit 2·ra + rb selects edges[dir][ra][rb].
        const std::array<std::array<uint8_t, 64>, 2>& adjacency = subpixelAdjacency();
        auto addEdges = [this](int dir, unsigned m, int a) {
            const uint64_t bit = uint64_t(1) << a;
            edges[dir][0][0] |= bit & (uint64_t(0) - (m & 1u));
            edges[dir][0][1] |= bit & (uint64_t(0) - ((m >> 1) & 1u));
            edges[dir][1][0] |= bit & (uint64_t(0) - ((m >> 2) & 1u));
            edges[dir][1][1] |= bit & (uint64_t(0) - ((m >> 3) & 1u));
        };
        for (int v = 0; v < 6; ++v) {
            for (int u = 0; u < 6; ++u) {
                const int a = v * 6 + u;
                if (u + 1 < 6) addEdges(0, adjacency[0][types[a] * 8 + types[a + 1]], a);
                if (v + 1 < 6) addEdges(1, adjacency[1][types[a] * 8 + types[a + 6]], a);
            }
        }
        label.fill(-1);
    }

    /// The label of the connected region holding `node`, flood-filled bit-parallel on first
    /// demand (only the labels' equality matters).
    int find(int node) {
        if (label[node] >= 0) return label[node];
        uint64_t c[2] = {0, 0};
        c[node & 1] = uint64_t(1) << (node >> 1);
        for (;;) {
            const uint64_t c0 = c[0], c1 = c[1];
            for (int ra = 0; ra < 2; ++ra) {
                for (int rb = 0; rb < 2; ++rb) {
                    c[rb] |= (c[ra] & edges[0][ra][rb]) << 1;
                    c[ra] |= (c[rb] >> 1) & edges[0][ra][rb];
                    c[rb] |= (c[ra] & edges[1][ra][rb]) << 6;
                    c[ra] |= (c[rb] >> 6) & edges[1][ra][rb];
                }
            }
            if (c[0] == c0 && c[1] == c1) break;
        }
        const int8_t id = static_cast<int8_t>(labels++);
        component[id] = {c[0], c[1]};
        for (int r = 0; r < 2; ++r)
            for (uint64_t m = c[r]; m; m &= m - 1) label[std::countr_zero(m) * 2 + r] = id;
        return id;
    }

    /// The pixel's value: each region of its own 4 subpixels coloured from the samples it
    /// reaches, area-weighted; complex or unreached regions keep the estimate.
    glm::vec3 colourOwnRegions(const EdgeCodeTables& sub, const glm::vec3& estimate) {
        glm::vec3 total(0.0f);
        for (int v = 2; v < 4; ++v) {
            for (int u = 2; u < 4; ++u) {
                const int s = v * 6 + u;
                const uint8_t type = types[s];
                if (type == kNeighbourTypeComplex) {
                    total += 0.25f * estimate;
                    continue;
                }
                const int regions = type == kNeighbourTypeEmpty ? 1 : 2;
                for (int r = 0; r < regions; ++r) {
                    const float area0 = sub.region0Area[codes[s]];
                    const float area = regions == 1 ? 1.0f : (r == 0 ? area0 : 1.0f - area0);
                    const std::array<uint64_t, 2>& reached = component[find(s * 2 + r)];
                    glm::vec3 sum(0.0f);
                    float weight = 0.0f;
                    for (int k = 0; k < sampleCount; ++k) {
                        const int node = samples[k].node;
                        if (!((reached[node & 1] >> (node >> 1)) & 1)) continue;
                        const float w = filterWeight(samples[k].u - u, samples[k].v - v);
                        sum += w * samples[k].colour;
                        weight += w;
                    }
                    total += 0.25f * area * (weight > 0.0f ? sum / weight : estimate);
                }
            }
        }
        return total;
    }
};

std::vector<size_t> EdgePointImage::listComplexPixels() {
    // The complex pixels in pixel order, rows in parallel at offsets from the per-row counts.
    const int W = mWidth;
    const int H = mHeight;
    std::vector<int>& complexPixels = mComplexPixels;
    std::vector<size_t> rowStart(static_cast<size_t>(H) + 1, 0);
    for (int y = 0; y < H; ++y) rowStart[y + 1] = rowStart[y] + mRowCounts[y][2];
    complexPixels.resize(rowStart[H]);
    forRows(mOptions.parallel, H, [&](int y) {
        size_t k = rowStart[y];
        if (k == rowStart[y + 1]) return;
        for (int x = 0; x < W; ++x)
            if (mEdgeCode[index(x, y)] == kEdgeCodeComplex)
                complexPixels[k++] = static_cast<int>(index(x, y));
    });
    return rowStart;
}

void EdgePointImage::keepDenseComplexEstimates(const std::vector<size_t>& rowStart, Image& out) {
    // Complex pixels in dense clusters keep their estimate now and leave the list; the others
    // are marked in mFiltered (complex pixels only) so that subpixel codes are computed around
    // them alone. (Within a dense cluster the subpixel regions reach few usable samples, those
    // in complex subpixels being skipped, and came out noisier than the estimate, the render
    // cache's reconstruction: §7.5.)
    const int W = mWidth;
    const int H = mHeight;
    std::vector<int>& complexPixels = mComplexPixels;
    mFiltered.assign(static_cast<size_t>(W) * H, 0);
    forRows(mOptions.parallel, H, [&](int y) {
        for (size_t k = rowStart[y]; k < rowStart[y + 1]; ++k) {
            const int pixel = complexPixels[k];
            if (mDense[pixel]) {
                out.at(pixel % W, y) = Rgb(mPrimary[pixel]);
            } else {
                mFiltered[pixel] = 1;
            }
        }
    });
    complexPixels.erase(std::remove_if(complexPixels.begin(), complexPixels.end(),
                                       [&](int pixel) { return !mFiltered[pixel]; }),
                        complexPixels.end());
}

void EdgePointImage::computeSubpixelCodes(bool dense) {
    const int W = mWidth;
    const int H = mHeight;
    // 4 bits of a boundary line at twice-pixel coordinate k2 (even: pixel boundary, odd:
    // half-pixel line) over the half of pixel segment `cell` selected by `half`.
    auto horizontalBits = [&](int k2, int column, int half) -> unsigned {
        const uint8_t m = (k2 & 1) == 0 ? mHorizontal[static_cast<size_t>(k2 / 2) * W + column]
                                        : mHorizontalMid[static_cast<size_t>(k2 / 2) * W + column];
        return (m >> (4 * half)) & 15u;
    };
    auto verticalBits = [&](int k2, int row, int half) -> unsigned {
        const uint8_t m = (k2 & 1) == 0 ? mVertical[static_cast<size_t>(row) * (W + 1) + k2 / 2]
                                        : mVerticalMid[static_cast<size_t>(row) * W + k2 / 2];
        return (m >> (4 * half)) & 15u;
    };

    const std::array<uint8_t, kEdgeCodeCount>& subpixelType = subpixelTypes();
    // Subpixel edge codes of every pixel in some complex pixel's 3×3 neighbourhood, once
    // (complex pixels cluster along dense edges, so neighbourhoods overlap): subpixel
    // (sx, sy) of pixel (px, py) lies between lines 2·px + sx, 2·px + sx + 1 (x) and
    // 2·py + sy, 2·py + sy + 1 (y) on the half-pixel grid.
    forRows(mOptions.parallel, H, [&](int py) {
        const int y0 = std::max(0, py - 1), y1 = std::min(H - 1, py + 1);
        bool anyComplex = false;
        for (int y = y0; y <= y1; ++y) anyComplex |= mRowCounts[y][2] > 0;
        if (!anyComplex) return;
        // Whether column x of rows y0..y1 holds a complex pixel to filter.
        auto columnComplex = [&](int x) {
            if (x < 0 || x >= W) return false;
            for (int y = y0; y <= y1; ++y)
                if (dense ? mFiltered[index(x, y)] != 0
                          : mEdgeCode[index(x, y)] == kEdgeCodeComplex)
                    return true;
            return false;
        };
        bool left = false, centre = columnComplex(0);
        for (int px = 0; px < W; ++px) {
            const bool right = columnComplex(px + 1);
            const bool marked = left || centre || right;
            left = centre;
            centre = right;
            if (!marked) continue;
            const size_t i = index(px, py);
            for (int sy = 0; sy < 2; ++sy) {
                for (int sx = 0; sx < 2; ++sx) {
                    const int k2y = 2 * py + sy;
                    const int k2x = 2 * px + sx;
                    const uint16_t code =
                        codeFromMasks(horizontalBits(k2y, px, sx), verticalBits(k2x + 1, py, sy),
                                      horizontalBits(k2y + 1, px, sx), verticalBits(k2x, py, sy),
                                      kSubpixelPiecesPerSide);
                    mSubCode[4 * i + 2 * sy + sx] = code;
                    mSubType[4 * i + 2 * sy + sx] = subpixelType[code];
                }
            }
        }
    });
}

bool EdgePointImage::filterSampleFreeComplexPixel(int pixel, Image& out) const {
    // No sample in the 3×3 neighbourhood: every region keeps the estimate; the same sums in
    // the same order as the general filter's (ComplexNeighbourhood::colourOwnRegions).
    const EdgeCodeTables& sub = EdgeCodeTables::subpixel();
    const int W = mWidth;
    const int H = mHeight;
    const int cx = pixel % W, cy = pixel / W;
    bool anySample = false;
    for (int py = std::max(0, cy - 1); py <= std::min(H - 1, cy + 1); ++py)
        for (int px = std::max(0, cx - 1); px <= std::min(W - 1, cx + 1); ++px)
            anySample |= mSamplePos[index(px, py)] != 0xFF;
    if (anySample) return false;
    const glm::vec3 estimate = mPrimary[pixel];
    glm::vec3 total(0.0f);
    for (int s = 0; s < 4; ++s) {
        const uint8_t type = mSubType[4 * static_cast<size_t>(pixel) + s];
        if (type == kNeighbourTypeComplex) {
            total += 0.25f * estimate;
            continue;
        }
        const int regions = type == kNeighbourTypeEmpty ? 1 : 2;
        const float area0 = sub.region0Area[mSubCode[4 * static_cast<size_t>(pixel) + s]];
        for (int r = 0; r < regions; ++r) {
            const float area = regions == 1 ? 1.0f : (r == 0 ? area0 : 1.0f - area0);
            total += 0.25f * area * estimate;
        }
    }
    out.at(cx, cy) = Rgb(total);
    return true;
}

void EdgePointImage::gatherSubpixelCodes(int x, int y, ComplexNeighbourhood& nb) const {
    // Subpixel edge codes over the 6×6 subpixels of the 3×3 pixel neighbourhood (outside the
    // image: complex).
    const int W = mWidth;
    const int H = mHeight;
    for (int v = 0; v < 6; ++v) {
        for (int u = 0; u < 6; ++u) {
            const int px = x - 1 + u / 2;
            const int py = y - 1 + v / 2;
            uint16_t code = kEdgeCodeComplex;
            uint8_t type = kNeighbourTypeComplex;
            if (px >= 0 && py >= 0 && px < W && py < H) {
                const size_t s = 4 * index(px, py) + 2 * (v & 1) + (u & 1);
                code = mSubCode[s];
                type = mSubType[s];
            }
            nb.codes[v * 6 + u] = code;
            nb.types[v * 6 + u] = type;
        }
    }
}

void EdgePointImage::gatherSubpixelSamples(int x, int y, ComplexNeighbourhood& nb) const {
    // Samples of the 3×3 pixels placed in their subpixel regions (node = subpixel · 2 +
    // region); those in complex subpixels or on an ambiguous side are skipped.
    const EdgeCodeTables& sub = EdgeCodeTables::subpixel();
    const int W = mWidth;
    const int H = mHeight;
    for (int py = y - 1; py <= y + 1; ++py) {
        for (int px = x - 1; px <= x + 1; ++px) {
            if (px < 0 || py < 0 || px >= W || py >= H) continue;
            const uint8_t pos = mSamplePos[index(px, py)];
            if (pos == 0xFF) continue;
            const int sx = pos & 3;
            const int sy = pos >> 2;
            const int u = 2 * (px - x + 1) + sx / 2;
            const int v = 2 * (py - y + 1) + sy / 2;
            const uint8_t type = nb.types[v * 6 + u];
            if (type == kNeighbourTypeComplex) continue;
            int region = 0;
            if (type != kNeighbourTypeEmpty) {
                const SampleSide side = sub.side(nb.codes[v * 6 + u], (sx & 1) + 2 * (sy & 1));
                if (side == SampleSide::Ambiguous) continue;
                region = side == SampleSide::Region1 ? 1 : 0;
            }
            nb.samples[nb.sampleCount++] = {(v * 6 + u) * 2 + region, u, v,
                                            mSampleColour[index(px, py)]};
        }
    }
}

void EdgePointImage::filterComplexPixel(int pixel, Image& out) const {
    if (mOptions.complexFilterShortcut && filterSampleFreeComplexPixel(pixel, out)) return;
    const int x = pixel % mWidth;
    const int y = pixel / mWidth;
    const glm::vec3 estimate = mPrimary[pixel];
    // All 4 own subpixels complex (common inside dense geometry): the pixel keeps its
    // estimate, summed as colourOwnRegions sums it.
    const uint8_t* own = &mSubType[4 * static_cast<size_t>(pixel)];
    if (own[0] == kNeighbourTypeComplex && own[1] == kNeighbourTypeComplex &&
        own[2] == kNeighbourTypeComplex && own[3] == kNeighbourTypeComplex) {
        glm::vec3 total(0.0f);
        for (int s = 0; s < 4; ++s) total += 0.25f * estimate;
        out.at(x, y) = Rgb(total);
        return;
    }
    // Connected subpixel regions by bit-parallel flood fill. Only the components of the
    // pixel's own 4 subpixels' regions are needed: they are flood-filled on demand (at most
    // 8, usually 2–4), and a sample counts for a region when its node lies in the region's
    // component.
    ComplexNeighbourhood nb;
    gatherSubpixelCodes(x, y, nb);
    nb.connectRegions();
    gatherSubpixelSamples(x, y, nb);
    out.at(x, y) = Rgb(nb.colourOwnRegions(EdgeCodeTables::subpixel(), estimate));
}

void EdgePointImage::filterComplexPixels(Image& out) {
    const std::vector<size_t> rowStart = listComplexPixels();
    // EpiOptions::denseComplexLimit: complex pixels in dense clusters keep their estimate.
    const bool dense = mOptions.denseComplexLimit > 0;
    if (dense) keepDenseComplexEstimates(rowStart, out);
    computeSubpixelCodes(dense);
    const std::vector<int>& complexPixels = mComplexPixels;
    if (!mOptions.parallel) {
        for (int pixel : complexPixels) filterComplexPixel(pixel, out);
        return;
    }
    tbb::parallel_for(tbb::blocked_range<size_t>(0, complexPixels.size(), 16),
                      [&](const tbb::blocked_range<size_t>& range) {
                          for (size_t n = range.begin(); n < range.end(); ++n)
                              filterComplexPixel(complexPixels[n], out);
                      });
}

// ---- Dense complex regions ---------------------------------------------------------------

void EdgePointImage::markDenseComplex() {
    // EpiOptions::denseComplexLimit: the pixels, of any class, with at least that many complex
    // pixels in their 3×3 (itself included), from per-row sums of three. The complex filter
    // leaves such complex pixels to their estimate, and the smoothing's dense regions
    // (denseRadius) take their box means.
    const size_t n = static_cast<size_t>(mWidth) * mHeight;
    mComplexRow.resize(n);
    mDense.resize(n);
    forRows(mOptions.parallel, mHeight, [&](int y) {
        uint8_t* row = &mComplexRow[static_cast<size_t>(y) * mWidth];
        if (mRowCounts[y][2] == 0) {
            std::fill_n(row, mWidth, uint8_t{0});
            return;
        }
        const uint16_t* codes = &mEdgeCode[static_cast<size_t>(y) * mWidth];
        for (int x = 0; x < mWidth; ++x) {
            int c = codes[x] == kEdgeCodeComplex;
            if (x > 0) c += codes[x - 1] == kEdgeCodeComplex;
            if (x + 1 < mWidth) c += codes[x + 1] == kEdgeCodeComplex;
            row[x] = static_cast<uint8_t>(c);
        }
    });
    forRows(mOptions.parallel, mHeight, [&](int y) {
        uint8_t* __restrict mask = &mDense[static_cast<size_t>(y) * mWidth];
        const int y0 = std::max(0, y - 1), y1 = std::min(mHeight - 1, y + 1);
        bool any = false;
        for (int yy = y0; yy <= y1; ++yy) any = any || mRowCounts[yy][2] > 0;
        if (!any) {
            std::fill_n(mask, mWidth, uint8_t{0});
            return;
        }
        const int W = mWidth, limit = mOptions.denseComplexLimit;
        const uint8_t* __restrict r0 = &mComplexRow[static_cast<size_t>(y0) * W];
        const uint8_t* __restrict r1 = &mComplexRow[static_cast<size_t>(y) * W];
        const uint8_t* __restrict r2 = &mComplexRow[static_cast<size_t>(y1) * W];
        const int rows = y1 - y0 + 1;  // 3 inside the image, fewer at its borders
        for (int x = 0; x < W; ++x) {
            const int c = r0[x] + (rows >= 2 ? r2[x] : 0) + (rows == 3 ? r1[x] : 0);
            mask[x] = c >= limit;
        }
    });
}

// ---- Reconstruct --------------------------------------------------------------------------

Image EdgePointImage::reconstruct(bool useEdges) {
    mTimes.reachabilityMs = mTimes.interpolateMs = mTimes.antiAliasMs = 0.0;
    mTimes.complexFilterMs = mTimes.smoothMs = 0.0;
    Image out(mWidth, mHeight);

    // The smoothing passes mark the pixels they give a value (1), markHoles the rest.
    mHole.assign(static_cast<size_t>(mWidth) * mHeight, 0);
    if (!useEdges) {
        auto start = std::chrono::steady_clock::now();
        interpolatePlain();
        mWeight = mPlainWeight;
        std::fill(mReach.begin(), mReach.end(), kAllNeighbours | kAllEmptyFlag);
        forRows(mOptions.parallel, mHeight, [&](int y) {
            for (int x = 0; x < mWidth; ++x) out.at(x, y) = Rgb(mPlain[index(x, y)]);
        });
        mTimes.interpolateMs = msSince(start);
        markHoles(false);
        return out;
    }

    auto start = std::chrono::steady_clock::now();
    computeReachabilityMap();
    mTimes.reachabilityMs = msSince(start);

    start = std::chrono::steady_clock::now();
    interpolatePlain();
    interpolatePrimary(out);
    mTimes.interpolateMs = msSince(start);

    if (mOptions.antiAlias) {
        start = std::chrono::steady_clock::now();
        antiAlias(out);
        mTimes.antiAliasMs = msSince(start);
    }
    if (mOptions.denseComplexLimit > 0) markDenseComplex();
    if (mOptions.complexFilter) {
        start = std::chrono::steady_clock::now();
        filterComplexPixels(out);
        mTimes.complexFilterMs = msSince(start);
    }
    if (mOptions.smoothRadius > 0) {
        // Last: it replaces whole pixels, whatever the stages above gave them. A stage of
        // its own (not one of the paper's three filters).
        start = std::chrono::steady_clock::now();
        smoothEdgeFreeRegions(out);
        mTimes.smoothMs = msSince(start);
    }
    if (mOptions.ownPointPrior > 0) {
        start = std::chrono::steady_clock::now();
        showOwnPoints(out);
        mTimes.smoothMs += msSince(start);
    }
    markHoles(true);
    return out;
}

void EdgePointImage::markHoles(bool useEdges) {
    // A pixel has a value from the points when its filter reached one (its own, or the plain
    // 5×5 estimate that interpolatePrimary and the complex filter fall back to), or when the
    // smoothing wrote it (mHole 1 on entry); the rest is a hole. A pixel of a simple pixel's
    // secondary region takes a neighbour's colour only through anti-aliasing, which mixes it
    // with the primary: with neither weight it is a hole too.
    std::vector<size_t> rowHoles(static_cast<size_t>(mHeight), 0);
    forRows(mOptions.parallel, mHeight, [&](int y) {
        size_t holes = 0;
        for (int x = 0; x < mWidth; ++x) {
            const size_t i = index(x, y);
            const bool reached =
                mWeight[i] > 0.0f || (useEdges && mPlainWeight[i] > 0.0f) || mHole[i] != 0;
            mHole[i] = reached ? 0 : 1;
            holes += reached ? 0 : 1;
        }
        rowHoles[static_cast<size_t>(y)] = holes;
    });
    mHoleCount = 0;
    for (size_t h : rowHoles) mHoleCount += h;
}

// ---- Edge-free smoothing ------------------------------------------------------------------

namespace {

/// Edge-free smoothing: empty pixels at most this far (Chebyshev) from a simple or complex
/// pixel are filtered by reachability, the others by boxes.
constexpr int kRingDistance = 2;

}  // namespace

void EdgePointImage::computeEdgeDistance(int cap) {
    const size_t n = static_cast<size_t>(mWidth) * mHeight;
    // Chebyshev distance to the nearest simple or complex pixel, capped at R + 1: along each
    // row first (two sweeps), then the minimum over the rows within the cap of
    // max(|dy|, row distance). Pixels beyond the image count as empty.
    mEdgeDistanceRow.resize(n);
    mEdgeDistance.resize(n);
    forRows(mOptions.parallel, mHeight, [&](int y) {
        uint8_t* row = &mEdgeDistanceRow[static_cast<size_t>(y) * mWidth];
        const uint16_t* codes = &mEdgeCode[static_cast<size_t>(y) * mWidth];
        int d = cap;
        for (int x = 0; x < mWidth; ++x) {
            d = codes[x] != kEdgeCodeEmpty ? 0 : std::min(d + 1, cap);
            row[x] = static_cast<uint8_t>(d);
        }
        d = cap;
        for (int x = mWidth - 1; x >= 0; --x) {
            d = row[x] == 0 ? 0 : std::min(d + 1, cap);
            row[x] = static_cast<uint8_t>(std::min<int>(row[x], d));
        }
    });
    forRows(mOptions.parallel, mHeight, [&](int y) {
        const int y0 = std::max(0, y - cap), y1 = std::min(mHeight - 1, y + cap);
        // (Restrict, and the width in a local: byte pointers may alias anything, the member
        // mWidth included, which would keep this loop scalar.)
        const int W = mWidth;
        uint8_t* __restrict dst = &mEdgeDistance[static_cast<size_t>(y) * W];
        for (int x = 0; x < W; ++x) dst[x] = static_cast<uint8_t>(cap);
        for (int yy = y0; yy <= y1; ++yy) {
            const uint8_t dy = static_cast<uint8_t>(std::abs(yy - y));
            const uint8_t* __restrict row = &mEdgeDistanceRow[static_cast<size_t>(yy) * W];
            for (int x = 0; x < W; ++x) {
                const uint8_t far = row[x] > dy ? row[x] : dy;
                dst[x] = dst[x] < far ? dst[x] : far;
            }
        }
    });
}

void EdgePointImage::buildSummedAreaTable() {
    // Summed-area table of (colour, 1) over the points, in double (float sums of 262k terms
    // lose the colour's low bits): S(x, y) = Σ over x' < x, y' < y. Rows in parallel, then
    // columns in parallel blocks.
    // Every entry is written below; only row 0 and column 0 are zeros.
    const int sw = mWidth + 1;
    mSummedArea.resize(static_cast<size_t>(sw) * (mHeight + 1));
    std::fill_n(mSummedArea.begin(), sw, glm::dvec4(0.0));
    const int pw = mWidth + 4;
    forRows(mOptions.parallel, mHeight, [&](int y) {
        const glm::vec4* src = &mPaddedAll[static_cast<size_t>(y + 2) * pw + 2];
        glm::dvec4* dst = &mSummedArea[static_cast<size_t>(y + 1) * sw];
        glm::dvec4 sum(0.0);
        dst[0] = sum;
        for (int x = 0; x < mWidth; ++x) dst[x + 1] = sum += glm::dvec4(src[x]);
    });
    constexpr int kColumns = 32;
    forRows(mOptions.parallel, (sw + kColumns - 1) / kColumns, [&](int block) {
        const int x0 = block * kColumns, x1 = std::min(sw, x0 + kColumns);
        for (int y = 1; y <= mHeight; ++y) {
            glm::dvec4* row = &mSummedArea[static_cast<size_t>(y) * sw];
            const glm::dvec4* above = row - sw;
            for (int x = x0; x < x1; ++x) row[x] += above[x];
        }
    });
}

glm::dvec4 EdgePointImage::boxSum(int x, int y, int r) const {
    const int sw = mWidth + 1;
    const int xa = std::max(0, x - r), xb = std::min(mWidth, x + r + 1);
    const int ya = std::max(0, y - r), yb = std::min(mHeight, y + r + 1);
    return mSummedArea[static_cast<size_t>(yb) * sw + xb] -
           mSummedArea[static_cast<size_t>(yb) * sw + xa] -
           mSummedArea[static_cast<size_t>(ya) * sw + xb] +
           mSummedArea[static_cast<size_t>(ya) * sw + xa];
}

bool EdgePointImage::writeDenseMean(Image& out, int x, int y) {
    const glm::dvec4 sum = boxSum(x, y, mOptions.denseRadius);
    if (!(sum.w >= 1.5)) return false;
    out.at(x, y) = Rgb(glm::dvec3(sum) / sum.w);
    mHole[index(x, y)] = 1;  // written: not a hole (markHoles)
    return true;
}

void EdgePointImage::smoothBoxes(Image& out, int R) {
    // Each empty pixel whose nearest edge pixel is d > kRingDistance away takes the box
    // average of radius min(d − 1, R) (a box no edge crosses), when the box holds at least two
    // points; nearer ones are filtered by smoothNearEdges().
    forRows(mOptions.parallel, mHeight, [&](int y) {
        for (int x = 0; x < mWidth; ++x) {
            const int d = mEdgeDistance[index(x, y)];
            if (d <= kRingDistance) continue;
            const glm::dvec4 sum = boxSum(x, y, std::min(d - 1, R));
            if (sum.w >= 1.5) {
                out.at(x, y) = Rgb(glm::dvec3(sum) / sum.w);
                mHole[index(x, y)] = 1;  // written: not a hole (markHoles)
            }
        }
    });
}

void EdgePointImage::smoothNearEdges(Image& out, bool dense) {
    // Empty pixels next to an edge pixel (d = 1: any box would cross it) and at d = 2 (a box
    // of radius 1, a handful of points): the filter of §5.3 applied once more, to the primary
    // colours of the pixel and of its reachable 5×5 neighbours, each already a filtered
    // average of the samples it reaches. Still edge-respecting (mReach), with about twice the
    // support. (armadillo-field against the converged reference: the error in these pixels
    // fell by a fifth, 0.000534 → 0.000434 of the mean squared error; the boxes did better
    // from d = 3 on.)
    std::array<float, 24> weight;
    std::array<std::ptrdiff_t, 24> offset;  // of each 5×5 cell from the centre, in pixels
    for (int k = 0; k < 24; ++k) {
        const int dx = kBitCell[k] % 5 - 2, dy = kBitCell[k] / 5 - 2;
        weight[k] = filterWeight(dx, dy);
        offset[k] = static_cast<std::ptrdiff_t>(dy) * mWidth + dx;
    }
    forRows(mOptions.parallel, mHeight, [&](int y) {
        // Rows and columns two or more pixels inside the image reach no cell outside it.
        const bool innerRow = y >= 2 && y + 2 < mHeight;
        for (int x = 0; x < mWidth; ++x) {
            const size_t i = index(x, y);
            const int d = mEdgeDistance[i];
            if (d < 1 || d > kRingDistance) continue;
            if (dense && mDense[i] && writeDenseMean(out, x, y)) continue;
            glm::vec3 sum = mWeight[i] > 0.0f ? mPrimary[i] : glm::vec3(0.0f);
            float total = mWeight[i] > 0.0f ? 1.0f : 0.0f;
            const bool inner = innerRow && x >= 2 && x + 2 < mWidth;
            for (uint32_t bits = mReach[i] & 0xFFFFFFu; bits; bits &= bits - 1) {
                const int k = std::countr_zero(bits);
                if (!inner) {
                    const int px = x + kBitCell[k] % 5 - 2, py = y + kBitCell[k] / 5 - 2;
                    if (px < 0 || py < 0 || px >= mWidth || py >= mHeight) continue;
                }
                const size_t j = i + offset[k];
                if (!(mWeight[j] > 0.0f)) continue;
                sum += weight[k] * mPrimary[j];
                total += weight[k];
            }
            if (total > 0.0f) {
                out.at(x, y) = Rgb(sum / total);
                mHole[i] = 1;  // written: not a hole (markHoles)
            }
        }
    });
}

void EdgePointImage::smoothEdgeFreeRegions(Image& out) {
    const int R = std::clamp(mOptions.smoothRadius, 1, 100);
    // Distances are capped where they stop mattering: past the largest box, and past the
    // pixels the reachability pass takes (so that R = 1 still leaves d ≥ 3 to the boxes).
    const int cap = std::max(R, kRingDistance) + 1;
    computeEdgeDistance(cap);
    buildSummedAreaTable();
    // EpiOptions::denseRadius: a dense pixel takes the mean of every point in its box,
    // whatever its class, when the box holds two or more (writeDenseMean; else it keeps what
    // it has).
    const bool dense = mOptions.denseRadius > 0 && mOptions.denseComplexLimit > 0;
    smoothBoxes(out, R);
    smoothNearEdges(out, dense);
    // Dense regions' simple and complex pixels (d = 0; the ring pass wrote the empty ones).
    if (dense) {
        forRows(mOptions.parallel, mHeight, [&](int y) {
            for (int x = 0; x < mWidth; ++x) {
                const size_t i = index(x, y);
                if (mDense[i] && mEdgeDistance[i] == 0) writeDenseMean(out, x, y);
            }
        });
    }
}

// ---- Classification image -----------------------------------------------------------------

void EdgePointImage::showOwnPoints(Image& out) const {
    const double k = mOptions.ownPointPrior;
    forRows(mOptions.parallel, mHeight, [&](int y) {
        for (int x = 0; x < mWidth; ++x) {
            const size_t i = index(x, y);
            if (mSamplePos[i] == 0xFF || mEdgeCode[i] != kEdgeCodeEmpty || mSampleTrust[i] == 0)
                continue;
            const Rgb own(mSampleColour[i]);
            if (mSampleTrust[i] == kEpiTrustExact) {
                out.at(x, y) = own;
                continue;
            }
            const double n = mSampleTrust[i];
            out.at(x, y) = (own * n + out.at(x, y) * k) / (n + k);
        }
    });
}

Image EdgePointImage::classificationImage() const {
    Image image(mWidth, mHeight);
    for (int y = 0; y < mHeight; ++y) {
        for (int x = 0; x < mWidth; ++x) {
            const size_t i = index(x, y);
            switch (pixelClass(x, y)) {
                case PixelClass::Empty:
                    image.at(x, y) = mSamplePos[i] != 0xFF ? Rgb(0.05) : Rgb(0.0);
                    break;
                case PixelClass::Simple:
                    image.at(x, y) = Rgb(0.6, 0.1, 0.8);
                    break;
                case PixelClass::Complex:
                    image.at(x, y) = Rgb(0.1, 0.8, 0.1);
                    break;
            }
        }
    }
    return image;
}

}  // namespace penumbra
