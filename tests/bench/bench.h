#pragma once
// Benchmarks behind `penumbra bench`: each prints figures and ratios against a baseline
// measured in the same run (STYLE: speed lives in benchmarks, never in timed tests).

#include <string>
#include <vector>

#include "solver/progressive_solver.h"

namespace penumbra {

struct BenchOptions {
    std::vector<std::string> scenes;
    double maxSecondsPerScene = 120;  ///< solver time cap per scene
    std::string jsonOut;              ///< optional JSON with every figure
};

/// `penumbra bench solver`: raw Embree occlusion rays/s vs solver rays/s, time to 10%, 1%,
/// 0.1% unshot energy, peak memory, per scene. Returns the process exit status.
int runSolverBench(const BenchOptions& options);

struct RedistributionBenchOptions {
    std::vector<std::string> cases{"cube-room", "robot-room"};
    std::string sceneDir = "scenes";
    double referenceEps = 1e-3;  ///< convergence of the references and the starting solution
    double maxMs = 20000;        ///< solver time per method run
    std::string plotDir;         ///< writes redistribution-<scene>.png there when set
    std::string jsonOut;
};

/// `penumbra bench redistribution`: George et al. Figures 6 and 7 — error against time after
/// adding an object, for redistribution, from-scratch progressive refinement, and insertion
/// without redistribution.
int runRedistributionBench(const RedistributionBenchOptions& options);

}  // namespace penumbra
