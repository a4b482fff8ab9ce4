#include "render/light_change.h"

#include <algorithm>
#include <cmath>

namespace penumbra {

std::vector<double> elementLuminance(const std::vector<Rgb>& radiosity) {
    std::vector<double> y(radiosity.size());
    for (std::size_t e = 0; e < radiosity.size(); ++e) y[e] = luminance(radiosity[e]);
    return y;
}

std::vector<std::uint8_t> changedElements(const std::vector<double>& before,
                                          const std::vector<double>& after, double threshold) {
    double mean = 0;
    for (double y : after) mean += y;
    mean = after.empty() ? 0 : mean / double(after.size());
    std::vector<std::uint8_t> changed(after.size(), 1);
    for (std::size_t e = 0; e < std::min(after.size(), before.size()); ++e)
        changed[e] =
            std::abs(after[e] - before[e]) > threshold * std::max(before[e], 1e-3 * mean);
    return changed;
}

}  // namespace penumbra
