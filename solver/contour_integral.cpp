#include "solver/contour_integral.h"

#include <algorithm>
#include <cmath>

namespace penumbra {

namespace {

// atan(a) = a·P(a²) on a = min/max ∈ [0, 1], P of degree 10 fitted by us (least squares
// reweighted toward minimax absolute error: max 1.4e-10 on [0, 1]), then the octant. The
// contour integral takes four of these per polygon; libm's atan2 was a tenth of a cube-room
// solve. Selects instead of branches, so the edge loop below vectorizes.
inline double atan2Lane(double y, double x) {
    const double ax = std::abs(x);
    const double hi = std::max(ax, y), lo = std::min(ax, y);
    const double a = lo / (hi > 0 ? hi : 1.0), s = a * a;
    // Estrin's scheme: a short dependency chain.
    const double s2 = s * s, s4 = s2 * s2, s8 = s4 * s4;
    const double p01 = 0.99999999667237049 + s * -0.3333330208903717;
    const double p23 = 0.19999129786621939 + s * -0.14274432022169178;
    const double p45 = 0.11028650565781659 + s * -0.087138588795384275;
    const double p67 = 0.065413758853929485 + s * -0.042088081586575191;
    const double p89 = 0.020467823501212654 + s * -0.0063947658920403376;
    const double p10 = 0.00093755837204316853;
    const double p = (p01 + s2 * p23) + s4 * (p45 + s2 * p67) + s8 * (p89 + s2 * p10);
    double r = a * p;
    r = y > ax ? M_PI_2 - r : r;
    r = x < 0 ? M_PI - r : r;
    return hi > 0 ? r : 0.0;
}

}  // namespace

// GCC's load-time clones (ifunc resolvers) run before a ThreadSanitizer runtime is set up,
// and an instrumented resolver crashes the program at load: TSan builds take the default
// code only.
#if defined(PENUMBRA_NO_TARGET_CLONES)
#define PENUMBRA_CLONES(...)
#else
#define PENUMBRA_CLONES(...) __attribute__((target_clones(__VA_ARGS__)))
#endif

double angleAtan2(double y, double x) { return atan2Lane(y, x); }

PENUMBRA_CLONES("avx2", "default")
double integrateContour(const Vec3& x, const Vec3& n, const Vec3* v, std::size_t count) {
    // The vertices' offsets from x in coordinate arrays, the first repeated at the end: each
    // edge's term is an independent lane.
    constexpr std::size_t kMax = 16;
    double sum = 0;
    for (std::size_t base = 0; base < count; base += kMax) {
        const std::size_t m = std::min(kMax, count - base);
        alignas(16) double rx[kMax + 1], ry[kMax + 1], rz[kMax + 1], term[kMax];
        for (std::size_t i = 0; i <= m; ++i) {
            const Vec3& p = v[base + i < count ? base + i : 0];
            rx[i] = p.x - x.x;
            ry[i] = p.y - x.y;
            rz[i] = p.z - x.z;
        }
        const double nx = n.x, ny = n.y, nz = n.z;
        for (std::size_t i = 0; i < m; ++i) {
            const double cx = ry[i] * rz[i + 1] - rz[i] * ry[i + 1];
            const double cy = rz[i] * rx[i + 1] - rx[i] * rz[i + 1];
            const double cz = rx[i] * ry[i + 1] - ry[i] * rx[i + 1];
            const double cl = std::sqrt(cx * cx + cy * cy + cz * cz);
            const double d = rx[i] * rx[i + 1] + ry[i] * ry[i + 1] + rz[i] * rz[i + 1];
            const double nc = nx * cx + ny * cy + nz * cz;
            // An edge through x (a zero cross product) adds nothing; a NaN is kept.
            const double t = atan2Lane(cl, d) * nc / (cl <= 0 ? 1.0 : cl);
            term[i] = cl <= 0 ? 0.0 : t;
        }
        for (std::size_t i = 0; i < m; ++i) sum += term[i];
    }
    return sum;
}

PENUMBRA_CLONES("avx", "default")
void integrateContourLanes(const Vec3* xs, const Vec3* ns, const Vec3* v, std::size_t count,
                           double* sums) {
    constexpr int L = kContourLanes;
    double px[L], py[L], pz[L], nx[L], ny[L], nz[L], sum[L];
    for (int l = 0; l < L; ++l) {
        px[l] = xs[l].x, py[l] = xs[l].y, pz[l] = xs[l].z;
        nx[l] = ns[l].x, ny[l] = ns[l].y, nz[l] = ns[l].z;
        sum[l] = 0;
    }
    for (std::size_t i = 0; i < count; ++i) {
        const Vec3& a = v[i];
        const Vec3& b = v[i + 1 < count ? i + 1 : 0];
        for (int l = 0; l < L; ++l) {
            const double ax = a.x - px[l], ay = a.y - py[l], az = a.z - pz[l];
            const double bx = b.x - px[l], by = b.y - py[l], bz = b.z - pz[l];
            const double cx = ay * bz - az * by;
            const double cy = az * bx - ax * bz;
            const double cz = ax * by - ay * bx;
            const double cl = std::sqrt(cx * cx + cy * cy + cz * cz);
            const double d = ax * bx + ay * by + az * bz;
            const double nc = nx[l] * cx + ny[l] * cy + nz[l] * cz;
            const double t = atan2Lane(cl, d) * nc / (cl <= 0 ? 1.0 : cl);
            sum[l] += cl <= 0 ? 0.0 : t;
        }
    }
    for (int l = 0; l < L; ++l) sums[l] = sum[l];
}

}  // namespace penumbra
