// Tables of the edge-and-point image (Bala et al. 2003 §4.2–4.3, §5.2–5.3); see reachability.h
// for the conventions.
//
// Index: boundary geometry · edge codes · code tables · neighbour codes · neighbour table ·
// chaining table

#include "render/display/reachability.h"

#include <algorithm>
#include <cmath>
#include <sstream>

namespace penumbra {

// ---- Boundary geometry ------------------------------------------------------------------

glm::dvec2 boundaryPoint(int side, double t) {
    switch (side) {
        case 0:
            return {t, 0.0};
        case 1:
            return {1.0, t};
        case 2:
            return {1.0 - t, 1.0};
        default:
            return {0.0, 1.0 - t};
    }
}

glm::dvec2 positionCentre(int position, int piecesPerSide) {
    int side = position / piecesPerSide;
    int piece = position % piecesPerSide;
    return boundaryPoint(side, (piece + 0.5) / piecesPerSide);
}

namespace {

double cross2(const glm::dvec2& u, const glm::dvec2& v) { return u.x * v.y - u.y * v.x; }

/// Rounding tolerance of cross products of unit-square points (exact geometry touches).
constexpr double kSideTolerance = 1e-12;

/// The corner where side `side` ends (clockwise).
glm::dvec2 sideEndCorner(int side) { return boundaryPoint(side, 1.0); }

}  // namespace

// ---- Edge codes -------------------------------------------------------------------------

uint16_t makeEdgeCode(int positionA, int positionB, int piecesPerSide) {
    if (positionA / piecesPerSide == positionB / piecesPerSide) return kEdgeCodeComplex;
    int p0 = std::min(positionA, positionB);
    int p1 = std::max(positionA, positionB);
    return static_cast<uint16_t>((p0 << 5) | p1);
}

bool isSimpleEdgeCode(uint16_t code, int piecesPerSide) {
    int p0 = edgeCodeStart(code);
    int p1 = edgeCodeEnd(code);
    int n = 4 * piecesPerSide;
    return p0 < n && p1 < n && p0 < p1 && p0 / piecesPerSide != p1 / piecesPerSide;
}

std::string edgeCodeToString(uint16_t code, int piecesPerSide) {
    if (code == kEdgeCodeEmpty) return "empty";
    if (!isSimpleEdgeCode(code, piecesPerSide)) return "complex";
    std::ostringstream out;
    int p0 = edgeCodeStart(code);
    int p1 = edgeCodeEnd(code);
    out << p0 << "-" << p1 << " (side " << p0 / piecesPerSide << " piece " << p0 % piecesPerSide
        << " -> side " << p1 / piecesPerSide << " piece " << p1 % piecesPerSide << ")";
    return out.str();
}

// ---- Code tables ------------------------------------------------------------------------

EdgeCodeTables EdgeCodeTables::build(int piecesPerSide, int cellsPerSide) {
    EdgeCodeTables tables;
    tables.piecesPerSide = piecesPerSide;
    tables.cellsPerSide = cellsPerSide;
    tables.region0Area.fill(1.0f);
    const int cells = cellsPerSide * cellsPerSide;
    tables.sampleSide.assign(static_cast<size_t>(kEdgeCodeCount) * cells, SampleSide::Region0);
    tables.antiAliasNeighbours.assign(static_cast<size_t>(kEdgeCodeCount) * 2, {});
    const double n = piecesPerSide;

    for (int code = 0; code < kEdgeCodeCount; ++code) {
        if (!isSimpleEdgeCode(static_cast<uint16_t>(code), piecesPerSide)) continue;
        const int p0 = edgeCodeStart(static_cast<uint16_t>(code));
        const int p1 = edgeCodeEnd(static_cast<uint16_t>(code));
        const int s0 = p0 / piecesPerSide;
        const int s1 = p1 / piecesPerSide;
        const glm::dvec2 c0 = positionCentre(p0, piecesPerSide);
        const glm::dvec2 c1 = positionCentre(p1, piecesPerSide);

        // Region 0: the chord plus the clockwise arc p0 → corners → p1 (shoelace area).
        std::vector<glm::dvec2> polygon{c0};
        for (int s = s0; s < s1; ++s) polygon.push_back(sideEndCorner(s));
        polygon.push_back(c1);
        double twiceArea = 0.0;
        for (size_t k = 0; k < polygon.size(); ++k) {
            twiceArea += cross2(polygon[k], polygon[(k + 1) % polygon.size()]);
        }
        tables.region0Area[code] = static_cast<float>(std::abs(twiceArea) * 0.5);

        // The corner ending side s0 lies on the arc, strictly on region 0's side of any edge.
        const double region0Sign = cross2(c1 - c0, sideEndCorner(s0) - c0) > 0.0 ? 1.0 : -1.0;

        // §4.3 edge-ambiguous cells. cross(v − u, x − u) is multilinear in the endpoint
        // parameters along the two pieces and in the cell coordinates, so its sign over the
        // whole family is decided at the 2·2·4 extreme combinations.
        std::array<glm::dvec2, 2> ends0{boundaryPoint(s0, (p0 % piecesPerSide) / n),
                                        boundaryPoint(s0, (p0 % piecesPerSide + 1) / n)};
        std::array<glm::dvec2, 2> ends1{boundaryPoint(s1, (p1 % piecesPerSide) / n),
                                        boundaryPoint(s1, (p1 % piecesPerSide + 1) / n)};
        for (int cy = 0; cy < cellsPerSide; ++cy) {
            for (int cx = 0; cx < cellsPerSide; ++cx) {
                bool any0 = false;
                bool any1 = false;
                for (const auto& u : ends0) {
                    for (const auto& v : ends1) {
                        for (int corner = 0; corner < 4; ++corner) {
                            glm::dvec2 x{(cx + (corner & 1)) / double(cellsPerSide),
                                         (cy + (corner >> 1)) / double(cellsPerSide)};
                            double s = cross2(v - u, x - u) * region0Sign;
                            // Touching the cell boundary is not crossing it.
                            if (s > kSideTolerance) any0 = true;
                            if (s < -kSideTolerance) any1 = true;
                        }
                    }
                }
                SampleSide side = any0 && any1 ? SampleSide::Ambiguous
                                  : any1       ? SampleSide::Region1
                                               : SampleSide::Region0;
                tables.sampleSide[static_cast<size_t>(code) * cells + cx + cellsPerSide * cy] =
                    side;
            }
        }

        // §5.3 anti-aliasing neighbours: rank the 8 neighbours by the signed distance of
        // their centres on the secondary region's side of the approximated edge.
        const glm::dvec2 dir = c1 - c0;
        const double len = std::sqrt(glm::dot(dir, dir));
        for (int secondary = 0; secondary < 2; ++secondary) {
            struct Candidate {
                double distance;
                int manhattan;
                int dx, dy;
            };
            std::vector<Candidate> candidates;
            const double sign = secondary == 0 ? region0Sign : -region0Sign;
            for (int dy = -1; dy <= 1; ++dy) {
                for (int dx = -1; dx <= 1; ++dx) {
                    if (dx == 0 && dy == 0) continue;
                    glm::dvec2 centre{0.5 + dx, 0.5 + dy};
                    double d = cross2(dir, centre - c0) / len * sign;
                    if (d > 0.0) candidates.push_back({d, std::abs(dx) + std::abs(dy), dx, dy});
                }
            }
            std::sort(candidates.begin(), candidates.end(),
                      [](const Candidate& a, const Candidate& b) {
                          if (std::abs(a.distance - b.distance) > 1e-9) {
                              return a.distance > b.distance;
                          }
                          return a.manhattan < b.manhattan;
                      });
            auto& choice = tables.antiAliasNeighbours[static_cast<size_t>(code) * 2 + secondary];
            choice.count = static_cast<uint8_t>(std::min<size_t>(3, candidates.size()));
            for (int k = 0; k < choice.count; ++k) {
                choice.dx[k] = static_cast<int8_t>(candidates[k].dx);
                choice.dy[k] = static_cast<int8_t>(candidates[k].dy);
            }
        }
    }
    return tables;
}

const EdgeCodeTables& EdgeCodeTables::pixel() {
    static const EdgeCodeTables tables = build(kEpiPiecesPerSide, kEpiSampleCellsPerSide);
    return tables;
}

const EdgeCodeTables& EdgeCodeTables::subpixel() {
    static const EdgeCodeTables tables = build(kSubpixelPiecesPerSide, kSubpixelSampleCellsPerSide);
    return tables;
}

// ---- Neighbour codes --------------------------------------------------------------------

namespace {

constexpr std::array<std::array<int, 2>, 7> kTypeSides{
    {{-1, -1}, {0, 1}, {0, 2}, {0, 3}, {1, 2}, {1, 3}, {2, 3}}};

}  // namespace

std::array<int, 2> neighbourTypeSides(uint8_t type) {
    if (type < 1 || type > 6) return {-1, -1};
    return kTypeSides[type];
}

uint8_t neighbourType(uint16_t code, int piecesPerSide) {
    if (code == kEdgeCodeEmpty) return kNeighbourTypeEmpty;
    if (!isSimpleEdgeCode(code, piecesPerSide)) return kNeighbourTypeComplex;
    int s0 = edgeCodeStart(code) / piecesPerSide;
    int s1 = edgeCodeEnd(code) / piecesPerSide;
    for (uint8_t type = 1; type <= 6; ++type) {
        if (kTypeSides[type][0] == s0 && kTypeSides[type][1] == s1) return type;
    }
    return kNeighbourTypeComplex;
}

uint8_t makeNeighbourCode(uint16_t code, int piecesPerSide, bool primaryIsRegion1) {
    uint8_t type = neighbourType(code, piecesPerSide);
    if (type == kNeighbourTypeEmpty || type == kNeighbourTypeComplex) return type;
    return static_cast<uint8_t>(type | (primaryIsRegion1 ? kNeighbourPrimaryIsRegion1 : 0));
}

// ---- Neighbour table --------------------------------------------------------------------

namespace {

/// Region (0 or 1) of a pixel of simple type `type` that touches `side` at points whose
/// clockwise parameter is below (tBelowCrossing) or above the crossing on that side. A side
/// without a crossing lies wholly in one region; empty pixels are all region 0.
int regionAtSide(uint8_t type, int side, bool tBelowCrossing) {
    if (type == kNeighbourTypeEmpty) return 0;
    const int s0 = kTypeSides[type][0];
    const int s1 = kTypeSides[type][1];
    if (side == s0) return tBelowCrossing ? 1 : 0;  // the arc leaves p0 clockwise
    if (side == s1) return tBelowCrossing ? 0 : 1;  // and arrives at p1
    return side > s0 && side < s1 ? 0 : 1;
}

}  // namespace

uint8_t regionAdjacency(NeighbourDirection direction, uint8_t typeA, uint8_t typeB) {
    typeA &= 7;
    typeB &= 7;
    if (typeA == kNeighbourTypeComplex || typeB == kNeighbourTypeComplex) return 0;
    // Shared side of a and of b; sides 2 and 3 run against the shared coordinate (x for a
    // horizontal side, y for a vertical one).
    const int sideA = (static_cast<int>(direction) + 1) % 4;
    const int sideB = (sideA + 2) % 4;
    const bool reversedA = sideA >= 2;
    const bool reversedB = sideB >= 2;
    uint8_t mask = 0;
    // The shared side splits at the (common) crossing into the part before and after it.
    for (bool beforeCrossing : {true, false}) {
        int ra = regionAtSide(typeA, sideA, beforeCrossing != reversedA);
        int rb = regionAtSide(typeB, sideB, beforeCrossing != reversedB);
        mask |= static_cast<uint8_t>(1 << (ra * 2 + rb));
    }
    return mask;
}

const NeighbourReachabilityTable& neighbourReachabilityTable() {
    static const NeighbourReachabilityTable table = [] {
        NeighbourReachabilityTable t{};
        for (int d = 0; d < 4; ++d) {
            for (int a = 0; a < 16; ++a) {
                for (int b = 0; b < 16; ++b) {
                    const uint8_t typeA = a & 7;
                    const uint8_t typeB = b & 7;
                    const uint8_t regions =
                        regionAdjacency(static_cast<NeighbourDirection>(d), typeA, typeB);
                    const bool simpleA = typeA != kNeighbourTypeEmpty;
                    const bool simpleB = typeB != kNeighbourTypeEmpty;
                    // Primary/secondary region numbers; empty pixels have no secondary.
                    const int pa = simpleA && (a & kNeighbourPrimaryIsRegion1) ? 1 : 0;
                    const int pb = simpleB && (b & kNeighbourPrimaryIsRegion1) ? 1 : 0;
                    auto connected = [&](int ra, int rb) { return (regions >> (ra * 2 + rb)) & 1; };
                    uint8_t mask = 0;
                    if (connected(pa, pb)) mask |= kReachPP;
                    if (simpleB && connected(pa, 1 - pb)) mask |= kReachPS;
                    if (simpleA && connected(1 - pa, pb)) mask |= kReachSP;
                    if (simpleA && simpleB && connected(1 - pa, 1 - pb)) mask |= kReachSS;
                    t[d][(a << 4) | b] = mask;
                }
            }
        }
        return t;
    }();
    return table;
}

// ---- Chaining table ---------------------------------------------------------------------

const std::array<uint8_t, 256>& chainingTable() {
    static const std::array<uint8_t, 256> table = [] {
        std::array<uint8_t, 256> t{};
        for (int ab = 0; ab < 16; ++ab) {
            for (int bd = 0; bd < 16; ++bd) {
                auto bit = [](int m, uint8_t b) { return (m & b) != 0; };
                bool pp = (bit(ab, kReachPP) && bit(bd, kReachPP)) ||
                          (bit(ab, kReachPS) && bit(bd, kReachSP));
                bool ps = (bit(ab, kReachPP) && bit(bd, kReachPS)) ||
                          (bit(ab, kReachPS) && bit(bd, kReachSS));
                bool sp = (bit(ab, kReachSP) && bit(bd, kReachPP)) ||
                          (bit(ab, kReachSS) && bit(bd, kReachSP));
                bool ss = (bit(ab, kReachSP) && bit(bd, kReachPS)) ||
                          (bit(ab, kReachSS) && bit(bd, kReachSS));
                t[(ab << 4) | bd] = static_cast<uint8_t>((pp ? kReachPP : 0) | (ps ? kReachPS : 0) |
                                                         (sp ? kReachSP : 0) | (ss ? kReachSS : 0));
            }
        }
        return t;
    }();
    return table;
}

std::string reachabilityMaskToString(uint8_t mask) {
    std::ostringstream out;
    out << "(" << ((mask & kReachPP) ? 1 : 0) << "," << ((mask & kReachPS) ? 1 : 0) << ","
        << ((mask & kReachSP) ? 1 : 0) << "," << ((mask & kReachSS) ? 1 : 0) << ")";
    return out.str();
}

}  // namespace penumbra
