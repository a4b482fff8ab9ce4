#pragma once
// Helpers shared by the SessionRunner tests (no window).

#include <chrono>
#include <functional>
#include <memory>
#include <thread>

#include "ui/session_runner.h"

namespace penumbra::test {

/// Pumps an unthreaded runner until `done` holds for its latest image (at most `seconds`),
/// sleeping `pauseMs` between pumps.
inline std::shared_ptr<const ViewportImage> pumpUntil(
    SessionRunner& runner, double seconds, const std::function<bool(const ViewportImage&)>& done,
    int pauseMs = 2) {
    const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
    std::shared_ptr<const ViewportImage> img;
    while (std::chrono::steady_clock::now() < end) {
        runner.pump();
        img = runner.image();
        if (img && done(*img)) break;
        if (pauseMs > 0) std::this_thread::sleep_for(std::chrono::milliseconds(pauseMs));
    }
    return img;
}

/// Waits until `done` holds for a threaded runner's latest image (at most `seconds`).
inline std::shared_ptr<const ViewportImage> waitUntil(
    SessionRunner& runner, double seconds, const std::function<bool(const ViewportImage&)>& done) {
    const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
    std::shared_ptr<const ViewportImage> img;
    while (std::chrono::steady_clock::now() < end) {
        img = runner.image();
        if (img && done(*img)) break;
        std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    return img;
}

}  // namespace penumbra::test
