#include "ui/recovery.h"

#include <cstdlib>
#include <filesystem>
#include <functional>
#include <sstream>

#include "core/durable_file.h"
#include "edit/edit_log.h"

namespace penumbra {

namespace fs = std::filesystem;

namespace {

fs::path stateFolder() {
    if (const char* state = std::getenv("XDG_STATE_HOME"); state && *state)
        return fs::path(state) / "penumbra" / "recovery";
    if (const char* home = std::getenv("HOME"); home && *home)
        return fs::path(home) / ".local" / "state" / "penumbra" / "recovery";
    return fs::temp_directory_path() / "penumbra-recovery";
}

/// The edits of the log at `path` (none when it does not exist), into `out`. A log that
/// cannot be read is moved to PATH.unreadable for the user to look at (the error names it),
/// never deleted.
void readInto(const fs::path& path, const std::string& sceneDir, UnsavedEdits& out) {
    if (!fs::exists(path)) return;
    try {
        for (const LoggedEdit& e : readEditLog(path.string(), sceneDir)) {
            if (e.command.isSolverWork()) continue;
            EditCommand c = e.command;
            c.tMs.reset();
            out.edits.push_back(std::move(c));
        }
    } catch (const std::exception& e) {
        const fs::path kept = path.string() + ".unreadable";
        std::error_code ignored;
        fs::rename(path, kept, ignored);
        out.error = std::string(e.what()) + " (kept as " + kept.string() + ")";
    }
}

}  // namespace

std::string recoveryJournalPath(const std::string& scenePath) {
    const fs::path folder = stateFolder();
    std::error_code ignored;
    fs::create_directories(folder, ignored);
    const std::string absolute = fs::weakly_canonical(fs::absolute(scenePath)).string();
    std::ostringstream name;
    name << fs::path(scenePath).stem().string() << "-" << std::hex
         << std::hash<std::string>{}(absolute) << ".jsonl";
    return (folder / name.str()).string();
}

UnsavedEdits takeUnsavedEdits(const std::string& journal, const std::string& sceneDir) {
    UnsavedEdits out;
    const fs::path aside = journal + ".unsaved";
    readInto(aside, sceneDir, out);
    readInto(journal, sceneDir, out);
    std::error_code ignored;
    if (out.edits.empty()) {
        fs::remove(aside, ignored);
        fs::remove(journal, ignored);
        return out;
    }
    // George et al.'s drag ends with an unselect; a session killed mid-drag did not write it.
    int selected = 0;
    for (const EditCommand& c : out.edits) {
        if (std::holds_alternative<SelectCommand>(c.op)) selected = 1;
        if (std::holds_alternative<UnselectCommand>(c.op)) selected = 0;
    }
    if (selected) out.edits.push_back(UnselectCommand{});
    // Set aside as one log (written whole, durably: core/durable_file.h), then the journal goes.
    std::string text;
    for (const EditCommand& c : out.edits) text += formatEditCommand(c) + "\n";
    writeFileAtomically(aside.string(), text);
    fs::remove(journal, ignored);
    out.file = aside.string();
    return out;
}

void discardUnsaved(const UnsavedEdits& unsaved) {
    std::error_code ignored;
    if (!unsaved.file.empty()) fs::remove(unsaved.file, ignored);
}

}  // namespace penumbra
