#pragma once
// A pinhole camera over an image raster: primary ray directions for pixel coordinates and
// the inverse projection of world points to pixel coordinates.

#include <glm/glm.hpp>
#include <optional>
#include <string>

#include "solver/scene.h"

namespace penumbra {

/// Pinhole camera built from a scene Camera (position, lookAt, up, vertical fovDeg) and an
/// image size. Pixel coordinates: px grows right in [0, width], py grows down in
/// [0, height]; pixel (i, j) covers [i, i+1) × [j, j+1), its centre is (i + 0.5, j + 0.5).
/// Square pixels: the horizontal field of view follows from the aspect ratio.
/// `camera` turned by `deg` degrees about its up axis around its look-at point (Rodrigues'
/// rotation of the position): a camera path orbiting the scene.
Camera orbitCamera(const Camera& camera, double deg);

class CameraRays {
public:
    /// Throws std::invalid_argument when width or height is not positive, fovDeg is not in
    /// (0, 180), or position == lookAt. An `up` parallel to the view direction is replaced
    /// by a perpendicular one.
    CameraRays(const Camera& camera, int width, int height);

    /// World-space eye point, the origin of every primary ray.
    const Vec3& origin() const { return mOrigin; }
    /// Unit world-space direction of the ray through pixel coordinates (px, py).
    Vec3 rayDirection(double px, double py) const;
    /// Pixel coordinates (px, py) where a world point projects; empty when the point is not
    /// in front of the camera. The result may lie outside the raster. One division (the
    /// render cache projects every cached point each frame); inline, as its caller computes
    /// the same view depth.
    std::optional<glm::dvec2> projectToPixel(const Vec3& world) const {
        const double depth = glm::dot(world - mOrigin, mForward);
        if (!(depth > 0.0)) return std::nullopt;
        return projectAtDepth(world, depth);
    }
    /// projectToPixel for a point whose view depth dot(world − origin, forward) is known and
    /// positive: the view-space coordinates scaled to pixels (mPixelRight, mPixelUp) over the
    /// depth.
    glm::dvec2 projectAtDepth(const Vec3& world, double depth) const {
        const Vec3 d = world - mOrigin;
        const double inv = 1.0 / depth;
        return {0.5 * mWidth + glm::dot(d, mPixelRight) * inv,
                0.5 * mHeight - glm::dot(d, mPixelUp) * inv};
    }

    /// Pixels spanned by a unit length facing the camera at unit view depth (divide by the
    /// depth for other depths).
    double pixelsPerUnit() const { return 0.5 * mHeight / mTanHalfY; }
    int width() const { return mWidth; }
    int height() const { return mHeight; }
    const Vec3& forward() const { return mForward; }  ///< unit view direction
    const Vec3& right() const { return mRight; }      ///< unit, image +x
    const Vec3& up() const { return mUp; }            ///< unit, image −y
    std::string toString() const;
    /// The same view: eye, orientation, field of view and raster, bit for bit.
    bool operator==(const CameraRays&) const = default;

private:
    Vec3 mOrigin{0.0};
    Vec3 mForward{0, 0, -1};
    Vec3 mRight{1, 0, 0};
    Vec3 mUp{0, 1, 0};
    double mTanHalfY = 1;       ///< tan(fovY / 2)
    double mTanHalfX = 1;       ///< tanHalfY · width / height
    Vec3 mPixelRight{1, 0, 0};  ///< mRight · width / (2 tanHalfX): projectAtDepth
    Vec3 mPixelUp{0, 1, 0};     ///< mUp · height / (2 tanHalfY)
    int mWidth = 1;
    int mHeight = 1;
};

}  // namespace penumbra
