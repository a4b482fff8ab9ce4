#pragma once
// An editing session: the document (Scene), its lit solution (discretization, tracer,
// progressive solver) and the edits that change both, with undo/redo, the selection and the
// edit log (George, Sillion, Greenberg 1990; DESIGN.md "Edit log").
//
// Object versions: the discretization never forgets an object. Adding an object appends a
// version; moving it appends a new version and marks the old one dead; the solver is told
// both (SceneChange) and redistributes. mVersionOf maps each document object id to its
// current version.

#include <cstdint>
#include <functional>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <unordered_map>
#include <vector>

#include "edit/edit_command.h"
#include "edit/edit_log.h"
#include "edit/lit_scene.h"
#include "solver/edit_event.h"

namespace penumbra {

class EditSession {
public:
    /// Loads the scene at `path` (InputError on bad input) and builds its solution (not yet
    /// solved: call apply(ConvergeCommand{...}) or solver().converge()). A glTF or OBJ scene is
    /// imported with `import`.
    static std::unique_ptr<EditSession> open(const std::string& path, const SolverOptions& options,
                                             const ImportOptions& import = {});
    /// `sourceName` names the scene in error messages.
    EditSession(Scene scene, const SolverOptions& options, const std::string& sourceName = "scene");
    ~EditSession();
    EditSession(const EditSession&) = delete;
    EditSession& operator=(const EditSession&) = delete;

    /// Appends every committed edit to the log at `path` from now on (see EditLogWriter).
    /// `resolveHistory`: undo and redo are logged as the edits they perform (a log that
    /// starts after the history it undoes, as the editor's recovery journal does after a save,
    /// then replays on its own).
    void openLog(const std::string& path, bool resolveHistory = false);
    void closeLog();
    const EditLogWriter* log() const { return mLog.get(); }

    /// Validates `command` against the current document, then applies it: updates the
    /// document, performs the structural change on the discretization and tracer, hands the
    /// resulting EditEvent to the solver (ProgressiveSolver::apply), records the inverse for
    /// undo and appends the command to the log. Returns the event, for the display and the
    /// editor to consume as the solver did (its `preview` is previewVersion() after it). Invalid
    /// edits (unknown id, duplicate add, bad value, select while another object is selected,
    /// unselect with nothing selected, undo with nothing to undo, ...) throw InputError naming
    /// `source`, and change neither the document, the solution nor the log. The log line is written
    /// and synced after validation and before anything changes (write-ahead): when it cannot be
    /// written, std::runtime_error is thrown and the edit is not applied.
    ///
    /// Selection follows George et al.: select takes the object out of the solution (it stays
    /// in the document); transform and move then build a dead version at the new place and
    /// show it through the solver's preview buffer; material edits update the dead version;
    /// unselect puts the object back where it is and records the whole drag as one undo step.
    /// Removing the selected object, and undo/redo while an object is selected, are refused.
    EditEvent apply(const EditCommand& command, const EditSource& source = {});

    /// Solver work without logging: up to `shots` shots, and as many preview shots while an
    /// object is selected. Returns the shots done.
    std::uint64_t solve(int shots);
    /// Shoots until converged(eps) (or `maxShots`), finishing the preview too while an object
    /// is selected. Returns the shots done.
    std::uint64_t converge(double eps, std::uint64_t maxShots = 100000000);

    /// The document.
    const Scene& scene() const { return mLit->scene(); }
    Discretization& discretization() { return mLit->discretization(); }
    const Discretization& discretization() const { return mLit->solver().discretization(); }
    RayTracer& tracer() { return mLit->tracer(); }
    const RayTracer& tracer() const { return mLit->tracer(); }
    ProgressiveSolver& solver() { return mLit->solver(); }
    const ProgressiveSolver& solver() const { return mLit->solver(); }

    /// Current version (Discretization object index) of a document object, or -1.
    int objectVersion(const std::string& id) const;
    /// Id of the selected object, "" when none.
    const std::string& selected() const { return mSelected; }
    /// The version the drag previews (the selected object where it is now), -1 when nothing
    /// is selected. The solver holds it (ProgressiveSolver::previewObject); every other copy
    /// is a snapshot of it published to another thread.
    int previewVersion() const { return solver().previewObject(); }
    std::size_t undoDepth() const { return mUndo.size(); }
    std::size_t redoDepth() const { return mRedo.size(); }

    /// Element radiosity for display (ProgressiveSolver::displayRadiosity: B, ambient term and
    /// the preview buffer).
    std::vector<Rgb> displayRadiosity() const { return solver().displayRadiosity(); }
    /// Element radiosity B plus the preview buffer (what export writes).
    std::vector<Rgb> radiosityWithPreview() const;

    /// Writes the document atomically (saveScene) to `path`, which becomes the document's
    /// location: relative mesh paths, in the document and in the undo and redo history, are
    /// rewritten relative to `path`'s folder (rebaseMeshPath), so Save as into another folder
    /// keeps every mesh. Throws InputError when the file cannot be written, changing nothing.
    void saveScene(const std::string& path);
    /// The folder relative mesh paths of the document are relative to: the scene file's
    /// folder for open(), "" (the working directory) for a session built from a Scene.
    const std::string& sceneDirectory() const { return mSceneDir; }
    /// Exports the lit document (every document object at its current version, dead versions
    /// left out) as exportLitScene does.
    void exportLitScene(const std::string& path) const;

    /// The `--report` fields (shots, rays, seconds, unshot_fraction, elements, patches), with
    /// elements and patches counted over objects in the solution.
    nlohmann::json reportJson() const;
    std::string toString() const;

private:
    struct UndoRecord {
        EditCommand forward;
        EditCommand inverse;
        int forwardPosition = -1;  ///< document index for an add (redo of an add), -1: append
        int inversePosition = -1;  ///< document index for an add (undo of a remove)
    };
    /// A validated edit, ready to perform.
    struct Plan {
        std::function<EditEvent()> perform;
        std::optional<UndoRecord> record;  ///< pushed on the undo stack once performed
    };
    enum class History { Record, Undo, Redo };

    Plan plan(const EditCommand& command, const EditSource& source, int position);
    Plan planAdd(const AddCommand& c, const EditSource& source, int position);
    Plan planRemove(const RemoveCommand& c, const EditSource& source);
    Plan planTransform(const std::string& id, const Transform& transform, const EditSource& source,
                       const std::string& key);
    Plan planMaterial(const MaterialCommand& c, const EditSource& source);
    Plan planSelect(const SelectCommand& c, const EditSource& source);
    Plan planUnselect(const EditSource& source);

    /// Index of the document object `id`, failing with "unknown object" naming `source`.
    int requireObject(const std::string& id, const EditSource& source,
                      const std::string& key = "id") const;
    /// Fails naming `source` and `key` when `object` cannot be discretized.
    void checkDiscretizable(const SceneObject& object, const EditSource& source,
                            const std::string& key) const;
    /// Appends a version of document object `index`, alive or dead, to the discretization and
    /// tracer; returns it.
    int addVersion(int index, bool alive);
    void setVersionAlive(int version, bool alive);
    bool versionEmits(int version) const;
    /// Gives document object `index` material `m`: in place when the object already owns its
    /// material (one made by an earlier edit and used by nobody else), else a new material
    /// named after the object.
    void setDocumentMaterial(int index, const Material& m);

    std::unique_ptr<LitScene> mLit;
    std::string mSourceName;
    std::string mSceneDir;  ///< see sceneDirectory()
    std::unordered_map<std::string, int> mVersionOf;
    /// Materials made by material edits: name -> owning object id.
    std::unordered_map<std::string, std::string> mOwnedMaterials;
    std::vector<UndoRecord> mUndo, mRedo;
    std::string mSelected;
    Transform mSelectedFrom;  ///< the selected object's transform when it was selected
    int mDragOrigin = -1;     ///< the selected object's version when it was selected
    std::unique_ptr<EditLogWriter> mLog;
    bool mLogResolvesHistory = false;  ///< see openLog
};

}  // namespace penumbra
