// The recovery journal's bookkeeping (ui/recovery.h), without a window: which edits an earlier
// session left, set aside until they are recovered or discarded.

#include "ui/recovery.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>

#include "edit/edit_log.h"

namespace penumbra {
namespace {

namespace fs = std::filesystem;

class Recovery : public ::testing::Test {
protected:
    void SetUp() override {
        mDir = fs::temp_directory_path() / ("penumbra_recovery_" + std::to_string(::getpid()));
        fs::remove_all(mDir);
        fs::create_directories(mDir);
        ::setenv("XDG_STATE_HOME", (mDir / "state").c_str(), 1);
    }
    void TearDown() override { fs::remove_all(mDir); }
    fs::path mDir;
};

TEST_F(Recovery, JournalsAreOnePerSceneFileInTheStateFolder) {
    const std::string a = recoveryJournalPath((mDir / "a/room.json").string());
    const std::string b = recoveryJournalPath((mDir / "b/room.json").string());
    EXPECT_NE(a, b) << "two scenes of the same name";
    EXPECT_EQ(a, recoveryJournalPath((mDir / "a/../a/room.json").string()));
    EXPECT_EQ(fs::path(a).parent_path(), mDir / "state/penumbra/recovery");
    EXPECT_EQ(fs::path(a).filename().string().rfind("room-", 0), 0u);
}

TEST_F(Recovery, AnInterruptedSessionsEditsAreSetAsideUntilAnswered) {
    const std::string journal = recoveryJournalPath((mDir / "room.json").string());
    {
        EditLogWriter log(journal);
        log.append(MoveCommand{"crate", {0.1, 0, 0}});
        log.append(SolveCommand{10});  // solver work: not an edit to recover
        log.append(SelectCommand{"slab"});
        log.append(MoveCommand{"slab", {0, 0.2, 0}});
    }  // killed mid-drag: no unselect
    UnsavedEdits unsaved = takeUnsavedEdits(journal, "");
    ASSERT_TRUE(unsaved.error.empty()) << unsaved.error;
    ASSERT_EQ(unsaved.edits.size(), 4u);
    EXPECT_EQ(unsaved.edits[0].toString(),
              EditCommand(MoveCommand{"crate", {0.1, 0, 0}}).toString());
    EXPECT_TRUE(std::holds_alternative<SelectCommand>(unsaved.edits[1].op));
    EXPECT_TRUE(std::holds_alternative<UnselectCommand>(unsaved.edits[3].op))
        << "the drag is ended";
    EXPECT_FALSE(fs::exists(journal)) << "the new session starts the journal again";
    ASSERT_TRUE(fs::exists(unsaved.file));

    // Not answered, and the next session was interrupted too: both sets, in order.
    {
        EditLogWriter log(journal);
        log.append(RemoveCommand{"crate"});
    }
    UnsavedEdits both = takeUnsavedEdits(journal, "");
    ASSERT_EQ(both.edits.size(), 5u);
    EXPECT_TRUE(std::holds_alternative<UnselectCommand>(both.edits[3].op));
    EXPECT_TRUE(std::holds_alternative<RemoveCommand>(both.edits[4].op));
    discardUnsaved(both);
    EXPECT_FALSE(fs::exists(both.file));
    EXPECT_TRUE(takeUnsavedEdits(journal, "").edits.empty());
}

TEST_F(Recovery, ASessionWithNothingUnsavedLeavesNothing) {
    const std::string journal = recoveryJournalPath((mDir / "room.json").string());
    {
        EditLogWriter log(journal);
        log.append(ConvergeCommand{1e-3});
    }
    const UnsavedEdits unsaved = takeUnsavedEdits(journal, "");
    EXPECT_TRUE(unsaved.edits.empty());
    EXPECT_TRUE(unsaved.file.empty());
    EXPECT_FALSE(fs::exists(journal));
}

}  // namespace
}  // namespace penumbra
