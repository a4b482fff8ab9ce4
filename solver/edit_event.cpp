#include "solver/edit_event.h"

#include <algorithm>
#include <sstream>

namespace penumbra {

namespace {

std::string listVersions(const std::vector<int>& v) {
    std::string s = "[";
    for (std::size_t i = 0; i < v.size(); ++i) s += (i ? ", " : "") + std::to_string(v[i]);
    return s + "]";
}

}  // namespace

std::vector<int> EditEvent::changed() const {
    std::vector<int> all = added;
    all.insert(all.end(), removed.begin(), removed.end());
    all.insert(all.end(), materialChanged.begin(), materialChanged.end());
    std::sort(all.begin(), all.end());
    all.erase(std::unique(all.begin(), all.end()), all.end());
    return all;
}

const char* EditEvent::kindName(Kind kind) {
    switch (kind) {
        case Kind::Solved:
            return "solved";
        case Kind::Changed:
            return "changed";
        case Kind::DragBegan:
            return "drag began";
        case Kind::PreviewMoved:
            return "preview moved";
        case Kind::DragEnded:
            return "drag ended";
    }
    return "?";
}

std::string EditEvent::toString() const {
    std::ostringstream s;
    s << "EditEvent{" << kindName(kind);
    if (!object.empty()) s << " '" << object << "'";
    s << ", origin " << origin << ", preview " << preview << ", added " << listVersions(added)
      << ", removed " << listVersions(removed) << ", materialChanged "
      << listVersions(materialChanged) << ", geometry " << geometry << ", material " << material
      << ", emitter " << emitter << ", shots " << shots << "}";
    return s.str();
}

void coalescePreviews(std::vector<EditEvent>& events) {
    std::vector<EditEvent> kept;
    kept.reserve(events.size());
    for (EditEvent& e : events) {
        if (e.kind == EditEvent::Kind::PreviewMoved && !kept.empty()) {
            EditEvent& last = kept.back();
            const bool sameDrag = (last.kind == EditEvent::Kind::PreviewMoved ||
                                   last.kind == EditEvent::Kind::DragBegan) &&
                                  last.origin == e.origin;
            if (sameDrag) {
                last.preview = e.preview;
                last.geometry = last.geometry || e.geometry;
                last.material = last.material || e.material;
                last.emitter = last.emitter || e.emitter;
                continue;
            }
        }
        kept.push_back(std::move(e));
    }
    events = std::move(kept);
}

}  // namespace penumbra
