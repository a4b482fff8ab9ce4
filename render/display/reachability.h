#pragma once
// The table-driven core of the edge-and-point image (Bala, Walter, Greenberg 2003): the
// boundary-position and 10-bit edge encodings (§4.2), the 4-bit sample position and
// edge-ambiguous samples (§4.3), region areas for anti-aliasing (§5.3), the 4-bit neighbour
// code, the 256-entry neighbour reachability table and the chaining table (§5.2).
//
// Index: boundary positions · edge codes · code tables (areas, sample sides, anti-aliasing
// neighbours) · neighbour codes · reachability masks (neighbour table, chaining)
//
// Conventions. A pixel (or a half-pixel subpixel, §5.4) is the unit square in local
// coordinates (x right, y down). Its boundary is cut into 4·n pieces (n = 8 for pixels: 1/8
// pixel; n = 4 for subpixels, again 1/8 pixel) numbered clockwise on screen from the top-left
// corner: side 0 top (left → right), side 1 right (top → bottom), side 2 bottom (right →
// left), side 3 left (bottom → top). A simple pixel's approximated edge joins the centres of
// two pieces p0 < p1 on different sides; it splits the pixel into region 0, bounded by the
// chord and the clockwise boundary arc from p0 to p1, and region 1, the rest.

#include <array>
#include <cstdint>
#include <glm/glm.hpp>
#include <string>
#include <vector>

namespace penumbra {

// ---- Boundary positions -----------------------------------------------------------------

constexpr int kEpiPiecesPerSide = 8;            ///< §4.2: 1/8-pixel boundary precision
constexpr int kEpiSampleCellsPerSide = 4;       ///< §4.3: 4×4 sample regions, 4 bits
constexpr int kSubpixelPiecesPerSide = 4;       ///< §5.4: half-pixel sides in 1/8 pixels
constexpr int kSubpixelSampleCellsPerSide = 2;  ///< §5.4: a pixel's 4×4 cells per subpixel

/// Position index (0 .. 4·piecesPerSide−1) of piece `piece` (0 .. piecesPerSide−1, counted
/// clockwise along the side) on `side` (0 top, 1 right, 2 bottom, 3 left).
inline int boundaryPosition(int side, int piece, int piecesPerSide) {
    return side * piecesPerSide + piece;
}
/// Point in local [0,1]² at clockwise parameter t ∈ [0,1] along `side`.
glm::dvec2 boundaryPoint(int side, double t);
/// Centre of boundary piece `position` in local [0,1]².
glm::dvec2 positionCentre(int position, int piecesPerSide);

// ---- Edge codes -------------------------------------------------------------------------

/// 10-bit edge code (§4.2): (p0 << 5) | p1 with p0 < p1 on different sides. Both endpoints on
/// one side is disallowed; two of those combinations encode empty and complex pixels.
constexpr uint16_t kEdgeCodeEmpty = 0;    ///< (0, 0)
constexpr uint16_t kEdgeCodeComplex = 1;  ///< (0, 1): same side
constexpr int kEdgeCodeCount = 1024;

/// Code of the edge between two boundary positions; kEdgeCodeComplex when they lie on the
/// same side.
uint16_t makeEdgeCode(int positionA, int positionB, int piecesPerSide);
inline int edgeCodeStart(uint16_t code) { return code >> 5; }
inline int edgeCodeEnd(uint16_t code) { return code & 31; }
/// True for codes of a simple pixel (two positions on different sides).
bool isSimpleEdgeCode(uint16_t code, int piecesPerSide);
/// "empty", "complex" or "p0-p1 (side s0 piece k0 → side s1 piece k1)".
std::string edgeCodeToString(uint16_t code, int piecesPerSide);

// ---- Code tables ------------------------------------------------------------------------

/// Which region of a simple pixel a sample cell lies in, or edge-ambiguous (§4.3): the cell
/// may lie on either side of some edge whose endpoints lie anywhere in the two pieces.
enum class SampleSide : uint8_t { Region0 = 0, Region1 = 1, Ambiguous = 2 };

/// Precomputed per-code tables for one boundary resolution (pixels or subpixels).
struct EdgeCodeTables {
    int piecesPerSide = kEpiPiecesPerSide;
    int cellsPerSide = kEpiSampleCellsPerSide;
    /// Fraction of the pixel in region 0 of each simple code (edge through piece centres);
    /// 1 for empty and complex codes.
    std::array<float, kEdgeCodeCount> region0Area{};
    /// [code · cells² + cell], cell = cx + cellsPerSide·cy; Region0 for non-simple codes.
    std::vector<SampleSide> sampleSide;
    /// Anti-aliasing (§5.3): for each simple code and each region r as the *secondary* one,
    /// up to 3 of the 8 neighbours (dx, dy ∈ {−1,0,1}) most likely to show region r's colour,
    /// best first: ordered by how far the neighbour's centre lies on region r's side of the
    /// edge. [code · 2 + r]; count 0 for non-simple codes.
    struct NeighbourChoice {
        uint8_t count = 0;
        std::array<int8_t, 3> dx{}, dy{};
    };
    std::vector<NeighbourChoice> antiAliasNeighbours;

    SampleSide side(uint16_t code, int cell) const {
        return sampleSide[static_cast<size_t>(code) * cellsPerSide * cellsPerSide + cell];
    }
    /// Tables for pixels (8 pieces per side, 4×4 cells).
    static const EdgeCodeTables& pixel();
    /// Tables for half-pixel subpixels (4 pieces per side, 2×2 cells).
    static const EdgeCodeTables& subpixel();
    /// Builds the tables; prefer pixel()/subpixel(), which are built once.
    static EdgeCodeTables build(int piecesPerSide, int cellsPerSide);
};

// ---- Neighbour codes --------------------------------------------------------------------

/// 4-bit neighbour code (§5.2): bits 0–2 the pixel type — 0 empty, 1..6 simple with the edge
/// on sides (0,1) (0,2) (0,3) (1,2) (1,3) (2,3), 7 complex — and bit 3 set when region 1 is
/// the primary region. Empty and complex pixels have only a primary region (region 0).
constexpr uint8_t kNeighbourTypeEmpty = 0;
constexpr uint8_t kNeighbourTypeComplex = 7;
constexpr uint8_t kNeighbourPrimaryIsRegion1 = 8;
/// The 3-bit type of an edge code.
uint8_t neighbourType(uint16_t code, int piecesPerSide);
/// The 4-bit neighbour code; the primary flag is ignored for empty and complex codes.
uint8_t makeNeighbourCode(uint16_t code, int piecesPerSide, bool primaryIsRegion1);
/// The two sides of a simple type (1..6), s0 < s1.
std::array<int, 2> neighbourTypeSides(uint8_t type);

// ---- Reachability masks -----------------------------------------------------------------

/// 4-bit reachability mask a ↔ b (§5.2): (Pa↔Pb, Pa↔Sb, Sa↔Pb, Sa↔Sb) as bits 0..3.
constexpr uint8_t kReachPP = 1;
constexpr uint8_t kReachPS = 2;
constexpr uint8_t kReachSP = 4;
constexpr uint8_t kReachSS = 8;

/// Where pixel b lies relative to pixel a.
enum class NeighbourDirection : uint8_t { Right = 0, Down = 1, Left = 2, Up = 3 };

/// Connectivity of the regions of two adjacent pixels of types typeA and typeB (0..7)
/// across their shared side, in region terms: bits (A0↔B0, A0↔B1, A1↔B0, A1↔B1). The two
/// pixels record the same crossing on the shared side; when only one of them has a
/// crossing there, its two regions both touch the other's undivided side.
uint8_t regionAdjacency(NeighbourDirection direction, uint8_t typeA, uint8_t typeB);

/// The neighbour reachability tables (§5.2), one 256-entry table per direction, indexed by
/// (neighbour code of a) << 4 | (neighbour code of b), giving the 4-bit mask a ↔ b.
/// Complex pixels reach nothing; empty pixels have no secondary region.
using NeighbourReachabilityTable = std::array<std::array<uint8_t, 256>, 4>;
const NeighbourReachabilityTable& neighbourReachabilityTable();
inline uint8_t neighbourReachability(NeighbourDirection direction, uint8_t codeA, uint8_t codeB) {
    return neighbourReachabilityTable()[static_cast<int>(direction)][(codeA << 4) | codeB];
}

/// The chaining table (§5.2): [ab << 4 | bd] → the mask a ↔ d through b, over paths through
/// both b's primary and secondary regions.
const std::array<uint8_t, 256>& chainingTable();
inline uint8_t chainReachability(uint8_t ab, uint8_t bd) { return chainingTable()[(ab << 4) | bd]; }

/// "(PP,PS,SP,SS)" as in the paper's Figure 6 example, e.g. "(0,1,0,0)".
std::string reachabilityMaskToString(uint8_t mask);

}  // namespace penumbra
