#include "core/colour.h"

#include <algorithm>
#include <cmath>

namespace penumbra {

double srgbEncode(double linear) {
    if (linear <= 0.0031308) return 12.92 * linear;
    return 1.055 * std::pow(linear, 1.0 / 2.4) - 0.055;
}

double srgbDecode(double encoded) {
    if (encoded <= 0.04045) return encoded / 12.92;
    return std::pow((encoded + 0.055) / 1.055, 2.4);
}

double srgbEncodeClipped(double linear) {
    const double v = srgbEncode(linear);
    if (!(v > 0.0)) return 0.0;
    return std::min(v, 1.0);
}

std::uint8_t srgbByteExact(double linear) {
    return static_cast<std::uint8_t>(std::lround(srgbEncodeClipped(linear) * 255.0));
}

std::uint8_t srgbByte(double linear) {
    // threshold[k]: the smallest linear value shown as byte k (the decoded midpoint between
    // k − 1 and k); start[i]: the byte at the start of bin i of kBins equal bins over [0, 1].
    constexpr int kBins = 4096;
    struct Tables {
        double threshold[257];
        std::uint8_t start[kBins];
    };
    static const Tables t = [] {
        Tables t{};
        t.threshold[0] = -1.0;
        for (int k = 1; k <= 255; ++k) t.threshold[k] = srgbDecode((k - 0.5) / 255.0);
        t.threshold[256] = 2.0;
        int k = 0;
        for (int i = 0; i < kBins; ++i) {
            while (k < 255 && double(i) / kBins >= t.threshold[k + 1]) ++k;
            t.start[i] = static_cast<std::uint8_t>(k);
        }
        return t;
    }();
    if (!(linear > 0.0)) return 0;  // also NaN
    if (linear >= 1.0) return 255;
    int k = t.start[static_cast<int>(linear * kBins)];
    while (linear >= t.threshold[k + 1]) ++k;
    return static_cast<std::uint8_t>(k);
}

}  // namespace penumbra
