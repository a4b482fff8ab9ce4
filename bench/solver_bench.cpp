// `penumbra bench solver`: raw Embree occlusion throughput on each scene, the solver's own
// ray throughput and their ratio, time to 10%, 1% and 0.1% unshot energy, and peak memory.
// Each scene runs in a fresh child process (this executable, re-run) so its peak resident
// memory is its own. Not a fork: a child forked after oneTBB started its workers inherits
// none of them and runs every parallel loop on one thread.
//
// Index: measurements · Google Benchmark micro-benchmarks · table
#include <benchmark/benchmark.h>
#include <spawn.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>
#include <tbb/task_arena.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <mutex>
#include <nlohmann/json.hpp>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "bench/bench.h"
#include "core/durable_file.h"
#include "core/random.h"
#include "core/timing.h"
#include "edit/lit_scene.h"
#include "solver/form_factor.h"

namespace penumbra {

namespace {

/// Random element-to-element occlusion segments, the same kind of query a shot makes.
struct Segments {
    std::vector<Vec3> from, to;
};

Segments makeSegments(const Discretization& disc, std::size_t count) {
    Segments s;
    s.from.resize(count);
    s.to.resize(count);
    const auto& el = disc.elements();
    for (std::size_t i = 0; i < count; ++i) {
        std::uint64_t h = hashPair(0xbe7c4ull, i);
        const Element& a = el[h % el.size()];
        const Element& b = el[hashPair(h, 1) % el.size()];
        s.from[i] = a.centroid + a.normal * 1e-4;
        s.to[i] = b.centroid + b.normal * 1e-4;
    }
    return s;
}

/// Occlusion rays per second over all worker threads; `threads`, when given, receives the
/// number of distinct threads that traced.
double rawOcclusionRate(const RayTracer& tracer, const Segments& s, int* threads = nullptr) {
    std::mutex seenMutex;
    std::set<std::thread::id> seen;
    auto start = Clock::now();
    std::size_t blocked = tbb::parallel_reduce(
        tbb::blocked_range<std::size_t>(0, s.from.size(), 1024), std::size_t(0),
        [&](const auto& r, std::size_t acc) {
            if (threads) {
                std::lock_guard<std::mutex> lock(seenMutex);
                seen.insert(std::this_thread::get_id());
            }
            for (std::size_t i = r.begin(); i != r.end(); ++i)
                acc += tracer.occluded(s.from[i], s.to[i]) ? 1 : 0;
            return acc;
        },
        std::plus<>());
    benchmark::DoNotOptimize(blocked);
    const double rate = static_cast<double>(s.from.size()) / secondsSince(start);
    if (threads) *threads = static_cast<int>(seen.size());
    return rate;
}

/// Closest-hit rays per second over all worker threads, from the same points along the same
/// directions (the stochastic batches' query).
double rawHitRate(const RayTracer& tracer, const Segments& s) {
    std::vector<Vec3> dirs(s.from.size());
    for (std::size_t i = 0; i < dirs.size(); ++i) {
        const Vec3 d = s.to[i] - s.from[i];
        dirs[i] = glm::length(d) > 0 ? glm::normalize(d) : Vec3(0, 0, 1);
    }
    auto start = Clock::now();
    std::size_t hits = tbb::parallel_reduce(
        tbb::blocked_range<std::size_t>(0, s.from.size(), 1024), std::size_t(0),
        [&](const auto& r, std::size_t acc) {
            for (std::size_t i = r.begin(); i != r.end(); ++i)
                acc += tracer.firstHit(s.from[i], dirs[i]).element >= 0 ? 1 : 0;
            return acc;
        },
        std::plus<>());
    benchmark::DoNotOptimize(hits);
    return static_cast<double>(s.from.size()) / secondsSince(start);
}

long peakResidentKiB() {
    rusage u{};
    getrusage(RUSAGE_SELF, &u);
    return u.ru_maxrss;
}

nlohmann::json measureScene(const std::string& path, const BenchOptions& options) {
    nlohmann::json r;
    r["scene"] = path;
    auto loadStart = Clock::now();
    auto lit = LitScene::open(path, interactiveSolverOptions());
    r["load_seconds"] = secondsSince(loadStart);
    r["patches"] = lit->discretization().patches().size();
    r["elements"] = lit->discretization().elements().size();

    Segments segs = makeSegments(lit->discretization(), 1 << 20);
    rawOcclusionRate(lit->tracer(), segs);  // warm up
    // Each raw rate is the median of ten passes over the 2^20 segments, five before the solve
    // and five after it: single passes are short and move with what else the machine runs,
    // and so do medians taken minutes apart, so the solve is bracketed.
    int threadsSeen = 0;
    auto passes = [](auto&& rate, std::vector<double>& into) {
        for (int k = 0; k < 5; ++k) into.push_back(rate());
    };
    auto median = [](std::vector<double> v) {
        std::sort(v.begin(), v.end());
        const std::size_t n = v.size();
        return n == 0 ? 0.0 : n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
    };
    auto occlusionPass = [&] {
        int seen = 0;
        const double rate = rawOcclusionRate(lit->tracer(), segs, &seen);
        threadsSeen = std::max(threadsSeen, seen);
        return rate;
    };
    auto hitPass = [&] { return rawHitRate(lit->tracer(), segs); };
    std::vector<double> rawBefore, rawAfter, hitBefore, hitAfter;
    passes(occlusionPass, rawBefore);
    passes(hitPass, hitBefore);

    // The solve, timed to each threshold. A short solve is one burst of a shared machine's
    // noise (cube-room's 0.4 s moved by ±10% between back-to-back runs), so solves under a
    // second are repeated on fresh copies of the scene, five in all, and the median one is
    // reported; their rays are the same (the solver does not depend on timing).
    const double thresholds[] = {0.1, 0.01, 0.001};
    const char* names[] = {"seconds_to_10pct", "seconds_to_1pct", "seconds_to_0.1pct"};
    struct Solve {
        double seconds[3] = {-1, -1, -1};
        std::uint64_t shots[3] = {0, 0, 0};
        SolverStats stats;
        double unshot = 0;
    };
    auto solve = [&](ProgressiveSolver& solver) {
        Solve run;
        for (int k = 0; k < 3; ++k) {
            while (solver.unshotFraction() > thresholds[k] &&
                   solver.stats().seconds < options.maxSecondsPerScene) {
                if (solver.step(1) == 0) break;
            }
            if (solver.unshotFraction() > thresholds[k]) break;
            run.seconds[k] = solver.stats().seconds;
            run.shots[k] = solver.stats().shots;
        }
        run.stats = solver.stats();
        run.unshot = solver.unshotFraction();
        return run;
    };
    std::vector<Solve> solves{solve(lit->solver())};
    // Peak memory up to the end of the first solve (the high-water mark includes the passes
    // before it, as it always did), read before the repeats and the passes after it allocate.
    r["peak_rss_mib"] = peakResidentKiB() / 1024.0;
    while (solves.size() < 5 && solves.front().stats.seconds < 1.0) {
        auto again = LitScene::open(path, interactiveSolverOptions());
        solves.push_back(solve(again->solver()));
    }
    nlohmann::json allSeconds = nlohmann::json::array();
    for (const Solve& run : solves) allSeconds.push_back(run.stats.seconds);
    r["solve_seconds_all"] = allSeconds;
    std::sort(solves.begin(), solves.end(),
              [](const Solve& a, const Solve& b) { return a.stats.seconds < b.stats.seconds; });
    const Solve& mid = solves[solves.size() / 2];
    for (int k = 0; k < 3; ++k) {
        r[names[k]] = nullptr;
        if (mid.seconds[k] < 0) continue;
        r[names[k]] = mid.seconds[k];
        r[std::string("shots_to_") + (names[k] + 11)] = mid.shots[k];
    }
    passes(occlusionPass, rawAfter);
    passes(hitPass, hitAfter);
    std::vector<double> rawAll = rawBefore, hitAll = hitBefore;
    rawAll.insert(rawAll.end(), rawAfter.begin(), rawAfter.end());
    hitAll.insert(hitAll.end(), hitAfter.begin(), hitAfter.end());
    const double raw = median(rawAll), rawHit = median(hitAll);
    r["raw_occlusion_rays_per_s"] = raw;
    r["raw_occlusion_rays_per_s_before"] = median(rawBefore);
    r["raw_occlusion_rays_per_s_after"] = median(rawAfter);
    r["threads"] = tbb::this_task_arena::max_concurrency();
    r["threads_seen"] = threadsSeen;
    r["raw_closest_hit_rays_per_s"] = rawHit;

    const SolverStats& st = mid.stats;
    double solverRate = st.seconds > 0 ? st.rays / st.seconds : 0;
    r["solver_rays_per_s"] = solverRate;
    r["ratio_solver_to_raw"] = raw > 0 ? solverRate / raw : 0;
    // The same ray budget traced alone: the solver's closest-hit rays (stochastic batches) at
    // the raw closest-hit rate, the rest at the raw occlusion rate. solver / this is the share
    // of the solver's time spent tracing its own rays.
    const double hitRays = static_cast<double>(st.stochasticRays);
    const double occlusionRays = static_cast<double>(st.rays) - hitRays;
    const double rawMixSeconds = occlusionRays / raw + hitRays / rawHit;
    r["stochastic_ray_share"] = st.rays > 0 ? hitRays / static_cast<double>(st.rays) : 0.0;
    r["ratio_solver_to_raw_mix"] = st.seconds > 0 ? rawMixSeconds / st.seconds : 0;
    r["shots"] = st.shots;
    r["stochastic_batches"] = st.stochasticBatches;
    r["unshot_fraction"] = mid.unshot;
    r["solver_seconds"] = st.seconds;
    return r;
}

/// Runs measureScene in a fresh process of this executable (`penumbra-bench solver --child-scene`),
/// so its peak memory is its own and oneTBB starts its workers there.
nlohmann::json measureSceneIsolated(const std::string& path, const BenchOptions& options) {
    int fds[2];
    if (pipe(fds) != 0) return measureScene(path, options);
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_addclose(&actions, fds[0]);
    posix_spawn_file_actions_adddup2(&actions, fds[1], STDOUT_FILENO);
    posix_spawn_file_actions_addclose(&actions, fds[1]);
    const std::string maxSeconds = std::to_string(options.maxSecondsPerScene);
    std::vector<std::string> args{"penumbra-bench", "solver",  "--child-scene", path,
                                  "--max-seconds",  maxSeconds};
    std::vector<char*> argv;
    for (std::string& a : args) argv.push_back(a.data());
    argv.push_back(nullptr);
    pid_t pid = 0;
    const int spawned =
        posix_spawn(&pid, "/proc/self/exe", &actions, nullptr, argv.data(), environ);
    posix_spawn_file_actions_destroy(&actions);
    close(fds[1]);
    if (spawned != 0) {
        close(fds[0]);
        return {{"scene", path}, {"error", "cannot start the benchmark child"}};
    }
    std::string text;
    char buf[4096];
    ssize_t n;
    while ((n = read(fds[0], buf, sizeof buf)) > 0) text.append(buf, static_cast<std::size_t>(n));
    close(fds[0]);
    int status = 0;
    waitpid(pid, &status, 0);
    nlohmann::json r = nlohmann::json::parse(text, nullptr, false);
    if (!WIFEXITED(status) || WEXITSTATUS(status) != 0 || r.is_discarded() || !r.is_object()) {
        const std::string how = WIFSIGNALED(status)
                                    ? "killed by signal " + std::to_string(WTERMSIG(status))
                                    : "exit status " + std::to_string(WEXITSTATUS(status));
        return {{"scene", path}, {"error", "benchmark child failed (" + how + ")"}};
    }
    return r;
}

std::string cell(const nlohmann::json& v, const char* fmt) {
    if (v.is_null()) return "—";
    char b[64];
    std::snprintf(b, sizeof b, fmt, v.get<double>());
    return b;
}

}  // namespace

int runSolverBench(const BenchOptions& options) {
    if (!options.childScene.empty()) {
        // The child of measureSceneIsolated: one scene, its JSON on stdout.
        nlohmann::json r;
        try {
            r = measureScene(options.childScene, options);
        } catch (const std::exception& e) {
            r = {{"scene", options.childScene}, {"error", e.what()}};
        }
        std::printf("%s", r.dump().c_str());
        std::fflush(stdout);  // before any teardown
        return 0;
    }
    // Micro-benchmarks through Google Benchmark: the per-query costs behind the table.
    {
        auto lit = LitScene::open(options.scenes.front(), interactiveSolverOptions());
        Segments segs = makeSegments(lit->discretization(), 1 << 16);
        const Discretization& disc = lit->discretization();
        benchmark::RegisterBenchmark(
            ("occluded1/" + options.scenes.front()).c_str(), [&](benchmark::State& st) {
                std::size_t i = 0;
                for (auto _ : st) {
                    benchmark::DoNotOptimize(lit->tracer().occluded(segs.from[i], segs.to[i]));
                    i = (i + 1) & 0xffff;
                }
                st.SetItemsProcessed(st.iterations());
            });
        // The stochastic shots' query: the closest hit along a ray from a surface point.
        std::vector<Vec3> dirs(segs.from.size());
        for (std::size_t i = 0; i < dirs.size(); ++i) {
            const Vec3 d = segs.to[i] - segs.from[i];
            dirs[i] = glm::length(d) > 0 ? glm::normalize(d) : Vec3(0, 0, 1);
        }
        benchmark::RegisterBenchmark(
            ("firstHit1/" + options.scenes.front()).c_str(), [&](benchmark::State& st) {
                std::size_t i = 0;
                for (auto _ : st) {
                    benchmark::DoNotOptimize(lit->tracer().firstHit(segs.from[i], dirs[i]));
                    i = (i + 1) & 0xffff;
                }
                st.SetItemsProcessed(st.iterations());
            });
        benchmark::RegisterBenchmark(
            ("formFactorToPatch/" + options.scenes.front()).c_str(), [&](benchmark::State& st) {
                std::size_t i = 0;
                for (auto _ : st) {
                    const Element& e = disc.elements()[(i * 7919) % disc.elements().size()];
                    int p = static_cast<int>((i * 104729) % disc.patches().size());
                    benchmark::DoNotOptimize(
                        formFactorToPatch(disc, lit->tracer(), e.centroid, e.normal, p, i, 1, 16));
                    ++i;
                }
                st.SetItemsProcessed(st.iterations());
            });
        int argc = 1;
        char arg0[] = "penumbra-bench";
        char* argv[] = {arg0, nullptr};
        benchmark::Initialize(&argc, argv);
        benchmark::RunSpecifiedBenchmarks();
        benchmark::ClearRegisteredBenchmarks();
    }

    nlohmann::json rows = nlohmann::json::array();
    std::printf(
        "\n| scene | patches | elements | raw Mrays/s | solver Mrays/s | ratio | raw hit Mrays/s | "
        "hit-ray share | ratio to same mix | to 10%% s | to 1%% s | to 0.1%% s | peak MiB | "
        "threads |\n");
    std::printf("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
    for (const std::string& scene : options.scenes) {
        nlohmann::json r = measureSceneIsolated(scene, options);
        rows.push_back(r);
        if (r.contains("error")) {
            std::printf("| %s | error: %s |\n", scene.c_str(),
                        r["error"].get<std::string>().c_str());
            continue;
        }
        std::printf(
            "| %s | %zu | %zu | %s | %s | %s | %s | %s | %s | %s | %s | %s | %s | %d |\n",
            scene.c_str(), r["patches"].get<std::size_t>(), r["elements"].get<std::size_t>(),
            cell(r["raw_occlusion_rays_per_s"].get<double>() / 1e6, "%.2f").c_str(),
            cell(r["solver_rays_per_s"].get<double>() / 1e6, "%.2f").c_str(),
            cell(r["ratio_solver_to_raw"], "%.2f").c_str(),
            cell(r["raw_closest_hit_rays_per_s"].get<double>() / 1e6, "%.2f").c_str(),
            cell(r["stochastic_ray_share"], "%.2f").c_str(),
            cell(r["ratio_solver_to_raw_mix"], "%.2f").c_str(),
            cell(r["seconds_to_10pct"], "%.2f").c_str(), cell(r["seconds_to_1pct"], "%.2f").c_str(),
            cell(r["seconds_to_0.1pct"], "%.2f").c_str(), cell(r["peak_rss_mib"], "%.0f").c_str(),
            r["threads_seen"].get<int>());
        std::fflush(stdout);
    }
    if (!options.jsonOut.empty()) writeFileAtomically(options.jsonOut, rows.dump(2) + "\n");
    return 0;
}

}  // namespace penumbra
