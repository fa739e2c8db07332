// Thread stress of the wait/process exchange ("Parallel TreeCut
// Manipulation", figure 2): a render loop stand-in polls a threaded Feedback
// Stage with randomized delays on both sides, checks every list it receives
// (complete and valid), verifies that the lists the frame may read (the
// current one, the fading previous one) keep their content until the next
// poll while the stage thread writes, and switches strategies,
// parameters, views and models, and shuts stages down, in the middle of
// iterations. TREECUT_STRESS_EXCHANGES sets the number of exchanges (default
// 1,000,000: about 55 s in Release, run alone; the ASan and TSan presets set
// 100,000), spread over sessions of a size that scales with it, so a small
// run still shuts several stages down. Nothing here measures time; a
// deadlock hangs and the CTest timeout fails the test.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <memory>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include "strategy_fixtures.hpp"
#include "treecut/feedback_stage.hpp"
#include "treecut/model.hpp"
#include "treecut/strategies/builtin.hpp"

namespace treecut {
namespace {

std::uint64_t exchanges_wanted() {
  if (const char* env = std::getenv("TREECUT_STRESS_EXCHANGES")) {
    return std::strtoull(env, nullptr, 10);
  }
  return 1'000'000;
}

std::uint64_t checksum(std::span<const NodeId> nodes) {
  std::uint64_t h = 0xcbf29ce484222325ull;
  for (const NodeId n : nodes) h = (h ^ n) * 0x100000001b3ull;
  return h;
}

struct InFlight {
  std::uint64_t generation;
  std::span<const NodeId> nodes;
  std::uint64_t sum;
};

// One stage's life: returns the exchanges it made. Destroyed at a random
// moment, often while an iteration runs.
std::uint64_t run_session(std::mt19937_64& rng, std::uint64_t budget,
                          const std::vector<std::shared_ptr<const Hierarchy>>& models,
                          const StrategyRegistry& registry, std::uint64_t& lists_checked) {
  const auto& h0 = models[rng() % models.size()];
  StageOptions options;
  options.list_buffers = 3 + static_cast<unsigned>(rng() % 3);
  options.blend_frames = static_cast<unsigned>(rng() % 3);
  // How the idle stage notices requests: the defaults (spin, then poll), or
  // parked at once, so that every request wakes it.
  if (rng() % 2 == 0) {
    options.idle_spin = std::chrono::microseconds{0};
    options.idle_park_after = std::chrono::microseconds{rng() % 2 == 0 ? 0 : 300};
    options.idle_poll_interval = std::chrono::microseconds{10};
  }
  auto walk = std::make_unique<test::RandomWalkStrategy>(rng());
  walk->set_param("spin", static_cast<double>(rng() % 2000));
  FeedbackStage stage(Model{h0, TreeCut::root_cut(*h0)}, std::move(walk), options);

  std::shared_ptr<const Hierarchy> current = h0;
  std::vector<InFlight> drawn;  // what this frame may read, checked before the next poll
  std::uint64_t version = 1;
  const std::uint64_t frames = budget * 4 + 1000;
  for (std::uint64_t frame = 0; frame < frames && stage.counters().exchanges < budget; ++frame) {
    // Inputs at random moments, whether or not an iteration runs.
    // A converged stage requests nothing until the view changes: move the camera.
    const std::uint64_t dice = stage.counters().converged ? 0 : rng() % 1000;
    if (dice < 40) {
      ViewSnapshot v = test::orbit_view(*current, static_cast<float>(rng() % 628) / 100.0f,
                                        0.3f + static_cast<float>(rng() % 300) / 100.0f);
      v.version = ++version;
      stage.set_view(v);
    } else if (dice < 44) {
      const std::vector<std::string> names = registry.names();
      stage.set_strategy(registry.create(names[rng() % names.size()]));
    } else if (dice < 48) {
      auto walk2 = std::make_unique<test::RandomWalkStrategy>(rng());
      walk2->set_param("spin", static_cast<double>(rng() % 2000));
      stage.set_strategy(std::move(walk2));
    } else if (dice < 50 && stage.strategy_name() == "optimization") {
      stage.set_param("max_nodes", static_cast<double>(50 + rng() % 3000));
    } else if (dice < 51) {
      current = models[rng() % models.size()];
      stage.set_model(Model{current, breadth_first_cut(*current, rng() % 500)});
    }

    const FrameLists f = stage.poll();
    if (f.exchanged) {
      std::string why = TreeCut::validate(*f.current.hierarchy, f.current.nodes);
      if (why.empty() && !std::is_sorted(f.current.nodes.begin(), f.current.nodes.end())) {
        why = "the list is not in ascending id order";
      }
      if (!why.empty()) {
        ADD_FAILURE() << "generation " << f.current.generation << ": " << why;
        return stage.counters().exchanges;
      }
      ++lists_checked;
    }
    drawn.clear();
    drawn.push_back({f.current.generation, f.current.nodes, checksum(f.current.nodes)});
    if (!f.previous.nodes.empty()) {
      drawn.push_back({f.previous.generation, f.previous.nodes, checksum(f.previous.nodes)});
    }
    // Render-thread delay: mostly none, sometimes a short spin or a yield.
    const std::uint64_t delay = rng() % 100;
    if (delay < 10) {
      volatile std::uint64_t sink = 0;
      for (std::uint64_t i = 0; i < rng() % 3000; ++i) sink = sink + i;
    } else if (delay < 12) {
      std::this_thread::yield();
    }
    // The stage thread ran meanwhile: the lists of this frame are unchanged.
    for (const InFlight& d : drawn) {
      if (checksum(d.nodes) != d.sum) {
        ADD_FAILURE() << "list " << d.generation << " changed while the frame could read it";
        return stage.counters().exchanges;
      }
    }
  }
  return stage.counters().exchanges;  // ~FeedbackStage: shutdown, maybe mid-iteration
}

TEST(ExchangeStress, EveryExchangedListIsCompleteAndValid) {
  const std::uint64_t wanted = exchanges_wanted();
  const std::vector<std::shared_ptr<const Hierarchy>> models = {
      test::small_hierarchy(tools::ModelKind::Sphere, 3000),
      test::small_hierarchy(tools::ModelKind::Terrain, 2000),
      test::small_hierarchy(tools::ModelKind::City, 2500)};
  const StrategyRegistry registry = strategies::builtin_registry();
  std::mt19937_64 rng(20240611);
  std::uint64_t exchanges = 0;
  std::uint64_t lists_checked = 0;
  int sessions = 0;
  while (exchanges < wanted && !HasFailure()) {
    const std::uint64_t budget = std::min<std::uint64_t>(
        wanted - exchanges, 1000 + rng() % std::max<std::uint64_t>(wanted / 10, 1));
    exchanges += run_session(rng, budget, models, registry, lists_checked);
    ++sessions;
  }
  EXPECT_GE(exchanges, wanted);
  EXPECT_EQ(lists_checked, exchanges);
  std::printf("%llu exchanges in %d stage lifetimes, every list validated\n",
              static_cast<unsigned long long>(exchanges), sessions);
}

TEST(ExchangeStress, ShutdownAtAnyMomentNeverDeadlocks) {
  const auto h = test::small_hierarchy(tools::ModelKind::Sphere, 3000);
  std::mt19937_64 rng(7);
  const int lives = static_cast<int>(std::min<std::uint64_t>(2000, exchanges_wanted() / 100 + 10));
  for (int i = 0; i < lives; ++i) {
    auto walk = std::make_unique<test::RandomWalkStrategy>(rng());
    walk->set_param("spin", static_cast<double>(rng() % 100000));
    StageOptions options;
    if (rng() % 2 == 0) options.idle_park_after = std::chrono::microseconds{0};  // parked when idle
    FeedbackStage stage(Model{h, TreeCut::root_cut(*h)}, std::move(walk), options);
    const std::uint64_t polls = rng() % 5;
    for (std::uint64_t p = 0; p < polls; ++p) stage.poll();
    if (rng() % 2 == 0) stage.set_strategy(std::make_unique<test::RandomWalkStrategy>(rng()));
  }
  SUCCEED() << lives << " stages started and destroyed";
}

}  // namespace
}  // namespace treecut
