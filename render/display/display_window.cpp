// InteractiveDisplay's windowed frames (InteractiveDisplayOptions::windowedFrames): which
// pixels' points and edges changed since they were last reconstructed.
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <vector>

#include "render/display/interactive_display.h"

namespace penumbra {

namespace {

/// A key for an edge: equal edges (bit for bit) have equal keys, and different ones almost
/// surely not (splitmix64 over the fields' bits).
std::uint64_t edgeKey(const ScreenEdge& e) {
    auto mix = [](std::uint64_t h, std::uint64_t v) {
        h ^= v + 0x9e3779b97f4a7c15ull + (h << 6) + (h >> 2);
        h ^= h >> 30;
        h *= 0xbf58476d1ce4e5b9ull;
        h ^= h >> 27;
        h *= 0x94d049bb133111ebull;
        return h ^ (h >> 31);
    };
    std::uint64_t h = static_cast<std::uint64_t>(e.kind);
    for (double v : {e.a.x, e.a.y, e.b.x, e.b.y, e.depthA, e.depthB})
        h = mix(h, std::bit_cast<std::uint64_t>(v));
    return h;
}

/// The pixels an edge may mark (its extent and a pixel around), within the raster; empty for
/// an edge with a NaN end (the EPI skips those).
PixelWindow edgeWindow(const ScreenEdge& e, int width, int height) {
    const double xmin = std::min(e.a.x, e.b.x), xmax = std::max(e.a.x, e.b.x);
    const double ymin = std::min(e.a.y, e.b.y), ymax = std::max(e.a.y, e.b.y);
    if (std::isnan(xmin) || std::isnan(xmax) || std::isnan(ymin) || std::isnan(ymax)) return {};
    auto clampTo = [](double v, int hi) {
        return static_cast<int>(std::clamp(v, 0.0, static_cast<double>(hi)));
    };
    return {clampTo(std::floor(xmin) - 1.0, width), clampTo(std::floor(ymin) - 1.0, height),
            clampTo(std::floor(xmax) + 2.0, width), clampTo(std::floor(ymax) + 2.0, height)};
}

}  // namespace

std::optional<std::vector<PixelWindow>> InteractiveDisplay::changedWindows() const {
    if (!mWindowValid || !mFrameCameraSame) return std::nullopt;
    const int W = mOptions.width, H = mOptions.height;
    const EpiPointArrays points = const_cast<EdgePointImage&>(mEpi).pointArrays();
    const float tolerance = static_cast<float>(mOptions.windowColourTolerance);
    // Points: per row the first and last pixel whose point differs from what it showed.
    std::vector<std::pair<int, int>> rows(static_cast<std::size_t>(H), {W, -1});
    tbb::parallel_for(tbb::blocked_range<int>(0, H, 8), [&](const tbb::blocked_range<int>& r) {
        for (int y = r.begin(); y != r.end(); ++y) {
            int first = W, last = -1;
            for (int x = 0; x < W; ++x) {
                const std::size_t k = static_cast<std::size_t>(y) * W + x;
                const glm::vec3 c = points.colour[k], s = mShownColour[k];
                const glm::vec3 d = glm::abs(c - s), m = glm::max(glm::abs(c), glm::abs(s));
                const bool changed = points.depth[k] != mShownDepth[k] ||
                                     points.position[k] != mShownPosition[k] ||
                                     points.trust[k] != mShownTrust[k] || d.x > tolerance * m.x ||
                                     d.y > tolerance * m.y || d.z > tolerance * m.z;
                if (changed) first = std::min(first, x), last = x;
            }
            rows[static_cast<std::size_t>(y)] = {first, last};
        }
    });
    // Bands of rows, each with the rectangle of its changes.
    constexpr int kBand = 32;
    const int bands = (H + kBand - 1) / kBand;
    std::vector<PixelWindow> band(static_cast<std::size_t>(bands));
    for (int y = 0; y < H; ++y)
        if (rows[y].second >= 0)
            band[y / kBand] = band[y / kBand].unite({rows[y].first, y, rows[y].second + 1, y + 1});
    auto addToBands = [&](const PixelWindow& w) {
        for (int b = w.y0 / kBand; !w.empty() && b <= (w.y1 - 1) / kBand; ++b)
            band[b] = band[b].unite(
                {w.x0, std::max(w.y0, b * kBand), w.x1, std::min(w.y1, (b + 1) * kBand)});
    };
    // Edges: those in only one of the last reconstruction's list and this frame's (sorted by
    // key, walked together).
    std::vector<std::pair<std::uint64_t, std::size_t>> keys(mScreenEdges.size());
    for (std::size_t i = 0; i < mScreenEdges.size(); ++i) keys[i] = {edgeKey(mScreenEdges[i]), i};
    std::sort(keys.begin(), keys.end());
    std::size_t i = 0, j = 0;
    while (i < keys.size() || j < mShownEdges.size()) {
        if (j == mShownEdges.size() || (i < keys.size() && keys[i].first < mShownEdges[j].first)) {
            addToBands(edgeWindow(mScreenEdges[keys[i++].second], W, H));
        } else if (i == keys.size() || mShownEdges[j].first < keys[i].first) {
            addToBands(edgeWindow(mShownEdges[j++].second, W, H));
        } else {
            ++i, ++j;
        }
    }
    // The bands' rectangles merged downwards while one window costs no more than two: a
    // window reconstructs its input, the rectangle grown by twice the reach.
    const int reach2 = 2 * mEpi.reconstructionReach();
    auto cost = [&](const PixelWindow& w) {
        return static_cast<double>(w.grownWithin(reach2, W, H).area());
    };
    std::vector<PixelWindow> windows;
    for (const PixelWindow& w : band) {
        if (w.empty()) continue;
        if (!windows.empty() && cost(windows.back().unite(w)) <= cost(windows.back()) + cost(w)) {
            windows.back() = windows.back().unite(w);
        } else {
            windows.push_back(w);
        }
    }
    // Too large a share: the whole frame costs no more.
    double total = 0;
    for (const PixelWindow& w : windows) total += cost(w);
    if (total > mOptions.windowMaxShare * W * H) return std::nullopt;
    return windows;
}

void InteractiveDisplay::noteShown(const PixelWindow& window) {
    const int W = mOptions.width;
    const std::size_t n = static_cast<std::size_t>(W) * mOptions.height;
    if (mShownDepth.size() != n) {
        mShownDepth.assign(n, 0.0);
        mShownColour.assign(n, glm::vec3(0.0f));
        mShownPosition.assign(n, 0);
        mShownTrust.assign(n, 0);
    }
    const EpiPointArrays points = mEpi.pointArrays();
    const int w = window.x1 - window.x0;
    tbb::parallel_for(tbb::blocked_range<int>(window.y0, window.y1, 16),
                      [&](const tbb::blocked_range<int>& r) {
                          for (int y = r.begin(); y != r.end(); ++y) {
                              const std::size_t k = static_cast<std::size_t>(y) * W + window.x0;
                              std::copy_n(points.depth + k, w, mShownDepth.data() + k);
                              std::copy_n(points.colour + k, w, mShownColour.data() + k);
                              std::copy_n(points.position + k, w, mShownPosition.data() + k);
                              std::copy_n(points.trust + k, w, mShownTrust.data() + k);
                          }
                      });
}

void InteractiveDisplay::noteShownEdges() {
    // Every edge that changed lay inside a window: the frame's list is the one shown.
    mShownEdges.resize(mScreenEdges.size());
    for (std::size_t i = 0; i < mScreenEdges.size(); ++i)
        mShownEdges[i] = {edgeKey(mScreenEdges[i]), mScreenEdges[i]};
    std::sort(mShownEdges.begin(), mShownEdges.end(),
              [](const auto& a, const auto& b) { return a.first < b.first; });
}

}  // namespace penumbra
