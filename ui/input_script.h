#pragma once
// An input script: what a user does in the editor, written down and played by the editor's
// frame loop through EditorControls (ui/editor_driver.h): `penumbra-editor SCENE --script FILE`,
// and the benchmarks (ui/editor_benches.h), which generate theirs. One command a line, `#`
// comments and blank lines skipped:
//
//   wait-lit [MAX_S]          until the lighting has settled (the runner quiescent), at most
//                             MAX_S seconds (120); longer is a warning line, and the script goes on
//   select ID                 selects the object, as a click on it does
//   wait-images N [MAX_S]     until N more viewport images have been shown (at most MAX_S, 10)
//   drag                      presses the selected object's gizmo
//   move DX DY DZ             one gizmo position: the object translated by (DX, DY, DZ) metres
//                             from where the drag began; one a frame-loop tick
//   drop                      releases the gizmo
//   wait S                    S seconds
//   wait-settled [MAX_S]      until the lighting has settled and the viewport shows the latest
//                             image (at most MAX_S, 60)
//   mark NAME                 tells the script's observer (InputScript::onMark) of this moment
//   quit                      ends the editor (status 0)
//
// A malformed line is an InputError naming the file and line (exit status 2); an object the
// scene does not have, met while playing, is one error line and the editor ends with status 2.
//
// Index: InputScript

#include <functional>
#include <string>
#include <vector>

#include "ui/editor_driver.h"

namespace penumbra {

class InputScript : public EditorDriver {
public:
    /// Parses `text`, naming `source` in errors. Throws InputError for a malformed line.
    static InputScript parse(const std::string& text, const std::string& source);
    /// Reads and parses the file (InputError when it cannot be read).
    static InputScript load(const std::string& path);

    /// Called at each `mark NAME` with the editor, the name and the time.
    std::function<void(EditorControls& editor, const std::string& name, double now)> onMark;

    void tick(EditorControls& editor, double now) override;
    void shown(EditorControls& editor, const std::shared_ptr<const ViewportImage>& image,
               double now) override;
    /// While a select waits for its images and while the gizmo is held.
    bool wantsFrames() const override;

    /// Every command played.
    bool done() const { return mNext >= mCommands.size(); }
    /// Gizmo positions sent in the current (or last) drag.
    int moves() const { return mMoves; }
    std::size_t size() const { return mCommands.size(); }

private:
    struct Command {
        int line = 0;
        std::string verb;
        std::string name;            ///< select's id, mark's name
        std::vector<double> values;  ///< the numbers
    };
    /// Plays `c` at `now`; true when it is done (the script goes on to the next).
    bool step(const Command& c, EditorControls& editor, double now);

    std::string mSource;
    std::vector<Command> mCommands;
    std::size_t mNext = 0;
    bool mStarted = false;  ///< the current command has begun (its start time and images)
    double mStartedAt = 0;
    long mImagesAtStart = 0;
    long mImages = 0;
    bool mHolding = false;  ///< between drag and drop
    bool mWaitingImages = false;
    int mMoves = 0;
};

}  // namespace penumbra
