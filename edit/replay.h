#pragma once
// `penumbra replay` (DESIGN.md "Command line"): replays an edit log over a scene for
// regression, with per-edit solver cost, George et al.'s eq. 7 error against from-scratch
// references, and comparison with a golden report.

#include <cstdint>
#include <functional>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>

#include "edit/io/scene_import.h"
#include "solver/edit_event.h"
#include "solver/progressive_solver.h"

namespace penumbra {

class EditSession;

struct ReplayOptions {
    std::string scenePath;
    std::string logPath;
    /// Shots spent after every line that is not solve/converge (an interactive budget).
    int budgetShots = 0;
    /// The scene is converged to this before the first line.
    double converge = 1e-3;
    /// Solver configuration of the session (seed, stochastic tail...). References use it too,
    /// without subdivision: the tail's cost does not grow with the element count, so a
    /// robot-room reference takes seconds where a deterministic one took minutes.
    SolverOptions solver = interactiveSolverOptions();
    /// Convergence of the references (the unshot fraction they stop at); < 0: `converge`.
    double referenceEps = -1;
    /// Compute a from-scratch reference after every line that changes the lit scene and
    /// report "error_rms" and "error_top1".
    bool reference = false;
    /// After the last line: probe points ("x y z nx ny nz" per line; irradiance goes to the
    /// report's "points"), export of the lit scene, and the edited scene.
    std::string pointsPath;
    std::string exportPath;
    std::string saveScenePath;
    /// How a glTF or OBJ scene is imported.
    ImportOptions import;
    /// Cap on shots of any one convergence.
    std::uint64_t maxShots = 100000000;
    /// Called once the scene is converged, before the first line, and after every line (its
    /// shots spent) with that line's report entry, to which it may add: the command line's
    /// holodeck forgets what each edit changed there. Either may be empty.
    std::function<void(EditSession&)> afterConverge;
    std::function<void(EditSession&, const EditEvent&, nlohmann::json& entry)> afterEdit;
};

/// Replays the log (see ReplayOptions) and returns the report: shots, rays, seconds (solver
/// time, references excluded), unshot_fraction, elements, patches, and "edits", one object
/// per log line with "line", "op", "shots", "rays", "ms", "checksum" (Σ Y·A over elements in
/// the solution after the line), "objects" (the same sum per object id), "unshot_fraction",
/// "error_estimate" (ProgressiveSolver::computeSettlingSummary: no reference needed),
/// "estimate_ms" (its time, not in "ms"; the report's "estimate_seconds" sums them), and
/// with a reference "estimate_coverage" (the fraction of elements whose change to the
/// reference the estimate bounds), "error_rms" and
/// "error_top1" (George et al. eq. 7 over all elements in the solution, and over the 1% whose
/// reference luminance changed most with the last edit that changed the lit scene; 0 before
/// any such edit; while an object is selected it is out of both the solution and the
/// reference). Bad input (scene, log, an edit naming an unknown id...) throws InputError
/// naming the file and line.
nlohmann::json runReplay(const ReplayOptions& options);

/// Reads a golden report written by `replay --report`. Throws InputError.
nlohmann::json readReplayReport(const std::string& path);

/// Compares a replay report with a golden one: per edit the op and shots exactly, checksum
/// within relative `checksumTolerance` (default 1e-9), error_rms within 1e-6 when both have
/// it, and the number of edits. Returns one line naming the first differing edit (line, op,
/// field, both values; for a checksum, the objects whose lighting changed most and by how
/// much, when both reports have per-object sums), or nullopt when they agree. `goldenName` names
/// the golden report in the message.
std::optional<std::string> compareReplayReports(const nlohmann::json& report,
                                                const nlohmann::json& golden,
                                                const std::string& goldenName,
                                                double checksumTolerance = 1e-9);

}  // namespace penumbra
