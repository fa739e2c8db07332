// The Feedback Stage on its own thread: strategy switch and shutdown while an
// iteration is running, convergence stopping the requests, the counters.
// Synchronization in these tests uses explicit handshakes, never sleeps.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <memory>
#include <string>
#include <thread>

#if defined(__linux__)
#include <sched.h>
#include <time.h>
#endif

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
  auto h = test::small_hierarchy(tools::ModelKind::Sphere, 4000);
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

// Ignores cancellation until the test lets it go (a plugin that checks
// in.cancelled() too rarely, or never).
class StubbornStrategy final : public Strategy {
 public:
  StubbornStrategy(std::atomic<int>* entered, std::atomic<bool>* release)
      : Strategy({}), entered_(entered), release_(release) {}
  [[nodiscard]] std::string_view name() const override { return "stubborn"; }
  [[nodiscard]] Mode mode() const override { return Mode::Evolve; }
  void reset(const Hierarchy&) override {}
  void iterate(const IterationInput&, IterationOutput& out) override {
    entered_->fetch_add(1);
    entered_->notify_all();
    for (bool r = release_->load(); !r; r = release_->load()) release_->wait(r);
    out.result.cancelled = true;
  }

 private:
  std::atomic<int>* entered_;
  std::atomic<bool>* release_;
};

TEST(FeedbackThread, AStrategyIgnoringCancellationIsReportedByTheDestructor) {
  std::atomic<int> entered{0};
  std::atomic<bool> release{false};
  std::string report;
  {
    StageOptions o;
    o.cancel_timeout = std::chrono::milliseconds(20);
    o.on_slow_cancel = [&](const std::string& what) {
      report = what;  // the destructor's thread; read after it returned
      release.store(true);
      release.notify_all();
    };
    auto s = std::make_unique<StubbornStrategy>(&entered, &release);
    s->set_origin("/plugins/libstubborn.so");
    FeedbackStage stage(model(), std::move(s), o);
    ASSERT_TRUE(stage.poll().requested);
    wait_until_entered(entered, 1);
  }  // cancels; the strategy ignores it; reported, then it is let go and joined
  EXPECT_EQ(report.rfind("strategy 'stubborn' (plugin /plugins/libstubborn.so) ignored "
                         "cancellation for ",
                         0),
            0u)
      << report;
}

class ThrowIntStrategy final : public Strategy {
 public:
  ThrowIntStrategy() : Strategy({}) {}
  [[nodiscard]] std::string_view name() const override { return "throws_int"; }
  [[nodiscard]] Mode mode() const override { return Mode::Evolve; }
  void reset(const Hierarchy&) override {}
  void iterate(const IterationInput&, IterationOutput&) override { throw 42; }
};

TEST(FeedbackThread, AnIntThrownOnTheStageThreadReachesPollAsAStrategyError) {
  FeedbackStage stage(model(), std::make_unique<ThrowIntStrategy>());
  std::string what;
  while (what.empty()) {
    try {
      stage.poll();
    } catch (const StrategyError& e) {
      what = e.what();
    }
    std::this_thread::yield();
  }
  EXPECT_EQ(what, "strategy 'throws_int': threw an exception of type int");
  EXPECT_EQ(stage.counters().errors, 1u);
  EXPECT_EQ(stage.front().generation, 1u);
}

#if defined(__linux__)
// Burns `work` of its own thread's CPU time per iteration: a stage thread
// that gets no CPU makes no progress.
class BurnStrategy final : public Strategy {
 public:
  explicit BurnStrategy(std::chrono::nanoseconds work) : Strategy({}), work_(work) {}
  [[nodiscard]] std::string_view name() const override { return "burn"; }
  [[nodiscard]] Mode mode() const override { return Mode::Evolve; }
  void reset(const Hierarchy&) override {}
  void iterate(const IterationInput& in, IterationOutput&) override {
    const auto start = thread_cpu();
    while (thread_cpu() - start < work_ && !in.cancelled()) {
    }
    // The policy the work finished under (SCHED_OTHER once raised).
    if (sched_getscheduler(0) == SCHED_OTHER) raised.fetch_add(1);
  }
  std::atomic<int> raised{0};

 private:
  static std::chrono::nanoseconds thread_cpu() {
    timespec t{};
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
    return std::chrono::seconds(t.tv_sec) + std::chrono::nanoseconds(t.tv_nsec);
  }
  std::chrono::nanoseconds work_;
};

// The starvation: an Idle stage beside a CPU hog on the same core.
// Both this thread and the hog run at normal priority on one CPU, so the
// SCHED_IDLE stage gets (nearly) nothing unless poll() raises it once a
// request has waited past the bound. Without the raise each 20 ms iteration
// takes about 7 s of wall time here (SCHED_IDLE weighs 3 against 1024).
TEST(FeedbackThread, AStarvedIdleStageIsRaisedUntilItsIterationIsDone) {
  cpu_set_t before;
  ASSERT_EQ(sched_getaffinity(0, sizeof before, &before), 0);
  cpu_set_t one;
  CPU_ZERO(&one);
  for (int c = 0; c < CPU_SETSIZE; ++c) {
    if (CPU_ISSET(c, &before)) {
      CPU_SET(c, &one);
      break;
    }
  }
  ASSERT_EQ(sched_setaffinity(0, sizeof one, &one), 0);  // this thread; new ones inherit it
  std::atomic<bool> stop{false};
  std::thread hog([&] {
    while (!stop.load(std::memory_order_relaxed)) {
    }
  });
  {
    StageOptions o;
    o.priority = StagePriority::Idle;
    o.starvation_bound = std::chrono::milliseconds(5);
    auto burn = std::make_unique<BurnStrategy>(std::chrono::milliseconds(20));
    const BurnStrategy* b = burn.get();
    FeedbackStage stage(model(), std::move(burn), o);
    while (stage.counters().iterations < 3) {
      stage.poll();
      if (stage.counters().iterations == 0 && stage.counters().frames > 1000 &&
          !stage.can_boost()) {
        break;  // unprivileged: no raise possible (checked below)
      }
      std::this_thread::yield();
    }
    if (stage.can_boost()) {
      EXPECT_GE(stage.counters().iterations, 3u);
      EXPECT_GE(stage.counters().boosts, 1u);
      EXPECT_GE(stage.counters().starved, stage.counters().boosts);
      EXPECT_GE(b->raised.load(), 1) << "no iteration ran at the raised priority";
    }
    stop.store(true);
    hog.join();
    ASSERT_EQ(sched_setaffinity(0, sizeof before, &before), 0);
    if (!stage.can_boost()) GTEST_SKIP() << "this process may not raise a thread's priority";
  }
}
#endif

}  // namespace
}  // namespace treecut
