#include "edit/lit_scene.h"

#include <cmath>
#include <fstream>
#include <sstream>
#include <stdexcept>

#include "core/durable_file.h"
#include "core/input_error.h"
#include "edit/io/scene_io.h"

namespace penumbra {

std::unique_ptr<LitScene> LitScene::open(const std::string& path, const SolverOptions& options,
                                         const ImportOptions& import) {
    return std::make_unique<LitScene>(loadScene(path, import), options, path);
}

LitScene::LitScene(Scene scene, const SolverOptions& options, const std::string& sourceName)
    : mScene(std::move(scene)) {
    try {
        mDisc = std::make_unique<Discretization>(mScene);
    } catch (const std::invalid_argument& e) {
        throw InputError(sourceName, "", e.what());
    }
    mTracer = std::make_unique<RayTracer>(*mDisc);
    mSolver = std::make_unique<ProgressiveSolver>(*mDisc, *mTracer, options);
}

nlohmann::json LitScene::reportJson() const {
    const SolverStats& s = mSolver->stats();
    return {{"shots", s.shots},
            {"rays", s.rays},
            {"seconds", s.seconds},
            {"unshot_fraction", mSolver->unshotFraction()},
            {"elements", mDisc->elements().size()},
            {"patches", mDisc->patches().size()},
            {"subdivisions", s.subdivisions},
            {"stochastic_batches", s.stochasticBatches},
            {"emitted_energy_w", mSolver->emittedEnergy()}};
}

std::vector<ProbePoint> readProbePoints(const std::string& path) {
    std::ifstream in(path);
    if (!in) throw InputError(path, "", "cannot open points file");
    std::vector<ProbePoint> points;
    std::string line;
    for (int lineNo = 1; std::getline(in, line); ++lineNo) {
        auto hash = line.find('#');
        if (hash != std::string::npos) line.erase(hash);
        std::istringstream fields(line);
        std::string first;
        if (!(fields >> first)) continue;
        fields.clear();
        fields.seekg(0);
        double v[6];
        for (double& x : v) {
            std::string tok;
            if (!(fields >> tok))
                throw InputError(path, "line " + std::to_string(lineNo),
                                 "expected 6 numbers \"x y z nx ny nz\"");
            char* end = nullptr;
            x = std::strtod(tok.c_str(), &end);
            if (end == tok.c_str() || *end != '\0')
                throw InputError(path, "line " + std::to_string(lineNo),
                                 "'" + tok + "' is not a number");
            if (!std::isfinite(x))
                throw InputError(path, "line " + std::to_string(lineNo),
                                 "non-finite number '" + tok + "'");
        }
        std::string extra;
        if (fields >> extra)
            throw InputError(path, "line " + std::to_string(lineNo), "more than 6 numbers");
        Vec3 n(v[3], v[4], v[5]);
        if (!(glm::length(n) > 0))
            throw InputError(path, "line " + std::to_string(lineNo), "zero normal");
        points.push_back({Vec3(v[0], v[1], v[2]), glm::normalize(n)});
    }
    return points;
}

void saveSolution(const LitScene& lit, const std::string& path) {
    nlohmann::json j;
    j["format"] = "penumbra-solution/1";
    j["elements"] = lit.solver().radiosity().size();
    nlohmann::json b = nlohmann::json::array();
    for (const Rgb& c : lit.solver().radiosity()) b.push_back({c.x, c.y, c.z});
    j["radiosity"] = std::move(b);
    nlohmann::json u = nlohmann::json::array();
    for (std::size_t p = 0; p < lit.solver().discretization().patches().size(); ++p) {
        const Rgb& c = lit.solver().unshotRadiosity(static_cast<int>(p));
        u.push_back({c.x, c.y, c.z});
    }
    j["unshot"] = std::move(u);
    j["report"] = lit.reportJson();
    writeFileAtomically(path, j.dump());
}

}  // namespace penumbra
