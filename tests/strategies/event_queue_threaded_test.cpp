// event_queue run by a Feedback Stage on its own thread (the real set-up, and
// the TSan configuration's view of the strategy): after every iteration the
// published list equals the top-down cut of the view it was computed for,
// across a strategy switch from topdown and a parameter change travelling
// through the stage.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <glm/geometric.hpp>
#include <memory>
#include <thread>
#include <vector>

#include "strategy_fixtures.hpp"
#include "treecut/feedback_stage.hpp"
#include "treecut/model.hpp"
#include "treecut/strategies/event_queue.hpp"
#include "treecut/strategies/topdown.hpp"

namespace treecut {
namespace {

// The reference: topdown driven directly on this thread.
std::vector<NodeId> topdown_cut(strategies::TopDownStrategy& s, const Hierarchy& h, TreeCut& cut,
                                const ViewSnapshot& view) {
  test::iterate_once(s, h, cut, view);
  std::vector<NodeId> v(cut.nodes().begin(), cut.nodes().end());
  std::sort(v.begin(), v.end());
  return v;
}

// Hands `view` to the stage and returns the list of the iteration it caused.
std::vector<NodeId> stage_cut(FeedbackStage& stage, const ViewSnapshot& view) {
  stage.set_view(view);
  while (!stage.poll().requested) std::this_thread::yield();
  while (!stage.poll().exchanged) std::this_thread::yield();
  const FrontList& f = stage.front();
  return {f.nodes.begin(), f.nodes.end()};
}

TEST(EventQueueThreaded, event_queue_exact_vs_topdown_on_the_stage_thread) {
  const auto h = test::small_hierarchy(tools::ModelKind::Terrain, 30000);
  const glm::vec3 center = 0.5f * (h->bounds_min() + h->bounds_max());
  const float extent = glm::length(h->bounds_max() - h->bounds_min());
  FeedbackStage stage(Model{h, TreeCut::root_cut(*h)},
                      std::make_unique<strategies::TopDownStrategy>());
  strategies::TopDownStrategy reference;
  reference.reset(*h);
  TreeCut reference_cut = TreeCut::root_cut(*h);
  std::size_t largest = 0;
  for (int i = 0; i < 90; ++i) {
    if (i == 10) stage.set_strategy(std::make_unique<strategies::EventQueueStrategy>());
    if (i == 50) {
      stage.set_param("theta", 2.5);
      reference.set_param("theta", 2.5);
    }
    // Slow, then fast, then a jump to the other side.
    const float a =
        i < 40 ? 0.002f * float(i) : (i < 70 ? 0.08f * float(i) : 3.0f + 0.01f * float(i));
    const glm::vec3 eye =
        center + (0.6f + 0.003f * float(i)) * extent * glm::vec3(std::cos(a), 0.3f, std::sin(a));
    ViewSnapshot v =
        ViewSnapshot::look_at(eye, center, {640, 480}, 0.8f, 0.001f * extent, 20.0f * extent);
    v.version = std::uint64_t(i) + 1;
    const std::vector<NodeId> got = stage_cut(stage, v);
    const std::vector<NodeId> want = topdown_cut(reference, *h, reference_cut, v);
    ASSERT_EQ(got, want) << "iteration " << i << " (" << stage.strategy_name()
                         << "): " << got.size() << " nodes, topdown " << want.size();
    ASSERT_EQ(TreeCut::validate(*h, got), "");
    largest = std::max(largest, got.size());
  }
  EXPECT_EQ(stage.strategy_name(), "event_queue");
  EXPECT_GT(largest, 2000u);
}

}  // namespace
}  // namespace treecut
