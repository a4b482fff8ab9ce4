#pragma once
// The transform gizmo: translate (axis and plane handles), rotate (rings about the world
// axes) and scale (local axis handles and a uniform centre handle), with snapping.
//
// Index: geometry helpers (ray-line, ray-plane, Euler angles, snapping) · GizmoShape ·
//        Gizmo (handles on screen, hit testing, dragging)
//
// The pivot is the object's origin (Transform::translate), about which the scene-file
// transform rotates and scales, so a rotation or scale drag composes exactly with the
// object's transform. Handles keep a constant size on screen: the caller passes `size` in
// metres (for example distance-to-camera × 0.15).

#include <array>
#include <glm/glm.hpp>
#include <optional>
#include <string>
#include <vector>

#include "solver/scene.h"
#include "ui/picking.h"

namespace penumbra {

// ---------------------------------------------------------------------------------------------
// Geometry helpers.

/// Parameter s of the point point + s·axis (axis unit) on the line closest to `ray` (the
/// common perpendicular); empty when the ray is (nearly) parallel to the line.
std::optional<double> closestLineParameter(const Vec3& point, const Vec3& axis, const Ray& ray);
/// The ray's hit with the plane through `point` with normal `normal` (either side, t > 0);
/// empty when the ray is parallel to the plane or the plane is behind it.
std::optional<Vec3> intersectPlane(const Ray& ray, const Vec3& point, const Vec3& normal);
/// Rotation matrix of the scene transform's Euler angles: Rz · Ry · Rx (degrees).
glm::dmat3 rotationFromEulerDeg(const Vec3& rotateDeg);
/// Euler angles (degrees, X then Y then Z; Y in [−90, 90]) with
/// rotationFromEulerDeg(result) == rotation, for a proper rotation matrix.
Vec3 eulerDegFromRotation(const glm::dmat3& rotation);
/// `value` rounded to the nearest multiple of `step` (step ≤ 0: unchanged).
double snapToStep(double value, double step);

// ---------------------------------------------------------------------------------------------
// Gizmo.

enum class GizmoMode { Translate, Rotate, Scale };
/// X, Y, Z: axis handles (translate, scale) or rings (rotate). PlaneYZ/ZX/XY: translate in
/// the plane normal to X/Y/Z. Uniform: scale all axes (centre handle).
enum class GizmoHandle { None, X, Y, Z, PlaneYZ, PlaneZX, PlaneXY, Uniform };
const char* gizmoModeName(GizmoMode mode);
const char* gizmoHandleName(GizmoHandle handle);

struct GizmoSnap {
    bool enabled = false;
    double translate = 0.1;  ///< metres, per world axis
    double rotateDeg = 15;   ///< degrees
    double scale = 0.1;      ///< scale factor increments
};

/// A handle as drawn: pixel coordinates of a polyline (closed for rings) or a filled convex
/// polygon (plane and uniform handles).
struct GizmoShape {
    GizmoHandle handle = GizmoHandle::None;
    std::vector<glm::dvec2> points;
    bool filled = false;
    bool closed = false;
};

class Gizmo {
public:
    /// `transform`: the object's transform when the gizmo is shown (the pivot is its
    /// translate); `size`: handle length in metres (> 0).
    Gizmo(GizmoMode mode, const Transform& transform, double size);

    GizmoMode mode() const { return mMode; }
    const Transform& transform() const { return mStart; }
    const Vec3& pivot() const { return mStart.translate; }
    double size() const { return mSize; }
    /// Unit direction of handle i (0..2): the world axes for translate and rotate, the
    /// object's rotated local axes for scale.
    Vec3 axis(int i) const;

    /// The handles projected into a width × height view of `camera`; parts behind the
    /// camera are left out.
    std::vector<GizmoShape> shapes(const Camera& camera, int width, int height) const;
    /// The handle under pixel (px, py): inside a filled handle, or within `tolerancePx`
    /// pixels of a line or ring (the nearest wins); None otherwise.
    GizmoHandle hitTest(const Camera& camera, int width, int height, glm::dvec2 pixel,
                        double tolerancePx = 6.0) const;

    /// Starts dragging `handle` with the cursor's ray; false (and nothing starts) when the
    /// ray cannot grab it (parallel to the axis or plane).
    bool begin(GizmoHandle handle, const Ray& ray);
    GizmoHandle active() const { return mActive; }
    void end() { mActive = GizmoHandle::None; }
    /// The object's transform for the cursor's current ray: translate moves by the change of
    /// the closest point on the axis (or of the plane hit); rotate turns by the angle swept
    /// about the axis in the ring's plane; scale multiplies a local axis by the ratio of the
    /// distances from the pivot (uniform: all axes, measured in the view-facing plane).
    /// Snapping rounds the translation per world axis, the angle, or the factor. A ray that
    /// cannot be used (parallel) gives the start transform.
    Transform drag(const Ray& ray, const GizmoSnap& snap = {}) const;

    std::string toString() const;

private:
    GizmoMode mMode;
    Transform mStart;
    double mSize;
    glm::dmat3 mRotation;  ///< of mStart
    GizmoHandle mActive = GizmoHandle::None;
    Vec3 mGrab{0.0};          ///< grab point (plane and ring handles) at begin
    double mGrabParam = 0.0;  ///< grab parameter along the axis at begin
    Vec3 mViewNormal{0.0};    ///< uniform scale: normal of the view-facing plane
};

}  // namespace penumbra
