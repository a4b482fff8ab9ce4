// The command line's shared options and helpers; see app/cli_common.h.
#include "app/cli_common.h"

#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <sstream>

#include "core/durable_file.h"
#include "core/input_error.h"
#include "render/display/interactive_display.h"

namespace penumbra::cli {

void addSolveOptions(CLI::App* cmd, SolveArgs& a) {
    cmd->add_option("SCENE", a.scene, kSceneHelp)->required();
    addImportFlags(cmd, a.import);
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

SolverOptions solverOptionsOf(const SolveArgs& a) {
    SolverOptions options = interactiveSolverOptions();
    options.seed = a.seed;
    options.stochasticBelow = a.stochasticBelow;
    options.gradientThreshold = a.subdivide;
    return options;
}

std::unique_ptr<LitScene> openAndSolve(const SolveArgs& a) {
    auto lit = LitScene::open(a.scene, solverOptionsOf(a), a.import);
    lit->solver().converge(a.converge, a.maxShots, progressPrinter(a.converge));
    if (isatty(STDERR_FILENO)) std::fprintf(stderr, "\n");
    return lit;
}

void writeReport(const std::string& path, const nlohmann::json& report) {
    if (!path.empty()) writeFileAtomically(path, report.dump(2) + "\n");
}

Camera pickCamera(const Scene& scene, const std::string& scenePath, const std::string& name) {
    if (!name.empty()) {
        const Camera* c = scene.findCamera(name);
        if (!c) throw InputError(scenePath, "cameras", "no camera named '" + name + "'");
        return *c;
    }
    if (const Camera* c = scene.findCamera("default")) return *c;
    if (!scene.cameras.empty()) return scene.cameras.front();
    return Camera{};
}

std::string defaultHolodeckPath(const std::string& scene) {
    return std::filesystem::path(scene).replace_extension(".hdk").string();
}

void addReconstructionOptions(CLI::App* cmd, int& smooth, double& maxPenumbraPixels) {
    cmd->add_option("--smooth", smooth,
                    "epi: edge-free smoothing radius in pixels, 0 = the paper's reconstruction "
                    "(default " +
                        std::to_string(displayEpiOptions().smoothRadius) + ")")
        ->check(CLI::Range(0, 60));
    std::ostringstream penumbraDefault;
    penumbraDefault << InteractiveDisplayOptions{}.maxPenumbraPixels;
    cmd->add_option("--max-penumbra", maxPenumbraPixels,
                    "epi: soft shadow edges mark the image only where their penumbra is at most "
                    "this many pixels wide, 0 = every shadow edge as in the paper (default " +
                        penumbraDefault.str() + ")")
        ->check(CLI::Range(0.0, 1e6));
}

int parseCommandLine(CLI::App& app, int argc, char** argv, const char* program) {
    try {
        app.parse(argc, argv);
    } catch (const CLI::CallForHelp& e) {
        return app.exit(e);
    } catch (const CLI::ParseError& e) {
        std::fprintf(stderr, "%s: %s\n", program, e.what());
        return 2;
    }
    return -1;
}

}  // namespace penumbra::cli
