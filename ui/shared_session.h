#pragma once
// The editing session as the editor's services share it, and how they hear of its edits.
//
// EditSession is not thread-safe (plain members, no locks). The solver worker alone changes
// it, holding `structure` exclusively while it applies edits; shots change only the solver's
// own arrays and take no lock (the other threads see the lighting as published copies,
// RunnerBoard). Every other service (display producer, holodeck, interpolant builds) reads
// the discretization, the tracer and the document holding `structure` shared.
//
// The solver worker tells the other services what changed through EditListener, as the
// EditEvents EditSession::apply returned (the solver consumed the same events inside apply).

#include <atomic>
#include <memory>
#include <shared_mutex>
#include <stdexcept>

#include "edit/edit_session.h"
#include "solver/edit_event.h"

namespace penumbra {

struct SharedSession {
    explicit SharedSession(std::unique_ptr<EditSession> s) : session(std::move(s)) {
        if (!session) throw std::invalid_argument("SessionRunner: no session");
    }
    /// Read access for the services that hold `structure` shared.
    const EditSession& read() const { return *session; }

    std::unique_ptr<EditSession> session;
    /// Exclusive: the solver worker applying edits; shared: rendering, picking, builds.
    std::shared_mutex structure;
    /// Edit batches waiting for `structure`: a long reader (an interpolant build) stops at its
    /// next element so that an edit waits for an element, not a build.
    std::atomic<int> editsWaiting{0};
};

/// A service that hears of edits. Called on the solver worker's thread, in this order for
/// each batch: editsBegin (before the structure changes; `structure` held exclusively),
/// edited / saved for each applied edit and successful save in queue order, editsEnd (the
/// structure changed, still held exclusively); published after the new state is on the board
/// (no lock held), also after shots.
class EditListener {
public:
    virtual ~EditListener() = default;
    /// Stop reading the structure (asynchronous workers pause).
    virtual void editsBegin() {}
    /// One applied edit.
    virtual void edited(const EditEvent& event) { (void)event; }
    /// The document was written to the scene file the holodeck belongs to (File ▸ Save).
    virtual void savedHolodeckScene() {}
    /// The batch is applied: bring derived state up to date, resume workers.
    virtual void editsEnd() {}
    /// New lighting, document or solver figures are on the board.
    virtual void published() {}
};

}  // namespace penumbra
