// Index: geometry helpers · names · Gizmo: construction · shapes · hit testing · dragging

#include "ui/gizmo.h"

#include <algorithm>
#include <cmath>
#include <glm/gtc/matrix_transform.hpp>
#include <sstream>

#include "render/camera_rays.h"

namespace penumbra {

// ---------------------------------------------------------------------------------------------
// Geometry helpers.

std::optional<double> closestLineParameter(const Vec3& point, const Vec3& axis, const Ray& ray) {
    // Minimise |point + s·a − (o + t·d)| over s and t (both lines unit): the 2×2 normal
    // equations s − b·t = a·w, b·s − t = d·w with w = o − point, b = a·d.
    const Vec3 w = ray.origin - point;
    const double b = glm::dot(axis, ray.direction);
    const double denominator = 1.0 - b * b;
    if (denominator < 1e-9) return std::nullopt;
    const double aw = glm::dot(axis, w);
    const double dw = glm::dot(ray.direction, w);
    return (aw - b * dw) / denominator;
}

std::optional<Vec3> intersectPlane(const Ray& ray, const Vec3& point, const Vec3& normal) {
    const double dn = glm::dot(ray.direction, normal);
    if (std::abs(dn) < 1e-9) return std::nullopt;
    const double t = glm::dot(point - ray.origin, normal) / dn;
    if (!(t > 0) || !std::isfinite(t)) return std::nullopt;
    return ray.at(t);
}

glm::dmat3 rotationFromEulerDeg(const Vec3& deg) {
    const glm::dmat4 identity(1.0);
    const glm::dmat4 r = glm::rotate(identity, glm::radians(deg.z), Vec3(0, 0, 1)) *
                         glm::rotate(identity, glm::radians(deg.y), Vec3(0, 1, 0)) *
                         glm::rotate(identity, glm::radians(deg.x), Vec3(1, 0, 0));
    return glm::dmat3(r);
}

Vec3 eulerDegFromRotation(const glm::dmat3& m) {
    // R = Rz(c)·Ry(b)·Rx(a): R20 = −sin b, R21 = sin a cos b, R22 = cos a cos b,
    // R10 = cos b sin c, R00 = cos b cos c (glm is column-major: R[row][col] = m[col][row]).
    auto at = [&](int row, int col) { return m[col][row]; };
    const double sb = std::clamp(-at(2, 0), -1.0, 1.0);
    double a, b = std::asin(sb), c;
    if (std::abs(sb) < 1.0 - 1e-12) {
        a = std::atan2(at(2, 1), at(2, 2));
        c = std::atan2(at(1, 0), at(0, 0));
    } else {
        // Gimbal lock: only a − c (or a + c) is defined; put it all in a (c = 0), where
        // R11 = cos a and R12 = −sin a.
        c = 0.0;
        a = std::atan2(-at(1, 2), at(1, 1));
    }
    return glm::degrees(Vec3(a, b, c));
}

double snapToStep(double value, double step) {
    return step > 0 ? std::round(value / step) * step : value;
}

const char* gizmoModeName(GizmoMode mode) {
    switch (mode) {
        case GizmoMode::Translate:
            return "translate";
        case GizmoMode::Rotate:
            return "rotate";
        case GizmoMode::Scale:
            return "scale";
    }
    return "?";
}

const char* gizmoHandleName(GizmoHandle handle) {
    switch (handle) {
        case GizmoHandle::None:
            return "none";
        case GizmoHandle::X:
            return "x";
        case GizmoHandle::Y:
            return "y";
        case GizmoHandle::Z:
            return "z";
        case GizmoHandle::PlaneYZ:
            return "plane-yz";
        case GizmoHandle::PlaneZX:
            return "plane-zx";
        case GizmoHandle::PlaneXY:
            return "plane-xy";
        case GizmoHandle::Uniform:
            return "uniform";
    }
    return "?";
}

namespace {

int axisIndex(GizmoHandle h) {
    switch (h) {
        case GizmoHandle::X:
        case GizmoHandle::PlaneYZ:
            return 0;
        case GizmoHandle::Y:
        case GizmoHandle::PlaneZX:
            return 1;
        case GizmoHandle::Z:
        case GizmoHandle::PlaneXY:
            return 2;
        default:
            return -1;
    }
}

bool isPlane(GizmoHandle h) {
    return h == GizmoHandle::PlaneYZ || h == GizmoHandle::PlaneZX || h == GizmoHandle::PlaneXY;
}

bool insideConvex(glm::dvec2 p, const std::vector<glm::dvec2>& poly) {
    if (poly.size() < 3) return false;
    int sign = 0;
    for (std::size_t i = 0; i < poly.size(); ++i) {
        const glm::dvec2 a = poly[i], b = poly[(i + 1) % poly.size()];
        const double cross = (b.x - a.x) * (p.y - a.y) - (b.y - a.y) * (p.x - a.x);
        const int s = cross > 0 ? 1 : (cross < 0 ? -1 : 0);
        if (s == 0) continue;
        if (sign == 0) sign = s;
        if (s != sign) return false;
    }
    return true;
}

/// Rotation by `angle` radians about unit `axis`.
glm::dmat3 axisRotation(const Vec3& axis, double angle) {
    return glm::dmat3(glm::rotate(glm::dmat4(1.0), angle, axis));
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// Gizmo: construction.

Gizmo::Gizmo(GizmoMode mode, const Transform& transform, double size)
    : mMode(mode),
      mStart(transform),
      mSize(size > 0 ? size : 1.0),
      mRotation(rotationFromEulerDeg(transform.rotateDeg)) {}

Vec3 Gizmo::axis(int i) const {
    Vec3 e(0.0);
    e[i] = 1.0;
    return mMode == GizmoMode::Scale ? glm::normalize(mRotation * e) : e;
}

// ---------------------------------------------------------------------------------------------
// Shapes.

std::vector<GizmoShape> Gizmo::shapes(const Camera& camera, int width, int height) const {
    const CameraRays view(camera, width, height);
    std::vector<GizmoShape> out;
    const Vec3 c = pivot();
    const GizmoHandle axes[3] = {GizmoHandle::X, GizmoHandle::Y, GizmoHandle::Z};
    const GizmoHandle planes[3] = {GizmoHandle::PlaneYZ, GizmoHandle::PlaneZX,
                                   GizmoHandle::PlaneXY};

    // Project a world polyline; drop it when any point is behind the camera.
    auto add = [&](GizmoHandle h, const std::vector<Vec3>& world, bool filled, bool closed) {
        GizmoShape s{h, {}, filled, closed};
        for (const Vec3& p : world) {
            const auto px = view.projectToPixel(p);
            if (!px) return;
            s.points.push_back(*px);
        }
        out.push_back(std::move(s));
    };

    if (mMode == GizmoMode::Rotate) {
        // Rings of radius `size` in the planes normal to each world axis.
        constexpr int kSegments = 64;
        for (int i = 0; i < 3; ++i) {
            const Vec3 u = axis((i + 1) % 3), v = axis((i + 2) % 3);
            std::vector<Vec3> ring;
            for (int k = 0; k < kSegments; ++k) {
                const double a = 2.0 * M_PI * k / kSegments;
                ring.push_back(c + mSize * (std::cos(a) * u + std::sin(a) * v));
            }
            add(axes[i], ring, false, true);
        }
        return out;
    }
    for (int i = 0; i < 3; ++i)
        add(axes[i], {c + 0.2 * mSize * axis(i), c + mSize * axis(i)}, false, false);
    if (mMode == GizmoMode::Translate) {
        for (int i = 0; i < 3; ++i) {
            const Vec3 u = axis((i + 1) % 3), v = axis((i + 2) % 3);
            add(planes[i],
                {c + 0.3 * mSize * (u + v), c + mSize * (0.5 * u + 0.3 * v),
                 c + 0.5 * mSize * (u + v), c + mSize * (0.3 * u + 0.5 * v)},
                true, true);
        }
    } else {
        // Uniform scale: a square of ±7 pixels about the pivot.
        if (const auto p = view.projectToPixel(c)) {
            const double r = 7.0;
            out.push_back({GizmoHandle::Uniform,
                           {*p + glm::dvec2(-r, -r), *p + glm::dvec2(r, -r), *p + glm::dvec2(r, r),
                            *p + glm::dvec2(-r, r)},
                           true,
                           true});
        }
    }
    return out;
}

// ---------------------------------------------------------------------------------------------
// Hit testing.

GizmoHandle Gizmo::hitTest(const Camera& camera, int width, int height, glm::dvec2 pixel,
                           double tolerancePx) const {
    GizmoHandle best = GizmoHandle::None;
    double bestDistance = tolerancePx;
    for (const GizmoShape& s : shapes(camera, width, height)) {
        double d = 1e30;
        if (s.filled && insideConvex(pixel, s.points)) d = 0.0;
        const std::size_t n = s.points.size();
        for (std::size_t k = 0; k + 1 < n + (s.closed ? 1 : 0); ++k)
            d = std::min(d, distanceToSegment(pixel, s.points[k], s.points[(k + 1) % n]));
        // Filled handles win over lines passing through them.
        if (d < bestDistance || (d == 0.0 && s.filled)) {
            bestDistance = d;
            best = s.handle;
        }
    }
    return best;
}

// ---------------------------------------------------------------------------------------------
// Dragging.

bool Gizmo::begin(GizmoHandle handle, const Ray& ray) {
    mActive = GizmoHandle::None;
    const Vec3 c = pivot();
    const int i = axisIndex(handle);
    if (handle == GizmoHandle::None) return false;
    if (handle == GizmoHandle::Uniform) {
        mViewNormal = -ray.direction;
        const auto p = intersectPlane(ray, c, mViewNormal);
        if (!p || glm::length(*p - c) < 1e-9) return false;
        mGrab = *p;
    } else if (mMode == GizmoMode::Rotate || isPlane(handle)) {
        const auto p = intersectPlane(ray, c, axis(i));
        if (!p || (mMode == GizmoMode::Rotate && glm::length(*p - c) < 1e-9)) return false;
        mGrab = *p;
    } else {
        const auto s = closestLineParameter(c, axis(i), ray);
        if (!s || (mMode == GizmoMode::Scale && std::abs(*s) < 1e-9)) return false;
        mGrabParam = *s;
    }
    mActive = handle;
    return true;
}

Transform Gizmo::drag(const Ray& ray, const GizmoSnap& snap) const {
    Transform t = mStart;
    const Vec3 c = pivot();
    const int i = axisIndex(mActive);
    if (mActive == GizmoHandle::None) return t;

    if (mMode == GizmoMode::Translate) {
        Vec3 delta(0.0);
        if (isPlane(mActive)) {
            const auto p = intersectPlane(ray, c, axis(i));
            if (!p) return t;
            delta = *p - mGrab;
            delta[i] = 0.0;  // stay in the plane exactly
        } else {
            const auto s = closestLineParameter(c, axis(i), ray);
            if (!s) return t;
            delta = (*s - mGrabParam) * axis(i);
        }
        if (snap.enabled)
            for (int k = 0; k < 3; ++k) delta[k] = snapToStep(delta[k], snap.translate);
        t.translate = mStart.translate + delta;
        return t;
    }

    if (mMode == GizmoMode::Rotate) {
        const Vec3 a = axis(i);
        const auto p = intersectPlane(ray, c, a);
        if (!p) return t;
        const Vec3 v0 = mGrab - c, v1 = *p - c;
        if (glm::length(v1) < 1e-12) return t;
        // Signed angle from v0 to v1 about a.
        double angle = std::atan2(glm::dot(glm::cross(v0, v1), a), glm::dot(v0, v1));
        if (snap.enabled) angle = glm::radians(snapToStep(glm::degrees(angle), snap.rotateDeg));
        t.rotateDeg = eulerDegFromRotation(axisRotation(a, angle) * mRotation);
        return t;
    }

    // Scale.
    double factor = 1.0;
    if (mActive == GizmoHandle::Uniform) {
        const auto p = intersectPlane(ray, c, mViewNormal);
        if (!p) return t;
        factor = glm::length(*p - c) / glm::length(mGrab - c);
    } else {
        const auto s = closestLineParameter(c, axis(i), ray);
        if (!s) return t;
        factor = *s / mGrabParam;
    }
    if (snap.enabled) factor = snapToStep(factor, snap.scale);
    // Scale factors stay positive (the scene file forbids zero scale).
    factor = std::max(factor, 0.01);
    if (mActive == GizmoHandle::Uniform)
        t.scale = mStart.scale * factor;
    else
        t.scale[i] = mStart.scale[i] * factor;
    return t;
}

std::string Gizmo::toString() const {
    std::ostringstream s;
    s << "Gizmo{" << gizmoModeName(mMode) << ", size " << mSize << ", active "
      << gizmoHandleName(mActive) << ", " << mStart.toString() << "}";
    return s.str();
}

}  // namespace penumbra
