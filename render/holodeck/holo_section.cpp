#include "render/holodeck/holo_section.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>

namespace penumbra {

HoloSection::HoloSection(const Vec3& origin, const Vec3& size, const std::array<int, 3>& grid,
                         SectionKind kind)
    : mOrigin(origin), mSize(size), mGrid(grid), mKind(kind) {
    for (int a = 0; a < 3; ++a) {
        if (!std::isfinite(origin[a]) || !std::isfinite(size[a]) || !(size[a] > 0))
            throw std::invalid_argument("holodeck section: size must be positive and finite");
        if (grid[a] < 1 || grid[a] > 1024)
            throw std::invalid_argument("holodeck section: grid counts must be in [1, 1024]");
        mCellSize[a] = size[a] / grid[a];
    }
    for (int w = 0; w < 6; ++w) {
        mWallCells[w] = mGrid[axisU(w)] * mGrid[axisV(w)];
        mWallStart[w + 1] = mWallStart[w] + mWallCells[w];
    }
    mCellCount = mWallStart[6];
    for (int w = 0; w < 6; ++w)
        mBeamStart[w + 1] = mBeamStart[w] + std::int64_t(mWallCells[w]) *
                                                (mCellCount - std::int64_t(mWallCells[w]));
    mBeamCount = mBeamStart[6];
}

int HoloSection::wallOf(int cell) const {
    int w = 0;
    while (w < 5 && cell >= mWallStart[w + 1]) ++w;
    return w;
}

std::int64_t HoloSection::beamIndex(int entry, int exit) const {
    const int we = wallOf(entry), wx = wallOf(exit);
    if (we == wx) return -1;
    // The exit's rank among the cells not on the entry's wall.
    const std::int64_t rank = exit < mWallStart[we] ? exit : exit - mWallCells[we];
    return mBeamStart[we] + std::int64_t(entry - mWallStart[we]) * (mCellCount - mWallCells[we]) +
           rank;
}

std::pair<int, int> HoloSection::beamCells(std::int64_t beam) const {
    int we = 0;
    while (we < 5 && beam >= mBeamStart[we + 1]) ++we;
    const std::int64_t per = mCellCount - mWallCells[we];
    const std::int64_t offset = beam - mBeamStart[we];
    const int entry = mWallStart[we] + static_cast<int>(offset / per);
    const int rank = static_cast<int>(offset % per);
    const int exit = rank < mWallStart[we] ? rank : rank + mWallCells[we];
    return {entry, exit};
}

Vec3 HoloSection::wallPoint(const WallPoint& p) const {
    const int w = wallOf(p.cell);
    const int a = w / 2, au = axisU(w), av = axisV(w);
    const int local = p.cell - mWallStart[w];
    const int iu = local / mGrid[av], iv = local % mGrid[av];
    Vec3 x;
    x[a] = mOrigin[a] + (w % 2) * mSize[a];
    x[au] = mOrigin[au] + (iu + p.u) * mCellSize[au];
    x[av] = mOrigin[av] + (iv + p.v) * mCellSize[av];
    return x;
}

WallPoint HoloSection::locateOnWall(int w, const Vec3& x) const {
    const int au = axisU(w), av = axisV(w);
    // The cell along one in-plane axis and the position within it, clamped into the wall.
    auto along = [&](int axis, int& index) {
        const double f = (x[axis] - mOrigin[axis]) / mCellSize[axis];
        const double clamped = std::clamp(f, 0.0, std::nextafter(double(mGrid[axis]), 0.0));
        index = std::min(static_cast<int>(clamped), mGrid[axis] - 1);
        return std::min(clamped - index, std::nextafter(1.0, 0.0));
    };
    int iu = 0, iv = 0;
    WallPoint p;
    p.u = along(au, iu);
    p.v = along(av, iv);
    p.cell = mWallStart[w] + iu * mGrid[av] + iv;
    return p;
}

std::optional<BeamRay> HoloSection::locate(const Vec3& origin, const Vec3& direction) const {
    // The line's parameter interval inside the box (slabs), and the axes that bound it.
    double tNear = -std::numeric_limits<double>::infinity();
    double tFar = std::numeric_limits<double>::infinity();
    int axisNear = -1, axisFar = -1;
    for (int a = 0; a < 3; ++a) {
        const double lo = mOrigin[a], hi = mOrigin[a] + mSize[a];
        if (direction[a] == 0.0) {
            if (origin[a] <= lo || origin[a] >= hi) return std::nullopt;
            continue;
        }
        double t0 = (lo - origin[a]) / direction[a], t1 = (hi - origin[a]) / direction[a];
        if (t0 > t1) std::swap(t0, t1);
        if (t0 > tNear) tNear = t0, axisNear = a;
        if (t1 < tFar) tFar = t1, axisFar = a;
    }
    if (axisNear < 0 || axisFar < 0 || !(tNear < tFar)) return std::nullopt;
    // A line entering where it moves up an axis enters through that axis's low wall.
    const int wallIn = 2 * axisNear + (direction[axisNear] > 0 ? 0 : 1);
    const int wallOut = 2 * axisFar + (direction[axisFar] > 0 ? 1 : 0);
    if (wallIn == wallOut) return std::nullopt;
    BeamRay ray;
    ray.entry = locateOnWall(wallIn, origin + tNear * direction);
    ray.exit = locateOnWall(wallOut, origin + tFar * direction);
    ray.beam = beamIndex(ray.entry.cell, ray.exit.cell);
    return ray;
}

double HoloSection::beamVolume(std::int64_t beam) const {
    const auto [entry, exit] = beamCells(beam);
    const Vec3 a = wallPoint({entry, 0.5, 0.5}), b = wallPoint({exit, 0.5, 0.5});
    const double length = glm::length(b - a);
    if (!(length > 0)) return 0;
    const Vec3 t = (b - a) / length;
    // A cell's area projected across the line: its area times the cosine to its wall's normal.
    auto projected = [&](int cell) {
        const int w = wallOf(cell);
        return mCellSize[axisU(w)] * mCellSize[axisV(w)] * std::abs(t[w / 2]);
    };
    const double pa = projected(entry), pb = projected(exit);
    return length * (pa + pb + std::sqrt(pa * pb)) / 3.0;
}

std::string HoloSection::toString() const {
    std::ostringstream out;
    out << (mKind == SectionKind::Interior ? "interior" : "exterior") << " section at ("
        << mOrigin.x << ", " << mOrigin.y << ", " << mOrigin.z << ") size (" << mSize.x << ", "
        << mSize.y << ", " << mSize.z << ") grid " << mGrid[0] << "x" << mGrid[1] << "x" << mGrid[2]
        << ", " << mBeamCount << " beams";
    return out.str();
}

std::int64_t paperBeamCount(std::int64_t w, std::int64_t d, std::int64_t h) {
    return 2 * w * w * d * d + 2 * w * w * h * h + 2 * d * d * h * h + 8 * w * w * d * h +
           8 * w * d * d * h + 8 * w * d * h * h;
}

std::array<int, 3> nearCubicGrid(const Vec3& size, std::int64_t targetBeams) {
    const double diagonal = glm::length(size);
    // The cell edge whose grid (4–24 a side) gives the beam count nearest the target on a
    // logarithmic scale.
    std::array<int, 3> best{4, 4, 4};
    double bestMiss = std::numeric_limits<double>::infinity();
    for (int i = 0; i <= 400; ++i) {
        const double edge = diagonal * std::pow(10.0, -3.0 + 3.0 * i / 400.0);
        std::array<int, 3> grid;
        for (int a = 0; a < 3; ++a)
            grid[a] = std::clamp(static_cast<int>(std::lround(size[a] / edge)), 4, 24);
        const double beams = double(paperBeamCount(grid[0], grid[1], grid[2]));
        const double miss = std::abs(std::log(beams / double(targetBeams)));
        if (miss < bestMiss) bestMiss = miss, best = grid;
    }
    return best;
}

HoloSection layoutSection(const Vec3& lo, const Vec3& hi, double margin, std::int64_t targetBeams) {
    const Vec3 extent = hi - lo;
    const double diagonal = glm::length(extent);
    if (!std::isfinite(diagonal) || !(diagonal > 0))
        throw std::invalid_argument("holodeck layout: the bounds are empty or not finite");
    // Shrunk by the margin; a flat extent (a scene that is one plane) gets a thin slab.
    const double m = margin * diagonal;
    Vec3 origin, size;
    for (int a = 0; a < 3; ++a) {
        size[a] = std::max(extent[a] - 2 * m, 1e-3 * diagonal);
        origin[a] = lo[a] + 0.5 * (extent[a] - size[a]);
    }
    return HoloSection(origin, size, nearCubicGrid(size, targetBeams), SectionKind::Interior);
}

}  // namespace penumbra
