#pragma once
// The edit log: an append-only JSONL file, one committed edit per line (DESIGN.md "Edit
// log"). It is what survives a crash: every line is on disk before append() returns.

#include <chrono>
#include <string>
#include <vector>

#include "edit/edit_command.h"

namespace penumbra {

/// Appends edits to a log file. Opening an existing log appends to it; a final line cut off
/// by a crash (no newline and not valid JSON) is reported (spdlog::warn) and cut away first, so
/// the new lines do not run into it. Not copyable; closes the file on destruction.
class EditLogWriter {
public:
    /// Opens (creates) `path` for appending. Throws InputError naming the file when it cannot
    /// be opened. Session time starts now.
    explicit EditLogWriter(const std::string& path);
    ~EditLogWriter();
    EditLogWriter(const EditLogWriter&) = delete;
    EditLogWriter& operator=(const EditLogWriter&) = delete;

    /// Writes `command` as one line with "t_ms" = milliseconds since this writer was opened
    /// (replacing any t_ms the command carries), then flushes it to disk (write + fsync).
    /// Throws std::runtime_error naming the file when the write fails.
    void append(const EditCommand& command);

    /// Milliseconds since the writer was opened.
    double elapsedMs() const;
    const std::string& path() const { return mPath; }
    /// Lines written by this writer.
    int linesWritten() const { return mLines; }

private:
    std::string mPath;
    int mFd = -1;
    int mLines = 0;
    std::chrono::steady_clock::time_point mStart;
};

/// One command of a log with the line it came from.
struct LoggedEdit {
    int line = 0;  ///< 1-based
    EditCommand command;
};

/// Reads every edit of the log at `path`. Blank lines are skipped. A malformed line throws
/// InputError `PATH: line N: ...` (nothing is returned). A final line without newline that is
/// not valid JSON (a crash mid-write) is reported as one warning, `PATH: line N: truncated
/// final line ...` (spdlog::warn, core/log.h), and skipped; the lines before it are returned.
/// "add" objects' mesh files resolve relative to `meshBaseDir` (the scene's directory); their
/// materials are checked when the edit is applied. Throws InputError when the file cannot be
/// read.
std::vector<LoggedEdit> readEditLog(const std::string& path, const std::string& meshBaseDir = "");

}  // namespace penumbra
