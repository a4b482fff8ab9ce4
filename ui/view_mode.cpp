#include "ui/view_mode.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <stdexcept>

namespace penumbra {

namespace {

struct ModeName {
    ViewMode mode;
    const char* name;
    const char* label;
};

constexpr std::array<ModeName, kViewModeCount> kModes{{
    {ViewMode::Gouraud, "gouraud", "Gouraud"},
    {ViewMode::EdgeAndPoint, "epi", "Edge-and-point"},
    {ViewMode::Cache, "cache", "Plain cache"},
    {ViewMode::EdgesOverlay, "edges", "Edges overlay"},
    {ViewMode::SamplesOverlay, "samples", "Samples overlay"},
    {ViewMode::Difference, "difference", "Difference vs reference"},
    {ViewMode::OutOfDate, "outofdate", "Out-of-date lighting"},
    {ViewMode::Interpolant, "interpolant", "High fidelity (interpolants)"},
}};

std::uint8_t toByte(double v) {
    return static_cast<std::uint8_t>(std::lround(std::clamp(v, 0.0, 1.0) * 255.0));
}

}  // namespace

const char* viewModeLabel(ViewMode mode) { return kModes[static_cast<int>(mode)].label; }

const char* toString(ViewMode mode) { return kModes[static_cast<int>(mode)].name; }

std::optional<ViewMode> parseViewMode(const std::string& name) {
    for (const ModeName& m : kModes)
        if (name == m.name) return m.mode;
    return std::nullopt;
}

bool usesInteractiveDisplay(ViewMode mode) {
    return mode != ViewMode::Gouraud && mode != ViewMode::OutOfDate &&
           mode != ViewMode::Interpolant;
}

std::vector<std::uint8_t> encodeDisplay(const Image& radiance) {
    // Every frame of the viewport passes here: rows in parallel.
    std::vector<std::uint8_t> rgba(radiance.pixels.size() * 4);
    tbb::parallel_for(tbb::blocked_range<std::size_t>(0, radiance.pixels.size(), 1 << 14),
                      [&](const tbb::blocked_range<std::size_t>& r) {
                          for (std::size_t i = r.begin(); i != r.end(); ++i) {
                              const Rgb& p = radiance.pixels[i];
                              for (int c = 0; c < 3; ++c) rgba[4 * i + c] = srgbByte(p[c]);
                              rgba[4 * i + 3] = 255;
                          }
                      });
    return rgba;
}

void blendEdges(std::vector<std::uint8_t>& rgba, const Image& classes, double alpha) {
    if (rgba.size() != classes.pixels.size() * 4)
        throw std::invalid_argument("blendEdges: image sizes differ");
    for (std::size_t i = 0; i < classes.pixels.size(); ++i) {
        const Rgb& k = classes.pixels[i];
        if (std::max({k.x, k.y, k.z}) <= 0.3) continue;
        for (int c = 0; c < 3; ++c) {
            const double v = rgba[4 * i + c] / 255.0;
            rgba[4 * i + c] = toByte(v + alpha * (srgbEncodeClipped(k[c]) - v));
        }
    }
}

void markSamples(std::vector<std::uint8_t>& rgba, const std::vector<std::uint8_t>& flags,
                 std::uint8_t r, std::uint8_t g, std::uint8_t b) {
    if (rgba.size() != flags.size() * 4)
        throw std::invalid_argument("markSamples: image sizes differ");
    for (std::size_t i = 0; i < flags.size(); ++i)
        if (flags[i]) rgba[4 * i] = r, rgba[4 * i + 1] = g, rgba[4 * i + 2] = b;
}

void falseColour(double t, std::uint8_t* rgba) {
    // Piecewise linear through dark blue, blue, green, yellow, red.
    static constexpr double kStops[5][3] = {
        {0.0, 0.0, 0.15}, {0.0, 0.2, 1.0}, {0.0, 0.9, 0.2}, {1.0, 0.95, 0.0}, {1.0, 0.0, 0.0}};
    const double s = std::clamp(std::isfinite(t) ? t : 1.0, 0.0, 1.0) * 4.0;
    const int k = std::min(3, static_cast<int>(s));
    const double f = s - k;
    for (int c = 0; c < 3; ++c)
        rgba[c] = toByte(kStops[k][c] + f * (kStops[k + 1][c] - kStops[k][c]));
    rgba[3] = 255;
}

std::vector<std::uint8_t> differenceImage(const Image& a, const Image& reference, double fullScale,
                                          double* meanDifference) {
    const int rw = reference.width, rh = reference.height;
    if (rw <= 0 || rh <= 0 || a.width % rw != 0 || a.height % rh != 0 ||
        a.width / rw != a.height / rh)
        throw std::invalid_argument("differenceImage: " + std::to_string(a.width) + "x" +
                                    std::to_string(a.height) + " is not a multiple of " +
                                    std::to_string(rw) + "x" + std::to_string(rh));
    const int f = a.width / rw;
    std::vector<std::uint8_t> rgba(a.pixels.size() * 4);
    double sum = 0;
    for (int y = 0; y < rh; ++y)
        for (int x = 0; x < rw; ++x) {
            Rgb mean(0.0);
            for (int j = 0; j < f; ++j)
                for (int i = 0; i < f; ++i) mean += a.at(x * f + i, y * f + j);
            mean /= double(f * f);
            const Rgb& r = reference.at(x, y);
            double d = 0;
            for (int c = 0; c < 3; ++c)
                d += std::abs(srgbEncodeClipped(mean[c]) - srgbEncodeClipped(r[c]));
            d /= 3.0;
            sum += d;
            std::uint8_t colour[4];
            falseColour(fullScale > 0 ? d / fullScale : 1.0, colour);
            for (int j = 0; j < f; ++j)
                for (int i = 0; i < f; ++i) {
                    const std::size_t p = static_cast<std::size_t>(y * f + j) * a.width + x * f + i;
                    std::copy(colour, colour + 4, &rgba[4 * p]);
                }
        }
    if (meanDifference) *meanDifference = sum / (double(rw) * rh);
    return rgba;
}

void tintPending(std::vector<std::uint8_t>& rgba, const Image& pending, double scale) {
    if (rgba.size() != pending.pixels.size() * 4)
        throw std::invalid_argument("tintPending: image sizes differ");
    static constexpr double kRed[3] = {1.0, 0.05, 0.05};
    for (std::size_t i = 0; i < pending.pixels.size(); ++i) {
        const double l = luminance(pending.pixels[i]);
        const double w = scale > 0 ? 0.75 * std::clamp(l / scale, 0.0, 1.0) : 0.0;
        if (w <= 0) continue;
        for (int c = 0; c < 3; ++c) {
            const double v = rgba[4 * i + c] / 255.0;
            rgba[4 * i + c] = toByte(v + w * (kRed[c] - v));
        }
    }
}

}  // namespace penumbra
