#pragma once
// Benchmarks behind `penumbra bench`: each prints figures and ratios against a baseline
// measured in the same run (STYLE: speed lives in benchmarks, never in timed tests).

#include <cstdint>
#include <string>
#include <vector>

#include "solver/progressive_solver.h"

namespace penumbra {

struct BenchOptions {
    std::vector<std::string> scenes;
    double maxSecondsPerScene = 120;  ///< solver time cap per scene
    std::string jsonOut;              ///< optional JSON with every figure
    /// Internal: measure this one scene and print its JSON (the per-scene child process).
    std::string childScene;
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
    /// Reads the converged references from here (PATH-<scene>) when present, else writes
    /// them: repeated runs skip the reference solves.
    std::string referenceCache;
    /// Prints, per sample, the top-1% error split between the added objects' elements and
    /// the others.
    bool split = false;
};

/// `penumbra bench redistribution`: George et al. Figures 6 and 7 — error against time after
/// adding an object, for redistribution, from-scratch progressive refinement, and insertion
/// without redistribution.
int runRedistributionBench(const RedistributionBenchOptions& options);

struct DisplayBenchOptions {
    std::vector<std::string> cases{"robot-room", "armadillo-field"};
    std::string sceneDir = "scenes";
    int width = 512;
    int height = 512;
    int frames = 30;
    double sampleFraction = 0.02;  ///< new samples per frame (Bala et al.: 1–3%)
    double warmup = 0.25;          ///< fraction of the pixels shaded before the first frame
    double degPerFrame = 0.5;      ///< camera orbit per frame
    int referenceSamples = 2;      ///< reference supersampling per axis
    /// The display's adaptive shadow sampling (PointShaderOptions::shadowRefine, 0 = off,
    /// shadowMaxRefinedPerAxis, shadowDecisionPerAxis); the converged reference always uses
    /// its own deep setting.
    int shadowRefine = 0;
    int shadowMaxRefined = 16;
    int shadowDecision = 4;
    /// Also render a second converged reference with another seed and print their difference
    /// (the reference's own noise) and noise-subtracted errors.
    bool referenceCheck = false;
    /// EpiOptions::smoothRadius for the display (−1: the display's default).
    int smoothRadius = -1;
    /// InteractiveDisplayOptions::maxPenumbraPixels (−1: the display's default).
    double maxPenumbraPixels = -1;
    /// InteractiveDisplayOptions::cacheCapacityPerPixel (−1: the display's default).
    double cacheCapacity = -1;
    /// Skip the converged reference (minutes): errors against the plain reference only.
    bool skipConvergedReference = false;
    std::string plotDir;  ///< writes display-{cache,epi,reference,edges}.png of the first case
    std::string jsonOut;
};

/// `penumbra bench display`: Bala et al. 2003 Table 2 — per-frame stage times, fps, epi and
/// cache error against the every-pixel reference on the same samples, speedup over shading
/// every pixel once, silhouette time, shadow-edge update after a move.
int runDisplayBench(const DisplayBenchOptions& options);

struct HifiBenchOptions {
    std::vector<std::string> cases{"cornell-box", "cube-room"};  ///< robot-room: docs/hifi.md
    std::string sceneDir = "scenes";
    double converge = 1e-3;
    int gatherRays = 256;  ///< ExactIrradianceOptions::farRays, as `render --mode interpolant`
    int width = 1280;      ///< evaluation size
    int height = 720;
    int frames = 20;
    int errorWidth = 320;  ///< error images' size
    int errorHeight = 240;
    std::string plotDir;  ///< writes hifi-<scene>-{reference,gouraud,interpolant}.png there
    std::string jsonOut;
    /// The race against the path tracer: both against a `referenceSpp` path trace of the
    /// default view at compareWidth × compareHeight (0: no race). The path tracer renders at
    /// 1, 2, 4, … paths per pixel until its error is at most the interpolants' (or
    /// `pathTraceMaxSeconds` of tracing are spent, or a quarter of referenceSpp is reached).
    int referenceSpp = 1024;
    int compareWidth = 320;
    int compareHeight = 240;
    int compareSamples = 2;  ///< the interpolants' samples per pixel per axis, as `render`'s
    double pathTraceMaxSeconds = 900;
    /// Reads the path-traced references from PATH-<scene>-<W>x<H>-<spp>spp.exr when present,
    /// else writes them there: repeated runs skip the reference renders (minutes each). A
    /// changed scene needs a new PATH.
    std::string referenceCache;
};

/// `penumbra bench hifi`: Hardt & Teller 1996 — interpolant build time and triangles,
/// evaluation frames/s on the offscreen GL pass, and the error of gouraud, epi and
/// interpolant against the display's reference, per scene; then the path tracer's time to
/// the interpolants' error against a path-traced reference, over the interpolants' time
/// (leaf solve, build and render).
int runHifiBench(const HifiBenchOptions& options);

struct HolodeckBenchOptions {
    std::vector<std::string> cases{"cube-room", "robot-room"};
    std::string sceneDir = "scenes";
    std::int64_t samples = 2000000;  ///< the batch fill
    int width = 512;                 ///< the default camera's view, whose beams are read back
    int height = 512;
    /// `mpirun -np K penumbra holodeck fill` of `samples` for each K (empty: none), timed as a
    /// subprocess of this binary.
    std::vector<int> ranks{1, 2};
    /// A holodeck filled for no view this long (every beam in proportion to its volume), then
    /// nine views of the room opened from it (0: none).
    double genericSeconds = 60;
    /// Instead, a generic fill of this many samples (0: by time): the same samples however
    /// busy the machine is.
    std::int64_t genericSamples = 0;
    /// The generic holodeck's file: filled there and kept when missing, else reused as it is
    /// (the nine views then measure the same samples from run to run). Empty: a temporary file.
    std::string genericFile;
    std::string jsonOut;
};
/// `penumbra bench holodeck`: fill rate and bytes per sample of a batch fill; a view's samples
/// read back from disk and from memory, against shading them (Ward & Simmons 1999); the batch
/// fill's rate under mpirun with each of `ranks` processes; a holodeck filled for no view,
/// then nine views opened from it.
int runHolodeckBench(const HolodeckBenchOptions& options);

}  // namespace penumbra
