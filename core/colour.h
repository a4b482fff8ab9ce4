#pragma once
// The sRGB transfer function (IEC 61966-2-1) between linear values and display values.

#include <cstdint>

namespace penumbra {

/// sRGB encoding of a linear value. Defined for any finite input; values above 1 encode above
/// 1 (the caller clips), negative values map to 12.92·x.
double srgbEncode(double linear);
/// Inverse of srgbEncode.
double srgbDecode(double encoded);
/// srgbEncode clipped to [0, 1]: the displayed value of a linear value (NaN → 0, +∞ → 1).
double srgbEncodeClipped(double linear);
/// The 8-bit display value of a linear value, computed exactly: round(255 ·
/// srgbEncodeClipped(linear)). What image files store and the editor's viewport shows.
std::uint8_t srgbByteExact(double linear);
/// The 8-bit display value of a linear value: sRGB-encoded, clipped to [0, 1] (NaN → 0) and
/// rounded, by table lookup (for whole frames: no pow per channel). Equals
/// round(255 · srgbEncode(v)) except within a rounding error of a byte boundary.
std::uint8_t srgbByte(double linear);

}  // namespace penumbra
