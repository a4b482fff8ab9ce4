// penumbra: the command line (DESIGN.md "Command line"). Parses arguments and calls the
// libraries; exit status 0 success, 1 a --check mismatch, 2 bad input, 130 SIGINT stopped an
// interpolant build.
#include <tbb/global_control.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <OpenMesh/Core/System/omstream.hh>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <iostream>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <sstream>
#include <thread>
#include <unordered_set>

#include "app/cli_common.h"
#include "app/holodeck_commands.h"
#include "app/import_flags.h"
#include "core/durable_file.h"
#include "core/file_name.h"
#include "core/input_error.h"
#include "core/log.h"
#include "core/random.h"
#include "core/timing.h"
#include "edit/edit_log.h"
#include "edit/edit_session.h"
#include "edit/io/export.h"
#include "edit/io/scene_io.h"
#include "edit/lit_scene.h"
#include "edit/replay.h"
#include "render/camera_rays.h"
#include "render/display/display_report.h"
#include "render/display/interactive_display.h"
#include "render/gl/offscreen_context.h"
#include "render/gouraud_renderer.h"
#include "render/hifi/exact_irradiance.h"
#include "render/hifi/hifi_mesh.h"
#include "render/hifi/interpolant_gl.h"
#include "render/holodeck/holo_file.h"
#include "render/holodeck/holo_server.h"
#include "render/holodeck/holo_view.h"
#include "render/image.h"
#include "render/path_tracer.h"
#include "render/settling_overlay.h"

using namespace penumbra;
using namespace penumbra::cli;

namespace {

/// Thrown when SIGINT stopped an interpolant build: main exits with status 130.
struct BuildInterrupted {};

/// SIGINT while the interpolants are built (BuildSigint): during the meshing it asks the build
/// to stop at its next element; during the leaf solve, which has no such point, it ends the
/// process at once with status 130 (nothing has been written yet).
std::atomic<bool> gMeshing{false}, gInterrupted{false};
void onBuildSigint(int) {
    if (gMeshing.load()) {
        gInterrupted.store(true);
    } else {
        _exit(130);
    }
}

/// Installs onBuildSigint for its lifetime, then puts back what was there.
class BuildSigint {
public:
    BuildSigint() {
        gMeshing.store(false);
        gInterrupted.store(false);
        struct sigaction action {};
        action.sa_handler = onBuildSigint;
        sigemptyset(&action.sa_mask);
        sigaction(SIGINT, &action, &mPrevious);
    }
    ~BuildSigint() {
        sigaction(SIGINT, &mPrevious, nullptr);
        gMeshing.store(false);
    }
    BuildSigint(const BuildSigint&) = delete;
    BuildSigint& operator=(const BuildSigint&) = delete;

private:
    struct sigaction mPrevious {};
};

/// The high-fidelity mesh of a scene (Hardt & Teller 1996): exact irradiance with the far
/// field's rays and sampled visibility past 48 blockers, gathered from a second solve in which
/// every element shoots (leafReflectedRadiosity), meshed and sampled with progress on a
/// terminal (elements meshed of all, time left). With `leafOnly` the scene's own solver has not
/// run (the leaf solve replaces it) and receives the leaf solve's stats; else the leaf solve
/// falls back on the scene's solution where it would be the same solve. SIGINT stops it: throws
/// BuildInterrupted.
HifiMesh buildInterpolants(LitScene& lit, const SolveArgs& a, LeafSolveStats* leafOnly = nullptr) {
    const BuildSigint sigint;
    const Discretization& disc = lit.discretization();
    ExactIrradiance exact(disc, ExactIrradianceOptions::forInterpolants(a.gatherRays),
                          &lit.tracer());
    SolverOptions leafOptions = interactiveSolverOptions();
    leafOptions.seed = a.seed;
    leafOptions.stochasticBelow = a.stochasticBelow;
    if (leafOnly) {
        exact.setReflected(leafReflectedRadiosity(lit.scene(), disc, leafOptions, a.converge,
                                                  a.maxShots, leafOnly,
                                                  progressPrinter(a.converge)));
        if (isatty(STDERR_FILENO)) std::fprintf(stderr, "\n");
    } else {
        exact.setReflected(leafReflectedRadiosity(lit.scene(), disc, lit.solver(), leafOptions,
                                                  a.converge, a.maxShots));
    }
    HifiMesh mesh;
    const bool tty = ::isatty(STDERR_FILENO);
    HifiOptions options;
    options.cancelled = [] { return gInterrupted.load(); };
    gMeshing.store(true);
    const auto start = std::chrono::steady_clock::now();
    const long long total = static_cast<long long>(disc.elements().size());
    mesh.build(disc, exact, options, [&](double f) {
        if (!tty) return;
        // The time left at the pace so far (the build's fraction is of its elements).
        const double elapsed =
            std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
        std::fprintf(stderr, "\rmeshing and sampling %3.0f%%: %lld of %lld elements", 100 * f,
                     std::llround(f * total), total);
        if (f > 0.01 && f < 1)
            std::fprintf(stderr, ", %.0f s left   ", elapsed * (1 - f) / f);
        else
            std::fprintf(stderr, "              ");
    });
    if (tty) std::fprintf(stderr, "\n");
    if (mesh.stats().cancelled) {
        std::fprintf(stderr, "penumbra: interrupted; nothing written\n");
        throw BuildInterrupted{};
    }
    const HifiStats& st = mesh.stats();
    spdlog::debug(
        "interpolants: {} elements ({} meshed), {} triangles, {} samples, {} centre "
        "tests, {} covered, {} buried elements, {} capped, {} sampled once, built in {:.2f} s",
        st.elements, st.meshedElements, st.triangles, st.samples, st.centreSamples,
        st.coveredTriangles, st.buriedElements, st.cappedElements, st.singleSampleElements,
        st.seconds);
    return mesh;
}

nlohmann::json hifiReport(const HifiMesh& mesh) {
    const HifiStats& st = mesh.stats();
    return {{"elements", st.elements},
            {"meshed_elements", st.meshedElements},
            {"triangles", st.triangles},
            {"shadow_segments", st.shadowSegments},
            {"contact_segments", st.contactSegments},
            {"samples", st.samples},
            {"centre_samples", st.centreSamples},
            {"far_rays", st.farRays},
            {"covered_triangles", st.coveredTriangles},
            {"buried_elements", st.buriedElements},
            {"capped_elements", st.cappedElements},
            {"single_sample_elements", st.singleSampleElements},
            {"derived_far_fields", st.derivedFarFields},
            {"build_seconds", st.seconds}};
}

/// The interpolants as triangles for export: each split into four at its edge midpoints, so
/// that the linear interpolation of vertex colours other tools do follows the quadratic.
std::vector<LitTriangle> interpolantTriangles(const Discretization& disc, const HifiMesh& mesh) {
    std::vector<LitTriangle> out;
    out.reserve(4 * mesh.triangles().size());
    for (std::size_t t = 0; t < mesh.triangles().size(); ++t) {
        const HifiTriangle& tri = mesh.triangles()[t];
        // The corners and midpoints in the interpolant's order (A, AB, B, BC, C, CA) at (s, t),
        // p = p0 + s (p1 − p0) + t (p2 − p0). Positions are the corners themselves and the
        // symmetric midpoints, so a neighbour sharing an edge computes the same bits.
        const glm::dvec2 st[6] = {{0, 0}, {0.5, 0}, {1, 0}, {0.5, 0.5}, {0, 1}, {0, 0.5}};
        const Vec3 p[6] = {tri.p[0], 0.5 * (tri.p[0] + tri.p[1]),
                           tri.p[1], 0.5 * (tri.p[1] + tri.p[2]),
                           tri.p[2], 0.5 * (tri.p[2] + tri.p[0])};
        Rgb b[6];
        for (int k = 0; k < 6; ++k)
            b[k] = mesh.radiosity(disc, static_cast<int>(t), st[k].x, st[k].y);
        const int corners[4][3] = {{0, 1, 5}, {1, 2, 3}, {5, 3, 4}, {1, 3, 5}};
        for (const auto& c : corners)
            out.push_back({tri.element, {p[c[0]], p[c[1]], p[c[2]]}, {b[c[0]], b[c[1]], b[c[2]]}});
    }
    return out;
}

int runSolve(const SolveArgs& a) {
    if (!a.exportPath.empty()) checkExportPath(a.exportPath);
    auto lit = openAndSolve(a);
    if (!a.saveScene.empty()) saveScene(lit->scene(), a.saveScene);
    if (!a.save.empty()) saveSolution(*lit, a.save);
    nlohmann::json report = lit->reportJson();
    if (!a.exportPath.empty() && a.exportHifi) {
        const HifiMesh mesh = buildInterpolants(*lit, a);
        exportLitTriangles(lit->discretization(), interpolantTriangles(lit->discretization(), mesh),
                           a.exportPath, &lit->scene());
        report["hifi"] = hifiReport(mesh);
    } else if (!a.exportPath.empty()) {
        exportLitScene(lit->discretization(), lit->solver().radiosity(), a.exportPath,
                       &lit->scene());
    }
    writeReport(a.report, report);
    std::fprintf(
        stderr, "penumbra: %llu shots, %llu rays, %.3f s, unshot %.3g, %zu patches, %zu elements\n",
        static_cast<unsigned long long>(lit->solver().stats().shots),
        static_cast<unsigned long long>(lit->solver().stats().rays), lit->solver().stats().seconds,
        lit->solver().unshotFraction(), lit->discretization().patches().size(),
        lit->discretization().elements().size());
    return 0;
}

/// `probe`: the exact irradiance at each point (Hardt & Teller §5): emitters through their
/// visible parts, plus the solution's reflected light gathered the same way.
int runProbe(const SolveArgs& a, const std::string& pointsPath) {
    auto points = readProbePoints(pointsPath);
    auto lit = openAndSolve(a);
    const Discretization& disc = lit->discretization();
    ExactIrradiance exact(disc);
    exact.setReflected(reflectedRadiosity(disc, lit->solver()));
    for (const ProbePoint& p : points) {
        Rgb h = exact.irradiance(p.position, glm::normalize(p.normal));
        std::printf("%.9g %.9g %.9g\n", h.x, h.y, h.z);
    }
    return 0;
}

struct RenderArgs {
    std::string camera, mode = "gouraud", out;
    int width = 512, height = 512, samples = 2;
    // Interactive display modes (epi, cache, reference).
    std::string log, overlay, rmseFrames = "last";
    std::string compare;   ///< EXR reference: the report adds relative_rmse
    std::string holodeck;  ///< epi, cache: the first frame starts from this holodeck's samples
    int gatherRays = 256;  ///< interpolant: ExactIrradianceOptions::farRays
    int frames = 0;        ///< 0: 1, or one per log line plus the first
    double sampleFraction = 0.02;
    double warmup = 0.25;
    double orbitDeg = 0.5;                          ///< per frame
    int smooth = displayEpiOptions().smoothRadius;  ///< EPI edge-free smoothing radius
    /// Soft shadow edges wider than this on screen do not mark the EPI (0: all do).
    double maxPenumbraPixels = InteractiveDisplayOptions{}.maxPenumbraPixels;
};

/// The scene's camera named `name`, else "default", else the first, else a default Camera.
/// The fields every `render` report has: the image written, the mode and the size.
void addImageFields(nlohmann::json& report, const RenderArgs& r) {
    report["image"] = r.out;
    report["mode"] = r.mode;
    report["width"] = r.width;
    report["height"] = r.height;
}

/// `path` with "-SUFFIX" before its extension: out.png, "0003" -> out-0003.png.
std::string siblingPath(const std::string& path, const std::string& suffix) {
    std::filesystem::path p(path);
    std::filesystem::path name = p.stem();
    name += "-" + suffix;
    name += p.extension();
    return (p.parent_path() / name).string();
}

/// The relative RMSE of `image` against the EXR `path`, lamps left out, for the report.
double compareWith(const Image& image, const std::string& path, const Discretization& disc,
                   const RayTracer& tracer, const CameraRays& rays) {
    const Image reference = readExr(path);
    if (reference.width != image.width || reference.height != image.height)
        throw InputError(path, "",
                         "is " + std::to_string(reference.width) + "x" +
                             std::to_string(reference.height) + ", the render " +
                             std::to_string(image.width) + "x" + std::to_string(image.height));
    return relativeRmse(image, reference, emitterMask(disc, tracer, rays));
}

/// The blotch figure of `image` against the EXR `path` (flatWindowErrors: 32 × 32 pixel windows
/// of one flat face, stride 4, errors between 4 × 4-pixel cells), for the report.
nlohmann::json flatWindowsWith(const Image& image, const std::string& path,
                               const Discretization& disc, const RayTracer& tracer,
                               const CameraRays& rays) {
    const WindowErrors w =
        flatWindowErrors(image, readExr(path), flatFaceKeys(disc, tracer, rays), 32, 4, 4);
    return {{"windows", w.windows},
            {"mean_std", w.meanStd},
            {"max_std", w.maxStd},
            {"worst_x", w.worstX},
            {"worst_y", w.worstY}};
}

InteractiveDisplayOptions displayOptionsOf(const RenderArgs& r, std::uint64_t seed) {
    InteractiveDisplayOptions options;
    options.width = r.width;
    options.height = r.height;
    options.sampleFraction = r.sampleFraction;
    options.epi.smoothRadius = r.smooth;
    options.maxPenumbraPixels = r.maxPenumbraPixels;
    options.shader.seed = seed;
    options.cache.seed = seed;
    return options;
}

/// `render --holodeck` (Ward & Simmons 1999): the first frame takes the holodeck's samples of
/// the view; at the end the points the display shaded itself go into it. A new file gets the
/// scene's sections.
class RenderHolodeck {
public:
    RenderHolodeck(const std::string& path, const EditSession& session)
        : mFile(path, holodeckSections(session.scene().settings, session.discretization())),
          mServer(mFile, nullptr) {}

    /// Puts the holodeck's samples of the view into the display: those of every beam whose
    /// hits the view can see, whichever views or fill stored them (the index of the beams'
    /// hits is built at the first view). With `findEdges` (an edge-and-point frame follows),
    /// the display finds its shadow edges meanwhile. Returns the milliseconds.
    double seedView(InteractiveDisplay& display, EditSession& session, const CameraRays& rays,
                    bool findEdges) {
        const auto start = std::chrono::steady_clock::now();
        const std::uint64_t frame = display.nextFrame(), serial = display.shadingSerial();
        auto gather = [&] {
            if (!mIndex) mIndex.emplace(mServer);
            return mIndex->viewPoints(session.discretization(), session.tracer(), rays, frame,
                                      serial);
        };
        std::vector<ShadedPoint> points;
        if (findEdges) {
            points = display.insertShadedFindingEdges(gather);
        } else {
            points = gather();
            display.insertShaded(points);
        }
        for (const ShadedPoint& p : points) mFromHolodeck.insert(positionKey(p.position));
        mLastSamples = std::int64_t(points.size());
        if (mViews++ == 0) mSamples = mLastSamples;
        return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start)
            .count();
    }
    /// The points the first view took; the last view's.
    std::int64_t samples() const { return mSamples; }
    std::int64_t lastSamples() const { return mLastSamples; }

    /// Stores the points the display shaded itself (not those the holodeck brought).
    void storeShaded(const InteractiveDisplay& display, EditSession& session, const Vec3& eye) {
        std::vector<CachePoint> shaded;
        for (const CachePoint& p : display.cache().points())
            if (!mFromHolodeck.count(positionKey(p.position))) shaded.push_back(p);
        mStored = storeViewPoints(mServer, shaded, session.tracer(), eye);
    }

    void addTo(nlohmann::json& report) const {
        report["holodeck"] = mFile.path();
        report["holodeck_samples"] = mSamples;
        report["holodeck_stored"] = mStored;
    }

private:
    /// A point's identity: its position's bits.
    static std::uint64_t positionKey(const Vec3& p) {
        std::uint64_t bits[3];
        std::memcpy(bits, &p.x, sizeof bits);
        return hashPair(hashPair(bits[0], bits[1]), bits[2]);
    }

    HoloFile mFile;
    HoloServer mServer;
    std::optional<HoloHitIndex> mIndex;
    int mViews = 0;
    std::int64_t mLastSamples = 0;
    std::unordered_set<std::uint64_t> mFromHolodeck;
    std::int64_t mSamples = 0, mStored = 0;
};

/// `render --mode reference`: one frame of the display's brute-force reference.
Image referenceFrame(InteractiveDisplay& display, const CameraRays& rays, int samples, int k,
                     nlohmann::json& entry) {
    const auto start = std::chrono::steady_clock::now();
    Image image = display.renderReference(rays, samples);
    const double ms =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start)
            .count();
    entry.update({{"frame", k},
                  {"total_ms", ms},
                  {"reconstruct_ms", 0.0},
                  {"new_sample_fraction", double(samples) * samples}});
    return image;
}

/// `render --mode epi|cache|reference`: the interactive display (Bala et al. 2003) over an
/// edit session, frames along an orbit or while replaying an edit log one line per frame.
int runDisplayRender(const SolveArgs& a, const RenderArgs& r) {
    // Read every input before solving.
    const SolverOptions options = solverOptionsOf(a);
    auto session = EditSession::open(a.scene, options, a.import);
    std::vector<LoggedEdit> edits;
    if (!r.log.empty())
        edits = readEditLog(r.log, std::filesystem::path(a.scene).parent_path().string());
    const Camera camera = pickCamera(session->scene(), a.scene, r.camera);
    (void)CameraRays(camera, r.width, r.height);  // validates the camera (std::invalid_argument)
    const int frames = r.frames > 0 ? r.frames : (r.log.empty() ? 1 : int(edits.size()) + 1);

    session->converge(a.converge, a.maxShots);
    InteractiveDisplay display(session->discretization(), session->tracer(), options,
                               displayOptionsOf(r, a.seed));
    display.apply(SolutionView::of(session->solver()));

    const bool reference = r.mode == "reference";
    std::optional<RenderHolodeck> holodeck;
    if (!r.holodeck.empty() && !reference) holodeck.emplace(r.holodeck, *session);
    nlohmann::json frameReports = nlohmann::json::array();
    Image image;
    std::optional<CameraRays> rays;
    for (int k = 0; k < frames; ++k) {
        nlohmann::json entry;
        // One log line per frame (frame 0 shows the scene before the log).
        if (k >= 1 && k - 1 < static_cast<int>(edits.size())) {
            const LoggedEdit& logged = edits[k - 1];
            const EditEvent event = session->apply(logged.command, EditSource{r.log, logged.line});
            if (!logged.command.isSolverWork()) session->converge(a.converge, a.maxShots);
            // A drag's preview is traced without a subset of its own (the whole scene,
            // filtered): one frame per line, nothing to amortize.
            display.apply(event, {}, &session->solver());
            display.apply(SolutionView::of(session->solver()));
            entry["edit"] = {{"line", logged.line}, {"op", logged.command.opName()}};
        }
        const Camera frameCamera = r.log.empty() ? orbitCamera(camera, k * r.orbitDeg) : camera;
        rays.emplace(frameCamera, r.width, r.height);
        if (reference) {
            image = referenceFrame(display, *rays, r.samples, k, entry);
        } else {
            // Each view of a walkthrough takes its points from the holodeck first.
            const bool seed = holodeck && (k == 0 || (r.log.empty() && r.orbitDeg != 0));
            const double holodeckMs =
                seed ? holodeck->seedView(display, *session, *rays, r.mode == "epi") : 0.0;
            // The warm-up shades what the holodeck did not bring.
            const double warmPoints = r.warmup * r.width * r.height;
            const double brought = holodeck ? double(holodeck->samples()) : 0.0;
            if (k == 0 && r.warmup > 0 && brought < warmPoints) display.warmUp(*rays, r.warmup);
            image = display.renderFrame(*rays, r.mode == "epi");
            entry.update(displayFrameJson(display.lastFrame()));
            if (seed) {
                entry["holodeck_ms"] = holodeckMs;
                entry["holodeck_samples"] = holodeck->lastSamples();
                entry["total_ms"] = entry["total_ms"].get<double>() + holodeckMs;
            }
            if (r.rmseFrames == "all" || (r.rmseFrames == "last" && k == frames - 1)) {
                const Image ref = display.renderReference(*rays, r.samples);
                entry["rmse"] = displayRmse(image, ref);
                entry["linear_rmse"] = imageRmse(image, ref);
            }
        }
        if (frames > 1) {
            char number[16];
            std::snprintf(number, sizeof number, "%04d", k);
            writeImage(image, siblingPath(r.out, number));
        }
        frameReports.push_back(std::move(entry));
    }
    writeImage(image, r.out);
    if (holodeck) holodeck->storeShaded(display, *session, rays->origin());
    if (r.overlay == "edges") {
        // The reference shades no EPI: run one display frame from the final camera for it.
        if (reference) {
            if (r.warmup > 0) display.warmUp(*rays, r.warmup);
            display.renderFrame(*rays, true);
        }
        writePng(display.edgeImage(), siblingPath(r.out, "edges"));
    }
    nlohmann::json report = session->reportJson();
    addImageFields(report, r);
    report["sample_fraction"] = r.sampleFraction;
    report["warmup"] = r.warmup;
    report["smooth_radius"] = r.smooth;
    report["max_penumbra_pixels"] = r.maxPenumbraPixels;
    report["frames"] = std::move(frameReports);
    if (holodeck) holodeck->addTo(report);
    if (!r.compare.empty())
        report["relative_rmse"] =
            compareWith(image, r.compare, session->discretization(), session->tracer(), *rays);
    writeReport(a.report, report);
    return 0;
}

/// `render --mode pathtrace`: the brute-force path-traced reference of the scene as it is
/// (no solve), --samples² paths per pixel.
int runPathTraceRender(const SolveArgs& a, const RenderArgs& r) {
    auto session = EditSession::open(a.scene, SolverOptions{}, a.import);
    const Camera camera = pickCamera(session->scene(), a.scene, r.camera);
    const CameraRays rays(camera, r.width, r.height);
    PathTraceOptions options;
    options.samplesPerPixel = r.samples * r.samples;
    options.seed = a.seed;
    const bool tty = ::isatty(STDERR_FILENO);
    PathTraceResult traced =
        pathTrace(session->discretization(), session->tracer(), rays, options, [&](double f) {
            if (tty) std::fprintf(stderr, "\rpath tracing %3.0f%%", 100 * f);
        });
    if (tty) std::fprintf(stderr, "\n");
    writeImage(traced.image, r.out);
    nlohmann::json report;
    addImageFields(report, r);
    report["samples_per_pixel"] = options.samplesPerPixel;
    report["paths"] = traced.paths;
    report["seconds"] = traced.seconds;
    if (!r.compare.empty())
        report["relative_rmse"] =
            relativeRmse(traced.image, readExr(r.compare), traced.emitterMask);
    writeReport(a.report, report);
    return 0;
}

/// `render --mode interpolant`: the high-fidelity picture (Hardt & Teller 1996) — the
/// converged solution's elements meshed along their discontinuities, quadratic interpolants
/// through exact irradiance samples, evaluated per pixel.
int runInterpolantRender(const SolveArgs& a, const RenderArgs& r) {
    using Clock = std::chrono::steady_clock;
    // The picture gathers from the leaf solve, in which every element shoots: the scene's own
    // solve would be thrown away, so it runs only where adaptive subdivision (--subdivide)
    // makes elements the leaf solve does not have.
    const bool leafOnly = !(a.subdivide > 0);
    auto lit = leafOnly ? LitScene::open(a.scene, solverOptionsOf(a), a.import) : openAndSolve(a);
    const Camera camera = pickCamera(lit->scene(), a.scene, r.camera);
    const CameraRays rays(camera, r.width, r.height);
    const Discretization& disc = lit->discretization();
    SolveArgs withRays = a;
    withRays.gatherRays = r.gatherRays;
    LeafSolveStats leaf;
    const HifiMesh mesh = buildInterpolants(*lit, withRays, leafOnly ? &leaf : nullptr);
    // The paper's passes on an offscreen GL context (EGL on a GPU, else OSMesa); one Embree
    // ray per sample when no context can be made.
    nlohmann::json pass;
    Image image;
    const auto start = Clock::now();
    try {
        OffscreenContext context;
        InterpolantGlRenderer renderer;
        renderer.upload(mesh);
        InterpolantGlTiming timing;
        image = renderer.render(disc, mesh, rays, r.samples, &timing);
        pass = {{"pass", context.name()},
                {"gl_renderer", context.renderer()},
                {"raster_ms", timing.rasterMs},
                {"read_ms", timing.readMs},
                {"evaluate_ms", timing.evaluateMs}};
    } catch (const std::runtime_error& e) {
        std::fprintf(stderr, "penumbra: no offscreen GL (%s); per-pixel rays instead\n", e.what());
        image = renderInterpolants(disc, lit->tracer(), mesh, rays, r.samples);
        pass = {{"pass", "embree"}};
    }
    const double ms = std::chrono::duration<double, std::milli>(Clock::now() - start).count();
    writeImage(image, r.out);
    nlohmann::json report = lit->reportJson();
    if (leafOnly) {
        // The solve the picture was made from.
        report["shots"] = leaf.solver.shots;
        report["rays"] = leaf.solver.rays;
        report["seconds"] = leaf.solver.seconds;
        report["unshot_fraction"] = leaf.unshotFraction;
        report["stochastic_batches"] = leaf.solver.stochasticBatches;
    }
    addImageFields(report, r);
    report["pixel_pass"] = pass;
    report["hifi"] = hifiReport(mesh);
    report["hifi"]["render_ms"] = ms;
    if (!r.compare.empty()) {
        report["relative_rmse"] = compareWith(image, r.compare, disc, lit->tracer(), rays);
        report["flat_windows"] = flatWindowsWith(image, r.compare, disc, lit->tracer(), rays);
    }
    writeReport(a.report, report);
    return 0;
}

/// `render --overlay settling` (Gouraud): the scene solved, then --log's lines applied as
/// `replay` applies them (solve and converge lines shoot, edits do not), then the picture
/// with the settling estimate's heat map over it (render/settling_overlay.h). The report adds
/// "error_estimate" (eq. 7, as replay's), "reflected_estimate" and "settled".
int runSettlingRender(const SolveArgs& a, const RenderArgs& r) {
    auto session = EditSession::open(a.scene, solverOptionsOf(a), a.import);
    std::vector<LoggedEdit> edits;
    if (!r.log.empty())
        edits = readEditLog(r.log, std::filesystem::path(a.scene).parent_path().string());
    const Camera camera = pickCamera(session->scene(), a.scene, r.camera);
    (void)CameraRays(camera, r.width, r.height);  // validates the camera (std::invalid_argument)
    session->converge(a.converge, a.maxShots);
    for (const LoggedEdit& logged : edits)
        session->apply(logged.command, EditSource{r.log, logged.line});

    const Discretization& disc = session->discretization();
    const SettlingEstimate settling = session->solver().computeSettling();
    const Image picture = renderGouraud(disc, session->tracer(), session->displayRadiosity(),
                                        camera, r.width, r.height, r.samples);
    const Image changeImage = renderGouraud(disc, session->tracer(), settlingChangeValues(settling),
                                            camera, r.width, r.height, r.samples);
    // Radiance: the radiosity floor over π.
    const double floor = settlingFloorRadiosity(disc, session->solver().radiosity()) / M_PI;
    writeImage(blendSettling(picture, changeImage, floor), r.out);
    nlohmann::json report = session->reportJson();
    addImageFields(report, r);
    report["overlay"] = r.overlay;
    report["error_estimate"] = settling.relativeRms;
    report["reflected_estimate"] = settling.reflectedRms;
    report["settled"] = settling.reflectedRms < kSettledRms;
    writeReport(a.report, report);
    return 0;
}

int runRender(const SolveArgs& a, const RenderArgs& r) {
    if (r.mode != "gouraud" && r.mode != "epi" && r.mode != "cache" && r.mode != "reference" &&
        r.mode != "pathtrace" && r.mode != "interpolant")
        throw InputError("--mode", "",
                         "unknown mode '" + r.mode +
                             "' (available: epi, cache, reference, gouraud, interpolant, "
                             "pathtrace)");
    if (r.mode != "pathtrace" && r.samples > 16)
        throw InputError("--samples", "", "at most 16 per axis outside --mode pathtrace");
    if (!r.overlay.empty() && r.overlay != "edges" && r.overlay != "settling")
        throw InputError("--overlay", "",
                         "unknown overlay '" + r.overlay + "' (available: edges, settling)");
    if (r.overlay == "settling" && r.mode != "gouraud")
        throw InputError("--overlay", "", "settling needs --mode gouraud");
    if (r.rmseFrames != "last" && r.rmseFrames != "all" && r.rmseFrames != "none")
        throw InputError("--rmse", "",
                         "unknown value '" + r.rmseFrames + "' (available: last, all, none)");
    if (!r.holodeck.empty() && r.mode != "epi" && r.mode != "cache")
        throw InputError("--holodeck", "", "needs --mode epi or cache (the display's modes)");
    if (r.mode == "pathtrace") return runPathTraceRender(a, r);
    if (r.mode == "interpolant") return runInterpolantRender(a, r);
    if (r.mode != "gouraud") return runDisplayRender(a, r);
    if (r.overlay == "settling") return runSettlingRender(a, r);
    auto lit = openAndSolve(a);
    const Camera camera = pickCamera(lit->scene(), a.scene, r.camera);
    Image image =
        renderGouraud(lit->discretization(), lit->tracer(), lit->solver().displayRadiosity(),
                      camera, r.width, r.height, r.samples);
    writeImage(image, r.out);
    nlohmann::json report = lit->reportJson();
    addImageFields(report, r);
    if (!r.compare.empty())
        report["relative_rmse"] = compareWith(image, r.compare, lit->discretization(),
                                              lit->tracer(), CameraRays(camera, r.width, r.height));
    writeReport(a.report, report);
    return 0;
}

struct ReplayArgs {
    ReplayOptions options;
    std::string report, check;
    double tolerance = 1e-9;  ///< --check: relative tolerance of the lighting checksum
    int threads = 0;
    double stochasticBelow = interactiveSolverOptions().stochasticBelow;
    std::uint64_t seed = 1;
    std::string holodeck;             ///< --holodeck: forget what each edit changed
    double holodeckThreshold = 0.01;  ///< relative change of an element's light that counts
};

/// replay --holodeck: after every line, the holodeck forgets the samples the edit changed
/// (HoloServer::invalidate), with the elements whose radiosity luminance changed by more than
/// `threshold` of what it was (new elements count as changed); adds "beams_invalidated" and
/// "samples_invalidated" to the line's entry.
struct ReplayHolodeck {
    std::string path;
    double threshold = 0.01;
    std::optional<HoloFile> file;
    std::unique_ptr<HoloServer> server;
    std::vector<double> previous;  ///< element luminance after the previous line

    void open(EditSession& session) {
        file.emplace(path, holodeckSections(session.scene().settings, session.discretization()));
        server = std::make_unique<HoloServer>(*file, nullptr);
        previous = elementLuminance(session.solver().radiosity());
    }
    void afterEdit(EditSession& session, nlohmann::json& entry) {
        std::vector<double> now = elementLuminance(session.solver().radiosity());
        const Invalidation result =
            server->invalidate(session.tracer(), changedElements(previous, now, threshold));
        entry["beams_invalidated"] = result.beams;
        entry["samples_invalidated"] = result.samples;
        previous = std::move(now);
    }
};

/// `replay`: exit 0, 1 on a --check mismatch (one line naming the edit), 2 on bad input.
int runReplayCommand(ReplayArgs& a) {
    a.options.solver = interactiveSolverOptions();
    a.options.solver.seed = a.seed;
    a.options.solver.stochasticBelow = a.stochasticBelow;
    ReplayHolodeck holodeck;
    holodeck.path = a.holodeck;
    holodeck.threshold = a.holodeckThreshold;
    if (!a.holodeck.empty()) {
        a.options.afterConverge = [&](EditSession& session) { holodeck.open(session); };
        a.options.afterEdit = [&](EditSession& session, const EditEvent&, nlohmann::json& entry) {
            holodeck.afterEdit(session, entry);
        };
    }
    // Read the golden report first: a missing golden is bad input, not a mismatch.
    nlohmann::json golden;
    if (!a.check.empty()) golden = readReplayReport(a.check);
    nlohmann::json report = runReplay(a.options);
    if (report.contains("points"))
        for (const auto& h : report["points"])
            std::printf("%.9g %.9g %.9g\n", h[0].get<double>(), h[1].get<double>(),
                        h[2].get<double>());
    writeReport(a.report, report);
    // On a mismatch the one line naming the edit is all that goes to stderr.
    if (!a.check.empty()) {
        if (auto mismatch = compareReplayReports(report, golden, a.check, a.tolerance)) {
            std::fprintf(stderr, "penumbra: %s\n", mismatch->c_str());
            return 1;
        }
    }
    std::fprintf(stderr,
                 "penumbra: replayed %zu edits, %llu shots, %llu rays, %.3f s, unshot %.3g\n",
                 report["edits"].size(), report["shots"].get<unsigned long long>(),
                 report["rays"].get<unsigned long long>(), report["seconds"].get<double>(),
                 report["unshot_fraction"].get<double>());
    return 0;
}

/// Every subcommand's options land here; the CLI::App pointers say which one ran.
struct Commands {
    SolveArgs solve;
    std::string pointsPath;
    RenderArgs render;
    ReplayArgs replay;
    HolodeckCommands holodeck;
    CLI::App *solveCmd = nullptr, *probeCmd = nullptr, *exportCmd = nullptr, *renderCmd = nullptr,
             *replayCmd = nullptr, *benchCmd = nullptr;
};

/// solve, probe and export.
void addSolveCommands(CLI::App& app, Commands& c) {
    SolveArgs& solve = c.solve;
    CLI::App* solveCmd = c.solveCmd = app.add_subcommand("solve", "solve a scene to convergence");
    addSolveOptions(solveCmd, solve);
    solveCmd->add_option("--save", solve.save, "write the solution (JSON)");
    solveCmd->add_option("--export", solve.exportPath,
                         "export the lit scene (.ply .gltf .glb .obj)");
    solveCmd->add_option("--report", solve.report, "write a JSON report");
    solveCmd->add_option("--save-scene", solve.saveScene,
                         "write the scene as penumbra-scene/1 JSON (an imported one's meshes "
                         "beside it)");

    CLI::App* probeCmd = c.probeCmd = app.add_subcommand("probe", "print irradiance at points");
    addSolveOptions(probeCmd, solve);
    probeCmd->add_option("--points", c.pointsPath, "file of \"x y z nx ny nz\" lines")->required();

    CLI::App* exportCmd = c.exportCmd =
        app.add_subcommand("export", "solve and export the lit scene");
    addSolveOptions(exportCmd, solve);
    exportCmd->add_option("OUT", solve.exportPath, "output (.ply .gltf .glb .obj)")->required();
    exportCmd->add_option("--report", solve.report, "write a JSON report");
    exportCmd->add_flag("--hifi", solve.exportHifi,
                        "export the high-fidelity mesh (Hardt & Teller 1996: discontinuity-meshed "
                        "triangles, colours from their quadratic interpolants) instead of the "
                        "elements");
    exportCmd
        ->add_option("--gather-rays", solve.gatherRays,
                     "--hifi: sample the far field's indirect light with this many rays per "
                     "point (default 256; 0: every patch exactly)")
        ->check(CLI::Range(0, 1 << 20));
}

void addRenderCommand(CLI::App& app, Commands& c) {
    SolveArgs& solve = c.solve;
    RenderArgs& render = c.render;
    CLI::App* renderCmd = c.renderCmd = app.add_subcommand("render", "solve and render an image");
    addSolveOptions(renderCmd, solve);
    renderCmd->add_option("--camera", render.camera,
                          "camera name (default: 'default' or the first)");
    renderCmd->add_option("--width", render.width)->check(CLI::Range(1, 16384));
    renderCmd->add_option("--height", render.height)->check(CLI::Range(1, 16384));
    renderCmd
        ->add_option("--samples", render.samples,
                     "samples per pixel per axis (at most 16; 256 for pathtrace)")
        ->check(CLI::Range(1, 256));
    renderCmd->add_option("--mode", render.mode,
                          "epi, cache, reference, gouraud (default), interpolant or pathtrace");
    renderCmd
        ->add_option("--gather-rays", render.gatherRays,
                     "interpolant: sample the far field's indirect light with this many rays "
                     "per point (default 256; 0: every patch exactly)")
        ->check(CLI::Range(0, 1 << 20));
    renderCmd->add_option("--compare", render.compare,
                          "report the relative RMSE against this EXR (lamps left out)");
    renderCmd->add_option("--holodeck", render.holodeck,
                          "epi, cache: start the first frame (every frame of an orbit) from "
                          "the stored samples its view can see, and store the shaded points in "
                          "it (created when missing)");
    renderCmd->add_option("--out", render.out, "image (.png or .exr)")->required();
    renderCmd->add_option("--report", solve.report, "write a JSON report");
    renderCmd
        ->add_option("--frames", render.frames,
                     "frames along a camera orbit, or one per --log line (epi, cache, "
                     "reference)")
        ->check(CLI::Range(1, 100000));
    renderCmd->add_option("--log", render.log, "replay this edit log, one line per frame");
    renderCmd->add_option("--overlay", render.overlay,
                          "edges (epi, cache): also write the EPI pixel classes as "
                          "OUT-edges.png; settling (gouraud): the settling estimate as a heat "
                          "map over the image, after --log's lines");
    renderCmd
        ->add_option("--sample-fraction", render.sampleFraction,
                     "new samples per frame as a fraction of the pixels (default 0.02)")
        ->check(CLI::Range(0.0, 1.0));
    addReconstructionOptions(renderCmd, render.smooth, render.maxPenumbraPixels);
    renderCmd
        ->add_option("--warmup", render.warmup,
                     "fraction of the pixels shaded before the first frame (default 0.25)")
        ->check(CLI::Range(0.0, 1.0));
    renderCmd
        ->add_option("--orbit-deg", render.orbitDeg,
                     "camera orbit per frame about the look-at point, degrees (default 0.5)")
        ->check(CLI::Range(-360.0, 360.0));
    renderCmd->add_option("--rmse", render.rmseFrames,
                          "frames compared with the reference: last (default), all, none");
}

void addReplayCommand(CLI::App& app, Commands& c) {
    ReplayArgs& replay = c.replay;
    CLI::App* replayCmd = c.replayCmd =
        app.add_subcommand("replay", "replay an edit log over a scene");
    replayCmd->add_option("SCENE", replay.options.scenePath, kSceneHelp)->required();
    addImportFlags(replayCmd, replay.options.import);
    replayCmd->add_option("LOG", replay.options.logPath, "edit log (*.jsonl)")->required();
    replayCmd
        ->add_option("--budget-shots", replay.options.budgetShots,
                     "shots after every edit line (an interactive budget; default 0)")
        ->check(CLI::Range(0, 1000000000));
    replayCmd
        ->add_option("--converge", replay.options.converge,
                     "converge the scene to EPS before the first line; references too "
                     "(default 1e-3)")
        ->check(CLI::Range(0.0, 1.0));
    replayCmd->add_option("--save-scene", replay.options.saveScenePath,
                          "write the edited scene (JSON)");
    replayCmd->add_option("--points", replay.options.pointsPath,
                          "print irradiance at \"x y z nx ny nz\" points after the last line");
    replayCmd->add_flag("--reference", replay.options.reference,
                        "from-scratch reference after each edit: error_rms and error_top1");
    replayCmd
        ->add_option("--reference-eps", replay.options.referenceEps,
                     "--reference: convergence of the references (default: --converge)")
        ->check(CLI::Range(0.0, 1.0));
    replayCmd->add_option("--export", replay.options.exportPath,
                          "export the lit scene after the last line (.ply .gltf .glb .obj)");
    replayCmd->add_option("--report", replay.report, "write a JSON report");
    replayCmd->add_option("--holodeck", replay.holodeck,
                          "after every line the holodeck forgets what the edit changed; the "
                          "report adds beams_invalidated and samples_invalidated per line");
    replayCmd
        ->add_option("--holodeck-threshold", replay.holodeckThreshold,
                     "--holodeck: the relative change of an element's light that invalidates "
                     "samples on it (default 0.01)")
        ->check(CLI::Range(0.0, 1e6));
    replayCmd->add_option("--check", replay.check,
                          "compare with a golden report; exit 1 naming the first differing edit");
    replayCmd
        ->add_option("--tolerance", replay.tolerance,
                     "--check: relative tolerance of each edit's lighting checksum (default "
                     "1e-9; shots must match exactly)")
        ->check(CLI::Range(0.0, 1.0));
    replayCmd->add_option("--seed", replay.seed, "seed of the pair-seeded sample patterns");
    replayCmd->add_option("--threads", replay.threads, "worker threads (default: all cores)")
        ->check(CLI::NonNegativeNumber);
    replayCmd
        ->add_option("--stochastic-below", replay.stochasticBelow,
                     "shoot stochastically when a shot carries less than this fraction of "
                     "the emitted power (0: every shot deterministic)")
        ->check(CLI::Range(0.0, 1.0));
}

/// bench: penumbra-bench (app/penumbra_bench.cpp) with every argument after `bench`, its own
/// `--help` included, so the products carry no benchmark code.
void addBenchCommand(CLI::App& app, Commands& c) {
    c.benchCmd =
        app.add_subcommand("bench",
                           "benchmarks: solver | redistribution | display | hifi | holodeck (runs "
                           "penumbra-bench; `penumbra bench --help` lists them)");
    c.benchCmd->prefix_command();
    c.benchCmd->set_help_flag();
}

/// Replaces this process with penumbra-bench and the arguments; returns only on failure.
int runBench(const std::vector<std::string>& arguments, bool verbose) {
    const std::string path = siblingExecutable("penumbra-bench");
    std::vector<std::string> args{"penumbra-bench"};
    if (verbose) args.push_back("--verbose");
    args.insert(args.end(), arguments.begin(), arguments.end());
    std::vector<char*> argv;
    for (std::string& a : args) argv.push_back(a.data());
    argv.push_back(nullptr);
    std::fflush(nullptr);
    ::execv(path.c_str(), argv.data());
    std::fprintf(stderr, "penumbra: bench: cannot run %s: %s\n", path.c_str(),
                 std::strerror(errno));
    return 2;
}

}  // namespace

int main(int argc, char** argv) {
    // OpenMesh reports non-manifold faces it cannot link (which the edge finder handles by
    // giving them their own vertices) on its own error stream; Penumbra reports its errors.
    omerr().disable();
    CLI::App app{"Penumbra: interactive radiosity lighting editor, command line"};
    app.require_subcommand(1);
    bool verbose = false;
    app.add_flag("--verbose", verbose, "debug lines on stderr (what runs, and how long it takes)");
    Commands c;
    addSolveCommands(app, c);
    addRenderCommand(app, c);
    addReplayCommand(app, c);
    addBenchCommand(app, c);
    addHolodeckCommands(app, c.solve, c.holodeck);

    if (const int status = parseCommandLine(app, argc, argv, "penumbra"); status >= 0)
        return status;
    initLogging(verbose);

    std::optional<tbb::global_control> threads;
    const int threadCount = *c.replayCmd ? c.replay.threads : c.solve.threads;
    if (threadCount > 0) threads.emplace(tbb::global_control::max_allowed_parallelism, threadCount);

    try {
        if (*c.solveCmd) return runSolve(c.solve);
        if (*c.probeCmd) return runProbe(c.solve, c.pointsPath);
        if (*c.exportCmd) return runSolve(c.solve);
        if (*c.renderCmd) return runRender(c.solve, c.render);
        if (*c.replayCmd) return runReplayCommand(c.replay);
        if (*c.benchCmd) return runBench(c.benchCmd->remaining(), verbose);
        if (const int status = runHolodeckCommand(c.solve, c.holodeck); status >= 0) return status;
    } catch (const BuildInterrupted&) {
        return 130;  // 128 + SIGINT, as a shell reports a command Ctrl-C ended
    } catch (const std::exception& e) {
        std::fprintf(stderr, "penumbra: %s\n", e.what());
        return 2;
    }
    return 2;
}
