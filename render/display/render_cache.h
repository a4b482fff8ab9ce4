#pragma once
// The render cache (Walter, Drettakis, Parker 1999; Walter et al. 2002) as the edge-and-point
// renderer uses it (Bala, Walter, Greenberg 2003 §4.3): a fixed-size cache of shaded 3D points,
// reprojected to every new camera, depth-filtered against occlusion errors, and a priority
// image from which each frame's few new sample requests are drawn.
//
// Index: CachePoint · options · RenderCache (insert, reproject, requests,
//        invalidation, plain interpolation)
//
// Per frame, in order: insert() the points the shader finished, reproject() to the frame's
// camera (the visible points feed the EPI), requestSamples() for the shader, and optionally
// interpolatedImage() for a plain (edge-unaware) reconstruction.

#include <cstdint>
#include <functional>
#include <glm/glm.hpp>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <unordered_set>
#include <vector>

#include "render/camera_rays.h"
#include "render/display/edge_point_image.h"
#include "render/display/point_shader.h"
#include "render/image.h"
#include "solver/scene.h"

namespace penumbra {

// ScreenPoint (a cached point as seen in the current frame: sub-pixel position in CameraRays
// pixel coordinates, view depth along the camera's forward axis in metres, radiance, and age in
// frames reprojected since shaded, 0 in its first frame) is the EPI's input type, defined in
// render/display/edge_point_image.h.

/// One cached shaded point (Walter et al. 1999 §3). Its age and whether it survived the last
/// reprojection are kept by the cache (RenderCache::age, RenderCache::visible), in arrays
/// the per-frame passes stream through without touching these records.
struct CachePoint {
    Vec3 position{0.0};  ///< world space; misses sit kMissDistance along their ray
    Rgb colour{0.0};     ///< radiance, W/m²/sr
    int object = -1;     ///< Discretization object index, −1 for a miss
    int element = -1;
    std::uint64_t frame = 0;    ///< frame the point was requested in
    bool exact = false;         ///< ShadedPoint::exact (of every sample merged into it)
    int samples = 1;            ///< samples of its pixel merged into the colour (their mean)
    std::uint64_t shading = 0;  ///< ShadedPoint::shading: the shader state of its samples
    std::string toString() const;
};

struct RenderCacheOptions {
    /// Depth culling (after Walter et al. 1999): a point is taken as occluded when at least
    /// half of the points in its (2·depthRadius+1)² pixel neighbourhood are nearer than its
    /// depth / (1 + depthMargin).
    double depthMargin = 0.1;
    int depthRadius = 1;
    /// New samples per frame as a fraction of the pixels (Bala et al.: 1–3%), used when
    /// requestSamples() is given no budget.
    double sampleFraction = 0.02;
    int tileSize = 8;  ///< requests are stratified over tiles of this many pixels square
    /// Priority of a pixel with a point: ageWeight·age/(age + ageScale) +
    /// contrastWeight·(local luminance contrast in 3×3); an empty pixel has priority 1, above
    /// any pixel with a point.
    double ageWeight = 0.45;
    double ageScale = 16;
    double contrastWeight = 0.45;
    /// Bala et al. §5.3 prioritized sampling: once applyInterpolationFeedback() has the
    /// reconstruction's filter weights, an empty pixel's priority falls with the total weight
    /// w of the samples its interpolation reached, emptyFloor + (1 − emptyFloor)/(1 + w/
    /// feedbackWeight): 1 with no reachable sample, so the pixels edges cut off from their
    /// neighbours' samples are sampled first. feedbackWeight 0 keeps every empty pixel at 1.
    double emptyFloor = 0.5;
    double feedbackWeight = 0.25;
    /// A pixel requested in one of the last holdFrames frames is not requested again (its
    /// sample may still be in the shader's queue).
    int holdFrames = 2;
    /// Samples of one pixel accumulate (0 turns it off: each new point is a point of its own,
    /// and the pixel shows the youngest). A new point on the element of the point its pixel
    /// showed in the last reprojection, at the same depth (within 1%), is merged into that
    /// point instead of added: the colour becomes the mean of up to mergeSamples samples (a
    /// running mean, then an exponential one of that weight) shaded under the same shader
    /// state (ShadedPoint::shading; a sample of another state starts the mean again), exact
    /// while every sample was (ShadedPoint::exact). A still view's pixels thus converge to their
    /// own mean over their footprint (noise in penumbrae, detail finer than a pixel) instead of
    /// showing the last sample.
    int mergeSamples = 0;
    std::uint64_t seed = 1;
    /// reproject() on oneTBB over pixel bands (z-buffer) and rows (culling, output, priority),
    /// requestSamples() over tiles; false runs the plain serial references. Both give
    /// bit-identical results.
    bool parallel = true;
    /// A still camera (the parallel reprojection into an EPI's arrays, the same camera and
    /// arrays as the last one): only the pixels the points changed since then reach (their
    /// old and new pixels and, for the culling, the neighbours) are redone, at a cost in
    /// proportion to the changes instead of the cache. The result equals a whole reprojection
    /// bit for bit; beyond incrementalShare of the points changed, the whole one runs.
    bool incremental = true;
    double incrementalShare = 0.25;
};

class RenderCache {
public:
    /// An image raster of width × height pixels and room for `capacity` points (Walter et al.
    /// use a few times the pixel count). Throws std::invalid_argument for non-positive sizes.
    RenderCache(int width, int height, std::size_t capacity, RenderCacheOptions options = {});
    RenderCache(const RenderCache&) = delete;
    RenderCache& operator=(const RenderCache&) = delete;

    // -- Points ----------------------------------------------------------------------------

    /// Adds shaded points with age 0. When the cache is full, the points replaced are those
    /// not visible in the last frame first, then the oldest (largest age). Never exceeds
    /// capacity(); of a batch larger than the capacity only the last capacity() points stay.
    /// With RenderCacheOptions::mergeSamples, a point of the same pixel, element and depth as
    /// a visible point of the last reprojection is merged into it (age 0) instead; shaded
    /// under another shader state (ShadedPoint::shading), it replaces that point's value.
    void insert(const std::vector<ShadedPoint>& points);
    void insert(const ShadedPoint& point) { insert(std::vector<ShadedPoint>{point}); }

    // -- Per frame -------------------------------------------------------------------------

    /// Starts a frame: projects every cached point with camera.projectToPixel (same raster size
    /// as the cache), keeps the nearest point per pixel (of near-equal depths, within 1%, the
    /// youngest), removes depth-culled points from the image (they stay cached), marks the
    /// survivors visible, then increments every point's age. Returns the visible points in
    /// row-major pixel order, at most one per pixel.
    const std::vector<ScreenPoint>& reproject(const CameraRays& camera);
    /// The same reprojection, with the visible points written straight into an EPI's point
    /// arrays (exactly as EdgePointImage::build would place screenPoints(), empty pixels
    /// included) instead of into the screen point list, which screenPoints() then builds
    /// only when asked: the list and its copy into the EPI were a fifth of the reprojection's
    /// memory traffic. `points` must span this cache's raster.
    /// Throws std::invalid_argument when the camera or `points` spans another raster.
    void reproject(const CameraRays& camera, const EpiPointArrays& points);
    /// The visible points of the last reproject(). After reproject(camera, EpiPointArrays)
    /// the first call builds the list, so (like interpolatedImage()) it writes the cache's
    /// state although const: call it from the thread that owns the cache.
    const std::vector<ScreenPoint>& screenPoints() const {
        if (mScreenPending) buildScreenPoints();
        return mScreen;
    }
    /// How many points the last reproject() kept (screenPoints().size()).
    std::size_t visibleCount() const { return mVisibleCount; }
    /// Whether the last reproject() redid only the changed pixels (RenderCacheOptions::
    /// incremental), and how many pixels it redid then.
    bool lastReprojectionIncremental() const { return mIncrementalFrame; }
    std::size_t lastReprojectedPixels() const { return mReprojectedPixels; }
    /// Per pixel (y·width + x): index into points() of its visible point, or −1. Valid until the
    /// next insert() or invalidation.
    const std::vector<int>& pixelPoints() const { return mPixelPoint; }
    /// Per pixel priority from the last reproject() (Walter et al.: empty pixels first, then
    /// old points and high local contrast), in [0, 1], as applyInterpolationFeedback() left
    /// it.
    const std::vector<double>& priority() const { return mPriority; }
    /// Lowers the priority of the empty pixels of the last reproject() by the total filter
    /// weight their interpolation found (one weight per pixel, row-major, as
    /// EdgePointImage::interpolationWeights(); see RenderCacheOptions::emptyFloor). Throws
    /// std::invalid_argument when the size differs from the raster.
    void applyInterpolationFeedback(const std::vector<float>& weights);
    /// Draws this frame's new sample requests from the priority image: `budget` requests
    /// (negative: sampleFraction × pixels), allocated to tiles in proportion to their summed
    /// priority by systematic sampling, then to each tile's highest-priority pixels, at a
    /// jittered position inside the pixel. What an edit changed comes first: as many of the
    /// requests as there are carried pixels not waiting are drawn among them alone, then as
    /// many as there are stale ones among those, the rest as above. Rays come from `camera`
    /// (the frame's camera).
    /// `changedBudget` more requests may go to carried and stale pixels, up to as many as
    /// there are: after an edit the changed region is re-shaded faster than the budget the
    /// rest of the image needs.
    std::vector<ShadeRequest> requestSamples(const CameraRays& camera, int budget = -1,
                                             int changedBudget = 0);
    /// With `only` true, requestSamples() draws among the pixels an edit changed alone: those
    /// without a point and those whose point is stale or carried (while an object is dragged:
    /// the region its moves changed; the rest waits for the drop).
    void setRequestChangedOnly(bool only) { mRequestChangedOnly = only; }
    /// Leaves out of requestSamples() the pixels whose point is converged: fresh (not stale or
    /// carried) with trust[k] (the last reprojection's ScreenPoint::trust per pixel, as
    /// EpiPointArrays::trust holds it) at least `converged`; and every pixel requested `cap`
    /// times (> 0) since the view, the lighting or the cache's points last changed (a pixel
    /// whose samples fall on different elements, or are culled behind a nearer neighbour,
    /// never converges). A still view so stops asking. nullptr: none left out. `trust` must
    /// outlive the calls.
    void setRequestConverged(const std::uint8_t* trust, std::uint8_t converged, int cap) {
        mConvergedTrust = trust;
        mConverged = converged;
        mRequestCap = cap;
    }
    /// Plain render-cache reconstruction of the last frame (no edges): a pixel with a point
    /// shows it, an empty one the distance-weighted mean of the points within 1, 2 or 3 pixels
    /// (the first ring that has any); black when none.
    Image interpolatedImage() const;

    // -- Invalidation (Bala et al. §7.5; take effect in the next reproject()) ----------------

    /// Drops every point on one of `objects`. Returns how many.
    std::size_t invalidateObjects(const std::unordered_set<int>& objects);
    /// Drops every point within the world-space sphere. Returns how many.
    std::size_t invalidateRegion(const Vec3& centre, double radius);
    /// Drops every point on one of `elements`. Returns how many.
    std::size_t invalidateElements(const std::unordered_set<int>& elements);
    /// Drops point i where drop[i] != 0 (indices of points(); sized as it). Returns how many.
    std::size_t invalidatePoints(const std::vector<std::uint8_t>& drop);
    void clear();

    // -- Keeping points across an edit (instead of dropping them) ----------------------------
    // A point whose lighting changed keeps an estimate of its new colour and is marked stale:
    // its pixel has the highest sampling priority (as an empty one) and a fresh point at the
    // same depth replaces it in the z-buffer, so the shader re-shades changed regions first
    // while nothing goes black meanwhile.

    /// Adds delta[e] to the colour of every point on element e (elements beyond delta: none)
    /// and marks stale the points on the elements with stale[e] != 0. A channel the change
    /// would take below 0 (a point darker than its element, as in a shadow, whose element
    /// lost more light than the point shows) is scaled by the element's relative change
    /// instead, (before[e] + delta[e]) / before[e] with `before` the element's colour before
    /// the change (0 when `before` is empty or holds no light there), and the point is marked
    /// stale. A point shaded at shader state `exactSince` or later (CachePoint::shading) takes
    /// delta[e] − exactPart[e] instead: the part of the change it already holds. Returns the
    /// points marked.
    std::size_t relight(const std::vector<Rgb>& delta, const std::vector<std::uint8_t>& stale,
                        const std::vector<Rgb>& before = {}, const std::vector<Rgb>& exactPart = {},
                        std::uint64_t exactSince = std::numeric_limits<std::uint64_t>::max());
    /// A rigid move of an object's points: every point on `fromObject` moves by `toFromFrom`
    /// (world to world), now lies on `toObject` and element + elementOffset (the version built
    /// from the same mesh at the new place), and is stale. Returns how many moved.
    std::size_t carry(int fromObject, int toObject, const Mat4& toFromFrom, int elementOffset);
    /// Marks stale every point on one of `objects`. Returns how many.
    std::size_t markStale(const std::unordered_set<int>& objects);
    /// Whether point i is stale (relight, carry, markStale) and not yet replaced.
    bool stale(std::size_t i) const { return (mFlags[i] & kStaleFlag) != 0; }
    /// Points for which `hidden(position, object)` holds are left out of every reprojection
    /// until the next setHidden (they stay cached): those behind an object that moved in front
    /// of them, for this view. An empty function shows every point again. Called in parallel
    /// (oneTBB). Returns how many are hidden.
    std::size_t setHidden(const std::function<bool(const Vec3& position, int object)>& hidden);
    /// Whether point i is hidden by the last setHidden.
    bool hidden(std::size_t i) const { return (mFlags[i] & kHiddenFlag) != 0; }
    /// Whether point i was carried (carry) and not yet replaced: stale, and with no estimate
    /// of its new lighting (its colour is what it showed where it was).
    bool carried(std::size_t i) const { return (mFlags[i] & kCarriedFlag) != 0; }
    /// A stale point's age as the priority and the z-buffer see it (above any real age), and
    /// a carried one's (above a stale one's: re-shaded first).
    static constexpr int kStaleAge = 1 << 24;
    static constexpr int kCarriedAge = 2 * kStaleAge;

    const std::vector<CachePoint>& points() const { return mPoints; }
    /// Per point (indices of points()): its element, its object, its position (the records'
    /// fields, packed for passes over every point).
    const std::vector<std::int32_t>& pointElements() const { return mElementOf; }
    const std::vector<std::int32_t>& pointObjects() const { return mObjectOf; }
    const std::vector<Vec3>& pointPositions() const { return mPosition; }
    /// Frames reprojected since point i was shaded.
    int age(std::size_t i) const { return static_cast<int>(mFrame - mBorn[i]); }
    /// Whether point i survived the last reprojection (new points count as visible).
    bool visible(std::size_t i) const { return mVisible[i] != 0; }
    std::size_t size() const { return mPoints.size(); }
    std::size_t capacity() const { return mCapacity; }
    int width() const { return mWidth; }
    int height() const { return mHeight; }
    /// Frames started by reproject() so far; requests carry it as their frame.
    std::uint64_t frame() const { return mFrame; }
    const RenderCacheOptions& options() const { return mOptions; }
    std::string toString() const;

private:
    template <class Drop>
    std::size_t dropIf(Drop drop);
    /// dropIf() with the screen point list pending: the list's point indices follow the moves
    /// (the dropped points' records kept), instead of the whole list being built first.
    void renumberPendingScreen(const std::vector<int>& gone, std::size_t kept);
    /// The slots insert() replaces for `count` new points, ascending: the `count` points
    /// first by the key (visible in the last frame, birth frame, index), hidden before visible
    /// and the oldest first.
    std::vector<int> evictionSlots(std::size_t count) const;
    /// The plain serial reprojection (RenderCacheOptions::parallel false): the reference the
    /// parallel one must equal bit for bit.
    void reprojectSerial(const CameraRays& camera);
    /// The parallel reprojection: one pass over the points (project, age, hide), a z-buffer
    /// per band of rows, culling on pixel-indexed depths, output rows in parallel: into the
    /// screen point list, or with `epi` into its arrays (the list left pending).
    void reprojectParallel(const CameraRays& camera, const EpiPointArrays* epi);
    /// reprojectParallel()'s projection pass over `chunks` chunks of points: mProj (depth,
    /// pixel, age), each point's band of rows (mProjBand, 0xFF off screen or hidden) and the
    /// points per chunk and band (mChunkBandCount).
    void projectPoints(const CameraRays& camera, int bands, std::size_t chunks);
    /// reprojectParallel(): the on-screen points of each band in index order (mBandPoints
    /// from mBandStart[band]), chunk offsets from the counts, then a scatter.
    void sortPointsByBand(int bands, std::size_t chunks);
    /// reprojectParallel(): the z-buffer (mPixelPoint, mPixelDepth, mPixelAge), bands of rows
    /// in parallel, each taking its points in index order as reprojectSerial() does.
    void zBufferBands(int bands);
    /// reprojectParallel(): depth culling of the z-buffer's points as reprojectSerial()'s,
    /// rows in parallel; leaves the survivors in mPixelPoint and their count per row in
    /// mRowCount[y + 1].
    void cullOccludedPoints();
    /// Of two near-equal depths (within this fraction) the younger point wins the pixel.
    static constexpr double kSameSurface = 0.01;
    /// The z-buffer depth of a pixel without a point (for the culling: never nearer, and not
    /// counted).
    static constexpr double kNoDepth = std::numeric_limits<double>::infinity();
    /// The z-buffer's rule (every reprojection's, in index order): a point at `depth` of age
    /// `age` takes a pixel held at `heldDepth` by a point of age `heldAge` when it is nearer
    /// by more than kSameSurface, or as near and younger.
    static bool takesPixel(double depth, int age, double heldDepth, int heldAge) {
        return depth < heldDepth * (1 - kSameSurface) ||
               (depth <= heldDepth * (1 + kSameSurface) && age < heldAge);
    }
    /// Pixel k's visible point i as the frame shows it, seen from `camera`: the position
    /// projected again at the z-buffer's depth, the pixel's age, the point's trust.
    ScreenPoint shownPoint(const CameraRays& camera, std::size_t k, int i) const {
        const CachePoint& pt = mPoints[i];
        return {camera.projectAtDepth(pt.position, mPixelDepth[k]), mPixelDepth[k], pt.colour,
                mPixelAge[k], trustOf(static_cast<std::size_t>(i))};
    }
    /// Pixel (x, y)'s point of the z-buffer `zPoint` (depths in mPixelDepth) after depth
    /// culling: −1 when culled or empty.
    int culledPoint(const std::vector<int>& zPoint, int x, int y) const;
    /// `position`'s view depth and pixel for `camera`; false when it falls off the raster.
    bool projectOne(const CameraRays& camera, const Vec3& position, double& depth,
                    int& pixel) const;
    /// reprojectParallel(): the visible pixels' output, rows in parallel from mRowCount's
    /// offsets: the screen point list, or with `epi` its arrays (the list left pending), and
    /// the luminance the priority reads.
    void writeVisiblePixels(const CameraRays& camera, const EpiPointArrays* epi);
    /// reprojectParallel() into an EPI with the camera of the frame before: the pixel lists
    /// and the pre-culling z-buffer an incremental reprojection starts from.
    void keepForIncremental(const EpiPointArrays& epi);
    /// The incremental reprojection (RenderCacheOptions::incremental) when it applies; false
    /// when the whole one must run.
    bool reprojectIncremental(const CameraRays& camera, const EpiPointArrays& epi);
    /// reprojectIncremental(), step 1: the points `touched` in place leave their old pixels'
    /// lists and join their new ones'; both pixels are dirty.
    void relinkTouched(const CameraRays& camera, const std::vector<int>& touched);
    /// Step 2: the z-buffer of the `dirty` pixels from their lists; per dirty pixel whether its
    /// depth moved (the one thing its neighbours' culling reads of it).
    std::vector<std::uint8_t> zBufferDirty(const std::vector<int>& dirty);
    /// Step 3: the culling, visible point and EPI sample of the dirty pixels and of those
    /// whose culling reads a moved depth. Returns the samples rewritten.
    std::size_t redoAffected(const CameraRays& camera, const EpiPointArrays& epi,
                             const std::vector<int>& touched, const std::vector<int>& dirty,
                             const std::vector<std::uint8_t>& depthMoved);
    /// Step 4: the samples of the shown points among `recoloured` (colour-only changes), or
    /// of every shown point when they are many. Returns the samples rewritten.
    std::size_t rewriteRecoloured(const CameraRays& camera, const EpiPointArrays& epi,
                                  const std::vector<int>& recoloured);
    /// Point i changes (insert, merge, carry, hide, stale, …): its old and new pixels are
    /// redone by the next incremental reprojection.
    void touch(std::size_t i) { mTouched[i] = kTouchedPlace; }
    /// Only point i's colour changes (relight): its sample is rewritten where it is shown.
    void touchColour(std::size_t i) {
        if (!mTouched[i]) mTouched[i] = kTouchedColour;
    }
    static constexpr std::uint8_t kTouchedPlace = 1, kTouchedColour = 2;
    /// The incremental reprojection's output for pixel k showing point i (−1: none): the
    /// EPI's sample, the luminance the priority reads, the screen index.
    void writeShown(const CameraRays& camera, const EpiPointArrays& epi, int k, int i);
    /// writeShown() for a point whose colour alone changed since its sample was written.
    void writeShownColour(const CameraRays& camera, const EpiPointArrays& epi, int k, int i);
    /// dropIf(), with the incremental state kept: the dropped points (indices, ascending)
    /// leave their pixels' lists, which are redone.
    void leavePixels(const std::vector<int>& gone);
    /// dropIf(): point `from` moves to index `to` (a hole), all its arrays with it.
    void movePoint(std::size_t from, std::size_t to);
    /// movePoint() with the incremental state kept: its projection and its place in its
    /// pixel's list follow it, and the pixel is redone.
    void movedInPixels(int from, int to);
    /// Takes point i out of pixel k's list (nothing when it is not there).
    void unlinkFromPixel(int i, int k);
    /// The projection arrays (mProj, mProjBand, mNextInPixel) sized as the points,
    /// points appended since the last reprojection off screen and touched.
    void growPerPointArrays();
    /// The priority image from the visible pixels' luminance (mLuminance, mLuminanceHi) and
    /// ages (mPixelAge), which both reprojections fill.
    void computePriority();
    /// The screen point list of a reprojection that wrote an EPI's arrays instead: from the
    /// visible pixels' points (mScreenOfPixel holds their indices until then), depths and
    /// ages, and the frame's camera. insert() and the invalidations call it before they
    /// overwrite or move a point it reads.
    void buildScreenPoints() const;
    /// requestSamples() for a positive budget: the plain serial reference
    /// (RenderCacheOptions::parallel false) and the parallel one, equal bit for bit.
    /// Among the pixels of tier ≥ `tier` alone (the passes of requestSamples).
    std::vector<ShadeRequest> requestSamplesSerial(const CameraRays& camera, int budget, int tier);
    std::vector<ShadeRequest> requestSamplesParallel(const CameraRays& camera, int budget,
                                                     int tier);
    /// Pixel k may not be requested: it holds a fresh point, and the drag asks only for changed
    /// ones (setRequestChangedOnly) or the point has converged (setRequestConverged); or the
    /// drag asks only for changed ones and k is a lone hole among fresh points.
    bool notRequestable(std::size_t k) const {
        const bool fresh = freshPixel(k);
        return (mConvergedTrust && mRequestCap > 0 && mRequestCount[k] >= mRequestCap) ||
               (fresh &&
                (mRequestChangedOnly || (mConvergedTrust && mConvergedTrust[k] >= mConverged))) ||
               (mRequestChangedOnly && mScreenOfPixel[k] < 0 && loneHole(k));
    }
    /// Pixel k's four neighbours (those in the raster) hold fresh points. A still view not yet
    /// converged has such holes scattered everywhere (the reconstruction interpolates across
    /// them); what a drag changed (a dropped shadow, where the object was) empties regions.
    /// Sampling the lone holes while dragging would change pixels in every row, and no frame
    /// could be reconstructed in windows.
    bool loneHole(std::size_t k) const {
        const std::size_t W = static_cast<std::size_t>(mWidth);
        const std::size_t x = k % W;
        return (x == 0 || freshPixel(k - 1)) && (x + 1 == W || freshPixel(k + 1)) &&
               (k < W || freshPixel(k - W)) &&
               (k + W >= mScreenOfPixel.size() || freshPixel(k + W));
    }
    /// Pixel k shows a point that is neither stale nor carried.
    bool freshPixel(std::size_t k) const {
        return mScreenOfPixel[k] >= 0 && mPixelAge[k] < kStaleAge;
    }
    /// Per pixel: requests since the view, the lighting or the points last changed
    /// (setRequestConverged's cap), saturating.
    std::vector<std::uint16_t> mRequestCount;
    int mRequestCap = 0;
    /// Something changed (the view, the lighting, the points): every pixel may be asked again.
    void restartRequestCounts() { std::fill(mRequestCount.begin(), mRequestCount.end(), 0); }
    bool mRequestChangedOnly = false;
    const std::uint8_t* mConvergedTrust = nullptr;
    std::uint8_t mConverged = 255;
    /// Pixel k was requested within the last holdFrames frames: it waits.
    bool held(std::size_t k) const {
        return mRequested[k] > 0 && mFrame + 1 < mRequested[k] + mOptions.holdFrames;
    }
    /// Which pass of requestSamples pixel k belongs to: 2 a carried point, 1 a stale one,
    /// 0 any other (empty pixels included).
    int pixelTier(std::size_t k) const {
        return (mScreenOfPixel[k] >= 0) *
               ((mPixelAge[k] >= kStaleAge) + (mPixelAge[k] >= kCarriedAge));
    }
    /// The random stream of this frame's requests in pass `tier`.
    std::uint64_t frameSeed(int tier) const;

    int mWidth;
    int mHeight;
    std::size_t mCapacity;
    RenderCacheOptions mOptions;
    std::vector<CachePoint> mPoints;
    // Per point, beside mPoints: what every reprojection reads or writes, so it streams through
    // 33 bytes a point instead of the whole records.
    std::vector<Vec3> mPosition;         ///< mPoints[i].position
    /// mPoints[i].element and .object: the passes that pick points by their element or object
    /// (relight, carry, hiding, a drag's shadow drop) read 8 bytes a point, not the records.
    std::vector<std::int32_t> mElementOf, mObjectOf;
    std::vector<std::uint64_t> mBorn;    ///< mFrame when inserted: its age is mFrame − this
    std::vector<std::uint8_t> mVisible;  ///< survived the last reprojection
    /// Age during the current reprojection (mFrame already counts it), as the frame's screen
    /// points carry it: 0 in a point's first.
    int ageBefore(std::size_t i) const { return static_cast<int>(mFrame - 1 - mBorn[i]); }
    /// ageBefore, or kStaleAge for a stale point, kCarriedAge for a carried one.
    int pointAge(std::size_t i) const {
        return (mFlags[i] & kCarriedFlag) ? kCarriedAge
               : (mFlags[i] & kStaleFlag) ? kStaleAge
                                          : ageBefore(i);
    }
    static constexpr std::uint8_t kStaleFlag = 1, kHiddenFlag = 2, kCarriedFlag = 4;
    std::vector<std::uint8_t> mFlags;  ///< per point: kStaleFlag, kHiddenFlag, kCarriedFlag
    std::uint64_t mFrame = 0;
    /// The first frame of the current view (the camera of every reprojection since): points
    /// requested before it were shaded for another view, so their pixel's own value is not
    /// known (ScreenPoint::trust 0) until a sample of this view merges into them.
    std::uint64_t mViewFrame = 0;
    /// ScreenPoint::trust of point i in the current view: 0 for a carried point, whose colour
    /// is what it showed where it was (up to its elements' change of direct light): shown as
    /// its pixel's exact value it would print a moved object's old shading pixel by pixel
    /// among freshly shaded ones, so the reconstruction blends it with its neighbours until it
    /// is re-shaded. (A stale point in place keeps its trust: its estimate is its own
    /// element's change, closer than its neighbours across a moving shadow's edge.)
    std::uint8_t trustOf(std::size_t i) const {
        const CachePoint& p = mPoints[i];
        if (mFlags[i] & kCarriedFlag) return 0;
        return p.frame >= mViewFrame ? epiTrust(p.exact, p.samples) : 0;
    }
    /// Before a reprojection to `camera`: starts a new view when the camera moved.
    void noteView(const CameraRays& camera) {
        if (!mLastCamera || !(*mLastCamera == camera)) {
            mViewFrame = mFrame;
            restartRequestCounts();
        }
        mLastCamera = camera;
    }

    std::vector<int> mPixelPoint;  ///< per pixel, −1 when empty
    /// Visible points, row-major; built on demand while mScreenPending.
    mutable std::vector<ScreenPoint> mScreen;
    /// Per pixel index into mScreen, −1 when empty (while mScreenPending: the point's index).
    mutable std::vector<int> mScreenOfPixel;
    mutable bool mScreenPending = false;
    std::optional<CameraRays> mScreenCamera;  ///< the pending list's camera
    /// While the list is pending: the records of points a merge changed since the
    /// reprojection, as the list must show them (pixel, colour, position, trust), so that a
    /// merge need not build the whole list first.
    struct PendingOriginal {
        std::size_t pixel;
        Rgb colour;
        Vec3 position;
        std::uint8_t trust;
    };
    mutable std::vector<PendingOriginal> mPendingOriginals;
    std::size_t mVisibleCount = 0;
    std::vector<double> mPriority;          ///< per pixel
    std::vector<std::uint64_t> mRequested;  ///< per pixel, frame + 1 of the last request

    // Per pixel, from the last reprojection: what the priority reads, and with mRowCount what
    // a pending screen point list is built from (not scratch: both paths fill them).
    std::vector<int> mPixelAge;  ///< age of its z-buffer point (meaningful where one survived)
    /// The last reprojection's camera (insert() finds a new point's pixel with it).
    std::optional<CameraRays> mLastCamera;
    /// insert(): merges the points of `batch` from `first` on that fall on a visible point of
    /// their pixel (mergeSamples); returns, per batch point, whether it was merged.
    std::vector<std::uint8_t> mergeIntoPixels(const std::vector<ShadedPoint>& batch,
                                              std::size_t first);
    std::vector<double> mPixelDepth;   ///< depth of its z-buffer point (parallel path)
    std::vector<double> mLuminance;    ///< luminance of its point, 1e300 without
    std::vector<double> mLuminanceHi;  ///< the same, −1e300 without
    std::vector<int> mRowCount;        ///< per row: visible points (prefix sums; parallel path)

    // Scratch of reprojectParallel(), kept between frames.
    /// A point as the projection pass leaves it: view depth and pixel (both only when on
    /// screen) and age before this frame's increment.
    struct ProjectedPoint {
        double depth;
        int pixel;
        int age;
    };
    /// The same, with its point index, in a band's list for the z-buffer.
    struct BandEntry {
        double depth;
        int pixel;
        int age;
        int point;
    };
    std::vector<ProjectedPoint> mProj;           ///< per point
    std::vector<int> mFiltered;                  ///< per pixel: culling's output, swapped in
    std::vector<std::uint8_t> mRowBand;          ///< per row: its band
    std::vector<std::uint8_t> mProjBand;         ///< per point: band of rows (0xFF off screen)
    std::vector<std::uint32_t> mChunkBandCount;  ///< per chunk of points and band: count, then slot
    std::vector<std::uint32_t> mBandStart;       ///< per band: first entry in mBandPoints
    std::vector<BandEntry> mBandPoints;          ///< on-screen points by band, in index order
    // The incremental reprojection's state (kept by a whole reprojection into an EPI whose
    // camera did not move; mIncrementalValid while it describes the cache).
    bool mIncrementalValid = false;
    bool mIncrementalFrame = false;
    std::size_t mReprojectedPixels = 0;
    EpiPointArrays mIncrementalEpi;       ///< the arrays the last reprojection wrote
    std::vector<int> mZPoint;             ///< per pixel: the z-buffer's point before culling
    std::vector<int> mShownPoint;         ///< per pixel: its visible point after culling
    std::vector<int> mPixelHead;          ///< per pixel: first point projecting there, −1
    std::vector<int> mNextInPixel;        ///< per point: next point of its pixel's list
    std::vector<std::uint8_t> mTouched;   ///< per point: changed since the last reprojection
    std::vector<std::uint8_t> mDirty;     ///< per pixel: its points changed
    std::vector<std::uint8_t> mAffected;  ///< per pixel: scratch of the incremental pass
    std::vector<int> mRowVisible;         ///< per row: visible points
    /// Scratch of dropIf(): per point whether it goes.
    std::vector<std::uint8_t> mDropFlags;
    // Scratch of requestSamplesParallel().
    std::vector<double> mEffective;    ///< per pixel: priority, 0 while held back
    std::vector<double> mTileSum;      ///< per tile: summed effective priority
    std::vector<int> mTileCandidates;  ///< per tile: pixels with positive effective priority
};

}  // namespace penumbra
