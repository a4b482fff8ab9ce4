// `penumbra bench hifi` (Hardt & Teller 1996): per scene, the interpolant build (time,
// triangles, samples), per-frame evaluation at 1280 × 720 on the offscreen GL pass along a
// camera orbit, and the error of gouraud, epi and interpolant against the display's `reference`
// image of the same view; then an edit (the scene's last plain object moved) and the mesh's
// incremental update against the full build. The paper's figures are the baseline: 2.5
// CPU-hours for 6,576 triangles, 2.3 frames/s at 640 × 480.

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

struct HifiCase {
    std::string name;
    double buildSeconds = 0, leafSolveSeconds = 0;
    HifiStats stats;
    double frameMs = 0, rasterMs = 0, readMs = 0, evaluateMs = 0;
    double errGouraud = 0, errEpi = 0, errInterpolant = 0;
    std::string pass;
    /// The edit: the object moved, the update's time and elements re-meshed, and the updated
    /// interpolants' error against the reference after the edit.
    std::string edited;
    double updateSeconds = 0, errUpdate = 0;
    int remeshed = 0, alive = 0;
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

    auto start = Clock::now();
    ExactIrradiance exact(disc, ExactIrradianceOptions::forInterpolants(o.gatherRays), &tracer);
    exact.setReflected(leafReflectedRadiosity(session->scene(), disc, session->solver(), options,
                                              o.converge, 100000000));
    c.leafSolveSeconds = secondsSince(start);
    HifiMesh mesh;
    start = Clock::now();
    mesh.build(disc, exact);
    c.buildSeconds = secondsSince(start);
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
    measureUpdate(o, *session, options, camera, mesh, renderer, c);
    out = {{"scene", name},
           {"elements", c.stats.elements},
           {"meshed_elements", c.stats.meshedElements},
           {"triangles", c.stats.triangles},
           {"samples", c.stats.samples},
           {"leaf_solve_s", c.leafSolveSeconds},
           {"build_s", c.buildSeconds},
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
    return c;
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
    if (!options.jsonOut.empty()) writeFileAtomically(options.jsonOut, all.dump(2) + "\n");
    return 0;
}

}  // namespace penumbra
