#pragma once
// InputError: the one exception type for bad user input (scene files, mesh files, edit logs,
// holodeck files, command-line values). The command line catches it, prints `penumbra: ` + what()
// on one line and exits with status 2 (DESIGN.md, "Command line").

#include <stdexcept>
#include <string>

namespace penumbra {

/// A problem with user input, reported as exactly one line:
///   `FILE: KEY-OR-LINE: what is wrong`   e.g. `scenes/x.json: objects[2].material: unknown
///   material 'red'`, or `FILE: what is wrong` when no key or line applies.
/// Newlines in any part are replaced by spaces so what() never spans lines.
struct InputError : std::runtime_error {
    /// file: the offending file as the user named it; where: key path (`objects[3].id`) or
    /// `line N` / `line N, column M`, may be empty; problem: what is wrong, lower case.
    InputError(const std::string& file, const std::string& where, const std::string& problem)
        : std::runtime_error(composeMessage(file, where, problem)),
          mFile(file),
          mWhere(where),
          mProblem(problem) {}

    const std::string& file() const { return mFile; }
    const std::string& where() const { return mWhere; }
    const std::string& problem() const { return mProblem; }

    /// The one-line message what() returns, without constructing an exception.
    static std::string composeMessage(const std::string& file, const std::string& where,
                                      const std::string& problem) {
        std::string message = file.empty() ? std::string("(input)") : file;
        if (!where.empty()) message += ": " + where;
        message += ": " + problem;
        for (char& c : message) {
            if (c == '\n' || c == '\r') c = ' ';
        }
        // Trim trailing spaces left by a message that ended in a newline.
        while (!message.empty() && message.back() == ' ') message.pop_back();
        return message;
    }

private:
    std::string mFile;
    std::string mWhere;
    std::string mProblem;
};

}  // namespace penumbra
