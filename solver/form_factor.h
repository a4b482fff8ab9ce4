#pragma once
// Form factors: the analytic point-to-polygon form factor (Lambert's contour integral) and
// the ray-traced point-to-patch estimate in the manner of Wallace et al. 1989.

#include <cstdint>
#include <vector>

#include "solver/contour_integral.h"
#include "solver/ray_tracer.h"
#include "solver/scene.h"

namespace penumbra {

class Discretization;
class RayTracer;

/// Form factor from a differential area at `x` with unit normal `n` to a planar polygon
/// (vertices counter-clockwise seen from its front). The polygon is clipped to the
/// hemisphere above `x`; a point behind the polygon's plane sees nothing (one-sided).
/// Lambert's formula: F = 1/(2π) Σ_k β_k (n · γ̂_k), β_k the angle each edge subtends.
double polygonFormFactor(const Vec3& x, const Vec3& n, const std::vector<Vec3>& polygon);

/// Number of visibility rays used for a pair with unoccluded form factor `fUnoccluded`.
/// Depends on geometry only, never on energy, so a later recomputation of the same pair
/// traces the same rays.
int visibilityRayCount(double fUnoccluded, int maxRays);

/// Ray-traced form factor from point (x, n) to patch `patch`: the exact unoccluded form
/// factor of each of the patch's element polygons, times the visible fraction estimated by
/// `rays` shadow rays to points stratified over the patch by that form factor. The sample
/// pattern depends only on (seed, receiverKey, patch), so it is reproducible bit for bit.
/// `visibility` is passed to the ray tracer. Returns 0 for points behind the patch.
struct PointToPatch {
    double unoccluded = 0;  ///< analytic, no visibility
    double visible = 0;     ///< the estimate with visibility
    int rays = 0;           ///< rays traced
};
PointToPatch formFactorToPatch(const Discretization& disc, const RayTracer& tracer, const Vec3& x,
                               const Vec3& n, int patch, std::uint64_t receiverKey,
                               std::uint64_t seed, int maxRays, const Visibility& visibility = {});

/// A receiving point of formFactorsToPatch: the point, its unit normal and its key (the
/// receiverKey of formFactorToPatch).
struct Receiver {
    Vec3 x, n;
    std::uint64_t key = 0;
};

/// formFactorToPatch from each of `count` receivers to one patch, the same results bit for bit
/// (out[i] for receivers[i]). For a planar patch, the unoccluded form factors of its whole
/// outline come first, kContourLanes receivers at a time, then each receiver's samples and
/// rays: a pair's contour sum no longer waits for the pair before it to finish tracing.
void formFactorsToPatch(const Discretization& disc, const RayTracer& tracer, int patch,
                        const Receiver* receivers, int count, std::uint64_t seed, int maxRays,
                        const Visibility& visibility, PointToPatch* out);

/// Which of the two worlds of formFactorChange hold the changed objects.
enum class ChangedObjectsIn {
    Either,  ///< some in each (a move), or not known
    After,   ///< all of them after, none before (an addition)
    Before,  ///< all of them before, none after (a removal)
};

/// F(after) − F(before) for the same pair and the same pair-seeded samples as
/// formFactorToPatch, where the two worlds differ only by the objects that `changed` admits
/// (a Visibility::subset of the added and removed objects). The samples are first traced
/// against the changed objects alone (packets of up to 16); only samples that meet one are
/// traced in `before` and `after`, so unchanged visibility cancels exactly and costs one cheap
/// ray. When `where` says one world holds every changed object, a sample meeting one is
/// blocked in that world (the same instances give the same hits), so only the other world is
/// traced. `visible` holds the difference, `rays` every ray traced.
PointToPatch formFactorChange(const Discretization& disc, const RayTracer& tracer, const Vec3& x,
                              const Vec3& n, int patch, std::uint64_t receiverKey,
                              std::uint64_t seed, int maxRays, const Visibility& before,
                              const Visibility& after, const Visibility& changed,
                              ChangedObjectsIn where = ChangedObjectsIn::Either);

}  // namespace penumbra
