// EditSession: every op, applied through the session, converges to a from-scratch solve of the
// final scene on the same discretization (DESIGN.md "Redistribution equals recomputation");
// undo returns to the pre-edit solution; bad edits change neither the document, the solution
// nor the log.
#include "edit/edit_session.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <memory>
#include <sstream>

#include "core/input_error.h"
#include "edit/edit_log.h"
#include "edit/io/mesh_io.h"
#include "edit/io/scene_io.h"
#include "test_scenes.h"

namespace penumbra {
namespace {

namespace fs = std::filesystem;

constexpr double kEps = 1e-5;

/// A room lit from the ceiling with a table-like slab and a red crate (as in
/// tests/solver/redistribution_test.cpp).
Scene makeRoom(bool withCrate = true) {
    Scene scene = test::makeLitRoom("red");
    if (withCrate)
        scene.objects.push_back([] {
            SceneObject box;
            box.id = "crate";
            box.shape.type = ShapeType::Box;
            box.shape.size = Vec3(0.4);
            box.material = "red";
            box.transform.translate = Vec3(0.1, -0.55, 0.0);
            box.transform.rotateDeg = Vec3(0, 25, 0);
            return box;
        }());
    return scene;
}

SceneObject makeBox(const std::string& id, Vec3 at, const std::string& material) {
    SceneObject box;
    box.id = id;
    box.shape.type = ShapeType::Box;
    box.shape.size = Vec3(0.4);
    box.material = material;
    box.transform.translate = at;
    return box;
}

std::unique_ptr<EditSession> openRoom(bool withCrate = true) {
    auto session = std::make_unique<EditSession>(makeRoom(withCrate), SolverOptions{}, "room");
    session->apply(ConvergeCommand{kEps});
    return session;
}

/// A from-scratch converged solve of the session's lit scene on its own discretization.
std::vector<Rgb> solveFromScratch(EditSession& session) {
    ProgressiveSolver reference(session.discretization(), session.tracer());
    reference.converge(kEps, 10000000);
    return reference.radiosity();
}

struct Comparison {
    double rms = 0;    ///< George eq. 7 over elements in the solution, relative
    double worst = 0;  ///< largest relative error on elements brighter than 1% of the max
    int worstElement = -1;
    double minB = 0;
    std::string toString() const {
        std::ostringstream s;
        s << "rms " << rms << ", worst " << worst << " at element " << worstElement << ", min B "
          << minB;
        return s.str();
    }
};

/// Compares per element: `current[currentIndex[k]]` with `reference[referenceIndex[k]]`.
Comparison compare(const Discretization& disc, const std::vector<Rgb>& current,
                   const std::vector<int>& currentIndex, const std::vector<Rgb>& reference,
                   const std::vector<int>& referenceIndex) {
    Comparison c;
    double maxY = 0, num = 0, den = 0;
    for (int r : referenceIndex) maxY = std::max(maxY, luminance(reference[r]));
    for (std::size_t k = 0; k < currentIndex.size(); ++k) {
        const int e = currentIndex[k];
        const double a = disc.elements()[e].area;
        const double y = luminance(current[e]), yRef = luminance(reference[referenceIndex[k]]);
        num += (y - yRef) * (y - yRef) * a;
        den += yRef * yRef * a;
        c.minB = std::min({c.minB, current[e].x, current[e].y, current[e].z});
        if (yRef > 0.01 * maxY) {
            const double rel = std::abs(y - yRef) / yRef;
            if (rel > c.worst) c.worst = rel, c.worstElement = e;
        }
    }
    c.rms = den > 0 ? std::sqrt(num / den) : 0;
    return c;
}

void expectTolerances(const Comparison& c, const std::string& what) {
    EXPECT_LE(c.rms, 0.01) << what << ": " << c.toString();
    EXPECT_LE(c.worst, 0.05) << what << ": " << c.toString();
    EXPECT_GE(c.minB, -1e-6) << what << ": negative radiosity after convergence, " << c.toString();
}

/// Converges the session and compares it with a from-scratch solve of its lit scene.
void expectMatchesFromScratch(EditSession& session, const std::string& what) {
    session.apply(ConvergeCommand{kEps});
    ASSERT_TRUE(session.solver().converged(kEps)) << what << ": did not converge";
    const std::vector<Rgb> reference = solveFromScratch(session);
    const std::vector<int> alive = session.discretization().aliveElements();
    expectTolerances(
        compare(session.discretization(), session.solver().radiosity(), alive, reference, alive),
        what + " vs from-scratch (" + session.toString() + ")");
}

/// The radiosity of every document object's current version, element by element: versions
/// built from the same object have the same elements in the same order, so snapshots taken
/// before and after an undo compare element for element.
struct Snapshot {
    std::vector<Rgb> radiosity;
    std::vector<int> elements;  ///< element indices, document object by object
};

Snapshot snapshot(const EditSession& session) {
    Snapshot s;
    s.radiosity = session.solver().radiosity();
    const Discretization& disc = session.discretization();
    for (const SceneObject& object : session.scene().objects) {
        const int v = session.objectVersion(object.id);
        for (std::size_t e = 0; e < disc.elements().size(); ++e)
            if (disc.elements()[e].object == v) s.elements.push_back(static_cast<int>(e));
    }
    return s;
}

TEST(EditSession, AddEqualsRecomputation) {
    auto session = openRoom(false);
    EditEvent r = session->apply(AddCommand{makeBox("crate", {0.1, -0.55, 0.0}, "red")});
    EXPECT_TRUE(r.geometry) << r.toString();
    EXPECT_FALSE(r.emitter) << r.toString();
    ASSERT_EQ(r.added.size(), 1u) << r.toString();
    EXPECT_EQ(session->objectVersion("crate"), r.added[0]);
    EXPECT_EQ(session->scene().findObject("crate"), 8);
    expectMatchesFromScratch(*session, "add");
}

TEST(EditSession, RemoveEqualsRecomputation) {
    auto session = openRoom();
    const int crate = session->objectVersion("crate");
    EditEvent r = session->apply(RemoveCommand{"crate"});
    EXPECT_EQ(r.removed, std::vector<int>{crate}) << r.toString();
    EXPECT_EQ(session->scene().findObject("crate"), -1);
    EXPECT_EQ(session->objectVersion("crate"), -1);
    EXPECT_FALSE(session->discretization().objects()[crate].alive);
    expectMatchesFromScratch(*session, "remove");
}

TEST(EditSession, MoveEqualsRecomputation) {
    auto session = openRoom();
    const int before = session->objectVersion("crate");
    EditEvent r = session->apply(MoveCommand{"crate", {-0.9, -0.75, 0.6}});
    EXPECT_EQ(r.removed, std::vector<int>{before}) << r.toString();
    ASSERT_EQ(r.added.size(), 1u);
    const Transform& t = session->scene().objects[session->scene().findObject("crate")].transform;
    EXPECT_EQ(t.translate, Vec3(0.1 - 0.9, -0.55 - 0.75, 0.6));
    EXPECT_EQ(t.rotateDeg, Vec3(0, 25, 0));
    expectMatchesFromScratch(*session, "move");
}

TEST(EditSession, TransformEqualsRecomputation) {
    auto session = openRoom();
    TransformCommand c;
    c.id = "crate";
    c.translate = Vec3(-0.7, -1.2, -0.5);
    c.scale = Vec3(1.5, 0.75, 1.0);
    session->apply(c);
    const Transform& t = session->scene().objects[session->scene().findObject("crate")].transform;
    EXPECT_EQ(t.translate, Vec3(-0.7, -1.2, -0.5));
    EXPECT_EQ(t.rotateDeg, Vec3(0, 25, 0)) << "absent keys keep their value";
    EXPECT_EQ(t.scale, Vec3(1.5, 0.75, 1.0));
    expectMatchesFromScratch(*session, "transform");
}

TEST(EditSession, ReflectanceEqualsRecomputation) {
    auto session = openRoom();
    MaterialCommand c;
    c.id = "crate";
    c.reflectance = Rgb(0.1, 0.8, 0.3);
    EditEvent r = session->apply(c);
    EXPECT_TRUE(r.material) << r.toString();
    EXPECT_FALSE(r.emitter) << r.toString();
    EXPECT_EQ(r.materialChanged, std::vector<int>{session->objectVersion("crate")});
    // The shared material "red" (also the slab's) is untouched; the crate got its own.
    const Scene& doc = session->scene();
    const SceneObject& crate = doc.objects[doc.findObject("crate")];
    EXPECT_EQ(doc.findMaterial("red")->reflectance, Rgb(0.7, 0.2, 0.15));
    EXPECT_EQ(doc.findMaterial(crate.material)->reflectance, Rgb(0.1, 0.8, 0.3));
    EXPECT_EQ(doc.objects[doc.findObject("slab")].material, "red");
    expectMatchesFromScratch(*session, "reflectance");
}

TEST(EditSession, EmitterAddMoveRemoveAndEmissionChange) {
    auto session = openRoom();
    EditEvent r = session->apply(AddCommand{makeBox("lamp2", {-0.9, 0.5, -0.9}, "lamp")});
    EXPECT_TRUE(r.emitter) << r.toString();
    session->apply(ConvergeCommand{1e-3});  // interrupted: pending work stays in the change log
    r = session->apply(MoveCommand{"lamp2", {1.8, -0.2, 0.2}});
    EXPECT_TRUE(r.emitter) << r.toString();
    expectMatchesFromScratch(*session, "emitter-move");
    r = session->apply(RemoveCommand{"lamp2"});
    EXPECT_TRUE(r.emitter) << r.toString();
    expectMatchesFromScratch(*session, "emitter-remove");
    MaterialCommand glow;
    glow.id = "crate";
    glow.emission = Rgb(2.0, 0.0, 0.0);
    r = session->apply(glow);
    EXPECT_TRUE(r.emitter) << r.toString();
    expectMatchesFromScratch(*session, "emission-change");
}

TEST(EditSession, TwoSidedChangeRebuildsTheObject) {
    auto session = openRoom();
    MaterialCommand c;
    c.id = "slab";
    c.twoSided = true;
    EditEvent r = session->apply(c);
    EXPECT_EQ(r.removed.size(), 1u) << r.toString();
    EXPECT_EQ(r.added.size(), 1u) << r.toString();
    EXPECT_TRUE(session->discretization().objects()[session->objectVersion("slab")].twoSided);
    expectMatchesFromScratch(*session, "two-sided");
}

TEST(EditSession, SelectDragUnselect) {
    auto session = openRoom();
    const int original = session->objectVersion("crate");
    EditEvent r = session->apply(SelectCommand{"crate"});
    EXPECT_EQ(r.kind, EditEvent::Kind::DragBegan) << r.toString();
    EXPECT_EQ(r.object, "crate");
    EXPECT_EQ(r.origin, original);
    EXPECT_EQ(r.preview, original) << "previewed where it was";
    EXPECT_EQ(session->previewVersion(), original);
    EXPECT_EQ(r.removed, std::vector<int>{original});
    EXPECT_EQ(session->selected(), "crate");
    EXPECT_FALSE(session->discretization().objects()[original].alive)
        << "a selected object leaves the solution";
    EXPECT_NE(session->scene().findObject("crate"), -1) << "but stays in the document";

    // Drag through three positions with a few shots at each; every position replaces the
    // preview buffer with a new dead version.
    int previous = original;
    for (Vec3 by : {Vec3(-0.3, 0, 0.2), Vec3(-0.3, 0, 0.2), Vec3(-0.3, -0.75, 0.2)}) {
        r = session->apply(MoveCommand{"crate", by});
        EXPECT_EQ(r.kind, EditEvent::Kind::PreviewMoved) << r.toString();
        EXPECT_EQ(r.origin, original);
        ASSERT_GE(r.preview, 0) << r.toString();
        EXPECT_NE(r.preview, previous);
        EXPECT_FALSE(session->discretization().objects()[r.preview].alive);
        EXPECT_EQ(session->solver().previewObject(), r.preview);
        EXPECT_TRUE(r.added.empty() && r.removed.empty()) << r.toString();
        previous = r.preview;
        EditEvent solved = session->apply(SolveCommand{5});
        EXPECT_GT(solved.shots, 0u);
    }
    const std::size_t undoBefore = session->undoDepth();
    r = session->apply(UnselectCommand{});
    EXPECT_EQ(r.kind, EditEvent::Kind::DragEnded) << r.toString();
    EXPECT_EQ(r.origin, original);
    EXPECT_EQ(r.preview, -1);
    EXPECT_EQ(r.added, std::vector<int>{previous}) << r.toString();
    EXPECT_TRUE(session->selected().empty());
    EXPECT_EQ(session->solver().previewObject(), -1);
    EXPECT_EQ(session->undoDepth(), undoBefore + 1) << "a drag is one undo step";
    expectMatchesFromScratch(*session, "select-drag-unselect");

    // Undo the whole drag at once.
    session->apply(UndoCommand{});
    const Transform& t = session->scene().objects[session->scene().findObject("crate")].transform;
    EXPECT_EQ(t.translate, Vec3(0.1, -0.55, 0.0));
    expectMatchesFromScratch(*session, "drag-undo");
}

TEST(EditSession, AnEditDuringADragIsAChangeThatRestartsThePreview) {
    // Another object removed while the crate is dragged: the solution changes, the drag goes
    // on, and its preview (computed in the scene as it was) starts again.
    auto session = openRoom();
    const int original = session->objectVersion("crate");
    session->apply(SelectCommand{"crate"});
    const int preview = session->apply(MoveCommand{"crate", {-0.3, 0, 0.2}}).preview;
    session->apply(SolveCommand{20});
    const int slab = session->objectVersion("slab");
    const EditEvent r = session->apply(RemoveCommand{"slab"});
    EXPECT_EQ(r.kind, EditEvent::Kind::Changed) << r.toString();
    EXPECT_EQ(r.removed, std::vector<int>{slab});
    EXPECT_EQ(r.origin, original) << "the drag goes on";
    EXPECT_EQ(r.preview, preview) << "the same version, previewed again";
    EXPECT_TRUE(r.previewChanged());
    EXPECT_FALSE(session->solver().previewComplete()) << "its buffer started again";
    const EditEvent solved = session->apply(SolveCommand{5});
    EXPECT_EQ(solved.kind, EditEvent::Kind::Solved);
    EXPECT_FALSE(solved.previewChanged());
    EXPECT_EQ(solved.preview, preview);
    session->apply(UnselectCommand{});
    expectMatchesFromScratch(*session, "remove-during-drag");
}

TEST(EditSession, ABatchOfDragPositionsCoalescesToItsLast) {
    // coalescePreviews against the events one by one: a select followed by positions becomes
    // one DragBegan previewing the last; positions in a row become their last; a change of
    // another object in between, and the drop, stay where they are.
    auto session = openRoom();
    std::vector<EditEvent> events;
    events.push_back(session->apply(SelectCommand{"crate"}));
    events.push_back(session->apply(MoveCommand{"crate", {-0.1, 0, 0}}));
    events.push_back(session->apply(MoveCommand{"crate", {-0.1, 0, 0}}));
    events.push_back(session->apply(AddCommand{makeBox("cube", {0.9, -0.55, 0.9}, "red")}));
    events.push_back(session->apply(MoveCommand{"crate", {-0.1, 0, 0}}));
    events.push_back(session->apply(MoveCommand{"crate", {-0.1, 0, 0}}));
    events.push_back(session->apply(UnselectCommand{}));
    const std::vector<EditEvent> all = events;
    coalescePreviews(events);
    using Kind = EditEvent::Kind;
    ASSERT_EQ(events.size(), 4u);
    EXPECT_EQ(events[0].kind, Kind::DragBegan);
    EXPECT_EQ(events[0].origin, all[0].origin);
    EXPECT_EQ(events[0].preview, all[2].preview) << "the select previews the batch's last place";
    EXPECT_EQ(events[1].kind, Kind::Changed);
    EXPECT_EQ(events[1].added, all[3].added);
    EXPECT_EQ(events[2].kind, Kind::PreviewMoved);
    EXPECT_EQ(events[2].preview, all[5].preview);
    EXPECT_EQ(events[3].kind, Kind::DragEnded);
    EXPECT_EQ(events[3].added, std::vector<int>{all[5].preview});
}

TEST(EditSession, ALogThatResolvesHistoryWritesWhatUndoAndRedoDid) {
    // The editor's recovery journal starts again at every save, after history it may undo:
    // its undo and redo lines are the edits they performed, and it replays on its own.
    const std::string path = (std::filesystem::temp_directory_path() /
                              ("penumbra_resolved_" + std::to_string(::getpid()) + ".jsonl"))
                                 .string();
    std::filesystem::remove(path);
    auto session = openRoom();
    session->apply(MoveCommand{"crate", {-0.4, 0.0, 0.2}});
    session->openLog(path, true);
    session->apply(UndoCommand{});
    session->apply(RedoCommand{});
    session->apply(UndoCommand{});
    session->closeLog();
    const std::vector<LoggedEdit> lines = readEditLog(path);
    ASSERT_EQ(lines.size(), 3u);
    for (const LoggedEdit& e : lines) EXPECT_STREQ(e.command.opName(), "transform");

    // Replayed from the saved state (the move done), without its history: the same document.
    auto replayed = openRoom();
    replayed->apply(MoveCommand{"crate", {-0.4, 0.0, 0.2}});
    auto fresh = std::make_unique<EditSession>(replayed->scene(), SolverOptions{});
    for (const LoggedEdit& e : lines) fresh->apply(e.command);
    const auto at = [](const EditSession& s) {
        return s.scene().objects[s.scene().findObject("crate")].transform.translate;
    };
    EXPECT_EQ(at(*fresh), at(*session));
    std::filesystem::remove(path);
}

TEST(EditSession, MaterialEditOnSelectedObjectAppliesOnUnselect) {
    auto session = openRoom();
    session->apply(SelectCommand{"crate"});
    MaterialCommand c;
    c.id = "crate";
    c.emission = Rgb(3.0, 1.0, 0.0);
    const double emittedBefore = session->solver().emittedEnergy();
    EditEvent r = session->apply(c);
    EXPECT_TRUE(r.material);
    EXPECT_EQ(r.kind, EditEvent::Kind::PreviewMoved) << r.toString();
    EXPECT_FALSE(r.solutionChanged()) << r.toString();
    EXPECT_EQ(session->solver().emittedEnergy(), emittedBefore) << "not in the solution yet";
    session->apply(MoveCommand{"crate", {0.0, 0.5, 0.0}});
    session->apply(UnselectCommand{});
    EXPECT_GT(session->solver().emittedEnergy(), emittedBefore);
    expectMatchesFromScratch(*session, "material-while-selected");
}

TEST(EditSession, UndoReturnsToThePreEditSolutionAndRedoReapplies) {
    auto session = openRoom();
    const Snapshot before = snapshot(*session);
    session->apply(MoveCommand{"crate", {-0.9, -0.75, 0.6}});
    session->apply(ConvergeCommand{kEps});
    const Snapshot moved = snapshot(*session);

    EditEvent r = session->apply(UndoCommand{});
    EXPECT_EQ(r.added.size(), 1u) << "undo redistributes like any other edit: " << r.toString();
    EXPECT_EQ(session->redoDepth(), 1u);
    session->apply(ConvergeCommand{kEps});
    Snapshot undone = snapshot(*session);
    ASSERT_EQ(undone.elements.size(), before.elements.size());
    expectTolerances(compare(session->discretization(), undone.radiosity, undone.elements,
                             before.radiosity, before.elements),
                     "undo vs pre-edit");
    expectMatchesFromScratch(*session, "undo");

    session->apply(RedoCommand{});
    EXPECT_EQ(session->redoDepth(), 0u);
    session->apply(ConvergeCommand{kEps});
    Snapshot redone = snapshot(*session);
    ASSERT_EQ(redone.elements.size(), moved.elements.size());
    expectTolerances(compare(session->discretization(), redone.radiosity, redone.elements,
                             moved.radiosity, moved.elements),
                     "redo vs post-edit");
    expectMatchesFromScratch(*session, "redo");
}

TEST(EditSession, UndoOfRemoveAndAddRestoresTheDocument) {
    auto session = openRoom();
    const std::string original = sceneToJson(session->scene()).dump();
    session->apply(RemoveCommand{"crate"});
    session->apply(AddCommand{makeBox("cube", {0.5, -1.3, 0.5}, "white")});
    MaterialCommand c;
    c.id = "slab";
    c.reflectance = Rgb(0.2);
    session->apply(c);
    session->apply(UndoCommand{});
    session->apply(UndoCommand{});
    session->apply(UndoCommand{});
    EXPECT_EQ(session->undoDepth(), 0u);
    EXPECT_EQ(session->redoDepth(), 3u);
    // Same objects in the same order; the slab keeps the material made for it by the edit,
    // with the original values.
    Scene doc = session->scene();
    const Scene& scene = doc;
    EXPECT_EQ(scene.findObject("crate"), 8) << "a removed object comes back where it was";
    EXPECT_EQ(scene.findMaterial(scene.objects[scene.findObject("slab")].material)->reflectance,
              Rgb(0.7, 0.2, 0.15));
    doc.objects[doc.findObject("slab")].material = "red";
    doc.materials.erase(doc.materials.begin() + 3, doc.materials.end());
    EXPECT_EQ(sceneToJson(doc).dump(), original);
    expectMatchesFromScratch(*session, "undo-three");
}

// ---------------------------------------------------------------------------------------------
// Bad edits change nothing.

std::string readFile(const fs::path& path) {
    std::ifstream in(path, std::ios::binary);
    std::stringstream s;
    s << in.rdbuf();
    return s.str();
}

struct State {
    std::string document;
    std::vector<Rgb> radiosity;
    std::vector<Rgb> unshot;
    std::size_t objectVersions = 0;
    std::size_t pendingChanges = 0;
    std::size_t undo = 0, redo = 0;
    std::string selected;
    std::string log;
};

State captureState(EditSession& session, const fs::path& log) {
    State s;
    s.document = sceneToJson(session.scene()).dump();
    s.radiosity = session.solver().radiosity();
    for (std::size_t p = 0; p < session.discretization().patches().size(); ++p)
        s.unshot.push_back(session.solver().unshotRadiosity(static_cast<int>(p)));
    s.objectVersions = session.discretization().objects().size();
    s.pendingChanges = session.solver().pendingChanges();
    s.undo = session.undoDepth();
    s.redo = session.redoDepth();
    s.selected = session.selected();
    s.log = readFile(log);
    return s;
}

void expectUnchanged(const State& a, const State& b, const std::string& what) {
    EXPECT_EQ(a.document, b.document) << what << ": document changed";
    ASSERT_EQ(a.radiosity.size(), b.radiosity.size()) << what;
    EXPECT_EQ(std::memcmp(a.radiosity.data(), b.radiosity.data(), a.radiosity.size() * sizeof(Rgb)),
              0)
        << what << ": radiosity changed";
    ASSERT_EQ(a.unshot.size(), b.unshot.size()) << what;
    EXPECT_EQ(std::memcmp(a.unshot.data(), b.unshot.data(), a.unshot.size() * sizeof(Rgb)), 0)
        << what << ": unshot radiosity changed";
    EXPECT_EQ(a.objectVersions, b.objectVersions) << what << ": discretization changed";
    EXPECT_EQ(a.pendingChanges, b.pendingChanges) << what << ": change log changed";
    EXPECT_EQ(a.undo, b.undo) << what;
    EXPECT_EQ(a.redo, b.redo) << what;
    EXPECT_EQ(a.selected, b.selected) << what;
    EXPECT_EQ(a.log, b.log) << what << ": edit log changed";
}

TEST(EditSession, BadEditsChangeNeitherSceneSolutionNorLog) {
    const fs::path dir =
        fs::temp_directory_path() / ("penumbra_session_" + std::to_string(::getpid()));
    fs::create_directories(dir);
    const fs::path log = dir / "edits.jsonl";
    fs::remove(log);
    auto session = std::make_unique<EditSession>(makeRoom(), SolverOptions{}, "room");
    session->openLog(log.string());
    session->apply(SolveCommand{30});  // part-way: unshot energy and pending work present
    session->apply(MoveCommand{"crate", {0.2, 0, 0}});
    session->apply(SolveCommand{3});

    TransformCommand zeroScale;
    zeroScale.id = "crate";
    zeroScale.scale = Vec3(1, 0, 1);
    MaterialCommand tooBright;
    tooBright.id = "crate";
    tooBright.reflectance = Rgb(1.5, 0.2, 0.2);
    MaterialCommand negative;
    negative.id = "slab";
    negative.emission = Rgb(-1.0, 0.0, 0.0);
    SceneObject flat = makeBox("flat", {0, 0, 0}, "white");
    flat.shape.size = Vec3(0.4, 0.0, 0.4);
    const struct {
        const char* name;
        EditCommand command;
        const char* key;
    } bad[] = {
        {"remove unknown id", RemoveCommand{"ghost"}, "id"},
        {"move unknown id", MoveCommand{"ghost", {0.1, 0, 0}}, "id"},
        {"select unknown id", SelectCommand{"ghost"}, "id"},
        {"material unknown id", MaterialCommand{"ghost", Rgb(0.5), {}, {}}, "id"},
        {"duplicate add", AddCommand{makeBox("crate", {0, 0, 0}, "white")}, "object.id"},
        {"add unknown material", AddCommand{makeBox("cube", {0, 0, 0}, "gold")}, "object.material"},
        {"add degenerate box", AddCommand{flat}, "object.shape.size"},
        {"move by NaN", MoveCommand{"crate", {std::nan(""), 0, 0}}, "by"},
        {"zero scale", zeroScale, "transform.scale"},
        {"reflectance out of range", tooBright, "material.reflectance"},
        {"negative emission", negative, "material.emission"},
        {"negative shots", SolveCommand{-1}, "shots"},
        {"threshold out of range", ConvergeCommand{2.0}, "threshold"},
        {"unselect with nothing selected", UnselectCommand{}, "op"},
        {"redo with nothing to redo", RedoCommand{}, "op"},
    };
    for (const auto& b : bad) {
        const State before = captureState(*session, log);
        try {
            session->apply(b.command, EditSource{"edits.jsonl", 7});
            ADD_FAILURE() << b.name << ": accepted " << b.command.toString();
        } catch (const InputError& e) {
            EXPECT_EQ(e.file(), "edits.jsonl") << b.name;
            EXPECT_EQ(e.where(), std::string("line 7: ") + b.key) << b.name << ": " << e.what();
        }
        expectUnchanged(before, captureState(*session, log), b.name);
    }

    // Select while another object is selected; remove the selected object; undo while selected;
    // and undo with an empty history.
    session->apply(SelectCommand{"crate"});
    for (const EditCommand& command :
         {EditCommand(SelectCommand{"slab"}), EditCommand(RemoveCommand{"crate"}),
          EditCommand(UndoCommand{})}) {
        const State before = captureState(*session, log);
        EXPECT_THROW(session->apply(command), InputError) << command.toString();
        expectUnchanged(before, captureState(*session, log), command.toString());
    }
    session->apply(UnselectCommand{});
    session->apply(UndoCommand{});
    const State before = captureState(*session, log);
    EXPECT_THROW(session->apply(UndoCommand{}), InputError);
    expectUnchanged(before, captureState(*session, log), "undo with nothing to undo");
    session.reset();
    fs::remove_all(dir);
}

TEST(EditSession, SaveAsIntoAnotherFolderKeepsEveryMesh) {
    const fs::path root =
        fs::temp_directory_path() / ("penumbra_save_as_" + std::to_string(::getpid()));
    fs::remove_all(root);
    fs::create_directories(root / "project" / "meshes");
    fs::create_directories(root / "elsewhere" / "deeper");
    {
        std::ofstream off(root / "project" / "meshes" / "tet.off");
        off << "OFF\n4 4 0\n0 0 0\n0.3 0 0\n0 0.3 0\n0 0 0.3\n"
               "3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3\n";
    }
    auto meshObject = [&](const std::string& id, const Vec3& at) {
        SceneObject o;
        o.id = id;
        o.shape.type = ShapeType::Mesh;
        o.shape.file = "meshes/tet.off";
        o.shape.mesh = loadMeshFile((root / "project" / "meshes" / "tet.off").string());
        o.material = "white";
        o.transform.translate = at;
        return o;
    };
    Scene scene = makeRoom(false);
    scene.objects.push_back(meshObject("tet", Vec3(-0.4, -0.9, 0.2)));
    const std::string original = (root / "project" / "scene.json").string();
    saveScene(scene, original);

    auto session = EditSession::open(original, SolverOptions{});
    EXPECT_EQ(session->sceneDirectory(), (root / "project").string());
    session->apply(AddCommand{meshObject("tet2", Vec3(0.4, -0.9, -0.2))});
    session->apply(UndoCommand{});  // the add waits on the redo stack

    // A save that cannot be written changes nothing.
    EXPECT_THROW(session->saveScene((root / "missing" / "scene.json").string()), InputError);
    EXPECT_EQ(session->sceneDirectory(), (root / "project").string());
    EXPECT_EQ(session->scene().objects.back().shape.file, "meshes/tet.off");

    const std::string moved = (root / "elsewhere" / "deeper" / "scene.json").string();
    session->saveScene(moved);
    EXPECT_EQ(session->sceneDirectory(), (root / "elsewhere" / "deeper").string());
    Scene reloaded = loadScene(moved);  // throws if a mesh path no longer resolves
    ASSERT_EQ(reloaded.objects.back().id, "tet");
    EXPECT_EQ(reloaded.objects.back().shape.file, "../../project/meshes/tet.off");
    EXPECT_EQ(reloaded.objects.back().shape.mesh.positions.size(), 4u);

    // The history's add names the mesh from the new folder too.
    session->apply(RedoCommand{});
    session->saveScene(moved);
    reloaded = loadScene(moved);
    ASSERT_EQ(reloaded.objects.back().id, "tet2");
    EXPECT_EQ(reloaded.objects.back().shape.file, "../../project/meshes/tet.off");

    // And back home: the paths are as first written.
    session->saveScene(original);
    reloaded = loadScene(original);
    EXPECT_EQ(reloaded.objects[reloaded.objects.size() - 2].shape.file, "meshes/tet.off");
    EXPECT_EQ(reloaded.objects.back().shape.file, "meshes/tet.off");
    fs::remove_all(root);
}

}  // namespace
}  // namespace penumbra
