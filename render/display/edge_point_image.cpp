// The edge-and-point image (Bala, Walter, Greenberg 2003 §4–5); see edge_point_image.h. This
// file builds it: the points, the edges and the pixel classes; epi_reconstruction.cpp filters
// and reconstructs it.
//
// Index: toString · construction · points (§4.3) · depth filter (§4.5) · edge rasterization
// (§4.5) · classification (§4.1, §4.2, §5.1) · reachability (§5.2)

#include "render/display/edge_point_image.h"

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
#include "render/display/edge_point_image_internal.h"

namespace penumbra {

using namespace epi_detail;

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

}  // namespace penumbra
