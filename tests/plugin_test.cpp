// Plugins: loading errors are InputErrors; the example plugin (built out of
// tree against an installed treecut by the example_plugin_roundtrip test, which
// passes its path in TREECUT_EXAMPLE_PLUGIN) registers and runs its strategy.
#include "treecut/plugin.hpp"

#include <gtest/gtest.h>

#include <cstdlib>
#include <memory>
#include <string>

#include "strategy_fixtures.hpp"
#include "treecut/error.hpp"
#include "treecut/feedback_stage.hpp"
#include "treecut/model.hpp"
#include "treecut/registry.hpp"
#include "treecut/strategies/builtin.hpp"

namespace treecut {
namespace {

std::string message_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const InputError& e) {
    return e.what();
  }
  return "no InputError";
}

TEST(Plugin, AMissingFileIsAnInputErrorNamingIt) {
  StrategyRegistry r;
  const std::string m = message_of([&] { r.load_plugin("/nonexistent/libnothing.so"); });
  EXPECT_NE(m.find("/nonexistent/libnothing.so: cannot load plugin"), std::string::npos) << m;
}

TEST(Plugin, ALibraryWithoutEntryPointsIsRefused) {
  StrategyRegistry r;
  const std::string m = message_of([&] { r.load_plugin("libm.so.6"); });
  EXPECT_NE(m.find("not a treecut plugin"), std::string::npos) << m;
  EXPECT_TRUE(r.names().empty());
}

TEST(ExamplePlugin, RegistersAndRunsItsStrategyInAFeedbackStage) {
  const char* path = std::getenv("TREECUT_EXAMPLE_PLUGIN");
  if (path == nullptr) GTEST_SKIP() << "run by the example_plugin_roundtrip test";
  StrategyRegistry registry = strategies::builtin_registry();
  registry.load_plugin(path);
  ASSERT_TRUE(registry.contains("uniform_depth"));
  for (const StrategyInfo& info : registry.list()) {
    EXPECT_EQ(info.origin, info.name == "uniform_depth" ? std::string(path) : "built-in");
  }
  EXPECT_THROW(registry.load_plugin(path), InputError) << "a second load duplicates the name";
  EXPECT_TRUE(registry.contains("uniform_depth"));

  const auto h = test::small_hierarchy(ModelKind::Terrain, 5000);
  StageOptions options;
  options.launch = Launch::Manual;
  FeedbackStage stage(Model{h, TreeCut::root_cut(*h)}, registry.create("uniform_depth"), options);
  stage.set_param("depth", 1.0);
  for (int i = 0; i < 4 * h->level_count() && !stage.counters().converged; ++i) {
    const FrameLists f = stage.poll();
    ASSERT_EQ(TreeCut::validate(*h, f.current.nodes), "");
    stage.step();
  }
  ASSERT_TRUE(stage.counters().converged);
  EXPECT_EQ(stage.front().nodes.size(), h->leaf_count()) << "depth 1.0: every leaf";
}

}  // namespace
}  // namespace treecut
