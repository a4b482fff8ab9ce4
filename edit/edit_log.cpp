// Edit log: append-only JSONL writer (write + fsync per line) and reader.
#include "edit/edit_log.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cmath>
#include <cstring>
#include <fstream>
#include <sstream>
#include <stdexcept>

#include "core/input_error.h"
#include "core/log.h"

namespace penumbra {

namespace {

/// True when `text` parses as JSON (of any kind).
bool isValidJson(const std::string& text) { return nlohmann::json::accept(text); }

/// Writes all of `text` to `fd`; false on error.
bool writeAll(int fd, const std::string& text) {
    for (size_t written = 0; written < text.size();) {
        const ssize_t n = ::write(fd, text.data() + written, text.size() - written);
        if (n < 0) {
            if (errno == EINTR) continue;
            return false;
        }
        written += static_cast<size_t>(n);
    }
    return true;
}

int countLines(const std::string& text, size_t end) {
    int lines = 1;
    for (size_t i = 0; i < end && i < text.size(); ++i)
        if (text[i] == '\n') ++lines;
    return lines;
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// Writer.

EditLogWriter::EditLogWriter(const std::string& path)
    : mPath(path), mStart(std::chrono::steady_clock::now()) {
    mFd = ::open(path.c_str(), O_RDWR | O_CREAT | O_APPEND | O_CLOEXEC, 0644);
    if (mFd < 0)
        throw InputError(path, "", std::string("cannot open edit log: ") + std::strerror(errno));

    // An existing log must end in a newline before lines are appended. A final line cut off
    // mid-write is dropped (the reader would skip it anyway); a complete one gets its newline.
    struct stat st {};
    if (::fstat(mFd, &st) == 0 && st.st_size > 0) {
        std::ifstream in(path, std::ios::binary);
        std::stringstream buffer;
        buffer << in.rdbuf();
        const std::string text = buffer.str();
        if (!text.empty() && text.back() != '\n') {
            const size_t lastNewline = text.rfind('\n');
            const size_t start = lastNewline == std::string::npos ? 0 : lastNewline + 1;
            const std::string last = text.substr(start);
            bool ok;
            if (isValidJson(last)) {
                ok = writeAll(mFd, "\n");
            } else {
                spdlog::warn(
                    "{}: line {}: truncated final line (no newline, not valid JSON) removed "
                    "before appending",
                    path, countLines(text, start));
                ok = ::ftruncate(mFd, static_cast<off_t>(start)) == 0;
            }
            if (!ok || ::fsync(mFd) != 0) {
                const std::string reason = std::strerror(errno);
                ::close(mFd);
                throw InputError(path, "", "cannot repair the edit log's last line: " + reason);
            }
        }
    }
}

EditLogWriter::~EditLogWriter() {
    if (mFd >= 0) ::close(mFd);
}

double EditLogWriter::elapsedMs() const {
    return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - mStart)
        .count();
}

void EditLogWriter::append(const EditCommand& command) {
    EditCommand stamped = command;
    stamped.tMs = std::round(elapsedMs() * 1000.0) / 1000.0;  // microsecond resolution
    const std::string line = formatEditCommand(stamped) + "\n";
    // One write per line, so a crash leaves at most the final line incomplete.
    if (!writeAll(mFd, line) || ::fsync(mFd) != 0)
        throw std::runtime_error(mPath + ": cannot write edit log: " + std::strerror(errno));
    ++mLines;
}

// ---------------------------------------------------------------------------------------------
// Reader.

std::vector<LoggedEdit> readEditLog(const std::string& path, const std::string& meshBaseDir) {
    std::ifstream in(path, std::ios::binary);
    if (!in)
        throw InputError(path, "", std::string("cannot read edit log: ") + std::strerror(errno));
    std::stringstream buffer;
    buffer << in.rdbuf();
    if (in.bad()) throw InputError(path, "", "cannot read edit log: read error");
    const std::string text = buffer.str();

    std::vector<LoggedEdit> edits;
    size_t start = 0;
    for (int lineNo = 1; start < text.size(); ++lineNo) {
        const size_t newline = text.find('\n', start);
        const bool complete = newline != std::string::npos;
        std::string line = text.substr(start, complete ? newline - start : std::string::npos);
        start = complete ? newline + 1 : text.size();
        if (!line.empty() && line.back() == '\r') line.pop_back();
        if (line.find_first_not_of(" \t") == std::string::npos) continue;
        if (!complete && !isValidJson(line)) {
            // A crash mid-write: report it, keep everything before it.
            spdlog::warn("{}: line {}: truncated final line (no newline, not valid JSON) skipped",
                         path, lineNo);
            break;
        }
        EditSource source{path, lineNo};
        edits.push_back({lineNo, parseEditCommand(line, source, nullptr, meshBaseDir)});
    }
    return edits;
}

}  // namespace penumbra
