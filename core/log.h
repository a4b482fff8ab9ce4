#pragma once
// Logging through spdlog (Debian's libspdlog), on stderr. Debug lines say what the editor's
// threads do and how long it takes; they show with `--verbose` (both executables). Errors
// keep their own contract (one line naming the input, exit status 2) and do not go through
// here. Use spdlog::debug("...{}...", ...) at the call site.

#include <spdlog/spdlog.h>

namespace penumbra {

/// Makes the default logger write to stderr ("penumbra debug: ..."), at debug level when
/// `verbose`, else warnings and errors only. Call once at start-up, before other threads.
void initLogging(bool verbose);

}  // namespace penumbra
