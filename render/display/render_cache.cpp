// Index: construction · insertion and replacement · reprojection and depth culling (Walter et
//        al. 1999) · priority image and sample requests · plain interpolation (invalidation
//        and toString: render_cache_invalidation.cpp)
#include "render/display/render_cache.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numeric>
#include <sstream>
#include <stdexcept>

#include "core/random.h"
#include "solver/form_factor.h"

namespace penumbra {

namespace {

/// reprojectParallel(): points per chunk of the projection pass, whose band counts give each
/// chunk's slots in the bands' lists.
constexpr std::size_t kProjectChunk = 8192;

/// The frame's random draws, counter-based: draw i is hashPair(seed, i), so any stretch of
/// the sequence can be drawn where it is used (requestSamplesParallel() starts each tile at
/// its offset) and no serial chain has to run ahead of the requests.
struct CacheRandom {
    std::uint64_t seed;
    std::uint64_t index = 0;
    static double at(std::uint64_t seed, std::uint64_t i) {
        return static_cast<double>(hashPair(seed, i) >> 11) * 0x1.0p-53;
    }
    double next() { return at(seed, index++); }
};

}  // namespace

// ---------------------------------------------------------------------------------------------
// Construction

RenderCache::RenderCache(int width, int height, std::size_t capacity, RenderCacheOptions options)
    : mWidth(width), mHeight(height), mCapacity(capacity), mOptions(options) {
    if (width <= 0 || height <= 0 || capacity == 0) {
        throw std::invalid_argument("RenderCache: size must be positive, got " +
                                    std::to_string(width) + "x" + std::to_string(height) +
                                    " pixels and capacity " + std::to_string(capacity));
    }
    const std::size_t pixels = static_cast<std::size_t>(width) * height;
    mPoints.reserve(capacity);
    mPosition.reserve(capacity);
    mElementOf.reserve(capacity);
    mObjectOf.reserve(capacity);
    mBorn.reserve(capacity);
    mVisible.reserve(capacity);
    mFlags.reserve(capacity);
    mPixelPoint.assign(pixels, -1);
    mScreenOfPixel.assign(pixels, -1);
    mPriority.assign(pixels, 1.0);
    mRequested.assign(pixels, 0);
    mDirty.assign(pixels, 0);
    mAffected.assign(pixels, 0);
    mRowVisible.assign(static_cast<std::size_t>(height), 0);
}

// ---------------------------------------------------------------------------------------------
// Insertion and replacement

std::vector<int> RenderCache::evictionSlots(std::size_t count) const {
    // The `count` smallest keys (visible in the last frame, birth frame, index): every hidden
    // point when there are not enough of them, then the oldest of one class, ties in index
    // order. Not a sort (nth_element over the cache's index order reads both arrays at
    // random, a cost that grows with the cache), but a radix select: one parallel pass counts ages
    // per chunk of points and class, which gives the threshold age and each chunk's share of the
    // slots, and a second parallel pass writes them. Which class a point is in follows no
    // pattern, so both passes decide by selects. Only when more than the needed points of the
    // class are older than the histogram reaches (long sessions) does a serial refinement
    // on birth frames find the threshold.
    const std::size_t n = mPoints.size();
    count = std::min(count, n);
    if (count == 0) return {};
    const std::uint8_t* visible = mVisible.data();
    const std::uint64_t* born = mBorn.data();
    constexpr std::size_t kChunk = 1 << 16;
    constexpr std::uint64_t kAges = 4096;  // the last bucket holds every older point
    const std::size_t chunks = (n + kChunk - 1) / kChunk;
    // Per chunk and class (hidden 0, visible 1), a histogram of ages.
    std::vector<std::uint32_t> ages(chunks * 2 * kAges);
    tbb::parallel_for(std::size_t(0), chunks, [&](std::size_t c) {
        std::uint32_t* h = &ages[c * 2 * kAges];
        const std::size_t end = std::min(n, (c + 1) * kChunk);
        for (std::size_t i = c * kChunk; i != end; ++i)
            ++h[(visible[i] != 0) * kAges + std::min(mFrame - born[i], kAges - 1)];
    });
    auto bucket = [&](std::size_t c, int cls, std::uint64_t age) -> std::size_t {
        return ages[(c * 2 + cls) * kAges + age];
    };
    std::vector<std::size_t> hiddenIn(chunks, 0);
    std::size_t hidden = 0;
    for (std::size_t c = 0; c < chunks; ++c) {
        for (std::uint64_t a = 0; a < kAges; ++a) hiddenIn[c] += bucket(c, 0, a);
        hidden += hiddenIn[c];
    }
    // The class the selection runs in and how many it takes there.
    const int cls = count <= hidden ? 0 : 1;
    std::size_t need = cls == 0 ? count : count - hidden;
    // The threshold, oldest first: of the class, ages above `age` are taken and `need` at it.
    std::uint64_t age = kAges - 1;
    for (;; --age) {
        std::size_t here = 0;
        for (std::size_t c = 0; c < chunks; ++c) here += bucket(c, cls, age);
        if (here >= need) break;
        need -= here;
    }
    // Each chunk's slots: its hidden points when all are taken, its class points above the
    // threshold, and its ties in index order up to the quota.
    std::vector<std::size_t> at(chunks + 1, 0), ties(chunks, 0);
    std::uint64_t threshold;  // the birth frame of the threshold age; older ones are taken
    if (age < kAges - 1) {
        threshold = mFrame - age;
        std::size_t quota = need;
        for (std::size_t c = 0; c < chunks; ++c) {
            std::size_t above = 0;
            for (std::uint64_t a = age + 1; a < kAges; ++a) above += bucket(c, cls, a);
            ties[c] = std::min(quota, bucket(c, cls, age));
            quota -= ties[c];
            at[c + 1] = at[c] + (cls == 1 ? hiddenIn[c] : 0) + above + ties[c];
        }
    } else {
        // The oldest bucket holds at least `need` points of the class: find the birth frame
        // among them (born <= hi) by rounds of histograms, each 4,096 times narrower.
        std::uint64_t lo = 0, hi = mFrame - (kAges - 1);
        std::vector<std::size_t> histogram(kAges);
        for (;;) {
            int shift = 0;
            while (((hi - lo) >> shift) >= kAges) ++shift;
            std::fill(histogram.begin(), histogram.end(), 0);
            for (std::size_t i = 0; i < n; ++i)
                if ((visible[i] != 0) == cls && born[i] >= lo && born[i] <= hi)
                    ++histogram[(born[i] - lo) >> shift];
            std::size_t b = 0, below = 0;
            while (below + histogram[b] < need) below += histogram[b++];
            need -= below;
            lo += static_cast<std::uint64_t>(b) << shift;
            if (shift == 0) break;
            hi = std::min(hi, lo + ((std::uint64_t(1) << shift) - 1));
        }
        threshold = lo;
        // One chunk: the scan below runs serially.
        ties.assign(1, need);
        at.assign(2, 0);
        at[1] = count;
    }
    const std::size_t scanChunk = age < kAges - 1 ? kChunk : n;
    // A chunk writes each candidate before deciding to keep it, but only while its share is
    // not full, so never past it.
    std::vector<int> slots(count);
    const unsigned hiddenTaken = cls;  // 1: every hidden point is taken
    tbb::parallel_for(std::size_t(0), at.size() - 1, [&](std::size_t c) {
        std::size_t m = at[c], tie = ties[c];
        const std::size_t end = std::min(n, (c + 1) * scanChunk);
        const std::size_t limit = at[c + 1];
        for (std::size_t i = c * scanChunk; i != end && m != limit; ++i) {
            const unsigned in = (visible[i] != 0) == hiddenTaken;
            const unsigned isTie = in & (born[i] == threshold) & (tie != 0);
            const unsigned take = ((in ^ 1u) & hiddenTaken) | (in & (born[i] < threshold)) | isTie;
            slots[m] = static_cast<int>(i);
            m += take;
            tie -= isTie;
        }
    });
    return slots;
}

std::vector<std::uint8_t> RenderCache::mergeIntoPixels(const std::vector<ShadedPoint>& batch,
                                                       std::size_t first) {
    std::vector<std::uint8_t> merged(batch.size(), 0);
    if (mOptions.mergeSamples <= 0 || !mLastCamera) return merged;
    const CameraRays& camera = *mLastCamera;
    const int cap = mOptions.mergeSamples;
    const bool built = !mScreenPending;
    for (std::size_t b = first; b < batch.size(); ++b) {
        const ShadedPoint& s = batch[b];
        if (s.stale || !s.hit()) continue;
        // mPixelPoint is the last reprojection's until an insert or a drop clears it.
        const auto p = camera.projectToPixel(s.position);
        if (!p || !(p->x >= 0 && p->x < mWidth && p->y >= 0 && p->y < mHeight)) continue;
        const int x = std::min(static_cast<int>(p->x), mWidth - 1);
        const int y = std::min(static_cast<int>(p->y), mHeight - 1);
        const int i = mPixelPoint[static_cast<std::size_t>(y) * mWidth + x];
        if (i < 0 || mFlags[i] != 0) continue;
        CachePoint& q = mPoints[i];
        if (q.element != s.element || q.frame > s.frame) continue;
        const Vec3& o = camera.origin();
        const double dq = glm::dot(q.position - o, camera.forward());
        const double ds = glm::dot(s.position - o, camera.forward());
        if (!(std::abs(ds - dq) <= dq * kSameSurface)) continue;
        // A pending screen point list reads the visible points' records: it keeps the
        // reprojection's (the first change of a point is the one recorded).
        if (!built)
            mPendingOriginals.push_back({static_cast<std::size_t>(y) * mWidth + x, q.colour,
                                         q.position, trustOf(static_cast<std::size_t>(i))});
        touch(static_cast<std::size_t>(i));
        if (q.shading != s.shading) {
            // Shaded under other lighting (a solution update, a drag step): the new sample
            // replaces the mean, which would otherwise lag behind the change.
            q.position = s.position;
            mPosition[i] = s.position;
            q.colour = s.radiance;
            q.samples = s.samples;
            q.exact = s.exact;
            q.shading = s.shading;
        } else {
            // The mean over the pixel's footprint: exact samples differ where the pixel holds
            // detail finer than itself (a fine mesh's facets), noisy ones also by their noise.
            const int n = std::min(q.samples, cap - 1);
            const int m = std::max(1, s.samples);
            q.colour = (q.colour * static_cast<double>(n) + s.radiance * static_cast<double>(m)) /
                       static_cast<double>(n + m);
            q.samples = n + m;
            q.exact = q.exact && s.exact;
        }
        q.frame = s.frame;
        mBorn[i] = mFrame;  // age 0 in the next reprojection
        merged[b] = 1;
    }
    return merged;
}

void RenderCache::insert(const std::vector<ShadedPoint>& all) {
    auto toCache = [](const ShadedPoint& s) {
        CachePoint p;
        p.position = s.position;
        p.colour = s.radiance;
        p.object = s.object;
        p.element = s.element;
        p.frame = s.frame;
        p.exact = s.exact;
        p.samples = std::max(1, s.samples);
        p.shading = s.shading;
        return p;
    };
    // Of a batch larger than the cache only its last capacity() points stay.
    const std::size_t firstOfAll = all.size() > mCapacity ? all.size() - mCapacity : 0;
    const std::vector<std::uint8_t> merged = mergeIntoPixels(all, firstOfAll);
    std::vector<ShadedPoint> unmerged;
    const bool anyMerged = std::find(merged.begin(), merged.end(), 1) != merged.end();
    if (anyMerged) {
        for (std::size_t b = firstOfAll; b < all.size(); ++b)
            if (!merged[b]) unmerged.push_back(all[b]);
    }
    const std::vector<ShadedPoint>& batch = anyMerged ? unmerged : all;
    std::size_t first = anyMerged ? 0 : firstOfAll;
    std::size_t count = batch.size() - first;
    if (count == 0) {
        if (anyMerged) std::fill(mPixelPoint.begin(), mPixelPoint.end(), -1);
        return;
    }
    const std::size_t existing = mPoints.size();
    const std::size_t free = mCapacity - existing;
    std::size_t victims = count > free ? count - free : 0;

    // Replace first what was not visible in the last frame, then the oldest.
    const std::vector<int> slots = victims > 0 ? evictionSlots(victims) : std::vector<int>{};
    // A pending screen point list reads the visible points' records: build it before one is
    // overwritten (only when the hidden points do not suffice).
    if (mScreenPending)
        for (int slot : slots)
            if (mVisible[slot] && mBorn[slot] < mFrame) {  // not one inserted since
                buildScreenPoints();
                break;
            }
    std::size_t v = 0;
    for (std::size_t i = first; i < batch.size(); ++i) {
        std::size_t slot = mPoints.size();
        if (slot < mCapacity) {
            mPoints.push_back(toCache(batch[i]));
            mPosition.emplace_back();
            mElementOf.emplace_back();
            mObjectOf.emplace_back();
            mBorn.emplace_back();
            mVisible.emplace_back();
            mFlags.emplace_back();
            mTouched.emplace_back();
        } else {
            slot = static_cast<std::size_t>(slots[v++]);
            mPoints[slot] = toCache(batch[i]);
        }
        touch(slot);
        mPosition[slot] = batch[i].position;
        mElementOf[slot] = batch[i].element;
        mObjectOf[slot] = batch[i].object;
        mBorn[slot] = mFrame;  // age 0 in the next reprojection
        mVisible[slot] = 1;    // new points count as visible
        mFlags[slot] = batch[i].stale ? kStaleFlag : 0;
    }
    std::fill(mPixelPoint.begin(), mPixelPoint.end(), -1);
}

// ---------------------------------------------------------------------------------------------
// Reprojection and depth culling

namespace {

void checkRaster(const CameraRays& camera, int width, int height) {
    if (camera.width() != width || camera.height() != height) {
        throw std::invalid_argument("RenderCache::reproject: camera raster " +
                                    std::to_string(camera.width()) + "x" +
                                    std::to_string(camera.height()) + " differs from the cache's " +
                                    std::to_string(width) + "x" + std::to_string(height));
    }
}

}  // namespace

const std::vector<ScreenPoint>& RenderCache::reproject(const CameraRays& camera) {
    checkRaster(camera, mWidth, mHeight);
    ++mFrame;
    mIncrementalValid = false;  // no EPI arrays to update next time
    if (mOptions.parallel) {
        reprojectParallel(camera, nullptr);
    } else {
        reprojectSerial(camera);
    }
    return mScreen;
}

void RenderCache::reproject(const CameraRays& camera, const EpiPointArrays& points) {
    checkRaster(camera, mWidth, mHeight);
    if (points.width != mWidth || points.height != mHeight || !points.depth || !points.colour ||
        !points.position) {
        throw std::invalid_argument("RenderCache::reproject: EPI point arrays of " +
                                    std::to_string(points.width) + "x" +
                                    std::to_string(points.height) + " for the cache's " +
                                    std::to_string(mWidth) + "x" + std::to_string(mHeight));
    }
    ++mFrame;
    if (mOptions.parallel) {
        if (mOptions.incremental && reprojectIncremental(camera, points)) return;
        reprojectParallel(camera, &points);
        return;
    }
    mIncrementalValid = false;
    // The serial reference: the list, then placed as EdgePointImage::build places it.
    reprojectSerial(camera);
    for (std::size_t k = 0; k < mScreenOfPixel.size(); ++k) {
        const int s = mScreenOfPixel[k];
        points.place(k, s >= 0 ? &mScreen[s] : nullptr);
    }
}

void RenderCache::reprojectSerial(const CameraRays& camera) {
    const std::size_t n = mPoints.size();
    std::vector<glm::dvec2> position(n);
    std::vector<double> depth(n);
    std::vector<int> pixel(n, -1);

    // Project every point to the new camera.
    for (std::size_t i = 0; i < n; ++i) {
        if (mFlags[i] & kHiddenFlag) continue;  // behind a moving object (setHidden)
        const auto p = camera.projectToPixel(mPosition[i]);
        if (!p || !(p->x >= 0 && p->x < mWidth && p->y >= 0 && p->y < mHeight)) continue;
        position[i] = *p;
        depth[i] = glm::dot(mPosition[i] - camera.origin(), camera.forward());
        const int x = std::min(static_cast<int>(p->x), mWidth - 1);
        const int y = std::min(static_cast<int>(p->y), mHeight - 1);
        pixel[i] = y * mWidth + x;
    }

    // Z-buffer: the nearest point per pixel; of near-equal depths the youngest.
    std::fill(mPixelPoint.begin(), mPixelPoint.end(), -1);
    for (std::size_t i = 0; i < n; ++i) {
        if (pixel[i] < 0) continue;
        int& cur = mPixelPoint[pixel[i]];
        if (cur < 0) {
            cur = static_cast<int>(i);
            continue;
        }
        const double dc = depth[cur];
        if (takesPixel(depth[i], pointAge(i), dc, pointAge(cur))) cur = static_cast<int>(i);
    }

    // Depth culling (after Walter et al. 1999): a point is taken as hidden when at least half
    // of the points around it are nearer by more than the margin, i.e. it is seen through a
    // gap in a nearer surface. Walter et al. compare with the neighbourhood's mean depth; that
    // also culls the background points along every silhouette, a one-pixel band that new
    // samples could never fill (each would be culled again), so the majority is used instead.
    const std::vector<int> unfiltered = mPixelPoint;
    const int rad = std::max(0, mOptions.depthRadius);
    for (int y = 0; y < mHeight; ++y) {
        for (int x = 0; x < mWidth; ++x) {
            const int self = unfiltered[y * mWidth + x];
            if (self < 0) continue;
            int neighbours = 0, nearer = 0;
            for (int dy = -rad; dy <= rad; ++dy)
                for (int dx = -rad; dx <= rad; ++dx) {
                    const int xx = x + dx, yy = y + dy;
                    if ((dx == 0 && dy == 0) || xx < 0 || yy < 0 || xx >= mWidth || yy >= mHeight)
                        continue;
                    const int q = unfiltered[yy * mWidth + xx];
                    if (q < 0) continue;
                    ++neighbours;
                    nearer += depth[q] * (1 + mOptions.depthMargin) < depth[self];
                }
            if (nearer > 0 && 2 * nearer >= neighbours) mPixelPoint[y * mWidth + x] = -1;
        }
    }

    // Visible points in pixel order (every point ages by a frame: ages count from mFrame),
    // and per pixel the luminance and age the priority reads.
    std::fill(mVisible.begin(), mVisible.end(), 0);
    mScreen.clear();
    mScreenPending = false;
    mPendingOriginals.clear();
    std::fill(mScreenOfPixel.begin(), mScreenOfPixel.end(), -1);
    mLuminance.assign(mPixelPoint.size(), 1e300);
    mLuminanceHi.assign(mPixelPoint.size(), -1e300);
    mPixelAge.resize(mPixelPoint.size());
    noteView(camera);
    std::fill(mTouched.begin(), mTouched.end(), 0);
    std::fill(mDirty.begin(), mDirty.end(), 0);
    mIncrementalFrame = false;
    mReprojectedPixels = mPixelPoint.size();
    for (std::size_t k = 0; k < mPixelPoint.size(); ++k) {
        const int i = mPixelPoint[k];
        if (i < 0) continue;
        mVisible[i] = 1;
        mScreenOfPixel[k] = static_cast<int>(mScreen.size());
        mScreen.push_back({position[i], depth[i], mPoints[i].colour, pointAge(i),
                           trustOf(static_cast<std::size_t>(i))});
        mLuminance[k] = mLuminanceHi[k] = luminance(mPoints[i].colour);
        mPixelAge[k] = pointAge(i);
    }
    mVisibleCount = mScreen.size();
    computePriority();
}

void RenderCache::reprojectParallel(const CameraRays& camera, const EpiPointArrays* epi) {
    // The same rules as reprojectSerial(), reorganized for two cores and for memory traffic:
    // the points (about 80 bytes each, a few per pixel) are read once; everything after works
    // on compact per-point and per-pixel arrays.
    const std::size_t n = mPoints.size();
    const std::size_t pixels = static_cast<std::size_t>(mWidth) * mHeight;
    mProj.resize(n);
    mPixelDepth.resize(pixels);
    mPixelAge.resize(pixels);
    const bool still = mLastCamera && *mLastCamera == camera;
    noteView(camera);
    mLuminance.resize(pixels);
    mLuminanceHi.resize(pixels);
    mRowCount.resize(static_cast<std::size_t>(mHeight) + 1);
    std::fill(mVisible.begin(), mVisible.end(), 0);
    std::fill(mTouched.begin(), mTouched.end(), 0);
    std::fill(mDirty.begin(), mDirty.end(), 0);
    mIncrementalFrame = false;
    mReprojectedPixels = pixels;
    const int bands = std::min(mHeight, 8);
    const std::size_t chunks = (n + kProjectChunk - 1) / kProjectChunk;
    projectPoints(camera, bands, chunks);
    sortPointsByBand(bands, chunks);
    zBufferBands(bands);
    cullOccludedPoints();
    writeVisiblePixels(camera, epi);
    // A camera that did not move is likely to stay: keep what the next frame's incremental
    // reprojection starts from.
    if (epi && still && mOptions.incremental)
        keepForIncremental(*epi);
    else
        mIncrementalValid = false;
    computePriority();
}

bool RenderCache::projectOne(const CameraRays& camera, const Vec3& position, double& depth,
                             int& pixel) const {
    const auto p = camera.projectToPixel(position);
    if (!p || !(p->x >= 0 && p->x < mWidth && p->y >= 0 && p->y < mHeight)) return false;
    depth = glm::dot(position - camera.origin(), camera.forward());
    const int x = std::min(static_cast<int>(p->x), mWidth - 1);
    const int y = std::min(static_cast<int>(p->y), mHeight - 1);
    pixel = y * mWidth + x;
    return true;
}

void RenderCache::projectPoints(const CameraRays& camera, int bands, std::size_t chunks) {
    // One pass over the points' compact arrays (position, birth frame): project, remember the
    // age; and the band of rows each point falls in, counted per fixed chunk of points.
    const std::size_t n = mPoints.size();
    mProjBand.resize(n);
    mChunkBandCount.assign(chunks * static_cast<std::size_t>(bands), 0);
    // Band b holds rows [⌊H·b/B⌋, ⌊H·(b+1)/B⌋), looked up per row rather than found by a
    // 64-bit division per point.
    mRowBand.resize(static_cast<std::size_t>(mHeight));
    for (int b = 0; b < bands; ++b)
        for (int y = static_cast<int>(static_cast<long long>(mHeight) * b / bands);
             y < static_cast<long long>(mHeight) * (b + 1) / bands; ++y)
            mRowBand[y] = static_cast<std::uint8_t>(b);
    tbb::parallel_for(std::size_t(0), chunks, [&](std::size_t c) {
        std::uint32_t* count = &mChunkBandCount[c * static_cast<std::size_t>(bands)];
        const std::size_t end = std::min(n, (c + 1) * kProjectChunk);
        for (std::size_t i = c * kProjectChunk; i != end; ++i) {
            const Vec3& position = mPosition[i];
            ProjectedPoint& proj = mProj[i];
            proj.age = pointAge(i);
            mProjBand[i] = 0xFF;
            if (mFlags[i] & kHiddenFlag) continue;  // behind a moving object (setHidden)
            if (!projectOne(camera, position, proj.depth, proj.pixel)) continue;
            const std::uint8_t b = mRowBand[proj.pixel / mWidth];
            mProjBand[i] = b;
            ++count[b];
        }
    });
}

void RenderCache::sortPointsByBand(int bands, std::size_t chunks) {
    const std::size_t n = mPoints.size();
    // Each band's points in index order (chunk offsets from the counts, then a scatter), so
    // a band reads only its own points: scanning every point per band cost a mispredicted
    // branch per point and band.
    mBandStart.assign(static_cast<std::size_t>(bands) + 1, 0);
    for (int b = 0; b < bands; ++b) {
        std::uint32_t at = mBandStart[b];
        for (std::size_t c = 0; c < chunks; ++c) {
            std::uint32_t& k = mChunkBandCount[c * static_cast<std::size_t>(bands) + b];
            const std::uint32_t here = k;
            k = at;  // now the chunk's first slot in the band's list
            at += here;
        }
        mBandStart[b + 1] = at;
    }
    // The entries carry what the z-buffer reads: a band's points are spread over the whole
    // index range, so reading their projections through the point index pulled every cache
    // line of the per-point arrays into every band.
    mBandPoints.resize(mBandStart[bands]);
    tbb::parallel_for(std::size_t(0), chunks, [&](std::size_t c) {
        std::uint32_t* slot = &mChunkBandCount[c * static_cast<std::size_t>(bands)];
        const std::size_t end = std::min(n, (c + 1) * kProjectChunk);
        for (std::size_t i = c * kProjectChunk; i != end; ++i)
            if (mProjBand[i] != 0xFF) {
                const ProjectedPoint& proj = mProj[i];
                mBandPoints[slot[mProjBand[i]]++] = {proj.depth, proj.pixel, proj.age,
                                                     static_cast<int>(i)};
            }
    });
}

void RenderCache::zBufferBands(int bands) {
    // Z-buffer per band of rows: each band takes its points in index order, as the serial
    // loop does, so ties resolve identically. Pixels without a point keep depth kNoDepth.
    tbb::parallel_for(0, bands, [&](int band) {
        const int lo = static_cast<int>(static_cast<long long>(mHeight) * band / bands) * mWidth;
        const int hi =
            static_cast<int>(static_cast<long long>(mHeight) * (band + 1) / bands) * mWidth;
        std::fill(mPixelPoint.begin() + lo, mPixelPoint.begin() + hi, -1);
        std::fill(mPixelDepth.begin() + lo, mPixelDepth.begin() + hi, kNoDepth);
        for (std::uint32_t j = mBandStart[band]; j != mBandStart[band + 1]; ++j) {
            const BandEntry& e = mBandPoints[j];
            const int k = e.pixel;
            int& cur = mPixelPoint[k];
            const double d = e.depth;
            if (cur >= 0) {
                const double dc = mPixelDepth[k];
                if (!takesPixel(d, e.age, dc, mPixelAge[k])) continue;
            }
            cur = e.point;
            mPixelDepth[k] = d;
            mPixelAge[k] = e.age;
        }
    });
}

int RenderCache::culledPoint(const std::vector<int>& zPoint, int x, int y) const {
    const int rad = std::max(0, mOptions.depthRadius);
    const double margin = 1 + mOptions.depthMargin;
    const int k = y * mWidth + x;
    if (zPoint[k] < 0) return -1;
    const double self = mPixelDepth[k];
    int neighbours = 0, nearer = 0;
    for (int dy = -rad; dy <= rad; ++dy) {
        const int yy = y + dy;
        if (yy < 0 || yy >= mHeight) continue;
        for (int dx = -rad; dx <= rad; ++dx) {
            const int xx = x + dx;
            if ((dx == 0 && dy == 0) || xx < 0 || xx >= mWidth) continue;
            const int q = yy * mWidth + xx;
            if (zPoint[q] < 0) continue;
            ++neighbours;
            nearer += mPixelDepth[q] * margin < self;
        }
    }
    return nearer > 0 && 2 * nearer >= neighbours ? -1 : zPoint[k];
}

void RenderCache::cullOccludedPoints() {
    const std::size_t pixels = static_cast<std::size_t>(mWidth) * mHeight;
    // Depth culling as in reprojectSerial(), on pixel-indexed depths, branch-free for inner
    // pixels of the usual 3×3: reads the z-buffer, writes the survivors to mFiltered (then
    // swapped in) and counts them per row.
    const int rad = std::max(0, mOptions.depthRadius);
    const double margin = 1 + mOptions.depthMargin;
    mFiltered.resize(pixels);
    tbb::parallel_for(0, mHeight, [&](int y) {
        // Any pixel and radius: the point or −1 when culled.
        auto cullAt = [&](int x) { return culledPoint(mPixelPoint, x, y); };
        const std::size_t row = static_cast<std::size_t>(y) * mWidth;
        int* __restrict filtered = &mFiltered[row];
        int survivors = 0;
        if (rad == 1 && y > 0 && y + 1 < mHeight && mWidth > 2) {
            // Inner pixels of an inner row without branches, so the loop vectorizes (which
            // pixels hold a point follows no pattern): an empty pixel's depth is +inf, so it
            // counts as no neighbour, and it stays −1 whatever its counts.
            const double* __restrict up = &mPixelDepth[row - mWidth];
            const double* __restrict mid = &mPixelDepth[row];
            const double* __restrict down = &mPixelDepth[row + mWidth];
            const int* __restrict point = &mPixelPoint[row];
            filtered[0] = cullAt(0);
            survivors += filtered[0] >= 0;
            const int W = mWidth;
            // In doubles first (two loops of one element width each vectorize; one mixing
            // doubles and ints did not): 1 where culled.
            thread_local std::vector<double> cullRow;
            cullRow.resize(static_cast<std::size_t>(W));
            double* __restrict cull = cullRow.data();
            for (int x = 1; x + 1 < W; ++x) {
                const double self = mid[x];
                const double neighbours =
                    (up[x - 1] != kNoDepth ? 1.0 : 0.0) + (up[x] != kNoDepth ? 1.0 : 0.0) +
                    (up[x + 1] != kNoDepth ? 1.0 : 0.0) + (mid[x - 1] != kNoDepth ? 1.0 : 0.0) +
                    (mid[x + 1] != kNoDepth ? 1.0 : 0.0) + (down[x - 1] != kNoDepth ? 1.0 : 0.0) +
                    (down[x] != kNoDepth ? 1.0 : 0.0) + (down[x + 1] != kNoDepth ? 1.0 : 0.0);
                const double nearer = (up[x - 1] * margin < self ? 1.0 : 0.0) +
                                      (up[x] * margin < self ? 1.0 : 0.0) +
                                      (up[x + 1] * margin < self ? 1.0 : 0.0) +
                                      (mid[x - 1] * margin < self ? 1.0 : 0.0) +
                                      (mid[x + 1] * margin < self ? 1.0 : 0.0) +
                                      (down[x - 1] * margin < self ? 1.0 : 0.0) +
                                      (down[x] * margin < self ? 1.0 : 0.0) +
                                      (down[x + 1] * margin < self ? 1.0 : 0.0);
                cull[x] = nearer > 0 && 2 * nearer >= neighbours ? 1.0 : 0.0;
            }
            for (int x = 1; x + 1 < W; ++x) {
                const int f = point[x] | -static_cast<int>(cull[x] != 0);  // −1 when culled
                filtered[x] = f;
                survivors += f >= 0;
            }
            filtered[mWidth - 1] = cullAt(mWidth - 1);
            survivors += filtered[mWidth - 1] >= 0;
        } else {
            for (int x = 0; x < mWidth; ++x) {
                filtered[x] = cullAt(x);
                survivors += filtered[x] >= 0;
            }
        }
        mRowCount[y + 1] = survivors;
    });
    mPixelPoint.swap(mFiltered);
}

void RenderCache::writeVisiblePixels(const CameraRays& camera, const EpiPointArrays* epi) {
    // Visible points in pixel order: offsets from the per-row counts, then rows in parallel.
    mRowCount[0] = 0;
    for (int y = 0; y < mHeight; ++y) mRowCount[y + 1] += mRowCount[y];
    mVisibleCount = static_cast<std::size_t>(mRowCount[mHeight]);
    mScreenPending = epi != nullptr;
    mPendingOriginals.clear();
    if (epi)
        mScreenCamera = camera;
    else
        mScreen.resize(mVisibleCount);
    tbb::parallel_for(0, mHeight, [&](int y) {
        int s = mRowCount[y];
        for (int x = 0; x < mWidth; ++x) {
            const int k = y * mWidth + x;
            // The points are in insertion order, not pixel order: fetch ahead.
            constexpr int kAhead = 8;
            if (x + kAhead < mWidth && mPixelPoint[k + kAhead] >= 0)
                __builtin_prefetch(&mPoints[mPixelPoint[k + kAhead]].colour);
            const int i = mPixelPoint[k];
            if (i < 0) {
                mScreenOfPixel[k] = -1;
                mLuminance[k] = 1e300;
                mLuminanceHi[k] = -1e300;
                if (epi) epi->place(k, nullptr);
                continue;
            }
            const CachePoint& pt = mPoints[i];
            mVisible[i] = 1;
            // Depth and age from the pixel's z-buffer entry (read in order; the point and its
            // flag are the random access). The position is projected again from the point's
            // record, on the line its colour is read from, with the z-buffer's depth: the
            // projection pass's value bit for bit, without writing and reading it per point.
            const ScreenPoint p = shownPoint(camera, k, i);
            if (epi) {
                // What EdgePointImage::build would place from the list (a NaN colour is not).
                mScreenOfPixel[k] = i;
                epi->place(k, &p);
            } else {
                mScreenOfPixel[k] = s;
                mScreen[s++] = p;
            }
            // computePriority()'s luminance, while the colour is at hand.
            const double l = luminance(pt.colour);
            mLuminance[k] = l;
            mLuminanceHi[k] = l;
        }
    });
}

void RenderCache::buildScreenPoints() const {
    // Rows in parallel from their offsets (reprojectParallel()'s row counts).
    mScreen.resize(mVisibleCount);
    tbb::parallel_for(0, mHeight, [&](int y) {
        int s = mRowCount[y];
        for (int x = 0; x < mWidth; ++x) {
            const int k = y * mWidth + x;
            const int i = mScreenOfPixel[k];
            if (i < 0) continue;
            mScreen[s] = shownPoint(*mScreenCamera, k, i);
            mScreenOfPixel[k] = s++;
        }
    });
    // Points merged into since the reprojection, as it showed them (the earliest record last,
    // so it wins).
    for (auto o = mPendingOriginals.rbegin(); o != mPendingOriginals.rend(); ++o) {
        ScreenPoint& p = mScreen[mScreenOfPixel[o->pixel]];
        p.position = mScreenCamera->projectAtDepth(o->position, mPixelDepth[o->pixel]);
        p.colour = o->colour;
        p.trust = o->trust;
    }
    mPendingOriginals.clear();
    mScreenPending = false;
}

// ---------------------------------------------------------------------------------------------
// Priority image and sample requests

void RenderCache::computePriority() {
    // The reprojection filled the luminance per pixel with sentinels where there is no point
    // (1e300 for the minimum, −1e300 for the maximum: the loop's initial values, so they
    // change nothing). The 3×3 minimum and maximum, separably: per row, the column extremes
    // over the rows y − 1 … y + 1 inside the image (vectorized), then over x − 1 … x + 1 (min
    // and max are exact, so this equals a nine-point loop per pixel).
    tbb::parallel_for(tbb::blocked_range<int>(0, mHeight), [&](const tbb::blocked_range<int>& r) {
        const int W = mWidth;
        thread_local std::vector<double> columnLo, columnHi;
        columnLo.resize(static_cast<std::size_t>(W));
        columnHi.resize(static_cast<std::size_t>(W));
        double* __restrict cl = columnLo.data();
        double* __restrict ch = columnHi.data();
        for (int y = r.begin(); y != r.end(); ++y) {
            const int y0 = std::max(0, y - 1), y1 = std::min(mHeight - 1, y + 1);
            const double* __restrict l0 = &mLuminance[static_cast<std::size_t>(y0) * W];
            const double* __restrict h0 = &mLuminanceHi[static_cast<std::size_t>(y0) * W];
            for (int x = 0; x < W; ++x) {
                cl[x] = l0[x];
                ch[x] = h0[x];
            }
            for (int yy = y0 + 1; yy <= y1; ++yy) {
                const double* __restrict l = &mLuminance[static_cast<std::size_t>(yy) * W];
                const double* __restrict h = &mLuminanceHi[static_cast<std::size_t>(yy) * W];
                for (int x = 0; x < W; ++x) {
                    cl[x] = std::min(cl[x], l[x]);
                    ch[x] = std::max(ch[x], h[x]);
                }
            }
            // Every pixel computes and the empty ones take 1 (no point: most wanted) by a
            // select, so that the loop vectorizes: which pixels are empty follows no pattern.
            const std::size_t row = static_cast<std::size_t>(y) * W;
            const int* __restrict screen = &mScreenOfPixel[row];
            const int* __restrict ages = &mPixelAge[row];
            double* __restrict priority = &mPriority[row];
            const double ageWeight = mOptions.ageWeight, ageScale = mOptions.ageScale;
            const double contrastWeight = mOptions.contrastWeight;
            auto prioritize = [&](int x, double lo, double hi) {
                // Local luminance contrast over the 3×3 points (Walter et al. 2002).
                const double contrast = hi > 0 ? (hi - lo) / (hi + lo) : 0.0;
                const double age = ages[x];
                const double p =
                    std::min(0.99, ageWeight * age / (age + ageScale) +
                                       contrastWeight * std::clamp(contrast, 0.0, 1.0));
                // Empty pixels and stale points (their lighting changed) first.
                priority[x] = screen[x] < 0 || age >= kStaleAge ? 1.0 : p;
            };
            // The extremes in the order of a left-to-right scan: cl[x], then x − 1, then x + 1.
            prioritize(0, W > 1 ? std::min(cl[0], cl[1]) : cl[0],
                       W > 1 ? std::max(ch[0], ch[1]) : ch[0]);
            for (int x = 1; x + 1 < W; ++x)
                prioritize(x, std::min(std::min(cl[x], cl[x - 1]), cl[x + 1]),
                           std::max(std::max(ch[x], ch[x - 1]), ch[x + 1]));
            if (W > 1)
                prioritize(W - 1, std::min(cl[W - 1], cl[W - 2]), std::max(ch[W - 1], ch[W - 2]));
        }
    });
}

void RenderCache::applyInterpolationFeedback(const std::vector<float>& weights) {
    if (weights.size() != mPriority.size())
        throw std::invalid_argument(
            "RenderCache::applyInterpolationFeedback: " + std::to_string(weights.size()) +
            " weights for " + std::to_string(mPriority.size()) + " pixels");
    if (!(mOptions.feedbackWeight > 0)) return;
    const double floor = std::clamp(mOptions.emptyFloor, 0.0, 1.0);
    const double scale = 1.0 / mOptions.feedbackWeight;
    tbb::parallel_for(0, mHeight, [&](int y) {
        // Every pixel computes, the ones with a point keep theirs (a select, not a branch on
        // scattered empty pixels).
        const std::size_t row = static_cast<std::size_t>(y) * mWidth;
        const int* __restrict screen = &mScreenOfPixel[row];
        const float* __restrict weight = &weights[row];
        double* __restrict priority = &mPriority[row];
        for (int x = 0; x < mWidth; ++x) {
            const double w = std::max(0.0, static_cast<double>(weight[x]));
            const double fed = floor + (1.0 - floor) / (1.0 + w * scale);
            priority[x] = screen[x] >= 0 ? priority[x] : fed;
        }
    });
}

std::vector<ShadeRequest> RenderCache::requestSamples(const CameraRays& camera, int budget,
                                                      int changedBudget) {
    const std::size_t pixels = mPriority.size();
    if (budget < 0)
        budget =
            static_cast<int>(std::lround(mOptions.sampleFraction * static_cast<double>(pixels)));
    if (budget <= 0) return {};
    if (mConvergedTrust && mRequestCap > 0) mRequestCount.resize(pixels, 0);
    // What an edit changed first (Bala et al. §7.5: re-shaded before anything else): carried
    // points (no estimate of their new lighting), then stale ones (an estimate), each pass as
    // many requests as its pixels not waiting, drawn among them alone; the rest of the budget
    // over every pixel as usual (the pixels just requested wait).
    // Carried and stale pixels not waiting (most frames: none, and only the last pass runs).
    const auto changed = tbb::parallel_reduce(
        tbb::blocked_range<std::size_t>(0, pixels, 4096), std::array<std::size_t, 2>{0, 0},
        [&](const tbb::blocked_range<std::size_t>& r, std::array<std::size_t, 2> c) {
            for (std::size_t k = r.begin(); k != r.end(); ++k) {
                const int tier = held(k) || notRequestable(k) ? 0 : pixelTier(k);
                c[0] += tier == 1;
                c[1] += tier == 2;
            }
            return c;
        },
        [](std::array<std::size_t, 2> a, const std::array<std::size_t, 2>& b) {
            return std::array<std::size_t, 2>{a[0] + b[0], a[1] + b[1]};
        });
    const std::size_t count[3] = {0, changed[0], changed[1]};
    budget += static_cast<int>(std::min<std::size_t>(
        static_cast<std::size_t>(std::max(changedBudget, 0)), count[1] + count[2]));
    // Per pass, the pixels it draws among (tier ≥ the pass's), less those already requested.
    const std::size_t among[3] = {pixels, count[1] + count[2], count[2]};
    std::vector<ShadeRequest> out;
    for (int tier : {2, 1, 0}) {
        const std::size_t open = among[tier] > out.size() ? among[tier] - out.size() : 0;
        const int take = static_cast<int>(std::min<std::size_t>(budget, open));
        if (take <= 0) continue;
        std::vector<ShadeRequest> pass = mOptions.parallel
                                             ? requestSamplesParallel(camera, take, tier)
                                             : requestSamplesSerial(camera, take, tier);
        budget -= static_cast<int>(pass.size());
        out.insert(out.end(), pass.begin(), pass.end());
        if (budget <= 0) break;
    }
    if (mConvergedTrust && mRequestCap > 0) {
        for (const ShadeRequest& r : out) {
            std::uint16_t& n = mRequestCount[static_cast<std::size_t>(r.pixel.y) * mWidth +
                                             static_cast<std::size_t>(r.pixel.x)];
            if (n < 0xFFFF) ++n;
        }
    }
    return out;
}

std::uint64_t RenderCache::frameSeed(int tier) const {
    return hashPair(tier == 0 ? mOptions.seed : mOptions.seed ^ (0x57A1E5EEDULL * tier), mFrame);
}

std::vector<ShadeRequest> RenderCache::requestSamplesSerial(const CameraRays& camera, int budget,
                                                            int tier) {
    const std::size_t pixels = mPriority.size();
    std::vector<ShadeRequest> out;

    // Effective priority: pixels requested in the last holdFrames frames wait; only those of
    // tier ≥ `tier` count.
    std::vector<double> pr(mPriority);
    for (std::size_t k = 0; k < pixels; ++k)
        if (held(k) || pixelTier(k) < tier || notRequestable(k)) pr[k] = 0;

    // Tiles: summed priority, then a systematic sample of `budget` positions over the sums.
    const int T = std::max(1, mOptions.tileSize);
    const int tilesX = (mWidth + T - 1) / T, tilesY = (mHeight + T - 1) / T;
    std::vector<double> tileSum(static_cast<std::size_t>(tilesX) * tilesY, 0.0);
    for (int y = 0; y < mHeight; ++y)
        for (int x = 0; x < mWidth; ++x) tileSum[(y / T) * tilesX + x / T] += pr[y * mWidth + x];
    const double total = std::accumulate(tileSum.begin(), tileSum.end(), 0.0);
    if (!(total > 0)) return out;
    CacheRandom rng{frameSeed(tier)};
    std::vector<int> tileCount(tileSum.size(), 0);
    {
        const double u0 = rng.next();
        std::size_t t = 0;
        double upTo = tileSum[0];
        for (int k = 0; k < budget; ++k) {
            const double target = (u0 + k) / budget * total;
            while (t + 1 < tileSum.size() && target >= upTo) upTo += tileSum[++t];
            ++tileCount[t];
        }
    }

    // Within a tile, its highest-priority pixels (random order among equals), jittered.
    std::vector<std::pair<double, int>> cand;
    for (int ty = 0; ty < tilesY; ++ty) {
        for (int tx = 0; tx < tilesX; ++tx) {
            const int want = tileCount[ty * tilesX + tx];
            if (want == 0) continue;
            cand.clear();
            for (int y = ty * T; y < std::min(mHeight, (ty + 1) * T); ++y)
                for (int x = tx * T; x < std::min(mWidth, (tx + 1) * T); ++x) {
                    const double p = pr[y * mWidth + x];
                    if (p > 0) cand.push_back({p + 1e-9 * rng.next(), y * mWidth + x});
                }
            const std::size_t take = std::min<std::size_t>(want, cand.size());
            std::partial_sort(cand.begin(), cand.begin() + take, cand.end(),
                              [](const auto& a, const auto& b) { return a.first > b.first; });
            for (std::size_t c = 0; c < take; ++c) {
                const int k = cand[c].second;
                // The y jitter is drawn first: the order GCC evaluated the two draws in when
                // they were the arguments of one constructor (kept so the samples stay put).
                const double jy = rng.next();
                const double jx = rng.next();
                const glm::dvec2 p(k % mWidth + jx, k / mWidth + jy);
                out.push_back({p, camera.origin(), camera.rayDirection(p.x, p.y), mFrame});
                mRequested[k] = mFrame + 1;
            }
        }
    }
    return out;
}

std::vector<ShadeRequest> RenderCache::requestSamplesParallel(const CameraRays& camera, int budget,
                                                              int tier) {
    // requestSamplesSerial() reorganized: the effective priorities, tile sums and each tile's
    // choice run in parallel; each tile draws its stretch of the frame's counter-based random
    // sequence from its offset (the order the serial loop consumes it in: u0, then per tile
    // that gets requests one draw per candidate and two per request).
    // Bit for bit the serial result (tested).
    const int T = std::max(1, mOptions.tileSize);
    const int tilesX = (mWidth + T - 1) / T, tilesY = (mHeight + T - 1) / T;
    const std::size_t tiles = static_cast<std::size_t>(tilesX) * tilesY;
    mEffective.resize(mPriority.size());
    mTileSum.assign(tiles, 0.0);
    mTileCandidates.assign(tiles, 0);
    tbb::parallel_for(0, tilesY, [&](int ty) {
        // Each tile sums its pixels row by row, left to right, as the serial loop does.
        for (int y = ty * T; y < std::min(mHeight, (ty + 1) * T); ++y) {
            for (int tx = 0; tx < tilesX; ++tx) {
                const std::size_t t = static_cast<std::size_t>(ty) * tilesX + tx;
                double sum = mTileSum[t];
                int candidates = mTileCandidates[t];
                for (int x = tx * T; x < std::min(mWidth, (tx + 1) * T); ++x) {
                    const std::size_t k = static_cast<std::size_t>(y) * mWidth + x;
                    // (A select: the held pixels are scattered.)
                    const bool out = held(k) || pixelTier(k) < tier || notRequestable(k);
                    const double p = out ? 0.0 : mPriority[k];
                    mEffective[k] = p;
                    sum += p;
                    candidates += p > 0;
                }
                mTileSum[t] = sum;
                mTileCandidates[t] = candidates;
            }
        }
    });
    const double total = std::accumulate(mTileSum.begin(), mTileSum.end(), 0.0);
    if (!(total > 0)) return {};
    const std::uint64_t seed = frameSeed(tier);
    std::vector<int> tileCount(tiles, 0);
    {
        const double u0 = CacheRandom::at(seed, 0);
        std::size_t t = 0;
        double upTo = mTileSum[0];
        for (int k = 0; k < budget; ++k) {
            const double target = (u0 + k) / budget * total;
            while (t + 1 < tiles && target >= upTo) upTo += mTileSum[++t];
            ++tileCount[t];
        }
    }
    // Per tile: its offset in the random stream and in the output.
    std::vector<std::size_t> drawStart(tiles + 1, 0), outStart(tiles + 1, 0);
    for (std::size_t t = 0; t < tiles; ++t) {
        const std::size_t want = static_cast<std::size_t>(tileCount[t]);
        const std::size_t candidates = static_cast<std::size_t>(mTileCandidates[t]);
        const std::size_t take = std::min(want, candidates);
        drawStart[t + 1] = drawStart[t] + (want == 0 ? 0 : candidates + 2 * take);
        outStart[t + 1] = outStart[t] + (want == 0 ? 0 : take);
    }

    std::vector<ShadeRequest> out(outStart[tiles]);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, tiles, 16), [&](const tbb::blocked_range<
                                                                         std::size_t>& r) {
        std::vector<std::pair<double, int>> cand;
        for (std::size_t t = r.begin(); t != r.end(); ++t) {
            const int want = tileCount[t];
            if (want == 0) continue;
            const int tx = static_cast<int>(t % tilesX), ty = static_cast<int>(t / tilesX);
            // The tile's stretch of the stream: one draw per candidate (its tie-break), then
            // two per request (its place in the pixel).
            const std::uint64_t first = 1 + drawStart[t];  // after u0
            cand.clear();
            double top = 0;
            for (int y = ty * T; y < std::min(mHeight, (ty + 1) * T); ++y)
                for (int x = tx * T; x < std::min(mWidth, (tx + 1) * T); ++x) {
                    const double p = mEffective[y * mWidth + x];
                    if (!(p > 0)) continue;
                    cand.push_back({p, y * mWidth + x});
                    top = std::max(top, p);
                }
            const std::size_t take = std::min<std::size_t>(want, cand.size());
            // Candidate c's sort key: its priority and its tie-break draw.
            auto keyOf = [&](std::size_t c) {
                return cand[c].first + 1e-9 * CacheRandom::at(seed, first + c);
            };
            if (take == 1) {
                // Most tiles take one: the first largest p + 1e-9·draw (as the partial sort
                // below keeps it), whose draw in [0, 1) can lift only a p within 1e-9 of the
                // top (2e-9 for rounding); the other candidates' draws are never computed.
                std::size_t best = 0;
                double bestKey = -1;
                for (std::size_t c = 0; c < cand.size(); ++c) {
                    if (cand[c].first + 2e-9 < top) continue;
                    const double key = keyOf(c);
                    if (key > bestKey) best = c, bestKey = key;
                }
                cand[0] = {bestKey, cand[best].second};
            } else {
                for (std::size_t c = 0; c < cand.size(); ++c) cand[c].first = keyOf(c);
                std::partial_sort(cand.begin(), cand.begin() + take, cand.end(),
                                  [](const auto& a, const auto& b) { return a.first > b.first; });
            }
            CacheRandom draw{seed, first + cand.size()};
            for (std::size_t c = 0; c < take; ++c) {
                const int k = cand[c].second;
                const double jy = draw.next();  // y first, as requestSamplesSerial()
                const double jx = draw.next();
                const glm::dvec2 p(k % mWidth + jx, k / mWidth + jy);
                out[outStart[t] + c] = {p, camera.origin(), camera.rayDirection(p.x, p.y), mFrame};
                mRequested[k] = mFrame + 1;
            }
        }
    });
    return out;
}

// ---------------------------------------------------------------------------------------------
// Plain interpolation

Image RenderCache::interpolatedImage() const {
    if (mScreenPending) buildScreenPoints();
    Image image(mWidth, mHeight);
    tbb::parallel_for(0, mHeight, [&](int y) {
        for (int x = 0; x < mWidth; ++x) {
            const int s = mScreenOfPixel[y * mWidth + x];
            if (s >= 0) {
                image.at(x, y) = mScreen[s].colour;
                continue;
            }
            // The first ring of radius 1, 2 or 3 pixels that holds points, weighted 1/(1 + d²).
            for (int r = 1; r <= 3; ++r) {
                Rgb sum(0.0);
                double w = 0;
                for (int dy = -r; dy <= r; ++dy)
                    for (int dx = -r; dx <= r; ++dx) {
                        const int xx = x + dx, yy = y + dy;
                        if (xx < 0 || yy < 0 || xx >= mWidth || yy >= mHeight) continue;
                        const int q = mScreenOfPixel[yy * mWidth + xx];
                        if (q < 0) continue;
                        const glm::dvec2 d = mScreen[q].position - glm::dvec2(x + 0.5, y + 0.5);
                        const double wq = 1.0 / (1.0 + glm::dot(d, d));
                        sum += wq * mScreen[q].colour;
                        w += wq;
                    }
                if (w > 0) {
                    image.at(x, y) = sum / w;
                    break;
                }
            }
        }
    });
    return image;
}

}  // namespace penumbra
