// Index: StillBench (checkpoints, references)

#include "ui/still_bench.h"

#include <filesystem>
#include <iostream>
#include <utility>

#include "edit/edit_session.h"
#include "render/camera_rays.h"
#include "render/display/interactive_display.h"
#include "render/display/point_shader.h"
#include "render/gouraud_renderer.h"
#include "render/image.h"
#include "render/path_tracer.h"
#include "solver/progressive_solver.h"

namespace penumbra {

StillBench::StillBench(StillBenchOptions options) : mOptions(std::move(options)) {
    for (double t : {1.0, 2.0, 5.0, 10.0, 20.0, 30.0, 60.0})
        if (t < mOptions.seconds) mCheckpoints.push_back({t, nullptr});
    mCheckpoints.push_back({mOptions.seconds, nullptr});
}

void StillBench::shown(const std::shared_ptr<const ViewportImage>& image, double now) {
    if (!image || !begun()) return;
    // The image on screen when each checkpoint passes: the latest one shown before it.
    const double t = now - mStart;
    for (Checkpoint& c : mCheckpoints)
        if (t <= c.seconds) {
            c.image = image;
            c.shownAt = t;
        }
}

nlohmann::json StillBench::analyse() {
    nlohmann::json out = {{"bench", "still"}, {"scene", mOptions.scene}};
    const ViewportImage* last = nullptr;
    for (const Checkpoint& c : mCheckpoints)
        if (c.image) last = c.image.get();
    if (!last || mOptions.scene.empty()) {
        out["error"] = "no image shown";
        return out;
    }
    const int w = last->render.radiance.width, h = last->render.radiance.height;
    std::cerr << "penumbra-editor: --bench-still: reference and Gouraud renders (" << w << "x" << h
              << ")\n";
    const SolverOptions solverOptions = interactiveSolverOptions();
    auto session = EditSession::open(mOptions.scene, solverOptions, mOptions.import);
    session->converge(1e-3);
    // The reference converged as InteractiveDisplay::renderConvergedReference's: deep shadow
    // sampling, and the pixels whose samples spread (the lamps' and objects' edges) shaded with
    // edgeSamplesPerAxis² jittered samples, so that neither the display's anti-aliasing of an
    // edge nor Gouraud's 2 × 2 grid is measured against a coarse grid's own.
    ConvergedReferenceOptions ro;
    ro.samplesPerAxis = mOptions.referenceSamplesPerAxis;
    PointShader shader(session->discretization(), session->tracer(), solverOptions,
                       convergedReferenceShaderOptions(displayShaderOptions(), ro));
    shader.updateSolution(session->solver());
    const CameraRays rays(last->camera, w, h);
    std::size_t edgePixels = 0;
    const Image reference = renderEdgeRefinedReference(shader, rays, ro, {}, &edgePixels);
    const Image gouraud =
        renderGouraud(session->discretization(), session->tracer(),
                      session->solver().displayRadiosity(), last->camera, w, h, 2);
    // Two measures: the displayed values over every pixel, and the linear values with the lamps
    // and their edge pixels left out as `penumbra render --compare` does (a lamp's edge pixels
    // depend on how each image anti-aliases a value far above white).
    const std::vector<std::uint8_t> lamps =
        emitterMask(session->discretization(), session->tracer(), rays);
    const double gouraudError = relativeDisplayRmse(gouraud, reference);
    const double gouraudUnlit = relativeRmse(gouraud, reference, lamps);
    out["width"] = w;
    out["height"] = h;
    out["reference_edge_pixels"] = edgePixels;
    out["gouraud_error"] = gouraudError;
    out["gouraud_error_without_lamps"] = gouraudUnlit;
    nlohmann::json points = nlohmann::json::array();
    double closer = -1, closerUnlit = -1;
    for (const Checkpoint& c : mCheckpoints) {
        if (!c.image) continue;
        const Image& shown = c.image->render.radiance;
        const bool sameView = shown.width == w && shown.height == h;
        const double error = sameView ? relativeDisplayRmse(shown, reference) : -1;
        const double unlit = sameView ? relativeRmse(shown, reference, lamps) : -1;
        if (closer < 0 && error >= 0 && error < gouraudError) closer = c.seconds;
        if (closerUnlit < 0 && unlit >= 0 && unlit < gouraudUnlit) closerUnlit = c.seconds;
        points.push_back({{"s", c.seconds},
                          {"shown_at_s", c.shownAt},
                          {"error", error},
                          {"error_without_lamps", unlit},
                          {"mode", static_cast<int>(c.image->mode)},
                          {"settled_frames", c.image->settledFrames},
                          {"unsampled_pixels", c.image->display.unsampledPixels}});
    }
    out["checkpoints"] = std::move(points);
    out["closer_than_gouraud_at_s"] = closer;
    out["closer_than_gouraud_without_lamps_at_s"] = closerUnlit;
    if (!mOptions.recordDir.empty()) {
        const std::filesystem::path dir(mOptions.recordDir);
        std::filesystem::create_directories(dir);
        writePng(reference, (dir / "still-reference.png").string());
        writePng(gouraud, (dir / "still-gouraud.png").string());
        for (const Checkpoint& c : mCheckpoints)
            if (c.image)
                writePng(c.image->render.radiance,
                         (dir / ("still-" + std::to_string(static_cast<int>(c.seconds)) + "s.png"))
                             .string());
    }
    return out;
}

}  // namespace penumbra
