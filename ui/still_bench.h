#pragma once
// What the user sees when nothing moves, measured (`penumbra-editor --bench-still SECONDS`): the
// viewport's image at a few moments after the lighting settled (the runner quiescent: the
// solution converged, the display built; then 1, 2, 5, 10 s … up to SECONDS), each
// compared with a reference render of the same view (the lighting converged, every pixel shaded
// with the point shader on a 2×2 sub-pixel grid) and, for scale, the Gouraud render of the same
// view and converged lighting against the same reference. The display's still view should come
// closer to the reference than Gouraud does (issue 47, point 5).
//
// Index: StillBenchOptions · StillBench

#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "edit/io/scene_import.h"
#include "ui/runner_board.h"

namespace penumbra {

struct StillBenchOptions {
    std::string scene;  ///< the scene file the editor opened (for the references)
    ImportOptions import;  ///< how it was imported when it is a glTF or OBJ file
    double seconds = 10;
    int referenceSamplesPerAxis = 2;
    std::string recordDir;  ///< "" for none: else the images, the reference and Gouraud
};

class StillBench {
public:
    explicit StillBench(StillBenchOptions options);
    /// The lighting settled at `now` (seconds on the clock the other calls use): the
    /// checkpoints count from here.
    void begin(double now) { mStart = now; }
    bool begun() const { return mStart >= 0; }
    /// The image the viewport shows at `now` (nullptr: none yet): kept for every checkpoint
    /// not yet passed.
    void shown(const std::shared_ptr<const ViewportImage>& image, double now);
    bool done(double now) const { return begun() && now - mStart >= mOptions.seconds; }
    /// Solves the scene again to convergence, renders the reference and the Gouraud image of the
    /// last image's view and size, and returns the figures as JSON: per checkpoint its seconds,
    /// the image's error (relativeDisplayRmse) and error_without_lamps (relativeRmse with the
    /// lamps and their edge pixels left out, as `render --compare`), the display's settled
    /// frames; Gouraud's two errors; and for each measure the first checkpoint closer to the
    /// reference than Gouraud (closer_than_gouraud[_without_lamps]_at_s, -1 none).
    nlohmann::json analyse();

private:
    struct Checkpoint {
        double seconds = 0;
        std::shared_ptr<const ViewportImage> image;
        double shownAt = -1;  ///< when the kept image was seen (seconds after begin())
    };
    StillBenchOptions mOptions;
    std::vector<Checkpoint> mCheckpoints;
    double mStart = -1;  ///< begin()'s time, -1 before
};

}  // namespace penumbra
