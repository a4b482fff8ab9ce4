#pragma once
// Helpers shared by the in-process editor display tests.

#include <algorithm>
#include <chrono>
#include <thread>

#include "ui/editor_app.h"

namespace penumbra::test {

/// Runs editor frames until `done()` (or the time limit), at most ~200 frames per second, or
/// at most `fps` frames per second when given (a drag benchmark moves its object one step a
/// frame: at the editor's own frame cap, as a user's drag would).
template <typename Done>
bool runUntil(EditorApp& app, Done done, double seconds, double fps = 200) {
    const auto start = std::chrono::steady_clock::now();
    const auto period = std::chrono::duration<double>(1.0 / fps);
    while (std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count() <
           seconds) {
        const auto frameStart = std::chrono::steady_clock::now();
        app.frame();
        if (done()) return true;
        std::this_thread::sleep_until(frameStart +
                                      std::max(period, std::chrono::duration<double>(0.005)));
    }
    return false;
}

}  // namespace penumbra::test
