#pragma once
// The high-fidelity irradiance mesh (Hardt & Teller 1996 §2, §4): every solution element is
// triangulated — by CGAL's constrained Delaunay triangulation where discontinuities cross it,
// as itself elsewhere (their hybrid quadtree-mesh) — and every triangle carries a quadratic
// irradiance interpolant through six exact samples (ExactIrradiance) at its vertices and edge
// midpoints. Radiosity at a surface point is then E + ρ·R(s, t).
//
// Discontinuities on an element: the VE and EV events of each emitter and the blockers between
// them (§4.1; EEE events are ignored, as in the paper), ranked by the paper's weight
// w = max(d_sb / d_br) · B_src (§4.2) with the k strongest of weight ≥ w_min kept; and contact
// lines, where another surface meets or nearly touches the element (a box on a floor, a lamp
// set into a ceiling), always kept: across them irradiance jumps.
//
// Index: QuadraticInterpolant · HifiOptions · HifiTriangle · HifiStats · HifiMesh

#include <array>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "render/image.h"
#include "solver/scene.h"

namespace penumbra {

class CameraRays;
class Discretization;
class ExactIrradiance;
class RayTracer;

/// R(s, t) = A s² + 2B st + 2C s + D t² + 2E t + F over barycentric (s, t) of a triangle
/// p0, p1, p2 (point p0 + s (p1 − p0) + t (p2 − p0)), stored as the paper stores it:
/// (A, 2B, 2C, D, 2E, F) per colour channel.
struct QuadraticInterpolant {
    std::array<Rgb, 6> c{};
    /// From the samples at (0,0), (½,0), (1,0), (½,½), (0,1), (0,½) — the vertices and edge
    /// midpoints in the paper's order (§2.2's closed form).
    static QuadraticInterpolant fromSamples(const std::array<Rgb, 6>& r);
    Rgb operator()(double s, double t) const {
        return c[0] * (s * s) + c[1] * (s * t) + c[2] * s + c[3] * (t * t) + c[4] * t + c[5];
    }
    /// Irradiance, which is never negative: where the quadratic dips below 0 between its
    /// samples (beside a sharp change it rings), 0.
    Rgb irradiance(double s, double t) const { return glm::max((*this)(s, t), Rgb(0.0)); }
};

struct HifiOptions {
    /// k: the strongest shadow discontinuities kept per element (the paper's setting: 10).
    int maxDiscontinuities = 10;
    /// At most this many segments per element, contact lines (longest first) and shadow
    /// segments (strongest first) together: where many objects meet or cross an element, the
    /// constrained triangulation stays small.
    int maxSegments = 24;
    /// At most this many triangles per element: refinement (level by level over the element)
    /// stops there, and a constrained triangulation with more drops its weaker half of shadow
    /// segments (then the shorter half of the contact lines) until it fits.
    int maxTriangles = 32;
    /// w_min (W/m²): weaker discontinuities are not meshed.
    double minWeight = 1.0;
    /// A surface within this fraction of an element's size (√area) of its plane, in front
    /// of it, touches it: its outline there is a contact line.
    double contactFraction = 0.25;
    /// Representation-error refinement (the paper's §7.2 proposal): a triangle whose
    /// interpolant of the gathered part (ExactIrradiance::Parts) misses it at the triangle's
    /// centre by more than this fraction of the whole irradiance there (plus 1e-4 of the
    /// brightest emitter's luminance) is split into four, up to maxRefineDepth times. 0 turns
    /// it off.
    double refineTolerance = 0.03;
    int maxRefineDepth = 3;
    /// With the far field's rays (ExactIrradianceOptions::farRays): once every sample is
    /// taken, each sample's far field is a local linear fit of its neighbours' on the same
    /// plane (off contact lines) within this many median element sizes (√area), and the
    /// interpolants are fitted to that: the rays' noise averages out over the neighbourhood
    /// instead of freezing into each triangle. This radius serves samples with no other
    /// surface within the near field's reach (the far field is the whole indirect light
    /// there, and smooth); `farFieldNearPoolRadius` those with one, whose far field changes
    /// faster. 0 turns either off. Near another surface (a box's face above the floor, the
    /// strip along a wall's corner) a fit over a strip of such samples leans with the near
    /// field's curvature, so by default those keep their own far field, whose further
    /// passes (farFieldRefineBudget below) hold its noise down instead.
    double farFieldPoolRadius = 2.0;
    double farFieldNearPoolRadius = 0.0;
    /// With the far field's rays and farFieldPoolRadius: the samples the pooling serves (off
    /// contact lines, no other surface within the near field's reach) cast no far-field rays of
    /// their own but `farFieldPreviewRays` for the refinement test's scale. Once every sample
    /// is taken, per plane one such sample in each cell `farFieldRecordSpacing` × the plane's
    /// median element size (√area) wide — a record — casts `farFieldRecordPasses` passes
    /// (farRays, 4 × farRays, ...), and every such sample's far field is the local linear fit
    /// of the records of its plane within farFieldPoolRadius × that size: the far field's rays
    /// go by area, not by sample, so a plane refined finely under shadows (a floor beneath
    /// tessellated meshes) casts no more of them than a plain one. A sample with fewer than 8
    /// records within reach casts its own rays as before. 0 (the default) turns it off; 0.8 is
    /// the setting docs/hifi.md measures.
    double farFieldRecordSpacing = 0.0;
    int farFieldRecordPasses = 2;
    int farFieldPreviewRays = 16;
    /// With the far field's rays: once every sample is taken (before the pooling), the
    /// samples whose far field's estimated standard error exceeds farFieldRefineTolerance of
    /// their whole irradiance — the noise that would show — get the far field's next passes
    /// (ExactIrradiance::refineFarField: 4 ×, then 16 × its rays, with strata twice and four
    /// times as fine), the worst first, up to farFieldRefinePasses passes and within
    /// farFieldRefineBudget × the first passes' rays: the build's cost stays bounded whatever
    /// the scene. 0 turns it off.
    double farFieldRefineTolerance = 0.01;
    double farFieldRefineBudget = 1.0;
    int farFieldRefinePasses = 3;
    /// With the far field's rays and the refit they bring (farFieldPoolRadius or
    /// farFieldRefineBudget set): on an element no contact line touches, only the samples of
    /// its base triangles — the element's own fan, the triangles an element nothing crosses is
    /// meshed into — cast the far field's rays; every other sample there (the vertices and
    /// midpoints of shadow discontinuities' triangles, refinement's midpoints) takes the far
    /// field from the quadratic through its base triangle's six samples, as an element nothing
    /// crosses shows it. The far field is smooth over an element (its sources are at least
    /// the near field's reach away) while shadows split it finely, so the rays follow the
    /// elements, not the discontinuities; the gathered part stays exact at every sample.
    bool farFieldFromBase = true;
    /// Polled once per element: when it returns true the build stops early and the mesh is
    /// left incomplete (HifiStats::cancelled). The editor cancels a build an edit outdates.
    std::function<bool()> cancelled;
};

struct HifiTriangle {
    std::array<Vec3, 3> p;  ///< world space, counter-clockwise seen from the front
    int element = -1;
    QuadraticInterpolant irradiance;
};

struct HifiStats {
    int elements = 0;
    int meshedElements = 0;  ///< elements triangulated around discontinuities
    int triangles = 0;
    int shadowSegments = 0;   ///< kept VE/EV segments
    int contactSegments = 0;  ///< contact lines
    int remeshed = 0;         ///< elements this build meshed (update(): the changed ones)
    int samples = 0;          ///< irradiance evaluations at triangle vertices and midpoints
    int centreSamples = 0;    ///< exact-part evaluations at centres (the refinement test)
    long long farRays = 0;    ///< the far field's rays over all samples (farRays per pass)
    double seconds = 0;
    bool cancelled = false;  ///< HifiOptions::cancelled stopped the build
    /// Triangles dropped inside other objects (with ExactIrradiance's ray tracer).
    int coveredTriangles = 0;
    /// Elements wholly inside another object that bounds a solid (with the ray tracer): no
    /// segments, no triangles, no samples.
    int buriedElements = 0;
    /// Elements whose segments or triangles HifiOptions::maxSegments / maxTriangles cut.
    int cappedElements = 0;
    /// Elements no wider than refinement's finest triangle (diameter at most the diagonal of a
    /// square of 4^−maxRefineDepth of the area-weighted median element's area) and crossed by
    /// no segment: sampled once, at the centroid, with a constant interpolant.
    int singleSampleElements = 0;
    /// Samples whose far field came from their element's base triangles
    /// (HifiOptions::farFieldFromBase), not rays of their own.
    int derivedFarFields = 0;
};

/// Built once for a scene state; rebuild after an edit.
class HifiMesh {
public:
    /// Meshes every alive element and samples each triangle's irradiance with `exact` (which
    /// must hold the solution's reflected light for indirect light). `progress(fraction)` is
    /// called from the calling thread.
    void build(const Discretization& disc, const ExactIrradiance& exact,
               const HifiOptions& options = {}, const std::function<void(double)>& progress = {});

    /// After an edit (§ point 6 of the incremental display): re-meshes and re-samples the
    /// alive elements flagged in `remesh` (hifiRemeshElements) and every element new since
    /// the last build, with `exact` holding the new solution; every other alive element keeps
    /// its triangles, and dead ones lose theirs. The stats count this update's work; `remesh`
    /// may be shorter than the elements (the rest count as unflagged).
    void update(const Discretization& disc, const ExactIrradiance& exact,
                const std::vector<std::uint8_t>& remesh, const HifiOptions& options = {},
                const std::function<void(double)>& progress = {});

    const std::vector<HifiTriangle>& triangles() const { return mTriangles; }
    /// Triangles of element e: triangles()[first(e) .. first(e + 1)).
    int first(int element) const { return mFirst[element]; }
    /// The triangle of `element` containing world point x (its plane's projection), with
    /// barycentrics (s, t); -1 when the element has none.
    int locate(int element, const Vec3& x, double& s, double& t) const;
    /// Radiosity B = E + ρ R(s, t) of a triangle at (s, t), with the element's material (R
    /// clamped at 0: QuadraticInterpolant::irradiance).
    Rgb radiosity(const Discretization& disc, int triangle, double s, double t) const;
    const HifiStats& stats() const { return mStats; }
    std::string toString() const;

private:
    /// Meshes the elements `todo` and assembles the triangles, keeping this mesh's own for the
    /// alive elements `keep` flags.
    void mesh(const Discretization& disc, const ExactIrradiance& exact, const HifiOptions& options,
              const std::function<void(double)>& progress, const std::vector<int>& todo,
              const std::vector<std::uint8_t>& keep);

    std::vector<HifiTriangle> mTriangles;
    std::vector<int> mFirst;  ///< per element, plus one past the end
    HifiStats mStats;
};

/// The elements an edit makes HifiMesh::update re-mesh, given `changedObjects` (the versions
/// the edit added, removed or changed: EditEvent::changed()): those whose radiosity luminance
/// moved from `before` (the solution the mesh was built with) to `after` by more than
/// `threshold` of what it was (dark elements against a floor of 1e-3 of the mean); those
/// crossed by a shadow event (VE/EV) a changed object casts, before or after, of at least
/// options.minWeight (a penumbra can move across an element whose mean light holds); and
/// those within options.contactFraction of their size of a changed object's bounds, where
/// contact lines come and go. A changed emitter moves every event it casts: all are flagged.
/// Elements past `before`'s end are new and flagged; dead ones are flagged (update drops
/// them either way).
std::vector<std::uint8_t> hifiRemeshElements(const Discretization& disc,
                                             const std::vector<Rgb>& before,
                                             const std::vector<Rgb>& after,
                                             const std::vector<int>& changedObjects,
                                             double threshold = 0.01,
                                             const HifiOptions& options = {});

/// The per-pixel pass (§2.6) with the visible triangle and its barycentrics found by one
/// Embree ray per sample: radiance B/π, `samples`² jittered samples per pixel.
Image renderInterpolants(const Discretization& disc, const RayTracer& tracer, const HifiMesh& mesh,
                         const CameraRays& rays, int samples = 1);

/// A discontinuity segment on an element with its weight (w = max(d_sb / d_br) · B_src; contact
/// lines carry infinity).
struct Discontinuity {
    Vec3 a, b;
    double weight = 0;
};

/// How an element's wedges are found: through the bounding-volume hierarchy over the wedges'
/// regions (what builds use), or by testing every wedge in the scene (its reference).
enum class WedgeSearch { Indexed, Every };

/// The VE/EV discontinuities of every emitter on element `e`, clipped to it, strongest first.
std::vector<Discontinuity> shadowDiscontinuities(const Discretization& disc, int element,
                                                 WedgeSearch search = WedgeSearch::Indexed);
/// The contact lines on element `e`, clipped to it.
std::vector<Discontinuity> contactLines(const Discretization& disc, int element,
                                        double contactFraction);

}  // namespace penumbra
