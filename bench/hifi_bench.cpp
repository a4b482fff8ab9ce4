// `penumbra bench hifi` (Hardt & Teller 1996): per scene, the interpolant build (time,
// triangles, samples), per-frame evaluation at 1280 × 720 on the offscreen GL pass along a
// camera orbit, and the error of gouraud, epi and interpolant against the display's `reference`
// image of the same view; the race against the path tracer (its time, at doubling paths per
// pixel, to the interpolants' error against a path-traced reference, over the interpolants'
// leaf solve, build and render); then an edit (the scene's last plain object moved) and the
// mesh's incremental update against the full build. The paper's figures are the baseline: 2.5
// CPU-hours for 6,576 triangles, 2.3 frames/s at 640 × 480.

#include <sys/resource.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "bench/bench.h"
#include "core/durable_file.h"
#include "core/timing.h"
#include "edit/edit_command.h"
#include "edit/edit_session.h"
#include "render/camera_rays.h"
#include "render/display/interactive_display.h"
#include "render/gl/offscreen_context.h"
#include "render/gouraud_renderer.h"
#include "render/hifi/exact_irradiance.h"
#include "render/hifi/hifi_mesh.h"
#include "render/hifi/interpolant_gl.h"
#include "render/image.h"
#include "render/path_tracer.h"

namespace penumbra {

namespace {

/// Wall and CPU seconds (user and system, of every thread of the process) of one step: on 2
/// cores shared with other jobs the CPU seconds are the steadier figure.
struct Spent {
    double wall = 0, cpu = 0;
};

class Stopwatch {
public:
    Stopwatch() : mStart(Clock::now()), mCpu(cpuSeconds()) {}
    Spent elapsed() const { return {secondsSince(mStart), cpuSeconds() - mCpu}; }

private:
    static double cpuSeconds() {
        rusage u{};
        getrusage(RUSAGE_SELF, &u);
        return double(u.ru_utime.tv_sec + u.ru_stime.tv_sec) +
               1e-6 * double(u.ru_utime.tv_usec + u.ru_stime.tv_usec);
    }
    Clock::time_point mStart;
    double mCpu;
};

/// One path-traced picture of the race: its paths per pixel, tracing time and error.
struct PathTracePoint {
    int spp = 0;
    Spent spent;
    double error = 0;
};

/// The path tracer against the interpolants, both measured against a path-traced reference.
struct PathTraceRace {
    bool ran = false;
    double interpolantError = 0;
    Spent render;       ///< the interpolants' picture at the comparison size
    Spent interpolant;  ///< leaf solve + build + render
    std::vector<PathTracePoint> points;
    /// The path tracer's seconds at the interpolants' error (findEqualError); `extrapolated`
    /// when no two pictures bracket it.
    Spent toEqualError;
    double sppAtEqualError = 0;
    bool extrapolated = false;
    /// The reference's own noise (relative RMSE), fitted from the path tracer's pictures
    /// (fitNoise), and the interpolants' error less it.
    double referenceNoise = 0, interpolantErrorLessNoise = 0;
    double referenceSeconds = 0;  ///< 0 when read from the cache
};

struct HifiCase {
    std::string name;
    double buildSeconds = 0, leafSolveSeconds = 0;  ///< wall
    Spent leafSolve, build;
    HifiStats stats;
    double frameMs = 0, rasterMs = 0, readMs = 0, evaluateMs = 0;
    double errGouraud = 0, errEpi = 0, errInterpolant = 0;
    std::string pass;
    /// The edit: the object moved, the update's time and elements re-meshed, and the updated
    /// interpolants' error against the reference after the edit.
    std::string edited;
    double updateSeconds = 0, errUpdate = 0;
    int remeshed = 0, alive = 0;
    PathTraceRace race;
};

/// The scene's last object that is not a lamp (the one a designer just placed).
std::string lastPlainObject(const Scene& scene) {
    for (auto it = scene.objects.rbegin(); it != scene.objects.rend(); ++it) {
        const Material* m = scene.findMaterial(it->material);
        if (m && !m->isEmitter()) return it->id;
    }
    return "";
}

/// Moves the scene's last plain object 0.2 m along x, solves again, and updates `mesh`
/// (HifiMesh::update with hifiRemeshElements) instead of building it anew; the update's
/// interpolants against the display's reference of the edited scene.
void measureUpdate(const HifiBenchOptions& o, EditSession& session, const SolverOptions& options,
                   const Camera& camera, HifiMesh& mesh, InterpolantGlRenderer& renderer,
                   HifiCase& c) {
    c.edited = lastPlainObject(session.scene());
    if (c.edited.empty()) return;
    const std::vector<Rgb> before = session.solver().radiosity();
    const EditEvent event = session.apply(MoveCommand{c.edited, Vec3(0.2, 0, 0)});
    session.converge(o.converge, 100000000);
    const Discretization& disc = session.discretization();
    ExactIrradiance exact(disc, ExactIrradianceOptions::forInterpolants(o.gatherRays),
                          &session.tracer());
    exact.setReflected(leafReflectedRadiosity(session.scene(), disc, session.solver(), options,
                                              o.converge, 100000000));
    const auto start = Clock::now();
    const std::vector<std::uint8_t> remesh =
        hifiRemeshElements(disc, before, session.solver().radiosity(), event.changed());
    mesh.update(disc, exact, remesh);
    c.updateSeconds = secondsSince(start);
    c.remeshed = mesh.stats().remeshed;
    for (int e = 0; e < int(disc.elements().size()); ++e) c.alive += disc.elementAlive(e);
    const CameraRays small(camera, o.errorWidth, o.errorHeight);
    InteractiveDisplayOptions displayOptions;
    displayOptions.width = o.errorWidth;
    displayOptions.height = o.errorHeight;
    InteractiveDisplay display(disc, session.tracer(), options, displayOptions);
    display.apply(SolutionView::of(session.solver()));
    const Image reference = display.renderReference(small, 2);
    renderer.upload(mesh);
    c.errUpdate = relativeRmse(renderer.render(disc, mesh, small, 2), reference,
                               emitterMask(disc, session.tracer(), small));
}

/// The seed of the path-traced references; the race's pictures use 1, 2, 3, ….
constexpr std::uint64_t kReferenceSeed = 0x5eed0f2e;

/// The path-traced reference of the view: read from the cache when one is there, else
/// rendered (and cached when asked).
Image pathTraceReference(const HifiBenchOptions& o, const std::string& name,
                         const Discretization& disc, const RayTracer& tracer,
                         const CameraRays& rays, PathTraceRace& race) {
    std::string cachePath;
    if (!o.referenceCache.empty()) {
        cachePath = o.referenceCache + "-" + name + "-" + std::to_string(o.compareWidth) + "x" +
                    std::to_string(o.compareHeight) + "-" + std::to_string(o.referenceSpp) +
                    "spp.exr";
        if (std::filesystem::exists(cachePath)) {
            Image cached = readExr(cachePath);
            if (cached.width == o.compareWidth && cached.height == o.compareHeight) return cached;
        }
    }
    PathTraceOptions options;
    options.samplesPerPixel = o.referenceSpp;
    options.seed = kReferenceSeed;
    PathTraceResult traced = pathTrace(disc, tracer, rays, options);
    race.referenceSeconds = traced.seconds;
    if (!cachePath.empty()) writeExr(traced.image, cachePath);
    return std::move(traced.image);
}

/// The path tracer's error is its noise alone: against a reference of N paths per pixel, a
/// picture of n paths measures e² = a (1/n + 1/N), the two pictures' independent noises. `a`
/// fitted by least squares over the race's pictures (those of 4 paths or more, when two are)
/// gives the reference's own noise √(a / N), which every measured error (the interpolants' too)
/// has in it and which is taken out of each before they are compared.
double fitNoise(const std::vector<PathTracePoint>& points, int referenceSpp) {
    const bool skipSmall =
        std::count_if(points.begin(), points.end(), [](const auto& p) { return p.spp >= 4; }) >= 2;
    double xy = 0, xx = 0;
    for (const PathTracePoint& p : points) {
        if (skipSmall && p.spp < 4) continue;
        const double x = 1.0 / p.spp + 1.0 / referenceSpp;
        xy += x * p.error * p.error;
        xx += x * x;
    }
    return xx > 0 ? xy / xx : 0.0;
}

/// The race's result from its pictures: the errors less the reference's noise, then the path
/// tracer's seconds (and paths per pixel) at the interpolants' error, log-log interpolated
/// between the two pictures that bracket it; outside them, along the fitted noise (paths
/// a / e², seconds in proportion to paths from the nearest picture), marked extrapolated.
void findEqualError(int referenceSpp, PathTraceRace& race) {
    const std::vector<PathTracePoint>& p = race.points;
    race.extrapolated = true;
    if (p.empty()) return;
    const double a = fitNoise(p, referenceSpp);
    const double floor2 = a / referenceSpp;
    race.referenceNoise = std::sqrt(floor2);
    auto clean = [&](double e) { return std::sqrt(std::max(0.0, e * e - floor2)); };
    const double target = clean(race.interpolantError);
    race.interpolantErrorLessNoise = target;
    if (!(target > 0)) {
        race.toEqualError = {HUGE_VAL, HUGE_VAL};
        race.sppAtEqualError = HUGE_VAL;
        return;
    }
    std::size_t i = 0;
    while (i < p.size() && clean(p[i].error) > target) ++i;
    if (i > 0 && i < p.size() && clean(p[i].error) > 0) {
        // The bracket [i−1, i]: the first picture at or below the error and the one before it.
        const PathTracePoint &lo = p[i - 1], &hi = p[i];
        const double f =
            std::log(target / clean(lo.error)) / std::log(clean(hi.error) / clean(lo.error));
        race.toEqualError = {lo.spent.wall * std::pow(hi.spent.wall / lo.spent.wall, f),
                             lo.spent.cpu * std::pow(hi.spent.cpu / lo.spent.cpu, f)};
        race.sppAtEqualError = lo.spp * std::pow(double(hi.spp) / lo.spp, f);
        race.extrapolated = false;
        return;
    }
    const PathTracePoint& nearest = i == 0 ? p.front() : p.back();
    race.sppAtEqualError = a / (target * target);
    const double scale = race.sppAtEqualError / nearest.spp;
    race.toEqualError = {nearest.spent.wall * scale, nearest.spent.cpu * scale};
}

/// The race: the interpolants' picture and path traces at doubling paths per pixel, all
/// against the reference, lamps left out (docs/hifi.md, "The reference: a path tracer").
void racePathTracer(const HifiBenchOptions& o, const std::string& name, const Discretization& disc,
                    const RayTracer& tracer, const Camera& camera, const HifiMesh& mesh,
                    InterpolantGlRenderer& renderer, HifiCase& c) {
    if (o.compareWidth <= 0 || o.compareHeight <= 0 || o.referenceSpp <= 0) return;
    PathTraceRace& race = c.race;
    race.ran = true;
    const CameraRays rays(camera, o.compareWidth, o.compareHeight);
    const Image reference = pathTraceReference(o, name, disc, tracer, rays, race);
    const std::vector<std::uint8_t> mask = emitterMask(disc, tracer, rays);
    const Stopwatch watch;
    const Image interpolant = renderer.render(disc, mesh, rays, o.compareSamples);
    race.render = watch.elapsed();
    race.interpolant = {c.leafSolve.wall + c.build.wall + race.render.wall,
                        c.leafSolve.cpu + c.build.cpu + race.render.cpu};
    race.interpolantError = relativeRmse(interpolant, reference, mask);
    double traced = 0;
    for (int spp = 1; spp <= std::max(1, o.referenceSpp / 4); spp *= 2) {
        PathTraceOptions options;
        options.samplesPerPixel = spp;
        options.seed = static_cast<std::uint64_t>(race.points.size()) + 1;
        const Stopwatch traceWatch;
        const PathTraceResult result = pathTrace(disc, tracer, rays, options);
        const Spent spent = traceWatch.elapsed();
        race.points.push_back({spp, spent, relativeRmse(result.image, reference, mask)});
        traced += spent.wall;
        std::printf(
            "%s: path trace %d spp %.2f s (%.2f CPU-s), error %.2f%% (interpolants %.2f%%)\n",
            name.c_str(), spp, spent.wall, spent.cpu, 100 * race.points.back().error,
            100 * race.interpolantError);
        std::fflush(stdout);
        findEqualError(o.referenceSpp, race);
        if (race.points.size() >= 2 && !race.extrapolated) break;
        if (traced >= o.pathTraceMaxSeconds) break;
    }
    findEqualError(o.referenceSpp, race);
    if (!o.plotDir.empty()) {
        writePng(reference, o.plotDir + "/hifi-" + name + "-pathtrace-reference.png");
        writePng(interpolant, o.plotDir + "/hifi-" + name + "-pathtrace-interpolant.png");
    }
}

nlohmann::json raceJson(const PathTraceRace& r) {
    nlohmann::json points = nlohmann::json::array();
    for (const PathTracePoint& p : r.points)
        points.push_back({{"spp", p.spp},
                          {"seconds", p.spent.wall},
                          {"cpu_seconds", p.spent.cpu},
                          {"error", p.error}});
    return {{"interpolant_error", r.interpolantError},
            {"reference_noise", r.referenceNoise},
            {"interpolant_error_less_noise", r.interpolantErrorLessNoise},
            {"interpolant_render_s", r.render.wall},
            {"interpolant_s", r.interpolant.wall},
            {"interpolant_cpu_s", r.interpolant.cpu},
            {"pathtrace", points},
            {"pathtrace_s_at_equal_error", r.toEqualError.wall},
            {"pathtrace_cpu_s_at_equal_error", r.toEqualError.cpu},
            {"pathtrace_spp_at_equal_error", r.sppAtEqualError},
            {"extrapolated", r.extrapolated},
            {"ratio", r.interpolant.wall > 0 ? r.toEqualError.wall / r.interpolant.wall : 0},
            {"cpu_ratio", r.interpolant.cpu > 0 ? r.toEqualError.cpu / r.interpolant.cpu : 0},
            {"reference_s", r.referenceSeconds}};
}

HifiCase runCase(const HifiBenchOptions& o, const std::string& name, nlohmann::json& out,
                 OffscreenContext& context) {
    HifiCase c;
    c.name = name;
    // A bundled scene file, else a glTF scene of that name (the furnished room from Blender).
    std::string path = o.sceneDir + "/" + name + ".json";
    if (!std::filesystem::exists(path) &&
        std::filesystem::exists(o.sceneDir + "/gltf/" + name + ".glb"))
        path = o.sceneDir + "/gltf/" + name + ".glb";
    SolverOptions options = interactiveSolverOptions();
    auto session = EditSession::open(path, options);
    session->converge(o.converge, 100000000);
    const Discretization& disc = session->discretization();
    const RayTracer& tracer = session->tracer();
    const Camera camera = session->scene().findCamera("default")
                              ? *session->scene().findCamera("default")
                          : session->scene().cameras.empty() ? Camera{}
                                                             : session->scene().cameras.front();

    Stopwatch watch;
    ExactIrradiance exact(disc, ExactIrradianceOptions::forInterpolants(o.gatherRays), &tracer);
    exact.setReflected(leafReflectedRadiosity(session->scene(), disc, session->solver(), options,
                                              o.converge, 100000000));
    c.leafSolve = watch.elapsed();
    c.leafSolveSeconds = c.leafSolve.wall;
    HifiMesh mesh;
    watch = Stopwatch();
    mesh.build(disc, exact);
    c.build = watch.elapsed();
    c.buildSeconds = c.build.wall;
    c.stats = mesh.stats();

    // Evaluation along an orbit at the full size.
    InterpolantGlRenderer renderer;
    renderer.upload(mesh);
    c.pass = context.name();
    // One frame untimed first: the first draw compiles the GL driver's shader variants
    // (llvmpipe: tens of milliseconds), which a steady frame rate leaves out.
    renderer.render(disc, mesh, CameraRays(camera, o.width, o.height), 1);
    for (int k = 0; k < o.frames; ++k) {
        const CameraRays rays(orbitCamera(camera, 0.5 * k), o.width, o.height);
        InterpolantGlTiming t;
        const auto frameStart = Clock::now();
        renderer.render(disc, mesh, rays, 1, &t);
        c.frameMs += 1e3 * secondsSince(frameStart);
        c.rasterMs += t.rasterMs;
        c.readMs += t.readMs;
        c.evaluateMs += t.evaluateMs;
    }
    c.frameMs /= o.frames;
    c.rasterMs /= o.frames;
    c.readMs /= o.frames;
    c.evaluateMs /= o.frames;

    // Errors against the display's reference of one view, lamps left out.
    const CameraRays small(camera, o.errorWidth, o.errorHeight);
    InteractiveDisplayOptions displayOptions;
    displayOptions.width = o.errorWidth;
    displayOptions.height = o.errorHeight;
    InteractiveDisplay display(disc, tracer, options, displayOptions);
    display.apply(SolutionView::of(session->solver()));
    const Image reference = display.renderReference(small, 2);
    const std::vector<std::uint8_t> mask = emitterMask(disc, tracer, small);
    const Image gouraud = renderGouraud(disc, tracer, session->solver().displayRadiosity(), camera,
                                        o.errorWidth, o.errorHeight, 2);
    display.warmUp(small, 0.25);
    Image epi;
    for (int k = 0; k < 10; ++k) epi = display.renderFrame(small, true);
    const Image interpolant = renderer.render(disc, mesh, small, 2);
    c.errGouraud = relativeRmse(gouraud, reference, mask);
    c.errEpi = relativeRmse(epi, reference, mask);
    c.errInterpolant = relativeRmse(interpolant, reference, mask);
    if (!o.plotDir.empty()) {
        writePng(reference, o.plotDir + "/hifi-" + name + "-reference.png");
        writePng(gouraud, o.plotDir + "/hifi-" + name + "-gouraud.png");
        writePng(interpolant, o.plotDir + "/hifi-" + name + "-interpolant.png");
    }
    racePathTracer(o, name, disc, tracer, camera, mesh, renderer, c);
    measureUpdate(o, *session, options, camera, mesh, renderer, c);
    out = {{"scene", name},
           {"elements", c.stats.elements},
           {"meshed_elements", c.stats.meshedElements},
           {"triangles", c.stats.triangles},
           {"samples", c.stats.samples},
           {"leaf_solve_s", c.leafSolveSeconds},
           {"build_s", c.buildSeconds},
           {"leaf_solve_cpu_s", c.leafSolve.cpu},
           {"build_cpu_s", c.build.cpu},
           {"frame_ms", c.frameMs},
           {"raster_ms", c.rasterMs},
           {"read_ms", c.readMs},
           {"evaluate_ms", c.evaluateMs},
           {"pass", c.pass},
           {"error_gouraud", c.errGouraud},
           {"error_epi", c.errEpi},
           {"error_interpolant", c.errInterpolant},
           {"edited", c.edited},
           {"update_s", c.updateSeconds},
           {"update_remeshed", c.remeshed},
           {"update_alive_elements", c.alive},
           {"error_update", c.errUpdate}};
    if (c.race.ran) out["pathtrace_race"] = raceJson(c.race);
    return c;
}

/// The race's table: per scene the interpolants' error and time against the path tracer's
/// time to that error, and their ratio.
void printRace(const HifiBenchOptions& o, const std::vector<HifiCase>& results) {
    if (std::none_of(results.begin(), results.end(), [](const HifiCase& c) { return c.race.ran; }))
        return;
    std::printf("\n%-14s %9s %9s %9s %8s %8s | %8s %9s %9s | %8s %8s\n", "path trace", "measured",
                "ref_noise", "less_it", "hifi_s", "hifi_cpu", "pt_spp", "pt_s", "pt_cpu", "ratio",
                "cpu_rat");
    for (const HifiCase& c : results) {
        const PathTraceRace& r = c.race;
        if (!r.ran) continue;
        const char* mark = r.extrapolated ? "~" : " ";
        std::printf(
            "%-14s %8.2f%% %8.2f%% %8.2f%% %8.1f %8.1f | %7.0f%s %8.1f%s %8.1f%s | %7.2fx %7.2fx\n",
            c.name.c_str(), 100 * r.interpolantError, 100 * r.referenceNoise,
            100 * r.interpolantErrorLessNoise, r.interpolant.wall, r.interpolant.cpu,
            r.sppAtEqualError, mark, r.toEqualError.wall, mark, r.toEqualError.cpu, mark,
            r.interpolant.wall > 0 ? r.toEqualError.wall / r.interpolant.wall : 0.0,
            r.interpolant.cpu > 0 ? r.toEqualError.cpu / r.interpolant.cpu : 0.0);
    }
    std::printf(
        "(interpolants at %dx%d samples per pixel against a %d-spp path trace at %dx%d, relative "
        "RMSE, lamps left out; ref_noise: the reference's own, fitted from the path tracer's "
        "pictures, and taken out of every error; hifi: leaf solve + build + render, wall and CPU "
        "seconds; pt: the path tracer's paths per pixel, wall and CPU seconds to the "
        "interpolants' error, log-log between doubling paths per pixel, ~ extrapolated along its "
        "fitted noise; ratio: pt / hifi, wall and CPU)\n",
        o.compareSamples, o.compareSamples, o.referenceSpp, o.compareWidth, o.compareHeight);
}

}  // namespace

int runHifiBench(const HifiBenchOptions& options) {
    OffscreenContext context;
    std::printf("pixel pass: %s (%s)\n", context.name().c_str(), context.renderer().c_str());
    std::vector<HifiCase> results;
    nlohmann::json all = nlohmann::json::array();
    for (const std::string& name : options.cases) {
        nlohmann::json j;
        results.push_back(runCase(options, name, j, context));
        all.push_back(std::move(j));
        const HifiCase& c = results.back();
        std::printf("%s: leaf solve %.1f s, build %.1f s, %d triangles\n", name.c_str(),
                    c.leafSolveSeconds, c.buildSeconds, c.stats.triangles);
        std::fflush(stdout);
    }
    const double paperTrianglesPerCpuSecond = 6576.0 / (2.5 * 3600);
    const double paperPixelsPerSecond = 640.0 * 480 * 2.3;
    std::printf("\n%-14s %9s %9s %9s %10s %8s %7s %8s | %8s %8s %11s\n", "scene", "elements",
                "triangles", "build_s", "tri/CPU-s", "x paper", "fps", "x paper", "gouraud", "epi",
                "interpolant");
    for (const HifiCase& c : results) {
        const double triPerCpuSecond = c.stats.triangles / (2.0 * c.buildSeconds);
        const double fps = 1e3 / c.frameMs;
        std::printf("%-14s %9d %9d %9.1f %10.1f %8.0f %7.1f %8.1f | %7.2f%% %7.2f%% %10.2f%%\n",
                    c.name.c_str(), c.stats.elements, c.stats.triangles, c.buildSeconds,
                    triPerCpuSecond, triPerCpuSecond / paperTrianglesPerCpuSecond, fps,
                    fps * options.width * options.height / paperPixelsPerSecond, 100 * c.errGouraud,
                    100 * c.errEpi, 100 * c.errInterpolant);
    }
    std::printf(
        "(build on 2 cores; fps at %dx%d, x paper in pixels/s against 2.3 fps at 640x480; "
        "errors: relative RMSE against the display's reference at %dx%d, lamps left out)\n",
        options.width, options.height, options.errorWidth, options.errorHeight);
    std::printf("\n%-14s %-16s %9s %11s %9s %8s %12s\n", "after an edit", "moved 0.2 m",
                "update_s", "x build", "remeshed", "of alive", "interpolant");
    for (const HifiCase& c : results)
        std::printf("%-14s %-16s %9.2f %10.1fx %9d %8d %11.2f%%\n", c.name.c_str(),
                    c.edited.c_str(), c.updateSeconds,
                    c.updateSeconds > 0 ? c.buildSeconds / c.updateSeconds : 0.0, c.remeshed,
                    c.alive, 100 * c.errUpdate);
    printRace(options, results);
    if (!options.jsonOut.empty()) writeFileAtomically(options.jsonOut, all.dump(2) + "\n");
    return 0;
}

}  // namespace penumbra
