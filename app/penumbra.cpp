// penumbra: the command line (DESIGN.md "Command line"). Parses arguments and calls the
// libraries; exit status 0 success, 1 a --check mismatch, 2 bad input.
#include <tbb/global_control.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <memory>
#include <optional>

#include "bench/bench.h"
#include "edit/export.h"
#include "edit/input_error.h"
#include "edit/lit_scene.h"
#include "edit/replay.h"
#include "render/gouraud_renderer.h"
#include "render/image.h"

using namespace penumbra;

namespace {

struct SolveArgs {
    std::string scene;
    double converge = 1e-3;
    std::uint64_t maxShots = 1000000;
    int threads = 0;
    std::uint64_t seed = 1;
    double subdivide = 0;
    double stochasticBelow = interactiveSolverOptions().stochasticBelow;
    std::string save, exportPath, report;
};

void addSolveOptions(CLI::App* cmd, SolveArgs& a) {
    cmd->add_option("SCENE", a.scene, "scene file (*.json)")->required();
    cmd->add_option("--converge", a.converge,
                    "stop when unshot energy < EPS x emitted energy (default 1e-3)")
        ->check(CLI::Range(0.0, 1.0));
    cmd->add_option("--max-shots", a.maxShots, "at most N shots");
    cmd->add_option("--threads", a.threads, "worker threads (default: all cores)")
        ->check(CLI::NonNegativeNumber);
    cmd->add_option("--seed", a.seed, "seed of the pair-seeded sample patterns");
    cmd->add_option("--subdivide", a.subdivide,
                    "adaptive element subdivision where neighbour radiosity differs by more "
                    "than this fraction (0: off)")
        ->check(CLI::Range(0.0, 10.0));
    cmd->add_option("--stochastic-below", a.stochasticBelow,
                    "shoot stochastically when a shot carries less than this fraction of the "
                    "emitted power (0: every shot deterministic)")
        ->check(CLI::Range(0.0, 1.0));
}

/// Progress on stderr when it is a terminal.
std::function<void(double)> progressPrinter(double eps) {
    if (!isatty(STDERR_FILENO)) return {};
    return [eps](double unshot) {
        static int calls = 0;
        if (++calls % 16) return;
        double done = unshot > 0 ? std::log(unshot) / std::log(eps) : 1.0;
        std::fprintf(stderr, "\rsolving: unshot %.4f%%  (%3.0f%%)", unshot * 100,
                     std::clamp(done, 0.0, 1.0) * 100);
    };
}

std::unique_ptr<LitScene> openAndSolve(const SolveArgs& a) {
    SolverOptions options = interactiveSolverOptions();
    options.seed = a.seed;
    options.stochasticBelow = a.stochasticBelow;
    options.gradientThreshold = a.subdivide;
    auto lit = LitScene::open(a.scene, options);
    lit->solver().converge(a.converge, a.maxShots, progressPrinter(a.converge));
    if (isatty(STDERR_FILENO)) std::fprintf(stderr, "\n");
    return lit;
}

void writeReport(const std::string& path, const nlohmann::json& report) {
    if (!path.empty()) writeFileAtomically(path, report.dump(2) + "\n");
}

int runSolve(const SolveArgs& a) {
    auto lit = openAndSolve(a);
    if (!a.save.empty()) saveSolution(*lit, a.save);
    if (!a.exportPath.empty())
        exportLitScene(lit->discretization(), lit->solver().radiosity(), a.exportPath);
    nlohmann::json report = lit->reportJson();
    writeReport(a.report, report);
    std::fprintf(
        stderr, "penumbra: %llu shots, %llu rays, %.3f s, unshot %.3g, %zu patches, %zu elements\n",
        static_cast<unsigned long long>(lit->solver().stats().shots),
        static_cast<unsigned long long>(lit->solver().stats().rays), lit->solver().stats().seconds,
        lit->solver().unshotFraction(), lit->discretization().patches().size(),
        lit->discretization().elements().size());
    return 0;
}

int runProbe(const SolveArgs& a, const std::string& pointsPath) {
    auto points = readProbePoints(pointsPath);
    auto lit = openAndSolve(a);
    for (const ProbePoint& p : points) {
        Rgb h = lit->solver().irradianceAt(p.position, p.normal, 64);
        std::printf("%.9g %.9g %.9g\n", h.x, h.y, h.z);
    }
    return 0;
}

struct RenderArgs {
    std::string camera, mode = "gouraud", out;
    int width = 512, height = 512, samples = 2;
};

int runRender(const SolveArgs& a, const RenderArgs& r) {
    if (r.mode != "gouraud")
        throw InputError("--mode", "",
                         "unknown or not yet available mode '" + r.mode + "' (available: gouraud)");
    auto lit = openAndSolve(a);
    const Scene& scene = lit->scene();
    Camera camera;
    if (!r.camera.empty()) {
        const Camera* c = scene.findCamera(r.camera);
        if (!c) throw InputError(a.scene, "cameras", "no camera named '" + r.camera + "'");
        camera = *c;
    } else if (const Camera* c = scene.findCamera("default")) {
        camera = *c;
    } else if (!scene.cameras.empty()) {
        camera = scene.cameras.front();
    }
    Image image =
        renderGouraud(lit->discretization(), lit->tracer(), lit->solver().displayRadiosity(),
                      camera, r.width, r.height, r.samples);
    writeImage(image, r.out);
    nlohmann::json report = lit->reportJson();
    report["image"] = r.out;
    writeReport(a.report, report);
    return 0;
}

struct ReplayArgs {
    ReplayOptions options;
    std::string report, check;
    int threads = 0;
    double stochasticBelow = interactiveSolverOptions().stochasticBelow;
    std::uint64_t seed = 1;
};

/// `replay`: exit 0, 1 on a --check mismatch (one line naming the edit), 2 on bad input.
int runReplayCommand(ReplayArgs& a) {
    a.options.solver = interactiveSolverOptions();
    a.options.solver.seed = a.seed;
    a.options.solver.stochasticBelow = a.stochasticBelow;
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
        if (auto mismatch = compareReplayReports(report, golden, a.check)) {
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

}  // namespace

int main(int argc, char** argv) {
    CLI::App app{"Penumbra: interactive radiosity lighting editor, command line"};
    app.require_subcommand(1);
    SolveArgs solve;
    std::string pointsPath;
    RenderArgs render;

    CLI::App* solveCmd = app.add_subcommand("solve", "solve a scene to convergence");
    addSolveOptions(solveCmd, solve);
    solveCmd->add_option("--save", solve.save, "write the solution (JSON)");
    solveCmd->add_option("--export", solve.exportPath,
                         "export the lit scene (.ply .gltf .glb .obj)");
    solveCmd->add_option("--report", solve.report, "write a JSON report");

    CLI::App* probeCmd = app.add_subcommand("probe", "print irradiance at points");
    addSolveOptions(probeCmd, solve);
    probeCmd->add_option("--points", pointsPath, "file of \"x y z nx ny nz\" lines")->required();

    CLI::App* exportCmd = app.add_subcommand("export", "solve and export the lit scene");
    addSolveOptions(exportCmd, solve);
    exportCmd->add_option("OUT", solve.exportPath, "output (.ply .gltf .glb .obj)")->required();
    exportCmd->add_option("--report", solve.report, "write a JSON report");

    CLI::App* renderCmd = app.add_subcommand("render", "solve and render an image");
    addSolveOptions(renderCmd, solve);
    renderCmd->add_option("--camera", render.camera,
                          "camera name (default: 'default' or the first)");
    renderCmd->add_option("--width", render.width)->check(CLI::Range(1, 16384));
    renderCmd->add_option("--height", render.height)->check(CLI::Range(1, 16384));
    renderCmd->add_option("--samples", render.samples, "samples per pixel per axis")
        ->check(CLI::Range(1, 16));
    renderCmd->add_option("--mode", render.mode, "gouraud");
    renderCmd->add_option("--out", render.out, "image (.png or .exr)")->required();
    renderCmd->add_option("--report", solve.report, "write a JSON report");

    ReplayArgs replay;
    CLI::App* replayCmd = app.add_subcommand("replay", "replay an edit log over a scene");
    replayCmd->add_option("SCENE", replay.options.scenePath, "scene file (*.json)")->required();
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
    replayCmd->add_option("--export", replay.options.exportPath,
                          "export the lit scene after the last line (.ply .gltf .glb .obj)");
    replayCmd->add_option("--report", replay.report, "write a JSON report");
    replayCmd->add_option("--check", replay.check,
                          "compare with a golden report; exit 1 naming the first differing edit");
    replayCmd->add_option("--seed", replay.seed, "seed of the pair-seeded sample patterns");
    replayCmd->add_option("--threads", replay.threads, "worker threads (default: all cores)")
        ->check(CLI::NonNegativeNumber);
    replayCmd
        ->add_option("--stochastic-below", replay.stochasticBelow,
                     "shoot stochastically when a shot carries less than this fraction of "
                     "the emitted power (0: every shot deterministic)")
        ->check(CLI::Range(0.0, 1.0));

    CLI::App* benchCmd = app.add_subcommand("bench", "benchmarks (Google Benchmark + tables)");
    benchCmd->require_subcommand(1);
    BenchOptions bench;
    CLI::App* benchSolver = benchCmd->add_subcommand("solver", "solver throughput and convergence");
    benchSolver->add_option("--scenes", bench.scenes, "scene files")
        ->default_val(std::vector<std::string>{"scenes/cube-room.json", "scenes/cubicles.json",
                                               "scenes/robot-room.json", "scenes/large.json"});
    benchSolver->add_option("--max-seconds", bench.maxSecondsPerScene, "solver time cap per scene");
    benchSolver->add_option("--json", bench.jsonOut, "write every figure as JSON");
    RedistributionBenchOptions redist;
    CLI::App* benchRedist = benchCmd->add_subcommand(
        "redistribution", "George et al. Figures 6 and 7: error against time after an edit");
    benchRedist->add_option("--cases", redist.cases, "cube-room and/or robot-room");
    benchRedist->add_option("--scene-dir", redist.sceneDir, "folder with the scenes");
    benchRedist->add_option("--reference-eps", redist.referenceEps,
                            "convergence of the references");
    benchRedist->add_option("--max-ms", redist.maxMs, "solver time per method");
    benchRedist->add_option("--plot-dir", redist.plotDir, "write error-vs-time plots (PNG) here");
    benchRedist->add_option("--json", redist.jsonOut, "write every sample as JSON");

    try {
        app.parse(argc, argv);
    } catch (const CLI::CallForHelp& e) {
        return app.exit(e);
    } catch (const CLI::ParseError& e) {
        std::fprintf(stderr, "penumbra: %s\n", e.what());
        return 2;
    }

    std::optional<tbb::global_control> threads;
    const int threadCount = *replayCmd ? replay.threads : solve.threads;
    if (threadCount > 0) threads.emplace(tbb::global_control::max_allowed_parallelism, threadCount);

    try {
        if (*solveCmd) return runSolve(solve);
        if (*probeCmd) return runProbe(solve, pointsPath);
        if (*exportCmd) return runSolve(solve);
        if (*renderCmd) return runRender(solve, render);
        if (*replayCmd) return runReplayCommand(replay);
        if (*benchSolver) return runSolverBench(bench);
        if (*benchRedist) return runRedistributionBench(redist);
    } catch (const std::exception& e) {
        std::fprintf(stderr, "penumbra: %s\n", e.what());
        return 2;
    }
    return 2;
}
