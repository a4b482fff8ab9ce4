#pragma once
// Helpers shared by the in-process editor display tests.

#include <chrono>
#include <thread>

#include "ui/editor_app.h"

namespace penumbra::test {

/// Runs editor frames until `done()` (or the time limit), at most ~200 frames per second.
template <typename Done>
bool runUntil(EditorApp& app, Done done, double seconds) {
    const auto start = std::chrono::steady_clock::now();
    while (std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count() <
           seconds) {
        app.frame();
        if (done()) return true;
        std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
    return false;
}

}  // namespace penumbra::test
