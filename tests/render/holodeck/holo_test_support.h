#pragma once
// What the holodeck tests share: a fresh path for a test's file, and makeLitRoom solved with a
// synchronous point shader over it.

#include <unistd.h>

#include <filesystem>
#include <memory>
#include <string>

#include "render/display/point_shader.h"
#include "solver/discretization.h"
#include "solver/progressive_solver.h"
#include "solver/ray_tracer.h"
#include "test_scenes.h"

namespace penumbra::test {

/// `name` in a folder of the test's own under the system's temporary folder (the process id
/// keeps concurrent runs apart), removed if present.
inline std::string holoTempFile(const std::string& test, const std::string& name) {
    namespace fs = std::filesystem;
    const fs::path dir =
        fs::temp_directory_path() / ("penumbra_" + test + "_" + std::to_string(::getpid()));
    fs::create_directories(dir);
    const fs::path file = dir / name;
    fs::remove(file);
    return file.string();
}

/// makeLitRoom solved, and a synchronous point shader over it.
struct LitRoom {
    Scene scene = makeLitRoom("red");
    Discretization disc{scene};
    RayTracer tracer{disc};
    SolverOptions options;
    ProgressiveSolver solver{disc, tracer, options};
    std::unique_ptr<PointShader> shader;
    LitRoom() {
        solver.converge(1e-3, 100000);
        PointShaderOptions o;
        o.threads = 0;
        shader = std::make_unique<PointShader>(disc, tracer, options, o);
        shader->updateSolution(solver);
    }
};

}  // namespace penumbra::test
