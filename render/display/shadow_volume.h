#pragma once
// Which points an object's move can change the direct light of: those from which some
// segment to a lamp meets the object's bounds, before or after the move (the object's shadow
// volumes, Bala et al. §6 "Moving objects": the shadows of the moved light–blocker pairs are
// recomputed). Conservative: the object's axis-aligned box stands for the object.

#include <vector>

#include "core/math.h"
#include "render/display/shadow_events.h"

namespace penumbra {

/// The light as the shaft test reads it: its polygon (one vertex: a point light), its plane
/// and its bounding box.
struct ShaftLight {
    std::vector<Vec3> polygon;
    Vec3 normal{0.0};  ///< the emitting side (Newell normal, counter-clockwise from the front)
    Vec3 centroid{0.0};
    double area = 0;  ///< 0 for a point light
    Vec3 lo{0.0}, hi{0.0};
    /// The points blockedFraction traces to: the centroid and each vertex a quarter of the way
    /// in towards it (the light's own point for a point light).
    std::vector<Vec3> samples;
    explicit ShaftLight(const Light& light);
};

/// Whether a segment from `x` to some point of `light` can meet the box [lo, hi]: the pyramid
/// from x over the light's polygon overlaps the box (no face plane of the pyramid has the whole
/// box outside, and the boxes overlap). False when x is behind the light's emitting plane (it
/// receives none of its light). Conservative: true may be returned for a box the pyramid only
/// nearly meets, never false for one it meets.
bool shaftMeetsBox(const Vec3& x, const ShaftLight& light, const Vec3& lo, const Vec3& hi);

/// The share of the light's samples (ShaftLight::samples) whose segment from x meets the box
/// [lo, hi]: a coarse estimate of how much of the light the box hides from x, 0 when the
/// shaft misses it (shaftMeetsBox) or x is behind the light.
double blockedFraction(const Vec3& x, const ShaftLight& light, const Vec3& lo, const Vec3& hi);

/// The unoccluded form factor from a small patch at x with normal n to the light, from its
/// centroid (cosines over π d², times the area; 1/(π d²)·cos for a point light): the weight of
/// the light at x among others.
double lightWeight(const Vec3& x, const Vec3& n, const ShaftLight& light);

}  // namespace penumbra
