#pragma once
// Command creation for a gizmo drag (George, Sillion, Greenberg 1990, "select → temporary
// buffer → unselect"): the drag selects the object (it leaves the solution), sends each new
// position as an absolute transform edit (the session shows it through the solver's preview
// buffer), and unselects it at the end (it rejoins the solution where it now is; the session
// records the whole drag as one undo step). Pure logic: it returns the commands and never
// touches a session, so the UI can queue them for the worker thread and tests can check them.

#include <optional>
#include <string>
#include <vector>

#include "edit/edit_command.h"

namespace penumbra {

class DragController {
public:
    /// Starts dragging `id`, whose document transform is `start`: returns {select id}.
    /// Throws std::logic_error when a drag is already active.
    std::vector<EditCommand> begin(const std::string& id, const Transform& start);
    /// The object's transform for the cursor now: a transform edit with all three keys when
    /// it differs from the last one sent (or from `start`), else nothing. Nothing when no
    /// drag is active.
    std::optional<EditCommand> update(const Transform& transform);
    /// Ends the drag where it is: {unselect}.
    std::vector<EditCommand> end();
    /// Ends the drag where it began: {transform back to start (only when it moved), unselect}.
    std::vector<EditCommand> cancel();

    bool active() const { return mActive; }
    const std::string& id() const { return mId; }
    const Transform& start() const { return mStart; }
    /// The last transform sent (start before the first update).
    const Transform& current() const { return mCurrent; }
    /// Transform edits sent in this drag.
    int updates() const { return mUpdates; }

private:
    bool mActive = false;
    std::string mId;
    Transform mStart, mCurrent;
    int mUpdates = 0;
};

}  // namespace penumbra
