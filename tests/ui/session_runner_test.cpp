// SessionRunner's runtime strategy switch (George et al.'s strategy one/two and threshold):
// the setter validates, the getter answers at once, and the solver thread applies the switch
// to the session's ProgressiveSolver between shots (seen through SolverSnapshot, which reads
// the solver's own options). And the settling estimate's per-element map, computed only for
// the overlay.

#include "ui/session_runner.h"

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <stdexcept>
#include <thread>

#include "test_scenes.h"

namespace penumbra {
namespace {

std::unique_ptr<EditSession> litRoomSession() {
    return std::make_unique<EditSession>(test::makeLitRoom("red"), SolverOptions{});
}

TEST(SessionRunnerStrategy, SetterReachesTheSolverBetweenShots) {
    SessionRunnerOptions options;
    options.threaded = false;
    options.solveBudgetMs = 1;
    SessionRunner runner(litRoomSession(), options);
    // The defaults come from the solver's options.
    EXPECT_EQ(runner.strategy(), RedistributionStrategy::RedistributeFirst);
    EXPECT_EQ(runner.redistributionThreshold(), 0.0);
    EXPECT_EQ(runner.solver().strategy, RedistributionStrategy::RedistributeFirst);

    runner.setStrategy(RedistributionStrategy::Interleave, 0.05);
    // Requested at once, applied only by the solver iteration.
    EXPECT_EQ(runner.strategy(), RedistributionStrategy::Interleave);
    EXPECT_EQ(runner.redistributionThreshold(), 0.05);
    EXPECT_EQ(runner.solver().strategy, RedistributionStrategy::RedistributeFirst);
    runner.pump();
    EXPECT_EQ(runner.solver().strategy, RedistributionStrategy::Interleave);
    EXPECT_EQ(runner.solver().redistributionThreshold, 0.05);

    // Also while the solver is paused (the switch is not solver work).
    runner.setPaused(true);
    runner.setStrategy(RedistributionStrategy::RedistributeFirst, 0.25);
    runner.pump();
    EXPECT_EQ(runner.solver().strategy, RedistributionStrategy::RedistributeFirst);
    EXPECT_EQ(runner.solver().redistributionThreshold, 0.25);
}

TEST(SessionRunnerStrategy, InvalidThresholdIsRejectedAndChangesNothing) {
    SessionRunnerOptions options;
    options.threaded = false;
    SessionRunner runner(litRoomSession(), options);
    EXPECT_THROW(runner.setStrategy(RedistributionStrategy::Interleave, -0.1),
                 std::invalid_argument);
    EXPECT_THROW(runner.setStrategy(RedistributionStrategy::Interleave, 1.5),
                 std::invalid_argument);
    EXPECT_THROW(runner.setStrategy(RedistributionStrategy::Interleave, std::nan("")),
                 std::invalid_argument);
    EXPECT_EQ(runner.strategy(), RedistributionStrategy::RedistributeFirst);
    runner.pump();
    EXPECT_EQ(runner.solver().strategy, RedistributionStrategy::RedistributeFirst);
    EXPECT_TRUE(runner.takeMessages().empty());
}

TEST(SessionRunnerStrategy, ThreadedRunnerAppliesTheSwitch) {
    SessionRunnerOptions options;
    options.solveBudgetMs = 2;
    SessionRunner runner(litRoomSession(), options);
    runner.setStrategy(RedistributionStrategy::Interleave, 0.5);
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(10);
    while (runner.solver().strategy != RedistributionStrategy::Interleave &&
           std::chrono::steady_clock::now() < deadline)
        std::this_thread::sleep_for(std::chrono::milliseconds(5));
    EXPECT_EQ(runner.solver().strategy, RedistributionStrategy::Interleave);
    EXPECT_EQ(runner.solver().redistributionThreshold, 0.5);
}

TEST(SessionRunnerSettling, ThePerElementMapIsComputedOnlyForTheOverlay) {
    // The status line's "settled" needs the estimate's sums alone; its per-element map
    // (ProgressiveSolver::computeSettling) is computed only while View ▸ Overlay ▸ Settling
    // is on, and dropped once it is off again.
    SessionRunnerOptions options;
    options.threaded = false;
    options.solveBudgetMs = 1;
    SessionRunner runner(litRoomSession(), options);
    runner.pump();
    EXPECT_GE(runner.solver().settlingRms, 0.0) << "the status figure";
    EXPECT_EQ(runner.light().settling, nullptr) << "no map without the overlay";

    ViewRequest view;
    view.width = view.height = 16;
    view.mode = ViewMode::Gouraud;
    view.settlingOverlay = true;
    runner.setView(view);
    runner.pump();
    const PublishedLight on = runner.light();
    ASSERT_NE(on.settling, nullptr) << "the overlay's map at its first publication";
    EXPECT_EQ(on.settling->size(), on.radiosity->size());

    view.settlingOverlay = false;
    runner.setView(view);
    for (int k = 0; k < 4 && runner.light().settling; ++k) {
        std::this_thread::sleep_for(std::chrono::milliseconds(250));
        runner.pump();
    }
    EXPECT_EQ(runner.light().settling, nullptr) << "the map dropped with the overlay";
    EXPECT_GE(runner.solver().settlingRms, 0.0);
}

}  // namespace
}  // namespace penumbra
