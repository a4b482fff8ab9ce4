// RenderCache's invalidation (Bala et al. §7.5: what an edit changed leaves the cache, is
// relit, carried with a moved object, marked stale or hidden) and its toString; see
// render_cache.h.

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <sstream>

#include "render/display/parallel_indices.h"
#include "render/display/render_cache.h"

namespace penumbra {

// ---------------------------------------------------------------------------------------------
// Invalidation

template <class Drop>
std::size_t RenderCache::dropIf(Drop drop) {
    // Which points go (in parallel: the predicates only read), then each hole below the new
    // size takes the next surviving point from above it: a drag's shadow drop removes a few
    // thousand points of hundreds of thousands every frame, and so moves only that many
    // instead of compacting the whole cache. The survivors' order changes; the ties that
    // reprojection and replacement resolve by index stay deterministic. A pending screen
    // point list reads points by index: renumbered (renumberPendingScreen).
    const std::size_t before = mPoints.size();
    const std::vector<int> gone =
        indicesWhere(before, [&](std::size_t i) { return drop(mPoints[i]); });
    mDropFlags.assign(before, 0);
    for (int i : gone) mDropFlags[i] = 1;
    if (gone.empty()) return 0;
    const std::size_t kept = before - gone.size();
    if (mScreenPending) {
        if (kept > 0)
            renumberPendingScreen(gone, kept);
        else
            buildScreenPoints();
    }
    if (mIncrementalValid) leavePixels(gone);
    std::size_t from = kept;
    for (int hole : gone) {
        if (static_cast<std::size_t>(hole) >= kept) break;
        while (mDropFlags[from]) ++from;
        movePoint(from++, static_cast<std::size_t>(hole));
    }
    mPoints.resize(kept);
    mPosition.resize(kept);
    mElementOf.resize(kept);
    mObjectOf.resize(kept);
    mBorn.resize(kept);
    mVisible.resize(kept);
    mFlags.resize(kept);
    mTouched.resize(kept);
    if (mIncrementalValid) {
        mProj.resize(kept);
        mProjBand.resize(kept);
        mNextInPixel.resize(kept);
    }
    std::fill(mPixelPoint.begin(), mPixelPoint.end(), -1);
    restartRequestCounts();
    return gone.size();
}

void RenderCache::renumberPendingScreen(const std::vector<int>& gone, std::size_t kept) {
    // The holes below `kept` take the survivors above it in order (dropIf): each survivor's
    // new index.
    const std::size_t before = mPoints.size();
    std::vector<int> newIndex(before - kept, -1);
    std::size_t from = kept;
    for (int hole : gone) {
        if (static_cast<std::size_t>(hole) >= kept) break;
        while (mDropFlags[from]) ++from;
        newIndex[from++ - kept] = hole;
    }
    // Per pixel of the list: a moved point under its new index; a dropped one keeps the
    // reprojection's record (as a merge does) over a stand-in index, which the record
    // overrides in everything the list reads of the point.
    const int pixels = mWidth * mHeight;
    constexpr int kChunk = 1 << 14;
    const int chunks = (pixels + kChunk - 1) / kChunk;
    std::vector<std::vector<PendingOriginal>> records(static_cast<std::size_t>(chunks));
    tbb::parallel_for(0, chunks, [&](int c) {
        for (int k = c * kChunk; k < std::min(pixels, (c + 1) * kChunk); ++k) {
            const int i = mScreenOfPixel[k];
            if (i < 0) continue;
            if (mDropFlags[i]) {
                const CachePoint& p = mPoints[i];
                records[c].push_back({static_cast<std::size_t>(k), p.colour, p.position,
                                      trustOf(static_cast<std::size_t>(i))});
                mScreenOfPixel[k] = 0;
            } else if (static_cast<std::size_t>(i) >= kept) {
                mScreenOfPixel[k] = newIndex[i - kept];
            }
        }
    });
    for (const auto& r : records)
        mPendingOriginals.insert(mPendingOriginals.end(), r.begin(), r.end());
}

void RenderCache::movePoint(std::size_t from, std::size_t to) {
    mPoints[to] = std::move(mPoints[from]);
    mPosition[to] = mPosition[from];
    mElementOf[to] = mElementOf[from];
    mObjectOf[to] = mObjectOf[from];
    mBorn[to] = mBorn[from];
    mVisible[to] = mVisible[from];
    mFlags[to] = mFlags[from];
    mTouched[to] = mTouched[from];
    if (mIncrementalValid) movedInPixels(static_cast<int>(from), static_cast<int>(to));
}

std::size_t RenderCache::invalidatePoints(const std::vector<std::uint8_t>& drop) {
    if (drop.size() != mPoints.size())
        throw std::invalid_argument(
            "RenderCache::invalidatePoints: " + std::to_string(drop.size()) + " flags for " +
            std::to_string(mPoints.size()) + " points");
    // dropIf asks of each point before any moves: its index is its place in mPoints then.
    return dropIf([&](const CachePoint& p) { return drop[&p - mPoints.data()] != 0; });
}

std::size_t RenderCache::invalidateObjects(const std::unordered_set<int>& objects) {
    return dropIf([&](const CachePoint& p) { return objects.count(p.object) > 0; });
}

std::size_t RenderCache::invalidateRegion(const Vec3& centre, double radius) {
    return dropIf([&](const CachePoint& p) { return glm::length(p.position - centre) <= radius; });
}

std::size_t RenderCache::invalidateElements(const std::unordered_set<int>& elements) {
    return dropIf(
        [&](const CachePoint& p) { return p.element >= 0 && elements.count(p.element) > 0; });
}

void RenderCache::clear() {
    dropIf([](const CachePoint&) { return true; });
}

std::size_t RenderCache::relight(const std::vector<Rgb>& delta,
                                 const std::vector<std::uint8_t>& stale,
                                 const std::vector<Rgb>& before, const std::vector<Rgb>& exactPart,
                                 std::uint64_t exactSince) {
    restartRequestCounts();
    // (A pending screen point list, built later, shows the relit colours: the points are the
    // same, only their estimate is newer.)
    const std::size_t n = mPoints.size();
    std::vector<std::size_t> counts((n + 8191) / 8192, 0);
    tbb::parallel_for(std::size_t(0), counts.size(), [&](std::size_t c) {
        std::size_t changed = 0;
        for (std::size_t i = c * 8192; i < std::min(n, (c + 1) * 8192); ++i) {
            if (mElementOf[i] < 0) continue;
            const auto e = static_cast<std::size_t>(mElementOf[i]);
            bool below = false;
            if (e < delta.size() && delta[e] != Rgb(0.0)) {
                CachePoint& p = mPoints[i];
                const Rgb change = p.shading >= exactSince && e < exactPart.size()
                                       ? delta[e] - exactPart[e]
                                       : delta[e];
                for (int c = 0; c < 3; ++c) {
                    const double added = p.colour[c] + change[c];
                    if (added >= 0) {
                        p.colour[c] = added;
                        continue;
                    }
                    // Darker than its element's loss: the element's share of it, never black
                    // while the element keeps light.
                    below = true;
                    const double was = e < before.size() ? before[e][c] : 0.0;
                    p.colour[c] *= was > 0 ? std::max(0.0, (was + change[c]) / was) : 0.0;
                }
                touchColour(i);
            }
            if ((e < stale.size() && stale[e]) || below) {
                if (!(mFlags[i] & kStaleFlag)) touch(i);
                mFlags[i] |= kStaleFlag;
                ++changed;
            }
        }
        counts[c] = changed;
    });
    std::size_t total = 0;
    for (std::size_t c : counts) total += c;
    return total;
}

std::size_t RenderCache::carry(int fromObject, int toObject, const Mat4& toFromFrom,
                               int elementOffset) {
    restartRequestCounts();
    // A pending screen point list shows the points where the reprojection saw them: the moved
    // ones it shows keep that record (mergeIntoPixels' way), rather than the whole list being
    // built now for a few of its points.
    const bool pending = mScreenPending && mScreenCamera.has_value();
    constexpr std::size_t kChunk = 4096;
    const std::size_t n = mPoints.size();
    const std::size_t chunks = (n + kChunk - 1) / kChunk;
    std::vector<std::size_t> counts(chunks, 0);
    std::vector<std::vector<PendingOriginal>> originals(pending ? chunks : 0);
    tbb::parallel_for(std::size_t(0), chunks, [&](std::size_t c) {
        std::size_t here = 0;
        for (std::size_t i = c * kChunk; i < std::min(n, (c + 1) * kChunk); ++i) {
            if (mObjectOf[i] != fromObject) continue;
            CachePoint& p = mPoints[i];
            double depth = 0;
            int pixel = -1;
            if (pending && projectOne(*mScreenCamera, p.position, depth, pixel) &&
                mScreenOfPixel[pixel] == static_cast<int>(i))
                originals[c].push_back(
                    {static_cast<std::size_t>(pixel), p.colour, p.position, trustOf(i)});
            p.position = Vec3(toFromFrom * glm::dvec4(p.position, 1.0));
            p.object = toObject;
            p.element += elementOffset;
            mPosition[i] = p.position;
            mObjectOf[i] = toObject;
            mElementOf[i] = p.element;
            mFlags[i] |= kStaleFlag | kCarriedFlag;
            touch(i);
            ++here;
        }
        counts[c] = here;
    });
    std::size_t moved = 0;
    for (std::size_t c = 0; c < chunks; ++c) {
        moved += counts[c];
        if (pending)
            mPendingOriginals.insert(mPendingOriginals.end(), originals[c].begin(),
                                     originals[c].end());
    }
    return moved;
}

std::size_t RenderCache::markStale(const std::unordered_set<int>& objects) {
    restartRequestCounts();
    std::size_t marked = 0;
    for (std::size_t i = 0; i < mPoints.size(); ++i)
        if (objects.count(mPoints[i].object)) {
            if (!(mFlags[i] & kStaleFlag)) touch(i);
            mFlags[i] |= kStaleFlag;
            ++marked;
        }
    return marked;
}

std::size_t RenderCache::setHidden(
    const std::function<bool(const Vec3& position, int object)>& hidden) {
    const std::size_t n = mPoints.size();
    std::vector<std::size_t> counts((n + 4095) / 4096, 0);
    tbb::parallel_for(std::size_t(0), counts.size(), [&](std::size_t c) {
        std::size_t here = 0;
        for (std::size_t i = c * 4096; i < std::min(n, (c + 1) * 4096); ++i) {
            const bool h = hidden && hidden(mPosition[i], mObjectOf[i]);
            if (h != ((mFlags[i] & kHiddenFlag) != 0)) touch(i);
            mFlags[i] =
                static_cast<std::uint8_t>((mFlags[i] & ~kHiddenFlag) | (h ? kHiddenFlag : 0));
            here += h;
        }
        counts[c] = here;
    });
    std::size_t total = 0;
    for (std::size_t c : counts) total += c;
    return total;
}

// ---------------------------------------------------------------------------------------------
// toString

std::string CachePoint::toString() const {
    std::ostringstream s;
    s << "CachePoint{position (" << position.x << ", " << position.y << ", " << position.z
      << "), colour (" << colour.x << ", " << colour.y << ", " << colour.z << "), object " << object
      << ", element " << element << ", frame " << frame << ", exact " << exact << ", samples "
      << samples << "}";
    return s.str();
}

std::string RenderCache::toString() const {
    std::ostringstream s;
    s << "RenderCache{" << mWidth << "x" << mHeight << ", " << mPoints.size() << "/" << mCapacity
      << " points, " << mVisibleCount << " visible, frame " << mFrame << "}";
    return s.str();
}

}  // namespace penumbra
