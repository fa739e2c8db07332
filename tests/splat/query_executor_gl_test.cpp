// The GPU query executor (treecut/splat/query_executor.hpp) on OSMesa: a wall
// the test builds in front of some small spheres and beside others. Every
// occluded proxy answers 0 samples, every visible one more; the batched
// answers (one instanced draw, a counter per request) equal each proxy drawn
// alone against the wall's depth and counted by a GL_SAMPLES_PASSED query
// (read after glFinish); the requests of a list generation are issued once;
// and no counter is ever read before its batch's fence was seen signaled (the
// GL entry points interposed: a signaled fence is reported pending for a few
// polls while the counters hold poison, with a check that this makes a read
// that comes too early visible).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <map>
#include <memory>
#include <numeric>
#include <utility>
#include <vector>

#include "treecut/controller.hpp"
#include "treecut/hierarchy.hpp"
#include "treecut/model.hpp"
#include "treecut/model_io.hpp"
#include "treecut/point_set.hpp"
#include "treecut/splat/camera.hpp"
#include "treecut/splat/context.hpp"
#include "treecut/splat/frame.hpp"
#include "treecut/splat/gl.hpp"
#include "treecut/splat/gl_objects.hpp"
#include "treecut/splat/query_executor.hpp"
#include "treecut/splat/renderer.hpp"
#include "treecut/strategy.hpp"
#include "treecut/tree_cut.hpp"

namespace treecut::splat {
namespace {

constexpr int kWidth = 160;
constexpr int kHeight = 120;

GlContext& context() {
  static const std::unique_ptr<GlContext> ctx = make_headless_context(kWidth, kHeight);
  ctx->make_current();
  return *ctx;
}

// A closed square wall in the plane z = 0, x and y in [-1, 1], facing +z.
const Hierarchy& wall() {
  static const Hierarchy h = [] {
    PointSet p;
    constexpr int n = 120;
    for (int i = 0; i < n; ++i) {
      for (int j = 0; j < n; ++j) {
        p.positions.push_back(
            {-1.0f + 2.0f * (float(i) + 0.5f) / n, -1.0f + 2.0f * (float(j) + 0.5f) / n, 0.0f});
        p.normals.push_back({0.0f, 0.0f, 1.0f});
        p.radii.push_back(2.0f / n);  // twice the half spacing: no holes
        p.curvature.push_back(0.0f);  // every attribute given: no k-NN
      }
    }
    return build_from_points(std::move(p));
  }();
  return h;
}

// Small spheres: behind the wall's middle (occluded), behind it but beside
// it (visible past its edge), and in front of it.
struct Probe {
  glm::vec3 center;
  bool occluded;
};
const std::vector<Probe>& probes() {
  static const std::vector<Probe> p = {
      {{0.0f, 0.0f, -1.0f}, true},  {{0.4f, 0.3f, -1.0f}, true},  {{-0.4f, -0.3f, -0.5f}, true},
      {{0.2f, -0.5f, -2.0f}, true}, {{2.0f, 0.0f, -1.0f}, false}, {{-2.0f, 0.5f, -1.0f}, false},
      {{0.0f, 1.5f, -1.0f}, false}, {{0.0f, 0.0f, 1.0f}, false},  {{0.5f, 0.5f, 0.5f}, false},
  };
  return p;
}

const Hierarchy& probe_hierarchy() {
  static const Hierarchy h = [] {
    PointSet p;
    for (const Probe& pr : probes()) {
      p.positions.push_back(pr.center);
      p.normals.push_back({0.0f, 0.0f, 1.0f});
      p.radii.push_back(0.05f);
      p.curvature.push_back(0.0f);
    }
    return build_from_points(std::move(p));
  }();
  return h;
}

Camera wall_camera() {
  Camera c;
  c.eye = {0.0f, 0.0f, 3.0f};
  c.target = {0.0f, 0.0f, 0.0f};
  c.near_plane = 0.1f;
  c.far_plane = 20.0f;
  return c;
}

// A request about node N of H (its sphere with it, as query_about() gives).
QueryRequest about(const Hierarchy& h, NodeId n, std::uint32_t tag,
                   QueryKind kind = QueryKind::Samples) {
  return {0, n, tag, kind, h.arrays().center_radius[n]};
}

// The leaf of the probe hierarchy at `center`.
NodeId leaf_at(glm::vec3 center) {
  const Hierarchy& h = probe_hierarchy();
  for (NodeId n = 0; n < h.node_count(); ++n) {
    if (h.is_leaf(n) && glm::length(h.center(n) - center) < 1e-4f) return n;
  }
  return kNoNode;
}

class QueryExecutorTest : public ::testing::Test {
 protected:
  void SetUp() override {
    context();
    renderer_ = std::make_unique<Renderer>(wall(), glm::ivec2(kWidth, kHeight));
    cut_.upload(wall(), TreeCut::leaf_cut(wall()).nodes());
    executor_ = std::make_unique<QueryExecutor>();
    renderer_->set_query_hook(executor_.get());
  }
  void TearDown() override { renderer_->set_query_hook(nullptr); }

  // A fresh executor with a minimum batch of `min_batch` (max_defer_frames
  // `defer`) in place of the default one.
  void use_executor(std::size_t min_batch, std::uint64_t defer = 1) {
    QueryExecutorOptions o;
    o.min_batch = min_batch;
    o.max_defer_frames = defer;
    renderer_->set_query_hook(nullptr);
    executor_ = std::make_unique<QueryExecutor>(o);
    renderer_->set_query_hook(executor_.get());
  }

  // One frame: the executor sees `list` as the drawn list of frame `frame`.
  void frame(const FrontList& list, std::uint64_t frame_number, bool finish = false) {
    executor_->begin_frame_render_thread(list, frame_number);
    renderer_->draw(cut_, wall_camera(), RenderSettings{}, finish);
  }

  FrontList list_of(const std::vector<QueryRequest>& requests, std::uint64_t generation) {
    FrontList l;
    l.generation = generation;
    l.hierarchy = &probe_hierarchy();
    l.queries = requests;
    return l;
  }

  // Frames (each finished) until every request is answered; the answers by tag.
  std::map<std::uint32_t, VisibilityResult> run_to_completion(const FrontList& list,
                                                              std::uint64_t& frame_number) {
    std::map<std::uint32_t, VisibilityResult> answers;
    for (int i = 0; i < 20 && answers.size() < list.queries.size(); ++i) {
      frame(list, ++frame_number, true);
      for (const VisibilityResult& r : executor_->results()) answers[r.tag] = r;
      executor_->clear_results();
    }
    return answers;
  }

  std::unique_ptr<Renderer> renderer_;
  CutBuffer cut_;
  std::unique_ptr<QueryExecutor> executor_;
};

// Each proxy drawn alone against the wall's depth (a batch of one) inside a
// GL_SAMPLES_PASSED query, read after glFinish: the reference for one request,
// counted by the GL's occlusion counter instead of the executor's atomics.
class AloneHook final : public QueryHook {
 public:
  explicit AloneHook(QueryRequest r) : request_(r) {}
  void run(const ViewSnapshot& view) override {
    QueryExecutorOptions o;
    o.min_batch = 1;  // issued in this run(), not batched with later ones
    QueryExecutor single(o);
    FrontList l;
    const std::vector<QueryRequest> one{request_};
    l.generation = 1;
    l.hierarchy = &probe_hierarchy();
    l.queries = one;
    single.begin_frame_render_thread(l, 1);
    const gl::Query q = gl::Query::create(GL_SAMPLES_PASSED);
    q.begin();
    single.run(view);  // draws the one proxy
    q.end();
    gl::Finish();
    if (const auto v = q.try_result()) samples = static_cast<std::int64_t>(*v);
  }
  QueryRequest request_;
  std::int64_t samples = -1;
};

// The frame's depth (read in the hook, where the renderer has it complete)
// and view: the reference of the CPU ray test below.
class DepthHook final : public QueryHook {
 public:
  void run(const ViewSnapshot& v) override {
    view = v;
    depth.assign(std::size_t(v.viewport.x) * std::size_t(v.viewport.y), 0.0f);
    gl::PixelStorei(GL_PACK_ALIGNMENT, 1);
    gl::ReadPixels(0, 0, v.viewport.x, v.viewport.y, GL_DEPTH_COMPONENT, GL_FLOAT, depth.data());
  }
  ViewSnapshot view;
  std::vector<float> depth;
};

// The samples of the sphere itself: pixels whose center's ray hits the
// sphere (eye outside it) with the nearest hit's window depth <= the
// frame's depth there (GL_LEQUAL). A conservative proxy counts at least
// these, and 0 only where this is 0.
std::uint32_t true_samples(glm::vec4 sphere, const DepthHook& d) {
  const ViewSnapshot& v = d.view;
  const glm::mat4 vp = v.projection * v.view;
  const glm::mat4 inv = glm::inverse(vp);
  const glm::vec3 c(sphere);
  const float r = sphere.w;
  std::uint32_t n = 0;
  for (int y = 0; y < v.viewport.y; ++y) {
    for (int x = 0; x < v.viewport.x; ++x) {
      const glm::vec2 ndc((float(x) + 0.5f) / float(v.viewport.x) * 2.0f - 1.0f,
                          (float(y) + 0.5f) / float(v.viewport.y) * 2.0f - 1.0f);
      const glm::vec4 far_h = inv * glm::vec4(ndc, 1.0f, 1.0f);
      const glm::vec3 dir = glm::normalize(glm::vec3(far_h) / far_h.w - v.derived.eye);
      const glm::vec3 oc = v.derived.eye - c;
      const float b = glm::dot(oc, dir);
      const float disc = b * b - (glm::dot(oc, oc) - r * r);
      if (disc < 0.0f) continue;
      const float t = -b - std::sqrt(disc);
      if (t <= 0.0f) continue;  // behind the eye
      const glm::vec4 hit = vp * glm::vec4(v.derived.eye + t * dir, 1.0f);
      const float depth = std::clamp(hit.z / hit.w * 0.5f + 0.5f, 0.0f, 1.0f);
      if (depth <= d.depth[std::size_t(y) * std::size_t(v.viewport.x) + std::size_t(x)]) ++n;
    }
  }
  return n;
}

TEST_F(QueryExecutorTest, OccludedProxiesAnswerZeroAndVisibleOnesMoreLikeEachAlone) {
  const Hierarchy& h = probe_hierarchy();
  std::vector<QueryRequest> requests;
  for (NodeId n = 0; n < h.node_count(); ++n) requests.push_back(about(h, n, n));
  std::uint64_t f = 0;
  const auto answers = run_to_completion(list_of(requests, 1), f);
  ASSERT_EQ(answers.size(), requests.size());

  for (const Probe& p : probes()) {
    const NodeId leaf = leaf_at(p.center);
    ASSERT_NE(leaf, kNoNode);
    const VisibilityResult& r = answers.at(leaf);
    EXPECT_EQ(r.node, leaf);
    if (p.occluded) {
      EXPECT_EQ(r.samples_passed, 0u) << "behind the wall at " << p.center.x << "," << p.center.y;
    } else {
      EXPECT_GT(r.samples_passed, 0u) << "visible at " << p.center.x << "," << p.center.y;
    }
    EXPECT_GT(r.frame_read, r.frame_issued);  // never in the frame that issued it
  }
  // Against the spheres themselves (a CPU ray test against the frame's
  // depth): every count at least the sphere's own samples, 0 only where the
  // sphere has none; the point sprite adds at most the corners of its square
  // (a bounding square of the sphere's disc: under 4/pi of it, plus a pixel
  // on every side).
  DepthHook depth;
  renderer_->set_query_hook(&depth);
  renderer_->draw(cut_, wall_camera(), RenderSettings{}, true);
  renderer_->set_query_hook(executor_.get());
  for (const QueryRequest& q : requests) {
    const std::uint32_t truth = true_samples(h.arrays().center_radius[q.node], depth);
    const std::uint32_t got = answers.at(q.tag).samples_passed;
    EXPECT_GE(got, truth) << "node " << q.node;
    EXPECT_EQ(got == 0, truth == 0) << "node " << q.node;
  }
  for (const Probe& p : probes()) {
    const NodeId leaf = leaf_at(p.center);
    const std::uint32_t truth = true_samples(h.arrays().center_radius[leaf], depth);
    EXPECT_EQ(truth == 0, p.occluded) << p.center.x << "," << p.center.y;
    if (!p.occluded) {
      const double side = std::sqrt(truth * 4.0 / 3.14159265) + 2.0;
      EXPECT_LE(answers.at(leaf).samples_passed, side * side) << "leaf " << leaf;
    }
  }
  EXPECT_GT(executor_->stats().point_proxies, 0u);
  // Every node (inner ones too), answered from one batch, equals its proxy
  // drawn alone: the batch's counters do not mix.
  for (const QueryRequest& q : requests) {
    AloneHook alone(q);
    renderer_->set_query_hook(&alone);
    renderer_->draw(cut_, wall_camera(), RenderSettings{}, true);
    renderer_->set_query_hook(executor_.get());
    EXPECT_EQ(alone.samples, std::int64_t(answers.at(q.tag).samples_passed)) << "node " << q.node;
  }
  // The root holds visible spheres: visible.
  EXPECT_GT(answers.at(0).samples_passed, 0u);
}

// Spheres the point path cannot take or need not draw: one reaching behind
// the eye's plane (beside the eye, in front of the wall: the quad path), one
// wider than the view (its sprite clipped to the viewport), one outside the
// view (answered 0 on the host), one ordinary. Each answer at least the
// sphere's own samples, 0 only where it has none; the same with every proxy
// a quad.
TEST_F(QueryExecutorTest, QuadPathAndClippedSpritesStayConservative) {
  static const Hierarchy big = [] {
    PointSet p;
    const std::vector<glm::vec4> spheres = {
        {1.6f, 0.0f, 2.9f, 1.5f},    // eye (0, 0, 3) outside, reaching behind it
        {0.0f, 0.0f, -3.0f, 4.0f},   // partly behind the wall, wider than the view
        {40.0f, 0.0f, -1.0f, 0.5f},  // outside the view
        {0.6f, 0.6f, 1.0f, 0.2f},    // in front of the wall
    };
    for (const glm::vec4& s : spheres) {
      p.positions.push_back(glm::vec3(s));
      p.normals.push_back({0.0f, 0.0f, 1.0f});
      p.radii.push_back(s.w);
      p.curvature.push_back(0.0f);
    }
    return build_from_points(std::move(p));
  }();
  DepthHook depth;
  renderer_->set_query_hook(&depth);
  renderer_->draw(cut_, wall_camera(), RenderSettings{}, true);
  for (const bool points : {true, false}) {
    QueryExecutorOptions o;
    o.point_proxies = points;
    executor_ = std::make_unique<QueryExecutor>(o);
    renderer_->set_query_hook(executor_.get());
    std::vector<QueryRequest> requests;
    for (NodeId n = 0; n < big.node_count(); ++n) {
      if (big.is_leaf(n)) requests.push_back(about(big, n, n));
    }
    ASSERT_EQ(requests.size(), 4u);
    FrontList list;
    list.generation = 1;
    list.hierarchy = &big;
    list.queries = requests;
    std::map<std::uint32_t, VisibilityResult> answers;
    std::uint64_t f = 0;
    for (int i = 0; i < 20 && answers.size() < requests.size(); ++i) {
      frame(list, ++f, true);
      for (const VisibilityResult& r : executor_->results()) answers[r.tag] = r;
      executor_->clear_results();
    }
    ASSERT_EQ(answers.size(), requests.size());
    int none = 0;
    for (const QueryRequest& q : requests) {
      const std::uint32_t truth = true_samples(big.arrays().center_radius[q.node], depth);
      const std::uint32_t got = answers.at(q.tag).samples_passed;
      EXPECT_GE(got, truth) << "node " << q.node << (points ? " points" : " quads");
      EXPECT_EQ(got == 0, truth == 0) << "node " << q.node << (points ? " points" : " quads");
      none += truth == 0 ? 1 : 0;
    }
    EXPECT_EQ(none, 1);  // only the one outside the view
    if (points) {
      EXPECT_EQ(executor_->stats().quad_proxies, 1u);  // the one reaching behind the eye
      EXPECT_EQ(executor_->stats().point_proxies, 2u);
      EXPECT_EQ(executor_->stats().offscreen, 1u);
    } else {
      EXPECT_EQ(executor_->stats().point_proxies, 0u);
    }
  }
}

// The executor tests the request's sphere, never the hierarchy: the same
// visible node asked with its sphere moved behind the wall is occluded, and
// asked without one (radius 0, or not finite) is answered 0 on the host.
TEST_F(QueryExecutorTest, TheSphereTestedIsTheRequests) {
  const Hierarchy& h = probe_hierarchy();
  NodeId visible = kNoNode;
  glm::vec3 hidden_at(0.0f);
  for (const Probe& p : probes()) {
    if (p.occluded) hidden_at = p.center;
    if (!p.occluded && visible == kNoNode) visible = leaf_at(p.center);
  }
  ASSERT_NE(visible, kNoNode);
  std::vector<QueryRequest> requests{about(h, visible, 0), about(h, visible, 1),
                                     about(h, visible, 2), about(h, visible, 3)};
  requests[1].sphere = glm::vec4(hidden_at, requests[1].sphere.w);
  requests[2].sphere.w = 0.0f;
  requests[3].sphere.x = std::numeric_limits<float>::quiet_NaN();
  std::uint64_t f = 0;
  const auto answers = run_to_completion(list_of(requests, 1), f);
  ASSERT_EQ(answers.size(), requests.size());
  EXPECT_GT(answers.at(0).samples_passed, 0u);
  for (std::uint32_t tag = 1; tag < 4; ++tag) {
    EXPECT_EQ(answers.at(tag).samples_passed, 0u) << tag;
    EXPECT_EQ(answers.at(tag).node, visible) << tag;
  }
  EXPECT_EQ(answers.at(2).frame_read, answers.at(2).frame_issued) << "answered on the host";
}

TEST_F(QueryExecutorTest, AnySamplesAnswersZeroOrOne) {
  std::vector<QueryRequest> requests;
  for (std::uint32_t i = 0; i < probes().size(); ++i) {
    requests.push_back(
        about(probe_hierarchy(), leaf_at(probes()[i].center), i, QueryKind::AnySamples));
  }
  std::uint64_t f = 0;
  const auto answers = run_to_completion(list_of(requests, 1), f);
  ASSERT_EQ(answers.size(), requests.size());
  for (std::uint32_t i = 0; i < probes().size(); ++i) {
    EXPECT_EQ(answers.at(i).kind, QueryKind::AnySamples);
    EXPECT_EQ(answers.at(i).samples_passed, probes()[i].occluded ? 0u : 1u) << i;
  }
}

TEST_F(QueryExecutorTest, RequestsOfOneGenerationRunOnceWithTheCapCarryingTheRest) {
  const Hierarchy& h = probe_hierarchy();
  std::vector<QueryRequest> requests;
  for (NodeId n = 0; n < h.node_count(); ++n) requests.push_back(about(h, n, n));
  ASSERT_GE(requests.size(), 5u);
  executor_->set_max_issue_per_frame(2);
  const FrontList list = list_of(requests, 7);
  std::uint64_t f = 0;
  std::map<std::uint32_t, int> answered;
  for (int i = 0; i < 40; ++i) {  // the same list polled again and again
    frame(list, ++f, true);
    EXPECT_LE(executor_->stats().issued_last, 2u);
    for (const VisibilityResult& r : executor_->results()) ++answered[r.tag];
    executor_->clear_results();
  }
  EXPECT_EQ(executor_->stats().issued, requests.size());
  EXPECT_EQ(answered.size(), requests.size());
  for (const auto& [tag, count] : answered) EXPECT_EQ(count, 1) << "tag " << tag;
  EXPECT_EQ(executor_->stats().pending, 0u);
  EXPECT_EQ(executor_->stats().queued, 0u);
  // The cap spread the requests over frames: the latest waited in the queue.
  EXPECT_GE(executor_->stats().latency_frames_max, 1u);
  // Pool: objects are reused, not made per frame.
  EXPECT_LE(executor_->stats().pool_size, 4u);

  // A new generation queues its own requests once. Below the minimum batch
  // they wait a frame (max_defer_frames 1) and are kept when the next
  // generation arrives: nothing dropped, both go out as one batch (cap 2).
  const FrontList next = list_of(requests, 8);
  frame(next, ++f, true);
  EXPECT_EQ(executor_->stats().issued_last, 0u);
  const FrontList third = list_of(requests, 9);
  frame(third, ++f, true);
  EXPECT_EQ(executor_->stats().dropped, 0u);
  EXPECT_EQ(executor_->stats().issued_last, 2u);
  EXPECT_EQ(executor_->stats().queued, 2 * requests.size() - 2);
  // Those were due and did not fit the cap: a newer generation drops them.
  const FrontList fourth = list_of(requests, 10);
  frame(fourth, ++f, true);
  EXPECT_EQ(executor_->stats().dropped, 2 * requests.size() - 2);
  EXPECT_EQ(executor_->stats().queued, requests.size());
}

// The probes' requests (tag = index + offset), and whether each is occluded.
std::vector<QueryRequest> probe_requests(std::uint32_t offset) {
  std::vector<QueryRequest> r;
  for (std::uint32_t i = 0; i < probes().size(); ++i) {
    r.push_back(about(probe_hierarchy(), leaf_at(probes()[i].center), offset + i));
  }
  return r;
}

// The GPU-latency model (culling/gpu_latency.hpp): answers read no earlier
// than min_answer_frames frames after their batch was issued, the same
// answers as without it.
TEST_F(QueryExecutorTest, AMinimumAnswerAgeHoldsAnswersBackAndKeepsThem) {
  std::map<std::uint32_t, std::uint32_t> samples[2];
  for (int i = 0; i < 2; ++i) {
    QueryExecutorOptions o;
    o.min_batch = 0;
    o.min_answer_frames = i == 0 ? 1 : 3;
    renderer_->set_query_hook(nullptr);
    executor_ = std::make_unique<QueryExecutor>(o);
    renderer_->set_query_hook(executor_.get());
    std::uint64_t f = 0;
    for (const auto& [tag, r] : run_to_completion(list_of(probe_requests(0), 1), f)) {
      samples[i][tag] = r.samples_passed;
      EXPECT_GE(r.frame_read - r.frame_issued, o.min_answer_frames) << "tag " << tag;
    }
    EXPECT_EQ(samples[i].size(), probes().size());
  }
  EXPECT_EQ(samples[0], samples[1]);
}

TEST_F(QueryExecutorTest, ATrickleBelowTheMinimumBatchGoesOutAfterMaxDeferFramesAsOneBatch) {
  constexpr std::uint64_t kDefer = 3;
  use_executor(1000, kDefer);
  const std::size_t k = probes().size();
  std::map<std::uint32_t, std::uint64_t> requested;  // tag -> frame of its request
  std::uint64_t f = 0;
  // A new generation every frame, k requests each: held back for kDefer
  // frames, then the four generations' requests go out as one batch.
  for (std::uint32_t g = 0; g <= kDefer; ++g) {
    const std::vector<QueryRequest> r = probe_requests(g * 100);
    for (const QueryRequest& q : r) requested[q.tag] = f + 1;
    frame(list_of(r, g + 1), ++f, true);
    if (g < kDefer) {
      EXPECT_EQ(executor_->stats().issued_last, 0u) << "frame " << f;
      EXPECT_EQ(executor_->stats().queued, (g + 1) * k);
    }
  }
  EXPECT_EQ(executor_->stats().issued_last, (kDefer + 1) * k);
  EXPECT_EQ(executor_->stats().batches, 1u);
  EXPECT_EQ(executor_->stats().deferred_runs, kDefer);
  EXPECT_EQ(executor_->stats().dropped, 0u);
  EXPECT_EQ(executor_->stats().queued, 0u);
  // The deferral of each request: kDefer, kDefer - 1, ..., 0 frames.
  EXPECT_EQ(executor_->stats().deferral_frames_total, k * kDefer * (kDefer + 1) / 2);
  const std::uint64_t issue_frame = f;
  std::vector<VisibilityResult> answers;
  for (int i = 0; i < 20 && answers.size() < requested.size(); ++i) {
    frame(list_of(probe_requests(0), kDefer + 1), ++f, true);  // the same list: nothing new
    answers.insert(answers.end(), executor_->results().begin(), executor_->results().end());
    executor_->clear_results();
  }
  ASSERT_EQ(answers.size(), requested.size());
  std::uint64_t latency_total = 0, latency_max = 0;
  std::map<std::uint32_t, int> once;
  for (const VisibilityResult& r : answers) {
    ++once[r.tag];
    const Probe& p = probes()[r.tag % 100];
    EXPECT_EQ(r.node, leaf_at(p.center));
    if (p.occluded) {
      EXPECT_EQ(r.samples_passed, 0u) << r.tag;
    } else {
      EXPECT_GT(r.samples_passed, 0u) << r.tag;
    }
    EXPECT_EQ(r.frame_issued, issue_frame);  // the frame its proxy was drawn in
    EXPECT_GT(r.frame_read, r.frame_issued);
    const std::uint64_t latency = r.frame_read - requested.at(r.tag);
    latency_total += latency;
    latency_max = std::max(latency_max, latency);
  }
  for (const auto& [tag, count] : once) EXPECT_EQ(count, 1) << "tag " << tag;
  // The latency counts from the request: the deferral included.
  EXPECT_EQ(executor_->stats().latency_frames_total, latency_total);
  EXPECT_EQ(executor_->stats().latency_frames_max, latency_max);
  EXPECT_GE(latency_max, kDefer + 1);
}

TEST_F(QueryExecutorTest, ABatchOfAtLeastMinBatchGoesOutAtOnceAndATrickleAFrameLater) {
  // The defaults: min_batch 256, max_defer_frames 1.
  ASSERT_EQ(executor_->options().min_batch, 256u);
  ASSERT_EQ(executor_->options().max_defer_frames, 1u);
  std::vector<QueryRequest> many;
  for (std::uint32_t rep = 0; many.size() < 300; ++rep) {
    for (QueryRequest q : probe_requests(0)) {
      q.tag = static_cast<std::uint32_t>(many.size());
      many.push_back(q);
    }
  }
  std::uint64_t f = 0;
  frame(list_of(many, 1), ++f, true);
  EXPECT_EQ(executor_->stats().issued_last, many.size());  // at once
  EXPECT_EQ(executor_->stats().deferred_runs, 0u);
  const auto answers = run_to_completion(list_of(many, 1), f);
  ASSERT_EQ(answers.size(), many.size());
  for (const auto& [tag, r] : answers) {
    EXPECT_EQ(r.frame_issued, 1u);
    const bool occluded = probes()[tag % probes().size()].occluded;
    EXPECT_EQ(r.samples_passed == 0, occluded) << tag;
  }
  // A few: held one frame, then issued whatever their number.
  const std::vector<QueryRequest> few = probe_requests(0);
  frame(list_of(few, 2), ++f, true);
  EXPECT_EQ(executor_->stats().issued_last, 0u);
  EXPECT_EQ(executor_->stats().deferred_runs, 1u);
  frame(list_of(few, 2), ++f, true);
  EXPECT_EQ(executor_->stats().issued_last, few.size());
}

// --- reads before the fence -----------------------------------------------
// The interposer knows each batch's counter buffer (the storage buffer bound
// last before the fence), its mapping and its upload size. When the real
// glClientWaitSync first says a batch's fence is signaled, the interposer
// saves the counters, overwrites them with kPoison and reports the fence
// pending for kHide more polls; then it restores them and reports it
// signaled. An executor that reads a counter before it was TOLD the fence is
// signaled reads poison (or the GPU's unfinished zeros), not the counts.
struct FenceCheck {
  static constexpr GLuint kPoison = 0xfffffff0u;
  static constexpr int kHide = 2;
  enum class Phase { Fresh, Hiding, Shown };
  struct Fence {
    GLuint buffer = 0;
    Phase phase = Phase::Fresh;
    int hide = kHide;
    std::vector<std::byte> saved;
  };
  static inline PFNGLMAPNAMEDBUFFERRANGEPROC real_map = nullptr;
  static inline PFNGLBINDBUFFERBASEPROC real_bind = nullptr;
  static inline PFNGLNAMEDBUFFERSUBDATAPROC real_sub_data = nullptr;
  static inline PFNGLFENCESYNCPROC real_fence = nullptr;
  static inline PFNGLCLIENTWAITSYNCPROC real_wait = nullptr;
  static inline PFNGLDELETESYNCPROC real_delete = nullptr;
  static inline std::map<GLuint, const std::byte*> mapped;
  static inline std::map<GLuint, GLsizeiptr> uploaded;
  static inline std::map<GLsync, Fence> fences;
  static inline GLuint last_storage = 0;
  static inline int hidden_polls = 0;

  static void* APIENTRY map(GLuint buffer, GLintptr offset, GLsizeiptr length, GLbitfield access) {
    void* p = real_map(buffer, offset, length, access);
    mapped[buffer] = static_cast<const std::byte*>(p);
    uploaded[buffer] = offset + length;  // the executor writes its batches into the mapping
    return p;
  }
  static void APIENTRY bind(GLenum target, GLuint index, GLuint buffer) {
    if (target == GL_SHADER_STORAGE_BUFFER && buffer != 0) last_storage = buffer;
    real_bind(target, index, buffer);
  }
  static void APIENTRY sub_data(GLuint buffer, GLintptr offset, GLsizeiptr size, const void* data) {
    uploaded[buffer] = offset + size;
    real_sub_data(buffer, offset, size, data);
  }
  static GLsync APIENTRY fence(GLenum condition, GLbitfield flags) {
    const GLsync s = real_fence(condition, flags);
    fences[s].buffer = last_storage;
    return s;
  }
  static GLenum APIENTRY wait(GLsync sync, GLbitfield flags, GLuint64 timeout) {
    const GLenum r = real_wait(sync, flags, timeout);
    const auto it = fences.find(sync);
    if (it == fences.end() || (r != GL_ALREADY_SIGNALED && r != GL_CONDITION_SATISFIED)) return r;
    Fence& f = it->second;
    const GLsizeiptr bytes = uploaded[f.buffer];
    if (f.phase == Phase::Fresh) {
      const std::byte* p = mapped[f.buffer];
      f.saved.assign(p, p + bytes);
      gl::ClearNamedBufferSubData(f.buffer, GL_R32UI, 0, bytes, GL_RED_INTEGER, GL_UNSIGNED_INT,
                                  &kPoison);
      gl::Finish();
      f.phase = Phase::Hiding;
    }
    if (f.phase == Phase::Hiding) {
      if (f.hide-- > 0) {
        ++hidden_polls;
        return GL_TIMEOUT_EXPIRED;
      }
      // Through the mapping (persistent and coherent, writable): the executor's
      // buffers have no GL_DYNAMIC_STORAGE_BIT.
      std::memcpy(const_cast<std::byte*>(mapped[f.buffer]), f.saved.data(), f.saved.size());
      f.phase = Phase::Shown;
    }
    return r;
  }
  static void APIENTRY remove(GLsync sync) {
    fences.erase(sync);
    real_delete(sync);
  }

  FenceCheck() {
    real_map = std::exchange(gl::MapNamedBufferRange, &map);
    real_bind = std::exchange(gl::BindBufferBase, &bind);
    real_sub_data = std::exchange(gl::NamedBufferSubData, &sub_data);
    real_fence = std::exchange(gl::FenceSync, &fence);
    real_wait = std::exchange(gl::ClientWaitSync, &wait);
    real_delete = std::exchange(gl::DeleteSync, &remove);
    mapped.clear();
    uploaded.clear();
    fences.clear();
    last_storage = 0;
    hidden_polls = 0;
  }
  ~FenceCheck() {
    gl::MapNamedBufferRange = real_map;
    gl::BindBufferBase = real_bind;
    gl::NamedBufferSubData = real_sub_data;
    gl::FenceSync = real_fence;
    gl::ClientWaitSync = real_wait;
    gl::DeleteSync = real_delete;
  }
  FenceCheck(const FenceCheck&) = delete;
  FenceCheck& operator=(const FenceCheck&) = delete;
};

TEST_F(QueryExecutorTest, FenceCheckMakesACounterReadBeforeTheSignalSeePoison) {
  const FenceCheck check;
  const Hierarchy& h = probe_hierarchy();
  std::vector<QueryRequest> requests;
  for (NodeId n = 0; n < h.node_count(); ++n) requests.push_back(about(h, n, n));
  const FrontList list = list_of(requests, 1);
  use_executor(1);                                // no minimum batch: issued in frame 1
  frame(list, 1, true);                           // the batch: one draw
  executor_->begin_frame_render_thread(list, 2);  // its fence
  gl::Finish();                                   // the GPU is done with it
  ASSERT_EQ(FenceCheck::fences.size(), 1u);
  const auto& [sync, f] = *FenceCheck::fences.begin();
  ASSERT_NE(FenceCheck::mapped[f.buffer], nullptr);
  const auto* counters = reinterpret_cast<const std::uint32_t*>(FenceCheck::mapped[f.buffer]);
  // Signaled in truth, reported pending: a read now would see the poison.
  EXPECT_EQ(gl::ClientWaitSync(sync, 0, 0), static_cast<GLenum>(GL_TIMEOUT_EXPIRED));
  for (std::size_t i = 0; i < requests.size(); ++i) EXPECT_EQ(counters[i], FenceCheck::kPoison);
  EXPECT_EQ(gl::ClientWaitSync(sync, 0, 0), static_cast<GLenum>(GL_TIMEOUT_EXPIRED));
  // Then signaled, with the counts back: the root's proxy is visible.
  const GLenum r = gl::ClientWaitSync(sync, 0, 0);
  EXPECT_TRUE(r == GL_ALREADY_SIGNALED || r == GL_CONDITION_SATISFIED) << r;
  std::uint32_t root = FenceCheck::kPoison;
  for (std::size_t i = 0; i < requests.size(); ++i) {
    EXPECT_NE(counters[i], FenceCheck::kPoison);
    if (requests[i].node == 0) root = counters[i];
  }
  EXPECT_GT(root, 0u);
  EXPECT_EQ(FenceCheck::hidden_polls, FenceCheck::kHide);
}

TEST_F(QueryExecutorTest, NeverReadsACounterBeforeItsFenceWasSeenSignaled) {
  const Hierarchy& h = probe_hierarchy();
  std::vector<QueryRequest> one_each;
  for (NodeId n = 0; n < h.node_count(); ++n) one_each.push_back(about(h, n, n));
  std::uint64_t f = 0;
  const auto expected = run_to_completion(list_of(one_each, 1), f);
  ASSERT_EQ(expected.size(), one_each.size());

  const FenceCheck check;
  std::vector<QueryRequest> requests;
  for (int rep = 0; rep < 200; ++rep) {
    for (NodeId n = 0; n < h.node_count(); ++n) {
      requests.push_back(about(h, n, static_cast<std::uint32_t>(requests.size())));
    }
  }
  executor_->set_max_issue_per_frame(500);  // several batches, several in flight
  std::size_t answered = 0;
  int wrong = 0;
  // Unfinished frames: fences signal when the GPU gets to them.
  for (int i = 0; i < 400 && answered < requests.size(); ++i) {
    frame(list_of(requests, 2), ++f, i % 7 == 6);
    for (const VisibilityResult& r : executor_->results()) {
      if (r.samples_passed != expected.at(r.node).samples_passed) ++wrong;
      EXPECT_GT(r.frame_read, r.frame_issued);
    }
    answered += executor_->results().size();
    executor_->clear_results();
  }
  EXPECT_EQ(answered, requests.size());
  EXPECT_EQ(wrong, 0) << "answers that read poison or unfinished counters";
  // The check was live: signaled fences were reported pending, and the
  // executor waited them out.
  EXPECT_GE(FenceCheck::hidden_polls, 2 * int(requests.size() / 500));
  EXPECT_GT(executor_->stats().batches, 1u);
}

// Posts one query per iteration (tagged with the iteration) about the root
// and records what comes back, with the frame of each request.
class AskingStrategy final : public Strategy {
 public:
  AskingStrategy() : Strategy({}) {}
  [[nodiscard]] std::string_view name() const override { return "asking"; }
  [[nodiscard]] Mode mode() const override { return Mode::Evolve; }
  void reset(const Hierarchy&) override {}
  void iterate(const IterationInput& in, IterationOutput& out) override {
    request_frames.push_back(in.view.frame);
    for (const VisibilityResult& v : in.view.visibility) seen.push_back({v, in.view.frame});
    out.queries->push_back(query_about(in, 0, static_cast<std::uint32_t>(request_frames.size())));
    out.result.converged = false;
  }
  struct Seen {
    VisibilityResult result;
    std::uint64_t request_frame;
  };
  std::vector<std::uint64_t> request_frames;
  std::vector<Seen> seen;
};

TEST(RenderThreadFrameQueries, ResultsReachTheStrategyFramesLaterOnOneFrameCounter) {
  context();
  auto h = std::make_shared<const Hierarchy>(wall());
  Renderer renderer(*h, {kWidth, kHeight});
  QueryExecutor executor;
  auto strategy = std::make_unique<AskingStrategy>();
  AskingStrategy* s = strategy.get();
  StageOptions o;
  o.launch = Launch::Manual;
  const Camera cam = wall_camera();
  Controller controller(Model{h, TreeCut::root_cut(*h)}, std::move(strategy),
                        view_snapshot(cam, {kWidth, kHeight}, Light{}), o);
  std::map<std::uint64_t, std::uint64_t> first_drawn;  // generation -> frame
  {
    RenderThreadFrame frame(controller, renderer, &executor);
    for (int i = 0; i < 30; ++i) {
      const FrameResult r = frame.run_render_thread(cam, RenderSettings{}, true);
      EXPECT_EQ(r.frame, static_cast<std::uint64_t>(i + 1));  // one counter, from 1
      EXPECT_EQ(r.frame, controller.frame());
      EXPECT_EQ(r.frame, controller.stage().counters().frames);
      first_drawn.emplace(r.generation, r.frame);
      controller.stage().step();
    }
  }
  ASSERT_GE(s->seen.size(), 5u);
  std::map<std::uint32_t, int> per_tag;
  for (const AskingStrategy::Seen& v : s->seen) {
    ++per_tag[v.result.tag];
    // Issued in a frame that drew the list asking for it (generation tag + 1:
    // the initial cut is generation 1 and asks nothing), read later, handed
    // over with a later request.
    const std::uint64_t generation = v.result.tag + 1;
    ASSERT_TRUE(first_drawn.count(generation)) << v.result.tag;
    EXPECT_GE(v.result.frame_issued, first_drawn.at(generation));
    EXPECT_GT(v.result.frame_read, v.result.frame_issued);
    EXPECT_GT(v.request_frame, v.result.frame_read);
    EXPECT_GT(v.result.samples_passed, 0u);  // the root in front of nothing
  }
  for (const auto& [tag, count] : per_tag) EXPECT_EQ(count, 1) << "tag " << tag;  // once
  // The request frames are the same counter: strictly increasing, within the run.
  for (std::size_t i = 1; i < s->request_frames.size(); ++i) {
    EXPECT_GT(s->request_frames[i], s->request_frames[i - 1]);
  }
  EXPECT_LE(s->request_frames.back(), 30u);
}

}  // namespace
}  // namespace treecut::splat
