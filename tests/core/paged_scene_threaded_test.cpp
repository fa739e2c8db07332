// A scene whose models are caches drawn from their pages (issue 45: "every
// strategy and the scene mode work on a paged model"; scene.hpp,
// SceneLoadOptions::paging; feedback_stage_scene_pages.cpp): standing still,
// the lists reach the whole scene's; flying within a tight budget, no
// object's list ever loses a node, whichever other object of its model draws
// coarser.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "strategy_fixtures.hpp"
#include "test_support.hpp"
#include "treecut/cache.hpp"
#include "treecut/feedback_stage.hpp"
#include "treecut/paged_hierarchy.hpp"
#include "treecut/scene.hpp"
#include "treecut/strategies/builtin.hpp"

using namespace treecut;
namespace fs = std::filesystem;

namespace {

constexpr int kWaitMs = 20000;

// Two caches of several pages each (a terrain of 100,000 points, a sphere
// of 60,000) and a scene of three objects: two instances of the terrain, one
// of the sphere.
fs::path paged_scene_file(const std::string& name) {
  const fs::path dir = test::scratch_dir(name);
  save_cache(*test::small_hierarchy(tools::ModelKind::Terrain, 100000), {1, 2, 3}, dir / "t.tch");
  save_cache(*test::small_hierarchy(tools::ModelKind::Sphere, 60000), {1, 2, 3}, dir / "s.tch");
  std::ofstream(dir / "three.scene") << "treecut-scene 1\n"
                                        "model t t.tch\n"
                                        "model s s.tch\n"
                                        "object t\n"
                                        "object t translate 2.2 0 0\n"
                                        "object s scale 0.6 translate 1.1 2.0 0.3\n";
  return dir / "three.scene";
}

// A camera above the scene, looking down on all three objects.
ViewSnapshot overview() {
  return ViewSnapshot::look_at({1.1f, -2.2f, 2.6f}, {1.1f, 0.6f, 0.0f}, {640, 480}, 0.9f, 0.01f,
                               20.0f);
}

std::shared_ptr<const StageScene> load(const fs::path& file, std::uint64_t memory) {
  SceneLoadOptions options;
  if (memory != 0) {
    options.paging.emplace();
    options.paging->memory_bytes = memory;
  }
  return stage_scene(load_scene(file, options));
}

StageOptions manual() {
  StageOptions o;
  o.launch = Launch::Manual;
  o.validate = true;  // every object's list a cut of its model, every step
  return o;
}

StrategyFactory factory(const std::string& name) {
  return [name] {
    std::unique_ptr<Strategy> s = strategies::builtin_registry().create(name);
    if (name == "budget") {
      s->set_param("points", 1e9);  // the cuts follow the view, not Eq. 1's shares
      s->set_param("culling", 0.0);
    }
    return s;
  };
}

std::vector<NodeId> lists(const FrameLists& f) {
  return {f.current.nodes.begin(), f.current.nodes.end()};
}

// Every paged model's pages read and idle (a frame never waits; a test may).
void wait_pages(const StageScene& scene) {
  for (const auto& p : scene.paged) {
    if (p) {
      ASSERT_TRUE(p->wait_idle(kWaitMs));
    }
  }
}

}  // namespace

TEST(PagedScene, StandingStillTheListsReachTheWholeScenes) {
  const fs::path file = paged_scene_file("paged_scene_still");
  for (const char* name : {"budget", "recursive"}) {
    SCOPED_TRACE(name);
    const auto whole = load(file, 0);
    ASSERT_TRUE(whole->paged.empty());
    FeedbackStage reference(whole, factory(name), manual());
    reference.set_view(overview());
    std::vector<NodeId> expect;
    for (int frame = 0; frame < 8; ++frame) {
      const FrameLists f = reference.poll();
      if (f.exchanged) expect = lists(f);
      reference.step();
    }
    ASSERT_FALSE(expect.empty());

    const auto scene = load(file, 256u << 20);
    ASSERT_EQ(scene->paged.size(), 2u);
    ASSERT_TRUE(scene->paged[0] && scene->paged[1]);
    for (const auto& p : scene->paged) ASSERT_EQ(p->stats().resident_pages, 1u);
    FeedbackStage stage(scene, factory(name), manual());
    stage.set_view(overview());
    bool reached = false;
    for (int frame = 0; frame < 400 && !reached; ++frame) {
      const FrameLists f = stage.poll();
      if (f.exchanged) reached = lists(f) == expect;
      stage.step();
      wait_pages(*scene);
    }
    EXPECT_TRUE(reached) << "the lists never reached the whole scene's";
    EXPECT_EQ(stage.counters().errors, 0u) << stage.counters().last_error;
    const Counters& c = stage.counters().last.counters;
    ASSERT_TRUE(c.find("pages_loaded"));
    EXPECT_GT(*c.find("pages_loaded"), 0.0);
    EXPECT_EQ(*c.find("pages_resident"), double(scene->paged[0]->stats().resident_pages +
                                                scene->paged[1]->stats().resident_pages));
  }
}

// Two instances of one model, one near and one far: the far one's coarse
// list does not free the pages the near one draws, and the budget holds.
TEST(PagedScene, AFlightWithinATightBudgetKeepsEveryObjectsListResident) {
  const fs::path file = paged_scene_file("paged_scene_flight");
  // Half of what the whole scene's pages take.
  std::uint64_t all = 0;
  for (const char* cache : {"t.tch", "s.tch"}) {
    const auto probe = PagedHierarchy::open(file.parent_path() / cache);
    test::load_every_page(*probe);
    all += probe->stats().resident_bytes;
  }
  const std::uint64_t budget = all / 2;
  for (const char* name : {"budget", "optimization"}) {
    SCOPED_TRACE(name);
    const auto scene = load(file, budget);
    FeedbackStage stage(scene, factory(name), manual());
    std::uint64_t evicted = 0;
    for (int frame = 0; frame < 240; ++frame) {
      // Low over the first terrain, then over the second: the other one far.
      const float x = -0.6f + 2.8f * float(frame) / 239.0f;
      stage.set_view(
          ViewSnapshot::look_at({x, -0.5f, 0.5f}, {x, 0.2f, 0.0f}, {640, 480}, 0.9f, 0.01f, 20.0f));
      (void)stage.poll();
      stage.step();
      wait_pages(*scene);
      std::uint64_t resident = 0;
      for (const auto& p : scene->paged) resident += p->stats().resident_bytes;
      // Each model's share of the budget, and what a group read beyond it
      // takes while the lists still hold the pages it would replace.
      ASSERT_LE(resident, budget + budget / 2) << "frame " << frame;
    }
    for (const auto& p : scene->paged) evicted += p->stats().evicted;
    EXPECT_GT(evicted, 0u) << "the flight never gave a page back";
    // validate is on: a list that lost a node's page fails its check.
    EXPECT_EQ(stage.counters().errors, 0u) << stage.counters().last_error;
  }
}

// A strategy per object keeps state for what its object's model holds: a
// paged model's budget, not its file, counts toward the limit.
TEST(PagedScene, PerObjectStrategiesCountWhatAPagedModelHolds) {
  const fs::path file = paged_scene_file("paged_scene_limit");
  std::ofstream many(file.parent_path() / "many.scene");
  many << "treecut-scene 1\nmodel t t.tch\n";
  for (int i = 0; i < 2000; ++i)
    many << "object t translate " << 2.2 * (i % 50) << " " << 2.2 * (i / 50) << " 0\n";
  many.close();
  const auto probe = strategies::builtin_registry().create("optimization");
  const auto whole = load(file.parent_path() / "many.scene", 0);
  ASSERT_GT(whole->object_nodes(), kMaxPerObjectNodes);
  EXPECT_NE(per_object_limit_problem(*whole, *probe), "");
  const auto paged = load(file.parent_path() / "many.scene", 1u << 20);
  EXPECT_LE(paged->object_nodes(), kMaxPerObjectNodes);
  EXPECT_EQ(per_object_limit_problem(*paged, *probe), "");
}

// Paging with no memory budget (PagingOptions' 0): the caches drawn from
// their pages without a limit, not each within a share of nothing.
TEST(PagedScene, PagingWithNoBudgetHasNoLimit) {
  const fs::path file = paged_scene_file("paged_scene_unlimited");
  SceneLoadOptions options;
  options.paging.emplace();
  const auto scene = stage_scene(load_scene(file, options));
  ASSERT_EQ(scene->paged.size(), 2u);
  for (const auto& p : scene->paged) {
    ASSERT_TRUE(p);
    EXPECT_EQ(p->memory_budget(), 0u);
  }
}
