#include "core/log.h"

#include <spdlog/sinks/stdout_sinks.h>

namespace penumbra {

void initLogging(bool verbose) {
    auto logger = spdlog::stderr_logger_mt("penumbra");
    logger->set_pattern("penumbra %l: [%H:%M:%S.%e] %v");
    logger->set_level(verbose ? spdlog::level::debug : spdlog::level::warn);
    spdlog::set_default_logger(logger);
}

}  // namespace penumbra
