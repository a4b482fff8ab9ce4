#include "render/holodeck/holo_sample.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace penumbra {

std::array<std::uint8_t, 4> encodeRgbe(const Rgb& c) {
    auto clean = [](double x) { return std::isfinite(x) && x > 0 ? x : 0.0; };
    const double r = clean(c.x), g = clean(c.y), b = clean(c.z);
    const double largest = std::max({r, g, b});
    if (largest < 1e-38) return {0, 0, 0, 0};
    // largest = m · 2^e with m in [0.5, 1): mantissas are the components in units of 2^(e−8).
    int e = 0;
    const double m = std::frexp(largest, &e);
    if (e > 127) return {255, 255, 255, 255};  // beyond RGBE's range: the largest it holds
    const double scale = m * 256.0 / largest;
    auto mantissa = [&](double x) {
        return static_cast<std::uint8_t>(std::min(255.0, std::floor(x * scale)));
    };
    return {mantissa(r), mantissa(g), mantissa(b), static_cast<std::uint8_t>(e + 128)};
}

Rgb decodeRgbe(const std::array<std::uint8_t, 4>& e) {
    if (e[3] == 0) return Rgb(0.0);
    // The centre of each mantissa's step.
    const double f = std::ldexp(1.0, int(e[3]) - (128 + 8));
    return {(e[0] + 0.5) * f, (e[1] + 0.5) * f, (e[2] + 0.5) * f};
}

DistanceCode::DistanceCode(double diagonal)
    : mDiagonal(diagonal),
      mStep(diagonal / kLinearCodes),
      mLogFactor(std::log1p(1.0 / kLinearCodes)) {
    if (!std::isfinite(diagonal) || !(diagonal > 0))
        throw std::invalid_argument("holodeck distance code: the diagonal must be positive");
}

std::uint16_t DistanceCode::encode(double distance) const {
    if (!(distance > 0)) return 0;  // also NaN
    if (distance < mDiagonal - 0.5 * mStep)
        return static_cast<std::uint16_t>(std::lround(distance / mStep));
    const double steps = std::log(distance / mDiagonal) / mLogFactor;
    return static_cast<std::uint16_t>(
        std::clamp(kLinearCodes + std::lround(steps), long(kLinearCodes), 65535L));
}

double DistanceCode::decode(std::uint16_t code) const {
    if (code < kLinearCodes) return code * mStep;
    return mDiagonal * std::exp((code - kLinearCodes) * mLogFactor);
}

std::uint8_t encodeCellPosition(double u) {
    return static_cast<std::uint8_t>(std::clamp(std::floor(u * 256.0), 0.0, 255.0));
}

HoloSample encodeSample(const Rgb& radiance, const WallPoint& entry, const WallPoint& exit,
                        double distance, const DistanceCode& code) {
    HoloSample s;
    s.rgbe = encodeRgbe(radiance);
    s.entry[0] = encodeCellPosition(entry.u);
    s.entry[1] = encodeCellPosition(entry.v);
    s.exit[0] = encodeCellPosition(exit.u);
    s.exit[1] = encodeCellPosition(exit.v);
    s.distance = code.encode(distance);
    return s;
}

DecodedSample decodeSample(const HoloSample& sample, const HoloSection& section, std::int64_t beam,
                           const DistanceCode& code) {
    const auto [entryCell, exitCell] = section.beamCells(beam);
    DecodedSample d;
    d.entry = section.wallPoint(
        {entryCell, decodeCellPosition(sample.entry[0]), decodeCellPosition(sample.entry[1])});
    const Vec3 exit = section.wallPoint(
        {exitCell, decodeCellPosition(sample.exit[0]), decodeCellPosition(sample.exit[1])});
    d.direction = glm::normalize(exit - d.entry);
    d.hit = d.entry + code.decode(sample.distance) * d.direction;
    d.radiance = decodeRgbe(sample.rgbe);
    return d;
}

}  // namespace penumbra
