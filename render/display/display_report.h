#pragma once
// The display's per-frame figures as the JSON reports list them: `penumbra render --report`'s
// "frames" and `penumbra bench display --json`'s.

#include <nlohmann/json.hpp>

namespace penumbra {

struct DisplayFrameStats;

/// One frame's number, stage times (ms), sample counts and edge and pixel counts, one key
/// each (snake_case, times ending in _ms).
nlohmann::json displayFrameJson(const DisplayFrameStats& f);

}  // namespace penumbra
