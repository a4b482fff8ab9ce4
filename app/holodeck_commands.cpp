// `penumbra holodeck`; see app/holodeck_commands.h.
#include "app/holodeck_commands.h"

#include <tbb/global_control.h>
#include <unistd.h>

#include <cstdio>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>

#include "app/mpi_world.h"
#include "core/input_error.h"
#include "core/timing.h"
#include "render/camera_rays.h"
#include "render/display/interactive_display.h"
#include "render/display/point_shader.h"
#include "render/holodeck/holo_file.h"
#include "render/holodeck/holo_merge.h"
#include "render/holodeck/holo_server.h"
#include "render/holodeck/holo_view.h"

namespace penumbra::cli {

namespace {

// ---------------------------------------------------------------------------------------------
// holodeck fill and info (Ward & Simmons 1999; docs/holodeck.md).

nlohmann::json holodeckJson(const HoloFile& file) {
    const HoloFileInfo info = file.info();
    nlohmann::json sections = nlohmann::json::array();
    for (const HoloSection& s : file.sections())
        sections.push_back({{"kind", s.kind() == SectionKind::Interior ? "interior" : "exterior"},
                            {"origin", {s.origin().x, s.origin().y, s.origin().z}},
                            {"size", {s.size().x, s.size().y, s.size().z}},
                            {"grid", {s.grid()[0], s.grid()[1], s.grid()[2]}},
                            {"beams", s.beamCount()}});
    return {
        {"file", file.path()},
        {"sections", sections},
        {"beams", info.beams},
        {"samples", info.samples},
        {"bytes", info.bytes},
        {"free_bytes", info.freeBytes},
        {"fragments", info.fragments},
        {"bytes_per_sample", info.samples > 0 ? double(info.bytes) / double(info.samples) : 0.0}};
}

int runHolodeckInfo(const HolodeckArgs& h) {
    const HoloFile file = HoloFile::openReadOnly(h.file);
    std::printf("%s\n", holodeckJson(file).dump(2).c_str());
    return 0;
}

/// The display's own point shader over a solved scene, as a fill shades with it: the display's
/// options, the command's seed.
std::unique_ptr<PointShader> makeFillShader(const SolveArgs& a, LitScene& lit) {
    PointShaderOptions shading = InteractiveDisplayOptions{}.shader;
    shading.seed = a.seed;
    shading.threads = 0;
    auto shader = std::make_unique<PointShader>(lit.discretization(), lit.tracer(),
                                                solverOptionsOf(a), shading);
    shader->updateSolution(lit.solver());
    return shader;
}

/// The sections of a new holodeck for a solved scene: the scene file's, or the layout over its
/// surfaces (an existing file keeps its own).
std::vector<HoloSection> newHolodeckSections(LitScene& lit) {
    return holodeckSections(lit.scene().settings, lit.discretization());
}

/// fill's new samples: --samples, or a million unless --seconds bounds it.
std::int64_t fillSamples(const HolodeckArgs& h) {
    return h.samples > 0 || h.seconds > 0 ? h.samples : 1000000;
}

int runHolodeckFillRanks(const MpiWorld& world, const SolveArgs& a, const HolodeckArgs& h);

int runHolodeckFill(const SolveArgs& a, const HolodeckArgs& h) {
    // Under mpirun, the ranks share the fill (docs/holodeck.md, "Scale-out"); otherwise MPI is
    // never initialised.
    if (launchedByMpirun()) {
        const MpiWorld world;
        return runHolodeckFillRanks(world, a, h);
    }
    const std::string path = h.file.empty() ? defaultHolodeckPath(a.scene) : h.file;
    auto lit = openAndSolve(a);
    std::optional<CameraRays> view;
    if (!h.camera.empty())
        view.emplace(pickCamera(lit->scene(), a.scene, h.camera), h.width, h.height);
    const std::unique_ptr<PointShader> shader = makeFillShader(a, *lit);
    // A new holodeck gets the scene's sections; an existing one keeps its own.
    HoloFile file(path, newHolodeckSections(*lit));
    HoloServer server(file, shader.get());
    const bool tty = ::isatty(STDERR_FILENO);
    const std::int64_t samples = fillSamples(h);
    const auto progress = [&](double f) {
        if (tty) std::fprintf(stderr, "\rholodeck: filling %3.0f%%", 100 * f);
    };
    // A camera: its pixel rays (fillView); none: every beam by its volume (batch mode).
    const FillStats stats =
        view ? fillView(server, *shader, lit->tracer(), *view, samples, h.seconds, a.seed, progress)
             : server.fill(server.batchRequests(1e6), samples, h.seconds, 5.0, progress);
    if (tty) std::fprintf(stderr, "\n");
    nlohmann::json report = holodeckJson(file);
    report["samples_added"] = stats.samples;
    report["beams_filled"] = stats.beams;
    report["seconds"] = stats.seconds;
    report["samples_per_second"] = stats.seconds > 0 ? stats.samples / stats.seconds : 0.0;
    std::printf("%s\n", report.dump(2).c_str());
    return 0;
}

// ---------------------------------------------------------------------------------------------
// holodeck fill under mpirun, and merge (docs/holodeck.md, "Scale-out"; render/holodeck/
// holo_merge.h says why a merge never duplicates a sample).

/// Rank k's part file beside the target: FILE.rankK.hdk.
std::string partPath(const std::string& path, int rank) {
    return std::filesystem::path(path)
        .replace_extension(".rank" + std::to_string(rank) + ".hdk")
        .string();
}

/// One phase of a job: runs `step` on every rank, then the ranks agree whether all succeeded;
/// the lowest failing rank prints its error (one line). False when any rank failed.
bool allSucceed(const MpiWorld& world, const std::function<void()>& step) {
    std::string error;
    try {
        step();
    } catch (const std::exception& e) {
        error = e.what();
        if (error.empty()) error = "failed";
    }
    const int failing = world.lowestFailing(!error.empty());
    if (failing == world.rank()) std::fprintf(stderr, "penumbra: %s\n", error.c_str());
    return failing < 0;
}

/// One rank's share of the fill's beams, started from the target's samples of them and filled
/// into its part file.
FillStats fillPart(const MpiWorld& world, const HolodeckArgs& h, const std::string& path,
                   const PointShader& shader) {
    HoloFile base = HoloFile::openReadOnly(path);
    // A part left by a killed run starts afresh (`holodeck merge` takes such parts).
    const std::string part = partPath(path, world.rank());
    std::error_code ignored;
    std::filesystem::remove(part, ignored);
    HoloFile file(part, base.sections());
    HoloServer server(file, &shader);
    const RankShare share =
        shareRequests(server.batchRequests(1e6), fillSamples(h), world.size(), world.rank());
    seedPart(base, file, share.requests);
    if (share.samples <= 0 && !(h.seconds > 0)) return {};
    const bool tty = world.rank() == 0 && ::isatty(STDERR_FILENO);
    const FillStats stats =
        server.fill(share.requests, share.samples, h.seconds, 5.0, [&](double f) {
            if (tty) std::fprintf(stderr, "\rholodeck: filling %3.0f%%", 100 * f);
        });
    if (tty) std::fprintf(stderr, "\n");
    return stats;
}

/// Rank 0: merges every rank's part into the target, removes the parts, and reports the file.
nlohmann::json mergeParts(const std::string& path, int ranks) {
    std::vector<std::string> parts;
    for (int k = 0; k < ranks; ++k) parts.push_back(partPath(path, k));
    HoloFile target(path, {});
    const Clock::time_point start = Clock::now();
    const HoloMergeStats merged = mergeHoloParts(target, parts);
    for (const std::string& part : parts) std::filesystem::remove(part);
    nlohmann::json report = holodeckJson(target);
    report["merge_seconds"] = secondsSince(start);
    report["beams_merged"] = merged.beams;
    return report;
}

int runHolodeckFillRanks(const MpiWorld& world, const SolveArgs& a, const HolodeckArgs& h) {
    const std::string path = h.file.empty() ? defaultHolodeckPath(a.scene) : h.file;
    // The machine's cores shared among its ranks, unless --threads says otherwise.
    std::optional<tbb::global_control> threads;
    if (a.threads == 0)
        threads.emplace(tbb::global_control::max_allowed_parallelism,
                        std::max(1, int(std::thread::hardware_concurrency()) / world.localSize()));
    // Every rank solves the scene (the same solution: the solver is deterministic); rank 0
    // opens or creates the target, so that every rank finds its sections.
    std::unique_ptr<LitScene> lit;
    std::unique_ptr<PointShader> shader;
    if (!allSucceed(world, [&] {
            // A view's fill shades its pixel rays in their own order (fillView): one process.
            if (!h.camera.empty())
                throw InputError("--camera", "",
                                 "under mpirun, fill shares every beam among the ranks; fill a "
                                 "camera's view without mpirun");
            lit = LitScene::open(a.scene, solverOptionsOf(a), a.import);
            const bool tty = world.rank() == 0 && ::isatty(STDERR_FILENO);
            lit->solver().converge(
                a.converge, a.maxShots,
                tty ? progressPrinter(a.converge) : std::function<void(double)>{});
            if (tty) std::fprintf(stderr, "\n");
            shader = makeFillShader(a, *lit);
            if (world.rank() == 0) HoloFile target(path, newHolodeckSections(*lit));
        }))
        return 2;
    // Every rank fills its share into its part; rank 0 merges them.
    const Clock::time_point start = Clock::now();
    FillStats stats;
    if (!allSucceed(world, [&] { stats = fillPart(world, h, path, *shader); })) {
        std::error_code ignored;
        std::filesystem::remove(partPath(path, world.rank()), ignored);
        return 2;
    }
    const std::int64_t samples = world.sum(stats.samples), beams = world.sum(stats.beams);
    const double fillSeconds = world.max(stats.seconds);
    nlohmann::json report;
    if (!allSucceed(world, [&] {
            if (world.rank() == 0) report = mergeParts(path, world.size());
        }))
        return 2;
    if (world.rank() != 0) return 0;
    const double seconds = secondsSince(start);
    report["ranks"] = world.size();
    report["samples_added"] = samples;
    report["beams_filled"] = beams;
    report["fill_seconds"] = fillSeconds;
    report["seconds"] = seconds;
    report["samples_per_second"] = seconds > 0 ? samples / seconds : 0.0;
    std::printf("%s\n", report.dump(2).c_str());
    return 0;
}

/// holodeck merge OUT PART...: a new OUT takes the first part's sections; a refused merge
/// leaves OUT as it was (a new one is removed).
int runHolodeckMerge(const HolodeckArgs& h) {
    const bool existed = std::filesystem::exists(h.file);
    try {
        HoloFile target(h.file, HoloFile::openReadOnly(h.parts.front()).sections());
        const HoloMergeStats merged = mergeHoloParts(target, h.parts);
        nlohmann::json report = holodeckJson(target);
        report["parts"] = merged.parts;
        report["beams_merged"] = merged.beams;
        report["samples_added"] = merged.samplesAdded;
        report["samples_shared"] = merged.samplesShared;
        std::printf("%s\n", report.dump(2).c_str());
    } catch (...) {
        std::error_code ignored;
        if (!existed) std::filesystem::remove(h.file, ignored);
        throw;
    }
    return 0;
}

}  // namespace

void addHolodeckCommands(CLI::App& app, SolveArgs& solve, HolodeckCommands& c) {
    CLI::App* holodeck =
        app.add_subcommand("holodeck", "the persistent ray cache (Ward & Simmons)");
    holodeck->require_subcommand(1);
    HolodeckArgs& h = c.args;
    CLI::App* fill = c.fill =
        holodeck->add_subcommand("fill", "solve a scene and fill its holodeck with shaded samples");
    addSolveOptions(fill, solve);
    fill->add_option("--holodeck", h.file, "the holodeck file (default: SCENE.hdk)");
    fill->add_option("--camera", h.camera,
                     "fill the beams this camera's view needs (default: every beam, in "
                     "proportion to its volume)");
    fill->add_option("--width", h.width, "--camera: view width in pixels")
        ->check(CLI::Range(1, 16384));
    fill->add_option("--height", h.height, "--camera: view height in pixels")
        ->check(CLI::Range(1, 16384));
    CLI::Option* seconds =
        fill->add_option("--seconds", h.seconds, "fill for S seconds")->check(CLI::PositiveNumber);
    fill->add_option("--samples", h.samples, "fill N new samples (default 1,000,000)")
        ->check(CLI::PositiveNumber)
        ->excludes(seconds);
    CLI::App* info = c.info =
        holodeck->add_subcommand("info", "print a holodeck's sections, beams, samples and bytes");
    info->add_option("FILE", h.file, "holodeck file")->required();
    CLI::App* merge = c.merge = holodeck->add_subcommand(
        "merge", "merge holodecks filled from the same one (e.g. by mpirun's ranks) into OUT");
    merge->add_option("OUT", h.file, "the holodeck merged into (created when missing)")->required();
    merge->add_option("PART", h.parts, "holodecks with OUT's sections, filled with one seed")
        ->required();
}

int runHolodeckCommand(const SolveArgs& solve, const HolodeckCommands& c) {
    if (*c.fill) return runHolodeckFill(solve, c.args);
    if (*c.info) return runHolodeckInfo(c.args);
    if (*c.merge) return runHolodeckMerge(c.args);
    return -1;
}

}  // namespace penumbra::cli
