#pragma once
// A holodeck section (Ward & Simmons 1999, §2.1): a gridded box through which rays are sorted
// into beams. A ray crossing the box enters through a cell of one wall and leaves through a
// cell of another; the rays through the same ordered pair of cells form one beam, whose
// samples are stored and read together.
//
// Walls are numbered 2·axis + side (side 0 at the box's minimum along that axis, 1 at its
// maximum); a wall's cells are indexed along its first and second in-plane axes, (axis+1)%3
// and (axis+2)%3. Cells of all six walls take one global index, wall by wall; a beam's index
// enumerates ordered pairs of cells on different walls, entry cell major, so the beam count
// is the paper's N = 2W²D² + 2W²H² + 2D²H² + 8W²DH + 8WD²H + 8WDH².
//
// Index: HoloSection · nearCubicGrid · layoutSection

#include <array>
#include <cstdint>
#include <optional>
#include <string>

#include "core/math.h"

namespace penumbra {

/// Where view rays start and what they see (§2.1): an interior section is a region of free
/// movement looked out of; an exterior one encloses objects viewed from outside.
enum class SectionKind : std::uint8_t { Interior = 0, Exterior = 1 };

/// A position on a wall: the wall's global cell index and the position within the cell along
/// the wall's two in-plane axes, each in [0, 1).
struct WallPoint {
    int cell = 0;
    double u = 0, v = 0;
};

/// A ray's place in a section: its beam and where it enters and leaves.
struct BeamRay {
    std::int64_t beam = 0;
    WallPoint entry, exit;
};

class HoloSection {
public:
    /// The box [origin, origin + size] gridded into `grid` cells along x, y and z. Throws
    /// std::invalid_argument when a size is not positive and finite or a grid count is not
    /// in [1, 1024].
    HoloSection(const Vec3& origin, const Vec3& size, const std::array<int, 3>& grid,
                SectionKind kind = SectionKind::Interior);

    const Vec3& origin() const { return mOrigin; }
    const Vec3& size() const { return mSize; }
    const std::array<int, 3>& grid() const { return mGrid; }
    SectionKind kind() const { return mKind; }
    double diagonal() const { return glm::length(mSize); }

    /// Cells on wall `w` (0..5) and over all walls.
    int wallCells(int w) const { return mWallCells[w]; }
    int cellCount() const { return mCellCount; }
    /// The wall a global cell index lies on.
    int wallOf(int cell) const;
    /// Beams: ordered pairs of cells on different walls.
    std::int64_t beamCount() const { return mBeamCount; }
    /// The beam of rays entering through cell `entry` and leaving through cell `exit`; -1 when
    /// both lie on one wall (no straight ray does that).
    std::int64_t beamIndex(int entry, int exit) const;
    /// The entry and exit cells of `beam` (the inverse of beamIndex).
    std::pair<int, int> beamCells(std::int64_t beam) const;

    /// The world point at `p` on its wall.
    Vec3 wallPoint(const WallPoint& p) const;
    /// The cell and in-cell position of the world point `x` on wall `w` (x is projected on
    /// the wall's plane and clamped into the wall).
    WallPoint locateOnWall(int w, const Vec3& x) const;
    /// The beam of the line through `origin` along `direction` (any length) and where that
    /// line crosses the walls; empty when it misses the box or only grazes it. The line, not
    /// the ray: a point behind `origin` may be its entry.
    std::optional<BeamRay> locate(const Vec3& origin, const Vec3& direction) const;
    /// The volume of the region the beam's rays sweep (§2.2: batch filling gives beams
    /// samples in proportion to it), as the frustum between its two cells: with L the distance
    /// between the cells' centres and a, b their areas projected across that line,
    /// L (a + b + √(ab)) / 3.
    double beamVolume(std::int64_t beam) const;

    std::string toString() const;

private:
    /// The wall's in-plane axes and the cell sizes along them.
    int axisU(int w) const { return (w / 2 + 1) % 3; }
    int axisV(int w) const { return (w / 2 + 2) % 3; }

    Vec3 mOrigin, mSize, mCellSize;
    std::array<int, 3> mGrid;
    SectionKind mKind;
    std::array<int, 6> mWallCells{};           ///< cells per wall
    std::array<int, 7> mWallStart{};           ///< first global cell index of each wall
    std::array<std::int64_t, 7> mBeamStart{};  ///< first beam whose entry lies on each wall
    int mCellCount = 0;
    std::int64_t mBeamCount = 0;
};

/// The paper's beam count for a W × D × H grid (§2.1), for checking a layout.
std::int64_t paperBeamCount(std::int64_t w, std::int64_t d, std::int64_t h);

/// Near-cubic cells for a box of `size`: the grid, 4 to 24 cells a side (§2.1: grids of 4–24 a
/// side and 50,000–500,000 beams work best), whose beam count comes nearest `targetBeams`.
std::array<int, 3> nearCubicGrid(const Vec3& size, std::int64_t targetBeams = 200000);

/// An interior section over `lo`–`hi` (a scene's bounds, shrunk by `margin` of its diagonal so
/// that entry points do not lie on the scene's walls), gridded with near-cubic cells so that its
/// beam count comes as close to `targetBeams` as the paper's limits allow: 4 to 24 cells a side
/// (§2.1: grids of 4–24 a side and 50,000–500,000 beams work best).
HoloSection layoutSection(const Vec3& lo, const Vec3& hi, double margin = 0.01,
                          std::int64_t targetBeams = 200000);

}  // namespace penumbra
