#pragma once
// What the command lines share (app/penumbra.cpp, app/holodeck_commands.cpp, and
// app/penumbra_bench.cpp): the scene and solver options, opening and solving a scene, reports,
// cameras, the display's reconstruction options, parsing.

#include <CLI/CLI.hpp>
#include <cstdint>
#include <functional>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>

#include "app/import_flags.h"
#include "edit/lit_scene.h"

namespace penumbra::cli {

struct SolveArgs {
    std::string scene;
    double converge = 1e-3;
    std::uint64_t maxShots = 1000000;
    int threads = 0;
    std::uint64_t seed = 1;
    double subdivide = 0;
    double stochasticBelow = interactiveSolverOptions().stochasticBelow;
    std::string save, exportPath, report, saveScene;
    ImportOptions import;
    bool exportHifi = false;  ///< export: the interpolants' triangles instead of the elements
    int gatherRays = 256;     ///< interpolants: ExactIrradianceOptions::farRays
};

inline constexpr const char* kSceneHelp = "scene file (*.json, or *.gltf *.glb *.obj to import)";

/// SCENE and the solver's options.
void addSolveOptions(CLI::App* cmd, SolveArgs& a);
/// Progress on stderr when it is a terminal.
std::function<void(double)> progressPrinter(double eps);
/// The solver's options as the command line sets them.
SolverOptions solverOptionsOf(const SolveArgs& a);
/// The scene opened (or imported) and solved to --converge.
std::unique_ptr<LitScene> openAndSolve(const SolveArgs& a);
/// The report written to `path` (written atomically; nothing for an empty path).
void writeReport(const std::string& path, const nlohmann::json& report);
/// The camera `name` of the scene (InputError naming the scene when there is none), else its
/// "default" camera, its first, or a default one.
Camera pickCamera(const Scene& scene, const std::string& scenePath, const std::string& name);
/// The holodeck beside a scene: its path with the extension .hdk.
std::string defaultHolodeckPath(const std::string& scene);
/// The EPI reconstruction options `render` and `bench display` share: `--smooth R` and
/// `--max-penumbra W`.
void addReconstructionOptions(CLI::App* cmd, int& smooth, double& maxPenumbraPixels);
/// Parses the command line: −1 when it parsed, else the exit status (0 after --help; 2 after
/// one error line "PROGRAM: what" on stderr).
int parseCommandLine(CLI::App& app, int argc, char** argv, const char* program);

}  // namespace penumbra::cli
