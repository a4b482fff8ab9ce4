#pragma once
// Progressive refinement radiosity (Cohen, Chen, Wallace, Greenberg 1988): shoot from the
// patch with the largest unshot energy ΔB·A, to every element, in interruptible steps; and
// radiosity redistribution (George, Sillion, Greenberg 1990): after an edit, the energy
// already shot is redistributed by F(t) − F(t−1), positive toward added objects and negative
// into their shadows, from a change log that keeps each edit's pending work until done.

#include <cmath>
#include <cstdint>
#include <functional>
#include <memory>
#include <vector>

#include "solver/discretization.h"
#include "solver/edit_event.h"
#include "solver/ray_tracer.h"

namespace penumbra {

struct ChangeEntry;
enum class ChangedObjectsIn;  // solver/form_factor.h
struct Receiver;              // solver/form_factor.h

/// George et al.'s interleaving strategies.
enum class RedistributionStrategy {
    RedistributeFirst,  ///< strategy one: redistribute down to a threshold, then interleave
    Interleave,         ///< strategy two: always shoot whichever carries more energy
};

struct SolverOptions {
    std::uint64_t seed = 1;
    int maxRaysPerPair = 16;       ///< visibility rays for the closest pairs
    /// Discretization::placeReceivers before solving: elements whose centroid a solid resting
    /// on them covers receive at a point in the open. For solves from scratch only (the
    /// interpolants' leaf solve): redistribution's edits keep every receiver where it was,
    /// and a fresh solve of the edited scene would place some elsewhere.
    bool placeReceivers = false;
    double gradientThreshold = 0;  ///< >0: adaptive element subdivision (Cohen §3.4)
    int maxSubdivisionLevel = 2;
    /// Once the strongest shooter carries less than this fraction of the emitted power, all
    /// remaining unshot energy is shot at once stochastically (Monte Carlo rays from the
    /// patches in proportion to ΔB·A, cosine-distributed; unbiased, cost independent of the
    /// element count). 0 turns stochastic shooting off: every shot is deterministic.
    double stochasticBelow = 0;
    /// Rays a stochastic batch of the whole emitted power would cast; a batch of power Φ
    /// casts raysPerEmittedPower × Φ / Φ_emitted rays (at least minStochasticRays).
    double raysPerEmittedPower = 4e6;
    int minStochasticRays = 1024;
    /// Cost of one of the batch's rays in deterministic-shot rays. The switch to the
    /// stochastic tail compares costs, not ray counts: a batch goes first once hitRayCost ×
    /// its rays is below a deterministic shot's mean ray count. A batch ray is a closest-hit
    /// ray (it enters the instance and finds the nearest triangle; an occlusion ray stops at
    /// any hit) and carries its own set-up (shooter, point, direction) and receiving, so it
    /// costs several deterministic rays. The default is the ratio of the two kinds' costs
    /// in the solver on cube-room, where the choice matters most (docs/solver.md); the time
    /// to converge is flat around it.
    double hitRayCost = 3.0;
    /// A stochastic batch (propagation or redistribution) takes the strongest shooters up
    /// to about this many rays; the rest wait for the next batch.
    double maxBatchRays = 2.5e5;
    /// Rays a redistribution batch casts per watt of importance, relative to the emitted
    /// power as raysPerEmittedPower is; 0 uses raysPerEmittedPower. Redistribution rays are
    /// aimed at the changed objects only, so fewer carry the same information.
    double redistributionRaysPerEmittedPower = 0;
    /// Once an edit's pending redistribution is weak (below stochasticBelow), the added
    /// objects' own elements gather it instead of receiving shots: this many stratified
    /// cosine rays per element from its centroid, each returning the shot radiosity of the
    /// pending patch it hits (Σ_j (B_j − ΔB_j) F_ij(t), F(t−1) = 0). 0: shots only.
    int gatherRays = 0;
    /// When > 0, a gather casts about this many rays in all: gatherRays per element, fewer
    /// (down to minGatherRays) when the added objects have many elements, so gathering to a
    /// large addition costs no more than a few shots.
    double gatherRayBudget = 0;
    int minGatherRays = 32;
    /// The gather starts once the edit's strongest pending shooter carries less than this
    /// fraction of the emitted power; 0 uses stochasticBelow.
    double gatherBelow = 0;
    /// > 1: the gather goes in two passes. The first traces, per receiving patch, one stratum
    /// picked at random of each block of gatherCoarseBlock × gatherCoarseBlock strata, each
    /// block from one of the patch's elements in turn, and gives every element of the patch
    /// that estimate (a coarse one, at a fraction of the rays: a patch of many small elements
    /// costs one element's rays), so the added object has its light quickly; the second, once
    /// the edit's strong shooters have shot, traces the other strata and corrects each element
    /// to exactly the one-pass gather. 1: one pass.
    int gatherCoarseBlock = 1;
    /// > 0: a drag preview, once its object has gathered its light, gathers the object's
    /// shadow in the light of the pending shooters that do not emit, casting about this many
    /// rays in all (gatherPreviewShadow), instead of leaving it to those shooters' shots (the
    /// hundreds of weak shooters, which a drag step never finishes). 0: shots only.
    double previewShadowRayBudget = 0;
    RedistributionStrategy strategy = RedistributionStrategy::RedistributeFirst;
    /// Strategy one redistributes first while the most important pending redistribution
    /// carries more than this fraction of the emitted power (0: all of it first).
    double redistributionThreshold = 0;
};

/// The configuration the command line and editor use: deterministic shots for the strong
/// shooters, stochastic shooting for the weak tail (see docs/solver.md for the choice and its
/// error). Plain SolverOptions{} is fully deterministic.
SolverOptions interactiveSolverOptions();

struct SolverStats {
    std::uint64_t shots = 0;
    std::uint64_t rays = 0;
    double seconds = 0;
    std::uint64_t subdivisions = 0;
    std::uint64_t stochasticBatches = 0;  ///< each counts as one shot in `shots`
    /// Rays of the propagation batches (closest-hit queries; the rest of `rays` are
    /// mostly occlusion queries), also counted in `rays`.
    std::uint64_t stochasticRays = 0;
    std::uint64_t redistributionShots = 0;  ///< also counted in `shots`
};

/// How far the solution is from settled (ProgressiveSolver::computeSettling; docs/solver.md
/// "Settling"), per element, in luminance (W/m²); 0 for elements not in the solution.
struct SettlingEstimate {
    /// How much the element's radiosity may still change from the work the solver holds:
    /// unshot energy (positive and negative), pending redistribution, and their
    /// interreflection. 0 once everything has been shot.
    std::vector<double> change;
    /// The standard deviation of the sampling noise the solution holds in the element's
    /// radiosity: every stochastic contribution it received (a propagation or redistribution
    /// batch's hit, a gather's ray) adds its square to the variance, an unbiased bound on the
    /// variance of a sum of independent hits. 0 where only deterministic shots have landed.
    std::vector<double> noise;
    /// The standard deviation of the noise a converged from-scratch solve would hold there
    /// (its stochastic tail, modelled from the element's indirect light): what the reference
    /// the estimate is compared with disagrees by, whatever is left to shoot.
    std::vector<double> referenceNoise;
    /// The interreflection every element shares before its own reflectance (W/m², per
    /// channel): `change` is ρ × (its first-order irradiance change + this), in luminance.
    Rgb interreflected{0.0};
    /// George et al. eq. 7 for `change`: sqrt(Σ change² A / Σ Y² A), Y the current luminance.
    double relativeRms = 0;
    /// The same against the reflected light alone, sqrt(Σ change² A / Σ (Y − E)² A) with E the
    /// element's emission: the lamps' own brightness, which dominates eq. 7's denominator
    /// (on cube-room about fifteen times the walls' part), does not dilute it, so it reads as
    /// the walls' relative change. What the editor's "lighting settled" compares.
    double reflectedRms = 0;
    /// The per-element bound on the change to a converged from-scratch solve: change plus
    /// kNoiseCover standard deviations of the difference of the two solves' noise.
    double bound(std::size_t e) const {
        return change[e] +
               kNoiseCover * std::sqrt(noise[e] * noise[e] + referenceNoise[e] * referenceNoise[e]);
    }
    static constexpr double kNoiseCover = 2.0;
};

/// What the solver is told about an edit. Object indices are Discretization objects
/// (versions): a move removes the old version and adds a new one.
struct SceneChange {
    std::vector<int> removed;  ///< already marked dead in the discretization and tracer
    std::vector<int> added;    ///< already appended, alive, and added to the tracer
};

class ProgressiveSolver {
public:
    /// `disc` and `tracer` must outlive the solver.
    ProgressiveSolver(Discretization& disc, RayTracer& tracer, SolverOptions options = {});
    ~ProgressiveSolver();

    /// Performs up to `maxShots` shots and returns the number done (fewer when no unshot
    /// energy is left). Control returns to the caller after each call.
    int step(int maxShots);

    /// Shoots until unshotFraction() < eps or `maxShots` shots; `progress(fraction)` is
    /// called after each shot when given. Returns the shots done.
    std::uint64_t converge(double eps, std::uint64_t maxShots,
                           const std::function<void(double)>& progress = {});

    /// Σ |ΔB|·A over patches, summed over RGB (W).
    double unshotEnergy() const;
    /// Σ E·A over patches, summed over RGB (W).
    double emittedEnergy() const { return mEmittedEnergy; }
    /// unshotEnergy / emittedEnergy (0 for a scene without emitters).
    double unshotFraction() const;

    /// Element radiosity B (W/m²), including emission.
    const std::vector<Rgb>& radiosity() const { return mElementB; }
    /// Element radiosity for display: B + ρ·Ambient (Cohen eq. 13).
    std::vector<Rgb> displayRadiosity() const;
    /// Cohen eq. 12: R Σ ΔB_j A_j / Σ A_j.
    Rgb ambient() const;
    /// Area-weighted mean of the patch's element radiosities.
    Rgb patchRadiosity(int patch) const;
    const Rgb& unshotRadiosity(int patch) const { return mPatchUnshot[patch]; }

    /// Takes an edit as EditSession made it (the discretization and tracer already changed):
    /// Changed → applyChange (versions added or removed) or changeMaterial (newMaterial), then
    /// setPreview(previewObject()) again while a drag goes on, since the preview was computed
    /// in the scene as it was; DragBegan → applyChange of the origin's removal, setPreview
    /// (origin); PreviewMoved → setPreview(preview); DragEnded → clearPreview, applyChange of
    /// the addition; Solved → nothing. Throws std::invalid_argument for a material change
    /// without newMaterial.
    void apply(const EditEvent& event);
    /// Records an edit (George et al.): removed objects' elements are zeroed and the energy
    /// their patches shot is queued for cancellation; added patches start with their emission
    /// unshot; every patch's already-shot radiosity B − ΔB is queued for redistribution by
    /// F(t) − F(t−1), evaluated in the scene just before and just after this edit, so edits
    /// whose redistribution is interrupted by later edits still converge to the right answer.
    /// `redistribute` false skips the redistribution (a baseline for benchmarks: the old
    /// solution with the object inserted and only new unshot energy propagated).
    void applyChange(const SceneChange& change, bool redistribute = true);
    /// A material edit on an alive object: reflectance changes B by Δρ·H, emission by ΔE; the
    /// correction is unshot radiosity of the object's patches (no redistribution needed).
    void changeMaterial(int object, const Material& material);
    /// Estimated power (W) still to redistribute over all pending edits.
    double pendingRedistribution() const;
    /// Edits whose redistribution is not finished.
    std::size_t pendingChanges() const;
    /// unshotFraction() ≤ eps and no redistribution pending.
    bool converged(double eps) const;
    /// Per element, how much its radiosity can still change (SettlingEstimate), from the
    /// unshot energy, the pending redistribution and unoccluded form factors; it traces rays
    /// only against the changed objects of pending edits, toward their strongest shooters,
    /// never in the scene. O(elements × (strong shooters + pending edits)).
    SettlingEstimate computeSettling() const;
    /// relativeRms and reflectedRms alone (change and noise empty). With more than
    /// kSettlingSummaryFullBelow alive elements, from a stratified sample of about one element
    /// in kSettlingSummaryStride of each object, each standing for its share of the object's
    /// area: the sums are area integrals of a field that varies smoothly over large surfaces,
    /// so the sample costs about 1/stride of the full pass and reads within a few percent of
    /// it. Below, the full pass (a small scene's change can sit on a handful of elements, and
    /// the pass is cheap). What `replay` reports per edit.
    SettlingEstimate computeSettlingSummary() const;
    static constexpr int kSettlingSummaryStride = 8;
    static constexpr std::size_t kSettlingSummaryFullBelow = 16384;

    /// Drag preview (George et al.: "while the object is selected, radiosity that is
    /// redistributed to adjust for changes of the object is stored separately, added to the
    /// radiosity solution only at display time, and erased if the object is changed again").
    /// `object` is a dead object version present in the tracer (the dragged object at its
    /// current position); the previous buffer is discarded.
    void setPreview(int object);
    /// Up to `maxShots` preview shots (the object's own emission first, then redistribution
    /// from the most important shooters) into the temporary buffer. Returns the shots done.
    int stepPreview(int maxShots);
    void clearPreview();
    int previewObject() const;
    /// Every shooter's light has reached the previewed object (its gather ran, or nothing is
    /// left to shoot): previewRadiosity() holds its whole indirect light, less sampling
    /// noise. Before, the object has only the strongest shooters' light.
    bool previewComplete() const;
    /// The temporary buffer: per element radiosity added for display only.
    const std::vector<Rgb>& previewRadiosity() const;
    /// The part of previewRadiosity() straight from emission (irradianceFromEmission's
    /// bookkeeping for the buffer; the previewed object's own emission included).
    const std::vector<Rgb>& previewRadiosityFromEmission() const;

    /// Element irradiance H (W/m²) received so far: B = E + ρ·H.
    const std::vector<Rgb>& irradiance() const { return mElementH; }
    /// The part of irradiance() that came straight from emission: what the emitters' E sent
    /// (shots, batches and redistribution split each shooter's radiosity into its emitted
    /// and reflected shares). H − this is the light reflected at least once, whatever order
    /// the shooters went in: a display that computes direct light itself takes its indirect
    /// part from the difference without waiting for the emitters' redistribution.
    const std::vector<Rgb>& irradianceFromEmission() const { return mElementHEmission; }

    /// Irradiance H (W/m²) arriving at point x with unit normal n, gathered from every
    /// patch's current radiosity with `rays` visibility rays per patch.
    Rgb irradianceAt(const Vec3& x, const Vec3& n, int rays = 16) const;

    const SolverStats& stats() const { return mStats; }
    const SolverOptions& options() const { return mOptions; }
    /// Switches George et al.'s interleaving strategy and strategy one's threshold between
    /// steps (the editor's solver panel). Pending work is kept; only the order changes.
    void setStrategy(RedistributionStrategy strategy, double redistributionThreshold);
    const Discretization& discretization() const { return mDisc; }

private:
    /// computeSettling's pass over `receivers` (alive elements), each standing for its area
    /// times weights[k] in the sums; change and noise per element only when perElement.
    SettlingEstimate estimateSettling(const std::vector<int>& receivers,
                                      const std::vector<double>& weights, bool perElement) const;

    struct Impl;
    void shootPatch(int patch);
    void initialize();
    /// Irradiance element `e` receives when `shooter` shoots radiosity dB, with F evaluated
    /// under `visibility`.
    /// `rays`, when given, is increased by the rays traced.
    Rgb irradianceFrom(int shooter, int e, const Rgb& dB, const Visibility& visibility = {},
                       int* rays = nullptr) const;
    /// False for pairs that cannot exchange light under `visibility` (irradianceFrom's culls:
    /// the shooter's own elements, receivers absent, either side behind the other).
    bool mayReceive(int shooter, int e, const Visibility& visibility) const;
    /// dB · (F(after) − F(before)) for the receiver r (an element of patch `receiverPatch`,
    /// its receiving point, normal and index as key) and `shooter`, tracing the worlds only for
    /// samples that meet an object `changed` admits (formFactorChange; `where` says which
    /// world holds the changed objects).
    Rgb irradianceChange(int shooter, int receiverPatch, const Receiver& r, const Rgb& dB,
                         const Visibility& before, const Visibility& after,
                         const Visibility& changed, ChangedObjectsIn where) const;
    /// Adds irradiance dH to element e (B += ρ dH) and its share to its patch's unshot;
    /// `emissionShare` (per channel) of dH came straight from emission.
    void receive(int e, const Rgb& dH, const Rgb& emissionShare = Rgb(0.0));
    /// receive() for an element whose patch and area the caller has at hand.
    void receive(int e, int patch, double area, const Rgb& dH, const Rgb& emissionShare);
    void updatePriority(int patch);
    /// Marks the patch of element e for one heap update in updateTouchedPriorities().
    void touchElement(int e);
    void updateTouchedPriorities();
    /// One element's share of a stochastic batch: irradiance for `element` of `patch`
    /// (element -1: nothing).
    struct Received {
        int element = -1;
        int patch = -1;   ///< the element's patch
        double area = 0;  ///< the element's area (from the hit's record: no element lookup)
        Rgb irradiance{0.0};
        int shooter = 0;  ///< index of its shooter's emission share in receiveAll's `shares`
    };
    /// receive() and touchElement() for every entry in list order, then the heap updates;
    /// parallel over blocks of patches with every sum in list order (bit-identical to the
    /// serial loop, independent of the thread count). `shares[r.shooter]` is the emission
    /// share of entry r's irradiance.
    void receiveAll(const std::vector<Received>& list, const std::vector<Rgb>& shares);
    /// Whether the next propagation shot (strongest shooter carrying `propagation` W) is a
    /// stochastic batch rather than a deterministic shot.
    bool shootsStochastically(double propagation) const;
    void ensureSizes();
    void recomputeEmitted();
    /// One redistribution shot from the most important pending shooter of the most
    /// important pending edit, or the second pass of its gather when that goes next. Returns
    /// false when it shot nothing: nothing is pending, or only a gather's second pass ran.
    bool shootRedistribution();
    /// All of entry k's remaining (weak) redistribution at once, on rays.
    void shootRedistributionBatch(int k);
    /// The change-log entry for `change`: worlds, shot snapshot, importance ranking.
    ChangeEntry makeChangeEntry(const SceneChange& change) const;
    /// Builds entry's before and after worlds as instance scenes (no history filter).
    void buildWorldScenes(ChangeEntry& entry) const;
    /// Irradiance each element receives when shooter j of entry c redistributes: every
    /// receiver it still owes, or with `addedOnly` only the added objects' elements (an
    /// emitter's light on them, ahead of its shadows: dueAddedFirst).
    void redistributionDelta(const ChangeEntry& c, int j, bool preview, std::vector<Rgb>& delta,
                             bool addedOnly = false) const;
    /// The emitters of entry c whose light on the added objects goes next, ahead of every full
    /// shot (ChangeEntry::addedFirst): those still pending, due a deterministic shot and not
    /// yet sent to them, most important first.
    std::vector<int> dueAddedFirst(const ChangeEntry& c) const;
    /// Whether entry c's world after the edit is the current scene (no later edit, no
    /// preview): its queries can skip the history filter.
    bool afterIsCurrentScene(const ChangeEntry& c, bool preview) const;
    /// Entry c's redistribution toward the added objects' elements, gathered
    /// (SolverOptions::gatherRays) from every shooter still pending, which is then marked
    /// `gathered` so its later shots skip those receivers. Writes irradiance per element.
    void gatherToAdded(ChangeEntry& c, bool preview, std::vector<Rgb>& delta);
    /// Whether entry c, whose strongest pending shooter carries `best` W, gathers next.
    bool shouldGather(const ChangeEntry& c, double best) const;
    /// Whether entry c's gather has a second pass pending that goes next (its strongest
    /// pending shooter carries `best` W: weak enough for the stochastic tail, or none left).
    bool shouldRefineGather(const ChangeEntry& c, double best) const;
    /// The second pass of entry c's gather (SolverOptions::gatherCoarseBlock): the strata the
    /// first pass left, and per element the correction from the first pass's estimate to the
    /// whole gather's. Writes irradiance per element.
    void refineGather(ChangeEntry& c, bool preview, std::vector<Rgb>& delta);
    /// A preview's shadow in the light of the pending shooters that do not emit, gathered in
    /// one pass instead of their shots (SolverOptions::previewShadowRayBudget): every element
    /// near the previewed object samples its bounding sphere's cone (the hemisphere, inside
    /// the sphere); where the ray meets the object, the element loses the shot radiosity of
    /// the pending patch the ray meets without it and gains the object's reflected radiosity.
    /// Those shooters are then done (their light on elements far from the object, where it
    /// subtends little, is left out). Writes per element the change of irradiance from the
    /// buffer's current state: the gathered shadow less the one carried from the drag's last
    /// position (setPreview).
    void gatherPreviewShadow(ChangeEntry& c, std::vector<Rgb>& delta);
    /// No gathered preview shadow to carry to the next preview (a drag begins or ends).
    void forgetPreviewShadow();
    /// The last gathered preview shadow moved with the object to version `object` (same
    /// elements): each receiver near it takes the gathered value where the object's motion
    /// since the gather brings it from (the surface found along the receiver's normal).
    std::vector<Rgb> movedPreviewShadow(const ChangeEntry& c, int object) const;
    /// Best pending redistribution importance (W), and which edit holds it.
    double bestRedistribution(int* entry) const;
    void subdivideSteepElements();
    /// Σ_j (B_j − ΔB_j) F(e ← j): the irradiance element e received from everything shot.
    Rgb gatherShotIrradiance(int element) const;
    /// Shoots all remaining unshot energy at once on rays (the weak tail).
    void shootStochasticBatch();

    Discretization& mDisc;
    RayTracer& mTracer;
    SolverOptions mOptions;
    std::vector<Rgb> mElementB;
    std::vector<Rgb> mElementH;
    std::vector<Rgb> mElementHEmission;  ///< the part of mElementH straight from emission
    std::vector<Rgb> mPatchUnshot;
    std::vector<Rgb> mPatchUnshotEmission;  ///< the part of mPatchUnshot that is emission
    double mEmittedEnergy = 0;
    SolverStats mStats;
    std::unique_ptr<Impl> mImpl;
};

}  // namespace penumbra
