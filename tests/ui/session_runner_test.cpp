// SessionRunner's runtime strategy switch (George et al.'s strategy one/two and threshold):
// the setter validates, the getter answers at once, and the solver thread applies the switch
// to the session's ProgressiveSolver between shots (seen through SolverSnapshot, which reads
// the solver's own options).

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

}  // namespace
}  // namespace penumbra
