#pragma once
// Edit events built by hand for display tests that drive InteractiveDisplay::apply without an
// EditSession's event at hand (a display that joins a drag late, or a step checked alone).
// Plain data as EditSession::apply returns it (solver/edit_event.h); the display reads only
// the fields set here.

#include <utility>
#include <vector>

#include "solver/edit_event.h"

namespace penumbra::test {

/// Versions entered (`added`), left (`removed`) or changed material in the solution; no drag.
inline EditEvent changedEvent(std::vector<int> added, std::vector<int> removed = {},
                              std::vector<int> materialChanged = {}) {
    EditEvent e;
    e.kind = EditEvent::Kind::Changed;
    e.added = std::move(added);
    e.removed = std::move(removed);
    e.materialChanged = std::move(materialChanged);
    return e;
}

/// The select of `origin`, showing `preview` (the origin itself, or a later position once
/// coalesced).
inline EditEvent dragBeganEvent(int origin, int preview) {
    EditEvent e;
    e.kind = EditEvent::Kind::DragBegan;
    e.origin = origin;
    e.preview = preview;
    return e;
}

/// The drag of `origin` shows `preview` now.
inline EditEvent previewMovedEvent(int origin, int preview) {
    EditEvent e;
    e.kind = EditEvent::Kind::PreviewMoved;
    e.origin = origin;
    e.preview = preview;
    return e;
}

/// The drag of `origin` ends with `added` back in the solution (its last preview), or with
/// nothing added (`added` empty: the preview just ends).
inline EditEvent dragEndedEvent(int origin, std::vector<int> added) {
    EditEvent e;
    e.kind = EditEvent::Kind::DragEnded;
    e.origin = origin;
    e.added = std::move(added);
    return e;
}

}  // namespace penumbra::test
