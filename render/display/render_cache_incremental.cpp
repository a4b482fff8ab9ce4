// RenderCache's incremental reprojection (RenderCacheOptions::incremental): with a still camera
// a frame redoes only the pixels its changed points reach, and equals the whole reprojection
// bit for bit. See render_cache.h.
//
// What the whole reprojection into an EPI keeps when the camera did not move
// (keepForIncremental): per pixel the list of points projecting there (in index order), the
// z-buffer's point before culling and the visible one after; per point its projection. Every
// change to a point touches it (touch()); dropIf() takes the dropped points out of their lists
// and renumbers the ones it moves (leavePixels(), movedInPixels()).
// The next reprojection with the same camera and arrays then:
//   1. takes each point touched in place out of its old pixel's list and into its new one's,
//      both pixels dirty (relinkTouched);
//   2. ages every pixel's point by a frame, as the whole reprojection's ages do, and redoes
//      the z-buffer of the dirty pixels from their lists in index order (the whole z-buffer's
//      order, which decides near-equal depths; zBufferDirty);
//   3. redoes the culling, the visible points and their EPI samples in the dirty pixels and
//      the neighbourhoods of those whose depth moved, all the culling reads of them
//      (redoAffected);
//   4. rewrites the colours of the relit points' samples (rewriteRecoloured);
//   5. recomputes the priority image (whole: it is cheap and every age moved).

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "render/display/parallel_indices.h"
#include "render/display/render_cache.h"

namespace penumbra {

namespace {

/// The indices where `flags` equals `value`, ascending, gathered in parallel.
std::vector<int> indicesOf(const std::vector<std::uint8_t>& flags, std::uint8_t value) {
    return indicesWhere(flags.size(), [&](std::size_t i) { return flags[i] == value; });
}

}  // namespace

void RenderCache::growPerPointArrays() {
    const std::size_t n = mPoints.size();
    if (mProj.size() < n) mProj.resize(n);
    if (mProjBand.size() < n) mProjBand.resize(n, 0xFF);
    if (mNextInPixel.size() < n) mNextInPixel.resize(n, -1);
}

void RenderCache::keepForIncremental(const EpiPointArrays& epi) {
    const std::size_t pixels = static_cast<std::size_t>(mWidth) * mHeight;
    // cullOccludedPoints() swapped the z-buffer out: mFiltered holds it before culling.
    mZPoint.swap(mFiltered);
    mShownPoint = mPixelPoint;
    mPixelHead.assign(pixels, -1);
    mNextInPixel.resize(mPoints.size());
    // Each band's entries are in index order: pushed to the front from the last, each
    // pixel's list comes out ascending. Bands own disjoint pixels.
    const int bands = static_cast<int>(mBandStart.size()) - 1;
    tbb::parallel_for(0, bands, [&](int band) {
        for (std::uint32_t j = mBandStart[band + 1]; j-- > mBandStart[band];) {
            const BandEntry& e = mBandPoints[j];
            mNextInPixel[e.point] = mPixelHead[e.pixel];
            mPixelHead[e.pixel] = e.point;
        }
    });
    for (int y = 0; y < mHeight; ++y) mRowVisible[y] = mRowCount[y + 1] - mRowCount[y];
    mIncrementalEpi = epi;
    mIncrementalValid = true;
}

bool RenderCache::reprojectIncremental(const CameraRays& camera, const EpiPointArrays& epi) {
    if (!mIncrementalValid || !mLastCamera || !(*mLastCamera == camera) ||
        epi.depth != mIncrementalEpi.depth || epi.colour != mIncrementalEpi.colour ||
        epi.position != mIncrementalEpi.position || epi.trust != mIncrementalEpi.trust)
        return false;
    const std::size_t n = mPoints.size();
    growPerPointArrays();
    const std::vector<int> touched = indicesOf(mTouched, kTouchedPlace);
    if (n == 0 || static_cast<double>(touched.size()) > mOptions.incrementalShare * n) return false;
    const std::vector<int> recoloured = indicesOf(mTouched, kTouchedColour);

    relinkTouched(camera, touched);
    // Every point a frame older (stale and carried ones keep their ages), then the dirty
    // pixels' z-buffer from their lists.
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, mPixelAge.size(), 1 << 15),
                      [&](const tbb::blocked_range<std::size_t>& r) {
                          int* __restrict age = mPixelAge.data();
                          for (std::size_t k = r.begin(); k != r.end(); ++k)
                              age[k] += age[k] < kStaleAge ? 1 : 0;
                      });
    const std::vector<int> dirty = indicesOf(mDirty, 1);
    const std::vector<std::uint8_t> depthMoved = zBufferDirty(dirty);
    // A screen point list built since the last reprojection renumbered mScreenOfPixel.
    if (!mScreenPending) mScreenOfPixel = mShownPoint;
    const std::size_t rewritten = redoAffected(camera, epi, touched, dirty, depthMoved) +
                                  rewriteRecoloured(camera, epi, recoloured);

    for (int k : dirty) mDirty[k] = 0;
    for (int i : touched) mTouched[i] = 0;
    for (int i : recoloured) mTouched[i] = 0;
    mRowCount[0] = 0;
    for (int y = 0; y < mHeight; ++y) mRowCount[y + 1] = mRowCount[y] + mRowVisible[y];
    mVisibleCount = static_cast<std::size_t>(mRowCount[mHeight]);
    mPixelPoint = mShownPoint;
    mScreenPending = true;
    mPendingOriginals.clear();
    mScreenCamera = camera;
    noteView(camera);
    mIncrementalFrame = true;
    mReprojectedPixels = std::min(rewritten, mShownPoint.size());
    computePriority();  // whole: it is cheap and every age moved
    return true;
}

void RenderCache::relinkTouched(const CameraRays& camera, const std::vector<int>& touched) {
    for (int i : touched)
        if (mProjBand[i] != 0xFF) {
            unlinkFromPixel(i, mProj[i].pixel);
            mDirty[mProj[i].pixel] = 1;
        }
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, touched.size(), 1024),
                      [&](const tbb::blocked_range<std::size_t>& r) {
                          for (std::size_t t = r.begin(); t != r.end(); ++t) {
                              const int i = touched[t];
                              ProjectedPoint& proj = mProj[i];
                              const bool on =
                                  !(mFlags[i] & kHiddenFlag) &&
                                  projectOne(camera, mPosition[i], proj.depth, proj.pixel);
                              mProjBand[i] = on ? 0 : 0xFF;
                          }
                      });
    for (int i : touched)
        if (mProjBand[i] != 0xFF) {
            const int k = mProj[i].pixel;
            mNextInPixel[i] = mPixelHead[k];
            mPixelHead[k] = i;
            mDirty[k] = 1;
        }
}

std::vector<std::uint8_t> RenderCache::zBufferDirty(const std::vector<int>& dirty) {
    std::vector<std::uint8_t> depthMoved(dirty.size());
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, dirty.size(), 256),
                      [&](const tbb::blocked_range<std::size_t>& r) {
                          std::vector<int> candidates;
                          for (std::size_t d = r.begin(); d != r.end(); ++d) {
                              const int k = dirty[d];
                              // In index order, as the whole z-buffer takes them.
                              candidates.clear();
                              for (int j = mPixelHead[k]; j >= 0; j = mNextInPixel[j])
                                  candidates.push_back(j);
                              std::sort(candidates.begin(), candidates.end());
                              int held = -1, heldAge = 0;
                              double heldDepth = kNoDepth;
                              for (int j : candidates) {
                                  const double depth = mProj[j].depth;
                                  const int age = pointAge(static_cast<std::size_t>(j));
                                  if (held >= 0 && !takesPixel(depth, age, heldDepth, heldAge))
                                      continue;
                                  held = j;
                                  heldDepth = depth;
                                  heldAge = age;
                              }
                              mZPoint[k] = held;
                              depthMoved[d] = mPixelDepth[k] != heldDepth;
                              mPixelDepth[k] = heldDepth;
                              if (held >= 0) mPixelAge[k] = heldAge;
                          }
                      });
    return depthMoved;
}

std::size_t RenderCache::redoAffected(const CameraRays& camera, const EpiPointArrays& epi,
                                      const std::vector<int>& touched,
                                      const std::vector<int>& dirty,
                                      const std::vector<std::uint8_t>& depthMoved) {
    const int rad = std::max(0, mOptions.depthRadius);
    std::vector<int> affected;
    affected.reserve(dirty.size() * 2);
    auto affect = [&](int q) {
        if (!mAffected[q]) {
            mAffected[q] = 1;
            affected.push_back(q);
        }
    };
    for (std::size_t d = 0; d < dirty.size(); ++d) {
        const int k = dirty[d];
        affect(k);
        if (!depthMoved[d]) continue;
        const int x = k % mWidth, y = k / mWidth;
        for (int yy = std::max(0, y - rad); yy <= std::min(mHeight - 1, y + rad); ++yy)
            for (int xx = std::max(0, x - rad); xx <= std::min(mWidth - 1, x + rad); ++xx)
                affect(yy * mWidth + xx);
    }
    std::vector<int> shown(affected.size());
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, affected.size(), 512),
                      [&](const tbb::blocked_range<std::size_t>& r) {
                          for (std::size_t a = r.begin(); a != r.end(); ++a)
                              shown[a] =
                                  culledPoint(mZPoint, affected[a] % mWidth, affected[a] / mWidth);
                      });
    // Visibility: the touched points and the former points of the pixels whose point
    // changed are not visible unless they are shown below. A pixel neither dirty nor showing
    // another point keeps its sample (its point is untouched).
    for (int i : touched) mVisible[i] = 0;
    std::vector<std::uint8_t> rewrite(affected.size());
    for (std::size_t a = 0; a < affected.size(); ++a) {
        const int k = affected[a];
        rewrite[a] = mDirty[k] || shown[a] != mShownPoint[k];
        if (!rewrite[a]) continue;
        if (mShownPoint[k] >= 0) {
            mVisible[mShownPoint[k]] = 0;
            --mRowVisible[k / mWidth];
        }
        if (shown[a] >= 0) ++mRowVisible[k / mWidth];
        mShownPoint[k] = shown[a];
    }
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, affected.size(), 512),
                      [&](const tbb::blocked_range<std::size_t>& r) {
                          for (std::size_t a = r.begin(); a != r.end(); ++a) {
                              mAffected[affected[a]] = 0;
                              if (rewrite[a]) writeShown(camera, epi, affected[a], shown[a]);
                          }
                      });
    return static_cast<std::size_t>(std::count(rewrite.begin(), rewrite.end(), 1));
}

std::size_t RenderCache::rewriteRecoloured(const CameraRays& camera, const EpiPointArrays& epi,
                                           const std::vector<int>& recoloured) {
    if (static_cast<double>(recoloured.size()) > mOptions.incrementalShare * mPoints.size()) {
        tbb::parallel_for(tbb::blocked_range<std::size_t>(0, mShownPoint.size(), 4096),
                          [&](const tbb::blocked_range<std::size_t>& r) {
                              for (std::size_t k = r.begin(); k != r.end(); ++k)
                                  if (mShownPoint[k] >= 0)
                                      writeShownColour(camera, epi, static_cast<int>(k),
                                                       mShownPoint[k]);
                          });
        return mShownPoint.size();
    }
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, recoloured.size(), 1024),
                      [&](const tbb::blocked_range<std::size_t>& r) {
                          for (std::size_t t = r.begin(); t != r.end(); ++t) {
                              const int i = recoloured[t];
                              if (mProjBand[i] == 0xFF) continue;
                              const int k = mProj[i].pixel;
                              if (mShownPoint[k] == i) writeShownColour(camera, epi, k, i);
                          }
                      });
    return recoloured.size();
}

void RenderCache::writeShown(const CameraRays& camera, const EpiPointArrays& epi, int k, int i) {
    mScreenOfPixel[k] = i;
    if (i < 0) {
        mLuminance[k] = 1e300;
        mLuminanceHi[k] = -1e300;
        epi.place(k, nullptr);
        return;
    }
    mVisible[i] = 1;
    const ScreenPoint p = shownPoint(camera, k, i);
    epi.place(k, &p);
    mLuminance[k] = mLuminanceHi[k] = luminance(p.colour);
}

void RenderCache::writeShownColour(const CameraRays& camera, const EpiPointArrays& epi, int k,
                                   int i) {
    // The sample's place, depth and trust stand; a kept sample stays kept while its colour is
    // finite (epiKeepsPoint), and then only its colour changes.
    const Rgb& colour = mPoints[i].colour;
    if (epi.position[k] == 0xFF || !std::isfinite(colour.x) || !std::isfinite(colour.y) ||
        !std::isfinite(colour.z)) {
        writeShown(camera, epi, k, i);
        return;
    }
    epi.colour[k] = glm::vec3(colour);
    mLuminance[k] = mLuminanceHi[k] = luminance(colour);
}

void RenderCache::leavePixels(const std::vector<int>& gone) {
    growPerPointArrays();
    for (int i : gone) {
        if (mProjBand[i] == 0xFF) continue;
        const int k = mProj[i].pixel;
        unlinkFromPixel(i, k);
        mDirty[k] = 1;
        if (mZPoint[k] == i) mZPoint[k] = -1;
        if (mShownPoint[k] == i) {
            mShownPoint[k] = -1;
            --mRowVisible[k / mWidth];
        }
    }
}

void RenderCache::movedInPixels(int from, int to) {
    mProj[to] = mProj[from];
    mProjBand[to] = mProjBand[from];
    if (mProjBand[from] == 0xFF) return;
    // Its place in the pixel's list, under its new index; the pixel is redone, since ties of
    // the z-buffer follow the index order.
    const int k = mProj[from].pixel;
    int* at = &mPixelHead[k];
    while (*at != from) at = &mNextInPixel[*at];
    *at = to;
    mNextInPixel[to] = mNextInPixel[from];
    mDirty[k] = 1;
    if (mZPoint[k] == from) mZPoint[k] = to;
    if (mShownPoint[k] == from) mShownPoint[k] = to;
}

void RenderCache::unlinkFromPixel(int i, int k) {
    int* at = &mPixelHead[k];
    while (*at >= 0 && *at != i) at = &mNextInPixel[*at];
    if (*at == i) *at = mNextInPixel[i];
}

}  // namespace penumbra
