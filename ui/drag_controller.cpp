#include "ui/drag_controller.h"

#include <stdexcept>

namespace penumbra {

std::vector<EditCommand> DragController::begin(const std::string& id, const Transform& start) {
    if (mActive) throw std::logic_error("DragController::begin: '" + mId + "' is being dragged");
    mActive = true;
    mId = id;
    mStart = mCurrent = start;
    mUpdates = 0;
    return {SelectCommand{id}};
}

std::optional<EditCommand> DragController::update(const Transform& transform) {
    if (!mActive || transform == mCurrent) return std::nullopt;
    mCurrent = transform;
    ++mUpdates;
    return EditCommand(fullTransformCommand(mId, transform));
}

std::vector<EditCommand> DragController::end() {
    if (!mActive) return {};
    mActive = false;
    return {UnselectCommand{}};
}

std::vector<EditCommand> DragController::cancel() {
    if (!mActive) return {};
    std::vector<EditCommand> out;
    if (mCurrent != mStart) out.push_back(fullTransformCommand(mId, mStart));
    out.push_back(UnselectCommand{});
    mActive = false;
    mCurrent = mStart;
    return out;
}

}  // namespace penumbra
