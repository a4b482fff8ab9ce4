// `penumbra bench holodeck` (Ward & Simmons 1999): per scene, a batch fill of a new holodeck
// (samples/s on every core, bytes per sample), the default camera's view filled to a sample per
// pixel, then that view's beams read back from the file with its pages dropped from the
// operating system's cache ("disk", after opening it) and again from the server's memory, each
// decoded to world-space samples on one thread. The baseline, measured in the same run, is
// shading as many of the view's rays with the display's point shader on one thread; the
// paper's figure is 41,000 samples/s read from file per view. Last, the batch fill shared among
// processes: `mpirun -np K` of this binary's `holodeck fill` for K = 1, 2 (docs/holodeck.md,
// "Scale-out"), the rate 2 against 1 measured in the same run. Then a holodeck filled for no
// view (--generic-seconds), opened once (its hit index) and nine views taken from it: the
// default camera's and eight looking around from the middle of the room, each against the
// display without the holodeck after one and after 30 frames of that view.

#include <fcntl.h>
#include <unistd.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "bench/bench.h"
#include "core/durable_file.h"
#include "core/file_name.h"
#include "core/timing.h"
#include "edit/edit_session.h"
#include "edit/lit_scene.h"
#include "render/camera_rays.h"
#include "render/display/interactive_display.h"
#include "render/display/point_shader.h"
#include "render/holodeck/holo_file.h"
#include "render/holodeck/holo_server.h"
#include "render/holodeck/holo_view.h"

namespace penumbra {
namespace {

struct HolodeckCase {
    std::string name;
    std::int64_t beams = 0, samples = 0, bytes = 0;
    double fillPerSecond = 0;
    std::int64_t viewBeams = 0, viewSamples = 0;
    double openMs = 0, diskPerSecond = 0, memoryPerSecond = 0, shadePerSecond = 0;
    /// Reopening the view: the first frame from the holodeck (its total, retrieval included)
    /// and its error; the display without it after its first frame and after 30 frames.
    double firstFrameMs = 0, firstFrameError = 0, displayFirstError = 0, display30Error = 0;
    std::int64_t firstFrameSamples = 0;
};

/// Drops the file's pages from the operating system's cache, so the next reads come from disk.
void dropFromPageCache(const std::string& path) {
    const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
    if (fd < 0) return;
    ::fdatasync(fd);
    ::posix_fadvise(fd, 0, 0, POSIX_FADV_DONTNEED);
    ::close(fd);
}

/// Every sample of the view's beams, read through `server` and decoded; returns how many.
std::int64_t readView(HoloServer& server, const std::vector<HoloSection>& sections,
                      const std::vector<BeamRequest>& view, std::vector<DecodedSample>& out) {
    out.clear();
    for (const BeamRequest& r : view)
        for (const HoloSample& sample : server.beam(r.section, r.beam))
            out.push_back(
                decodeSample(sample, sections[r.section], r.beam, server.distanceCode(r.section)));
    return std::int64_t(out.size());
}

/// The display without the holodeck on `rays`' view: its warm-up and first frame, then 30
/// frames; their errors against the converged reference it returns.
struct DisplayAlone {
    Image reference;
    double firstError = 0, error30 = 0;
};

DisplayAlone displayAlone(const EditSession& session, const SolverOptions& options,
                          const InteractiveDisplayOptions& displayOptions, const CameraRays& rays) {
    DisplayAlone d;
    InteractiveDisplay display(session.discretization(), session.tracer(), options, displayOptions);
    display.apply(SolutionView::of(session.solver()));
    display.warmUp(rays);
    Image image = display.renderFrame(rays);
    d.reference = display.renderReference(rays, 2);
    d.firstError = displayRmse(image, d.reference);
    for (int k = 1; k < 30; ++k) image = display.renderFrame(rays);
    d.error30 = displayRmse(image, d.reference);
    return d;
}

/// The view reopened from the holodeck, as `penumbra render --mode epi --holodeck` does: a
/// new display, the holodeck's points of the view, one frame; against the display without
/// the holodeck (its warm-up, then 30 frames of the same view), all against one reference.
void measureFirstFrame(EditSession& session, const SolverOptions& options, const CameraRays& rays,
                       const std::string& file, HolodeckCase& c) {
    InteractiveDisplayOptions displayOptions;
    displayOptions.width = rays.width();
    displayOptions.height = rays.height();
    const Discretization& disc = session.discretization();
    const DisplayAlone alone = displayAlone(session, options, displayOptions, rays);
    const Image& reference = alone.reference;
    c.displayFirstError = alone.firstError;
    c.display30Error = alone.error30;
    InteractiveDisplay display(disc, session.tracer(), options, displayOptions);
    display.apply(SolutionView::of(session.solver()));
    const auto start = Clock::now();
    HoloFile holo = HoloFile::openReadOnly(file);
    HoloServer server(holo, nullptr);
    const auto view = viewRequests(holo.sections(), rays, rays.width() / 4, rays.height() / 4, 1.0);
    const std::uint64_t cacheFrame = display.nextFrame(), serial = display.shadingSerial();
    c.firstFrameSamples =
        std::int64_t(display
                         .insertShadedFindingEdges([&] {
                             return holodeckViewPoints(server, view, disc, session.tracer(), rays,
                                                       cacheFrame, serial);
                         })
                         .size());
    const Image image = display.renderFrame(rays);
    c.firstFrameMs = 1e3 * secondsSince(start);
    c.firstFrameError = displayRmse(image, reference);
}

HolodeckCase runCase(const HolodeckBenchOptions& o, const std::string& name,
                     const std::string& file) {
    HolodeckCase c;
    c.name = name;
    const SolverOptions options = interactiveSolverOptions();
    auto session = EditSession::open(o.sceneDir + "/" + name + ".json", options);
    session->converge(1e-3, 100000000);
    const Discretization& disc = session->discretization();
    PointShaderOptions shading = InteractiveDisplayOptions{}.shader;
    shading.threads = 0;
    PointShader shader(disc, session->tracer(), options, shading);
    shader.updateSolution(session->solver());

    // A batch fill of every beam, then the default camera's view filled with a sample per
    // pixel (the paper's interactive mode, its rays through the eye: persisted for the next
    // visit).
    std::filesystem::remove(file);
    const Camera* defaultCamera = session->scene().findCamera("default");
    const Camera camera = defaultCamera ? *defaultCamera : Camera{};
    const CameraRays rays(camera, o.width, o.height);
    std::vector<BeamRequest> view;
    {
        HoloFile holo(file, holodeckSections(session->scene().settings, disc));
        HoloServer server(holo, &shader);
        const FillStats fill = server.fill(server.batchRequests(1e6), o.samples, 0);
        c.fillPerSecond = fill.samples / fill.seconds;
        view = viewRequests(holo.sections(), rays, o.width / 4, o.height / 4, 16.0);
        fillView(server, shader, session->tracer(), rays, std::int64_t(o.width) * o.height, 0);
    }
    std::vector<DecodedSample> decoded;
    // From disk: the file's pages dropped, a new file and server; opening (the directory) and
    // reading the view's beams timed apart.
    dropFromPageCache(file);
    {
        auto start = Clock::now();
        HoloFile holo = HoloFile::openReadOnly(file);
        c.openMs = 1e3 * secondsSince(start);
        HoloServer server(holo, nullptr);
        start = Clock::now();
        c.viewSamples = readView(server, holo.sections(), view, decoded);
        c.diskPerSecond = c.viewSamples / secondsSince(start);
        // From memory: the same beams again, now in the server's cache.
        const auto again = Clock::now();
        const int repeats = 5;
        for (int k = 0; k < repeats; ++k) readView(server, holo.sections(), view, decoded);
        c.memoryPerSecond = repeats * double(c.viewSamples) / secondsSince(again);
        const HoloFileInfo info = holo.info();
        c.beams = info.beams;
        c.samples = info.samples;
        c.bytes = info.bytes;
    }
    c.viewBeams = std::int64_t(view.size());
    measureFirstFrame(*session, options, rays, file, c);
    // The baseline: shading that many samples of the view's rays.
    {
        const std::int64_t n = std::min<std::int64_t>(c.viewSamples, 200000);
        const auto start = Clock::now();
        for (std::int64_t i = 0; i < n; ++i) {
            ShadeRequest r;
            r.pixel = glm::dvec2((i % o.width) + 0.5, ((i / o.width) % o.height) + 0.5);
            r.origin = rays.origin();
            r.direction = rays.rayDirection(r.pixel.x, r.pixel.y);
            r.frame = std::uint64_t(i);
            (void)shader.shade(r);
        }
        c.shadePerSecond = n / secondsSince(start);
    }
    return c;
}

/// One view opened from a holodeck filled for no view.
struct GenericView {
    std::string name;
    std::int64_t samples = 0;  ///< points the holodeck brought
    /// Taking them (HoloHitIndex::viewPoints) while the display finds its shadow edges
    /// (InteractiveDisplay::insertShadedFindingEdges), and the display's first frame with them.
    double pointsMs = 0;
    double firstFrameMs = 0;
    double edgesMs = 0;  ///< the shadow edges' own time in that, found once a display
    /// The same one after the other: the points alone, and with the first frame that finds
    /// the shadow edges.
    double serialPointsMs = 0, serialFirstFrameMs = 0;
    /// The editor's view change: the session's display (its shadow edges found when the scene
    /// opened) on the view, its cache empty: the holodeck's points and the first frame.
    double viewChangeMs = 0, viewChangeError = 0;
    double firstFrameError = 0, displayFirstError = 0, display30Error = 0;
};

/// `camera`'s look direction turned by `deg` degrees about its up axis, from `eye`.
Camera lookingAround(const Camera& camera, const Vec3& eye, double deg) {
    const Vec3 k = glm::normalize(camera.up);
    const Vec3 v = camera.lookAt - camera.position;
    const double a = deg * M_PI / 180;
    Camera c = camera;
    c.position = eye;
    c.lookAt = eye + v * std::cos(a) + glm::cross(k, v) * std::sin(a) +
               k * glm::dot(k, v) * (1 - std::cos(a));
    return c;
}

/// A holodeck filled for `o.genericSeconds` (or with `o.genericSamples`) with every beam
/// desired in proportion to its volume (no camera), reopened (the hit index built), and nine
/// views taken from it.
nlohmann::json runGeneric(const HolodeckBenchOptions& o, const std::string& name,
                          const std::string& file) {
    const SolverOptions options = interactiveSolverOptions();
    auto session = EditSession::open(o.sceneDir + "/" + name + ".json", options);
    session->converge(1e-3, 100000000);
    const Discretization& disc = session->discretization();
    // A kept file (--generic-holodeck) is reused as it is: its samples, not a new fill's.
    const bool reuse = !o.genericFile.empty() && std::filesystem::exists(file);
    if (!reuse) std::filesystem::remove(file);
    FillStats fill;
    if (reuse) {
        fill.samples = HoloFile::openReadOnly(file).info().samples;
    } else {
        PointShaderOptions shading = InteractiveDisplayOptions{}.shader;
        shading.threads = 0;
        PointShader shader(disc, session->tracer(), options, shading);
        shader.updateSolution(session->solver());
        HoloFile holo(file, holodeckSections(session->scene().settings, disc));
        HoloServer server(holo, &shader);
        fill = server.fill(server.batchRequests(1e9), o.genericSamples,
                           o.genericSamples > 0 ? 0 : o.genericSeconds);
    }
    const auto open = Clock::now();
    HoloFile holo = HoloFile::openReadOnly(file);
    HoloServer server(holo, nullptr);
    const HoloHitIndex index(server);
    const double openMs = 1e3 * secondsSince(open);

    const Camera* defaultCamera = session->scene().findCamera("default");
    const Camera camera = defaultCamera ? *defaultCamera : Camera{};
    const Vec3 middle = 0.5 * (camera.position + camera.lookAt);
    std::vector<std::pair<std::string, Camera>> views{{"default", camera}};
    for (int k = 0; k < 8; ++k)
        views.emplace_back("middle " + std::to_string(45 * k),
                           lookingAround(camera, middle, 45.0 * k));
    InteractiveDisplayOptions displayOptions;
    displayOptions.width = o.width;
    displayOptions.height = o.height;
    // The editor's display of the session: its shadow edges are found once, when the scene
    // opens (its first frame); a view change keeps them (InteractiveDisplay's copy carries
    // them, and its cache starts empty here).
    InteractiveDisplay sessionDisplay(disc, session->tracer(), options, displayOptions);
    sessionDisplay.apply(SolutionView::of(session->solver()));
    sessionDisplay.renderFrame(CameraRays(camera, o.width, o.height));
    const double sessionEdgesMs = sessionDisplay.lastFrame().times.shadowMs;
    std::printf(
        "\n%s: a holodeck filled for no view, %.0f s%s: %lld samples; opened with its hit "
        "index in %.0f ms (%lld hits); the session's shadow edges found in %.0f ms\n",
        name.c_str(), fill.seconds, reuse ? " (an earlier fill, reused)" : "",
        (long long)fill.samples, openMs, (long long)index.hits(), sessionEdgesMs);
    std::printf("%-12s %10s %10s %10s %10s %14s %9s %12s %14s %12s %16s %18s\n", "view", "samples",
                "points ms", "serial ms", "pts+edg ms", "1st frame ms", "edges ms", "1st error",
                "view change ms", "its error", "display 1st err", "display 30th err");
    nlohmann::json rows = nlohmann::json::array();
    for (const auto& [viewName, viewCamera] : views) {
        const CameraRays rays(viewCamera, o.width, o.height);
        GenericView v;
        v.name = viewName;
        const DisplayAlone alone = displayAlone(*session, options, displayOptions, rays);
        const Image& reference = alone.reference;
        v.displayFirstError = alone.firstError;
        v.display30Error = alone.error30;
        {
            // The same one after the other: the points, then the first frame finding the edges.
            InteractiveDisplay serial(disc, session->tracer(), options, displayOptions);
            serial.apply(SolutionView::of(session->solver()));
            const auto serialStart = Clock::now();
            serial.insertShaded(index.viewPoints(disc, session->tracer(), rays, serial.nextFrame(),
                                                 serial.shadingSerial()));
            v.serialPointsMs = 1e3 * secondsSince(serialStart);
            serial.renderFrame(rays);
            v.serialFirstFrameMs = 1e3 * secondsSince(serialStart);
        }
        InteractiveDisplay display(disc, session->tracer(), options, displayOptions);
        display.apply(SolutionView::of(session->solver()));
        // As `render --mode epi --holodeck` does: the holodeck's points taken while the new
        // display finds its shadow edges, then the first frame.
        const auto start = Clock::now();
        const std::uint64_t cacheFrame = display.nextFrame(), serial = display.shadingSerial();
        v.samples = std::int64_t(display
                                     .insertShadedFindingEdges([&] {
                                         return index.viewPoints(disc, session->tracer(), rays,
                                                                 cacheFrame, serial);
                                     })
                                     .size());
        v.pointsMs = 1e3 * secondsSince(start);
        const Image image = display.renderFrame(rays);
        v.firstFrameMs = 1e3 * secondsSince(start);
        v.edgesMs = display.lastShadowUpdateMs();
        v.firstFrameError = displayRmse(image, reference);
        {
            const auto changeStart = Clock::now();
            InteractiveDisplay moved(sessionDisplay, displayOptions);
            moved.insertShaded(index.viewPoints(disc, session->tracer(), rays,
                                                moved.cache().frame(), moved.shadingSerial()));
            const Image changed = moved.renderFrame(rays);
            v.viewChangeMs = 1e3 * secondsSince(changeStart);
            v.viewChangeError = displayRmse(changed, reference);
        }
        std::printf(
            "%-12s %10lld %10.1f %10.1f %10.1f %14.1f %9.1f %12.4f %14.1f %12.4f %16.4f "
            "%18.4f\n",
            v.name.c_str(), (long long)v.samples, v.serialPointsMs, v.serialFirstFrameMs,
            v.pointsMs, v.firstFrameMs, v.edgesMs, v.firstFrameError, v.viewChangeMs,
            v.viewChangeError, v.displayFirstError, v.display30Error);
        std::fflush(stdout);
        rows.push_back({{"view", v.name},
                        {"samples", v.samples},
                        {"serial_points_ms", v.serialPointsMs},
                        {"serial_first_frame_ms", v.serialFirstFrameMs},
                        {"points_ms", v.pointsMs},
                        {"first_frame_ms", v.firstFrameMs},
                        {"shadow_edges_ms", v.edgesMs},
                        {"view_change_ms", v.viewChangeMs},
                        {"view_change_error", v.viewChangeError},
                        {"first_frame_error", v.firstFrameError},
                        {"display_first_error", v.displayFirstError},
                        {"display_30_error", v.display30Error}});
    }
    std::printf(
        "goals: first frame <= 500 ms, its error <= the display's after 30 frames; a new "
        "display's first frame finds every shadow edge (edges ms); the editor's view change "
        "keeps the session's (view change ms)\n");
    return {{"fill_seconds", fill.seconds}, {"session_shadow_edges_ms", sessionEdgesMs},
            {"fill_samples", fill.samples}, {"open_ms", openMs},
            {"hits", index.hits()},         {"views", rows}};
}

/// One `mpirun -np K ... holodeck fill` of a new holodeck: its report's rates and the wall time
/// of the whole job (MPI's start, every rank's solve, fill and merge).
struct RanksFill {
    int ranks = 0;
    double samplesPerSecond = 0;  ///< the report's: fill and merge
    double fillPerSecond = 0;     ///< the slowest rank's fill alone
    double mergeSeconds = 0, wallSeconds = 0;
};

RanksFill runRanksFill(const HolodeckBenchOptions& o, const std::string& name, int ranks,
                       const std::string& file) {
    // Open MPI refuses to start as root unless told to (CI and these machines run as root).
    if (::geteuid() == 0) {
        ::setenv("OMPI_ALLOW_RUN_AS_ROOT", "1", 1);
        ::setenv("OMPI_ALLOW_RUN_AS_ROOT_CONFIRM", "1", 1);
    }
    const std::string penumbra = siblingExecutable("penumbra");
    const std::string command =
        "mpirun -q -np " + std::to_string(ranks) + " --oversubscribe --bind-to none '" + penumbra +
        "' holodeck fill '" + o.sceneDir + "/" + name + ".json' --holodeck '" + file +
        "' --samples " + std::to_string(o.samples) + " 2>&1";
    std::filesystem::remove(file);
    const auto start = Clock::now();
    FILE* pipe = ::popen(command.c_str(), "r");
    if (!pipe) throw std::runtime_error("bench holodeck: cannot run mpirun");
    std::string output;
    std::array<char, 4096> buffer;
    for (std::size_t n; (n = std::fread(buffer.data(), 1, buffer.size(), pipe)) > 0;)
        output.append(buffer.data(), n);
    const int status = ::pclose(pipe);
    RanksFill r;
    r.ranks = ranks;
    r.wallSeconds = secondsSince(start);
    std::filesystem::remove(file);
    if (status != 0) throw std::runtime_error("bench holodeck: " + command + ": " + output);
    const nlohmann::json report = nlohmann::json::parse(output.substr(output.find('{')));
    r.samplesPerSecond = report["samples_per_second"].get<double>();
    r.fillPerSecond = report["samples_added"].get<double>() / report["fill_seconds"].get<double>();
    r.mergeSeconds = report["merge_seconds"].get<double>();
    return r;
}

/// The batch fill under mpirun with every rank count of `o.ranks`, scene by scene; the ratio is
/// each count's rate against the first's.
nlohmann::json runRanksTable(const HolodeckBenchOptions& o) {
    nlohmann::json out = nlohmann::json::array();
    if (o.ranks.empty()) return out;
    std::printf("\n%-12s %6s %12s %14s %9s %9s %8s\n", "mpirun", "ranks", "samples/s", "fill smp/s",
                "merge s", "wall s", "ratio");
    for (const std::string& name : o.cases) {
        const std::string file =
            (std::filesystem::temp_directory_path() /
             ("penumbra-bench-ranks-" + name + "-" + std::to_string(::getpid()) + ".hdk"))
                .string();
        double base = 0;
        for (const int ranks : o.ranks) {
            const RanksFill r = runRanksFill(o, name, ranks, file);
            if (base == 0) base = r.samplesPerSecond;
            std::printf("%-12s %6d %12.0f %14.0f %9.2f %9.2f %8.2f\n", name.c_str(), r.ranks,
                        r.samplesPerSecond, r.fillPerSecond, r.mergeSeconds, r.wallSeconds,
                        r.samplesPerSecond / base);
            std::fflush(stdout);
            out.push_back({{"scene", name},
                           {"ranks", r.ranks},
                           {"samples_per_second", r.samplesPerSecond},
                           {"fill_samples_per_second", r.fillPerSecond},
                           {"merge_seconds", r.mergeSeconds},
                           {"wall_seconds", r.wallSeconds},
                           {"ratio", r.samplesPerSecond / base}});
        }
    }
    std::printf("samples/s: the report's (every rank's fill and the merge); wall: the whole job\n");
    return out;
}

}  // namespace

int runHolodeckBench(const HolodeckBenchOptions& o) {
    nlohmann::json out = nlohmann::json::array();
    std::printf("%-12s %8s %10s %7s %11s %8s %10s %8s %11s %13s %11s %9s\n", "scene", "beams",
                "samples", "B/smp", "fill smp/s", "v.beams", "v.samples", "open ms", "disk smp/s",
                "memory smp/s", "shade smp/s", "mem/shade");
    for (const std::string& name : o.cases) {
        const std::string file =
            (std::filesystem::temp_directory_path() /
             ("penumbra-bench-" + name + "-" + std::to_string(::getpid()) + ".hdk"))
                .string();
        const HolodeckCase c = runCase(o, name, file);
        std::filesystem::remove(file);
        const double bytesPerSample = c.samples > 0 ? double(c.bytes) / c.samples : 0;
        std::printf(
            "%-12s %8lld %10lld %7.2f %11.0f %8lld %10lld %8.1f %11.0f %13.0f %11.0f %9.1f\n",
            c.name.c_str(), (long long)c.beams, (long long)c.samples, bytesPerSample,
            c.fillPerSecond, (long long)c.viewBeams, (long long)c.viewSamples, c.openMs,
            c.diskPerSecond, c.memoryPerSecond, c.shadePerSecond,
            c.memoryPerSecond / c.shadePerSecond);
        std::fflush(stdout);
        out.push_back({{"scene", c.name},
                       {"beams", c.beams},
                       {"samples", c.samples},
                       {"bytes", c.bytes},
                       {"bytes_per_sample", bytesPerSample},
                       {"fill_samples_per_second", c.fillPerSecond},
                       {"view_beams", c.viewBeams},
                       {"view_samples", c.viewSamples},
                       {"open_ms", c.openMs},
                       {"disk_samples_per_second", c.diskPerSecond},
                       {"memory_samples_per_second", c.memoryPerSecond},
                       {"shade_samples_per_second", c.shadePerSecond},
                       {"first_frame_samples", c.firstFrameSamples},
                       {"first_frame_ms", c.firstFrameMs},
                       {"first_frame_error", c.firstFrameError},
                       {"display_first_error", c.displayFirstError},
                       {"display_30_error", c.display30Error}});
    }
    std::printf("paper (Ward & Simmons 1999, OEP office): 41,000 samples/s from file per view\n");
    std::printf("\n%-12s %10s %14s %12s %16s %18s\n", "reopened", "samples", "1st frame ms",
                "1st error", "display 1st err", "display 30th err");
    for (const nlohmann::json& c : out)
        std::printf("%-12s %10lld %14.1f %12.4f %16.4f %18.4f\n",
                    c["scene"].get<std::string>().c_str(),
                    (long long)c["first_frame_samples"].get<std::int64_t>(),
                    c["first_frame_ms"].get<double>(), c["first_frame_error"].get<double>(),
                    c["display_first_error"].get<double>(), c["display_30_error"].get<double>());
    std::printf("goals: first frame <= 500 ms, its error <= the display's after 30 frames\n");
    if (o.genericSeconds > 0 || o.genericSamples > 0)
        for (nlohmann::json& c : out) {
            const std::string name = c["scene"].get<std::string>();
            // A kept file per scene: --generic-holodeck itself for one scene, else beside it
            // with the scene's name.
            const std::string file =
                o.genericFile.empty()
                    ? (std::filesystem::temp_directory_path() /
                       ("penumbra-bench-generic-" + name + "-" + std::to_string(::getpid()) +
                        ".hdk"))
                          .string()
                    : (o.cases.size() == 1 ? o.genericFile : o.genericFile + "." + name + ".hdk");
            c["generic"] = runGeneric(o, name, file);
            if (o.genericFile.empty()) std::filesystem::remove(file);
        }
    // Each scene's entry gains its mpirun rows.
    for (const nlohmann::json& r : runRanksTable(o))
        for (nlohmann::json& c : out)
            if (c["scene"] == r["scene"]) c["mpirun"].push_back(r);
    if (!o.jsonOut.empty()) writeFileAtomically(o.jsonOut, out.dump(2) + "\n");
    return 0;
}

}  // namespace penumbra
