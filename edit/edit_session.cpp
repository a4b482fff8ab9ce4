// Index: construction and log · apply (validate, log, perform, history) ·
//        planning each op (validation first, mutation in `perform`) · versions and materials
//        · solver work · output (display, save, export, report)

#include "edit/edit_session.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <sstream>
#include <stdexcept>

#include "core/input_error.h"
#include "edit/io/export.h"
#include "edit/io/scene_io.h"

namespace penumbra {

namespace {

std::string quoteId(const std::string& id) { return "'" + id + "'"; }

MaterialCommand fullMaterial(const std::string& id, const Material& m) {
    MaterialCommand c;
    c.id = id;
    c.reflectance = m.reflectance;
    c.emission = m.emission;
    c.twoSided = m.twoSided;
    return c;
}

}  // namespace

// ---------------------------------------------------------------------------------------------
// Construction and log.

std::unique_ptr<EditSession> EditSession::open(const std::string& path,
                                               const SolverOptions& options,
                                               const ImportOptions& import) {
    auto session = std::make_unique<EditSession>(loadScene(path, import), options, path);
    session->mSceneDir = std::filesystem::path(path).parent_path().string();
    return session;
}

EditSession::EditSession(Scene scene, const SolverOptions& options, const std::string& sourceName)
    : mLit(std::make_unique<LitScene>(std::move(scene), options, sourceName)),
      mSourceName(sourceName) {
    // The discretization builds one version per document object, in document order.
    const Scene& doc = mLit->scene();
    for (std::size_t i = 0; i < doc.objects.size(); ++i)
        mVersionOf[doc.objects[i].id] = static_cast<int>(i);
}

EditSession::~EditSession() = default;

void EditSession::openLog(const std::string& path, bool resolveHistory) {
    mLog = std::make_unique<EditLogWriter>(path);
    mLogResolvesHistory = resolveHistory;
}

void EditSession::closeLog() { mLog.reset(); }

// ---------------------------------------------------------------------------------------------
// apply.

EditEvent EditSession::apply(const EditCommand& command, const EditSource& source) {
    checkEditValues(command, source);

    // Validate: plan the edit (undo and redo plan their recorded command) without changing
    // anything.
    History history = History::Record;
    Plan planned;
    if (std::holds_alternative<UndoCommand>(command.op) ||
        std::holds_alternative<RedoCommand>(command.op)) {
        const bool undo = std::holds_alternative<UndoCommand>(command.op);
        history = undo ? History::Undo : History::Redo;
        const auto& stack = undo ? mUndo : mRedo;
        if (stack.empty())
            throw InputError(source.file, source.where("op"),
                             undo ? "nothing to undo" : "nothing to redo");
        if (!mSelected.empty())
            throw InputError(source.file, source.where("op"),
                             "object " + quoteId(mSelected) + " is selected: unselect it before " +
                                 (undo ? "undo" : "redo"));
        const UndoRecord& record = stack.back();
        planned = undo ? plan(record.inverse, source, record.inversePosition)
                       : plan(record.forward, source, record.forwardPosition);
    } else {
        planned = plan(command, source, -1);
    }

    // Commit: the log line first (write-ahead: on disk before the solution changes), then the
    // document and structure, then the solver takes the event.
    if (mLog) {
        if (mLogResolvesHistory && history != History::Record) {
            const UndoRecord& record = history == History::Undo ? mUndo.back() : mRedo.back();
            mLog->append(history == History::Undo ? record.inverse : record.forward);
        } else {
            mLog->append(command);
        }
    }
    EditEvent event = planned.perform();
    if (event.kind == EditEvent::Kind::Changed && !mSelected.empty()) event.origin = mDragOrigin;
    solver().apply(event);
    event.preview = solver().previewObject();

    // History.
    switch (history) {
        case History::Record:
            if (planned.record) {
                mUndo.push_back(std::move(*planned.record));
                mRedo.clear();
            }
            break;
        case History::Undo:
            mRedo.push_back(std::move(mUndo.back()));
            mUndo.pop_back();
            break;
        case History::Redo:
            mUndo.push_back(std::move(mRedo.back()));
            mRedo.pop_back();
            break;
    }
    return event;
}

// ---------------------------------------------------------------------------------------------
// Planning each op.

EditSession::Plan EditSession::plan(const EditCommand& command, const EditSource& source,
                                    int position) {
    const Scene& doc = scene();
    if (auto* c = std::get_if<AddCommand>(&command.op)) return planAdd(*c, source, position);
    if (auto* c = std::get_if<RemoveCommand>(&command.op)) return planRemove(*c, source);
    if (auto* c = std::get_if<TransformCommand>(&command.op)) {
        const int index = requireObject(c->id, source);
        return planTransform(c->id, c->appliedTo(doc.objects[index].transform), source,
                             "transform");
    }
    if (auto* c = std::get_if<MoveCommand>(&command.op)) {
        const int index = requireObject(c->id, source);
        Transform t = doc.objects[index].transform;
        t.translate += c->by;
        return planTransform(c->id, t, source, "by");
    }
    if (auto* c = std::get_if<MaterialCommand>(&command.op)) return planMaterial(*c, source);
    if (auto* c = std::get_if<SelectCommand>(&command.op)) return planSelect(*c, source);
    if (std::holds_alternative<UnselectCommand>(command.op)) return planUnselect(source);
    if (auto* c = std::get_if<SolveCommand>(&command.op)) {
        const int shots = c->shots;
        return {[this, shots] {
                    EditEvent r;
                    r.shots = solve(shots);
                    return r;
                },
                std::nullopt};
    }
    if (auto* c = std::get_if<ConvergeCommand>(&command.op)) {
        const double eps = c->threshold;
        return {[this, eps] {
                    EditEvent r;
                    r.shots = converge(eps);
                    return r;
                },
                std::nullopt};
    }
    throw InputError(source.file, source.where("op"),
                     std::string("op '") + command.opName() + "' cannot be applied here");
}

EditSession::Plan EditSession::planAdd(const AddCommand& c, const EditSource& source,
                                       int position) {
    const Scene& doc = scene();
    const SceneObject& object = c.object;
    if (doc.findObject(object.id) >= 0)
        throw InputError(source.file, source.where("object.id"),
                         "duplicate object id " + quoteId(object.id));
    if (!object.material.empty() && !doc.findMaterial(object.material))
        throw InputError(source.file, source.where("object.material"),
                         "unknown material " + quoteId(object.material));
    checkDiscretizable(object, source, "object");
    const int at = position >= 0 && position <= static_cast<int>(doc.objects.size())
                       ? position
                       : static_cast<int>(doc.objects.size());

    Plan p;
    p.record = UndoRecord{AddCommand{object}, RemoveCommand{object.id}, at, -1};
    p.perform = [this, object, at] {
        Scene& d = mLit->scene();
        d.objects.insert(d.objects.begin() + at, object);
        const int v = addVersion(at, true);
        EditEvent r;
        r.kind = EditEvent::Kind::Changed;
        r.object = object.id;
        r.geometry = true;
        r.emitter = versionEmits(v);
        r.added = {v};
        return r;
    };
    return p;
}

EditSession::Plan EditSession::planRemove(const RemoveCommand& c, const EditSource& source) {
    const int index = requireObject(c.id, source);
    if (c.id == mSelected)
        throw InputError(
            source.file, source.where("id"),
            "object " + quoteId(c.id) + " is selected: unselect it before removing it");
    Plan p;
    p.record = UndoRecord{RemoveCommand{c.id}, AddCommand{scene().objects[index]}, -1, index};
    const std::string id = c.id;
    p.perform = [this, id, index] {
        Scene& d = mLit->scene();
        d.objects.erase(d.objects.begin() + index);
        const int v = mVersionOf.at(id);
        mVersionOf.erase(id);
        setVersionAlive(v, false);
        EditEvent r;
        r.kind = EditEvent::Kind::Changed;
        r.object = id;
        r.geometry = true;
        r.emitter = versionEmits(v);
        r.removed = {v};
        return r;
    };
    return p;
}

EditSession::Plan EditSession::planTransform(const std::string& id, const Transform& transform,
                                             const EditSource& source, const std::string& key) {
    const int index = requireObject(id, source);
    const SceneObject& current = scene().objects[index];
    if (!(std::isfinite(transform.translate.x) && std::isfinite(transform.translate.y) &&
          std::isfinite(transform.translate.z)))
        throw InputError(source.file, source.where(key), "the resulting translation is not finite");
    if (transform.scale != current.transform.scale) {
        SceneObject moved = current;
        moved.transform = transform;
        checkDiscretizable(moved, source, key);
    }
    const bool dragging = id == mSelected;

    Plan p;
    // A drag is recorded as one step when the object is unselected.
    if (!dragging)
        p.record = UndoRecord{fullTransformCommand(id, transform),
                              fullTransformCommand(id, current.transform), -1, -1};
    p.perform = [this, index, transform, dragging] {
        SceneObject& object = mLit->scene().objects[index];
        object.transform = transform;
        const int old = mVersionOf.at(object.id);
        EditEvent r;
        r.object = object.id;
        r.geometry = true;
        r.emitter = versionEmits(old);
        if (dragging) {
            // George et al.: the dragged object's corrections go to a temporary buffer that
            // the next position discards.
            r.kind = EditEvent::Kind::PreviewMoved;
            r.origin = mDragOrigin;
            r.preview = addVersion(index, false);
        } else {
            // A move is a removal plus an addition.
            const int v = addVersion(index, true);
            setVersionAlive(old, false);
            r.kind = EditEvent::Kind::Changed;
            r.removed = {old};
            r.added = {v};
        }
        return r;
    };
    return p;
}

EditSession::Plan EditSession::planMaterial(const MaterialCommand& c, const EditSource& source) {
    const int index = requireObject(c.id, source);
    const SceneObject& object = scene().objects[index];
    const Material* current =
        object.material.empty() ? nullptr : scene().findMaterial(object.material);
    if (!current)
        throw InputError(source.file, source.where("id"),
                         "object " + quoteId(c.id) +
                             " takes its materials from its mesh file; material edits need an "
                             "object with a scene material");
    const Material before = *current;
    const Material after = c.appliedTo(before);
    const bool selected = c.id == mSelected;

    Plan p;
    p.record = UndoRecord{fullMaterial(c.id, after), fullMaterial(c.id, before), -1, -1};
    p.perform = [this, index, before, after, selected] {
        setDocumentMaterial(index, after);
        const std::string& id = mLit->scene().objects[index].id;
        const int old = mVersionOf.at(id);
        EditEvent r;
        r.object = id;
        r.material = true;
        r.emitter = before.emission != after.emission;
        // Which side reflects is geometry: a two_sided change rebuilds the object.
        const bool rebuild = before.twoSided != after.twoSided;
        if (selected) {
            // Applies to the solution on unselect; meanwhile the preview shows it.
            int v = old;
            if (rebuild)
                v = addVersion(index, false);
            else
                mLit->discretization().setObjectMaterial(v, after);
            r.kind = EditEvent::Kind::PreviewMoved;
            r.origin = mDragOrigin;
            r.preview = v;
        } else if (rebuild) {
            const int v = addVersion(index, true);
            setVersionAlive(old, false);
            r.kind = EditEvent::Kind::Changed;
            r.geometry = true;
            r.removed = {old};
            r.added = {v};
        } else {
            // George et al.: a radiosity correction Δρ·H + ΔE from the object's patches (the
            // solver sets the material once it has read the old one).
            r.kind = EditEvent::Kind::Changed;
            r.materialChanged = {old};
            r.newMaterial = after;
        }
        return r;
    };
    return p;
}

EditSession::Plan EditSession::planSelect(const SelectCommand& c, const EditSource& source) {
    const int index = requireObject(c.id, source);
    if (!mSelected.empty())
        throw InputError(
            source.file, source.where("id"),
            "object " + quoteId(mSelected) + " is already selected: unselect it first");
    Plan p;
    const std::string id = c.id;
    p.perform = [this, id, index] {
        // George et al.: "when the user selects an object for change, the object is removed
        // from the radiosity solution"; the preview shows it where it is.
        const int v = mVersionOf.at(id);
        setVersionAlive(v, false);
        mSelected = id;
        mSelectedFrom = mLit->scene().objects[index].transform;
        mDragOrigin = v;
        EditEvent r;
        r.kind = EditEvent::Kind::DragBegan;
        r.object = id;
        r.emitter = versionEmits(v);
        r.origin = v;
        r.preview = v;
        r.removed = {v};
        return r;
    };
    return p;
}

EditSession::Plan EditSession::planUnselect(const EditSource& source) {
    if (mSelected.empty()) throw InputError(source.file, source.where("op"), "nothing is selected");
    const int index = requireObject(mSelected, source);
    const SceneObject& object = scene().objects[index];
    Plan p;
    if (object.transform != mSelectedFrom)
        p.record = UndoRecord{fullTransformCommand(object.id, object.transform),
                              fullTransformCommand(object.id, mSelectedFrom), -1, -1};
    p.perform = [this] {
        // "When the object is unselected, it is added back into the environment."
        const int v = mVersionOf.at(mSelected);
        setVersionAlive(v, true);
        EditEvent r;
        r.kind = EditEvent::Kind::DragEnded;
        r.object = mSelected;
        r.emitter = versionEmits(v);
        r.origin = mDragOrigin;
        r.added = {v};
        mSelected.clear();
        mDragOrigin = -1;
        return r;
    };
    return p;
}

// ---------------------------------------------------------------------------------------------
// Versions and materials.

int EditSession::requireObject(const std::string& id, const EditSource& source,
                               const std::string& key) const {
    const int index = scene().findObject(id);
    if (index < 0)
        throw InputError(source.file, source.where(key), "unknown object " + quoteId(id));
    return index;
}

void EditSession::checkDiscretizable(const SceneObject& object, const EditSource& source,
                                     const std::string& key) const {
    // Discretization::addObject may fail half-way; try the object alone first.
    Scene alone;
    alone.settings = scene().settings;
    alone.materials = scene().materials;
    alone.objects.push_back(object);
    try {
        Discretization trial(alone);
    } catch (const std::invalid_argument& e) {
        throw InputError(source.file, source.where(key), e.what());
    }
}

int EditSession::objectVersion(const std::string& id) const {
    auto it = mVersionOf.find(id);
    return it == mVersionOf.end() ? -1 : it->second;
}

int EditSession::addVersion(int index, bool alive) {
    const SceneObject& object = mLit->scene().objects[index];
    const int v = mLit->discretization().addObject(mLit->scene(), object);
    if (!alive) mLit->discretization().setAlive(v, false);
    mLit->tracer().addObject(v);
    mVersionOf[object.id] = v;
    return v;
}

void EditSession::setVersionAlive(int version, bool alive) {
    mLit->discretization().setAlive(version, alive);
    mLit->tracer().updateAlive(version);
}

bool EditSession::versionEmits(int version) const {
    const Discretization& disc = discretization();
    for (std::size_t p = 0; p < disc.patches().size(); ++p)
        if (disc.patches()[p].object == version &&
            disc.patchMaterial(static_cast<int>(p)).isEmitter())
            return true;
    return false;
}

void EditSession::setDocumentMaterial(int index, const Material& m) {
    Scene& doc = mLit->scene();
    SceneObject& object = doc.objects[index];
    auto owned = mOwnedMaterials.find(object.material);
    const bool ownsMaterial =
        owned != mOwnedMaterials.end() && owned->second == object.id &&
        std::count_if(doc.objects.begin(), doc.objects.end(),
                      [&](const SceneObject& o) { return o.material == object.material; }) == 1;
    if (ownsMaterial) {
        for (NamedMaterial& named : doc.materials)
            if (named.name == object.material) named.material = m;
        return;
    }
    // The scene's materials are shared; the edited object gets one of its own.
    std::string name = object.id;
    for (int k = 2; doc.findMaterial(name); ++k) name = object.id + "-" + std::to_string(k);
    doc.materials.push_back({name, m});
    mOwnedMaterials[name] = object.id;
    object.material = name;
}

// ---------------------------------------------------------------------------------------------
// Solver work.

std::uint64_t EditSession::solve(int shots) {
    std::uint64_t done = 0;
    if (!mSelected.empty()) done += static_cast<std::uint64_t>(solver().stepPreview(shots));
    done += static_cast<std::uint64_t>(solver().step(shots));
    return done;
}

std::uint64_t EditSession::converge(double eps, std::uint64_t maxShots) {
    std::uint64_t done = 0;
    if (!mSelected.empty()) {
        constexpr int kChunk = 64;
        while (done < maxShots) {
            const int n = solver().stepPreview(kChunk);
            done += static_cast<std::uint64_t>(n);
            if (n < kChunk) break;
        }
    }
    if (done < maxShots) done += solver().converge(eps, maxShots - done);
    return done;
}

// ---------------------------------------------------------------------------------------------
// Output.

std::vector<Rgb> EditSession::radiosityWithPreview() const {
    std::vector<Rgb> b = solver().radiosity();
    if (!mSelected.empty()) {
        const std::vector<Rgb>& preview = solver().previewRadiosity();
        for (std::size_t e = 0; e < b.size() && e < preview.size(); ++e) b[e] += preview[e];
    }
    return b;
}

void EditSession::saveScene(const std::string& path) {
    const std::string dir = std::filesystem::path(path).parent_path().string();
    // Mesh paths as they must be written at `path`; the document keeps the old ones until the
    // file is written, so a failed save changes nothing.
    Scene& doc = mLit->scene();
    std::vector<std::string> rebased(doc.objects.size());
    for (std::size_t i = 0; i < doc.objects.size(); ++i) {
        if (doc.objects[i].shape.type == ShapeType::Mesh)
            rebased[i] = rebaseMeshPath(doc.objects[i].shape.file, mSceneDir, dir);
    }
    auto swapPaths = [&] {
        for (std::size_t i = 0; i < doc.objects.size(); ++i)
            std::swap(doc.objects[i].shape.file, rebased[i]);
    };
    swapPaths();
    try {
        penumbra::saveScene(doc, path);
    } catch (...) {
        swapPaths();
        throw;
    }
    // The document now lives at `path`: the history's added objects name meshes from there too.
    for (std::vector<UndoRecord>* stack : {&mUndo, &mRedo}) {
        for (UndoRecord& record : *stack) {
            for (EditCommand* command : {&record.forward, &record.inverse}) {
                if (auto* add = std::get_if<AddCommand>(&command->op);
                    add && add->object.shape.type == ShapeType::Mesh)
                    add->object.shape.file = rebaseMeshPath(add->object.shape.file, mSceneDir, dir);
            }
        }
    }
    mSceneDir = dir;
}

void EditSession::exportLitScene(const std::string& path) const {
    // The session's discretization holds dead versions too; export a fresh discretization of
    // the document, whose objects are built exactly as their current versions were (same
    // shape, transform and settings give the same elements in the same order).
    const Discretization& disc = discretization();
    const Discretization compact(scene());
    std::vector<std::vector<int>> sessionElements(disc.objects().size());
    for (std::size_t e = 0; e < disc.elements().size(); ++e)
        sessionElements[disc.elements()[e].object].push_back(static_cast<int>(e));
    std::vector<std::vector<int>> compactElements(compact.objects().size());
    for (std::size_t e = 0; e < compact.elements().size(); ++e)
        compactElements[compact.elements()[e].object].push_back(static_cast<int>(e));

    const std::vector<Rgb> b = radiosityWithPreview();
    std::vector<Rgb> values(compact.elements().size(), Rgb(0.0));
    for (std::size_t i = 0; i < scene().objects.size(); ++i) {
        const std::vector<int>& from = sessionElements[objectVersion(scene().objects[i].id)];
        const std::vector<int>& to = compactElements[i];
        if (from.size() != to.size())
            throw std::runtime_error(path + ": cannot export object '" + scene().objects[i].id +
                                     "': its elements were subdivided");
        for (std::size_t k = 0; k < to.size(); ++k) values[to[k]] = b[from[k]];
    }
    penumbra::exportLitScene(compact, values, path, &scene());
}

nlohmann::json EditSession::reportJson() const {
    const Discretization& disc = discretization();
    std::size_t elements = 0, patches = 0;
    for (std::size_t e = 0; e < disc.elements().size(); ++e)
        elements += disc.elementAlive(static_cast<int>(e)) ? 1 : 0;
    for (std::size_t p = 0; p < disc.patches().size(); ++p)
        patches += disc.patchAlive(static_cast<int>(p)) ? 1 : 0;
    const SolverStats& s = solver().stats();
    return {{"shots", s.shots},
            {"rays", s.rays},
            {"seconds", s.seconds},
            {"unshot_fraction", solver().unshotFraction()},
            {"elements", elements},
            {"patches", patches},
            {"element_versions", disc.elements().size()},
            {"object_versions", disc.objects().size()},
            {"redistribution_shots", s.redistributionShots},
            {"pending_changes", solver().pendingChanges()},
            {"emitted_energy_w", solver().emittedEnergy()}};
}

std::string EditSession::toString() const {
    std::ostringstream s;
    s << "EditSession{" << mSourceName << ", " << scene().objects.size() << " objects, "
      << discretization().toString() << ", selected '" << mSelected << "', undo " << mUndo.size()
      << ", redo " << mRedo.size() << ", log " << (mLog ? mLog->path() : std::string("none"))
      << "}";
    return s.str();
}

}  // namespace penumbra
