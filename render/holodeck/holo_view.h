#pragma once
// The holodeck and the display (Ward & Simmons 1999, §2.4.2): a view's beams read back as the
// render cache's shaded points, and the points the display shaded written into the holodeck.
// Penumbra's surfaces are diffuse, so a sample's radiance holds wherever its hit point is seen
// from: a stored sample becomes a point of the view when the eye sees its hit point, whichever
// eye the sample was shaded for.

#include <array>
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

/// Where the stored beams' samples hit, so that any view takes every stored sample it can see,
/// whichever views or fill stored them (Ward & Simmons fill a holodeck once for walkthroughs
/// anywhere inside its sections). Built by reading every stored beam once: each sample's
/// decoded hit point beside the sample, grouped by beam, and per beam the bounding box of its
/// hit points, so a view reads only the beams whose box meets its frustum, from memory.
class HoloHitIndex {
public:
    explicit HoloHitIndex(HoloServer& server);
    /// The beams whose hit points' box meets `camera`'s view frustum (in front of the eye,
    /// within the raster's four side planes), in section and beam order; each desired as
    /// many samples as it holds.
    std::vector<BeamRequest> beamsSeenBy(const CameraRays& camera) const;
    /// The stored samples as shaded points of `camera`, chosen as holodeckViewPoints chooses
    /// them, from the beams beamsSeenBy finds. `cancelled` (may be empty), asked between
    /// blocks of work, ends the read early with no points (an edit waits for the tracer).
    std::vector<ShadedPoint> viewPoints(const Discretization& disc, const RayTracer& tracer,
                                        const CameraRays& camera, std::uint64_t frame,
                                        std::uint64_t shading,
                                        const std::function<bool()>& cancelled = {}) const;
    std::size_t beams() const { return mBeams.size(); }
    std::int64_t hits() const { return std::int64_t(mHits.size()); }

private:
    struct Bounds {
        int section = 0;
        std::int64_t beam = 0;
        std::size_t first = 0, count = 0;  ///< its samples in mHits and mSamples
        glm::vec3 lo{0.0f}, hi{0.0f};
    };
    /// The indices in mBeams of the beams whose box meets `camera`'s frustum.
    std::vector<std::size_t> seenBeams(const CameraRays& camera) const;
    /// A view's candidate samples: those of the beams seenBeams finds (holo_view.cpp).
    struct SeenSamples;
    std::vector<HoloSection> mSections;
    std::vector<DistanceCode> mCodes;
    std::vector<Bounds> mBeams;
    std::vector<glm::vec3> mHits;  ///< decoded hit points, misses left out
    /// Their rays' directions, octahedral in two 16-bit numbers (choosing a pixel's sample
    /// prefers those that came from the eye's side).
    std::vector<std::array<std::int16_t, 2>> mDirections;
    std::vector<HoloSample> mSamples;  ///< the samples they are of
};

/// The samples of `view`'s beams (viewRequests, or HoloHitIndex::beamsSeenBy) as shaded points
/// of `camera`. Each sample's stored hit point is projected; per pixel only the nearest depth's
/// samples stand (within 2%: the rest lie behind a surface the pixel sees), and of those the one
/// nearest the pixel's centre is taken (a batch-filled holodeck holds many per pixel; more than
/// one a pixel only crowds the display's cache). The eye's ray towards its stored hit must end
/// on a surface there (within the distance code's resolution), on the side the sample's ray
/// came from, and inside the raster; the point is where that ray ends, with the mean radiance
/// of the pixel's samples of that surface (ShadedPoint::samples of them). Points carry `frame`
/// (InteractiveDisplay::nextFrame(): the frame that shows them trusts them as its own) and
/// `shading` (PointShader::stateSerial) like points shaded now.
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
