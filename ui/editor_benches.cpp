// The benchmarks the editor drives through its own frame loop: --bench-drag (ui/drag_bench.h)
// and --bench-still (ui/still_bench.h). EditorApp's members; the measuring itself is in those
// classes.
//
// Index: still view · drag (stepping, report)

#include <GLFW/glfw3.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <nlohmann/json.hpp>
#include <vector>

#include "ui/drag_bench.h"
#include "ui/editor_app.h"
#include "ui/still_bench.h"

namespace penumbra {

// ---------------------------------------------------------------------------------------------
// Still view

void EditorApp::stepStillBench() {
    if (mOptions.benchStill <= 0 || mStillDone) return;
    const double now = glfwGetTime();
    if (!mStillBench) {
        StillBenchOptions still;
        // The file as opened (an imported scene's Penumbra path exists only once saved).
        still.scene = mOptions.scene;
        still.import = mOptions.import;
        still.seconds = mOptions.benchStill;
        still.recordDir = mOptions.record;
        mStillBench = std::make_unique<StillBench>(still);
        mStillStart = now;
    }
    if (!mStillBench->begun()) {
        // From the moment the lighting settled (at most 120 s after the start), as a user
        // who waits for the scene to light up and then looks.
        const bool settled = mRunner && mRunner->quiescent();
        if (!settled && now - mStillStart < 120) return;
        if (!settled) std::cerr << "penumbra-editor: --bench-still: not settled after 120 s\n";
        if (!mOptions.quiet)
            std::cerr << "penumbra-editor: --bench-still: settled after " << now - mStillStart
                      << " s\n";
        mStillBench->begin(now);
    }
    mStillBench->shown(mShown, now);
    if (mStillBench->done(now)) {
        mStillDone = true;
        mQuit = true;
    }
}

// ---------------------------------------------------------------------------------------------
// Drag benchmark: the object circles about where it starts, one position per frame, through
// the same path as a gizmo drag (select, coalesced transforms, unselect).

void EditorApp::stepBenchmark() {
    if (!mRunner) return;
    const double now = glfwGetTime();
    const auto doc = mRunner->document();
    const ObjectSummary* o = doc ? doc->find(mOptions.benchDrag) : nullptr;
    if (mBenchPhase == 0) {
        // Start once the scene is lit (at most 120 s), as a user would.
        if (o && !mRunner->quiescent() && now < 120) return;
        if (!o) {
            std::cerr << "penumbra-editor: --bench-drag: unknown object '" << mOptions.benchDrag
                      << "'\n";
            mQuit = true;
            return;
        }
        mSelection = o->id;
        mBenchSelectedImages = 0;
        mBenchSettleStart = now;
        mBenchPhase = 6;
        return;
    }
    if (mBenchPhase == 6) {
        // The second image after the select has the outline (the view request naming the
        // selection reaches the render thread with the first at the latest).
        if (!o || (mBenchSelectedImages < 2 && now - mBenchSettleStart < 10)) return;
        for (const EditCommand& c : mDrag.begin(o->id, o->transform)) submit(c);
        mStats = FrameStats{};
        mBenchOrigin = o->version;
        mBenchStart = now;
        DragBenchOptions bench;
        bench.scene = mScenePath;
        bench.object = o->id;
        bench.recordDir = mOptions.record;
        if (!mOptions.benchReferences) bench.dragReferences = 0, bench.scene.clear();
        mBench = std::make_unique<DragBench>(bench);
        mBench->started(now, o->transform);
        mBenchPhase = 1;
    }
    if (mBenchPhase == 1) {
        ++mBenchFrame;
        Transform t = mDrag.start();
        const double a = 2.0 * M_PI * mBenchFrame / 120.0;
        t.translate += Vec3(0.3 * std::sin(a), 0.0, 0.3 * (1.0 - std::cos(a)));
        if (auto c = mDrag.update(t)) mRunner->submitCoalescing(*c);
        mLastInteraction = now;
        if (mBenchFrame >= mOptions.frames) {
            const Transform final = mDrag.current();
            for (const EditCommand& c : mDrag.end()) submit(c);
            mBench->dropped(now, final);
            mBenchPhase = 2;
        }
    } else if (mBenchPhase == 2) {
        if (mBench->afterDropDone(now)) {
            mBench->windowDone();
            mBenchWindowStats = mStats;
            mBenchSettleStart = now;
            mBenchPhase = 3;
        }
    } else if (mBenchPhase == 3) {
        // The settled image: lighting converged and the display's cache full (at most 60 s).
        const bool settled = mRunner->quiescent() && mShown && mShown == mRunner->image();
        if (settled || now - mBenchSettleStart > 60) {
            if (!settled) std::cerr << "penumbra-editor: --bench-drag: not settled after 60 s\n";
            mBench->settled(mShown);
            mBenchSettleStart = now;
            mBenchPhase = 5;
        }
    } else if (mBenchPhase == 5) {
        // One second later, the same state again: the display's noise floor.
        if (now - mBenchSettleStart > 1.0 && mShown) {
            mBench->settledAgain(mShown);
            mBenchPhase = 4;
        }
    }
}

void EditorApp::printDragBenchReport() {
    // Frame-time figures from the select to the end of the window after the drop, then
    // what the images showed.
    const FrameStats& stats = mBenchPhase >= 3 ? mBenchWindowStats : mStats;
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
        {"mode", toString(mMode)},
        {"viewport", {mViewportW, mViewportH}},
        {"image_ms_median", at(im, 0.5)},
        {"image_ms_p95", at(im, 0.95)},
        {"drag_start_frames", stats.dragStartFrames},
        {"drag_start_ms", stats.dragStartMs}};
    report.update(mBench->analyse());
    std::printf("%s\n", report.dump().c_str());
    std::fflush(stdout);
}

}  // namespace penumbra
