#pragma once
// Exact irradiance at a point (Hardt & Teller 1996 §5, IrradianceAtPoint): for every source
// polygon, the part visible from the point, found by backprojecting the blockers onto the
// source's plane (Drettakis & Fiume 1994) and subtracting them as convex polygons, integrated
// with Lambert's contour formula. Direct light comes from the emitters' emission, indirect
// light from the solution's reflected radiosity (B − E = ρH per element), gathered the same way.
//
// Index: PolygonSet2 · ExactIrradianceOptions · ExactIrradiance

#include <algorithm>
#include <array>
#include <cstdint>
#include <functional>
#include <string>
#include <unordered_map>
#include <vector>

#include "render/box_tree.h"
#include "render/hifi/far_field.h"
#include "solver/progressive_solver.h"
#include "solver/scene.h"

namespace penumbra {

class Discretization;
class RayTracer;

/// A region of a plane as disjoint convex polygons (counter-clockwise): what is left of a
/// convex polygon after convex polygons are subtracted from it, one at a time.
class PolygonSet2 {
public:
    explicit PolygonSet2(std::vector<Vec2> convex);
    /// Removes a convex polygon (either winding). Each piece it overlaps is split into the
    /// parts outside each of its edges' lines in turn, so pieces stay convex and disjoint.
    void subtract(const std::vector<Vec2>& convex);
    const std::vector<std::vector<Vec2>>& pieces() const { return mPieces; }
    bool empty() const { return mPieces.empty(); }
    double area() const;

private:
    std::vector<std::vector<Vec2>> mPieces;
    double mMinArea;  ///< slivers below this (relative to the first polygon) are dropped
};

struct ExactIrradianceOptions {
    /// Gather indirect light from the solution (else direct only).
    bool indirect = true;
    /// A source patch nearer than this many bounding radii (centroid to point) is gathered
    /// element by element with each element's radiosity; farther, as its outline with the
    /// patch's mean radiosity.
    double nearRadii = 3.0;
    /// 0: every patch gathered exactly. N > 0 (with a ray tracer): only the near patches
    /// are; the rest of the hemisphere is sampled by N stratified cosine-distributed rays
    /// (refineFarField adds passes of 4 N, 16 N, ...),
    /// each reading the reflected radiosity of the element it hits (hits on near patches
    /// count nothing, they are in the exact part). The far field is smooth and its share
    /// small, so a few hundred rays keep its noise well under a per cent of the total, at a
    /// cost that does not grow with the number of patches.
    int farRays = 0;
    /// With farRays: an element is gathered exactly when the point is within this many of
    /// its own near radii — its bounding radius, at most 1.5 √area, so a sliver's reach
    /// follows its solid angle (0: every element of a patch within nearRadii). Element by
    /// element, the exact part stays a few sources per point however finely a mesh is
    /// tessellated; a patch-wide near field on a tessellated mesh holds hundreds.
    double nearElementRadii = 2;
    /// With a ray tracer and maxExactBlockers > 0: when more than this many blocker polygons
    /// reach into the pyramid from a point to a source (a finely tessellated mesh between
    /// them, whose shadows would split the source into hundreds of pieces), that source's
    /// visible fraction is estimated by `blockedRays` shadow rays stratified over it instead
    /// (the ratio estimator of formFactorToPatch; the unoccluded part stays exact).
    int maxExactBlockers = 0;
    int blockedRays = 256;
    /// With farRays and nearElementRadii: an element passes from the exact part to the far
    /// field's rays over a band of distances instead of at once — its share in the exact part
    /// falls smoothly from 1 at half its near distance to 0 at it, and the rays that reach it
    /// count the rest — so the split moves no light from one part to the other abruptly as
    /// the point moves, and both parts are continuous functions of it. Off: a hard ball.
    bool smoothFarField = false;
    /// What the interpolants use (`render --mode interpolant`, `export --hifi`, the editor,
    /// `bench hifi`): `farRays` rays for the far field (a first pass, which the build
    /// continues where its error shows: HifiOptions::farFieldRefineBudget) with the smooth
    /// split, sampled visibility past 48 blockers.
    static ExactIrradianceOptions forInterpolants(int farRays) {
        ExactIrradianceOptions o;
        o.farRays = farRays;
        o.maxExactBlockers = 48;
        o.smoothFarField = true;
        return o;
    }
};

/// Thread safety: const functions may be called from any thread. The Discretization must not
/// change while one runs; call rebuild() after it changed (an edit, a subdivision).
class ExactIrradiance {
public:
    /// `tracer` (optional) serves ExactIrradianceOptions::farRays.
    explicit ExactIrradiance(const Discretization& disc, ExactIrradianceOptions options = {},
                             const RayTracer* tracer = nullptr);
    /// Re-reads the alive objects' blockers and emitters.
    void rebuild();
    /// The light the solution reflects, per element (W/m²): B − E, i.e. ρ·H. Without one,
    /// irradiance() is direct light only.
    void setReflected(std::vector<Rgb> reflected);

    /// Form factor from (x, n) to the part of a planar convex `source` polygon
    /// (counter-clockwise seen from its front) that no blocker hides. Blockers of object
    /// `ignoreObject` are left out (-1: none).
    double visibleFormFactor(const Vec3& x, const Vec3& n, const std::vector<Vec3>& source,
                             int ignoreObject = -1) const;
    /// The visible part itself, in world space (pieces of the source's plane).
    std::vector<std::vector<Vec3>> visiblePart(const Vec3& x, const std::vector<Vec3>& source,
                                               int ignoreObject = -1) const;

    /// Irradiance (W/m²) straight from the emitters at x (unit normal n).
    Rgb direct(const Vec3& x, const Vec3& n) const;
    /// Irradiance (W/m²) from the reflected radiosity of every element (0 without
    /// setReflected()).
    Rgb indirect(const Vec3& x, const Vec3& n) const;
    Rgb irradiance(const Vec3& x, const Vec3& n) const {
        return direct(x, n) + (mOptions.indirect ? indirect(x, n) : Rgb(0.0));
    }
    /// Irradiance split by how it is found: `gathered` from sources one by one (the emitters;
    /// every reflecting source without farRays, the near ones with), `farField` the far
    /// field's rays (farRays). The gathered part is exact but for sources seen through more
    /// than maxExactBlockers blockers, whose visibility is sampled with the same points of the
    /// source from every x and so varies smoothly; it is the part to test an interpolant's fit
    /// against.
    struct Parts {
        Rgb gathered{0.0}, farField{0.0};
        /// The form factor of the reflecting sources gathered exactly (weighted by their
        /// share, with farRays): 0 where the far field's rays cover the whole hemisphere, so
        /// that it is the whole indirect light, a smooth function of the point.
        double nearShare = 0;
        /// The part of `gathered` that is reflected light (the near field's).
        Rgb nearIndirect{0.0};
        /// A surface other than the point's own plane lies within the near field's reach (with
        /// farRays and nearElementRadii): there the far field changes fast with the point.
        bool nearSurface = false;
        int farRays = 0;      ///< rays the far field cast
        int farPasses = 0;    ///< in that many passes (estimateFarField)
        double farError = 0;  ///< the far field's estimated standard error (luminance, W/m²)
        /// farField is not this point's own estimate but a fit over neighbouring points' rays
        /// (set by the interpolants' build: HifiOptions::farFieldRecordSpacing).
        bool farFitted = false;
        Rgb total() const { return gathered + farField; }
    };
    /// `withFarField` false leaves the far field's rays out.
    Parts irradianceParts(const Vec3& x, const Vec3& n, bool withFarField = true) const;
    /// Continues the far field of `parts` (irradianceParts at the same x and n) with its next
    /// passes, up to `passes` passes in all whatever their error (the caller chose the point
    /// for its error): farField, farError, farRays and farPasses are updated.
    void refineFarField(const Vec3& x, const Vec3& n, int passes, Parts& parts) const;
    /// A rough look at the far field of `parts` (irradianceParts at the same x and n without
    /// it): farField from one pass of `rays` rays, farRays and farPasses left 0, so that
    /// refineFarField starts the far field's own passes afresh. Returns the rays cast.
    int previewFarField(const Vec3& x, const Vec3& n, int rays, Parts& parts) const;

    std::size_t blockerCount() const { return mBlockers.size(); }
    std::size_t emitterCount() const { return mEmitters.size(); }
    const ExactIrradianceOptions& options() const { return mOptions; }
    /// The ray tracer given at construction (null without one).
    const RayTracer* tracer() const { return mTracer; }
    std::string toString() const;

private:
    struct Blocker {
        std::vector<Vec3> polygon;  ///< convex, world space
        Vec3 normal{0.0};           ///< unit
        Vec3 lo, hi;                ///< bounds
        int object = -1;
    };
    struct ObjectBlockers {
        int first = 0, count = 0;  ///< range in mBlockers
        Vec3 lo, hi;
        int object = -1;
        BoxTree tree;  ///< over the object's blockers, which are stored in its order
    };
    /// Fills mElementCells (nothing without nearElementRadii).
    void buildElementCells();
    struct Source {
        std::vector<Vec3> polygon;  ///< convex, counter-clockwise seen from the front
        Rgb radiosity{0.0};
        int object = -1;
    };
    struct SourcePatch {
        int patch = -1;
        Vec3 centroid{0.0};
        double radius = 0;
        bool convexOutline = false;
    };
    /// Replaces an object's emitter pieces by their union when they lie in one plane with one
    /// emission and tile a convex polygon (a panel lamp's patches): the visible part of one
    /// polygon is the same light as that of its pieces, for one pyramid's blockers instead of
    /// one per piece.
    static void mergeCoplanarEmitters(std::vector<Source>& sources);
    /// The polygons patch `sp` lights x with: its outline when far and convex, else its
    /// elements.
    void addSourcesOfPatch(const SourcePatch& sp, const Vec3& x, std::vector<Source>& out) const;

    bool nearPatch(int patch, const Vec3& x) const;
    bool nearElement(int element, const Vec3& x) const;
    /// An element's share of its light at x that the exact part gathers (nearElementRadii):
    /// 1 or 0 by nearElement, or with smoothFarField 1 within half its near distance, 0 past
    /// it, and a smoothstep between; the far field's rays count the rest.
    double nearElementWeight(int element, const Vec3& x) const;
    /// The patch distance (in its radii) within which a patch may hold near sources.
    double nearPatchRadii() const {
        // An element within k of its radii r_e of x lies in a patch whose centroid is within
        // k·r_e + |c_e − c_p| of x; for convex elements that is at most (4k + 1)/3 patch radii.
        const double k = mOptions.nearElementRadii;
        return k > 0 ? std::max(k + 1, (4 * k + 1) / 3) : mOptions.nearRadii;
    }
    /// visiblePart, giving up (and setting `tooMany`) once more than `maxBlockers` (> 0)
    /// blockers reach into the pyramid.
    std::vector<std::vector<Vec3>> clipVisible(const Vec3& x, const std::vector<Vec3>& source,
                                               int ignoreObject, int maxBlockers,
                                               bool& tooMany) const;
    /// The visible fraction of `source` from (x, n) by stratified shadow rays, weighted by
    /// the point-to-point kernel.
    double sampledVisibleFraction(const Vec3& x, const Vec3& n,
                                  const std::vector<Vec3>& source) const;
    /// The far field's passes at x (estimateFarField, passes of farRays, 4 farRays, ...) up to
    /// `passes` in all, continuing those `parts` holds (none: from the first): farField,
    /// farError, farRays and farPasses are set. `perPass` rays in the first pass (0: farRays).
    void addFarField(const Vec3& x, const Vec3& n, int passes, Parts& parts, int perPass = 0) const;
    /// Form factor to the visible part of `source`; `sampled` set when its visibility was
    /// estimated by rays (past maxExactBlockers).
    double formFactor(const Vec3& x, const Vec3& n, const std::vector<Vec3>& source,
                      int ignoreObject, bool& sampled) const;
    /// Adds radiosity × the visible form factor of `source` to the part it was found by.
    void addSource(const Vec3& x, const Vec3& n, const std::vector<Vec3>& source,
                   const Rgb& radiosity, Parts& parts) const;
    void addDirect(const Vec3& x, const Vec3& n, Parts& parts) const;
    /// The indirect light of the sources gathered one by one (every source without farRays,
    /// the near ones with).
    void addGathered(const Vec3& x, const Vec3& n, Parts& parts) const;
    bool sampledFarField() const { return mOptions.farRays > 0 && mTracer; }

    const Discretization& mDisc;
    ExactIrradianceOptions mOptions;
    const RayTracer* mTracer = nullptr;
    std::vector<Blocker> mBlockers;
    std::vector<ObjectBlockers> mObjects;
    std::vector<Source> mEmitters;
    std::vector<SourcePatch> mPatches;  ///< alive patches (indirect sources)
    /// mPatches indices by grid cell of their centroids (cells of mCellSize, at least the
    /// largest near distance): the near patches of a point are in its 27 cells.
    std::unordered_map<std::uint64_t, std::vector<int>> mPatchCells;
    double mCellSize = 1;
    std::uint64_t cellKey(long long i, long long j, long long k) const;
    std::vector<Rgb> mReflected;  ///< per element
    /// Per element: its bounding radius about the centroid, at most 1.5 √area (the near
    /// field's scale: a sliver's reach follows its solid angle, not its length).
    std::vector<double> mElementRadius;
    /// Per element: its centroid and nearElementRadii × mElementRadius, side by side, so that
    /// testing the elements a point's cell lists reads no more than it needs.
    struct NearBall {
        Vec3 centre{0.0};
        double reach = 0;
    };
    std::vector<NearBall> mNearBall;
    /// Per source element listed in mElementCells: its polygon (elementPolygon), read once.
    std::vector<std::vector<Vec3>> mElementPolygon;
    /// With farRays and nearElementRadii: the source elements by the grid cells their near
    /// balls (nearElementRadii × the element's radius about its centroid) overlap, so a
    /// point's near elements are all in its own cell (cells of mElementCellSize).
    std::unordered_map<std::uint64_t, std::vector<int>> mElementCells;
    double mElementCellSize = 1;
    std::vector<Rgb> mPatchReflected;  ///< per patch, area-weighted mean
    double mEpsilon = 1e-9;            ///< length tolerance, from the scene's size
};

/// Per element, the radiosity the solution reflects: B − E (ρ·H plus the solver's ambient
/// estimate of the light not yet shot, Cohen eq. 13), for ExactIrradiance::setReflected.
std::vector<Rgb> reflectedRadiosity(const Discretization& disc, const ProgressiveSolver& solver);
/// The same from a radiosity per element (a copy the solver published).
std::vector<Rgb> reflectedRadiosity(const Discretization& disc, const std::vector<Rgb>& radiosity);

/// The reflected radiosity of `disc`'s elements from a second solve of `scene` in which every
/// element is its own shooter (as the paper's hierarchical solution links leaf elements),
/// converged to `eps` (at most `maxShots`). A patch shoots its mean radiosity, which at a
/// concave contact (a box on a floor) is not what its elements near the contact send, so a
/// gather from a coarse-patch solution there comes out low. The second solve discretizes
/// `scene` with PatchGrouping::Elements, so its elements are `disc`'s own: each element takes
/// its twin's value (the same face of the object of the same id, at the same place); one with
/// no twin (adaptive subdivision made it) takes the area-weighted mean of the leaf elements
/// that overlap it. `disc`'s own patches stay the gather's source groups. The second solve
/// places its receivers in the open (SolverOptions::placeReceivers): a floor element the foot
/// of a box crosses with its centroid under the box would otherwise send nothing toward the
/// box's face, whose foot it fills half the view of. Returns `solved`'s reflected radiosity
/// when the patches already are the elements and no receiver moves.
std::vector<Rgb> leafReflectedRadiosity(const Scene& scene, const Discretization& disc,
                                        const ProgressiveSolver& solved,
                                        const SolverOptions& options, double eps,
                                        std::uint64_t maxShots);

/// What the leaf solve did (its solver's stats) and the unshot fraction it stopped at.
struct LeafSolveStats {
    SolverStats solver;
    double unshotFraction = 0;
};
/// The same without a solution of `disc` (none is needed: the leaf solve replaces it): the
/// leaf solve always runs, also where it is `disc`'s own (patches already elements). `stats`
/// (optional) receives what the leaf solve did; `progress` is the solver's
/// (ProgressiveSolver::converge).
std::vector<Rgb> leafReflectedRadiosity(const Scene& scene, const Discretization& disc,
                                        const SolverOptions& options, double eps,
                                        std::uint64_t maxShots, LeafSolveStats* stats = nullptr,
                                        const std::function<void(double)>& progress = {});

/// Whether a planar polygon is convex (all turns the same way about `normal`).
bool isConvexPolygon(const std::vector<Vec3>& polygon, const Vec3& normal);

}  // namespace penumbra
