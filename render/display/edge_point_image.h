#pragma once
// The edge-and-point image (EPI) of Bala, Walter, Greenberg 2003, §4–5: projected edges and
// reprojected shaded points combined per pixel with subpixel precision, then reconstructed
// by table-driven, edge-respecting interpolation and anti-aliasing. Pure 2D image-space code:
// it does not know where edges and points come from.
//
// Index: ScreenEdge · ScreenPoint · EpiStageTimes · EpiOptions · PixelClass · EdgePointImage
//
// Pixel coordinates: px grows right, py grows down; pixel (i, j) covers [i, i+1) × [j, j+1).

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <glm/glm.hpp>
#include <limits>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "render/display/reachability.h"
#include "render/image.h"
#include "solver/scene.h"

namespace penumbra {

/// A projected discontinuity edge in pixel coordinates.
struct ScreenEdge {
    enum class Kind : uint8_t { Silhouette, Sharp, Shadow };
    glm::dvec2 a{0.0};  ///< endpoints (pixels); may lie outside the image
    glm::dvec2 b{0.0};
    /// Camera-space depth (distance along the view axis) at the endpoints, for conservative
    /// occlusion culling (§4.5). A non-positive or non-finite depth disables culling.
    double depthA = 0.0;
    double depthB = 0.0;
    Kind kind = Kind::Silhouette;
    std::string toString() const;
};

/// A reprojected shaded point from the render cache.
struct ScreenPoint {
    glm::dvec2 position{0.0};  ///< sub-pixel position (pixels)
    double depth = 0.0;        ///< camera-space depth; the nearest point per pixel is kept
    Rgb colour{0.0};           ///< radiance, linear
    int age = 0;               ///< frames since shaded (carried for the render cache)
    /// How far the colour is the pixel's own value (epiTrust): 0 not known to be (a point
    /// shaded for another view, reprojected: it may be hidden in this one), n in 1…254 the mean
    /// of n samples of the same pixel, kEpiTrustExact a value without sampling noise
    /// (ShadedPoint::exact). The reconstruction shows a pixel's own point in proportion to it
    /// (EpiOptions::ownPointPrior).
    std::uint8_t trust = 0;
    std::string toString() const;
};

/// ScreenPoint::trust of an exact point.
inline constexpr std::uint8_t kEpiTrustExact = 255;
/// ScreenPoint::trust of a point shaded for the current view: exact, or the mean of `samples`
/// (≥ 1) noisy samples.
inline std::uint8_t epiTrust(bool exact, int samples) {
    return exact ? kEpiTrustExact
                 : static_cast<std::uint8_t>(std::clamp(samples, 1, kEpiTrustExact - 1));
}

/// Whether the EPI keeps a point (§4.3): finite values, inside the width × height raster.
inline bool epiKeepsPoint(const ScreenPoint& p, int width, int height) {
    return std::isfinite(p.position.x) && std::isfinite(p.position.y) && std::isfinite(p.depth) &&
           std::isfinite(p.colour.x) && std::isfinite(p.colour.y) && std::isfinite(p.colour.z) &&
           p.position.x >= 0.0 && p.position.y >= 0.0 && p.position.x < width &&
           p.position.y < height;
}

/// The 4-bit sample position (§4.3) of a kept point in its pixel: cx + 4·cy of the 4×4 cell.
inline std::uint8_t epiSampleCode(const glm::dvec2& position) {
    const int x = static_cast<int>(position.x);
    const int y = static_cast<int>(position.y);
    const int cx = std::min(3, static_cast<int>((position.x - x) * 4.0));
    const int cy = std::min(3, static_cast<int>((position.y - y) * 4.0));
    return static_cast<std::uint8_t>(cx + 4 * cy);
}

/// The EPI's per-pixel point arrays (row-major, width × height), for a producer that already
/// holds at most one point per pixel to write in place of build()'s placement (the render
/// cache, RenderCache::reproject(camera, EpiPointArrays)): per pixel the kept point's depth,
/// colour, 4-bit position and trust, or +inf, zero, 0xFF and 0 without one.
struct EpiPointArrays {
    double* depth = nullptr;
    glm::vec3* colour = nullptr;
    std::uint8_t* position = nullptr;
    int width = 0, height = 0;  ///< the raster the arrays span
    std::uint8_t* trust = nullptr;

    /// Pixel k's sample: `p` when the EPI keeps it (epiKeepsPoint), else none (also for
    /// nullptr).
    void place(std::size_t k, const ScreenPoint* p) const {
        const bool kept = p && epiKeepsPoint(*p, width, height);
        depth[k] = kept ? p->depth : std::numeric_limits<double>::infinity();
        colour[k] = kept ? glm::vec3(p->colour) : glm::vec3(0.0f);
        position[k] = kept ? epiSampleCode(p->position) : 0xFF;
        trust[k] = kept ? p->trust : 0;
    }
};

/// Milliseconds spent in each stage of the last build()/reconstruct() (Table 2's columns).
struct EpiStageTimes {
    double pointsMs = 0;         ///< nearest point per pixel, 4-bit positions
    double depthFilterMs = 0;    ///< §4.5 conservative 4×4 block depth
    double rasterizeMs = 0;      ///< §4.5 edge rasterization to 1/8-pixel intersections
    double classifyMs = 0;       ///< §4.1/4.5 empty/simple/complex, edge codes, primaries
    double reachabilityMs = 0;   ///< §5.2
    double interpolateMs = 0;    ///< §5.3
    double antiAliasMs = 0;      ///< §5.3 anti-aliasing pass
    double complexFilterMs = 0;  ///< §5.4
    double smoothMs = 0;         ///< edge-free smoothing and own points (EpiOptions)
    double buildMs() const { return pointsMs + depthFilterMs + rasterizeMs + classifyMs; }
    /// Reachability + interpolation + anti-aliasing: DESIGN.md's "reconstruct_ms".
    double reconstructMs() const { return reachabilityMs + interpolateMs + antiAliasMs; }
    std::string toString() const;
};

/// Switches for the optional parts of the pipeline (all on reproduces the paper).
struct EpiOptions {
    bool cullOccludedEdges = true;  ///< §4.5 depth culling against the filtered point depths
    /// §4.5 offset added to a 4×4 block's maximum point depth, relative to that depth:
    /// depthSlack + densitySlack · (fraction of the block's 16 pixels without a point).
    double depthSlack = 0.02;
    double densitySlack = 0.25;
    bool antiAlias = true;      ///< §5.3 anti-aliasing of simple pixels
    bool complexFilter = true;  ///< §5.4 subpixel filter for complex pixels
    /// §5.4: a complex pixel with no point in its 3×3 neighbourhood takes its regions' sums of
    /// the estimate directly; false runs the general filter for it (the reference, equal bit
    /// for bit).
    bool complexFilterShortcut = true;
    /// §5.4 in dense clusters (0 turns it off, the paper's filter everywhere): a complex pixel
    /// with at least this many complex pixels in its 3×3 neighbourhood (itself included)
    /// keeps its estimate, the render cache's 5×5 interpolation. Its subpixel regions there
    /// reach few usable samples, one or two each, and were noisier than the estimate
    /// (armadillo-field's statues, 50k triangles in 40–60 pixels: 0.000697 against 0.000660
    /// of the mean squared error), at half the filter's time.
    int denseComplexLimit = 0;
    /// Dense regions, part of the edge-free smoothing (used when smoothRadius and
    /// denseComplexLimit are positive; 0 turns it off): every pixel, of any class, with at
    /// least denseComplexLimit complex pixels in its 3×3 neighbourhood takes the mean of the
    /// points in its (2·denseRadius+1)² box, edges or not, when the box holds at least two.
    /// There the edges are finer than the pixels (armadillo-field's statues: silhouettes of
    /// 50k triangles in 40–60 pixels, every pixel of a statue complex), so no pixel's regions
    /// can be resolved, and the pixel's value, an average over geometry finer than itself,
    /// is best estimated by the neighbourhood's mean, as a texture is prefiltered. Against the
    /// converged reference: armadillo-field 0.0407 → 0.0373 with radius 3 (0.0387 with 2,
    /// 0.0407 with 1); robot-room, whose complex pixels follow resolvable silhouettes, 0.0070
    /// → 0.0087.
    int denseRadius = 0;
    /// Edge-free smoothing (an extension of §5.3; 0 turns it off). An empty pixel whose
    /// (2r+1)² box holds no simple or complex pixel lies in one region that no edge crosses
    /// (no silhouette, crease or shadow boundary). It takes the mean of every point in the
    /// largest such box, r = min(d − 1, smoothRadius) for the pixel's Chebyshev distance d
    /// to the nearest edge pixel, instead of the peaked 5×5 interpolation. The points' own
    /// noise (stochastic shadow rays in penumbrae) then averages out over (2r+1)² × density
    /// points, where the peaked filter keeps most of it. That from d = 3 on; empty pixels
    /// nearer an edge pixel (d = 1, 2) take §5.3's filter once more over the primary colours
    /// of themselves and their reachable 5×5 neighbours (those with a positive weight), which
    /// respects edges as §5.3 does with about twice its support. Simple and complex pixels
    /// keep §5.3–5.4 unchanged.
    int smoothRadius = 0;
    /// Own points (last stage; ≤ 0 turns it off, the paper's reconstruction): a pixel no edge
    /// crosses (class empty) that holds its own point shows that point's colour c in
    /// proportion to its trust (ScreenPoint::trust): c itself when exact, else
    /// (n·c + k·r)/(n + k) for the mean c of n samples, the reconstruction r and k this prior;
    /// a point of trust 0 (shaded for another view) is not shown. The filters above exist for
    /// sparse and noisy points; a pixel's own exact value is its value, and averaging it with its
    /// neighbours blurs what no edge marks (the facets of a low-poly mesh, whose creases are below
    /// the sharp-edge cutoff). So a still view, whose pixels all come to hold their own points,
    /// converges to every pixel's own shading.
    double ownPointPrior = 0;
    /// Build and reconstruct on oneTBB (bands and rows); false runs every stage serially, the
    /// reference the parallel stages must equal bit for bit.
    bool parallel = true;
    std::string toString() const;
};

/// A rectangle of pixels, [x0, x1) × [y0, y1); empty when x1 ≤ x0 or y1 ≤ y0.
struct PixelWindow {
    int x0 = 0, y0 = 0, x1 = 0, y1 = 0;
    bool empty() const { return x1 <= x0 || y1 <= y0; }
    long long area() const { return empty() ? 0 : static_cast<long long>(x1 - x0) * (y1 - y0); }
    /// The smallest window holding both (an empty one adds nothing).
    PixelWindow unite(const PixelWindow& o) const {
        if (empty()) return o;
        if (o.empty()) return *this;
        return {std::min(x0, o.x0), std::min(y0, o.y0), std::max(x1, o.x1), std::max(y1, o.y1)};
    }
    /// Grown by r pixels on every side, then clipped to the width × height raster.
    PixelWindow grownWithin(int r, int width, int height) const {
        if (empty()) return *this;
        return {std::max(0, x0 - r), std::max(0, y0 - r), std::min(width, x1 + r),
                std::min(height, y1 + r)};
    }
    bool operator==(const PixelWindow&) const = default;
    std::string toString() const;
};

/// §4.1 pixel classification.
enum class PixelClass : uint8_t { Empty = 0, Simple = 1, Complex = 2 };

/// The edge-and-point image and its reconstruction. Not thread-safe; build() and
/// reconstruct() use oneTBB internally (rows in parallel; results do not depend on the
/// thread count).
class EdgePointImage {
public:
    /// Throws std::invalid_argument unless width and height are positive.
    EdgePointImage(int width, int height, EpiOptions options = {});

    /// Builds the EPI (§4): keeps the nearest point per pixel with its 4-bit position
    /// (points outside the image or with non-finite values are ignored), filters the point
    /// depths over 4×4 blocks, rasterizes the edges' intersections with all pixel boundaries
    /// (and the half-pixel lines for §5.4) to 1/8 pixel, dropping intersections behind the
    /// filtered depth, classifies pixels, stores the 10-bit edge codes and chooses each
    /// simple pixel's primary region (§5.1). Edges with non-finite endpoints are ignored.
    void build(const std::vector<ScreenEdge>& edges, const std::vector<ScreenPoint>& points);
    /// The point arrays, for a producer to place the points (see EpiPointArrays); then
    /// build(edges). Valid for the life of the EPI.
    EpiPointArrays pointArrays() {
        return {mSampleDepth.data(), mSampleColour.data(), mSamplePos.data(), mWidth, mHeight,
                mSampleTrust.data()};
    }
    /// build() with the points already written through pointArrays() (every pixel); the
    /// stage times' pointsMs is then 0 (the producer's time).
    void build(const std::vector<ScreenEdge>& edges);

    /// Reconstructs an image (radiance, linear) from the last build(). With useEdges:
    /// reachability over 5×5 (§5.2), renormalized peaked interpolation of the primary
    /// regions (§5.3), edge-indexed anti-aliasing of simple pixels (§5.3) and the complex
    /// pixel filter (§5.4). Without: the plain render-cache interpolation of the same points
    /// with the same filter, ignoring edges (the comparison baseline). Pixels with no
    /// sample within reach fall back to the interpolation ignoring edges, and to black when
    /// there is none within 5×5 either.
    Image reconstruct(bool useEdges = true);

    /// How far a pixel's point or edges reach into the reconstruction, in pixels (Chebyshev):
    /// the 4×4 depth blocks, §5.2's 5×5 reachability and §5.3's filter over it, the
    /// anti-aliasing and complex-pixel neighbourhoods, and the smoothing's boxes and edge
    /// distance (EpiOptions::smoothRadius, denseRadius).
    int reconstructionReach() const;
    /// build() and reconstruct() redone on a window of the raster only: for a producer whose
    /// points and edges changed in a few pixels since the last frame (a still camera, an
    /// object moving), at a cost in proportion to the window's area instead of the raster's.
    /// Requires a reconstruct(useEdges) or reconstructWindow(…, useEdges) before it, since
    /// which the point arrays (pointArrays(), holding this frame's point in every pixel) and
    /// the edges differ only in the pixels of `changed` (an edge that appeared or went: in
    /// every pixel it crosses). `image` is that call's output; the pixels within
    /// reconstructionReach() of `changed` are replaced in it, the rest kept. The result
    /// equals a whole build() and reconstruct() (up to the rounding of the smoothing's
    /// summed-area sums). Afterwards holes(), holeCount(), interpolationWeights(),
    /// pixelClass() and countPixels() cover the whole raster; the other per-pixel state and
    /// the stage times are the window's, and a reconstruct() needs a build() first.
    void reconstructWindow(const std::vector<ScreenEdge>& edges, const PixelWindow& changed,
                           bool useEdges, Image& image);

    /// Empty pixels black (dark grey with a point), simple purple, complex green (as the
    /// paper's Figure 7) — the edges as the EPI sees them.
    Image classificationImage() const;

    const EpiStageTimes& stageTimes() const { return mTimes; }
    const EpiOptions& options() const { return mOptions; }
    /// EpiOptions::denseComplexLimit from the next reconstruct() on (a display's moving frames
    /// keep dense clusters' estimates; InteractiveDisplayOptions::movingDenseComplexLimit).
    void setDenseComplexLimit(int limit) { mOptions.denseComplexLimit = limit; }
    int width() const { return mWidth; }
    int height() const { return mHeight; }

    // ---- Per-pixel state (valid after build) ----
    PixelClass pixelClass(int x, int y) const;
    /// 10-bit edge code (§4.2): kEdgeCodeEmpty, kEdgeCodeComplex or a simple code.
    uint16_t edgeCode(int x, int y) const { return mEdgeCode[index(x, y)]; }
    /// 4-bit sample position (§4.3): cx + 4·cy of the 4×4 cell, or −1 without a point.
    int samplePosition(int x, int y) const;
    /// The kept point's colour (zero without one).
    Rgb sampleColour(int x, int y) const;
    /// True when the pixel's point takes part in edge-respecting interpolation: it exists,
    /// the pixel is not complex, and it is not edge-ambiguous.
    bool sampleUsable(int x, int y) const { return mUsable[index(x, y)] != 0; }
    /// §5.1: for simple pixels, whether region 1 (see reachability.h) is the primary one.
    bool primaryIsRegion1(int x, int y) const;
    /// The 4-bit neighbour code used by the reachability tables.
    uint8_t neighbourCode(int x, int y) const { return mNeighbourCode[index(x, y)]; }
    /// 8-bit intersection masks of the pixel's top, right, bottom and left boundary
    /// segments, bit k = k-th eighth along +x (horizontal) or +y (vertical).
    std::array<uint8_t, 4> boundaryMasks(int x, int y) const;
    /// 8-bit intersection masks of the pixel's half-pixel lines (§5.4): the horizontal line
    /// y + ½ and the vertical line x + ½, bits as boundaryMasks'.
    std::array<uint8_t, 2> halfLineMasks(int x, int y) const;

    /// §5.2 reachability from pixel (x, y) to each pixel of its 5×5 neighbourhood, by
    /// neighbour lookups, chaining and combining outward from the centre: 4-bit masks
    /// (kReachPP…) indexed (dy + 2)·5 + (dx + 2); pixels outside the image get 0. The
    /// centre's own entry is PP (and SS when simple); a complex centre reaches nothing.
    std::array<uint8_t, 25> computeReachability(int x, int y) const;

    /// After reconstruct(true): bit k of the 24-bit primary-to-primary mask, k running over
    /// the 5×5 neighbourhood row by row without the centre.
    uint32_t primaryReachability(int x, int y) const { return mReach[index(x, y)] & 0xFFFFFFu; }
    /// After reconstruct(true): bit k of the 8-bit mask (the 3×3 ring row by row without the
    /// centre) set when the pixel's secondary region reaches that neighbour's primary region.
    uint8_t secondaryReachability(int x, int y) const { return mSecondaryReach[index(x, y)]; }
    /// After reconstruct(): per pixel the total filter weight of the samples used, before
    /// renormalization (§5.3 prioritized sampling: low weight → high priority; 0 → none).
    const std::vector<float>& interpolationWeights() const { return mWeight; }
    /// After reconstruct(): 1 for the pixels whose value came from no point at all (no sample
    /// within the 5×5 filter and none in a smoothing box or ring): holes the caller fills
    /// (InteractiveDisplay's fallback); they are black in the reconstruction.
    const std::vector<uint8_t>& holes() const { return mHole; }
    /// After reconstruct(): how many pixels holes() marks.
    size_t holeCount() const { return mHoleCount; }
    /// After reconstruct(true): the pixel's primary colour (§5.3; a complex pixel's estimate),
    /// before anti-aliasing, the complex filter and smoothing.
    Rgb primaryColour(int x, int y) const { return Rgb(mPrimary[index(x, y)]); }

    /// Pixel counts by class (counted by build(), O(1)) and the number of culled
    /// intersections of the last build().
    size_t countPixels(PixelClass c) const;
    size_t culledIntersections() const { return mCulledIntersections; }
    std::string toString() const;

private:
    size_t index(int x, int y) const { return static_cast<size_t>(y) * mWidth + x; }
    void placePoints(const std::vector<ScreenPoint>& points);
    /// placePoints()' parallel fast path for points in strictly increasing pixel order (the
    /// render cache's); false, with the point state undefined, for any other input.
    bool placeSortedPoints(const std::vector<ScreenPoint>& points);
    void filterDepth();
    void rasterizeEdges(const std::vector<ScreenEdge>& edges);
    /// The intersections of one edge with the boundary lines owned by rows [rowLo, rowHi)
    /// (horizontal lines k/2 for k in [2·rowLo, kLineHi]); counts culled intersections.
    void rasterizeEdge(const ScreenEdge& e, int rowLo, int rowHi, int kLineHi, size_t& culled);
    void classifyPixels();
    /// §5.2 reachability of every pixel (mReach, mSecondaryReach): the serial reference or
    /// the parallel two passes that reuse prior scanlines' masks.
    void computeReachabilityMap();
    /// mNearEdge: per padded pixel, whether its column of 5 rows (y − 2 .. y + 2) holds an
    /// edge pixel, so that nearEdge() reads 5 bytes instead of the 5×5 codes.
    void markNearEdge();
    /// Whether the 5×5 neighbourhood of (x, y) holds any simple or complex pixel (after
    /// markNearEdge()); pixels far from every edge reach their whole neighbourhood.
    bool nearEdge(int x, int y) const;
    /// computeReachabilityMap()'s serial reference: computeReachability() for every pixel
    /// near an edge.
    void computeReachabilityMapSerial();
    /// Parallel pass 1: the propagation to the cells with dy ≥ 0 (mReachLower), the secondary
    /// ring's lower bits and, for the row below, mPartnerReach.
    void propagateLowerReachability();
    /// Parallel pass 2: mReach and mSecondaryReach from pass 1's masks, the cells on prior
    /// scanlines mirrored from the pixels there.
    void mirrorUpperReachability();
    void interpolatePlain();
    void interpolatePrimary(Image& out);
    /// EpiOptions::smoothRadius: replaces the interpolation of empty pixels far from every
    /// edge by a wide average of the points.
    void smoothEdgeFreeRegions(Image& out);
    /// EpiOptions::ownPointPrior: empty pixels with their own point show it by its trust.
    void showOwnPoints(Image& out) const;
    /// Smoothing: mEdgeDistance, each pixel's Chebyshev distance to the nearest simple or
    /// complex pixel, capped at `cap`.
    void computeEdgeDistance(int cap);
    /// Smoothing: mSummedArea, the summed-area table of (colour, 1) over the points (from
    /// mPaddedAll), for boxSum().
    void buildSummedAreaTable();
    /// Smoothing: the sum of (colour, 1) over the points of the (2r+1)² box around (x, y),
    /// clipped to the image (after buildSummedAreaTable()).
    glm::dvec4 boxSum(int x, int y, int r) const;
    /// EpiOptions::denseRadius: (x, y) takes the mean of the points in its box when it holds
    /// two or more (and is then no hole); false leaves the pixel as it is.
    bool writeDenseMean(Image& out, int x, int y);
    /// Smoothing: empty pixels farther than the ring from every edge pixel take the mean of
    /// the largest box around them that no edge crosses, radius at most R.
    void smoothBoxes(Image& out, int R);
    /// Smoothing: empty pixels in the ring near an edge pixel take §5.3's filter once more
    /// over reachable primary colours (dense ones, with `dense`, their box mean instead).
    void smoothNearEdges(Image& out, bool dense);
    /// holes() from the filter weights (and the smoothing's writes, already in mHole).
    void markHoles(bool useEdges);
    void antiAlias(Image& out) const;
    void markDenseComplex();
    /// §5.4 subpixel filter of the complex pixels (mComplexPixels), rows and pixels on
    /// oneTBB.
    void filterComplexPixels(Image& out);
    /// §5.4: mComplexPixels, the complex pixels' indices in pixel order; returns each row's
    /// first position in it (height + 1 entries).
    std::vector<size_t> listComplexPixels();
    /// EpiOptions::denseComplexLimit: complex pixels in dense clusters (mDense) keep their
    /// estimate in `out` and leave mComplexPixels; mFiltered marks those that remain.
    void keepDenseComplexEstimates(const std::vector<size_t>& rowStart, Image& out);
    /// §5.4: mSubCode and mSubType, the 4 subpixel edge codes and types of every pixel in
    /// the 3×3 neighbourhood of a complex pixel to filter (with `dense`, those in mFiltered).
    void computeSubpixelCodes(bool dense);
    /// §5.4 for one complex pixel (a pixel index): its 4 subpixels' regions coloured from the
    /// samples of the 3×3 neighbourhood that reach them, written to `out`.
    void filterComplexPixel(int pixel, Image& out) const;
    /// EpiOptions::complexFilterShortcut: when no point lies in the pixel's 3×3 neighbourhood,
    /// writes its regions' sums of the estimate, as the general filter would, and returns
    /// true; false (nothing written) otherwise.
    bool filterSampleFreeComplexPixel(int pixel, Image& out) const;
    /// One complex pixel's subpixel neighbourhood, codes, regions and samples (defined in
    /// the .cpp).
    struct ComplexNeighbourhood;
    /// The subpixel codes and types of the 6×6 subpixels around pixel (x, y) into `nb`.
    void gatherSubpixelCodes(int x, int y, ComplexNeighbourhood& nb) const;
    /// The points of the 3×3 pixels around (x, y), placed in their subpixel regions of `nb`
    /// (after gatherSubpixelCodes()).
    void gatherSubpixelSamples(int x, int y, ComplexNeighbourhood& nb) const;
    size_t paddedIndex(int x, int y) const {
        return static_cast<size_t>(y + 2) * (mWidth + 4) + (x + 2);
    }

    int mWidth = 0;
    int mHeight = 0;
    EpiOptions mOptions;
    EpiStageTimes mTimes;
    size_t mCulledIntersections = 0;

    // Points (§4.3): nearest per pixel.
    std::vector<glm::vec3> mSampleColour;
    std::vector<double> mSampleDepth;   ///< +inf without a point
    std::vector<uint8_t> mSamplePos;    ///< 0..15, 0xFF without a point
    std::vector<uint8_t> mSampleTrust;  ///< ScreenPoint::trust, 0 without a point
    std::vector<uint8_t> mUsable;       ///< see sampleUsable()
    std::vector<uint8_t> mPointBand;    ///< placePoints() scratch: band of rows per point
    std::vector<std::pair<uint8_t, uint8_t>> mChunkBands;  ///< and per 4096 points their range
    /// Per chunk of points: first and last accepted pixel (−1: none), or sorted = false.
    struct ChunkRange {
        long long first = -1, last = -1;
        bool sorted = true;
    };
    std::vector<ChunkRange> mChunkRanges;  ///< placeSortedPoints() scratch
    std::vector<float> mBlockDepth;        ///< §4.5 filtered depth per 4×4 block (+inf: none)
    int mBlocksX = 0;
    int mBlocksY = 0;

    // Edge rasterization (§4.5, §5.4): 8-bit intersection masks of boundary segments.
    std::vector<uint8_t> mHorizontal;     ///< line y = j, x ∈ [i, i+1): (H+1) × W
    std::vector<uint8_t> mVertical;       ///< line x = i, y ∈ [j, j+1): H × (W+1)
    std::vector<uint8_t> mHorizontalMid;  ///< line y = j + ½: H × W
    std::vector<uint8_t> mVerticalMid;    ///< line x = i + ½: H × W
    // rasterizeEdges() scratch: per edge its bands (first, last), per chunk of edges and band
    // a count then an offset, and the edges of each band at mBandEdgeStart[band].
    std::vector<std::pair<uint8_t, uint8_t>> mEdgeBands;
    std::vector<uint8_t> mRowBand;  ///< rasterizeEdges: each row's band
    std::vector<uint32_t> mChunkBandCount;
    std::vector<size_t> mBandEdgeStart;
    std::vector<uint32_t> mBandEdges;

    // Classification (§4.1–4.2, §5.1).
    std::vector<uint16_t> mEdgeCode;
    std::vector<uint8_t> mNeighbourCode;

    std::vector<uint8_t> mPaddedCode;            ///< neighbour codes, 2-pixel complex border
    std::vector<std::array<int, 3>> mRowCounts;  ///< per row: empty, simple, complex pixels
    std::array<size_t, 3> mPixelCounts{};        ///< their sums (countPixels)

    // Reconstruction (§5.2–5.4).
    std::vector<uint32_t> mReach;          ///< 24-bit primary-to-primary masks (+ all-empty flag)
    std::vector<uint8_t> mSecondaryReach;  ///< bit k: secondary reaches 3×3 neighbour k's primary
    std::vector<uint32_t> mReachLower;     ///< §5.2 reuse scratch: mReach's cells with dy ≥ 0
    std::vector<uint8_t> mPartnerReach;    ///< and bit dx+1: primary reaches (dx, +1)'s secondary
    std::vector<glm::vec4> mPaddedAll;     ///< (colour, 1) of every point, 2-pixel zero border
    std::vector<glm::vec4> mPaddedUsable;  ///< the same for usable points only
    std::vector<glm::vec4> mRowSums;       ///< horizontal pass of the plain filter
    std::vector<glm::vec3> mPlain;         ///< plain (edge-ignoring) interpolation
    std::vector<float> mPlainWeight;
    std::vector<glm::vec3> mPrimary;        ///< primary-region colours
    std::vector<uint8_t> mComplexRow;       ///< complex pixels in each 1×3 (markDenseComplex)
    std::vector<uint8_t> mDense;            ///< 1: denseComplexLimit reached in the 3×3
    std::vector<uint8_t> mEdgeDistanceRow;  ///< smoothing: distance along the row to an edge pixel
    std::vector<uint8_t> mEdgeDistance;     ///< smoothing: Chebyshev distance, capped
    std::vector<glm::dvec4> mSummedArea;    ///< smoothing: summed-area table of (colour, 1)
    std::vector<uint8_t> mNearEdge;         ///< padded scratch: edges within 5 rows
    std::vector<float> mWeight;             ///< interpolation weight before renormalization
    std::vector<uint8_t> mHole;             ///< holes(): 1 where no point reached the pixel
    size_t mHoleCount = 0;
    std::vector<int> mComplexPixels;  ///< §5.4 scratch: the complex pixels' indices
    std::vector<uint16_t> mSubCode;   ///< §5.4 scratch: 4 subpixel edge codes per marked pixel
    std::vector<uint8_t> mFiltered;   ///< §5.4 scratch: complex pixels the filter runs on
    std::vector<uint8_t> mSubType;    ///< §5.4 scratch: their neighbour types

    // reconstructWindow(): the window's own EPI (kept while its size holds) and its edges.
    std::unique_ptr<EdgePointImage> mWindow;
    std::vector<ScreenEdge> mWindowEdges;
};

/// False only when EdgePointImage::build() would record no intersection of `e` with any
/// boundary or half-pixel line of a width × height image, whatever the points: an endpoint is
/// not finite, both endpoints lie in one half-pixel cell (no line x = k/2 or y = k/2 between
/// them), or the edge lies wholly left of, right of, above or below the image (with a slack
/// beyond the rounding of the rasterizer's crossing coordinates). Dropping such edges before
/// build() leaves every mask, code, culled count and reconstructed pixel unchanged.
bool edgeMayMark(const ScreenEdge& e, int width, int height);

namespace detail {

/// std::floor(v), equal bit for bit for every double (−0.0 and integers come back as they
/// are, NaN and infinities unchanged), without a libm call: truncation and a correction for
/// |v| < 2^52, where larger magnitudes are integral already. The rasterizer's floor.
inline double floorExact(double v) {
    if (!(v > -4503599627370496.0 && v < 4503599627370496.0)) return v;
    const double t = static_cast<double>(static_cast<long long>(v));
    return t > v ? t - 1.0 : (t == v ? v : t);
}

}  // namespace detail

}  // namespace penumbra
