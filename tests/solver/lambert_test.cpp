// Lambert: the point-to-polygon form factor (polygonFormFactor, Lambert's contour integral) and
// the irradiance the solver gathers from an unoccluded emitter (irradianceAt), checked against
// truths computed here without the code under test:
//  - a brute-force area integral of cosθ_x cosθ_y / (π r²) over the polygon (midpoint rule on a
//    fine triangle grid, refined where cells are large next to the point), with max(0, ·) for
//    the receiver's horizon and for the polygon's back;
//  - the closed form for a differential area parallel to a rectangle (Howell's catalogue B-3,
//    superposed over the four corner rectangles);
//  - the coaxial-disk closed form F = R²/(R² + h²) bracketing a regular polygon between its
//    inscribed and circumscribed disks.
//
// Index: brute-force reference · closed forms · test points · polygonFormFactor tests ·
//        irradianceAt tests

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "solver/discretization.h"
#include "solver/form_factor.h"
#include "solver/progressive_solver.h"
#include "solver/ray_tracer.h"
#include "test_scenes.h"

namespace penumbra {
namespace {

std::string str(const Vec3& v) {
    std::ostringstream s;
    s.precision(9);
    s << "(" << v.x << ", " << v.y << ", " << v.z << ")";
    return s.str();
}

// ---------------------------------------------------------------------------------------------
// Brute-force reference

/// Midpoint-rule integral of the differential-area kernel over one triangle, refined by
/// quartering until every cell's longest edge is at most kCellRatio times its distance to x.
struct KernelIntegrator {
    static constexpr double kCellRatio = 0.04;
    static constexpr int kMaxDepth = 14;
    Vec3 x, n, ny;  // receiver point and normal, polygon front normal (unit)
    double sum = 0;

    double kernel(const Vec3& y) const {
        Vec3 d = y - x;
        double r2 = glm::dot(d, d);
        double cx = std::max(0.0, glm::dot(n, d));    // receiver horizon
        double cy = std::max(0.0, -glm::dot(ny, d));  // polygon seen from its front only
        return cx * cy / (M_PI * r2 * r2);
    }
    void cell(const Vec3& a, const Vec3& b, const Vec3& c, int depth) {
        Vec3 g = (a + b + c) / 3.0;
        double r = glm::length(g - x);
        double edge = std::max({glm::length(b - a), glm::length(c - b), glm::length(a - c)});
        if (edge > kCellRatio * r && depth < kMaxDepth) {
            Vec3 ab = 0.5 * (a + b), bc = 0.5 * (b + c), ca = 0.5 * (c + a);
            cell(a, ab, ca, depth + 1);
            cell(ab, b, bc, depth + 1);
            cell(ca, bc, c, depth + 1);
            cell(ab, bc, ca, depth + 1);
            return;
        }
        sum += 0.5 * glm::length(glm::cross(b - a, c - a)) * kernel(g);
    }
};

/// F from the differential area (x, n) to a convex planar polygon (counter-clockwise seen from
/// its front), by brute-force integration: every fan triangle is split into a regular
/// 64 × 64 lattice of sub-triangles, refined further near x.
double bruteForceFormFactor(const Vec3& x, const Vec3& n, const std::vector<Vec3>& poly) {
    Vec3 normal(0.0);
    for (std::size_t i = 0; i < poly.size(); ++i)
        normal += glm::cross(poly[i], poly[(i + 1) % poly.size()]);
    KernelIntegrator integ{x, glm::normalize(n), glm::normalize(normal)};
    constexpr int kGrid = 64;
    for (std::size_t t = 1; t + 1 < poly.size(); ++t) {
        const Vec3 p0 = poly[0], e1 = (poly[t] - p0) / double(kGrid),
                   e2 = (poly[t + 1] - p0) / double(kGrid);
        auto at = [&](int i, int j) { return p0 + double(i) * e1 + double(j) * e2; };
        for (int j = 0; j < kGrid; ++j)
            for (int i = 0; i + j < kGrid; ++i) {
                integ.cell(at(i, j), at(i + 1, j), at(i, j + 1), 0);
                if (i + j + 1 < kGrid) integ.cell(at(i + 1, j), at(i + 1, j + 1), at(i, j + 1), 0);
            }
    }
    return integ.sum;
}

// ---------------------------------------------------------------------------------------------
// Closed forms

/// Howell B-3: differential area parallel to an a × b rectangle at distance c, its normal
/// through one corner. Odd in a and in b, so corner terms superpose for any foot point.
double cornerRectangle(double a, double b, double c) {
    double A = a / c, B = b / c;
    double sa = std::sqrt(1 + A * A), sb = std::sqrt(1 + B * B);
    return (A / sa * std::atan(B / sa) + B / sb * std::atan(A / sb)) / (2 * M_PI);
}

/// Parallel rectangle [x0, x1] × [y0, y1] at height c above the foot point (px, py).
double parallelRectangle(double x0, double x1, double y0, double y1, double px, double py,
                         double c) {
    return cornerRectangle(x1 - px, y1 - py, c) - cornerRectangle(x0 - px, y1 - py, c) -
           cornerRectangle(x1 - px, y0 - py, c) + cornerRectangle(x0 - px, y0 - py, c);
}

/// Coaxial parallel disk of radius R at distance h.
double coaxialDisk(double R, double h) { return R * R / (R * R + h * h); }

// ---------------------------------------------------------------------------------------------
// Test points, in the frame of the polygon: origin at its reference point, XY its plane, +Z
// its front normal.

struct Frame {
    Vec3 origin, ex, ey, ez;
    Vec3 point(Vec3 p) const { return origin + p.x * ex + p.y * ey + p.z * ez; }
    Vec3 direction(Vec3 d) const { return glm::normalize(d.x * ex + d.y * ey + d.z * ez); }
};

/// A rigid frame in general orientation, so no test relies on axis-aligned geometry.
Frame tiltedFrame() {
    Transform t;
    t.rotateDeg = Vec3(30, 40, 10);
    t.translate = Vec3(0.3, -0.2, 0.5);
    return {t.translate, test::worldDirection(t, {1, 0, 0}), test::worldDirection(t, {0, 1, 0}),
            test::worldDirection(t, {0, 0, 1})};
}

struct Probe {
    const char* what;
    Vec3 p;  // frame coordinates, relative to the polygon's centre
    Vec3 n;  // frame coordinates, need not be unit
};

Vec3 tiltFromMinusZ(double deg, Vec3 toward) {
    double a = deg * M_PI / 180;
    return std::cos(a) * Vec3(0, 0, -1) + std::sin(a) * glm::normalize(toward);
}

/// Points for a polygon of size about 1 centred at the frame origin.
std::vector<Probe> probes() {
    const Vec3 down(0, 0, -1);
    return {
        {"far on axis", {0, 0, 20}, down},
        {"on axis, distance 1", {0, 0, 1}, down},
        {"on axis, distance 0.25", {0, 0, 0.25}, down},
        {"near 0.01 inside", {0.1, 0.05, 0.01}, down},
        {"near 0.02 by a corner", {0.3, 0.2, 0.02}, down},
        {"near 0.05 inside", {-0.2, 0.1, 0.05}, down},
        {"near 0.03 outside an edge", {0.2, -0.6, 0.03}, down},
        {"near 0.01, oblique normal", {0, 0, 0.01}, {0.3, 0.4, -1}},
        {"near 0.04 outside, tilted", {-0.6, -0.55, 0.04}, {1, 1, -1}},
        {"off axis facing the centre", {2, 1, 1}, {-2, -1, -1}},
        {"off axis, normal -Z", {2, 1, 1}, down},
        {"far off axis", {5, -3, 4}, {-5, 3, -4}},
        {"tilted 45 degrees", {0.2, 0.1, 0.5}, {1, 0, -1}},
        {"grazing 80 degrees", {0, 0, 0.5}, tiltFromMinusZ(80, {1, 0, 0})},
        {"grazing 88 degrees", {0.1, 0, 0.3}, tiltFromMinusZ(88, {1, 0, 0})},
        {"grazing 85 degrees, near 0.02", {0, 0.1, 0.02}, tiltFromMinusZ(85, {0, 1, 0})},
        {"grazing 89.5 degrees", {0, 0, 0.5}, tiltFromMinusZ(89.5, {0, -1, 0})},
        {"receiver perpendicular, outside", {0.9, 0, 0.2}, {-1, 0, 0}},
        {"receiver perpendicular, above: half below horizon", {0, 0, 0.4}, {0, 1, 0}},
        {"behind the polygon", {0, 0, -1}, {0, 0, 1}},
        {"just behind, near", {0.1, 0.1, -0.05}, {0, 0, 1}},
        {"in front, facing away", {0, 0, 1}, {0, 0, 1}},
        {"in the polygon's plane", {2, 0, 0}, {-1, 0, 0}},
    };
}

/// 1% relative, or 1e-6 absolute near 0.
double tolerance(double reference) { return std::max(0.01 * std::abs(reference), 1e-6); }

void checkPolygonAgainstBruteForce(const std::vector<Vec3>& localPolygon, Vec3 localCentre,
                                   const char* shape) {
    const Frame frame = tiltedFrame();
    std::vector<Vec3> polygon;
    for (const Vec3& v : localPolygon) polygon.push_back(frame.point(v));
    int nonZero = 0;
    for (const Probe& probe : probes()) {
        const Vec3 x = frame.point(localCentre + probe.p);
        const Vec3 n = frame.direction(probe.n);
        const double reference = bruteForceFormFactor(x, n, polygon);
        const double f = polygonFormFactor(x, n, polygon);
        nonZero += reference > 1e-6;
        EXPECT_NEAR(f, reference, tolerance(reference))
            << shape << ", " << probe.what << ": polygonFormFactor = " << f
            << ", brute-force integral = " << reference << " at x = " << str(x)
            << ", n = " << str(n);
    }
    EXPECT_GE(nonZero, 18) << shape << ": too few probes see the polygon";
}

// ---------------------------------------------------------------------------------------------
// polygonFormFactor

TEST(Lambert, SquareMatchesBruteForceIntegral) {
    checkPolygonAgainstBruteForce({{-0.5, -0.5, 0}, {0.5, -0.5, 0}, {0.5, 0.5, 0}, {-0.5, 0.5, 0}},
                                  Vec3(0.0), "unit square");
}

TEST(Lambert, TriangleMatchesBruteForceIntegral) {
    checkPolygonAgainstBruteForce({{0, 0, 0}, {1, 0, 0}, {0.3, 0.9, 0}}, Vec3(0.43, 0.3, 0),
                                  "triangle");
}

TEST(Lambert, BruteForceReferenceMatchesRectangleClosedForm) {
    // The reference itself against Howell B-3, so the polygon tests rest on a checked integral.
    const Frame frame = tiltedFrame();
    const std::vector<Vec3> rect = {frame.point({-0.5, -0.3, 0}), frame.point({0.5, -0.3, 0}),
                                    frame.point({0.5, 0.3, 0}), frame.point({-0.5, 0.3, 0})};
    for (Vec3 p : {Vec3(0, 0, 1), Vec3(0.2, 0.1, 0.01), Vec3(0.7, -0.5, 0.05), Vec3(3, 2, 0.5)}) {
        const double exact = parallelRectangle(-0.5, 0.5, -0.3, 0.3, p.x, p.y, p.z);
        const double brute = bruteForceFormFactor(frame.point(p), -frame.ez, rect);
        EXPECT_NEAR(brute, exact, 2e-3 * exact)
            << "brute force = " << brute << ", Howell B-3 = " << exact << " at " << str(p);
    }
}

TEST(Lambert, ParallelRectangleClosedForm) {
    // Howell B-3 superposed over four corner rectangles: on the axis, above a corner, above an
    // interior point, beside the rectangle, near and far.
    const Frame frame = tiltedFrame();
    const double x0 = -0.5, x1 = 0.5, y0 = -0.25, y1 = 0.75;
    const std::vector<Vec3> rect = {frame.point({x0, y0, 0}), frame.point({x1, y0, 0}),
                                    frame.point({x1, y1, 0}), frame.point({x0, y1, 0})};
    const Vec3 feet[] = {
        {0, 0.25, 0}, {0.5, 0.75, 0}, {0.3, -0.1, 0}, {1.2, 0.2, 0}, {-0.8, -0.9, 0}};
    for (Vec3 foot : feet)
        for (double c : {0.01, 0.05, 0.3, 1.0, 10.0}) {
            const double exact = parallelRectangle(x0, x1, y0, y1, foot.x, foot.y, c);
            const Vec3 x = frame.point(foot + Vec3(0, 0, c));
            const double f = polygonFormFactor(x, -frame.ez, rect);
            EXPECT_NEAR(f, exact, tolerance(exact) * 0.1)
                << "polygonFormFactor = " << f << ", Howell B-3 = " << exact << " at foot "
                << str(foot) << ", height " << c;
        }
    // The classic value: unit square, normal through its centre at distance 1.
    const double exact = parallelRectangle(-0.5, 0.5, -0.5, 0.5, 0, 0, 1);
    EXPECT_NEAR(exact, 0.2395, 5e-4) << "closed form itself";
}

TEST(Lambert, ManySidedPolygonBetweenInscribedAndCircumscribedDisks) {
    // A regular N-gon of circumradius R lies between its inscribed disk (radius R cos(π/N))
    // and its circumscribed disk; on the axis F is bracketed by the two disk closed forms and
    // equals the brute-force integral. The contract places no limit on the vertex count.
    const Frame frame = tiltedFrame();
    for (int sides : {6, 12, 15, 16, 24, 40}) {
        const double R = 0.5;
        std::vector<Vec3> poly;
        for (int k = 0; k < sides; ++k) {
            double a = 2 * M_PI * k / sides;
            poly.push_back(frame.point({R * std::cos(a), R * std::sin(a), 0}));
        }
        for (double h : {0.05, 0.5, 2.0}) {
            const Vec3 x = frame.point({0, 0, h});
            const double f = polygonFormFactor(x, -frame.ez, poly);
            const double lo = coaxialDisk(R * std::cos(M_PI / sides), h), hi = coaxialDisk(R, h);
            const double brute = bruteForceFormFactor(x, -frame.ez, poly);
            EXPECT_GE(f, lo * (1 - 1e-9)) << sides << "-gon at h = " << h << ": F = " << f
                                          << " below the inscribed-disk value " << lo;
            EXPECT_LE(f, hi * (1 + 1e-9)) << sides << "-gon at h = " << h << ": F = " << f
                                          << " above the circumscribed-disk value " << hi;
            EXPECT_NEAR(f, brute, tolerance(brute))
                << sides << "-gon at h = " << h << ": polygonFormFactor = " << f
                << ", brute-force integral = " << brute;
        }
        // Off axis and grazing too.
        const Vec3 x = frame.point({0.6, 0.2, 0.1});
        const Vec3 n = frame.direction(tiltFromMinusZ(70, {-1, 0, 0}));
        const double brute = bruteForceFormFactor(x, n, poly);
        const double f = polygonFormFactor(x, n, poly);
        EXPECT_NEAR(f, brute, tolerance(brute))
            << sides << "-gon off axis: polygonFormFactor = " << f << ", brute force = " << brute;
    }
}

TEST(Lambert, OneSidedAndDegenerate) {
    const std::vector<Vec3> square = {
        {-0.5, 0, -0.5}, {-0.5, 0, 0.5}, {0.5, 0, 0.5}, {0.5, 0, -0.5}};  // front +Y
    EXPECT_GT(polygonFormFactor({0, 1, 0}, {0, -1, 0}, square), 0.2);
    // The same square wound the other way faces -Y: the point is behind it.
    std::vector<Vec3> reversed(square.rbegin(), square.rend());
    EXPECT_EQ(polygonFormFactor({0, 1, 0}, {0, -1, 0}, reversed), 0.0);
    EXPECT_EQ(polygonFormFactor({0, 1, 0}, {0, -1, 0}, {{0, 0, 0}, {1, 0, 0}}), 0.0);
}

// ---------------------------------------------------------------------------------------------
// irradianceAt from a lone emitting quad

TEST(Lambert, IrradianceFromUnoccludedEmitterEqualsEmissionTimesFormFactor) {
    Scene scene = test::emptyScene(0.5, 0.25);
    const Rgb emission(2.0, 1.0, 0.5);
    test::addMaterial(scene, "lamp", Rgb(0.0), emission);
    // A 1 × 0.8 quad in general orientation (its front faces roughly -Y).
    SceneObject lamp = test::makeQuad("lamp", 1.0, 0.8, "lamp", {0.2, 1.0, -0.1}, {160, 30, 10});
    scene.objects.push_back(lamp);
    const std::vector<Vec3> corners = test::quadCorners(lamp);

    // Frame of the emitter: origin at its centre, +Z its front normal.
    Frame frame;
    frame.origin = 0.25 * (corners[0] + corners[1] + corners[2] + corners[3]);
    frame.ex = glm::normalize(corners[1] - corners[0]);
    frame.ez = glm::normalize(glm::cross(corners[1] - corners[0], corners[2] - corners[1]));
    frame.ey = glm::cross(frame.ez, frame.ex);
    ASSERT_GT(glm::dot(frame.ez, Vec3(0, -1, 0)), 0.5) << "the lamp should face down";

    Discretization disc(scene);
    RayTracer tracer(disc);
    ProgressiveSolver solver(disc, tracer);
    solver.converge(1e-9, 1000);  // nothing reflects: B stays E

    int nonZero = 0;
    for (const Probe& probe : probes()) {
        const Vec3 x = frame.point(probe.p);
        const Vec3 n = frame.direction(probe.n);
        const double f = bruteForceFormFactor(x, n, corners);
        nonZero += f > 1e-6;
        const Rgb h = solver.irradianceAt(x, n);
        for (int c = 0; c < 3; ++c) {
            const double expected = emission[c] * f;
            EXPECT_NEAR(h[c], expected, tolerance(expected))
                << probe.what << ", channel " << c << ": irradianceAt = " << h[c]
                << ", E × brute-force F = " << emission[c] << " × " << f << " = " << expected
                << " at x = " << str(x) << ", n = " << str(n);
        }
    }
    EXPECT_GE(nonZero, 18);
}

TEST(Lambert, IrradianceFromEmittingCylinderCapEqualsEmissionTimesFormFactor) {
    // An emitting cylinder seen from below its bottom cap, inside its radius: the side faces
    // outward, so only the cap (a regular polygon of the cylinder's nu sides) is seen. Truth:
    // E × the brute-force integral over that regular polygon.
    Scene scene = test::emptyScene(0.5, 0.25);
    const Rgb emission(1.5, 1.0, 0.5);
    test::addMaterial(scene, "lamp", Rgb(0.0), emission);
    const double r = 0.5, h = 0.4;
    SceneObject cyl;
    cyl.id = "lamp";
    cyl.shape.type = ShapeType::Cylinder;
    cyl.shape.radius = r;
    cyl.shape.height = h;
    cyl.shape.segments = 24;
    cyl.material = "lamp";
    scene.objects.push_back(cyl);
    Discretization disc(scene);
    RayTracer tracer(disc);
    ProgressiveSolver solver(disc, tracer);

    // nu: the number of elements around the bottom cap's centre.
    const Vec3 centre(0, -h / 2, 0);
    int nu = 0;
    for (int e = 0; e < static_cast<int>(disc.elements().size()); ++e)
        for (const Vec3& v : disc.elementPolygon(e))
            if (glm::length(v - centre) < 1e-6) {
                ++nu;
                break;
            }
    ASSERT_GE(nu, 24);
    std::vector<Vec3> cap;
    for (int k = 0; k < nu; ++k) {
        const double a = 2 * M_PI * k / nu;
        cap.push_back(centre + Vec3(r * std::cos(a), 0, r * std::sin(a)));
    }
    if (glm::cross(cap[1] - cap[0], cap[2] - cap[1]).y > 0) std::reverse(cap.begin(), cap.end());

    const Vec3 up(0, 1, 0);
    const struct {
        Vec3 x, n;
    } probes[] = {{{0, -0.3, 0}, up},
                  {{0, -1.2, 0}, up},
                  {{0.2, -0.22, 0.1}, up},
                  {{-0.3, -0.25, -0.2}, glm::normalize(Vec3(0.5, 1, 0))},
                  {{0.1, -0.6, 0}, glm::normalize(Vec3(1, 0.3, 0))}};
    for (const auto& p : probes) {
        const double f = bruteForceFormFactor(p.x, p.n, cap);
        const Rgb hIrr = solver.irradianceAt(p.x, p.n);
        for (int c = 0; c < 3; ++c) {
            const double expected = emission[c] * f;
            EXPECT_NEAR(hIrr[c], expected, tolerance(expected))
                << "channel " << c << ": irradianceAt = " << hIrr[c]
                << ", E × brute-force F of the " << nu << "-gon cap = " << expected
                << " at x = " << str(p.x) << ", n = " << str(p.n);
        }
    }
}

// angleAtan2, the contour integral's edge angle, against libm over the half-plane y ≥ 0:
// random directions at scales from 1e-300 to 1e300, the axes, the octant boundaries and zero.
TEST(Lambert, EdgeAngleMatchesLibmAtan2) {
    std::mt19937_64 rng(7);
    std::uniform_real_distribution<double> angle(0.0, M_PI), exponent(-300.0, 300.0);
    double worst = 0;
    for (int i = 0; i < 200000; ++i) {
        const double t = angle(rng), r = std::pow(10.0, exponent(rng));
        const double y = r * std::sin(t), x = r * std::cos(t);
        worst = std::max(worst, std::abs(angleAtan2(y, x) - std::atan2(y, x)));
    }
    EXPECT_LT(worst, 2e-10);
    for (double x : {-2.0, -1.0, -1e-300, 0.0, 1e-300, 1.0, 2.0})
        for (double y : {0.0, 1e-300, 1.0, 2.0}) {
            if (x == 0 && y == 0) continue;
            EXPECT_NEAR(angleAtan2(y, x), std::atan2(y, x), 2e-10) << y << ", " << x;
        }
    for (double y : {1e-300, 1.0, 1e300}) {
        EXPECT_NEAR(angleAtan2(y, y), M_PI / 4, 2e-10);
        EXPECT_NEAR(angleAtan2(y, -y), 3 * M_PI / 4, 2e-10);
    }
    EXPECT_EQ(angleAtan2(0.0, 0.0), 0.0);
}

}  // namespace
}  // namespace penumbra
