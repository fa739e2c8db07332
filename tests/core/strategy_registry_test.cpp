// The registry and the parameter contract of the Strategy API.
#include <gtest/gtest.h>

#include <memory>
#include <stdexcept>
#include <string>

#include "treecut/error.hpp"
#include "treecut/registry.hpp"
#include "treecut/strategies/builtin.hpp"
#include "treecut/strategies/optimization.hpp"

namespace treecut {
namespace {

TEST(StrategyRegistry, ListsTheBuiltInsSortedWithTheirParameters) {
  const StrategyRegistry r = strategies::builtin_registry();
  const auto list = r.list();
  ASSERT_EQ(list.size(), 7u);
  EXPECT_EQ(list[0].name, "bucket");
  EXPECT_EQ(list[1].name, "budget");
  EXPECT_EQ(list[2].name, "event_queue");
  EXPECT_EQ(list[3].name, "hoq");
  EXPECT_EQ(list[4].name, "optimization");
  EXPECT_EQ(list[5].name, "recursive");
  EXPECT_EQ(list[6].name, "topdown");
  for (const StrategyInfo& info : list) {
    EXPECT_EQ(info.origin, "built-in");
    EXPECT_FALSE(info.description.empty());
    EXPECT_FALSE(info.params.empty());
    for (const ParamSpec& p : info.params) {
      EXPECT_EQ(check_param(p, p.default_value), "") << info.name << "." << p.name;
    }
  }
  EXPECT_EQ(r.create("optimization")->param("k"), 8192.0);
}

TEST(StrategyRegistry, AnUnknownNameIsAnInputErrorListingTheKnownOnes) {
  const StrategyRegistry r = strategies::builtin_registry();
  try {
    (void)r.create("qsplat");
    FAIL() << "no exception";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()),
              "unknown strategy 'qsplat' (known: bucket, budget, event_queue, hoq, optimization, "
              "recursive, "
              "topdown)");
  }
}

TEST(StrategyRegistry, RefusesDuplicatesAndMismatchedFactories) {
  StrategyRegistry r = strategies::builtin_registry();
  EXPECT_THROW(
      r.add("bucket", "again", [] { return std::make_unique<strategies::OptimizationStrategy>(); }),
      std::invalid_argument);
  EXPECT_THROW(r.add("other", "lies about its name",
                     [] { return std::make_unique<strategies::OptimizationStrategy>(); }),
               std::invalid_argument);
  EXPECT_THROW(r.add("", "empty", nullptr), std::invalid_argument);
  EXPECT_EQ(r.names().size(), 7u);
}

TEST(StrategyParams, OutOfRangeNonIntegralAndUnknownValuesAreRefusedUnchanged) {
  strategies::OptimizationStrategy s;
  EXPECT_THROW(s.set_param("k", 0), InputError);
  EXPECT_THROW(s.set_param("k", 12.5), InputError);
  EXPECT_THROW(s.set_param("k", std::nan("")), InputError);
  EXPECT_THROW(s.set_param("kk", 3), InputError);
  EXPECT_THROW((void)s.param("kk"), InputError);
  EXPECT_EQ(s.param("k"), 8192.0);
  s.set_param("k", 16);
  EXPECT_EQ(s.param("k"), 16.0);
  try {
    s.set_param("curvature_weight", 2.0);
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()), "optimization: curvature_weight = 2 is out of range [0, 1]");
  }
}

}  // namespace
}  // namespace treecut
