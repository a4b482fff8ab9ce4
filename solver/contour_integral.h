#pragma once
// The kernel of the analytic form factors: Lambert's contour sum over a polygon's edges.
// Built with -fno-math-errno -fno-trapping-math (CMakeLists.txt), so GCC computes the edges
// two at a time, and integrateContour has an AVX2 clone chosen at load time (GCC target_clones)
// that computes four at a time: a quad outline in one step. integrateContourLanes, four points
// at once, has an AVX clone (for CPUs with AVX but not AVX2). None contracts to FMA, so every
// version gives the same bits.

#include <cstddef>

#include "solver/scene.h"

namespace penumbra {

/// atan2(y, x) for y ≥ 0, an angle in [0, π], within 2e-10 rad of std::atan2 and cheaper:
/// the contour integral's edge angles.
double angleAtan2(double y, double x);

/// Lambert's contour sum Σ_k β_k (n · γ̂_k) over the closed polygon v[0..count) seen from x
/// (β_k the angle edge k subtends, γ̂_k the unit normal of the plane through x and the
/// edge): 2π times the form factor from (x, n) to the polygon, signed by its winding. An
/// edge through x adds nothing.
double integrateContour(const Vec3& x, const Vec3& n, const Vec3* v, std::size_t count);

/// integrateContour of one polygon from kContourLanes points at once (xs[l], ns[l]), each
/// lane's sum bit for bit the one integrateContour gives: the same operations per edge in the
/// same order, with the lanes' independent chains side by side instead of one point's long
/// chain at a time.
constexpr int kContourLanes = 4;
void integrateContourLanes(const Vec3* xs, const Vec3* ns, const Vec3* v, std::size_t count,
                           double* sums);

}  // namespace penumbra
