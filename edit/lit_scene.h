#pragma once
// A scene opened for lighting: the document, its discretization, the Embree tracer and the
// progressive solver, built in that order. The command line and (later) the editor session
// hold one of these.

#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

// writeFileAtomically: saveSolution's, and the one for callers that write files of their own
// beside a lit scene's.
#include "core/durable_file.h"
#include "edit/io/scene_import.h"
#include "solver/discretization.h"
#include "solver/progressive_solver.h"
#include "solver/ray_tracer.h"
#include "solver/scene.h"

namespace penumbra {

class LitScene {
public:
    /// Loads `path` (throws InputError for bad input, naming the file and key; a glTF or OBJ
    /// scene is imported with `import`) and builds the discretization, tracer and solver.
    static std::unique_ptr<LitScene> open(const std::string& path, const SolverOptions& options,
                                          const ImportOptions& import = {});
    /// Builds from a scene already in memory; `sourceName` names it in error messages.
    LitScene(Scene scene, const SolverOptions& options, const std::string& sourceName);

    Scene& scene() { return mScene; }
    const Scene& scene() const { return mScene; }
    Discretization& discretization() { return *mDisc; }
    RayTracer& tracer() { return *mTracer; }
    const RayTracer& tracer() const { return *mTracer; }
    ProgressiveSolver& solver() { return *mSolver; }
    const ProgressiveSolver& solver() const { return *mSolver; }

    /// The `--report` fields every command shares: shots, rays, seconds, unshot_fraction,
    /// elements, patches (DESIGN.md), plus subdivisions and emitted energy.
    nlohmann::json reportJson() const;

private:
    Scene mScene;
    std::unique_ptr<Discretization> mDisc;
    std::unique_ptr<RayTracer> mTracer;
    std::unique_ptr<ProgressiveSolver> mSolver;
};

/// Reads "x y z nx ny nz" per line (blank lines and '#' comments skipped). Throws InputError
/// naming the file and line for a malformed line, a non-finite number or a zero normal.
struct ProbePoint {
    Vec3 position;
    Vec3 normal;
};
std::vector<ProbePoint> readProbePoints(const std::string& path);

/// Writes the element radiosities and unshot patch radiosities as JSON
/// ("penumbra-solution/1") with writeFileAtomically. Throws InputError naming the file when it
/// cannot be written.
void saveSolution(const LitScene& lit, const std::string& path);

}  // namespace penumbra
