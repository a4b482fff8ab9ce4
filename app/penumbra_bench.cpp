// penumbra-bench: the benchmarks, `penumbra bench SUBCOMMAND ...` (DESIGN.md "Command line":
// penumbra runs this executable, built beside it, with the arguments after `bench`). The
// bench/ module and Google Benchmark are linked here and into neither product. Exit status 0
// success, 2 bad input.
#include <CLI/CLI.hpp>
#include <OpenMesh/Core/System/omstream.hh>
#include <cstdint>
#include <cstdio>
#include <sstream>
#include <string>
#include <vector>

#include "app/cli_common.h"
#include "bench/bench.h"
#include "core/log.h"
#include "render/display/interactive_display.h"

using namespace penumbra;
using namespace penumbra::cli;

namespace {

/// Every benchmark's options; the CLI::App pointers say which one ran.
struct BenchCommands {
    BenchOptions bench;
    RedistributionBenchOptions redist;
    DisplayBenchOptions display;
    HifiBenchOptions hifi;
    HolodeckBenchOptions benchHolodeckOptions;
    CLI::App *benchSolver = nullptr, *benchRedist = nullptr, *benchDisplay = nullptr,
             *benchHifi = nullptr, *benchHolodeck = nullptr;
};

void addBenchCommands(CLI::App& app, BenchCommands& c) {
    BenchOptions& bench = c.bench;
    CLI::App* benchSolver = c.benchSolver =
        app.add_subcommand("solver", "solver throughput and convergence");
    benchSolver->add_option("--scenes", bench.scenes, "scene files")
        ->default_val(std::vector<std::string>{"scenes/cube-room.json", "scenes/cubicles.json",
                                               "scenes/robot-room.json", "scenes/large.json"});
    benchSolver->add_option("--max-seconds", bench.maxSecondsPerScene, "solver time cap per scene");
    benchSolver->add_option("--json", bench.jsonOut, "write every figure as JSON");
    benchSolver->add_option("--child-scene", bench.childScene, "internal: one scene, JSON out")
        ->group("");
    RedistributionBenchOptions& redist = c.redist;
    CLI::App* benchRedist = c.benchRedist = app.add_subcommand(
        "redistribution", "George et al. Figures 6 and 7: error against time after an edit");
    benchRedist->add_option("--cases", redist.cases, "cube-room and/or robot-room");
    benchRedist->add_option("--scene-dir", redist.sceneDir, "folder with the scenes");
    benchRedist->add_option("--reference-eps", redist.referenceEps,
                            "convergence of the references");
    benchRedist->add_option("--max-ms", redist.maxMs, "solver time per method");
    benchRedist->add_option("--plot-dir", redist.plotDir, "write error-vs-time plots (PNG) here");
    benchRedist->add_option("--json", redist.jsonOut, "write every sample as JSON");
    benchRedist->add_option("--reference-cache", redist.referenceCache,
                            "read the converged references from PATH-<scene>, or write them");
    benchRedist->add_flag("--split", redist.split,
                          "print the top-1% error on the added objects and on the rest");
    DisplayBenchOptions& display = c.display;
    HifiBenchOptions& hifi = c.hifi;
    CLI::App* benchHifi = c.benchHifi = app.add_subcommand(
        "hifi", "Hardt & Teller: interpolant build, evaluation fps, error against reference");
    benchHifi->add_option("--cases", hifi.cases,
                          "scenes by name: SCENE-DIR/NAME.json, else SCENE-DIR/gltf/NAME.glb "
                          "(default: cornell-box cube-room)");
    benchHifi->add_option("--scene-dir", hifi.sceneDir, "folder with the scenes");
    benchHifi->add_option("--width", hifi.width)->check(CLI::Range(8, 8192));
    benchHifi->add_option("--height", hifi.height)->check(CLI::Range(8, 8192));
    benchHifi->add_option("--frames", hifi.frames)->check(CLI::Range(1, 100000));
    benchHifi->add_option("--plot-dir", hifi.plotDir, "write the error images there");
    benchHifi->add_option("--json", hifi.jsonOut, "write every figure as JSON");
    benchHifi
        ->add_option("--reference-spp", hifi.referenceSpp,
                     "paths per pixel of the path-traced reference the path tracer races the "
                     "interpolants against (0: no race; default 1024)")
        ->check(CLI::Range(0, 1 << 20));
    benchHifi->add_option("--compare-width", hifi.compareWidth, "the race's picture size")
        ->check(CLI::Range(8, 8192));
    benchHifi->add_option("--compare-height", hifi.compareHeight)->check(CLI::Range(8, 8192));
    benchHifi
        ->add_option("--compare-samples", hifi.compareSamples,
                     "the interpolants' samples per pixel per axis in the race (default 2)")
        ->check(CLI::Range(1, 16));
    benchHifi
        ->add_option("--pathtrace-max-seconds", hifi.pathTraceMaxSeconds,
                     "stop the path tracer's doubling after this many seconds of tracing")
        ->check(CLI::Range(0.0, 1e7));
    benchHifi->add_option("--reference-cache", hifi.referenceCache,
                          "read the path-traced references from PATH-<scene>-<W>x<H>-<N>spp.exr, "
                          "or write them there");

    HolodeckBenchOptions& holo = c.benchHolodeckOptions;
    CLI::App* benchHolodeck = c.benchHolodeck = app.add_subcommand(
        "holodeck",
        "Ward & Simmons: fill rate, bytes per sample, view samples from disk and memory");
    benchHolodeck->add_option("--cases", holo.cases,
                              "scenes by name (default: cube-room robot-room)");
    benchHolodeck->add_option("--scene-dir", holo.sceneDir, "folder with the scenes");
    benchHolodeck->add_option("--samples", holo.samples, "samples of the batch fill")
        ->check(CLI::Range(std::int64_t(1), std::int64_t(1) << 40));
    benchHolodeck->add_option("--width", holo.width)->check(CLI::Range(8, 8192));
    benchHolodeck->add_option("--height", holo.height)->check(CLI::Range(8, 8192));
    benchHolodeck
        ->add_option("--generic-seconds", holo.genericSeconds,
                     "fill a holodeck for no view this long, then open nine views from it "
                     "(default 60; 0: skip)")
        ->check(CLI::Range(0.0, 1e6));
    benchHolodeck
        ->add_option("--generic-samples", holo.genericSamples,
                     "fill the holodeck for no view with this many samples instead of for "
                     "--generic-seconds")
        ->check(CLI::Range(std::int64_t(0), std::int64_t(1) << 40));
    benchHolodeck->add_flag_callback(
        "--no-mpirun", [&holo] { holo.ranks.clear(); }, "skip the batch fills under mpirun");
    benchHolodeck->add_option("--generic-holodeck", holo.genericFile,
                              "the generic fill's file: filled and kept when missing, else reused");
    benchHolodeck->add_option("--json", holo.jsonOut, "write every figure as JSON");

    CLI::App* benchDisplay = c.benchDisplay = app.add_subcommand(
        "display", "Bala et al. Table 2: display stage times, fps, epi vs cache error");
    benchDisplay->add_option("--cases", display.cases, "robot-room and/or armadillo-field");
    benchDisplay->add_option("--scene-dir", display.sceneDir, "folder with the scenes");
    benchDisplay->add_option("--width", display.width)->check(CLI::Range(8, 8192));
    benchDisplay->add_option("--height", display.height)->check(CLI::Range(8, 8192));
    benchDisplay->add_option("--frames", display.frames)->check(CLI::Range(2, 100000));
    benchDisplay->add_option("--sample-fraction", display.sampleFraction)
        ->check(CLI::Range(0.0, 1.0));
    benchDisplay->add_option("--warmup", display.warmup)->check(CLI::Range(0.0, 1.0));
    benchDisplay->add_option("--plot-dir", display.plotDir,
                             "write display-cache.png / display-epi.png (same samples) here");
    benchDisplay->add_option("--json", display.jsonOut, "write every frame as JSON");
    benchDisplay
        ->add_option("--shadow-refine", display.shadowRefine,
                     "display shader: adaptive shadow refinement factor (0 = off)")
        ->check(CLI::Range(0, 64));
    benchDisplay
        ->add_option("--shadow-max-refined", display.shadowMaxRefined,
                     "display shader: refined shadow strata per axis at most")
        ->check(CLI::Range(1, 256));
    benchDisplay
        ->add_option("--shadow-decision", display.shadowDecision,
                     "display shader: decision shadow rays per axis")
        ->check(CLI::Range(1, 64));
    addReconstructionOptions(benchDisplay, display.smoothRadius, display.maxPenumbraPixels);
    std::ostringstream capacityDefault;
    capacityDefault << InteractiveDisplayOptions{}.cacheCapacityPerPixel;
    benchDisplay
        ->add_option("--cache-capacity", display.cacheCapacity,
                     "render cache points per pixel (default " + capacityDefault.str() + ")")
        ->check(CLI::Range(0.1, 16.0));
    benchDisplay->add_flag("--reference-check", display.referenceCheck,
                           "render two converged references (different seeds): their noise");
    benchDisplay->add_flag("--no-converged-reference", display.skipConvergedReference,
                           "errors against the plain reference only (no converged one)");
}

}  // namespace

int main(int argc, char** argv) {
    // OpenMesh reports non-manifold faces it cannot link on its own error stream; Penumbra
    // reports its errors.
    omerr().disable();
    CLI::App app{"Penumbra benchmarks: figures and ratios against baselines of the same run"};
    app.name("penumbra bench");
    app.require_subcommand(1);
    bool verbose = false;
    app.add_flag("--verbose", verbose, "debug lines on stderr (what runs, and how long it takes)");
    BenchCommands c;
    addBenchCommands(app, c);
    if (const int status = parseCommandLine(app, argc, argv, "penumbra bench"); status >= 0)
        return status;
    initLogging(verbose);
    try {
        if (*c.benchSolver) return runSolverBench(c.bench);
        if (*c.benchRedist) return runRedistributionBench(c.redist);
        if (*c.benchDisplay) return runDisplayBench(c.display);
        if (*c.benchHifi) return runHifiBench(c.hifi);
        if (*c.benchHolodeck) return runHolodeckBench(c.benchHolodeckOptions);
    } catch (const std::exception& e) {
        std::fprintf(stderr, "penumbra bench: %s\n", e.what());
        return 2;
    }
    return 2;
}
