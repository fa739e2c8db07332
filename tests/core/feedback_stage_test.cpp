// The wait/process protocol driven synchronously (Launch::Manual): the test
// thread is both the render thread (poll) and the Feedback Stage (step).
#include "treecut/feedback_stage.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <limits>
#include <memory>
#include <set>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "strategy_fixtures.hpp"
#include "treecut/controller.hpp"
#include "treecut/error.hpp"
#include "treecut/model.hpp"
#include "treecut/strategies/optimization.hpp"
#include "treecut/strategies/recursive.hpp"

namespace treecut {
namespace {

using test::orbit_view;
using test::small_hierarchy;

Model sphere_model() {
  auto h = small_hierarchy(tools::ModelKind::Sphere, 5000);
  return Model{h, TreeCut::root_cut(*h)};
}

StageOptions manual(unsigned buffers = 3, unsigned blend = 0) {
  StageOptions o;
  o.launch = Launch::Manual;
  o.list_buffers = buffers;
  o.blend_frames = blend;
  return o;
}

// Records what it was given and posts one query per iteration.
class ProbeStrategy final : public Strategy {
 public:
  ProbeStrategy() : Strategy({{"level", "refine down to this depth", 2, 0, 64, true}}) {}
  [[nodiscard]] std::string_view name() const override { return "probe"; }
  [[nodiscard]] Mode mode() const override { return Mode::Evolve; }
  void reset(const Hierarchy&) override { ++resets; }
  void iterate(const IterationInput& in, IterationOutput& out) override {
    frames.push_back(in.view.frame);
    versions.push_back(in.view.version);
    for (const VisibilityResult& v : in.view.visibility) seen.push_back(v);
    const int level = static_cast<int>(param_at(0));
    std::vector<NodeId> refine;
    do {  // down to `level` in one iteration
      refine.clear();
      for (const NodeId n : out.cut->nodes()) {
        if (in.hierarchy.arrays().depth[n] < level && !in.hierarchy.is_leaf(n)) {
          refine.push_back(n);
        }
      }
      for (const NodeId n : refine) out.result.refined += out.cut->refine(in.hierarchy, n);
    } while (!refine.empty());
    out.queries->push_back(
        query_about(in, out.cut->nodes()[0], static_cast<std::uint32_t>(frames.size())));
    out.result.converged = out.result.refined == 0;
    out.result.counters.set("probe_iterations", double(frames.size()), "iterations");
    if (throw_next) {
      throw_next = false;
      throw std::runtime_error("probe failure");
    }
  }
  std::vector<std::uint64_t> frames;
  std::vector<std::uint64_t> versions;
  std::vector<VisibilityResult> seen;
  int resets = 0;
  bool throw_next = false;
};

TEST(Counters, KeepTheOrderFirstSetAndOverwriteByName) {
  Counters c;
  c.set("b_blocks", 2, "blocks");
  c.set("a_ms", 1.5, "ms");
  c.set("b_blocks", 3, "blocks");
  c.add("a_ms", 0.5, "ms");
  ASSERT_EQ(c.items().size(), 2u);
  EXPECT_EQ(c.items()[0].name(), "b_blocks");
  EXPECT_EQ(c.items()[0].unit(), "blocks");
  EXPECT_EQ(c.items()[1].name(), "a_ms");
  EXPECT_EQ(c.find("b_blocks"), 3.0);
  EXPECT_EQ(c.find("a_ms"), 2.0);
  EXPECT_FALSE(c.find("c").has_value());
  Counters sum = c;
  sum.add_all(c);
  EXPECT_EQ(sum.find("b_blocks"), 6.0);
  EXPECT_EQ(sum.find("a_ms"), 4.0);
  c.clear();
  EXPECT_TRUE(c.empty());
}

TEST(Counters, RefuseNamesThatAreNoColumnUnitsThatBreakACsvAndValuesThatAreNotFinite) {
  Counters c;
  for (const char* name :
       {"", "Blocks", "9lives", "a-b", "a b", "a,b", "a_name_of_thirty_two_characters_"}) {
    EXPECT_THROW(c.set(name, 1, ""), std::invalid_argument) << name;
  }
  EXPECT_NO_THROW(c.set("a_name_of_thirty_one_characters", 1, ""));
  EXPECT_THROW(c.set("x", 1, "a,b"), std::invalid_argument);
  EXPECT_THROW(c.set("x", 1, "twelve chars"), std::invalid_argument);
  EXPECT_THROW(c.set("x", std::numeric_limits<double>::quiet_NaN(), ""), std::invalid_argument);
  EXPECT_THROW(c.set("x", std::numeric_limits<double>::infinity(), ""), std::invalid_argument);
  EXPECT_EQ(c.items().size(), 1u) << "a refused counter leaves none behind";
  for (std::size_t i = 1; i < Counters::kMax; ++i) c.set("c" + std::to_string(i), 0, "");
  EXPECT_THROW(c.set("one_too_many", 0, ""), std::length_error);
  EXPECT_NO_THROW(c.set("c1", 5, "")) << "an existing name still takes a value";
}

TEST(FeedbackStage, AnIterationsNamedCountersReachTheRenderThreadsCounters) {
  FeedbackStage stage(sphere_model(), std::make_unique<ProbeStrategy>(), manual());
  EXPECT_TRUE(stage.counters().last.counters.empty());
  for (int i = 0; i < 3; ++i) {
    stage.poll();
    stage.step();
  }
  stage.poll();
  const Counters& c = stage.counters().last.counters;
  ASSERT_EQ(c.items().size(), 1u);
  EXPECT_EQ(c.items()[0].name(), "probe_iterations");
  EXPECT_EQ(c.items()[0].unit(), "iterations");
  EXPECT_EQ(c.find("probe_iterations"), double(stage.counters().iterations));
}

TEST(FeedbackStage, StartsInWaitWithTheModelCutAsGenerationOne) {
  FeedbackStage stage(sphere_model(), std::make_unique<ProbeStrategy>(), manual());
  EXPECT_FALSE(stage.processing());
  EXPECT_EQ(stage.front().generation, 1u);
  EXPECT_EQ(stage.front().nodes.size(), 1u);
  EXPECT_FALSE(stage.step()) << "nothing was requested yet";
}

TEST(FeedbackStage, RequestsThenExchangesOnTheNextPollUntilConverged) {
  auto probe = std::make_unique<ProbeStrategy>();
  ProbeStrategy* p = probe.get();
  FeedbackStage stage(sphere_model(), std::move(probe), manual());
  FrameLists f = stage.poll();
  EXPECT_TRUE(f.requested);
  EXPECT_FALSE(f.exchanged);
  EXPECT_TRUE(stage.processing());
  EXPECT_FALSE(stage.poll().exchanged) << "no exchange while Process runs";
  ASSERT_TRUE(stage.step());
  EXPECT_FALSE(stage.processing());
  f = stage.poll();
  EXPECT_TRUE(f.exchanged);
  EXPECT_EQ(f.current.generation, 2u);
  EXPECT_EQ(stage.counters().frames_last_iteration, 2u);
  const Hierarchy& h = *f.current.hierarchy;
  EXPECT_EQ(TreeCut::validate(h, f.current.nodes), "");
  for (const NodeId n : f.current.nodes) EXPECT_EQ(h.arrays().depth[n], 2);
  // Converged after the second iteration (nothing left to refine): no more requests.
  ASSERT_TRUE(f.requested);
  ASSERT_TRUE(stage.step());
  f = stage.poll();
  EXPECT_TRUE(f.exchanged);
  EXPECT_TRUE(stage.counters().converged);
  EXPECT_FALSE(f.requested);
  EXPECT_FALSE(stage.poll().requested);
  EXPECT_EQ(stage.counters().iterations, 2u);
  EXPECT_EQ(stage.counters().exchanges, 2u);
  EXPECT_EQ(p->frames, (std::vector<std::uint64_t>{1, 3}));
}

TEST(FeedbackStage, AViewChangeRequestsAgainAfterConvergence) {
  auto probe = std::make_unique<ProbeStrategy>();
  ProbeStrategy* p = probe.get();
  FeedbackStage stage(sphere_model(), std::move(probe), manual());
  for (int i = 0; i < 6; ++i) {
    stage.poll();
    stage.step();
  }
  ASSERT_TRUE(stage.counters().converged);
  EXPECT_FALSE(stage.poll().requested);
  ViewSnapshot v = orbit_view(*sphere_model().hierarchy, 1.0f);
  v.version = 42;
  stage.set_view(v);
  EXPECT_TRUE(stage.poll().requested);
  stage.step();
  EXPECT_EQ(p->versions.back(), 42u);
  stage.set_view(v);  // same version: not a change
  stage.poll();
  EXPECT_FALSE(stage.poll().requested);
}

TEST(FeedbackStage, ParametersApplyAtTheNextIterationAndBadOnesThrowAtOnce) {
  FeedbackStage stage(sphere_model(), std::make_unique<ProbeStrategy>(), manual());
  EXPECT_THROW(stage.set_param("nope", 1), InputError);
  EXPECT_THROW(stage.set_param("level", 1.5), InputError);
  EXPECT_THROW(stage.set_param("level", 99), InputError);
  stage.set_param("level", 4);
  for (int i = 0; i < 8; ++i) {
    stage.poll();
    stage.step();
  }
  const FrontList& f = stage.front();
  for (const NodeId n : f.nodes) {
    EXPECT_TRUE(f.hierarchy->arrays().depth[n] == 4 || f.hierarchy->is_leaf(n));
  }
}

// A parameter change is an event the strategy sees (IterationInput::
// params_version): under a static view the optimization strategy's hysteresis
// (a node coarsened under this view is not refined again) must not block the
// refinement a raised budget asks for.
TEST(FeedbackStage, RaisingMaxNodesUnderAStaticViewRefinesAgain) {
  Model m = sphere_model();
  const auto h = m.hierarchy;
  FeedbackStage stage(std::move(m), std::make_unique<strategies::OptimizationStrategy>(), manual());
  ViewSnapshot v = orbit_view(*h, 0.5f);
  v.version = 1;
  stage.set_view(v);
  const auto converge = [&] {
    for (int i = 0; i < 400; ++i) {
      const FrameLists f = stage.poll();
      if (!f.requested) break;
      stage.step();
    }
    EXPECT_TRUE(stage.counters().converged);
    return stage.front().nodes.size();
  };
  stage.set_param("max_nodes", 2000);
  const std::size_t full = converge();
  ASSERT_GT(full, 1500u) << "the view must want more nodes than the lowered budget";
  stage.set_param("max_nodes", 300);
  EXPECT_LE(converge(), 300u);
  const std::uint64_t iterations = stage.counters().iterations;
  stage.set_param("max_nodes", 2000);
  EXPECT_EQ(converge(), full) << "the same view and budget give the same cut again";
  EXPECT_GT(stage.counters().iterations, iterations + 1);
  // Setting the value a parameter already has is no event: one iteration
  // confirms convergence and changes nothing.
  stage.set_param("max_nodes", 2000);
  EXPECT_EQ(converge(), full);
  EXPECT_EQ(stage.counters().last.refined + stage.counters().last.coarsened, 0u);
}

// Issue 30: `param max_nodes N` then `converge` in a viewer script returned
// at once with "converged" at the old budget. Converged is for the inputs
// the stage has now: not at once after a new parameter, and not from the
// iteration that ran while it came.
TEST(FeedbackStage, AParameterSetDuringAnIterationIsNotConvergedByIt) {
  Model m = sphere_model();
  const auto h = m.hierarchy;
  FeedbackStage stage(std::move(m), std::make_unique<strategies::OptimizationStrategy>(), manual());
  ViewSnapshot v = orbit_view(*h, 0.5f);
  v.version = 1;
  stage.set_view(v);
  stage.set_param("max_nodes", 300);
  for (int i = 0; i < 400 && stage.poll().requested; ++i) stage.step();
  ASSERT_TRUE(stage.counters().converged);
  ASSERT_LE(stage.front().nodes.size(), 300u);
  v.version = 2;  // the same view again: an iteration is requested
  stage.set_view(v);
  ASSERT_TRUE(stage.poll().requested);
  stage.set_param("max_nodes", 2000);
  EXPECT_FALSE(stage.counters().converged) << "at once";
  ASSERT_TRUE(stage.step());  // the iteration requested before, at 300
  stage.poll();
  EXPECT_FALSE(stage.counters().converged) << "its answer is for the old budget";
  for (int i = 0; i < 400 && !stage.counters().converged; ++i) {
    stage.poll();
    stage.step();
  }
  EXPECT_TRUE(stage.counters().converged);
  EXPECT_GT(stage.front().nodes.size(), 1500u);
}

TEST(Strategy, ParamsVersionCountsValueChangesOnly) {
  strategies::OptimizationStrategy s;
  const std::uint64_t v0 = s.params_version();
  s.set_param("max_nodes", s.param("max_nodes"));
  EXPECT_EQ(s.params_version(), v0);
  s.set_param("max_nodes", 123);
  EXPECT_EQ(s.params_version(), v0 + 1);
  EXPECT_THROW(s.set_param("max_nodes", -1), InputError);
  EXPECT_EQ(s.params_version(), v0 + 1) << "a refused value changes nothing";
}

TEST(FeedbackStage, QueriesReachTheRenderThreadAndResultsComeBack) {
  auto probe = std::make_unique<ProbeStrategy>();
  ProbeStrategy* p = probe.get();
  FeedbackStage stage(sphere_model(), std::move(probe), manual());
  stage.poll();
  stage.step();
  const FrameLists f = stage.poll();
  ASSERT_EQ(f.current.queries.size(), 1u);
  const QueryRequest q = f.current.queries[0];
  const VisibilityResult r{q.object, q.node, q.tag, 17, 3};
  stage.post_visibility(std::span(&r, 1));
  stage.step();  // requested before the result was posted
  EXPECT_TRUE(p->seen.empty());
  stage.poll();
  stage.step();
  ASSERT_EQ(p->seen.size(), 1u);
  EXPECT_EQ(p->seen[0].node, q.node);
  EXPECT_EQ(p->seen[0].samples_passed, 17u);
  stage.poll();
  stage.step();
  EXPECT_EQ(p->seen.size(), 1u) << "a result is delivered once";
}

TEST(FeedbackStage, AReplacedListIsFreeAtOnce) {
  // The renderer copies a list in the frame of its exchange, so with two
  // buffers (front + back) the stage is asked again in the frame after every
  // exchange: no frame waits for a free buffer.
  FeedbackStage stage(sphere_model(), std::make_unique<test::RandomWalkStrategy>(), manual(2));
  for (int i = 0; i < 20; ++i) {
    const FrameLists f = stage.poll();
    EXPECT_TRUE(f.requested) << "frame " << i;
    if (i > 0) {
      EXPECT_TRUE(f.exchanged) << "frame " << i;
    }
    stage.step();
  }
  EXPECT_EQ(stage.counters().no_free_buffer, 0u);
  EXPECT_EQ(stage.counters().exchanges, 19u);
}

TEST(FeedbackStage, ListsKeepTheirContentWhileCurrentOrFading) {
  // What a renderer may rely on: the current list until the next exchange,
  // the fading previous one until its fade ends, whatever the stage writes
  // meanwhile (two buffers besides them: the stage always has one to write).
  for (const unsigned blend : {0u, 2u}) {
    FeedbackStage stage(sphere_model(), std::make_unique<test::RandomWalkStrategy>(),
                        manual(4, blend));
    struct Held {
      FrontList list;
      std::vector<NodeId> copy;
    };
    std::vector<Held> held;
    for (int i = 0; i < 300; ++i) {
      const FrameLists f = stage.poll();
      held.clear();
      held.push_back({f.current, {f.current.nodes.begin(), f.current.nodes.end()}});
      if (!f.previous.nodes.empty()) {
        held.push_back({f.previous, {f.previous.nodes.begin(), f.previous.nodes.end()}});
      }
      stage.step();  // the stage writes a back list while this frame draws
      for (const Held& g : held) {
        ASSERT_EQ(std::vector<NodeId>(g.list.nodes.begin(), g.list.nodes.end()), g.copy)
            << "generation " << g.list.generation << " was overwritten while drawn";
      }
    }
    EXPECT_GT(stage.counters().exchanges, blend > 0 ? 90u : 250u);
  }
}

TEST(FeedbackStage, BlendingKeepsThePreviousListWithRisingWeight) {
  FeedbackStage stage(sphere_model(), std::make_unique<test::RandomWalkStrategy>(), manual(4, 3));
  stage.poll();
  stage.step();
  FrameLists f = stage.poll();
  ASSERT_TRUE(f.exchanged);
  EXPECT_EQ(f.previous.generation, 1u);
  float last = f.blend;
  EXPECT_GT(last, 0.0f);
  EXPECT_LT(last, 1.0f);
  for (int i = 0; i < 2; ++i) {
    f = stage.poll();  // no step: nothing new to exchange
    EXPECT_EQ(f.previous.generation, 1u);
    EXPECT_GT(f.blend, last);
    last = f.blend;
  }
  f = stage.poll();
  EXPECT_TRUE(f.previous.nodes.empty());
  EXPECT_EQ(f.blend, 1.0f);
}

TEST(FeedbackStage, AStrategyExceptionReachesTheRenderThreadAndTheStageGoesOn) {
  auto probe = std::make_unique<ProbeStrategy>();
  probe->throw_next = true;
  FeedbackStage stage(sphere_model(), std::move(probe), manual());
  stage.poll();
  stage.step();
  EXPECT_THROW(stage.poll(), std::runtime_error);
  EXPECT_EQ(stage.front().generation, 1u);
  EXPECT_TRUE(stage.poll().requested);
  stage.step();
  EXPECT_TRUE(stage.poll().exchanged);
}

// Misbehaving strategies (points 2 and 3 of issue 9): what they hand back is
// checked, and whatever they throw becomes a StrategyError naming them.
class MisbehavingStrategy final : public Strategy {
 public:
  enum class Fault {
    None,
    ThrowInt,
    ThrowString,
    MissingNode,
    EmptyEvolveCut,
    Duplicate,
  };
  MisbehavingStrategy(Fault fault, Mode mode) : Strategy({}), fault_(fault), mode_(mode) {}
  [[nodiscard]] std::string_view name() const override { return "misbehaving"; }
  [[nodiscard]] Mode mode() const override { return mode_; }
  void reset(const Hierarchy&) override {}
  void iterate(const IterationInput& in, IterationOutput& out) override {
    const Hierarchy& h = in.hierarchy;
    const Fault f = std::exchange(fault_, Fault::None);  // misbehaves once
    if (f == Fault::ThrowInt) throw 42;
    if (f == Fault::ThrowString) throw std::string("not an exception class");
    if (f == Fault::EmptyEvolveCut) {
      *out.cut = TreeCut();
      return;
    }
    // Otherwise: the cut at depth 2 (evolving or rebuilt), maybe spoilt.
    std::vector<NodeId> level;
    for (NodeId n = h.level_begin(2); n < h.level_begin(3); ++n) level.push_back(n);
    if (f == Fault::MissingNode) level.pop_back();
    if (f == Fault::Duplicate) {
      // Same point total, but one node twice and another missing: only the
      // full check (TreeCut::validate) sees it.
      const auto& pc = h.arrays().point_count;
      for (std::size_t i = 0; i < level.size(); ++i) {
        for (std::size_t j = i + 1; j < level.size(); ++j) {
          if (pc[level[i]] == pc[level[j]]) {
            level[j] = level[i];
            i = j = level.size();
          }
        }
      }
    }
    if (mode_ == Mode::Rebuild) {
      *out.nodes = level;
    } else {
      *out.cut = TreeCut::from_nodes(h, level);
    }
    out.result.converged = true;
  }

 private:
  Fault fault_;
  Mode mode_;
};

std::string poll_error(FeedbackStage& stage) {
  try {
    stage.poll();
  } catch (const StrategyError& e) {
    return e.what();
  }
  return "no StrategyError";
}

// The stage goes on after a rejected iteration: the next poll requests, and
// the list the iteration after it returns is exchanged and valid.
void expect_next_iteration_exchanged(FeedbackStage& stage) {
  ASSERT_TRUE(stage.poll().requested);
  stage.step();
  const FrameLists f = stage.poll();
  EXPECT_TRUE(f.exchanged);
  EXPECT_EQ(TreeCut::validate(*f.current.hierarchy, f.current.nodes), "");
}

TEST(FeedbackStage, AnExceptionOfAnyTypeBecomesAStrategyErrorNamingTheStrategy) {
  using F = MisbehavingStrategy::Fault;
  for (const F fault : {F::ThrowInt, F::ThrowString}) {
    auto bad = std::make_unique<MisbehavingStrategy>(fault, Strategy::Mode::Rebuild);
    bad->set_origin("/plugins/libbad.so");
    FeedbackStage stage(sphere_model(), std::move(bad), manual());
    stage.poll();
    stage.step();
    const std::string m = poll_error(stage);
    EXPECT_EQ(m.rfind("strategy 'misbehaving' (plugin /plugins/libbad.so): threw", 0), 0u) << m;
    EXPECT_NE(m.find(fault == F::ThrowInt ? "of type int" : "std::"), std::string::npos) << m;
    EXPECT_EQ(stage.counters().errors, 1u);
    EXPECT_EQ(stage.counters().last_error, m);
    EXPECT_EQ(stage.front().generation, 1u) << "the previous list stays";
    // The stage goes on: the next iteration behaves and is exchanged.
    expect_next_iteration_exchanged(stage);
  }
}

TEST(FeedbackStage, ARebuildListMissingANodeIsRejectedAndThePreviousListStays) {
  auto bad = std::make_unique<MisbehavingStrategy>(MisbehavingStrategy::Fault::MissingNode,
                                                   Strategy::Mode::Rebuild);
  bad->set_origin("built-in");
  FeedbackStage stage(sphere_model(), std::move(bad), manual());
  const std::vector<NodeId> before(stage.front().nodes.begin(), stage.front().nodes.end());
  stage.poll();
  stage.step();
  const std::string m = poll_error(stage);
  EXPECT_EQ(
      m.rfind("strategy 'misbehaving' (built-in): returned an invalid cut: its nodes hold", 0), 0u)
      << m;
  EXPECT_EQ(stage.counters().invalid_cuts, 1u);
  EXPECT_EQ(stage.counters().exchanges, 0u);
  EXPECT_EQ(std::vector<NodeId>(stage.front().nodes.begin(), stage.front().nodes.end()), before);
  // The strategy behaves from now on: the next poll requests, the cut after it is shown.
  expect_next_iteration_exchanged(stage);
}

TEST(FeedbackStage, AnEmptyCutFromAnEvolveStrategyIsRejectedAndTheNextStartsFromTheFront) {
  FeedbackStage stage(sphere_model(),
                      std::make_unique<MisbehavingStrategy>(
                          MisbehavingStrategy::Fault::EmptyEvolveCut, Strategy::Mode::Evolve),
                      manual());
  stage.poll();
  stage.step();
  const std::string m = poll_error(stage);
  EXPECT_NE(m.find("strategy 'misbehaving': returned an invalid cut: the cut is empty"),
            std::string::npos)
      << m;
  EXPECT_EQ(stage.front().nodes.size(), 1u) << "the root, the initial cut";
  EXPECT_EQ(stage.counters().invalid_cuts, 1u);
  expect_next_iteration_exchanged(stage);
}

TEST(FeedbackStage, TheFullCheckCatchesADuplicateWithTheRightPointTotal) {
  StageOptions o = manual();
  o.validate = true;
  FeedbackStage stage(sphere_model(),
                      std::make_unique<MisbehavingStrategy>(MisbehavingStrategy::Fault::Duplicate,
                                                            Strategy::Mode::Rebuild),
                      o);
  stage.poll();
  stage.step();
  const std::string m = poll_error(stage);
  EXPECT_NE(m.find("returned an invalid cut: node "), std::string::npos) << m;
  EXPECT_NE(m.find("listed twice"), std::string::npos) << m;
}

TEST(FeedbackStage, SwitchingToARecursiveStrategyAndBackKeepsTheCutValid) {
  Model m = sphere_model();
  const auto h = m.hierarchy;
  FeedbackStage stage(std::move(m), std::make_unique<strategies::OptimizationStrategy>(), manual());
  ViewSnapshot v = orbit_view(*h, 0.5f);
  v.version = 1;
  stage.set_view(v);
  for (int round = 0; round < 3; ++round) {
    for (int i = 0; i < 5; ++i) {
      const FrameLists f = stage.poll();
      ASSERT_EQ(TreeCut::validate(*h, f.current.nodes), "");
      ASSERT_TRUE(std::is_sorted(f.current.nodes.begin(), f.current.nodes.end()))
          << "published lists are in ascending id order";
      stage.step();
    }
    stage.set_strategy(std::make_unique<strategies::RecursiveStrategy>());
    EXPECT_EQ(stage.strategy_name(), "recursive");
    for (int i = 0; i < 5; ++i) {
      ASSERT_EQ(TreeCut::validate(*h, stage.poll().current.nodes), "");
      stage.step();
    }
    stage.set_strategy(std::make_unique<strategies::OptimizationStrategy>());
  }
}

TEST(FeedbackStage, ANewModelResetsTheStrategy) {
  auto probe = std::make_unique<ProbeStrategy>();
  ProbeStrategy* p = probe.get();
  FeedbackStage stage(sphere_model(), std::move(probe), manual());
  EXPECT_EQ(p->resets, 1);
  auto terrain = small_hierarchy(tools::ModelKind::Terrain, 3000);
  stage.set_model(Model{terrain, TreeCut::root_cut(*terrain)});
  stage.poll();
  stage.step();
  EXPECT_EQ(p->resets, 2);
  const FrameLists f = stage.poll();
  EXPECT_EQ(f.current.hierarchy, terrain.get());
  EXPECT_EQ(TreeCut::validate(*terrain, f.current.nodes), "");
}

TEST(FeedbackStage, RejectsBadConstruction) {
  Model m = sphere_model();
  EXPECT_THROW(FeedbackStage(Model{}, std::make_unique<ProbeStrategy>(), manual()),
               std::invalid_argument);
  EXPECT_THROW(FeedbackStage(sphere_model(), nullptr, manual()), std::invalid_argument);
  EXPECT_THROW(FeedbackStage(sphere_model(), std::make_unique<ProbeStrategy>(), manual(1)),
               std::invalid_argument);
  EXPECT_THROW(
      FeedbackStage(Model{m.hierarchy, TreeCut()}, std::make_unique<ProbeStrategy>(), manual()),
      std::invalid_argument)
      << "an empty cut covers no leaf";
}

TEST(Controller, VersionsTheViewOnlyWhenTheCameraMoves) {
  Model m = sphere_model();
  const auto h = m.hierarchy;
  const ViewSnapshot v = orbit_view(*h, 0.0f);
  Controller c(std::move(m), std::make_unique<strategies::OptimizationStrategy>(), v, manual());
  const std::uint64_t v0 = c.view().version;
  c.set_camera(v.view, v.projection, v.viewport);
  EXPECT_EQ(c.view().version, v0);
  const ViewSnapshot w = orbit_view(*h, 1.0f);
  c.set_camera(w.view, w.projection, w.viewport);
  EXPECT_EQ(c.view().version, v0 + 1);
  EXPECT_NEAR(glm::length(c.view().derived.eye - w.derived.eye), 0.0f, 1e-4f);
  c.set_light(glm::vec3(0, 1, 0));
  EXPECT_EQ(c.view().version, v0 + 2);
  EXPECT_TRUE(c.begin_frame().requested);
  c.stage().step();
  EXPECT_TRUE(c.begin_frame().exchanged);
}

TEST(ViewSnapshot, FrustumProjectionAndBackfacing) {
  const ViewSnapshot v =
      ViewSnapshot::look_at({0, 0, 10}, {0, 0, 0}, {1000, 1000}, 0.8f, 0.1f, 100.0f);
  EXPECT_FALSE(v.outside_frustum({0, 0, 0}, 0.1f));
  EXPECT_TRUE(v.outside_frustum({0, 0, 20}, 1.0f)) << "behind the camera";
  EXPECT_TRUE(v.outside_frustum({100, 0, 0}, 1.0f));
  EXPECT_FALSE(v.outside_frustum({0, 0, -95}, 10.0f)) << "straddles the far plane";
  // tan(0.4) * 10 is half the screen height (500 px) at distance 10.
  const float px = v.projected_radius_px({0, 0, 0}, 0.1f);
  EXPECT_NEAR(px, 0.1f / (10.0f - 0.1f) * 500.0f / std::tan(0.4f), 0.01f);
  EXPECT_LT(v.projected_radius_px({0, 0, -10}, 0.1f), px);
  EXPECT_TRUE(v.backfacing({0, 0, 0}, 0.1f, {0, 0, -1}, 1.0f));
  EXPECT_FALSE(v.backfacing({0, 0, 0}, 0.1f, {0, 0, 1}, 1.0f));
  EXPECT_FALSE(v.backfacing({0, 0, 0}, 0.1f, {0, 0, -1}, 0.0f)) << "a half-space cone";
  EXPECT_FALSE(v.backfacing({-3, 0, 0}, 0.1f, {1, 0, 0}, 0.99f));
  EXPECT_TRUE(v.backfacing({3, 0, 0}, 0.1f, {1, 0, 0}, 0.99f));
}

// Keeps a copy of the snapshot of every iteration.
class SnapshotRecorder final : public Strategy {
 public:
  SnapshotRecorder() : Strategy({}) {}
  [[nodiscard]] std::string_view name() const override { return "recorder"; }
  [[nodiscard]] Mode mode() const override { return Mode::Evolve; }
  void reset(const Hierarchy&) override {}
  void iterate(const IterationInput& in, IterationOutput& out) override {
    views.push_back(in.view);
    out.result.converged = true;
  }
  std::vector<ViewSnapshot> views;
};

TEST(FeedbackStage, SetViewHandsTheSnapshotOverWholeOnTheStagesFrameCounter) {
  auto rec = std::make_unique<SnapshotRecorder>();
  SnapshotRecorder* r = rec.get();
  FeedbackStage stage(sphere_model(), std::move(rec), manual());
  ViewSnapshot v = orbit_view(*sphere_model().hierarchy, 0.7f, 1.3f);
  v.viewport = {321, 123};
  v.light_dir = {0.0f, 1.0f, 0.0f};
  v.version = 42;
  v.frame = 999;  // the stage numbers frames itself
  v.finalize();
  v.visibility = {{0, 1, 7, 5, 1, 2, QueryKind::Samples}};
  stage.set_view(v);
  ViewSnapshot w = v;
  w.visibility = {{0, 2, 8, 0, 2, 3, QueryKind::AnySamples}};
  stage.set_view(w);  // the same view again: its results are appended, not replacing
  stage.post_visibility(std::vector<VisibilityResult>{{0, 3, 9, 1, 3, 4, QueryKind::Samples}});
  (void)stage.poll();
  (void)stage.poll();  // Process: no request, but the frame counts
  ASSERT_TRUE(stage.step());
  ASSERT_EQ(r->views.size(), 1u);
  const ViewSnapshot& got = r->views[0];
  EXPECT_EQ(got.view, v.view);
  EXPECT_EQ(got.projection, v.projection);
  EXPECT_EQ(got.viewport, v.viewport);
  EXPECT_EQ(got.light_dir, v.light_dir);
  EXPECT_EQ(got.version, 42u);
  EXPECT_EQ(got.derived.eye, v.derived.eye);
  EXPECT_EQ(got.derived.pixel_scale, v.derived.pixel_scale);
  EXPECT_EQ(got.frame, 1u);  // the frame of the request, the stage's counter
  EXPECT_EQ(stage.frame(), 2u);
  ASSERT_EQ(got.visibility.size(), 3u);
  EXPECT_EQ(got.visibility[0].tag, 7u);
  EXPECT_EQ(got.visibility[1].tag, 8u);
  EXPECT_EQ(got.visibility[1].kind, QueryKind::AnySamples);
  EXPECT_EQ(got.visibility[2].tag, 9u);
  EXPECT_EQ(got.visibility[2].frame_read, 4u);
}

TEST(Controller, CountsFramesWithTheStagesCounter) {
  auto h = test::small_hierarchy(tools::ModelKind::Sphere, 5000);
  ViewSnapshot v = orbit_view(*h, 0.6f, 1.2f);
  v.frame = 500;  // an initial view's own number does not start a second count
  Controller c(Model{h, TreeCut::root_cut(*h)}, std::make_unique<SnapshotRecorder>(), v, manual());
  for (std::uint64_t i = 1; i <= 5; ++i) {
    (void)c.begin_frame();
    EXPECT_EQ(c.frame(), i);
    EXPECT_EQ(c.view().frame, i);
    EXPECT_EQ(c.stage().frame(), i);
    c.stage().step();
  }
}

}  // namespace
}  // namespace treecut
