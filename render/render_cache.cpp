// Index: construction · insertion and replacement · reprojection and depth culling (Walter et
//        al. 1999) · priority image and sample requests · plain interpolation · invalidation
//        · toString
#include "render/render_cache.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <sstream>
#include <stdexcept>

#include "solver/form_factor.h"

namespace penumbra {

namespace {

/// Of two near-equal depths (within this fraction) the younger point wins the pixel.
constexpr double kSameSurface = 0.01;

struct CacheRandom {
    std::uint64_t state;
    double next() {
        state = hashPair(state, 0x7f4a7c159e3779b9ull);
        return static_cast<double>(state >> 11) * 0x1.0p-53;
    }
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
    mPixelPoint.assign(pixels, -1);
    mScreenOfPixel.assign(pixels, -1);
    mPriority.assign(pixels, 1.0);
    mRequested.assign(pixels, 0);
}

// ---------------------------------------------------------------------------------------------
// Insertion and replacement

void RenderCache::insert(const std::vector<ShadedPoint>& batch) {
    auto toCache = [](const ShadedPoint& s) {
        CachePoint p;
        p.position = s.position;
        p.colour = s.radiance;
        p.object = s.object;
        p.element = s.element;
        p.age = 0;
        p.frame = s.frame;
        p.visible = true;
        return p;
    };
    // Of a batch larger than the cache only its last capacity() points stay.
    std::size_t first = batch.size() > mCapacity ? batch.size() - mCapacity : 0;
    std::size_t count = batch.size() - first;
    if (count == 0) return;
    const std::size_t existing = mPoints.size();
    const std::size_t free = mCapacity - existing;
    std::size_t victims = count > free ? count - free : 0;

    // Replace first what was not visible in the last frame, then the oldest.
    std::vector<int> order;
    if (victims > 0) {
        order.resize(existing);
        std::iota(order.begin(), order.end(), 0);
        auto moreEvictable = [&](int a, int b) {
            const CachePoint &pa = mPoints[a], &pb = mPoints[b];
            if (pa.visible != pb.visible) return !pa.visible;
            if (pa.age != pb.age) return pa.age > pb.age;
            return a < b;
        };
        std::nth_element(order.begin(), order.begin() + (victims - 1), order.end(), moreEvictable);
    }
    std::size_t v = 0;
    for (std::size_t i = first; i < batch.size(); ++i) {
        if (mPoints.size() < mCapacity)
            mPoints.push_back(toCache(batch[i]));
        else
            mPoints[order[v++]] = toCache(batch[i]);
    }
    std::fill(mPixelPoint.begin(), mPixelPoint.end(), -1);
}

// ---------------------------------------------------------------------------------------------
// Reprojection and depth culling

const std::vector<ScreenPoint>& RenderCache::reproject(const CameraRays& camera) {
    if (camera.width() != mWidth || camera.height() != mHeight) {
        throw std::invalid_argument("RenderCache::reproject: camera raster " +
                                    std::to_string(camera.width()) + "x" +
                                    std::to_string(camera.height()) + " differs from the cache's " +
                                    std::to_string(mWidth) + "x" + std::to_string(mHeight));
    }
    ++mFrame;
    const std::size_t n = mPoints.size();
    std::vector<glm::dvec2> position(n);
    std::vector<double> depth(n);
    std::vector<int> pixel(n, -1);

    // Project every point to the new camera (parallel; no shared writes).
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, n, 4096), [&](const auto& r) {
        for (std::size_t i = r.begin(); i != r.end(); ++i) {
            const auto p = camera.projectToPixel(mPoints[i].position);
            if (!p || !(p->x >= 0 && p->x < mWidth && p->y >= 0 && p->y < mHeight)) continue;
            position[i] = *p;
            depth[i] = glm::dot(mPoints[i].position - camera.origin(), camera.forward());
            const int x = std::min(static_cast<int>(p->x), mWidth - 1);
            const int y = std::min(static_cast<int>(p->y), mHeight - 1);
            pixel[i] = y * mWidth + x;
        }
    });

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
        if (depth[i] < dc * (1 - kSameSurface) ||
            (depth[i] <= dc * (1 + kSameSurface) && mPoints[i].age < mPoints[cur].age))
            cur = static_cast<int>(i);
    }

    // Depth culling (after Walter et al. 1999): a point is taken as hidden when at least half
    // of the points around it are nearer by more than the margin, i.e. it is seen through a
    // gap in a nearer surface. Walter et al. compare with the neighbourhood's mean depth; that
    // also culls the background points along every silhouette, a one-pixel band that new
    // samples could never fill (each would be culled again), so the majority is used instead.
    const std::vector<int> unfiltered = mPixelPoint;
    const int rad = std::max(0, mOptions.depthRadius);
    tbb::parallel_for(0, mHeight, [&](int y) {
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
    });

    // Visible points in pixel order; then every point ages by a frame.
    for (CachePoint& p : mPoints) p.visible = false;
    mScreen.clear();
    std::fill(mScreenOfPixel.begin(), mScreenOfPixel.end(), -1);
    for (std::size_t k = 0; k < mPixelPoint.size(); ++k) {
        const int i = mPixelPoint[k];
        if (i < 0) continue;
        mPoints[i].visible = true;
        mScreenOfPixel[k] = static_cast<int>(mScreen.size());
        mScreen.push_back({position[i], depth[i], mPoints[i].colour, mPoints[i].age});
    }
    computePriority();
    for (CachePoint& p : mPoints) ++p.age;
    return mScreen;
}

// ---------------------------------------------------------------------------------------------
// Priority image and sample requests

void RenderCache::computePriority() {
    tbb::parallel_for(0, mHeight, [&](int y) {
        for (int x = 0; x < mWidth; ++x) {
            const int s = mScreenOfPixel[y * mWidth + x];
            if (s < 0) {
                mPriority[y * mWidth + x] = 1.0;  // no point: most wanted
                continue;
            }
            // Local luminance contrast over the 3×3 points (Walter et al. 2002).
            double lo = 1e300, hi = -1e300;
            for (int dy = -1; dy <= 1; ++dy)
                for (int dx = -1; dx <= 1; ++dx) {
                    const int xx = x + dx, yy = y + dy;
                    if (xx < 0 || yy < 0 || xx >= mWidth || yy >= mHeight) continue;
                    const int q = mScreenOfPixel[yy * mWidth + xx];
                    if (q < 0) continue;
                    const double l = luminance(mScreen[q].colour);
                    lo = std::min(lo, l), hi = std::max(hi, l);
                }
            const double contrast = hi > 0 ? (hi - lo) / (hi + lo) : 0.0;
            const double age = mScreen[s].age;
            mPriority[y * mWidth + x] =
                std::min(0.99, mOptions.ageWeight * age / (age + mOptions.ageScale) +
                                   mOptions.contrastWeight * std::clamp(contrast, 0.0, 1.0));
        }
    });
}

std::vector<ShadeRequest> RenderCache::requestSamples(const CameraRays& camera, int budget) {
    const std::size_t pixels = mPriority.size();
    if (budget < 0)
        budget =
            static_cast<int>(std::lround(mOptions.sampleFraction * static_cast<double>(pixels)));
    std::vector<ShadeRequest> out;
    if (budget <= 0) return out;

    // Effective priority: pixels requested in the last holdFrames frames wait.
    std::vector<double> pr(mPriority);
    for (std::size_t k = 0; k < pixels; ++k)
        if (mRequested[k] > 0 && mFrame + 1 < mRequested[k] + mOptions.holdFrames) pr[k] = 0;

    // Tiles: summed priority, then a systematic sample of `budget` positions over the sums.
    const int T = std::max(1, mOptions.tileSize);
    const int tilesX = (mWidth + T - 1) / T, tilesY = (mHeight + T - 1) / T;
    std::vector<double> tileSum(static_cast<std::size_t>(tilesX) * tilesY, 0.0);
    for (int y = 0; y < mHeight; ++y)
        for (int x = 0; x < mWidth; ++x) tileSum[(y / T) * tilesX + x / T] += pr[y * mWidth + x];
    const double total = std::accumulate(tileSum.begin(), tileSum.end(), 0.0);
    if (!(total > 0)) return out;
    CacheRandom rng{hashPair(mOptions.seed, mFrame)};
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
                const glm::dvec2 p(k % mWidth + rng.next(), k / mWidth + rng.next());
                out.push_back({p, camera.origin(), camera.rayDirection(p.x, p.y), mFrame});
                mRequested[k] = mFrame + 1;
            }
        }
    }
    return out;
}

// ---------------------------------------------------------------------------------------------
// Plain interpolation

Image RenderCache::interpolatedImage() const {
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

// ---------------------------------------------------------------------------------------------
// Invalidation

template <class Drop>
std::size_t RenderCache::dropIf(Drop drop) {
    const std::size_t before = mPoints.size();
    mPoints.erase(std::remove_if(mPoints.begin(), mPoints.end(), drop), mPoints.end());
    std::fill(mPixelPoint.begin(), mPixelPoint.end(), -1);
    return before - mPoints.size();
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

// ---------------------------------------------------------------------------------------------
// toString

std::string CachePoint::toString() const {
    std::ostringstream s;
    s << "CachePoint{position (" << position.x << ", " << position.y << ", " << position.z
      << "), colour (" << colour.x << ", " << colour.y << ", " << colour.z << "), object " << object
      << ", element " << element << ", age " << age << ", frame " << frame
      << (visible ? ", visible}" : ", hidden}");
    return s.str();
}

std::string RenderCache::toString() const {
    std::ostringstream s;
    s << "RenderCache{" << mWidth << "x" << mHeight << ", " << mPoints.size() << "/" << mCapacity
      << " points, " << mScreen.size() << " visible, frame " << mFrame << "}";
    return s.str();
}

}  // namespace penumbra
