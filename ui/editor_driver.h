#pragma once
// Driving the editor from outside its own code: an input script (ui/input_script.h) and the
// benchmarks built on one (ui/editor_benches.h). The editor calls its driver once per tick of
// its frame loop, drawn or not, and for every viewport image it shows; the driver acts only
// through EditorControls, the actions a user's input takes (select, drag the gizmo, release),
// so a scripted session runs the same paths as a person's. EditorApp holds no state of its
// drivers.
//
// Index: EditorControls · EditorDriver

#include <memory>
#include <string>

#include "solver/scene.h"
#include "ui/view_mode.h"

namespace penumbra {

class SessionRunner;
struct ViewportImage;
struct FrameStats;

/// What a driver may do to the editor (EditorApp implements it).
class EditorControls {
public:
    virtual ~EditorControls() = default;
    /// The open scene's runner (nullptr without a scene).
    virtual SessionRunner* runner() = 0;
    /// Selects the object `id` ("" none), as a click on it does.
    virtual void select(const std::string& id) = 0;
    /// Begins dragging the selected object's gizmo from its transform now; false when nothing
    /// is selected or the object is gone.
    virtual bool beginDrag() = 0;
    /// The dragged object's transform when the drag began.
    virtual Transform dragStart() const = 0;
    /// Moves the dragged object to `to` (one gizmo position).
    virtual void dragTo(const Transform& to) = 0;
    /// Releases the gizmo; returns the transform the object rests at.
    virtual Transform endDrag() = 0;
    /// The viewport image shown now (nullptr before the first).
    virtual std::shared_ptr<const ViewportImage> shownImage() const = 0;
    /// The frame-loop figures since the start or the last resetFrameStats().
    virtual const FrameStats& frameStats() const = 0;
    virtual void resetFrameStats() = 0;
    /// The viewport's size in window pixels, and the display's divisor of it.
    virtual int viewportWidth() const = 0;
    virtual int viewportHeight() const = 0;
    virtual int displayDivisor() const = 0;
    /// The viewport's display mode (View ▸ Mode).
    virtual ViewMode viewMode() const = 0;
    /// The scene file the editor opened ("" none).
    virtual const std::string& scenePath() const = 0;
    /// Ends the frame loop after this tick, with `status` as the editor's exit status.
    virtual void quit(int status) = 0;
};

/// Something that drives the editor. `now` is glfwGetTime()'s clock in every call.
class EditorDriver {
public:
    virtual ~EditorDriver() = default;
    /// Once per tick of the frame loop (drawn or not), before the frame's input is handled.
    virtual void tick(EditorControls& editor, double now) = 0;
    /// A new viewport image is shown from now on.
    virtual void shown(EditorControls& editor, const std::shared_ptr<const ViewportImage>& image,
                       double now) {
        (void)editor, (void)image, (void)now;
    }
    /// Whether every tick must draw a frame (input is arriving, as while a user drags).
    virtual bool wantsFrames() const { return false; }
    /// After the frame loop ended (a report, say).
    virtual void finished(EditorControls& editor) { (void)editor; }
};

}  // namespace penumbra
