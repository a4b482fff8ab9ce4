#pragma once
// Elapsed time on the monotonic clock, for progress, reports and benchmarks.

#include <chrono>

namespace penumbra {

using Clock = std::chrono::steady_clock;

inline double secondsSince(Clock::time_point start) {
    return std::chrono::duration<double>(Clock::now() - start).count();
}

inline double msSince(Clock::time_point start) { return 1e3 * secondsSince(start); }

}  // namespace penumbra
