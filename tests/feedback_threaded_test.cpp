// The Feedback Stage on its own thread: strategy switch and shutdown while an
// iteration is running, convergence stopping the requests, the counters.
// Synchronization in these tests uses explicit handshakes, never sleeps.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <memory>
#include <thread>

#include "strategy_fixtures.hpp"
#include "treecut/feedback_stage.hpp"
#include "treecut/model.hpp"
#include "treecut/strategies/optimization.hpp"

namespace treecut {
namespace {

// Blocks inside iterate() until released or cancelled, so the test controls
// exactly when an iteration is "running".
class GateStrategy final : public Strategy {
 public:
  explicit GateStrategy(std::atomic<int>* entered) : Strategy({}), entered_(entered) {}
  [[nodiscard]] std::string_view name() const override { return "gate"; }
  [[nodiscard]] Mode mode() const override { return Mode::Evolve; }
  void reset(const Hierarchy&) override {}
  void iterate(const IterationInput& in, IterationOutput& out) override {
    entered_->fetch_add(1);
    entered_->notify_all();
    while (!in.cancelled()) std::this_thread::yield();
    out.result.cancelled = true;
  }

 private:
  std::atomic<int>* entered_;
};

void wait_until_entered(std::atomic<int>& entered, int count) {
  for (int v = entered.load(); v < count; v = entered.load()) entered.wait(v);
}

Model model() {
  auto h = test::small_hierarchy(ModelKind::Sphere, 4000);
  return Model{h, TreeCut::root_cut(*h)};
}

TEST(FeedbackThread, SwitchingStrategyMidIterationCancelsItAndTheNewOneRuns) {
  std::atomic<int> entered{0};
  FeedbackStage stage(model(), std::make_unique<GateStrategy>(&entered));
  ASSERT_TRUE(stage.poll().requested);
  wait_until_entered(entered, 1);
  EXPECT_TRUE(stage.processing());
  stage.set_strategy(std::make_unique<strategies::OptimizationStrategy>());
  // The gate sees the cancel, returns; the optimization strategy then converges.
  while (!stage.counters().converged || stage.counters().iterations < 2) {
    stage.poll();
    std::this_thread::yield();
  }
  EXPECT_TRUE(stage.counters().converged);
  EXPECT_EQ(stage.strategy_name(), "optimization");
  EXPECT_EQ(TreeCut::validate(*stage.front().hierarchy, stage.front().nodes), "");
  const std::uint64_t requests = stage.counters().requests;
  for (int i = 0; i < 100; ++i) stage.poll();
  EXPECT_EQ(stage.counters().requests, requests) << "converged: no more requests";
}

TEST(FeedbackThread, ShutdownWhileProcessRunsReturns) {
  std::atomic<int> entered{0};
  {
    FeedbackStage stage(model(), std::make_unique<GateStrategy>(&entered));
    stage.poll();
    wait_until_entered(entered, 1);
    ASSERT_TRUE(stage.processing());
  }  // the destructor cancels the gate and joins
  EXPECT_EQ(entered.load(), 1);
}

// A cancel asked for right after a request, before the stage thread has woken
// up, must reach that iteration: the gate returns only when cancelled, so a
// lost cancel hangs (tests/model/exchange_broken_cancel_cleared_by_stage.pml).
TEST(FeedbackThread, ShutdownRightAfterARequestCancelsTheIteration) {
  for (int i = 0; i < 100; ++i) {
    std::atomic<int> entered{0};
    FeedbackStage stage(model(), std::make_unique<GateStrategy>(&entered));
    ASSERT_TRUE(stage.poll().requested);
  }  // the destructor cancels the gate, whether or not it has entered it
}

TEST(FeedbackThread, SwitchingStrategyRightAfterARequestCancelsTheIteration) {
  for (int i = 0; i < 100; ++i) {
    std::atomic<int> entered{0};
    FeedbackStage stage(model(), std::make_unique<GateStrategy>(&entered));
    ASSERT_TRUE(stage.poll().requested);
    stage.set_strategy(std::make_unique<strategies::OptimizationStrategy>());
    while (stage.counters().iterations < 2) {
      stage.poll();
      std::this_thread::yield();
    }
    EXPECT_EQ(entered.load(), 1);
    EXPECT_EQ(stage.strategy_name(), "optimization");
  }
}

TEST(FeedbackThread, CountersTrackIterationsAndExchanges) {
  FeedbackStage stage(model(), std::make_unique<test::RandomWalkStrategy>());
  while (stage.counters().exchanges < 200) {
    stage.poll();
    std::this_thread::yield();
  }
  const StageCounters& c = stage.counters();
  EXPECT_EQ(c.iterations, c.exchanges);
  EXPECT_GE(c.requests, c.iterations);
  EXPECT_LE(c.requests, c.iterations + 1);
  EXPECT_GE(c.frames_last_iteration, 1u);
  EXPECT_GE(c.iteration_ns_total, c.iteration_ns_last);
  EXPECT_FALSE(c.converged);
  EXPECT_EQ(TreeCut::validate(*stage.front().hierarchy, stage.front().nodes), "");
}

// Each way an idle stage thread notices a request: spinning, polling at an
// interval, parked until woken (StageOptions::idle_*). A lost wake-up would
// hang here until the CTest timeout.
TEST(FeedbackThread, EveryIdlePolicyPicksUpRequests) {
  using std::chrono::microseconds;
  struct Policy {
    const char* name;
    microseconds spin, poll, park_after;
  };
  for (const Policy& p :
       {Policy{"spin", microseconds{10'000'000}, microseconds{1}, microseconds{20'000'000}},
        Policy{"poll", microseconds{0}, microseconds{20}, microseconds{20'000'000}},
        Policy{"park", microseconds{0}, microseconds{1}, microseconds{0}}}) {
    StageOptions o;
    o.idle_spin = p.spin;
    o.idle_poll_interval = p.poll;
    o.idle_park_after = p.park_after;
    FeedbackStage stage(model(), std::make_unique<test::RandomWalkStrategy>(), o);
    while (stage.counters().exchanges < 300) {
      stage.poll();
      std::this_thread::yield();
    }
    EXPECT_EQ(stage.counters().iterations, stage.counters().exchanges) << p.name;
    EXPECT_EQ(TreeCut::validate(*stage.front().hierarchy, stage.front().nodes), "") << p.name;
  }
}

}  // namespace
}  // namespace treecut
