#pragma once
// What the library logs (spdlog's default logger, core/log.h) while a test runs a step: the
// warnings of readers that go on (a truncated edit log, dropped mesh faces, ignored import
// features), one line each as "LEVEL: message".

#include <spdlog/sinks/ostream_sink.h>
#include <spdlog/spdlog.h>

#include <memory>
#include <sstream>
#include <string>

namespace penumbra::test {

/// While alive, spdlog's default logger writes "LEVEL: message" lines (warnings and above)
/// into text(); the previous logger is restored on destruction.
class LogCapture {
public:
    LogCapture() : mPrevious(spdlog::default_logger()) {
        auto sink = std::make_shared<spdlog::sinks::ostream_sink_mt>(mText);
        auto logger = std::make_shared<spdlog::logger>("penumbra-test-capture", sink);
        logger->set_pattern("%l: %v");
        logger->set_level(spdlog::level::warn);
        spdlog::set_default_logger(logger);
    }
    ~LogCapture() { spdlog::set_default_logger(mPrevious); }
    LogCapture(const LogCapture&) = delete;
    LogCapture& operator=(const LogCapture&) = delete;

    std::string text() const { return mText.str(); }

private:
    std::ostringstream mText;
    std::shared_ptr<spdlog::logger> mPrevious;
};

}  // namespace penumbra::test
