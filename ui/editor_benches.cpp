#include "ui/editor_benches.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <sstream>
#include <vector>

#include "ui/session_runner.h"

namespace penumbra {

// ---------------------------------------------------------------------------------------------
// Drag: the object circles 0.3 m about where it starts, one gizmo position a tick.

namespace {

/// The gizmo's offset from where the drag began at position k (120 positions a circle).
Vec3 circleOffset(int k) {
    const double a = 2.0 * M_PI * k / 120.0;
    return {0.3 * std::sin(a), 0.0, 0.3 * (1.0 - std::cos(a))};
}

}  // namespace

std::string DragBenchDriver::script(const std::string& object, int frames) {
    std::ostringstream s;
    s.precision(17);
    // Once the scene is lit, as a user would; select, and wait for the outline (the view
    // request naming the selection reaches the render thread with the first image at the
    // latest) before pressing the gizmo.
    s << "wait-lit 120\nselect " << object << "\nwait-images 2 10\nmark drag\ndrag\n";
    for (int k = 1; k <= frames; ++k) {
        const Vec3 d = circleOffset(k);
        s << "move " << d.x << ' ' << d.y << ' ' << d.z << '\n';
    }
    // The window after the drop, then the settled image (lighting converged, the display's
    // cache full) and the same state a second later (the display's noise floor).
    s << "drop\nmark dropped\nwait 2\nmark window-end\nwait-settled 60\nmark settled\nwait 1\n"
         "mark settled-again\nquit\n";
    return s.str();
}

DragBenchDriver::DragBenchDriver(DragBenchDriverOptions options)
    : mOptions(std::move(options)),
      mScript(InputScript::parse(script(mOptions.object, mOptions.frames), "--bench-drag")) {
    mScript.onMark = [this](EditorControls& editor, const std::string& name, double now) {
        mark(editor, name, now);
    };
}

void DragBenchDriver::tick(EditorControls& editor, double now) { mScript.tick(editor, now); }

void DragBenchDriver::mark(EditorControls& editor, const std::string& name, double now) {
    SessionRunner* runner = editor.runner();
    const auto doc = runner ? runner->document() : nullptr;
    const ObjectSummary* o = doc ? doc->find(mOptions.object) : nullptr;
    if (name == "drag" && o) {
        editor.resetFrameStats();
        mOrigin = o->version;
        mStart = now;
        DragBenchOptions bench;
        bench.scene = editor.scenePath();
        bench.object = o->id;
        bench.recordDir = mOptions.recordDir;
        if (!mOptions.references) bench.dragReferences = 0, bench.scene.clear();
        mBench = std::make_unique<DragBench>(bench);
        mBench->started(now, o->transform);
        mPhase = Phase::Dragging;
    } else if (!mBench) {
        return;
    } else if (name == "dropped") {
        Transform final = editor.dragStart();
        final.translate += circleOffset(mOptions.frames);
        mBench->dropped(now, final);
        mPhase = Phase::AfterDrop;
    } else if (name == "window-end") {
        mBench->windowDone();
        mWindow = editor.frameStats();
        mWindowDone = true;
        mPhase = Phase::Settling;
    } else if (name == "settled") {
        // (wait-settled warned when it gave up: the image shown then stands in.)
        mBench->settled(editor.shownImage());
    } else if (name == "settled-again") {
        if (editor.shownImage()) mBench->settledAgain(editor.shownImage());
        mPhase = Phase::Done;
    }
}

void DragBenchDriver::shown(EditorControls& editor,
                            const std::shared_ptr<const ViewportImage>& image, double now) {
    mScript.shown(editor, image, now);
    if (mBench && (mPhase == Phase::Dragging || mPhase == Phase::AfterDrop)) {
        // Full resolution: the viewport's, or its --display-divisor share.
        const int d = std::max(1, editor.displayDivisor());
        mBench->shown(image, now, editor.viewportWidth() / d, editor.viewportHeight() / d);
    }
    if (mPhase == Phase::Dragging && mDragStartFrames < 0 && image->previewVersion >= 0 &&
        image->previewVersion != mOrigin) {
        mDragStartFrames = mScript.moves();
        mDragStartMs = (now - mStart) * 1e3;
    }
}

nlohmann::json DragBenchDriver::report(EditorControls& editor) {
    // Frame-time figures from the drag to the end of the window after the drop, then what
    // the images showed.
    const FrameStats& stats = mWindowDone ? mWindow : editor.frameStats();
    std::vector<double> w = stats.workMs, p = stats.periodMs, im = stats.imageMs;
    std::sort(im.begin(), im.end());
    std::sort(w.begin(), w.end());
    std::sort(p.begin(), p.end());
    double sumP = 0;
    for (double v : p) sumP += v;
    auto at = [](const std::vector<double>& v, double q) {
        return v.empty() ? 0.0 : v[static_cast<std::size_t>(q * (v.size() - 1))];
    };
    nlohmann::json report = {
        {"frames", w.size()},
        {"work_ms_median", at(w, 0.5)},
        {"work_ms_p95", at(w, 0.95)},
        {"period_ms_median", at(p, 0.5)},
        {"period_ms_p95", at(p, 0.95)},
        {"fps", sumP > 0 ? 1000.0 * p.size() / sumP : 0.0},
        {"viewport_images", stats.imagesShown},
        {"viewport_images_per_s", stats.seconds() > 0 ? stats.imagesShown / stats.seconds() : 0.0},
        {"frames_drawn_share", stats.ticks > 0 ? double(w.size()) / stats.ticks : 0.0},
        {"mode", toString(editor.viewMode())},
        {"viewport", {editor.viewportWidth(), editor.viewportHeight()}},
        {"image_ms_median", at(im, 0.5)},
        {"image_ms_p95", at(im, 0.95)},
        {"drag_start_frames", mDragStartFrames},
        {"drag_start_ms", mDragStartMs}};
    if (mBench) report.update(mBench->analyse());
    return report;
}

void DragBenchDriver::finished(EditorControls& editor) {
    if (!mBench) return;
    std::printf("%s\n", report(editor).dump().c_str());
    std::fflush(stdout);
}

// ---------------------------------------------------------------------------------------------
// Still view

StillBenchDriver::StillBenchDriver(std::string scene, ImportOptions import, double seconds,
                                   std::string recordDir, bool quiet)
    : mQuiet(quiet),
      // From the moment the lighting settled, as a user who waits for the scene to light up
      // and then looks.
      mScript(InputScript::parse("wait-lit 120\nmark begin\n", "--bench-still")) {
    mOptions.scene = std::move(scene);
    mOptions.import = std::move(import);
    mOptions.seconds = seconds;
    mOptions.recordDir = std::move(recordDir);
    mBench = std::make_unique<StillBench>(mOptions);
    mScript.onMark = [this](EditorControls&, const std::string&, double now) {
        if (!mQuiet)
            std::cerr << "penumbra-editor: --bench-still: settled after " << now - mStart << " s\n";
        mBench->begin(now);
    };
}

void StillBenchDriver::tick(EditorControls& editor, double now) {
    if (mDone) return;
    if (mStart < 0) mStart = now;
    mScript.tick(editor, now);
    if (!mBench->begun()) return;
    mBench->shown(editor.shownImage(), now);
    if (mBench->done(now)) {
        mDone = true;
        editor.quit(0);
    }
}

void StillBenchDriver::finished(EditorControls&) {
    std::cout << mBench->analyse().dump() << std::endl;
}

}  // namespace penumbra
