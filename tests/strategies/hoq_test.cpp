// HOQ-coherent HLOD refinement (strategies/include/treecut/strategies/hoq.hpp,
// Charalambos et al. 2007): the sigmoid bias, the block SSE, the proxy's
// analytic pixels, the three outcomes of PredictRefinement (figure 3), and the
// `hoq` strategy driven directly with query answers that arrive frames late,
// as the View's executor delivers them.
#include "treecut/strategies/hoq.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <deque>
#include <functional>
#include <random>
#include <vector>

#include "strategy_fixtures.hpp"
#include "treecut/feedback_stage.hpp"
#include "treecut/tree_cut.hpp"

namespace {

using treecut::Hierarchy;
using treecut::IterationInput;
using treecut::IterationOutput;
using treecut::NodeId;
using treecut::QueryRequest;
using treecut::TreeCut;
using treecut::ViewSnapshot;
using treecut::VisibilityResult;
using treecut::culling::BlockId;
using treecut::culling::HlodBlocks;
using treecut::strategies::HoqStrategy;
using treecut::tools::ModelKind;
namespace hoq = treecut::culling::hoq;
using hoq::ChildState;
using hoq::NodeState;
using hoq::Prediction;

// ---------------------------------------------------------------- the bias

TEST(HoqBias, SmoothnessZeroGivesMu) {
  for (float t : {0.0f, 0.1f, 0.5f, 0.9f, 1.0f})
    for (int i = 0; i <= 20; ++i) {
      const float mu = float(i) / 20.0f;
      EXPECT_FLOAT_EQ(hoq::sigmoid_bias(mu, 0.0f, t), mu) << "mu " << mu << " t " << t;
    }
}

TEST(HoqBias, FullVisibilityGivesOneAndNoneGivesZero) {
  for (float s : {0.0f, 0.3f, 1.0f})
    for (float t : {0.0f, 0.2f, 0.5f, 1.0f}) {
      EXPECT_EQ(hoq::sigmoid_bias(1.0f, s, t), 1.0f) << "s " << s << " t " << t;
      EXPECT_EQ(hoq::sigmoid_bias(0.0f, s, t), 0.0f) << "s " << s << " t " << t;
    }
}

TEST(HoqBias, IsMonotoneAggressiveBelowTheTurnOverAndConservativeAbove) {
  for (float s : {0.25f, 0.5f, 1.0f})
    for (float t : {0.1f, 0.5f, 0.8f}) {
      float previous = -1.0f;
      for (int i = 0; i <= 1000; ++i) {
        const float mu = float(i) / 1000.0f;
        const float b = hoq::sigmoid_bias(mu, s, t);
        EXPECT_GE(b, previous) << "mu " << mu << " s " << s << " t " << t;
        EXPECT_GE(b, 0.0f);
        EXPECT_LE(b, 1.0f);
        if (mu > 0.0f && mu < t) {
          EXPECT_LT(b, mu) << "mu " << mu << " t " << t;
        }
        if (mu > t && mu < 1.0f) {
          EXPECT_GT(b, mu) << "mu " << mu << " t " << t;
        }
        previous = b;
      }
    }
  // A turn-over closer to 0 modulates less (the paper: more conservative).
  EXPECT_GT(hoq::sigmoid_bias(0.3f, 1.0f, 0.1f), hoq::sigmoid_bias(0.3f, 1.0f, 0.6f));
  EXPECT_FLOAT_EQ(hoq::vmsse(0.25f, 8.0f), 2.0f);
}

// ------------------------------------------------------- PredictRefinement

constexpr float kTau = 1.0f;

TEST(HoqPredict, StopWhenTheCachedBiasKeepsTheVmsseBelowTau) {
  const NodeState stopped{true, true, true, 0.1f};
  EXPECT_EQ(hoq::predict_refinement(stopped, 9.0f, {}, kTau), Prediction::Stop);   // 0.9 <= 1
  EXPECT_EQ(hoq::predict_refinement(stopped, 10.0f, {}, kTau), Prediction::Stop);  // 1.0 <= 1
}

TEST(HoqPredict, RefineWhenTheEstimateOfAStoppedNodeExceedsTauOrAChildNeedsMore) {
  const NodeState stopped{true, true, true, 0.1f};
  EXPECT_EQ(hoq::predict_refinement(stopped, 10.5f, {}, kTau), Prediction::Refine);
  // Refined last frame, one child refined too: no candidate to shift up.
  const NodeState refined{true, true, false, 1.0f};
  const ChildState children_a[] = {{true, 0.5f, 1.0f}, {false, 0.5f, 1.0f}};
  EXPECT_EQ(hoq::predict_refinement(refined, 1.5f, children_a, kTau), Prediction::Refine);
  // Every child stopped, but one child's own estimate exceeds tau.
  const ChildState children_b[] = {{true, 0.5f, 1.0f}, {true, 0.5f, 3.0f}};
  EXPECT_EQ(hoq::predict_refinement(refined, 1.5f, children_b, kTau), Prediction::Refine);
  // Every child would stop, but AvgBias * SSE(node) = 0.5 * 4 > tau.
  const ChildState children_c[] = {{true, 0.5f, 1.0f}, {true, 0.5f, 1.0f}};
  EXPECT_FLOAT_EQ(hoq::average_bias(children_c), 0.5f);
  EXPECT_EQ(hoq::predict_refinement(refined, 4.0f, children_c, kTau), Prediction::Refine);
}

TEST(HoqPredict, DelayForUnvisitedInvisibleAndShiftUpCandidates) {
  // Not visited in the last frame: nothing cached holds.
  EXPECT_EQ(hoq::predict_refinement({false, true, true, 0.0f}, 0.5f, {}, kTau), Prediction::Delay);
  // Invisible in the last frame.
  EXPECT_EQ(hoq::predict_refinement({true, false, true, 0.0f}, 0.5f, {}, kTau), Prediction::Delay);
  // Refined, every child stopped with its estimate <= tau, and AvgBias *
  // SSE(node) = (0.2 + 0.4) / 2 * 3 = 0.9 <= tau: the front may move up.
  const ChildState children[] = {{true, 0.2f, 2.0f}, {true, 0.4f, 2.5f}};
  EXPECT_FLOAT_EQ(hoq::average_bias(children), 0.3f);
  EXPECT_EQ(hoq::predict_refinement({true, true, false, 1.0f}, 3.0f, children, kTau),
            Prediction::Delay);
}

// ------------------------------------------------- SSE and the proxy pixels

TEST(HoqSse, NoSplatOfARepresentationProjectsLargerThanItsBlockSse) {
  const auto h = treecut::test::small_hierarchy(ModelKind::City, 20000);
  const HlodBlocks blocks = HlodBlocks::build(*h, 200);
  const auto& a = h->arrays();
  std::mt19937 rng(3);
  for (int v = 0; v < 6; ++v) {
    const ViewSnapshot view =
        treecut::test::orbit_view(*h, 1.1f * float(v), 0.15f + 0.3f * float(v));
    for (BlockId b = 0; b < blocks.block_count(); ++b) {
      if (blocks.is_leaf(b)) continue;
      float radius = 0.0f;
      for (NodeId n : blocks.representation(b)) radius = std::max(radius, a.center_radius[n].w);
      const float sse = hoq::block_sse(view, blocks.box(b), radius);
      for (NodeId n : blocks.representation(b)) {
        const glm::vec4 s = a.center_radius[n];
        ASSERT_LE(view.projected_radius_px(glm::vec3(s), s.w), sse * 1.0001f + 1e-4f)
            << "block " << b << " node " << n;
      }
    }
  }
  EXPECT_EQ(hoq::block_sse(treecut::test::orbit_view(*h, 0.0f), blocks.box(0), 0.0f), 0.0f);
}

TEST(HoqProxy, PixelsOfACentredSphereOffViewAndBehindTheEye) {
  const ViewSnapshot view =
      ViewSnapshot::look_at({0, 0, 10}, {0, 0, 0}, {400, 300}, 0.8f, 0.1f, 100.0f);
  const treecut::ViewSnapshot& cam = view;
  // Straight ahead at distance 10, radius 1: the tangent half-width is
  // f * r / sqrt(d^2 - r^2) pixels, f = 150 / tan(0.4); 1/8 pixel more on
  // each side; a square sprite of that side.
  const double f = 150.0 / std::tan(0.4);
  const double side = 2.0 * f / std::sqrt(99.0) + 0.25;
  EXPECT_NEAR(hoq::proxy_pixels(cam, {0, 0, 0}, 1.0f), side * side, 0.01 * side * side);
  // Off to the side, outside the view: no pixel.
  EXPECT_EQ(hoq::proxy_pixels(cam, {100, 0, 0}, 1.0f), 0.0);
  // Half off the left edge: the sprite is clipped, fewer pixels.
  const double edge = hoq::proxy_pixels(cam, {-5.6f, 0, 0}, 1.0f);
  EXPECT_GT(edge, 0.0);
  EXPECT_LT(edge, side * side);
  // The eye inside or behind: no analytic count.
  EXPECT_LT(hoq::proxy_pixels(cam, {0, 0, 10}, 1.0f), 0.0);
  EXPECT_LT(hoq::proxy_pixels(cam, {0, 0, 20}, 1.0f), 0.0);
  // mu: 0 without a sample, clamped to 1, 1 without an analytic count.
  EXPECT_EQ(hoq::relative_visibility(0, 100.0), 0.0f);
  EXPECT_FLOAT_EQ(hoq::relative_visibility(25, 100.0), 0.25f);
  EXPECT_EQ(hoq::relative_visibility(150, 100.0), 1.0f);
  EXPECT_EQ(hoq::relative_visibility(3, -1.0), 1.0f);
}

// ------------------------------------------------------- the strategy

// The View's executor, simulated: a request posted by the iteration of frame
// F is drawn in frame F + 1 and read `latency` frames later; its samples
// are the proxy's analytic pixels times what `visible_fraction` says of its
// node (the scene's occlusion, made up by the test).
class FakeExecutor {
 public:
  FakeExecutor(const Hierarchy& h, std::function<float(NodeId)> visible_fraction)
      : h_(h), fraction_(std::move(visible_fraction)) {}

  void post(const std::vector<QueryRequest>& queries, std::uint64_t frame, const ViewSnapshot& view,
            std::uint64_t latency) {
    const treecut::ViewSnapshot& cam = view;
    for (const QueryRequest& q : queries) {
      const glm::vec4 s = h_.arrays().center_radius[q.node];
      const double pixels = hoq::proxy_pixels(cam, glm::vec3(s), s.w);
      const float f = fraction_(q.node);
      std::uint32_t samples = 0;
      if (f > 0.0f) {
        samples = pixels < 0.0 ? std::uint32_t(view.viewport.x * view.viewport.y)
                               : std::uint32_t(std::max(1.0, std::floor(pixels * f)));
        if (pixels == 0.0) samples = 0;
      }
      VisibilityResult r;
      r.object = q.object;
      r.node = q.node;
      r.tag = q.tag;
      r.samples_passed = samples;
      r.frame_issued = frame + 1;
      r.frame_read = frame + 1 + latency;
      r.kind = q.kind;
      in_flight_.push_back(r);
    }
  }
  // The answers read by frame `frame` and not delivered yet.
  std::vector<VisibilityResult> due(std::uint64_t frame, bool hold = false) {
    std::vector<VisibilityResult> out;
    if (hold) return out;
    std::deque<VisibilityResult> rest;
    for (const VisibilityResult& r : in_flight_) {
      if (r.frame_read <= frame) {
        out.push_back(r);
      } else {
        rest.push_back(r);
      }
    }
    in_flight_.swap(rest);
    return out;
  }

 private:
  const Hierarchy& h_;
  std::function<float(NodeId)> fraction_;
  std::deque<VisibilityResult> in_flight_;
};

struct Step {
  treecut::IterationResult result;
  std::vector<NodeId> nodes;
  std::vector<QueryRequest> queries;
};

Step iterate(HoqStrategy& s, const Hierarchy& h, ViewSnapshot view) {
  Step st;
  TreeCut unused = TreeCut::root_cut(h);
  IterationInput in{h, view, 0, nullptr, s.params_version()};
  IterationOutput out;
  out.cut = &unused;
  out.nodes = &st.nodes;
  out.queries = &st.queries;
  s.iterate(in, out);
  st.result = out.result;
  return st;
}

// The block cut of refinement by SSE alone (every block visible: B = 1):
// what `hoq` must reach under a static camera when every answer is "fully
// visible", frustum culling included.
void sse_cut(const HlodBlocks& b, const Hierarchy& h, const ViewSnapshot& view,
             const std::vector<float>& radius, BlockId id, float tau, std::vector<BlockId>& out) {
  const glm::vec4 s = h.arrays().center_radius[b.root(id)];
  if (b.is_leaf(id) || view.outside_frustum(glm::vec3(s), s.w) ||
      hoq::block_sse(view, b.box(id), radius[id]) <= tau) {
    out.push_back(id);
    return;
  }
  for (BlockId c = b.first_child(id); c < b.first_child(id) + b.child_count(id); ++c)
    sse_cut(b, h, view, radius, c, tau, out);
}

std::vector<float> error_radii(const HlodBlocks& b, const Hierarchy& h) {
  std::vector<float> r(b.block_count(), 0.0f);
  for (BlockId i = 0; i < b.block_count(); ++i) {
    if (b.is_leaf(i)) continue;
    for (NodeId n : b.representation(i)) r[i] = std::max(r[i], h.arrays().center_radius[n].w);
  }
  return r;
}

// The ids of a block cut named by the blocks' nodes (HoqStrategy::block_cut).
std::vector<BlockId> ids(const HlodBlocks& b, std::span<const NodeId> cut) {
  std::vector<BlockId> out;
  for (const NodeId n : cut) out.push_back(b.block_of_root(n));
  return out;
}

using treecut::test::street_view;

class HoqStrategyTest : public ::testing::Test {
 protected:
  void SetUp() override {
    h = treecut::test::small_hierarchy(ModelKind::City, 20000);
    s.set_param("block_size", 200);
    s.set_param("theta", 2.0);
    s.reset(*h);
    blocks = HlodBlocks::build(*h, 200, treecut::culling::kHierarchyFanOut);
  }
  std::shared_ptr<const Hierarchy> h;
  HoqStrategy s;
  // The blocks `hoq` makes as it goes, built at once (the same, node for node).
  HlodBlocks blocks;
};

TEST_F(HoqStrategyTest, CutIsValidEveryIterationWithLateAnswersOnAMovingCamera) {
  // Blocks whose root lies in the western half are hidden, the rest half visible.
  const float mid = 0.5f * (h->bounds_min().x + h->bounds_max().x);
  FakeExecutor gpu(*h,
                   [&](NodeId n) { return h->arrays().center_radius[n].x < mid ? 0.0f : 0.5f; });
  std::mt19937 rng(11);
  std::uint64_t answered = 0, delayed = 0, refined = 0;
  for (std::uint64_t frame = 1; frame <= 120; ++frame) {
    ViewSnapshot view = street_view(*h, float(frame) / 60.0f);
    view.frame = frame;
    view.version = frame;
    view.visibility = gpu.due(frame);
    Step st = iterate(s, *h, view);
    const std::string why = TreeCut::validate(*h, [&] {
      std::sort(st.nodes.begin(), st.nodes.end());
      return st.nodes;
    }());
    ASSERT_EQ(why, "") << "frame " << frame;
    ASSERT_EQ(blocks.validate_cut(ids(blocks, s.block_cut())), "") << "frame " << frame;
    // Latency 1 to 4 frames, varying per iteration.
    gpu.post(st.queries, frame, view, 1 + rng() % 4);
    answered += s.last().answers;
    delayed += s.last().delayed;
    refined += s.last().refined;
    EXPECT_EQ(s.last().blocks, s.block_cut().size());
    EXPECT_EQ(s.last().drawn + s.last().culled, s.last().blocks);
  }
  EXPECT_GT(answered, 0u);
  EXPECT_GT(delayed, 0u);
  EXPECT_GT(refined, 0u);
  EXPECT_GT(s.block_cut().size(), 1u);
}

TEST_F(HoqStrategyTest, FullyVisibleAnswersConvergeToTheSseCut) {
  FakeExecutor gpu(*h, [](NodeId) { return 1.0f; });
  const ViewSnapshot fixed = street_view(*h, 0.4f);
  bool converged = false;
  for (std::uint64_t frame = 1; frame <= 200 && !converged; ++frame) {
    ViewSnapshot view = fixed;
    view.frame = frame;
    view.version = 1;
    view.visibility = gpu.due(frame);
    Step st = iterate(s, *h, view);
    gpu.post(st.queries, frame, view, 2);
    converged = st.result.converged;
  }
  ASSERT_TRUE(converged);
  std::vector<BlockId> expected;
  sse_cut(blocks, *h, fixed, error_radii(blocks, *h), 0, 2.0f, expected);
  std::vector<BlockId> got = ids(blocks, s.block_cut());
  std::sort(expected.begin(), expected.end());
  std::sort(got.begin(), got.end());
  EXPECT_EQ(got, expected);
  EXPECT_GT(got.size(), 10u);
  EXPECT_EQ(s.last().culled + s.last().drawn, got.size());
}

TEST_F(HoqStrategyTest, BarelyVisibleBlocksStopEarlyUnderVmsseButNotUnderBool) {
  // 2 % of every proxy unoccluded: B(0.02) = 0.5 * 0.02 + 0.5 * 0.0008 ~ 0.01.
  auto converge = [&](HoqStrategy& strategy) {
    FakeExecutor gpu(*h, [](NodeId) { return 0.02f; });
    const ViewSnapshot fixed = street_view(*h, 0.4f);
    bool converged = false;
    for (std::uint64_t frame = 1; frame <= 300 && !converged; ++frame) {
      ViewSnapshot view = fixed;
      view.frame = frame;
      view.version = 1;
      view.visibility = gpu.due(frame);
      Step st = iterate(strategy, *h, view);
      gpu.post(st.queries, frame, view, 2);
      converged = st.result.converged;
    }
    EXPECT_TRUE(converged);
    return ids(blocks, strategy.block_cut());
  };
  HoqStrategy boolean;
  boolean.set_param("block_size", 200);
  boolean.set_param("theta", 2.0);
  boolean.set_param("bias", 0);
  boolean.reset(*h);
  std::vector<BlockId> got = converge(boolean);
  std::vector<BlockId> expected;
  sse_cut(blocks, *h, street_view(*h, 0.4f), error_radii(blocks, *h), 0, 2.0f, expected);
  std::sort(got.begin(), got.end());
  std::sort(expected.begin(), expected.end());
  EXPECT_EQ(got, expected);                        // Bool: the SSE cut, visibility only culls
  EXPECT_LT(converge(s).size(), expected.size());  // VMSSE: fewer, coarser blocks
}

TEST_F(HoqStrategyTest, OccludedBlocksStayCoarserThanTheSseCut) {
  // Everything hidden.
  FakeExecutor gpu(*h, [](NodeId) { return 0.0f; });
  const ViewSnapshot fixed = street_view(*h, 0.4f);
  for (std::uint64_t frame = 1; frame <= 60; ++frame) {
    ViewSnapshot view = fixed;
    view.frame = frame;
    view.version = 1;
    view.visibility = gpu.due(frame);
    Step st = iterate(s, *h, view);
    gpu.post(st.queries, frame, view, 2);
  }
  std::vector<BlockId> sse;
  sse_cut(blocks, *h, fixed, error_radii(blocks, *h), 0, 2.0f, sse);
  EXPECT_LT(s.block_cut().size(), sse.size());
  // Every answer says invisible: the front moves up (shift-up candidates,
  // AvgBias 0) until the root block is culled, and nothing refines again.
  EXPECT_EQ(s.block_cut().size(), 1u);
  EXPECT_EQ(s.last().culled, 1u);
  EXPECT_EQ(s.last().drawn, 0u);
  EXPECT_EQ(s.last().refined, 0u);
}

TEST_F(HoqStrategyTest, ADelayedBlockKeepsItsStateUntilItsAnswerArrives) {
  FakeExecutor gpu(*h, [](NodeId) { return 1.0f; });
  const ViewSnapshot fixed = street_view(*h, 0.4f);
  auto run = [&](std::uint64_t frame, bool hold) {
    ViewSnapshot view = fixed;
    view.frame = frame;
    view.version = 1;
    view.visibility = gpu.due(frame, hold);
    Step st = iterate(s, *h, view);
    gpu.post(st.queries, frame, view, 1);
    return st;
  };
  // Without assume_visible: the first iteration, the root block enters, is
  // delayed and drawn as it is.
  s.set_param("assume_visible", 0);
  Step first = run(1, false);
  EXPECT_EQ(s.block_cut().size(), 1u);
  EXPECT_EQ(s.last().delayed, 1u);
  EXPECT_EQ(first.queries.size(), 1u);
  // While its answer is held back, nothing changes: the same cut, still delayed.
  for (std::uint64_t f = 2; f <= 6; ++f) {
    run(f, true);
    EXPECT_EQ(s.block_cut().size(), 1u) << f;
    EXPECT_EQ(s.last().delayed, 1u) << f;
  }
  // The answer arrives: the root block's VMSSE exceeds theta, it is refined,
  // drawn too coarse for the frames it waited (late_frames), and its children enter delayed.
  run(7, false);
  EXPECT_EQ(s.last().late_refined, 1u);
  EXPECT_EQ(s.last().late_frames, 7u + 1u - 1u);
  EXPECT_EQ(s.block_cut().size(), blocks.child_count(0));
  EXPECT_GE(s.last().delayed + s.last().culled, 1u);
}

TEST_F(HoqStrategyTest, AStoppedBlockWhoseNewAnswerRaisesItsBiasIsARarn) {
  // Hidden at first: the cut stays coarse, every block invisible.
  float fraction = 0.0f;
  FakeExecutor gpu(*h, [&](NodeId) { return fraction; });
  const ViewSnapshot fixed = street_view(*h, 0.4f);
  std::uint64_t frame = 0;
  auto run = [&] {
    ++frame;
    ViewSnapshot view = fixed;
    view.frame = frame;
    view.version = 1;
    view.visibility = gpu.due(frame);
    Step st = iterate(s, *h, view);
    gpu.post(st.queries, frame, view, 2);
  };
  // Barely visible: the root's children stop at a tiny bias (mu = 1e-4 of
  // their pixels gives B ~ 1e-4: VMSSE <= theta).
  fraction = 1e-6f;
  for (int i = 0; i < 30; ++i) run();
  const std::size_t coarse = s.block_cut().size();
  EXPECT_EQ(s.last().rarn, 0u);
  // Then fully visible: the next answers show VMSSE > theta for blocks the
  // prediction stopped: RARN, each drawn too coarse for >= its latency.
  fraction = 1.0f;
  std::uint64_t rarn = 0, rarn_frames = 0;
  for (int i = 0; i < 40; ++i) {
    run();
    rarn += s.last().rarn;
    rarn_frames += s.last().rarn_frames;
  }
  EXPECT_GT(rarn, 0u);
  EXPECT_GE(rarn_frames, rarn * 2u);  // issued at F + 1, read 2 frames later
  EXPECT_GT(s.block_cut().size(), coarse);
}

TEST_F(HoqStrategyTest, AssumingVisibleTheFirstIterationIsTheSseCutWithEveryBlockDelayed) {
  const ViewSnapshot view = street_view(*h, 0.4f);
  Step st = iterate(s, *h, view);
  std::vector<BlockId> expected;
  sse_cut(blocks, *h, view, error_radii(blocks, *h), 0, 2.0f, expected);
  std::vector<BlockId> got = ids(blocks, s.block_cut());
  std::sort(expected.begin(), expected.end());
  std::sort(got.begin(), got.end());
  EXPECT_EQ(got, expected);
  // Every block in view is queried; those that could still refine (not leaf
  // blocks) wait for their first answer: delayed.
  std::uint64_t drawn_interior = 0, drawn = 0;
  for (BlockId b : got) {
    const glm::vec4 sp = h->arrays().center_radius[blocks.root(b)];
    if (view.outside_frustum(glm::vec3(sp), sp.w)) continue;
    ++drawn;
    if (!blocks.is_leaf(b)) ++drawn_interior;
  }
  EXPECT_EQ(s.last().drawn, drawn);
  EXPECT_EQ(s.last().delayed, drawn_interior);
  EXPECT_EQ(st.queries.size(), drawn);
}

TEST(HoqStage, AnswersPostedToTheStageReachTheStrategyAndEveryListIsValid) {
  // The Feedback Stage driven synchronously, the test as the render thread:
  // each new list's queries are answered one frame after it is first drawn
  // (western half hidden), through post_visibility, as the executor does.
  const auto h = treecut::test::small_hierarchy(ModelKind::City, 20000);
  auto owned = std::make_unique<HoqStrategy>();
  owned->set_param("block_size", 200);
  owned->set_param("theta", 2.0);
  const HoqStrategy* hoq_strategy = owned.get();
  treecut::StageOptions options;
  options.launch = treecut::Launch::Manual;
  treecut::FeedbackStage stage(treecut::Model{h, TreeCut::root_cut(*h)}, std::move(owned), options);
  const float mid = 0.5f * (h->bounds_min().x + h->bounds_max().x);
  std::vector<VisibilityResult> next;
  std::uint64_t generation = 0, lists = 0;
  for (int frame = 0; frame < 150; ++frame) {
    ViewSnapshot view = street_view(*h, float(frame) / 80.0f);
    view.version = std::uint64_t(frame) + 1;
    stage.set_view(view);
    const treecut::FrameLists f = stage.poll();
    if (!next.empty()) {
      stage.post_visibility(next);  // read in this frame: issued in the last one
      next.clear();
    }
    if (f.current.generation != generation) {
      generation = f.current.generation;
      ASSERT_EQ(TreeCut::validate(*h, f.current.nodes), "") << "generation " << generation;
      ++lists;
      const treecut::ViewSnapshot& cam = view;
      for (const QueryRequest& q : f.current.queries) {
        const glm::vec4 sp = h->arrays().center_radius[q.node];
        const double pixels = hoq::proxy_pixels(cam, glm::vec3(sp), sp.w);
        const bool hidden = sp.x < mid;
        VisibilityResult r;
        r.object = q.object;
        r.node = q.node;
        r.tag = q.tag;
        r.samples_passed =
            hidden ? 0u : std::uint32_t(pixels < 0.0 ? 640.0 * 360.0 : std::max(1.0, pixels));
        r.frame_issued = stage.frame();
        r.frame_read = stage.frame() + 1;
        r.kind = q.kind;
        next.push_back(r);
      }
    }
    stage.step();
  }
  EXPECT_EQ(stage.counters().errors, 0u) << stage.counters().last_error;
  EXPECT_GT(lists, 50u);
  const treecut::strategies::HoqCounters& t = hoq_strategy->totals();
  EXPECT_GT(t.queries, 0u);
  EXPECT_GT(t.answers, 0u);
  EXPECT_LE(t.answers, t.queries);
  EXPECT_GT(t.culled, 0u);  // the hidden half
  EXPECT_GT(t.drawn, 0u);
  // Each answer is at least the two frames old the stage makes it: issued
  // in frame X, posted in X + 1 after that frame's request, taken by the
  // iteration requested in X + 2.
  EXPECT_GE(t.answer_age_frames, 2 * t.answers);
}

TEST_F(HoqStrategyTest, ABlockSizeChangeRebuildsTheBlocks) {
  ViewSnapshot view = street_view(*h, 0.0f);
  view.frame = 1;
  (void)iterate(s, *h, view);
  ASSERT_EQ(blocks.validate_cut(ids(blocks, s.block_cut())), "");
  const std::size_t before = s.blocks_made();
  s.set_param("block_size", 1000);
  view.frame = 2;
  Step st = iterate(s, *h, view);
  // Blocks of 1000 leaves now: a cut of those (a block of 200 that is none
  // of them has no id there).
  const HlodBlocks big = HlodBlocks::build(*h, 1000, treecut::culling::kHierarchyFanOut);
  EXPECT_EQ(big.validate_cut(ids(big, s.block_cut())), "");
  EXPECT_LT(s.blocks_made(), before);
  std::sort(st.nodes.begin(), st.nodes.end());
  EXPECT_EQ(TreeCut::validate(*h, st.nodes), "");
}

}  // namespace
