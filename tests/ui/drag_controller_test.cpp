// A gizmo drag turned into edit commands and applied to a real session: the log lines, one
// undo step for the whole drag, the preview while dragging, and the lighting that changes.

#include "ui/drag_controller.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "edit/edit_session.h"
#include "test_scenes.h"

namespace penumbra {
namespace {

Scene litRoom() {
    Scene s;
    s.settings.patchSize = 0.5;
    s.settings.elementSize = 0.25;
    test::addMaterial(s, "white", Rgb(0.6));
    test::addMaterial(s, "lamp", Rgb(0.5), Rgb(20.0));
    test::addClosedRoom(s, 2.0, "white");
    s.objects.push_back(test::makeQuad("lamp", 0.5, 0.5, "lamp", {0, 0.99, 0}, {180, 0, 0}));
    SceneObject crate;
    crate.id = "crate";
    crate.shape.type = ShapeType::Box;
    crate.shape.size = Vec3(0.5);
    crate.material = "white";
    crate.transform.translate = {0, -0.75, 0};
    s.objects.push_back(crate);
    return s;
}

/// Floor radiosity (luminance) under where the crate starts, summed over elements near x=0.
double floorUnderCrate(const EditSession& session) {
    const Discretization& d = session.discretization();
    const std::vector<Rgb> b = session.displayRadiosity();
    const int floor = session.objectVersion("floor");
    double sum = 0;
    for (std::size_t e = 0; e < d.elements().size(); ++e) {
        const Element& el = d.elements()[e];
        if (el.object == floor && std::abs(el.centroid.x) < 0.3 && std::abs(el.centroid.z) < 0.3)
            sum += luminance(b[e]);
    }
    return sum;
}

std::vector<std::string> readLines(const std::string& path) {
    std::ifstream in(path);
    std::vector<std::string> lines;
    for (std::string l; std::getline(in, l);) lines.push_back(l);
    return lines;
}

TEST(DragController, ProducesSelectTransformsUnselect) {
    DragController drag;
    Transform start;
    start.translate = {1, 2, 3};
    const auto begin = drag.begin("crate", start);
    ASSERT_EQ(begin.size(), 1u);
    EXPECT_EQ(begin[0].toString(), "{\"op\":\"select\",\"id\":\"crate\"}");
    EXPECT_FALSE(drag.update(start).has_value()) << "no move, no command";
    Transform t = start;
    t.translate.x = 1.5;
    const auto u = drag.update(t);
    ASSERT_TRUE(u.has_value());
    EXPECT_EQ(u->toString(),
              "{\"op\":\"transform\",\"id\":\"crate\",\"transform\":{\"translate\":[1.5,2.0,3.0],"
              "\"rotate_deg\":[0.0,0.0,0.0],\"scale\":[1.0,1.0,1.0]}}");
    EXPECT_FALSE(drag.update(t).has_value());
    EXPECT_THROW(drag.begin("other", start), std::logic_error);
    const auto cancel = drag.cancel();
    ASSERT_EQ(cancel.size(), 2u);
    EXPECT_STREQ(cancel[0].opName(), "transform");
    EXPECT_EQ(std::get<TransformCommand>(cancel[0].op).translate, start.translate);
    EXPECT_STREQ(cancel[1].opName(), "unselect");
    EXPECT_FALSE(drag.active());
    EXPECT_TRUE(drag.end().empty());
    EXPECT_FALSE(drag.update(t).has_value());
}

TEST(DragController, ADragOnASessionIsLoggedAndUndoneAsOneStep) {
    const std::string log =
        (std::filesystem::temp_directory_path() / "penumbra_drag_controller_test.jsonl").string();
    std::filesystem::remove(log);
    EditSession session(litRoom(), SolverOptions{}, "lit-room");
    session.openLog(log);
    session.converge(1e-3);
    const double before = floorUnderCrate(session);
    const Transform start = session.scene().objects[session.scene().findObject("crate")].transform;

    DragController drag;
    for (const EditCommand& c : drag.begin("crate", start)) session.apply(c);
    EXPECT_EQ(session.selected(), "crate");
    Transform t = start;
    for (double x : {0.2, 0.4, 0.6}) {
        t.translate.x = x;
        if (auto c = drag.update(t)) session.apply(*c);
        session.solve(50);  // preview shots while dragging
    }
    // The preview already shows more light under the crate's old place.
    EXPECT_GT(floorUnderCrate(session), before * 1.05) << "preview while dragging";
    for (const EditCommand& c : drag.end()) session.apply(c);
    EXPECT_EQ(session.selected(), "");
    session.converge(1e-3);
    const double after = floorUnderCrate(session);
    EXPECT_GT(after, before * 1.05) << "the floor under the crate's old place is lit now";

    // The log: select, three transforms, unselect.
    const std::vector<std::string> lines = readLines(log);
    ASSERT_EQ(lines.size(), 5u);
    const char* ops[] = {"select", "transform", "transform", "transform", "unselect"};
    for (int i = 0; i < 5; ++i) {
        const EditCommand c = parseEditCommand(lines[i], {log, i + 1});
        EXPECT_STREQ(c.opName(), ops[i]) << lines[i];
    }
    EXPECT_NE(lines[3].find("\"translate\":[0.6,-0.75,0.0]"), std::string::npos) << lines[3];

    // One undo step for the whole drag; undo brings the crate and its shadow back.
    ASSERT_EQ(session.undoDepth(), 1u);
    session.apply(UndoCommand{});
    EXPECT_EQ(session.scene().objects[session.scene().findObject("crate")].transform.translate,
              start.translate);
    session.converge(1e-3);
    // Under the crate the floor is dark again (redistribution leaves a residue of order the
    // convergence threshold, compared with the lit value).
    EXPECT_NEAR(floorUnderCrate(session), before, 0.03 * after) << "undo restores the shadow";
    session.apply(RedoCommand{});
    EXPECT_EQ(session.scene().objects[session.scene().findObject("crate")].transform.translate.x,
              0.6);
    session.closeLog();
    std::filesystem::remove(log);
}

}  // namespace
}  // namespace penumbra
