#pragma once
// Closed forms that tests take as truths, written out independently of the code under test.

#include <cmath>

namespace penumbra::test {

/// Form factor from a point to the corner rectangle [0, x] × [0, y] of a parallel plane at
/// height h above it (the point under the corner), odd in x and in y, so any rectangle is a
/// signed sum of four (the textbook closed form, e.g. Howell's catalogue, configuration B-3).
inline double cornerFormFactor(double x, double y, double h) {
    const double X = x / h, Y = y / h;
    const double a = std::sqrt(1 + X * X), b = std::sqrt(1 + Y * Y);
    return (X / a * std::atan(Y / a) + Y / b * std::atan(X / b)) / (2 * M_PI);
}

/// Form factor from a point to the rectangle [x0, x1] × [y0, y1] (offsets from the point) of a
/// parallel plane at height h.
inline double rectangleFormFactor(double x0, double x1, double y0, double y1, double h) {
    if (x1 <= x0 || y1 <= y0) return 0.0;
    return cornerFormFactor(x1, y1, h) - cornerFormFactor(x0, y1, h) - cornerFormFactor(x1, y0, h) +
           cornerFormFactor(x0, y0, h);
}

}  // namespace penumbra::test
