#pragma once
// What one applied edit did, in the user's terms: the one type EditSession::apply returns and
// the solver (ProgressiveSolver::apply), the display (InteractiveDisplay::apply) and the
// editor's runner consume. A drag is George, Sillion and Greenberg's (1990) selection
// protocol: select takes the object out of the solution and previews it where it was
// (DragBegan); each new position or material of the selected object replaces the preview
// (PreviewMoved); unselect puts the last preview back into the solution (DragEnded).
// Everything else that changes the lit scene is Changed.
//
// Versions are Discretization object indices: the discretization never forgets an object, an
// edit appends versions and marks old ones dead (EditSession).

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "solver/scene.h"

namespace penumbra {

struct EditEvent {
    enum class Kind : std::uint8_t {
        Solved,        ///< solver work only (solve, converge): the scene did not change
        Changed,       ///< versions entered, left or changed material in the solution
        DragBegan,     ///< select: `origin` left the solution and is previewed where it was
        PreviewMoved,  ///< the selected object moved or changed: `preview` is shown instead
        DragEnded,     ///< unselect: `added` = {the last preview}, back in the solution
    };
    Kind kind = Kind::Solved;
    std::string object;  ///< the document object edited ("" for Solved)
    /// The drag this event belongs to: the version selected (the drag's origin), -1 outside
    /// a drag. Set for DragBegan, PreviewMoved and DragEnded, and for Changed while a drag
    /// goes on (another object edited meanwhile).
    int origin = -1;
    /// The version previewed after the event (George et al.'s temporary buffer; dead, in the
    /// tracer), -1 for none. DragBegan: the origin itself (a later position once coalesced,
    /// see coalescePreviews). Changed during a drag: the same
    /// version, its preview started again because the scene around it changed.
    int preview = -1;
    std::vector<int> added;            ///< versions that entered the solution
    std::vector<int> removed;          ///< versions that left the solution
    std::vector<int> materialChanged;  ///< versions in the solution whose material changed
    /// The new material of `materialChanged` (George et al.'s ΔB = Δρ·H + ΔE correction needs
    /// it and the old one, which the discretization still holds when the solver applies it).
    std::optional<Material> newMaterial;
    bool geometry = false;    ///< document geometry changed (an object added, removed or moved)
    bool material = false;    ///< a material changed
    bool emitter = false;     ///< emission entered, left, moved or changed
    std::uint64_t shots = 0;  ///< solver shots the edit did (solve, converge), preview included

    /// The lit scene a from-scratch solve would see changed.
    bool solutionChanged() const {
        return !added.empty() || !removed.empty() || !materialChanged.empty();
    }
    /// added ∪ removed ∪ materialChanged, sorted, without duplicates.
    std::vector<int> changed() const;
    /// The preview changed: a new version is shown, or the shown one must be recomputed.
    bool previewChanged() const {
        return kind == Kind::DragBegan || kind == Kind::PreviewMoved || kind == Kind::DragEnded ||
               (kind == Kind::Changed && preview >= 0);
    }
    static const char* kindName(Kind kind);
    std::string toString() const;
};

/// For a consumer that takes a batch of events at once (the editor's displays): folds each
/// PreviewMoved into the DragBegan or PreviewMoved of the same drag just before it, which then
/// previews its version (a batch of drag positions shows only its last; a DragBegan's preview
/// may so be a later position than its origin). Every other event stays, in order. The
/// solver takes every event as it comes (EditSession::apply), never a coalesced one.
void coalescePreviews(std::vector<EditEvent>& events);

}  // namespace penumbra
