#pragma once
// The benchmarks that drive the editor from outside it (ui/editor_driver.h), each an input
// script (ui/input_script.h) it generates and an observer of the images the script's session
// shows:
//   --bench-drag ID: DragBenchDriver, what the user sees while an object is dragged
//     (ui/drag_bench.h): wait until the scene is lit, select the object, wait for two images
//     (the outline), drag it in a circle one gizmo position a tick, drop it, keep two seconds of
//     images, then the settled image and one a second later; one JSON line on stdout.
//   --bench-still S: StillBenchDriver, the viewport at rest against a reference
//     (ui/still_bench.h): wait until the scene is lit, then hand it S seconds of images.
//
// Index: DragBenchDriverOptions · DragBenchDriver · StillBenchDriver

#include <memory>
#include <nlohmann/json.hpp>
#include <string>

#include "edit/io/scene_import.h"
#include "ui/drag_bench.h"
#include "ui/editor_app.h"
#include "ui/input_script.h"
#include "ui/still_bench.h"

namespace penumbra {

struct DragBenchDriverOptions {
    std::string object;     ///< the dragged object's id
    int frames = 300;       ///< gizmo positions (one a tick): 120 make one circle
    std::string recordDir;  ///< every image shown and the references, "" none
    bool references = true;
};

class DragBenchDriver : public EditorDriver {
public:
    explicit DragBenchDriver(DragBenchDriverOptions options);
    /// The script the bench plays (marks drag, dropped, window-end, settled, settled-again).
    static std::string script(const std::string& object, int frames);

    void tick(EditorControls& editor, double now) override;
    void shown(EditorControls& editor, const std::shared_ptr<const ViewportImage>& image,
               double now) override;
    bool wantsFrames() const override { return mScript.wantsFrames(); }
    /// Prints report() as one JSON line on stdout (when the bench got to its drag).
    void finished(EditorControls& editor) override;

    /// The images seen so far (nullptr before the drag), and whether the bench has its
    /// second settled image.
    DragBench* bench() { return mBench.get(); }
    bool done() const { return mPhase == Phase::Done; }
    /// Ticks and ms from the drag's start to the first image that shows the object moved (a
    /// preview version other than the selected one), -1 if none came.
    int dragStartFrames() const { return mDragStartFrames; }
    double dragStartMs() const { return mDragStartMs; }
    /// The frame figures from the drag to the window's end, and DragBench::analyse().
    nlohmann::json report(EditorControls& editor);

private:
    enum class Phase { Waiting, Dragging, AfterDrop, Settling, Done };
    void mark(EditorControls& editor, const std::string& name, double now);

    DragBenchDriverOptions mOptions;
    InputScript mScript;
    Phase mPhase = Phase::Waiting;
    std::unique_ptr<DragBench> mBench;
    int mOrigin = -1;    ///< the object's version when the drag began
    double mStart = 0;   ///< when the drag began
    FrameStats mWindow;  ///< the frame figures at the window's end
    bool mWindowDone = false;
    int mDragStartFrames = -1;
    double mDragStartMs = -1;
};

class StillBenchDriver : public EditorDriver {
public:
    /// `scene` and `import` as the editor opened them; `seconds` of images from the moment the
    /// lighting settled (at most 120 s after the start).
    StillBenchDriver(std::string scene, ImportOptions import, double seconds, std::string recordDir,
                     bool quiet);
    void tick(EditorControls& editor, double now) override;
    /// Prints the bench's analysis as one JSON line on stdout.
    void finished(EditorControls& editor) override;
    StillBench* bench() { return mBench.get(); }
    bool done() const { return mDone; }

private:
    StillBenchOptions mOptions;
    bool mQuiet;
    InputScript mScript;
    std::unique_ptr<StillBench> mBench;
    double mStart = -1;
    bool mDone = false;
};

}  // namespace penumbra
