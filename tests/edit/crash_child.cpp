// The crash-safety test's child: plays the crash session (crash_edits.h) over makeLitRoom with
// an edit log, as the editor does, until it is killed. After each edit it writes
// "edit N\n" to stdout, and after each save "save K\n" (K: the rounds the saved scene holds),
// each with one write(2): what it acknowledged is then on disk (the log line is written and
// synced before apply returns; the scene is renamed into place before saveScene returns).
//
// crash_child DIR [EDITS]: the log is DIR/edits.jsonl, the scene DIR/scene.json; EDITS
// (default: no limit) stops it after that many edits.

#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <exception>
#include <string>

#include "crash_edits.h"
#include "edit/edit_session.h"

namespace {

void acknowledge(const std::string& line) {
    const std::string text = line + "\n";
    if (::write(STDOUT_FILENO, text.data(), text.size()) != static_cast<ssize_t>(text.size()))
        std::_Exit(3);
}

}  // namespace

int main(int argc, char** argv) {
    using namespace penumbra;
    if (argc < 2) {
        std::fprintf(stderr, "usage: crash_child DIR [EDITS]\n");
        return 2;
    }
    const std::string dir = argv[1];
    const long limit = argc > 2 ? std::atol(argv[2]) : -1;
    try {
        EditSession session(test::makeLitRoom("red"), SolverOptions{});
        session.converge(1e-2);
        session.openLog(dir + "/edits.jsonl");
        for (long i = 1; limit < 0 || i <= limit; ++i) {
            session.apply(test::crashEdit(static_cast<int>(i)));
            acknowledge("edit " + std::to_string(i));
            if ((i - 1) % test::kCrashRound == 0) {
                session.saveScene(dir + "/scene.json");
                acknowledge("save " + std::to_string((i - 1) / test::kCrashRound + 1));
            }
        }
    } catch (const std::exception& e) {
        std::fprintf(stderr, "crash_child: %s\n", e.what());
        return 2;
    }
    return 0;
}
