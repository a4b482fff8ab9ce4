#pragma once
// The editor's interactive camera: orbit about a target, pan, zoom (dolly), fly (WASD), frame
// a bounding sphere. World +Y is up. Converts to and from the scene's pinhole Camera, whose
// pixel conventions are render/camera_rays.h's.

#include <string>

#include "solver/scene.h"

namespace penumbra {

class ViewCamera {
public:
    /// Pitch stays within ±kMaxPitch (radians) so the view never flips over the pole.
    static constexpr double kMaxPitch = 1.5533430342749532;  // 89°
    static constexpr double kMinDistance = 1e-3;             ///< metres

    ViewCamera() = default;
    /// From a scene camera: target = lookAt, distance = |position − lookAt|, yaw and pitch
    /// from the view direction (its `up` is replaced by +Y), same vertical field of view.
    static ViewCamera fromCamera(const Camera& camera);
    /// The scene camera for rendering: position, lookAt = target, up = +Y, fovDeg.
    Camera toCamera() const;

    /// Eye point: target − distance · forward.
    Vec3 position() const;
    /// Unit view direction; yaw 0, pitch 0 looks down −Z, positive yaw turns toward +X.
    Vec3 forward() const;
    /// Unit image +x (horizontal).
    Vec3 right() const;
    /// Unit image up, perpendicular to forward and right.
    Vec3 up() const;

    /// Orbits about the target: yaw and pitch change by the given angles (radians); the
    /// distance to the target is kept; pitch is clamped to ±kMaxPitch.
    void orbit(double dYaw, double dPitch);
    /// Pans by a cursor move of (dx, dy) pixels (x right, y down) in a view `viewportHeight`
    /// pixels high: eye and target move in the view plane so a point at the target's depth
    /// stays under the cursor.
    void pan(double dxPixels, double dyPixels, int viewportHeight);
    /// Dollies toward the target: distance *= factor (factor > 0), at least kMinDistance.
    void zoom(double factor);
    /// Moves eye and target together by `delta` metres in the camera frame (x right, y up,
    /// z forward): the WASD fly mode.
    void fly(const Vec3& delta);
    /// Looks at a bounding sphere: target = centre, distance such that the sphere fits the
    /// vertical field of view (and the horizontal one for `aspect` = width / height < 1).
    void frame(const Vec3& centre, double radius, double aspect = 1.0);

    Vec3 target{0.0};
    double distance = 3.0;  ///< metres, eye to target
    double yaw = 0.0;       ///< radians
    double pitch = 0.0;     ///< radians
    double fovDeg = 40.0;   ///< vertical field of view

    std::string toString() const;
};

}  // namespace penumbra
