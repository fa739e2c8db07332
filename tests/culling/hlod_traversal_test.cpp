// The in-frame HLOD traversal (strategies/hlod_traversal.hpp: Bool, SW(B),
// Simp(B), Coh(B) of Charalambos et al. 2007) on a CPU device whose answers
// the tests script per block (samples = a scripted fraction of the box's
// projected pixels) and that logs every query, read and draw:
//  - the three outcomes of PredictRefinement (figure 3) in the traversal:
//    Stop draws a block at once and queries it, Refine traverses its
//    children without a query of it, Delay queries it and draws (or culls)
//    it only after its answer was read;
//  - SW(B) draws no more blocks than Bool where the scene is occluded;
//  - Coh(B) never reads an answer before it is available while the
//    traversal queue has work;
//  - under a frame or two of GPU latency (gpu_latency.hpp) Coh(B) with
//    carried answers blocks only in its drains, where the paper's form
//    blocks on most answers, and still converges to SW(B)'s blocks.
#include "treecut/culling/hlod_traversal.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <glm/gtc/matrix_transform.hpp>
#include <map>
#include <memory>
#include <vector>

#include "treecut/attributes.hpp"
#include "treecut/culling/gpu_latency.hpp"
#include "treecut/hierarchy.hpp"
#include "treecut/tools/generate.hpp"

namespace {

using treecut::Hierarchy;
using treecut::ViewSnapshot;
using treecut::culling::BlockId;
using treecut::culling::box_projected_pixels;
using treecut::culling::DeviceFrameStats;
using treecut::culling::HlodBlocks;
using treecut::culling::HlodFrameStats;
using treecut::culling::HlodMode;
using treecut::culling::HlodOptions;
using treecut::culling::HlodTraversal;
using treecut::culling::OcclusionDeviceRenderThread;
using treecut::culling::QueryHandle;

constexpr glm::ivec2 kViewport(320, 180);

std::shared_ptr<const Hierarchy> city() {
  static std::shared_ptr<const Hierarchy> h;
  if (!h) {
    treecut::PointSet ps = treecut::tools::generate_city(20000, 5);
    treecut::complete_attributes(ps);
    h = std::make_shared<const Hierarchy>(treecut::build_hierarchy(std::move(ps)));
  }
  return h;
}

ViewSnapshot view_at(const Hierarchy& h, float distance_factor) {
  const glm::vec3 c = 0.5f * (h.bounds_min() + h.bounds_max());
  const float r = 0.5f * glm::length(h.bounds_max() - h.bounds_min());
  const glm::vec3 eye = c + distance_factor * r * glm::normalize(glm::vec3(1.0f, 0.6f, 0.8f));
  const glm::mat4 view = glm::lookAt(eye, c, glm::vec3(0, 0, 1));
  const float aspect = float(kViewport.x) / float(kViewport.y);
  const glm::mat4 proj = glm::perspective(0.9f, aspect, 0.01f * r, 10.0f * r);
  ViewSnapshot v;
  v.view = view;
  v.projection = proj;
  v.viewport = kViewport;
  v.finalize();
  v.derived.near_radius = 0.02f * r;  // the tests' margin, wider than the near plane's
  return v;
}

enum class Op { Query, Read, Draw };
struct Event {
  Op op;
  BlockId block;
};

// Answers: samples = fraction(b) * the box's projected pixels, available
// `latency` device calls after the query.
class ScriptedDevice final : public OcclusionDeviceRenderThread {
 public:
  ScriptedDevice(const HlodBlocks& blocks, int latency) : blocks_(&blocks), latency_(latency) {}

  std::function<double(BlockId)> fraction = [](BlockId) { return 1.0; };
  const ViewSnapshot* view = nullptr;
  const HlodTraversal* traversal = nullptr;
  std::vector<Event> log;
  std::uint64_t blocked_with_work = 0;

  void begin_frame_render_thread() override {
    stats_ = {};
    log.clear();
    ++ticks_;
  }
  QueryHandle query_box_render_thread(BlockId b) override {
    ++ticks_;
    ++stats_.queries;
    log.push_back({Op::Query, b});
    double px =
        box_projected_pixels(*view, blocks_->box(b));
    if (px < 0) px = 100.0;
    // Fully visible is every pixel (mu = 1), whatever the rounding.
    const double f = fraction(b);
    const auto samples = static_cast<std::uint64_t>(f >= 1.0 ? std::ceil(px) : f * px);
    const QueryHandle q = next_++;
    queries_[q] = {b, samples, ticks_ + static_cast<std::uint64_t>(latency_)};
    return q;
  }
  QueryHandle query_draw_render_thread(BlockId b) override {
    const QueryHandle q = query_box_render_thread(b);
    draw_render_thread(b);
    return q;
  }
  bool result_available_render_thread(QueryHandle q) override {
    ++ticks_;
    return ticks_ >= queries_.at(q).ready;
  }
  std::uint64_t result_render_thread(QueryHandle q) override {
    ++ticks_;
    const Pending p = queries_.at(q);
    queries_.erase(q);
    if (ticks_ < p.ready) {
      ++stats_.blocking_reads;
      if (traversal != nullptr && traversal->queued() > 0) ++blocked_with_work;
      ticks_ = p.ready;
    }
    log.push_back({Op::Read, p.block});
    return p.samples;
  }
  void draw_render_thread(BlockId b) override {
    ++ticks_;
    log.push_back({Op::Draw, b});
    ++stats_.blocks_drawn;
    stats_.splats_drawn += blocks_->representation(b).size();
  }
  void end_frame_render_thread(bool) override { ++ticks_; }
  [[nodiscard]] const DeviceFrameStats& frame_stats() const override { return stats_; }

  // Index of the first event `op` on `b` in this frame's log, or -1.
  [[nodiscard]] long first(Op op, BlockId b) const {
    for (std::size_t i = 0; i < log.size(); ++i) {
      if (log[i].op == op && log[i].block == b) return static_cast<long>(i);
    }
    return -1;
  }

 private:
  struct Pending {
    BlockId block;
    std::uint64_t samples, ready;
  };
  const HlodBlocks* blocks_;
  int latency_;
  std::map<QueryHandle, Pending> queries_;
  QueryHandle next_ = 0;
  std::uint64_t ticks_ = 0;
  DeviceFrameStats stats_;
};

class HlodTraversalTest : public ::testing::Test {
 protected:
  void SetUp() override {
    h_ = city();
    blocks_ = HlodBlocks::build(*h_, 32);
    near_ = view_at(*h_, 1.6f);
    far_ = view_at(*h_, 4.0f);
    // tau: the median SSE of the interior blocks at the near view, so the
    // SSE cut there stops at interior blocks as well as leaf blocks.
    HlodTraversal probe(*h_, blocks_);
    std::vector<float> sse;
    for (BlockId b = 0; b < blocks_.block_count(); ++b) {
      if (!blocks_.is_leaf(b)) {
        sse.push_back(treecut::culling::hoq::block_sse(near_, blocks_.box(b),
                                                       probe.error_radius(b)));
      }
    }
    std::sort(sse.begin(), sse.end());
    tau_ = sse[sse.size() / 2];
  }

  HlodOptions options(HlodMode mode) const {
    HlodOptions o;
    o.mode = mode;
    o.tau = tau_;
    return o;
  }
  HlodFrameStats run(HlodTraversal& t, ScriptedDevice& d, const ViewSnapshot& v) {
    d.view = &v;
    d.traversal = &t;
    return t.frame_render_thread(d, v);
  }
  // Answers of a scene occluded on one side: boxes there hidden, a band of
  // them barely visible, the rest in full view.
  std::function<double(BlockId)> occluded_side() const {
    const glm::vec3 c = 0.5f * (h_->bounds_min() + h_->bounds_max());
    return [this, c](BlockId b) {
      const glm::vec3 m = 0.5f * (blocks_.box(b).lo + blocks_.box(b).hi);
      if (m.x < c.x - 0.2f * (c.x - h_->bounds_min().x)) return 0.0;
      if (m.y < c.y) return 0.1;
      return 1.0;
    };
  }
  float block_sse(const HlodTraversal& t, BlockId b, const ViewSnapshot& v) const {
    return treecut::culling::hoq::block_sse(v, blocks_.box(b), t.error_radius(b));
  }

  std::shared_ptr<const Hierarchy> h_;
  HlodBlocks blocks_;
  ViewSnapshot near_, far_;
  float tau_ = 1.0f;
};

TEST_F(HlodTraversalTest, BoxPixelsOfABoxFillingTheViewAreTheViewport) {
  treecut::culling::Box huge{glm::vec3(-1e4f), glm::vec3(1e4f)};
  // Behind the eye: no analytic count.
  EXPECT_LT(box_projected_pixels(near_, huge), 0.0);
  // A box seen whole is less than the viewport and more than nothing.
  const double px = box_projected_pixels(near_, blocks_.box(0));
  EXPECT_GT(px, 0.0);
  EXPECT_LE(px, double(kViewport.x) * kViewport.y + 1e-6);
}

TEST_F(HlodTraversalTest, StopDrawsAtOnceRefineQueriesNothingDelayWaitsForTheAnswer) {
  ScriptedDevice d(blocks_, 4);
  HlodTraversal t(*h_, blocks_, options(HlodMode::CohB));
  for (int i = 0; i < 6; ++i) run(t, d, near_);  // converged: every block fully visible
  const std::vector<BlockId> cut = t.drawn();
  std::vector<bool> stopped_interior(blocks_.block_count(), false);
  ASSERT_FALSE(cut.empty());

  // Stop: the same view again: every drawn block was stopped last frame with
  // bias * SSE <= tau, so it is drawn without waiting for its answer (the
  // query right before the draw, the read after it), and nothing is delayed.
  HlodFrameStats s = run(t, d, near_);
  // Only blocks without a sample (too small, or clipped away) are delayed:
  // invisible last frame, culled again.
  EXPECT_EQ(s.delayed, s.culled);
  EXPECT_EQ(s.rarn, 0u);
  EXPECT_EQ(t.drawn(), cut);
  std::size_t interior = 0;
  for (const BlockId b : cut) {
    const long q = d.first(Op::Query, b), dr = d.first(Op::Draw, b), r = d.first(Op::Read, b);
    ASSERT_GE(q, 0);
    EXPECT_EQ(dr, q + 1) << "block " << b;
    EXPECT_GT(r, dr) << "block " << b;
    if (!blocks_.is_leaf(b)) {
      ++interior;
      stopped_interior[b] = true;
    }
  }
  ASSERT_GT(interior, 0u) << "tau must stop the cut at interior blocks too";

  // Refine: closer, a stopped interior block whose SSE now exceeds tau is
  // refined: no query of it, its children traversed (queried: new to the
  // traversal, so delayed) in the same frame.
  const ViewSnapshot closer = view_at(*h_, 1.1f);
  s = run(t, d, closer);
  std::size_t refined = 0;
  for (BlockId b = 0; b < blocks_.block_count(); ++b) {
    if (!stopped_interior[b] || !(block_sse(t, b, closer) > tau_)) continue;
    ASSERT_TRUE(t.visited(b));
    if (t.outside(b)) continue;  // culled by the closer view's frustum
    ++refined;
    EXPECT_EQ(d.first(Op::Query, b), -1) << "block " << b;
    EXPECT_EQ(d.first(Op::Draw, b), -1) << "block " << b;
    for (BlockId c = blocks_.first_child(b); c < blocks_.first_child(b) + blocks_.child_count(b);
         ++c) {
      EXPECT_TRUE(t.visited(c)) << "block " << b << " child " << c;
    }
  }
  EXPECT_GT(refined, 0u);
  EXPECT_GT(s.delayed, 0u);  // the children, new to the traversal
  EXPECT_GT(s.delayed_drawn_new, 0u);
  EXPECT_EQ(s.delayed_drawn_hidden, 0u);
  EXPECT_EQ(s.delayed_drawn,
            s.delayed_drawn_shift_up + s.delayed_drawn_new + s.delayed_drawn_hidden);

  // Delay: a block hidden for one frame is invisible last frame: queried,
  // and drawn only after its answer is read.
  for (int i = 0; i < 6; ++i) run(t, d, near_);
  const std::vector<BlockId> cut2 = t.drawn();
  const BlockId hidden = cut2[cut2.size() / 2];
  d.fraction = [hidden](BlockId b) { return b == hidden ? 0.0 : 1.0; };
  s = run(t, d, near_);
  EXPECT_EQ(d.first(Op::Draw, hidden), d.first(Op::Query, hidden) + 1);  // stopped: drawn at once
  EXPECT_FALSE(t.visible(hidden));
  EXPECT_EQ(s.stopped_hidden, 1u);  // drawn although its answer found it hidden
  d.fraction = [](BlockId) { return 1.0; };
  s = run(t, d, near_);
  EXPECT_GE(s.delayed, 1u);
  // D by cause: the hidden block, drawn after its answer.
  EXPECT_EQ(s.delayed_drawn_hidden, 1u);
  EXPECT_EQ(s.delayed_drawn,
            s.delayed_drawn_shift_up + s.delayed_drawn_new + s.delayed_drawn_hidden);
  EXPECT_EQ(s.stopped_hidden, 0u);
  const long q = d.first(Op::Query, hidden), r = d.first(Op::Read, hidden);
  const long dr = d.first(Op::Draw, hidden);
  ASSERT_GE(q, 0);
  ASSERT_GE(dr, 0);
  EXPECT_LT(q, r);
  EXPECT_LT(r, dr);

  // Delay, shift up: farther, refined blocks whose children all stop with
  // room to spare are candidates: queried, their answers waited for, and
  // then drawn at their own level (VMSSE <= tau), their children not drawn.
  for (int i = 0; i < 6; ++i) run(t, d, near_);
  const ViewSnapshot farther = view_at(*h_, 2.4f);
  s = run(t, d, farther);
  EXPECT_GT(s.delayed_shift_up, 0u);
  EXPECT_GT(s.delayed_drawn_shift_up, 0u);
  EXPECT_LE(s.delayed_drawn_shift_up, s.delayed_shift_up);
  std::size_t shifted = 0;
  for (const BlockId b : t.drawn()) {
    if (blocks_.is_leaf(b)) continue;
    const long qb = d.first(Op::Query, b), rb = d.first(Op::Read, b), db = d.first(Op::Draw, b);
    if (qb >= 0 && rb > qb && db > rb) {
      ++shifted;
      EXPECT_EQ(d.first(Op::Draw, blocks_.first_child(b)), -1) << "block " << b;
    }
  }
  EXPECT_GT(shifted, 0u);
}

TEST_F(HlodTraversalTest, AStopWhoseAnswerSaysRefineIsARarn) {
  // Simp(B) predicts with the cached bias: a block stopped under a low bias
  // (mostly hidden) that then shows itself is drawn, then refined in the
  // same frame once its answer is read.
  ScriptedDevice d(blocks_, 2);
  HlodTraversal t(*h_, blocks_, options(HlodMode::SimpB));
  d.fraction = [](BlockId) { return 0.05; };
  for (int i = 0; i < 6; ++i) run(t, d, near_);
  d.fraction = [](BlockId) { return 1.0; };
  const HlodFrameStats s = run(t, d, near_);
  EXPECT_GT(s.rarn, 0u);
  // Bool on the same script never has one: it stops by SSE alone.
  HlodTraversal b(*h_, blocks_, options(HlodMode::Bool));
  d.fraction = [](BlockId) { return 0.05; };
  for (int i = 0; i < 6; ++i) run(b, d, near_);
  d.fraction = [](BlockId) { return 1.0; };
  EXPECT_EQ(run(b, d, near_).rarn, 0u);
}

TEST_F(HlodTraversalTest, StopAndWaitWithVmsseDrawsNoMoreBlocksThanBool) {
  // Occlusion: boxes on one side of the scene hidden, a band barely visible.
  const auto fraction = occluded_side();
  std::uint64_t dn[4] = {};
  const HlodMode modes[4] = {HlodMode::Bool, HlodMode::SwB, HlodMode::SimpB, HlodMode::CohB};
  for (int m = 0; m < 4; ++m) {
    ScriptedDevice d(blocks_, 3);
    d.fraction = fraction;
    HlodTraversal t(*h_, blocks_, options(modes[m]));
    for (int i = 0; i < 8; ++i) dn[m] = run(t, d, near_).drawn;
  }
  EXPECT_GT(dn[0], 0u);
  EXPECT_LT(dn[1], dn[0]) << "SW(B) " << dn[1] << " Bool " << dn[0];
  // Converged on a still view, Coh(B) draws the ideal count.
  EXPECT_EQ(dn[3], dn[1]);
}

TEST_F(HlodTraversalTest, CohBNeverReadsAnAnswerBeforeItIsAvailableWhileThereIsWork) {
  ScriptedDevice d(blocks_, 6);
  HlodTraversal t(*h_, blocks_, options(HlodMode::CohB));
  std::uint64_t reads = 0;
  for (int i = 0; i <= 20; ++i) {
    const float f = 1.2f + 0.1f * float(i);
    const HlodFrameStats s = run(t, d, view_at(*h_, f));
    reads += s.queries;
  }
  EXPECT_GT(reads, 0u);
  EXPECT_EQ(d.blocked_with_work, 0u);
  // SW(B) waits for every answer: the device's check is live.
  HlodTraversal sw(*h_, blocks_, options(HlodMode::SwB));
  run(sw, d, near_);
  EXPECT_GT(d.blocked_with_work, 0u);
}

// Under the latency model: the scripted device answers at once, the model
// `frames` frames after the issue.
HlodFrameStats run_latent(HlodTraversal& t, ScriptedDevice& d,
                          treecut::culling::LatentOcclusionDevice& latent, const ViewSnapshot& v) {
  d.view = &v;
  return t.frame_render_thread(latent, v);
}

TEST_F(HlodTraversalTest, CarriedCohBBlocksOnlyInItsDrainsUnderLatency) {
  for (const std::uint32_t frames : {1u, 2u}) {
    std::uint64_t queries[2] = {}, blocking[2] = {}, drains = 0, late = 0, carried = 0;
    for (int c = 0; c < 2; ++c) {
      ScriptedDevice d(blocks_, 0);
      treecut::culling::LatentOcclusionDevice latent(d, {frames, 0.0});
      HlodOptions o = options(HlodMode::CohB);
      o.carry_answers = c == 1;
      HlodTraversal t(*h_, blocks_, o);
      for (int i = 0; i <= 20; ++i) {
        // Nearer blocks half hidden, so biases change as the camera moves.
        d.fraction = [i](BlockId b) { return (b + static_cast<BlockId>(i)) % 3 == 0 ? 0.2 : 1.0; };
        const HlodFrameStats s = run_latent(t, d, latent, view_at(*h_, 1.2f + 0.1f * float(i)));
        queries[c] += s.queries;
        blocking[c] += s.blocking_reads;
        if (c == 1) drains += s.drains, late += s.late_refined, carried += s.carried_answers;
      }
      t.release_render_thread(latent);
    }
    EXPECT_GE(blocking[0], queries[0] / 2) << "the paper's Coh(B) reads in-frame: " << frames;
    EXPECT_LE(blocking[1], drains) << frames;
    EXPECT_LT(4 * blocking[1], blocking[0]) << frames;
    EXPECT_GT(carried, 0u) << frames;
    EXPECT_GT(late, 0u) << "a drawn block whose late answer says refine, refines: " << frames;
  }
}

TEST_F(HlodTraversalTest, CarriedCohBConvergesToStopAndWaitOnAStillViewUnderLatency) {
  const auto fraction = occluded_side();
  ScriptedDevice ds(blocks_, 0);
  ds.fraction = fraction;
  HlodTraversal sw(*h_, blocks_, options(HlodMode::SwB));
  const std::uint64_t ideal = run(sw, ds, near_).drawn;
  for (const std::uint32_t frames : {1u, 2u}) {
    ScriptedDevice d(blocks_, 0);
    d.fraction = fraction;
    treecut::culling::LatentOcclusionDevice latent(d, {frames, 0.0});
    HlodOptions o = options(HlodMode::CohB);
    o.carry_answers = true;
    HlodTraversal t(*h_, blocks_, o);
    HlodFrameStats s;
    for (int i = 0; i < 12; ++i) s = run_latent(t, d, latent, near_);
    EXPECT_EQ(s.drawn, ideal) << frames;
    // Converged: the hidden blocks still wait for their answers (figure 3
    // delays a block invisible last frame), in one drain a frame.
    EXPECT_EQ(s.drains, 1u) << frames;
    EXPECT_LE(s.blocking_reads, s.drains) << frames;
    t.release_render_thread(latent);
  }
}

// "Coh(B) tolerant" (the bench's latency-tolerant row): a block new to the
// traversal is drawn or refined by its SSE at once, not delayed for an
// answer a GPU gives a frame late.
TEST_F(HlodTraversalTest, AssumingNewBlocksVisibleDelaysNoneOfThem) {
  for (const bool assume : {false, true}) {
    ScriptedDevice d(blocks_, 0);
    treecut::culling::LatentOcclusionDevice latent(d, {1, 0.0});
    HlodOptions o = options(HlodMode::CohB);
    o.carry_answers = true;
    o.assume_new_visible = assume;
    HlodTraversal t(*h_, blocks_, o);
    const HlodFrameStats first = run_latent(t, d, latent, near_);
    if (assume) {
      EXPECT_EQ(first.delayed, 0u);
      EXPECT_GT(first.drawn, 0u) << "the first frame draws the SSE cut";
      EXPECT_EQ(first.blocking_reads, 0u) << "and waits for nothing";
    } else {
      EXPECT_GT(first.delayed, 0u) << "figure 3 delays every block of the first frame";
    }
    t.release_render_thread(latent);
  }
}

}  // namespace
