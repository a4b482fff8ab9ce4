#pragma once
// The interactive display of Bala, Walter, Greenberg 2003 (§3, Figure 2): one owner that wires
// the point shader (render/display/point_shader.h), the render cache
// (render/display/render_cache.h), the edge finder (render/display/edge_finder.h) and the
// edge-and-point image (render/display/edge_point_image.h) into frames, and tells them about edits.
//
// Index: DisplayStageTimes · DisplayFrameStats · InteractiveDisplayOptions · SolutionView ·
//        InteractiveDisplay (frames, warm-up, edits and solution updates, reference and error) ·
//        projectEdges · imageRmse
//
// One frame (renderFrame):
//   1. shaded points: synchronous mode inserts the points shaded at the end of the previous
//      frame (already in the cache); asynchronous mode takes whatever the workers finished;
//   2. the cache reprojects its points to the frame's camera (visible ScreenPoints), less those
//      behind an object that moved in front of them (hideOccluded);
//   3. edges: silhouettes and forward-facing sharp edges from the eye (per frame), shadow edges
//      (kept, recomputed only after an edit), clipped to the near plane and projected;
//   4. EdgePointImage::build + reconstruct(useEdges) (useEdges false: the render-cache baseline
//      "cache" from the same points); pixels no point reached (holes) from a one-ray fallback;
//   5. new sample requests (a fraction of the pixels, default 2%) from the cache's priority image;
//      synchronous mode shades them at once (oneTBB, deterministic in the requests) and inserts
//      them so they appear in the next frame; asynchronous mode submits them to the workers.
//
// Frame times: `totalMs` is the display pipeline (steps 1–5 without the shading), the paper's
// "Total" of Table 2 with the shader in another process; `shadeMs` is the synchronous shading
// of the frame's requests on the same cores (0 in asynchronous mode).

#include <array>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <unordered_set>
#include <utility>
#include <vector>

#include "render/camera_rays.h"
#include "render/display/edge_finder.h"
#include "render/display/edge_point_image.h"
#include "render/display/point_shader.h"
#include "render/display/render_cache.h"
#include "render/image.h"
#include "solver/progressive_solver.h"
#include "solver/scene.h"

namespace penumbra {

class Discretization;
class RayTracer;

/// Milliseconds per stage of one frame, the columns of Bala et al. Table 2.
struct DisplayStageTimes {
    double findEdgesMs = 0;      ///< silhouettes + sharp edges + shadow edges (+ projection)
    double silhouetteMs = 0;     ///<   of which silhouettes and sharp edges (edge trees)
    double shadowMs = 0;         ///<   of which shadow edges (0 when the cached ones were reused)
    double projectMs = 0;        ///<   of which near-plane clipping and projection
    double rasterizeMs = 0;      ///< EPI: depth filter, edge rasterization, classification
    double pointsMs = 0;         ///< cache insert + reprojection + EPI point placement
    double relightMs = 0;        ///<   of which relighting after a preview's estimate
    double hideMs = 0;           ///<   of which hiding the points behind a moving object
    double shadowDropMs = 0;     ///<   of which dropping the points a drag's move shadowed
    double shadowReshadeMs = 0;  ///<     of which re-shading some of them in the frame
    double insertMs = 0;         ///<   of which inserting the shaded points
    double reprojectMs = 0;      ///<   of which the reprojection (RenderCache::reproject)
    double reachabilityMs = 0;   ///< §5.2
    double interpolateMs = 0;    ///< §5.3
    double antiAliasMs = 0;      ///< §5.3
    double complexFilterMs = 0;  ///< §5.4
    double smoothMs = 0;         ///< edge-free smoothing (EpiOptions::smoothRadius)
    double fillMs = 0;           ///< the fallback for pixels no point reached (holes)
    double requestMs = 0;        ///< drawing the new sample requests from the priority image
    double totalMs = 0;          ///< the whole frame without synchronous shading
    double shadeMs = 0;          ///< synchronous shading of this frame's requests
    /// Reachability + interpolation + anti-aliasing (DESIGN.md "reconstruct_ms").
    double reconstructMs() const { return reachabilityMs + interpolateMs + antiAliasMs; }
    std::string toString() const;
};

struct DisplayFrameStats {
    std::uint64_t frame = 0;  ///< the render cache's frame number
    DisplayStageTimes times;
    std::size_t silhouetteEdges = 0;  ///< world edges found this frame
    std::size_t sharpEdges = 0;
    std::size_t shadowEdges = 0;
    std::size_t screenEdges =
        0;  ///< after near-plane clipping, less those that cannot mark the EPI
    std::size_t visiblePoints = 0;
    std::size_t newSamples = 0;        ///< points inserted for this frame (shaded since last)
    double newSampleFraction = 0;      ///< newSamples / pixels
    std::size_t requestedSamples = 0;  ///< requests made at the end of this frame
    /// Points dropped at this frame's start: in the old or new shadow volume of a dragged
    /// object (their view of a lamp changed).
    std::size_t droppedShadowed = 0;
    std::size_t emptyPixels = 0, simplePixels = 0, complexPixels = 0;
    /// Pixels no cached point reached (EdgePointImage::holes): shown from the fallback
    /// (InteractiveDisplayOptions::fillHoles), else black.
    std::size_t unsampledPixels = 0;
    /// Pixels shown without any value: the holes when the fallback is off, else 0.
    std::size_t unfilledPixels = 0;
    /// Pixels the frame rebuilt and reconstructed: the raster's, or with
    /// InteractiveDisplayOptions::windowedFrames the window its changes reach (0: nothing
    /// changed, the last image again).
    std::size_t reconstructedPixels = 0;
    /// Pixels the render cache's reprojection redid (RenderCache::lastReprojectedPixels: the
    /// raster's, or with a still camera those its changed points reach).
    std::size_t reprojectedPixels = 0;
    bool usedEdges = true;
    std::string toString() const;
};

/// PointShaderOptions as the display uses them by default: clampNegative off. A point's
/// direct light is Lambert's exact unoccluded part less a sampled blocked part, which
/// scatters about the truth and below 0 in umbrae; clamping each point there biased every
/// shadow upward once the points were averaged (armadillo-field, where the indirect light is
/// weak: +0.02–0.04 in display units within 8 pixels of a shadow edge, against the
/// converged reference). The frame is clamped instead, after the reconstruction.
inline PointShaderOptions displayShaderOptions() {
    PointShaderOptions o;
    o.clampNegative = false;
    // The display's edge finder finds its shadow events from the lights and blockers
    // themselves; recording who blocked each shadow ray cost a closest hit per blocked ray.
    o.recordTriples = false;
    return o;
}

/// EpiOptions as the display uses them by default: edge-free smoothing of radius 6 for the
/// pixels without a point of their own (the sparse points of wide walls need the larger
/// boxes), and own points shown through the filters (ownPointPrior 4: exact ones wholly, a
/// noisy mean by its samples), so a still view converges to every pixel's own shading. The
/// dense-region mean (denseComplexLimit) stays off: it averaged the pixels of fine meshes'
/// silhouettes and facets with their neighbours, which own points resolve (docs/display.md
/// has the figures).
inline EpiOptions displayEpiOptions() {
    EpiOptions o;
    o.smoothRadius = 6;
    o.ownPointPrior = 4;
    return o;
}

/// RenderCacheOptions as the display uses them by default: a pixel's samples merge into a
/// mean of up to 32 (RenderCacheOptions::mergeSamples).
inline RenderCacheOptions displayCacheOptions() {
    RenderCacheOptions o;
    o.mergeSamples = 32;
    return o;
}

struct InteractiveDisplayOptions {
    int width = 512;
    int height = 512;
    /// New samples per frame as a fraction of the pixels (Bala et al.: 1–3%).
    double sampleFraction = 0.02;
    /// Up to this fraction of the pixels more per frame for pixels whose point an edit made
    /// stale or carried (RenderCache::requestSamples): the region an edit changed catches up
    /// in a second or two instead of at the base rate. The editor's asynchronous display has
    /// shader capacity to spare for it; 0 (the default) keeps synchronous output unchanged.
    double changedSampleFraction = 0;
    /// A drag's move drops the points whose view of a lamp it changed (the object's old and new
    /// shadow volumes) at the next frame; false keeps them with the element-level estimate of
    /// the change (PointShader's preview job) until they are re-shaded.
    bool followShadows = true;
    /// An element's points are tested against the shadow volumes when the move changed the
    /// share of the lamps' light it receives by more than this at its centre or a corner; on
    /// the other elements the points keep their element's change of direct light (constant
    /// over the element: blocks in a soft shadow's penumbra, up to this share of the light).
    double shadowDropChange = 0.03;
    /// Of the pixels a move emptied (the dropped points', and those the object uncovered), one
    /// in each square of shadowReshadeCell² is re-shaded at once, in the frame (synchronously,
    /// oneTBB), so the frame shows the shadow where the object is from sparse points and the
    /// shadow's edges; the asynchronous shader fills the rest. 0: none at once (the region
    /// waits for the shader, shown from the fallback).
    int shadowReshadeCell = 5;
    /// At most this many re-shaded at once (larger cells beyond): the frame's cost.
    int shadowReshadeMax = 2000;
    /// The drop tests only the elements that some shaft to a lamp can reach the moved object
    /// from (a test per element and lamp); false tests every element's probe points, the
    /// reference the culled drop must equal.
    bool shadowDropCull = true;
    /// Lighting changes from drag positions (apply(EditEvent) of PreviewMoved) and published
    /// solutions (apply(SolutionView)) are relit once, at the next frame's start, instead of
    /// at each: a drag's positions and the solver's lighting arrive several times a frame, and
    /// each relight is a pass over every element and every cached point. The points end with
    /// the same colours (the changes add up); an element whose change crossed the stale
    /// threshold only between two frames is not marked stale. Their apply() then returns the
    /// points carried only. Structural edits (added, removed, dropped objects) relight at once.
    bool deferRelight = false;
    /// With the camera as in the last frame, a frame rebuilds and reconstructs only the
    /// window of pixels its changes reach (EdgePointImage::reconstructWindow): the pixels
    /// whose point or edges differ from what the last frames reconstructed, grown by the
    /// reconstruction's reach. A drag's frames then cost in proportion to the region the object
    /// and its shadows cover, and a still frame in which nothing changed costs nothing. false:
    /// every frame whole (the reference a windowed frame equals when windowColourTolerance is
    /// 0).
    bool windowedFrames = false;
    /// A point whose colour moved by at most this fraction of its value since its pixel was
    /// last reconstructed does not count as changed (the solver's light settling by fractions
    /// of a percent everywhere would make every frame whole); its pixel shows the change when
    /// next reconstructed. 0: every change counts.
    double windowColourTolerance = 0.005;
    /// A window larger than this share of the raster is reconstructed whole.
    double windowMaxShare = 0.6;
    /// While an object is dragged (a preview shown), new samples go only to the pixels the
    /// drag changed (RenderCache::setRequestChangedOnly: empty, stale or carried ones); the
    /// rest of the picture, at rest before the drag, is refined again after the drop.
    bool dragSamplesChangedOnly = false;
    /// A pixel whose own point is exact or the mean of the cache's mergeSamples samples (and
    /// fresh, shaded for this view) is not sampled again (RenderCache::setRequestConverged):
    /// a still view stops once every pixel has converged, and then costs next to nothing (with
    /// windowedFrames, frames in which nothing changed reconstruct nothing). Until its lighting
    /// or the view changes; false: the priority image samples every pixel forever.
    bool restWhenConverged = false;
    /// Synchronous: every frame's requests are shaded before renderFrame returns and appear in
    /// the next frame; output depends only on the inputs (CLI, tests, benchmarks).
    /// Asynchronous: requests go to the shader's worker threads; each frame takes what is done.
    bool synchronous = true;
    /// Render cache capacity as a multiple of the pixel count. Every cached point is
    /// reprojected every frame, so once the cache is full the points stage grows with it;
    /// the points beyond about 1.5 per pixel are hidden or off-screen ones from earlier views
    /// and do not improve the picture (docs/display.md has the figures). Bala et al. give the
    /// points ~9 MB, the Render Cache's size.
    double cacheCapacityPerPixel = 1.5;
    /// Near-plane distance (metres along the view axis) edges are clipped against.
    double nearPlane = 1e-3;
    bool shadowEdges = true;  ///< find shadow edges (silhouettes and sharp edges always)
    /// Pixels no cached point reaches (after a move, where an object was, or a new view) are
    /// shown from a cheap exact fallback rather than black: one primary ray in the displayed
    /// world and the solution's irradiance blended per vertex (PointShader::shadeFallback, the
    /// Gouraud view's shading). They keep the highest sampling priority, so points replace it.
    bool fillHoles = true;
    /// A soft shadow edge (an area light's umbral or penumbral event) marks the EPI only where
    /// its penumbra is at most this many pixels wide at one of its ends (≤ 0: every shadow
    /// edge marks, as in the paper). The width is measured as if the receiver faced the
    /// camera: a grazing view narrows a penumbra on screen, and that is not corrected. Across a
    /// wide penumbra the radiance is continuous (a D1 discontinuity, Heckbert 1992) and varies over
    /// many pixels, so the edge would only stop the interpolation and the smoothing from averaging
    /// the points' noise; narrow ones (a small light, or near contact: the "hardening" of Bala et
    /// al. Figure 9) stay edges.
    double maxPenumbraPixels = 2;
    /// After a solution update or an edit, cached points on elements whose shading (E + ρ·H,
    /// luminance) changed by more than this fraction of the element's value, or of 1% of the
    /// mean, are dropped (Bala et al. §7.5: invalidate samples whose lighting changed).
    double invalidateThreshold = 0.02;
    /// At most this many requests wait in the asynchronous shader's queue; a frame asks for
    /// no more than fit.
    std::size_t maxPendingPerFrame = 4;
    /// threads are forced to 0 in synchronous mode. The display's points are not clamped at
    /// 0 (displayShaderOptions): their noise averages out in the reconstruction, and the
    /// frame is clamped at 0 after it.
    PointShaderOptions shader = displayShaderOptions();
    RenderCacheOptions cache = displayCacheOptions();
    EdgeFinderOptions edges;
    /// The display's EPI: the paper's, plus edge-free smoothing of radius 6
    /// (EpiOptions::smoothRadius).
    EpiOptions epi = displayEpiOptions();
    /// While the camera moves (a frame whose camera differs from the last frame's), complex
    /// pixels with at least this many complex pixels in their 3×3 keep their estimate
    /// instead of going through the subpixel filter (EpiOptions::denseComplexLimit for that
    /// frame). The filter costs about a microsecond a complex pixel, and dense clusters of
    /// them (fine meshes' far silhouettes) are where it gains least; a still camera's frames,
    /// from the first after the camera stops, filter every complex pixel. 0: every frame
    /// filters as `epi` says.
    int movingDenseComplexLimit = 3;
    std::string toString() const;
};

/// How renderConvergedReference shades: far less noise than renderReference, at many times
/// its cost (a reference for error figures, not for display).
struct ConvergedReferenceOptions {
    std::uint64_t seed = 1;      ///< sub-pixel jitter and shadow patterns (two seeds: its noise)
    int samplesPerAxis = 2;      ///< jittered sub-pixel samples per axis everywhere
    int edgeSamplesPerAxis = 8;  ///< jittered sub-pixel samples per axis on edge pixels
    /// A pixel is an edge pixel when its samples' displayed values (sRGB, clipped to [0, 1])
    /// spread by more than this in some channel, or when the last EPI (same size) marks it
    /// simple or complex and useEpiEdges.
    double edgeSpread = 0.04;
    bool useEpiEdges = true;
    /// Detail above white (an emitter's outline): a pixel with samples above white and below
    /// it, and a pixel beside one with a sample above white, take this many per axis instead.
    /// A sliver of a lamp that a pixel's first samples miss still lights it well past white,
    /// and each sample that meets the lamp weighs the lamp's radiance, many times white.
    int brightEdgeSamplesPerAxis = 32;
    /// Shadow sampling of the reference's shader (PointShaderOptions' fields); no clamping of
    /// negative estimates, so the per-pixel means stay unbiased.
    int maxStrataPerAxis = 4;
    int shadowRefine = 4;
    int shadowMaxRefinedPerAxis = 16;
    int shadowDecisionPerAxis = 4;
    std::string toString() const;
};

/// Shadow edges in order of their narrower penumbra, for projectEpiEdges' penumbra test:
/// bucket k ≥ 2 holds the edges with min(penumbraA, penumbraB) in [2^(k−32), 2^(k−31)) (the
/// last one everything wider), bucket 0 those with a zero, non-finite or non-finite-ended
/// one (always projected), bucket 1 the narrower rest.
struct PenumbraOrder {
    static constexpr int kBuckets = 64;
    std::array<std::size_t, kBuckets + 1> start{};  ///< bucket k is [start[k], start[k + 1])
    Box3 bounds;                                    ///< every finite endpoint of the bucketed edges
};

/// The solver's lighting as the display takes it: views of the solver's arrays or of copies
/// of them, read only during apply(). (What PointShader::updateSolution's overloads take.)
struct SolutionView {
    const std::vector<Rgb>* irradiance = nullptr;    ///< required: ProgressiveSolver::irradiance()
    const std::vector<Rgb>* fromEmission = nullptr;  ///< required: its irradianceFromEmission()
    /// While the solver previews: its previewRadiosity() and previewRadiosityFromEmission()
    /// (null: none), previewObject() and previewComplete().
    const std::vector<Rgb>* previewRadiosity = nullptr;
    const std::vector<Rgb>* previewFromEmission = nullptr;
    int previewObject = -1;
    bool previewComplete = false;
    /// Views of `solver`'s own arrays (irradiance(), irradianceFromEmission(), and while it
    /// previews, previewRadiosity(), previewRadiosityFromEmission(), previewObject(),
    /// previewComplete()).
    static SolutionView of(const ProgressiveSolver& solver);
};

/// The display for one Discretization/RayTracer and the ProgressiveSolver over them. Not
/// thread-safe: call everything from one (the render) thread. The display changes only through
/// apply() (edits and new lighting) and the frame calls. In asynchronous mode, the
/// Discretization and RayTracer may only change while the shader is paused: hold
/// `PointShader::Pause pause(display.shader());` around the edit and apply() its event before
/// the pause ends.
class InteractiveDisplay {
public:
    /// `disc`, `tracer` must outlive the display; `solverOptions` are the options of the solver
    /// whose solution is displayed (PointShader reproduces its form factors). Builds the edge
    /// trees (EdgeFinder over `disc`), the cache and the EPI; direct lighting only until
    /// apply(SolutionView). Throws std::invalid_argument for a non-positive size.
    InteractiveDisplay(const Discretization& disc, const RayTracer& tracer,
                       const SolverOptions& solverOptions, InteractiveDisplayOptions options = {});
    /// A display of another size (`options`) over `source`'s scene that takes its edge finder,
    /// lights, H_direct, solution snapshot and preview (PointShader::copyDirectFrom) instead
    /// of building them: milliseconds instead of seconds. `source` must not change meanwhile
    /// (same thread; its shader's workers may run). Empty cache.
    InteractiveDisplay(const InteractiveDisplay& source, InteractiveDisplayOptions options);
    ~InteractiveDisplay();
    InteractiveDisplay(const InteractiveDisplay&) = delete;
    InteractiveDisplay& operator=(const InteractiveDisplay&) = delete;

    // -- Frames --------------------------------------------------------------------------------

    /// Renders one frame from `camera` (its raster must be width() × height()); `useEdges`
    /// false reconstructs without edges (the render-cache baseline, same points). Returns the
    /// reconstructed radiance (W/m²/sr, linear). Throws std::invalid_argument on a size
    /// mismatch.
    Image renderFrame(const CameraRays& camera, bool useEdges = true);
    /// renderFrame in its three steps, for a caller that lets edits in while the image is
    /// reconstructed (the editor's render thread: an edit waits for a step, not a frame).
    /// beginFrame (steps 1–3: points, hiding, edges) and finishFrame (holes filled, requests;
    /// the stats of lastFrame()) read the structure and the cache like renderFrame and must not
    /// overlap an edit; reconstructFrame (step 4, the EPI's own arrays) may: apply() never
    /// touches the EPI. Call them in order, one frame at a time.
    /// finishFrame fills the holes in the world beginFrame saw (the preview where the frame's
    /// points show it), not where edits between the steps moved it: framePreview() is that
    /// preview's version until finishFrame returns, and its subset must stay alive meanwhile.
    void beginFrame(const CameraRays& camera, bool useEdges = true);
    Image reconstructFrame();
    void finishFrame(const CameraRays& camera, Image& image);
    /// The preview version of the frame begun and not yet finished, -1 for none.
    int framePreview() const { return mFrameShading.previewObject(); }
    /// Reconstructs the last frame's EPI again without finding edges or requesting samples:
    /// `useEdges` true or false on exactly the same points and edges (for epi vs cache).
    Image reconstructLast(bool useEdges);
    /// The last frame's pixel classification (EdgePointImage::classificationImage: empty black,
    /// with a point dark grey, simple purple, complex green).
    Image edgeImage() const { return mEpi.classificationImage(); }
    const DisplayFrameStats& lastFrame() const { return mLast; }
    /// The last frame's projected edges.
    const std::vector<ScreenEdge>& screenEdges() const { return mScreenEdges; }

    /// Fills the cache from `camera` before the first frame: shades one point in each cell of a
    /// regular grid over the image whose cells hold 1/density pixels (density 1: every pixel;
    /// 0.25: every other pixel in x and y), jittered inside its pixel, deterministic. Always
    /// synchronous (shades on the calling thread with oneTBB). Returns the points shaded.
    std::size_t warmUp(const CameraRays& camera, double density = 0.25);
    /// Puts points shaded elsewhere (a holodeck's samples of this view) into the cache, as
    /// warmUp puts its own.
    void insertShaded(const std::vector<ShadedPoint>& points);
    /// insertShaded(gather()), with the shadow edges the next frame needs (when they are stale
    /// and the options find them) found while `gather` runs: the two are independent, and
    /// oneTBB's threads share the cores between them. The cache and the edges are then those
    /// of gather(), insertShaded and the frame's own search, bit for bit; the frame reuses the
    /// edges (its shadowMs is 0: lastShadowUpdateMs() has their time). `gather` must not use
    /// the display. Returns the points gather() returned.
    std::vector<ShadedPoint> insertShadedFindingEdges(
        const std::function<std::vector<ShadedPoint>()>& gather);
    /// The shader's state serial (PointShader::stateSerial): what points shaded now carry.
    std::uint64_t shadingSerial() const;
    /// The number the next frame's reprojection takes (RenderCache::frame() + 1): the frame
    /// points shaded for that frame's view carry (ShadedPoint::frame; a holodeck's points of
    /// a new view), so that the frame shows each as its pixel's own value (ScreenPoint::trust),
    /// as it shows the points shaded for its view since it began.
    std::uint64_t nextFrame() const { return mCache.frame() + 1; }

    // -- Edits and solution updates ------------------------------------------------------------

    // What the cache keeps across a change (the drag issue): a point is dropped only when its
    // surface is gone (a removed object; a version replaced by another shape). A moved
    // object's points move with it (carryPoints), stale, and take their elements' change of
    // direct light once the shader has estimated it at the new place; a point whose element's
    // shading changed takes the element's change and is marked stale (relightChanged: re-shaded
    // first, shown meanwhile); points behind a moved or new object are hidden from the frames, not
    // dropped (setOccluder). Pixels no point reaches take the fallback (fillHoles).

    /// Takes an edit (EditSession::apply's event; the structure already changed, shader paused
    /// in asynchronous mode): the one way the display learns of edits. Changed → notifyChanged
    /// (event.changed(), `solver`), then setPreview(event.preview) when a drag goes on;
    /// DragBegan → clearPreview when a preview is shown, beginDrag(origin) and
    /// setPreview(preview); PreviewMoved → setPreview; DragEnded → endDrag when this display
    /// followed the drag to its last preview, else clearPreview and notifyChanged(added);
    /// Solved → nothing. `drag` holds the RayTracer subsets the caller keeps alive for the
    /// drag (its origin alone from DragBegan to DragEnded; the preview alone until the next
    /// preview); `solver`, when given, is passed to each step (a snapshot of its solution,
    /// instead of the next apply(SolutionView)). Returns the points moved, dropped or marked.
    struct DragVisibility {
        Visibility origin;
        Visibility preview;
    };
    std::size_t apply(const EditEvent& event, const DragVisibility& drag = {},
                      const ProgressiveSolver* solver = nullptr);
    /// New lighting, no edit: snapshots the solution for the indirect part
    /// (PointShader::updateSolution) and relights the cached points whose element shading
    /// changed (relightChanged). apply(SolutionView::of(solver)) takes the solver's own arrays;
    /// a view of copies lets another thread's published snapshot in while the solver keeps
    /// shooting. Returns the points marked stale. Throws std::invalid_argument when
    /// `solution.irradiance` or `solution.fromEmission` is null.
    std::size_t apply(const SolutionView& solution);

    /// The origin of the drag in progress, -1 for none.
    int dragOrigin() const { return mShader->dragOrigin(); }
    /// The object whose cover hides points from the frames (a moving, new or dropped object),
    /// -1 for none; and whether its hiding test still filters the whole scene for it (no
    /// RayTracer subset of its own: after an edit added it, or a drag ended).
    int occluder() const { return mOccluder; }
    bool occluderNeedsSubset() const {
        return mOccluder >= 0 && mOccluderOnly.subset < 0 && mOccluderFrames != 0;
    }
    /// Gives occluder() `version` a subset admitting it alone (the caller keeps it alive while
    /// occluder() is `version`): the hiding test traces the one object instead of filtering
    /// every hit in the scene. The points already hidden stay hidden.
    void setOccluderSubset(int version, const Visibility& only) {
        if (version == mOccluder && only.subset >= 0) mOccluderOnly = only;
    }
    /// The preview version whose background estimate is queued or running (its subset must
    /// stay alive meanwhile), -1 for none (PointShader::directJobPreview).
    int directJobPreview() const { return mShader->directJobPreview(); }
    /// The preview version shown, -1 for none.
    int previewVersion() const { return mShader->previewObject(); }
    /// Milliseconds the last shadow-edge recomputation took (after a change, or the first frame).
    double lastShadowUpdateMs() const { return mLastShadowUpdateMs; }

    // -- Reference and parts -------------------------------------------------------------------

    /// Every pixel shaded with the point shader: samplesPerAxis² samples per pixel on a
    /// regular sub-pixel grid, averaged (box filter). oneTBB over rows; deterministic.
    Image renderReference(const CameraRays& camera, int samplesPerAxis = 2) const;
    /// A nearly converged reference for error figures: every pixel from options.samplesPerAxis²
    /// jittered sub-pixel samples (box filter), edge pixels (see ConvergedReferenceOptions::
    /// edgeSpread; with useEpiEdges the last build of epi() must be for `camera`) reshaded
    /// with edgeSamplesPerAxis² jittered samples instead, all with a copy of the shader using
    /// deep adaptive shadow sampling and no clamp of negative values. Pauses the shader while
    /// it runs; oneTBB over rows; deterministic in (options, camera, display state).
    Image renderConvergedReference(const CameraRays& camera,
                                   const ConvergedReferenceOptions& options = {}) const;
    /// Pixels the last renderConvergedReference reshaded as edge pixels.
    std::size_t lastReferenceEdgePixels() const { return mLastReferenceEdgePixels; }

    PointShader& shader() { return *mShader; }
    const PointShader& shader() const { return *mShader; }
    RenderCache& cache() { return mCache; }
    const RenderCache& cache() const { return mCache; }
    EdgeFinder& edgeFinder() { return mEdges; }
    EdgePointImage& epi() { return mEpi; }
    int width() const { return mOptions.width; }
    int height() const { return mOptions.height; }
    const InteractiveDisplayOptions& options() const { return mOptions; }
    /// InteractiveDisplayOptions::maxPenumbraPixels from the next frame on.
    void setMaxPenumbraPixels(double pixels) { mOptions.maxPenumbraPixels = pixels; }
    std::string toString() const;

private:
    // -- apply()'s steps -----------------------------------------------------------------------

    /// After an edit changed `changedObjects` (Discretization object versions added, removed,
    /// or with a new material; EditEvent::changed()): a version that
    /// replaced another of the same object (a move) takes its points; a removed object's
    /// points go; an added object hides what it covers for kOccluderFrames frames; points on
    /// an object with a new material are stale. Then brings the edge finder up to date
    /// (syncWith, lights of emitting objects), recomputes the direct lighting the change
    /// affects (PointShader::refreshDirect(changed)), takes the solver's solution when given,
    /// relights (relightChanged) and marks the shadow edges for recomputation at the next
    /// frame (only stale light–blocker pairs are redone). Pending asynchronous requests and
    /// results from before the edit are discarded. Returns the points moved, dropped or marked.
    std::size_t notifyChanged(const std::vector<int>& changedObjects,
                              const ProgressiveSolver* solver = nullptr);
    /// Drag preview (George et al.'s temporary buffer): shows `previewVersion`, the dead object
    /// version the solver previews (ProgressiveSolver::previewObject(): the dragged object at
    /// its current position), lit by the solver's previewRadiosity() and casting its shadows
    /// (PointShader::setPreview; `previewOnly` a RayTracer subset admitting only it, kept
    /// alive by the caller until the next setPreview/clearPreview). The previous preview's
    /// points (or, at a drag's first move, the origin's) move with the object; what it covers
    /// in the frames' views is hidden while it is previewed; takes the solver's solution when
    /// given and relights (with backgroundPreview the moving shadow's estimate comes later,
    /// in renderFrame). Requests in flight stay (results on an earlier preview are dropped
    /// when taken). Returns the points moved or marked.
    std::size_t setPreview(int previewVersion, const Visibility& previewOnly = {},
                           const ProgressiveSolver* solver = nullptr);
    /// Ends the preview (before notifyChanged of the unselect): its points wait for that
    /// notifyChanged, which carries them to the object's new version, or go at the next frame.
    /// Returns the points marked.
    std::size_t clearPreview(const ProgressiveSolver* solver = nullptr);
    /// George et al.'s select, instead of notifyChanged({origin}) and a preview computed from
    /// scratch: `origin` was just removed from the scene and is previewed where it was, so
    /// nothing shown changes (no point dropped, no direct light recomputed); later previews
    /// are estimated relative to it (PointShader::beginDrag). Followed by setPreview.
    void beginDrag(int origin, const Visibility& originOnly = {});
    /// George et al.'s unselect after beginDrag, instead of clearPreview and
    /// notifyChanged({added}): `added` (the preview version) is alive in the scene again; the
    /// last change becomes part of H_direct (PointShader::endDrag); the object's points stay
    /// (stale) and hide what it covers for kOccluderFrames frames; relights. Returns the points
    /// marked.
    std::size_t endDrag(int added, const ProgressiveSolver* solver = nullptr);

    // -- Helpers of the steps and frames -------------------------------------------------------

    /// Per element from the shader's snapshots: the radiance (E + ρ·(H_direct + H_indirect))/π
    /// and its direct part ρ·H_direct/π.
    void elementShading(std::vector<Rgb>& total, std::vector<Rgb>& direct) const;
    /// After the shader's lighting changed (a solution, an edit, a preview's estimate): adds
    /// each element's change to the cached points on it (where they reflect the element's
    /// shading) and marks stale those on elements whose shading or direct light moved by more
    /// than invalidateThreshold (Bala et al. §7.5: they are re-shaded first, and keep the
    /// estimate meanwhile instead of leaving a hole). Returns the points marked.
    std::size_t relightChanged();
    /// relightChanged() now, or at the next frame's start with deferRelight (returns 0 then).
    std::size_t relightOrDefer();
    /// Moves the cached points of version `from` onto version `to` of the same object at its
    /// new place (RenderCache::carry); drops them when the two are not the same mesh.
    std::size_t carryPoints(int from, int to);
    /// After relightChanged: the elements of `object` (a version that came to rest) take the
    /// later changes of their shading (relightChanged adds them to their points).
    void trustShown(int object);
    /// Points behind `version` (a moving or new object) are hidden from the frames' views,
    /// for `frames` frames (-1: until replaced), tested against `only` (empty: a filter
    /// admitting the version alone).
    void setOccluder(int version, const Visibility& only, int frames);
    /// The frame's hiding pass (RenderCache::setHidden): points whose ray from the eye meets
    /// the occluder, among those in its screen rectangle and beyond its nearest depth.
    std::size_t hideOccluded(const CameraRays& camera);
    /// Remembers which versions are alive (notifyChanged tells moves from the difference).
    void noteAlive();
    /// The per-element baseline of a display whose points are all shaded from now on.
    void startShown();
    /// Drops the points of the preview clearPreview left, if no notifyChanged took them.
    std::size_t dropLeftPreview();
    void syncLights();
    /// The edge finder follows the Discretization's versions and alive flags; the preview
    /// version counts as alive (its silhouettes, and shadows when they are on).
    void syncEdges();
    /// Frames an added or dropped object hides what it covers while its own points arrive.
    static constexpr int kOccluderFrames = 90;
    std::vector<ShadedPoint> shadeAll(const std::vector<ShadeRequest>& requests) const;
    /// The results shaded on an earlier version of the dragged object (its same mesh at an
    /// earlier place of the drag) moved onto `preview`, the version shown, as carryPoints moves
    /// cached points; stale and not exact. Without it every result of a drag's object arrives
    /// after the next move and goes, and the object shows its shading at the drag's start.
    void carryResults(std::vector<ShadedPoint>& results, int preview) const;
    /// The rigid motion that takes object version `from`'s world points onto version `to`'s
    /// (the same mesh at another place): worldFromObject(to) · worldFromObject(from)⁻¹.
    Mat4 motion(int from, int to) const;
    /// The last reconstruction's holes (EdgePointImage::holes) from the fallback.
    void fillHoles(const CameraRays& camera, Image& image) const;
    /// The shading state beginFrame saw, until finishFrame (framePreview).
    PointShader::Snapshot mFrameShading;

    const Discretization& mDisc;
    const RayTracer& mTracer;
    InteractiveDisplayOptions mOptions;
    std::unique_ptr<PointShader> mShader;
    RenderCache mCache;
    EdgeFinder mEdges;
    EdgePointImage mEpi;

    std::vector<WorldEdge> mShadowEdges;  ///< cached world shadow edges, by penumbra
    PenumbraOrder mShadowOrder;           ///< mShadowEdges' buckets
    std::vector<WorldEdge> mShadowScratch;
    bool mShadowsStale = true;
    /// A relight waits for the next frame (InteractiveDisplayOptions::deferRelight).
    bool mRelightPending = false;
    double mLastShadowUpdateMs = 0;
    std::vector<ScreenEdge> mScreenEdges;  ///< the last frame's edges that may mark the EPI
    /// InteractiveDisplayOptions::windowedFrames: windows covering the pixels whose points or
    /// edges changed since the last reconstruction (none: nothing changed), or nullopt when the
    /// frame must be whole (a new camera, another reconstruction, the first frame, changes
    /// over too large a share). Points from the EPI's arrays against mShown*, edges against
    /// mShownEdges; per band of rows a rectangle, bands merged where one window costs less.
    std::optional<std::vector<PixelWindow>> changedWindows() const;
    EpiStageTimes mWindowTimes;  ///< a windowed frame's EPI stages, summed over its windows
    /// After a reconstruction of `window` (the whole raster for a whole frame): what its pixels
    /// showed becomes mShown*.
    void noteShown(const PixelWindow& window);
    /// After a frame's reconstruction: its edges become mShownEdges.
    void noteShownEdges();
    bool mFrameWindowed = false;  ///< the frame being made is windowed
    /// The state a windowed frame starts from: the last reconstruction's image (clamped at 0,
    /// holes black), camera and mode, and per pixel the point it reconstructed.
    bool mWindowValid = false;
    bool mWindowUseEdges = true;
    bool mLastWindowed = false;  ///< the EPI's whole build is older than the last frame
    bool mFrameCameraSame = false;  ///< beginFrame's camera is the last frame's, windows valid
    std::optional<CameraRays> mPreviousCamera;  ///< the last frame's camera
    bool mCameraMoving = false;  ///< beginFrame's camera differs from the last frame's
    Image mShownImage;
    std::vector<double> mShownDepth;
    std::vector<glm::vec3> mShownColour;
    std::vector<std::uint8_t> mShownPosition, mShownTrust;
    /// The edges of the last reconstruction, with their keys (edgeKey), sorted by key.
    std::vector<std::pair<std::uint64_t, ScreenEdge>> mShownEdges;
    /// Per object: the last frame's silhouettes and facing sharp edges (allocations reused).
    std::vector<std::vector<WorldEdge>> mSilhouettes, mSharpEdges;
    std::vector<ScreenEdge> mProjectScratch;  ///< projectEpiEdges' working space
    std::size_t mInsertedSinceFrame = 0;      ///< points inserted since the last frame started
    DisplayFrameStats mLast;
    DisplayFrameStats mFrame;  ///< the frame between beginFrame and finishFrame
    /// Per element: the shader state serial at the last relight that marked it stale; points
    /// shaded with an older state arrive stale.
    std::vector<std::uint64_t> mChangedAt;
    mutable std::size_t mLastReferenceEdgePixels = 0;

    // What the cached points show, per element (relightChanged): the radiance and its direct
    // part they were shaded or relit with, and how far the element's points follow its
    // shading: kShownNone not at all; kShownAll every change is added to them (an object at
    // rest); kShownDirect only the changes of the direct part, once the shader has an estimate
    // for the element where it is (a drag's preview versions: their points were carried from
    // the place before, and their reflected light lags the moves).
    static constexpr std::uint8_t kShownNone = 0, kShownAll = 1, kShownDirect = 2;
    std::vector<Rgb> mShownTotal;
    std::vector<Rgb> mShownDirect;
    std::vector<std::uint8_t> mShownValid;
    std::vector<std::uint8_t> mKnownAlive;  ///< per version, at the last noteAlive
    // The object points are hidden behind (setOccluder), and how.
    int mOccluder = -1;
    int mOccluderFrames = 0;
    Visibility mOccluderOnly;
    std::vector<std::uint8_t> mOccluderMask;
    bool mHiding = false;  ///< the cache has hidden points
    // The occluder and view the hidden points were found for.
    int mHiddenFor = -1;
    int mHiddenWidth = 0, mHiddenHeight = 0;
    Vec3 mHiddenEye{0.0}, mHiddenForward{0.0}, mHiddenRight{0.0}, mHiddenUp{0.0};
    /// The preview clearPreview ended, whose points the next notifyChanged carries to the
    /// object's new version or drops (-1 none).
    int mLeftPreview = -1;
    // The drag's moving shadows (Bala et al. §6, moving objects): the preview versions shown
    // since the last frame's pass (the first is the one that frame showed), and the shader
    // state of the last move; the next frame drops the points in their shadow volumes.
    std::vector<int> mMovedVersions;
    std::uint64_t mMoveSerial = 0;
    // The shader state from which points on the scene's objects hold their direct light as
    // the scene has it (the last edit or cancelled drag, or the drag's start: its moves
    // re-shade the points whose view of a lamp they change); an element's later change of
    // direct light is its estimate catching up, which such points already hold
    // (relightChanged gives them the rest of the change).
    std::uint64_t mDirectSince = 0;
    /// Drops the cached points that lie in the shadow volume of a version in mMovedVersions for
    /// some live lamp (their view of it changed), and the finished `results` there that were
    /// shaded before the last move; re-shades one of their pixels in `camera`'s view per
    /// shadowReshadeCell² square at once. The rest are empty pixels: re-shaded first, shown
    /// from the fallback meanwhile. Returns the cached points dropped.
    std::size_t dropShadowed(std::vector<ShadedPoint>& results, const CameraRays& camera);
    /// Finds the shadow edges when they are stale (mShadowEdges, mShadowOrder); returns the
    /// milliseconds, 0 when they were current.
    double updateShadowEdges();
};

/// Clips world edges to the camera's near plane (view depth ≥ nearPlane) and projects them to
/// pixel coordinates; depth at each endpoint is its view depth (distance along forward()).
/// Segments entirely behind the plane are dropped.
/// With maxPenumbraPixels > 0, soft shadow edges whose penumbra (WorldEdge::penumbraA, B) is
/// wider than that on screen at both ends are dropped too.
std::vector<ScreenEdge> projectEdges(const std::vector<WorldEdge>& edges, const CameraRays& camera,
                                     double nearPlane = 1e-3, double maxPenumbraPixels = 0);

/// projectEdges over the concatenation of `lists[0]`, `lists[1]`, … less the edges
/// edgeMayMark() rejects for the camera's raster, in input order, into `out` (overwritten;
/// allocations kept, as `scratch`'s, working space). An EdgePointImage of the camera's size
/// built from `out` equals one built from projectEdges' result bit for bit. Chunks of edges in
/// parallel (oneTBB) unless `parallel` is false.
void projectEpiEdges(const std::vector<std::span<const WorldEdge>>& lists, const CameraRays& camera,
                     double nearPlane, std::vector<ScreenEdge>& out,
                     std::vector<ScreenEdge>& scratch, bool parallel = true,
                     double maxPenumbraPixels = 0);

/// Reorders `edges` into penumbra buckets, each in its former order (chunks in parallel;
/// `scratch` is working space).
PenumbraOrder orderByPenumbra(std::vector<WorldEdge>& edges, std::vector<WorldEdge>& scratch);
/// How many leading edges of a list ordered by orderByPenumbra projectEdge can keep for this
/// camera: every edge after them is wider than maxPenumbraPixels at both ends at any depth of
/// `order.bounds` in front of the near plane, so projectEdge would drop it. All of them when
/// maxPenumbraPixels ≤ 0.
std::size_t penumbraPrefix(const PenumbraOrder& order, const CameraRays& camera, double nearPlane,
                           double maxPenumbraPixels);

/// Every pixel of `camera` shaded with `shader` (synchronously, on the calling thread and
/// oneTBB): samplesPerAxis² samples per pixel on a regular sub-pixel grid, box-filtered, each
/// pixel clamped at 0 after averaging as a display frame is. Deterministic. What
/// InteractiveDisplay::renderReference does with its own shader; benchmarks use it for
/// references of other scene states. Throws std::invalid_argument for samplesPerAxis < 1.
Image renderShaderReference(const PointShader& shader, const CameraRays& camera,
                            int samplesPerAxis = 2);

/// The shader options of renderConvergedReference's shader: `display`'s, synchronous, with
/// `options`' deep shadow sampling and seed, negative estimates not clamped.
PointShaderOptions convergedReferenceShaderOptions(const PointShaderOptions& display,
                                                   const ConvergedReferenceOptions& options);
/// renderConvergedReference with a given shader (made with convergedReferenceShaderOptions):
/// options.samplesPerAxis² jittered samples a pixel, and options.edgeSamplesPerAxis² instead on
/// the pixels whose samples' displayed values spread by more than options.edgeSpread or for
/// which `edgePixel` (may be empty) holds, and options.brightEdgeSamplesPerAxis² on detail
/// above white (ConvergedReferenceOptions); the count of refined pixels into `edgePixels` when
/// given. Deterministic. Throws std::invalid_argument for samples per axis < 1.
Image renderEdgeRefinedReference(const PointShader& shader, const CameraRays& camera,
                                 const ConvergedReferenceOptions& options,
                                 const std::function<bool(int x, int y)>& edgePixel = {},
                                 std::size_t* edgePixels = nullptr);

/// Root mean square difference over all pixels and channels (linear values). Throws
/// std::invalid_argument when the sizes differ.
double imageRmse(const Image& a, const Image& b);
/// imageRmse(a, reference) / RMS of the reference (0 when the reference is black).
double relativeImageRmse(const Image& a, const Image& reference);
/// Root mean square difference of the displayed values: each channel sRGB-encoded and clipped
/// to [0, 1] as writePng stores it, so bright emitters do not dominate. In [0, 1]. Throws
/// std::invalid_argument when the sizes differ.
double displayRmse(const Image& a, const Image& b);
/// displayRmse(a, reference) over the RMS of the reference's displayed values (0 when they
/// are all 0): "within 1%" of an image is a value ≤ 0.01.
double relativeDisplayRmse(const Image& a, const Image& reference);

}  // namespace penumbra
