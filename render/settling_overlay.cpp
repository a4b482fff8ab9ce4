#include "render/settling_overlay.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "core/colour.h"

namespace penumbra {

std::vector<Rgb> settlingChangeValues(const SettlingEstimate& estimate) {
    std::vector<Rgb> values(estimate.change.size());
    for (std::size_t e = 0; e < values.size(); ++e) values[e] = Rgb(estimate.change[e]);
    return values;
}

double settlingFloorRadiosity(const Discretization& disc, const std::vector<Rgb>& radiosity) {
    double sum = 0;
    std::size_t n = 0;
    for (std::size_t e = 0; e < disc.elements().size() && e < radiosity.size(); ++e)
        if (disc.elementAlive(static_cast<int>(e))) sum += luminance(radiosity[e]), ++n;
    return n > 0 ? 0.01 * sum / static_cast<double>(n) : 0.0;
}

SettlingHeat settlingHeat(double relativeChange) {
    SettlingHeat h;
    if (!(relativeChange >= kSettledRelative)) return h;
    const double t = std::clamp(
        std::log(relativeChange / kSettledRelative) / std::log(kHotRelative / kSettledRelative),
        0.0, 1.0);
    // Yellow (255, 220, 0) to red (255, 0, 0); more opaque as it gets hotter.
    h.r = 255;
    h.g = static_cast<std::uint8_t>(std::lround(220 * (1 - t)));
    h.b = 0;
    h.alpha = 0.25 + 0.5 * t;
    return h;
}

double relativeChangeAt(const Image& change, const Image& radiance, std::size_t pixel,
                        double floorLuminance) {
    const double y = std::max(luminance(radiance.pixels[pixel]), floorLuminance);
    return y > 0 ? luminance(change.pixels[pixel]) / y : 0.0;
}

namespace {

void checkSizes(const Image& a, const Image& b) {
    if (a.width != b.width || a.height != b.height)
        throw std::invalid_argument("blendSettling: picture " + a.toString() + " and change " +
                                    b.toString() + " differ in size");
}

}  // namespace

Image blendSettling(const Image& picture, const Image& change, double floorLuminance) {
    checkSizes(picture, change);
    Image out = picture;
    for (std::size_t p = 0; p < out.pixels.size(); ++p) {
        const SettlingHeat h = settlingHeat(relativeChangeAt(change, picture, p, floorLuminance));
        if (h.alpha <= 0) continue;
        const double heat[3] = {h.r / 255.0, h.g / 255.0, h.b / 255.0};
        for (int c = 0; c < 3; ++c) {
            const double shown = srgbEncodeClipped(picture.pixels[p][c]);
            out.pixels[p][c] = srgbDecode(shown + h.alpha * (heat[c] - shown));
        }
    }
    return out;
}

void blendSettling(std::vector<std::uint8_t>& rgba, const Image& radiance, const Image& change,
                   double floorLuminance) {
    checkSizes(radiance, change);
    if (rgba.size() != radiance.pixels.size() * 4)
        throw std::invalid_argument("blendSettling: " + std::to_string(rgba.size() / 4) +
                                    " pixels for " + radiance.toString());
    for (std::size_t p = 0; p < radiance.pixels.size(); ++p) {
        const SettlingHeat h = settlingHeat(relativeChangeAt(change, radiance, p, floorLuminance));
        if (h.alpha <= 0) continue;
        const std::uint8_t heat[3] = {h.r, h.g, h.b};
        for (int c = 0; c < 3; ++c) {
            const double v = rgba[4 * p + c] + h.alpha * (heat[c] - rgba[4 * p + c]);
            rgba[4 * p + c] = static_cast<std::uint8_t>(std::lround(std::clamp(v, 0.0, 255.0)));
        }
    }
}

}  // namespace penumbra
