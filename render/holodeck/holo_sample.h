#pragma once
// A holodeck ray sample in ten bytes (Ward & Simmons 1999, Table I): the radiance in Ward's
// RGBE shared-exponent format (4 bytes), the entry and exit positions within their cells (one
// byte per degree of freedom, 2 + 2 bytes) and the distance from the entry point to the
// surface hit (2 bytes: linear up to the section's diagonal, logarithmic beyond).
//
// Index: RGBE · DistanceCode · HoloSample

#include <array>
#include <cstdint>

#include "core/math.h"
#include "render/holodeck/holo_section.h"

namespace penumbra {

/// Ward's RGBE ("Real Pixels"): three 8-bit mantissas sharing an 8-bit exponent of the largest
/// component. Negative and non-finite components encode as 0. A component's error is at most
/// half a mantissa step of the largest one: 2⁻⁸ of the largest component, relative.
std::array<std::uint8_t, 4> encodeRgbe(const Rgb& c);
Rgb decodeRgbe(const std::array<std::uint8_t, 4>& e);

/// The 16-bit distance of §2.1 for a section of diagonal `diagonal`: codes 0 to 2¹¹−1 step
/// linearly by diagonal / 2¹¹ up to the diagonal; codes from 2¹¹ grow by the factor
/// (1 + 2⁻¹¹) each, the linear step at the border, up to about 3·10¹³ diagonals. Error: half a
/// linear step below the diagonal, a relative 2⁻¹² above it.
class DistanceCode {
public:
    explicit DistanceCode(double diagonal);
    std::uint16_t encode(double distance) const;
    double decode(std::uint16_t code) const;

    static constexpr int kLinearCodes = 1 << 11;

private:
    double mDiagonal, mStep, mLogFactor;
};

/// One ray sample as stored (10 bytes, no padding): what the paper's file and server hold.
struct HoloSample {
    std::array<std::uint8_t, 4> rgbe{};
    std::uint8_t entry[2]{};  ///< position in the entry cell, (u, v) in 256ths
    std::uint8_t exit[2]{};   ///< position in the exit cell
    std::uint16_t distance = 0;
};
static_assert(sizeof(HoloSample) == 10, "a holodeck sample is ten bytes");

/// The byte of a position in [0, 1) within a cell, and the cell position it stands for (the
/// centre of its 256th).
std::uint8_t encodeCellPosition(double u);
inline double decodeCellPosition(std::uint8_t b) { return (b + 0.5) / 256.0; }

/// A sample decoded in world space: the ray from its entry point towards its exit point, the
/// radiance seen along it and the surface point it hit.
struct DecodedSample {
    Vec3 entry, direction, hit;
    Rgb radiance{0.0};
};

/// Encodes the ray of `beam` through `entry` and `exit` (positions within the beam's cells)
/// that saw `radiance` at `distance` from its entry point.
HoloSample encodeSample(const Rgb& radiance, const WallPoint& entry, const WallPoint& exit,
                        double distance, const DistanceCode& code);
/// The world-space sample of `sample` stored in beam `beam` of `section`.
DecodedSample decodeSample(const HoloSample& sample, const HoloSection& section, std::int64_t beam,
                           const DistanceCode& code);

}  // namespace penumbra
