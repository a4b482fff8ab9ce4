#pragma once
// The editor's recovery journal: every edit of a session also goes to an edit log in the
// user's state folder ($XDG_STATE_HOME/penumbra/recovery, else ~/.local/state/penumbra/recovery),
// one per scene file. Saving the scene starts it again, so it holds exactly the edits the
// scene file lacks. A session that ends with unsaved edits (a crash, kill -9, quitting without
// saving) leaves it behind, and the next session on that scene offers to replay it. The
// journal is an edit log like any other (append-only, each line synced before the edit
// applies), so a kill loses nothing acknowledged (tests/edit/crash_safety_test.cpp).

#include <string>
#include <vector>

#include "edit/edit_command.h"

namespace penumbra {

/// The journal of the scene saved at `scenePath`: the state folder's
/// NAME-HASH.jsonl, NAME the file's stem and HASH of its absolute path. Creates the folder.
std::string recoveryJournalPath(const std::string& scenePath);

/// What an earlier editor run left unsaved for the journal at `journal`: its edits (and those of
/// a JOURNAL.unsaved that an earlier start set aside and nobody recovered or discarded) in
/// order, solver work left out, and an unselect appended when they end with an object
/// selected. They are set aside in JOURNAL.unsaved (the journal itself is removed: the new
/// session starts it again), so they survive until recoverUnsaved's caller calls
/// discardUnsaved. A journal that cannot be read yields its readable lines and `error`.
struct UnsavedEdits {
    std::vector<EditCommand> edits;
    std::string file;   ///< JOURNAL.unsaved, "" when there was nothing
    std::string error;
};
UnsavedEdits takeUnsavedEdits(const std::string& journal, const std::string& sceneDir);

/// Removes what takeUnsavedEdits set aside.
void discardUnsaved(const UnsavedEdits& unsaved);

}  // namespace penumbra
