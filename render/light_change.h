#pragma once
// Which elements' light an edit changed, by the relative change of their radiosity's
// luminance: the test the holodeck (HoloServer::invalidate) and the high-fidelity mesh
// (hifiRemeshElements) share.

#include <cstdint>
#include <vector>

#include "core/math.h"

namespace penumbra {

/// Per element, the luminance of its radiosity (W/m²): what changedElements compares.
std::vector<double> elementLuminance(const std::vector<Rgb>& radiosity);

/// The elements whose light an edit changed: 1 where the luminance moved by more than
/// `threshold` of what it was (`before`; values below a thousandth of `after`'s mean count as
/// that), and for every element past `before`'s end (new elements); sized as `after`.
std::vector<std::uint8_t> changedElements(const std::vector<double>& before,
                                          const std::vector<double>& after, double threshold);

}  // namespace penumbra
