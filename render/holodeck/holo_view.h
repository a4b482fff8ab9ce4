#pragma once
// The holodeck and the display (Ward & Simmons 1999, §2.4.2): a view's beams read back as the
// render cache's shaded points, and the points the display shaded written into the holodeck.
// Penumbra's surfaces are diffuse, so a sample's radiance holds wherever its hit point is seen
// from: a stored sample becomes a point of the view when the eye sees its hit point, whichever
// eye the sample was shaded for.

#include <cstdint>
#include <functional>
#include <utility>
#include <vector>

#include "render/display/point_shader.h"
#include "render/display/render_cache.h"
#include "render/holodeck/holo_server.h"
#include "render/light_change.h"

namespace penumbra {

class Discretization;
class RayTracer;
struct Settings;

/// The bounds of the scene's surfaces (its alive objects' vertices).
std::pair<Vec3, Vec3> surfaceBounds(const Discretization& disc);

/// A new holodeck's sections: the scene file's (settings.holodeck), their grids derived where
/// not given (nearCubicGrid), or else one interior section over the scene's surfaces
/// (layoutSection). Throws std::invalid_argument when the scene has no surfaces.
std::vector<HoloSection> holodeckSections(const Settings& settings, const Discretization& disc);

/// The samples of `view`'s beams (viewRequests) as shaded points of `camera`: each sample's ray
/// is traced again in the scene as it is (a sample whose ray now ends elsewhere is stale and
/// left out), its hit must be seen from the eye (one occlusion ray) and inside the raster.
/// Of the samples in a pixel, the one nearest its centre is taken (a batch-filled holodeck
/// holds many per pixel; more than one a pixel only crowds the display's cache). Points carry
/// `frame` and `shading` (PointShader::stateSerial) like points shaded now.
std::vector<ShadedPoint> holodeckViewPoints(HoloServer& server,
                                            const std::vector<BeamRequest>& view,
                                            const Discretization& disc, const RayTracer& tracer,
                                            const CameraRays& camera, std::uint64_t frame,
                                            std::uint64_t shading);

/// The interactive fill of a view (§2.3 keeps a view's new rays near the eye; these pass
/// through it): `camera`'s pixel rays, one per pixel in a random order of the pixels (any
/// prefix spread over the image, no pixel twice in a pass), the first pass through the
/// pixels' centres and later ones jittered within them, shaded by `shader` on oneTBB's threads and stored as storeViewPoints
/// stores the display's points, until `maxSamples` samples are stored or `seconds` have
/// passed (either may be 0: no limit; not both), or a batch of rays stores none (a view of
/// nothing but sky). A reopened view then finds about a sample in every pixel, where the
/// ratio-ordered fill of the view's beams (HoloServer::fill with viewRequests) scatters them.
/// Commits after every batch; `progress` (may be empty) gets the fraction done.
FillStats fillView(HoloServer& server, const PointShader& shader, const RayTracer& tracer,
                   const CameraRays& camera, std::int64_t maxSamples, double seconds,
                   std::uint64_t seed = 1, const std::function<void(double)>& progress = {});

/// Writes the display's shaded points into the holodeck as samples of the rays from `eye`
/// through them, for the points the eye sees (a point shaded from another eye and hidden from
/// this one is left out) and whose ray crosses a section. Returns the samples added.
std::int64_t storeViewPoints(HoloServer& server, const std::vector<CachePoint>& points,
                             const RayTracer& tracer, const Vec3& eye);

}  // namespace penumbra
