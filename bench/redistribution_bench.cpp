// `penumbra bench redistribution`: George et al. 1990 Figures 6 and 7 on cube-room (add a
// cube on the table) and robot-room (add the robot). Error (eq. 7, all elements and the 1%
// that change most) against time after the edit for
//   (a) redistribution,
//   (b) progressive refinement from scratch,
//   (c) the old solution with the object inserted and only new unshot energy propagated,
// all on the same discretization, against a converged from-scratch reference; and, per sample,
// the solver's settling estimate of the error next to the true one (issue 44).
//
// Index: cases · error · one method run · plot · table
#include <tbb/global_control.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "bench/bench.h"
#include "core/durable_file.h"
#include "core/log.h"
#include "edit/io/scene_io.h"
#include "edit/lit_scene.h"
#include "render/image.h"

namespace penumbra {

namespace {

using Clock = std::chrono::steady_clock;

struct Case {
    std::string name;
    Scene base;
    std::vector<SceneObject> added;
};

Case cubeRoomCase(const std::string& dir) {
    Case c;
    c.name = "cube-room";
    c.base = loadScene(dir + "/cube-room.json");
    SceneObject cube;
    cube.id = "cube";
    cube.shape.type = ShapeType::Box;
    cube.shape.size = Vec3(0.35);
    cube.material = c.base.materials.front().name;
    // On the table top (upper face at y = 0.75, centred at x = 0, z = -0.2).
    cube.transform.translate = Vec3(0.15, 0.75 + 0.175, -0.25);
    cube.transform.rotateDeg = Vec3(0, 30, 0);
    c.added.push_back(cube);
    return c;
}

Case robotRoomCase(const std::string& dir) {
    Case c;
    c.name = "robot-room";
    c.base = loadScene(dir + "/robot-room-empty.json");
    Scene full = loadScene(dir + "/robot-room.json");
    for (const SceneObject& o : full.objects)
        if (o.id.rfind("robot", 0) == 0) c.added.push_back(o);
    return c;
}

/// Luminance per element of the alive elements (0 for dead ones).
std::vector<double> luminances(const Discretization& disc, const std::vector<Rgb>& b) {
    std::vector<double> y(b.size(), 0.0);
    for (std::size_t e = 0; e < b.size(); ++e)
        if (disc.elementAlive(static_cast<int>(e))) y[e] = luminance(b[e]);
    return y;
}

/// George et al. eq. 7 over `subset` (all alive elements when empty).
double eq7(const Discretization& disc, const std::vector<double>& ref,
           const std::vector<double>& cur, const std::vector<int>& subset) {
    double num = 0, den = 0;
    auto add = [&](std::size_t e) {
        double a = disc.elements()[e].area;
        num += (ref[e] - cur[e]) * (ref[e] - cur[e]) * a;
        den += ref[e] * ref[e] * a;
    };
    if (subset.empty()) {
        for (std::size_t e = 0; e < ref.size(); ++e)
            if (disc.elementAlive(static_cast<int>(e))) add(e);
    } else {
        for (int e : subset) add(static_cast<std::size_t>(e));
    }
    return den > 0 ? std::sqrt(num / den) : 0;
}

struct Sample {
    double ms;
    std::uint64_t shots;
    double all, top1;
    /// The solver's own estimate of `all` without the reference
    /// (ProgressiveSolver::computeSettling's relativeRms).
    double estimate;
};

struct World {
    Scene scene;
    std::unique_ptr<Discretization> disc;
    std::unique_ptr<RayTracer> tracer;
    std::vector<int> versions;  ///< the added objects' versions
    void setAdded(bool alive) {
        for (int v : versions) {
            disc->setAlive(v, alive);
            tracer->updateAlive(v);
        }
    }
};

/// Steps `solver` and samples the error at geometrically spaced shot counts; the time spent
/// measuring is not counted.
std::vector<Sample> run(ProgressiveSolver& solver, const World& w, const std::vector<double>& ref,
                        const std::vector<int>& top1, double maxMs, double startMs, bool split) {
    std::vector<Sample> out;
    double ms = startMs;
    std::uint64_t shots = 0, next = 1;
    auto record = [&] {
        auto y = luminances(*w.disc, solver.radiosity());
        out.push_back({ms, shots, eq7(*w.disc, ref, y, {}), eq7(*w.disc, ref, y, top1),
                       solver.computeSettling().relativeRms});
        if (split) {
            std::vector<int> on, off;
            for (int e : top1)
                (std::find(w.versions.begin(), w.versions.end(), w.disc->elements()[e].object) !=
                         w.versions.end()
                     ? on
                     : off)
                    .push_back(e);
            double num[2] = {0, 0}, den = 0;
            for (int e : top1) {
                double a = w.disc->elements()[e].area;
                den += ref[e] * ref[e] * a;
            }
            for (int k = 0; k < 2; ++k)
                for (int e : k ? off : on) {
                    double a = w.disc->elements()[e].area;
                    num[k] += (ref[e] - y[e]) * (ref[e] - y[e]) * a;
                }
            std::fprintf(stderr,
                         "  %.1f ms shots %llu top1 %.4f: added %zu el %.4f, others %zu el %.4f\n",
                         ms, static_cast<unsigned long long>(shots), out.back().top1, on.size(),
                         std::sqrt(num[0] / den), off.size(), std::sqrt(num[1] / den));
        }
    };
    record();
    while (ms < maxMs) {
        auto t0 = Clock::now();
        int done = solver.step(1);
        ms += std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
        if (done == 0) break;
        shots += 1;
        if (shots >= next) {
            record();
            next = std::max<std::uint64_t>(next + 1, static_cast<std::uint64_t>(next * 1.25));
        }
    }
    record();
    return out;
}

double timeTo(const std::vector<Sample>& s, double topLimit) {
    for (const Sample& x : s)
        if (x.top1 <= topLimit) return x.ms;
    return -1;
}

double errorAtShots(const std::vector<Sample>& s, std::uint64_t shots, bool top) {
    double v = s.empty() ? 0 : (top ? s.front().top1 : s.front().all);
    for (const Sample& x : s)
        if (x.shots <= shots) v = top ? x.top1 : x.all;
    return v;
}

/// A polyline of (milliseconds, error) points and its colour.
struct Series {
    std::vector<std::pair<double, double>> points;
    Rgb colour;
};

/// A log-log plot of error (1e-3 to 1) against milliseconds (0.1 to 1e5), one polyline per
/// series, with the 10% goal drawn as a grey line.
void plotLogLog(const std::vector<Series>& series, const std::string& path) {
    const int W = 640, H = 400, pad = 40;
    Image img(W, H, Rgb(1.0));
    double lo = 0.1, hi = 1e5;  // ms
    auto px = [&](double ms) {
        double t =
            (std::log10(std::max(ms, lo)) - std::log10(lo)) / (std::log10(hi) - std::log10(lo));
        return pad + t * (W - 2 * pad);
    };
    auto py = [&](double err) {  // 1e-3 .. 1
        double t = (std::log10(std::clamp(err, 1e-3, 1.0)) + 3) / 3;
        return H - pad - t * (H - 2 * pad);
    };
    auto line = [&](double x0, double y0, double x1, double y1, Rgb c) {
        int n = static_cast<int>(std::max(std::abs(x1 - x0), std::abs(y1 - y0))) + 1;
        for (int k = 0; k <= n; ++k) {
            int x = static_cast<int>(x0 + (x1 - x0) * k / n),
                y = static_cast<int>(y0 + (y1 - y0) * k / n);
            for (int dy = 0; dy < 2; ++dy)
                if (x >= 0 && x < W && y + dy >= 0 && y + dy < H) img.at(x, y + dy) = c;
        }
    };
    // Axes and decade grid.
    for (double d = 0.1; d <= hi; d *= 10) line(px(d), pad, px(d), H - pad, Rgb(0.85));
    for (double e = 1e-3; e <= 1.0; e *= 10) line(pad, py(e), W - pad, py(e), Rgb(0.85));
    line(px(0.1) - 1, py(0.1), W - pad, py(0.1), Rgb(0.6, 0.6, 0.6));  // the 10% goal
    for (const Series& s : series)
        for (std::size_t k = 1; k < s.points.size(); ++k)
            line(px(s.points[k - 1].first), py(s.points[k - 1].second), px(s.points[k].first),
                 py(s.points[k].second), s.colour);
    // sRGB-encoded values were chosen by eye: convert to linear for writePng.
    for (Rgb& p : img.pixels) p = Rgb(srgbDecode(p.x), srgbDecode(p.y), srgbDecode(p.z));
    writePng(img, path);
}

/// George et al.'s Figures 6 and 7: the top-1% error of each method (red: redistribution,
/// blue: from scratch, green: insert only).
void plot(const std::vector<std::vector<Sample>>& runs, const std::string& path) {
    const Rgb colours[3] = {Rgb(0.8, 0.1, 0.1), Rgb(0.1, 0.2, 0.8), Rgb(0.1, 0.6, 0.1)};
    std::vector<Series> series;
    for (std::size_t r = 0; r < runs.size(); ++r) {
        series.push_back({{}, colours[r % 3]});
        for (const Sample& x : runs[r]) series.back().points.push_back({x.ms, x.top1});
    }
    plotLogLog(series, path);
}

/// The settling estimate against the truth after the edit, redistributing: the error over
/// every element against the reference (red) and the solver's estimate of it (blue).
void plotSettling(const std::vector<Sample>& run, const std::string& path) {
    Series truth{{}, Rgb(0.8, 0.1, 0.1)}, estimate{{}, Rgb(0.1, 0.2, 0.8)};
    for (const Sample& x : run) {
        truth.points.push_back({x.ms, x.all});
        estimate.points.push_back({x.ms, x.estimate});
    }
    plotLogLog({truth, estimate}, path);
}

/// The smallest and largest estimate / truth over the samples still settling: the true error
/// above twice its floor (the last sample's, the converged solution's sampling noise against
/// the reference, which the estimate's change part leaves out by design).
std::pair<double, double> estimateRatios(const std::vector<Sample>& run) {
    double lo = 0, hi = 0;
    const double floor = run.empty() ? 0.0 : run.back().all;
    for (const Sample& x : run) {
        if (!(x.all > 2 * floor)) continue;
        const double r = x.estimate / x.all;
        lo = lo > 0 ? std::min(lo, r) : r;
        hi = std::max(hi, r);
    }
    return {lo, hi};
}

}  // namespace

int runRedistributionBench(const RedistributionBenchOptions& options) {
    nlohmann::json report = nlohmann::json::array();
    std::printf(
        "| scene | method | to top-1%% ≤ 10%% (ms) | top-1%% after 2 shots | after 50 | all after "
        "50 | speedup vs (b) |\n");
    std::printf("|---|---|---|---|---|---|---|\n");
    std::vector<Case> cases;
    for (const std::string& name : options.cases)
        cases.push_back(name == "robot-room" ? robotRoomCase(options.sceneDir)
                                             : cubeRoomCase(options.sceneDir));
    for (Case& c : cases) {
        World w;
        w.scene = c.base;
        w.disc = std::make_unique<Discretization>(w.scene);
        for (const SceneObject& o : c.added) w.versions.push_back(w.disc->addObject(w.scene, o));
        for (int v : w.versions) w.disc->setAlive(v, false);
        w.tracer = std::make_unique<RayTracer>(*w.disc);

        // Converged references before and after, from scratch, on this discretization.
        std::vector<double> yAfter, yBefore;
        const bool cache = !options.referenceCache.empty();
        const std::string cachePath = options.referenceCache + "-" + c.name;
        if (FILE* f = cache ? std::fopen(cachePath.c_str(), "rb") : nullptr) {
            std::size_t n = 0;
            if (std::fread(&n, sizeof n, 1, f) == 1) {
                yAfter.resize(n), yBefore.resize(n);
                if (std::fread(yAfter.data(), sizeof(double), n, f) != n ||
                    std::fread(yBefore.data(), sizeof(double), n, f) != n)
                    yAfter.clear();
            }
            std::fclose(f);
        }
        if (yAfter.empty()) {
            SolverOptions refOptions = interactiveSolverOptions();
            refOptions.raysPerEmittedPower *= 4;
            ProgressiveSolver before(*w.disc, *w.tracer, refOptions);
            before.converge(options.referenceEps, 100000000);
            w.setAdded(true);
            ProgressiveSolver after(*w.disc, *w.tracer, refOptions);
            after.converge(options.referenceEps, 100000000);
            yAfter = luminances(*w.disc, after.radiosity());
            w.setAdded(false);
            yBefore = luminances(*w.disc, before.radiosity());
            yBefore.resize(yAfter.size(), 0.0);
            if (cache) {
                // Whole or not at all: a torn cache would read as a shorter reference.
                const std::size_t n = yAfter.size();
                std::string bytes(reinterpret_cast<const char*>(&n), sizeof n);
                bytes.append(reinterpret_cast<const char*>(yAfter.data()), n * sizeof(double));
                bytes.append(reinterpret_cast<const char*>(yBefore.data()), n * sizeof(double));
                try {
                    writeFileAtomically(cachePath, bytes);
                } catch (const std::exception& e) {
                    spdlog::warn("reference cache not written: {}", e.what());
                }
            }
        }
        // The 1% of alive elements that change most (George et al.'s second error term).
        std::vector<int> order;
        for (std::size_t e = 0; e < yAfter.size(); ++e)
            if (w.disc->elementAlive(static_cast<int>(e)) ||
                std::find(w.versions.begin(), w.versions.end(), w.disc->elements()[e].object) !=
                    w.versions.end())
                order.push_back(static_cast<int>(e));
        std::sort(order.begin(), order.end(), [&](int a, int b) {
            return std::abs(yAfter[a] - yBefore[a]) > std::abs(yAfter[b] - yBefore[b]);
        });
        order.resize(std::max<std::size_t>(1, order.size() / 100));

        // (a) and (c) start from the solution before the edit, solved as the editor would.
        std::vector<std::vector<Sample>> runs;
        const char* names[3] = {"(a) redistribution", "(b) from scratch", "(c) insert only"};
        for (int method = 0; method < 3; ++method) {
            w.setAdded(false);
            auto solver =
                std::make_unique<ProgressiveSolver>(*w.disc, *w.tracer, interactiveSolverOptions());
            if (method != 1) solver->converge(options.referenceEps, 100000000);
            w.setAdded(true);
            auto t0 = Clock::now();
            if (method == 1)
                solver = std::make_unique<ProgressiveSolver>(*w.disc, *w.tracer,
                                                             interactiveSolverOptions());
            else
                solver->applyChange({{}, w.versions}, method == 0);
            double setupMs = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
            runs.push_back(run(*solver, w, yAfter, order, options.maxMs, setupMs, options.split));
        }
        double tb = timeTo(runs[1], 0.10);
        for (int method = 0; method < 3; ++method) {
            double t = timeTo(runs[method], 0.10);
            char speed[32] = "—";
            if (t > 0 && tb > 0) std::snprintf(speed, sizeof speed, "%.0f×", tb / t);
            char tt[32] = "not reached";
            if (t >= 0) std::snprintf(tt, sizeof tt, "%.1f", t);
            std::printf("| %s | %s | %s | %.3f | %.3f | %.4f | %s |\n", c.name.c_str(),
                        names[method], tt, errorAtShots(runs[method], 2, true),
                        errorAtShots(runs[method], 50, true), errorAtShots(runs[method], 50, false),
                        speed);
            nlohmann::json samples = nlohmann::json::array();
            for (const Sample& s : runs[method])
                samples.push_back({{"ms", s.ms},
                                   {"shots", s.shots},
                                   {"error_rms", s.all},
                                   {"error_top1", s.top1},
                                   {"error_estimate", s.estimate}});
            report.push_back({{"scene", c.name},
                              {"method", names[method]},
                              {"ms_to_top1_10pct", t},
                              {"samples", samples}});
        }
        const auto [lo, hi] = estimateRatios(runs[0]);
        std::printf(
            "| %s | settling estimate / true error_rms, settling (redistribution) | "
            "%.2f–%.2f | | | | |\n",
            c.name.c_str(), lo, hi);
        std::fflush(stdout);
        if (!options.plotDir.empty()) {
            plot(runs, options.plotDir + "/redistribution-" + c.name + ".png");
            plotSettling(runs[0], options.plotDir + "/settling-" + c.name + ".png");
        }
    }
    if (!options.jsonOut.empty()) writeFileAtomically(options.jsonOut, report.dump(1) + "\n");
    return 0;
}

}  // namespace penumbra
