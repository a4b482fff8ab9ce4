// EdgePointImage::reconstructWindow: build and reconstruct redone on a window of the raster,
// for frames in which only a few pixels' points and edges changed.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <sstream>
#include <stdexcept>

#include "render/display/edge_point_image.h"
#include "render/display/edge_point_image_internal.h"

namespace penumbra {

using epi_detail::forRows;

std::string PixelWindow::toString() const {
    std::ostringstream s;
    s << "PixelWindow{[" << x0 << ", " << x1 << ") x [" << y0 << ", " << y1 << ")}";
    return s.str();
}

int EdgePointImage::reconstructionReach() const {
    // A point or an edge crossing decides its pixel's class and codes; §5.2 chains
    // reachability over 5×5 (2 pixels), §5.3 interpolates over what a pixel reaches (2 more);
    // anti-aliasing and the complex filter mix 3×3 neighbours' results (1 more); the
    // smoothing's boxes reach smoothRadius and its edge distance smoothRadius + 1, the near-edge
    // ring filters primaries once more over 5×5 (2 more), the dense mean denseRadius plus its
    // 3×3 count. A point also sets its 4×4 block's culling depth, which decides the crossings
    // anywhere in the block (3 more, and the window keeps block alignment).
    const int smooth = mOptions.smoothRadius > 0 ? mOptions.smoothRadius + 1 + 2 : 0;
    const int dense = mOptions.denseComplexLimit > 0 ? mOptions.denseRadius + 1 : 0;
    return 3 + std::max({2 + 2 + 1, smooth, dense});
}

void EdgePointImage::reconstructWindow(const std::vector<ScreenEdge>& edges,
                                       const PixelWindow& changed, bool useEdges, Image& image) {
    if (image.width != mWidth || image.height != mHeight)
        throw std::invalid_argument("EdgePointImage::reconstructWindow: image " +
                                    std::to_string(image.width) + "x" +
                                    std::to_string(image.height) + " is not the raster's");
    const PixelWindow within =
        PixelWindow{std::max(0, changed.x0), std::max(0, changed.y0), std::min(mWidth, changed.x1),
                    std::min(mHeight, changed.y1)};
    if (within.empty()) return;
    const int reach = reconstructionReach();
    // The pixels whose output can change, and the input they read: reach farther again, the
    // input's origin and end on the 4×4 block grid so its blocks are the raster's.
    const PixelWindow out = within.grownWithin(reach, mWidth, mHeight);
    PixelWindow in = out.grownWithin(reach, mWidth, mHeight);
    in.x0 &= ~3, in.y0 &= ~3;
    in.x1 = std::min(mWidth, (in.x1 + 3) & ~3), in.y1 = std::min(mHeight, (in.y1 + 3) & ~3);
    const int w = in.x1 - in.x0, h = in.y1 - in.y0;
    if (!mWindow || mWindow->mWidth != w || mWindow->mHeight != h)
        mWindow = std::make_unique<EdgePointImage>(w, h, mOptions);
    EdgePointImage& sub = *mWindow;

    // Its points: the raster's arrays, row by row.
    forRows(mOptions.parallel, h, [&](int y) {
        const size_t from = index(in.x0, in.y0 + y), to = sub.index(0, y);
        std::copy_n(&mSampleDepth[from], w, &sub.mSampleDepth[to]);
        std::copy_n(&mSampleColour[from], w, &sub.mSampleColour[to]);
        std::copy_n(&mSamplePos[from], w, &sub.mSamplePos[to]);
        std::copy_n(&mSampleTrust[from], w, &sub.mSampleTrust[to]);
    });
    // Its edges: those whose extent meets it (a pixel of slack), moved to its origin.
    mWindowEdges.clear();
    const glm::dvec2 origin(in.x0, in.y0);
    for (const ScreenEdge& e : edges) {
        const double xmin = std::min(e.a.x, e.b.x), xmax = std::max(e.a.x, e.b.x);
        const double ymin = std::min(e.a.y, e.b.y), ymax = std::max(e.a.y, e.b.y);
        // (A NaN extent fails every comparison: the edge is skipped, as rasterizeEdge would.)
        if (!(xmax >= in.x0 - 1.0 && xmin <= in.x1 + 1.0 && ymax >= in.y0 - 1.0 &&
              ymin <= in.y1 + 1.0))
            continue;
        ScreenEdge moved = e;
        moved.a -= origin;
        moved.b -= origin;
        mWindowEdges.push_back(moved);
    }
    sub.build(mWindowEdges);
    const Image part = sub.reconstruct(useEdges);
    mTimes = sub.mTimes;

    // The output window back into the raster's image and per-pixel state.
    std::vector<long long> holeChange(static_cast<size_t>(out.y1 - out.y0), 0);
    forRows(mOptions.parallel, out.y1 - out.y0, [&](int row) {
        const int y = out.y0 + row, sy = y - in.y0;
        std::array<int, 3> before{0, 0, 0}, after{0, 0, 0};
        long long holes = 0;
        for (int x = out.x0; x < out.x1; ++x) {
            const size_t i = index(x, y), s = sub.index(x - in.x0, sy);
            auto classOf = [](uint16_t code) {
                return code == kEdgeCodeEmpty ? 0 : code == kEdgeCodeComplex ? 2 : 1;
            };
            ++before[classOf(mEdgeCode[i])];
            ++after[classOf(sub.mEdgeCode[s])];
            holes += static_cast<long long>(sub.mHole[s]) - mHole[i];
            mEdgeCode[i] = sub.mEdgeCode[s];
            mWeight[i] = sub.mWeight[s];
            mHole[i] = sub.mHole[s];
            image.at(x, y) = part.at(x - in.x0, sy);
        }
        for (int c = 0; c < 3; ++c) mRowCounts[y][c] += after[c] - before[c];
        holeChange[row] = holes;
    });
    mPixelCounts = {0, 0, 0};
    for (const auto& row : mRowCounts)
        for (int c = 0; c < 3; ++c) mPixelCounts[c] += row[c];
    long long holes = static_cast<long long>(mHoleCount);
    for (long long d : holeChange) holes += d;
    mHoleCount = static_cast<size_t>(holes);
}

}  // namespace penumbra
