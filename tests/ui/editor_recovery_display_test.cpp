// The editor offers to recover an unsaved session (ui/recovery.h): edits made and not saved
// (the session ended mid-drag) come back in the next session on that scene, when asked to, with
// the drag ended; saving empties the journal, and a session with nothing unsaved asks nothing.

#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>

#include "edit/edit_log.h"
#include "edit/io/scene_io.h"
#include "ui/editor_app.h"
#include "ui/editor_test_support.h"
#include "ui/recovery.h"

namespace penumbra {
namespace {

namespace fs = std::filesystem;
using test::runUntil;

TEST(EditorRecovery, UnsavedEditsComeBackInTheNextSessionAndSavingEndsThem) {
    const fs::path dir =
        fs::temp_directory_path() / ("penumbra_recovery_display_" + std::to_string(::getpid()));
    fs::remove_all(dir);
    fs::create_directories(dir);
    ::setenv("XDG_STATE_HOME", (dir / "state").c_str(), 1);
    const fs::path scene = dir / "room.json";
    fs::copy_file(fs::path(PENUMBRA_SOURCE_DIR) / "scenes/cube-room.json", scene);
    const std::string journal = recoveryJournalPath(scene.string());

    EditorOptions options;
    options.scene = scene.string();
    options.mode = ViewMode::Gouraud;
    options.width = 640;
    options.height = 400;
    options.quiet = true;
    const Vec3 at(0.9, 0.2, 0.9);
    {
        // The first session: an add and a drag it never ends, then it is gone.
        EditorApp app(options);
        SessionRunner& runner = *app.runner();
        EXPECT_TRUE(app.unsaved().edits.empty());
        SceneObject box;
        box.id = "recovered-box";
        box.shape.type = ShapeType::Box;
        box.shape.size = Vec3(0.3);
        box.material = "wood";
        box.transform.translate = at;
        runner.submit(AddCommand{box});
        runner.submit(SelectCommand{"recovered-box"});
        runner.submit(MoveCommand{"recovered-box", {0.0, 0.1, 0.0}});
        // (A drag in progress is never quiescent: wait for the three edits to apply.)
        ASSERT_TRUE(runUntil(
            app, [&] { return runner.queued() == 0 && runner.solver().selected == box.id; }, 60));
        ASSERT_EQ(readEditLog(journal).size(), 3u) << "each edit is journaled as it applies";
    }

    {
        // The second session offers them (the prompt is open); Recover replays them.
        EditorApp app(options);
        SessionRunner& runner = *app.runner();
        ASSERT_EQ(app.unsaved().edits.size(), 4u) << "the add, the drag and its end";
        for (int k = 0; k < 5; ++k) app.frame();  // the prompt is drawn
        // Kept for a look (the test's folder goes at its end).
        app.writeScreenshot((fs::temp_directory_path() / "penumbra_recovery_prompt.png").string());
        EXPECT_TRUE(runner.document()->find("recovered-box") == nullptr);
        app.recoverUnsaved();
        EXPECT_TRUE(app.unsaved().edits.empty());
        ASSERT_TRUE(runUntil(
            app, [&] { return runner.queued() == 0 && runner.quiescent(); }, 60));
        const ObjectSummary* box = runner.document()->find("recovered-box");
        ASSERT_NE(box, nullptr);
        EXPECT_EQ(box->transform.translate, at + Vec3(0.0, 0.1, 0.0));
        EXPECT_EQ(runner.solver().selected, "") << "the interrupted drag is ended";
        EXPECT_TRUE(runner.takeMessages().empty());
        EXPECT_EQ(readEditLog(journal).size(), 4u) << "journaled again as they apply";

        // Saving writes them to the scene and starts the journal again.
        app.saveScene(scene.string());
        ASSERT_TRUE(runUntil(
            app, [&] { return runner.queued() == 0 && runner.quiescent(); }, 60));
        EXPECT_TRUE(readEditLog(journal).empty());
    }
    EXPECT_FALSE(fs::exists(journal)) << "nothing unsaved: no journal left";
    EXPECT_GE(loadScene(scene.string()).findObject("recovered-box"), 0);

    {
        // Nothing to recover: no prompt.
        EditorApp app(options);
        EXPECT_TRUE(app.unsaved().edits.empty());
    }
    fs::remove_all(dir);
}

}  // namespace
}  // namespace penumbra
