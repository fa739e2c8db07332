// The GPU query executor (treecut/splat/query_executor.hpp) on OSMesa: a wall
// the test builds in front of some small spheres and beside others. Every
// occluded proxy answers 0 samples, every visible one more; the answers equal
// each proxy drawn alone against the wall's depth (read after glFinish); the
// requests of a list generation are issued once; and no result is ever read
// before GL_QUERY_RESULT_AVAILABLE said so (the GL entry points interposed,
// with a check that the interposer catches a read that comes too early).
#include "treecut/splat/query_executor.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <memory>
#include <numeric>
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
#include "treecut/splat/renderer.hpp"
#include "treecut/strategy.hpp"
#include "treecut/tree_cut.hpp"

namespace treecut::splat {
namespace {

constexpr int kWidth = 160;
constexpr int kHeight = 120;

GlContext& context() {
  static OsmesaContext ctx(kWidth, kHeight);
  ctx.make_current();
  return ctx;
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

// Each proxy drawn alone against the wall's depth, read after glFinish:
// the reference for one request.
class AloneHook final : public QueryHook {
 public:
  explicit AloneHook(QueryRequest r) : request_(r) {}
  void run(const FrameView& view) override {
    QueryExecutor single;
    FrontList l;
    const std::vector<QueryRequest> one{request_};
    l.generation = 1;
    l.hierarchy = &probe_hierarchy();
    l.queries = one;
    single.begin_frame_render_thread(l, 1);
    single.run(view);  // issues the one query
    gl::Finish();
    single.begin_frame_render_thread(l, 2);
    single.run(view);  // reads it: available after glFinish
    if (!single.results().empty()) samples = single.results().front().samples_passed;
  }
  QueryRequest request_;
  std::int64_t samples = -1;
};

TEST_F(QueryExecutorTest, OccludedProxiesAnswerZeroAndVisibleOnesMoreLikeEachAlone) {
  const Hierarchy& h = probe_hierarchy();
  std::vector<QueryRequest> requests;
  for (NodeId n = 0; n < h.node_count(); ++n) requests.push_back({0, n, n, QueryKind::Samples});
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
  // Every node (inner ones too) equals its proxy drawn alone.
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

TEST_F(QueryExecutorTest, AnySamplesAnswersZeroOrOne) {
  std::vector<QueryRequest> requests;
  for (std::uint32_t i = 0; i < probes().size(); ++i) {
    requests.push_back({0, leaf_at(probes()[i].center), i, QueryKind::AnySamples});
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
  for (NodeId n = 0; n < h.node_count(); ++n) requests.push_back({0, n, n, QueryKind::Samples});
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

  // A new generation queues its own requests once; unissued old ones are dropped.
  const FrontList next = list_of(requests, 8);
  frame(next, ++f, true);
  const FrontList third = list_of(requests, 9);
  frame(third, ++f, true);
  EXPECT_EQ(executor_->stats().dropped, requests.size() - 2);
}

// --- reads before GL_QUERY_RESULT_AVAILABLE --------------------------------
// The interposer remembers, per query object, whether the last availability
// check said "available" since the query was last begun; a GL_QUERY_RESULT
// read of an object without one is a violation.
struct ReadCheck {
  static inline PFNGLGETQUERYOBJECTUIVPROC real_uiv = nullptr;
  static inline PFNGLGETQUERYOBJECTUI64VPROC real_ui64v = nullptr;
  static inline PFNGLBEGINQUERYPROC real_begin = nullptr;
  static inline std::map<GLuint, bool> available;
  static inline int violations = 0;
  static inline int checks_false = 0;

  static void APIENTRY begin(GLenum target, GLuint id) {
    available[id] = false;
    real_begin(target, id);
  }
  static void APIENTRY uiv(GLuint id, GLenum pname, GLuint* params) {
    if (pname == GL_QUERY_RESULT) {
      if (!available[id]) ++violations;
      real_uiv(id, pname, params);
      return;
    }
    real_uiv(id, pname, params);
    if (pname == GL_QUERY_RESULT_AVAILABLE) {
      available[id] = *params != GL_FALSE;
      if (*params == GL_FALSE) ++checks_false;
    }
  }
  static void APIENTRY ui64v(GLuint id, GLenum pname, GLuint64* params) {
    if (pname == GL_QUERY_RESULT && !available[id]) ++violations;
    real_ui64v(id, pname, params);
  }

  ReadCheck() {
    real_uiv = gl::GetQueryObjectuiv;
    real_ui64v = gl::GetQueryObjectui64v;
    real_begin = gl::BeginQuery;
    gl::GetQueryObjectuiv = &uiv;
    gl::GetQueryObjectui64v = &ui64v;
    gl::BeginQuery = &begin;
    available.clear();
    violations = 0;
    checks_false = 0;
  }
  ~ReadCheck() {
    gl::GetQueryObjectuiv = real_uiv;
    gl::GetQueryObjectui64v = real_ui64v;
    gl::BeginQuery = real_begin;
  }
};

TEST(QueryReadCheck, CatchesAResultReadBeforeAvailabilityWasChecked) {
  context();
  const ReadCheck check;
  gl::Query q = gl::Query::create(GL_SAMPLES_PASSED);
  q.begin();
  q.end();
  GLuint64 value = 0;
  // The blocking read a careless executor would do.
  gl::GetQueryObjectui64v(q.id(), GL_QUERY_RESULT, &value);
  EXPECT_EQ(ReadCheck::violations, 1);
  // After a check that said "available", the same read is fine.
  gl::Finish();
  EXPECT_TRUE(q.try_result().has_value());
  EXPECT_EQ(ReadCheck::violations, 1);
}

TEST_F(QueryExecutorTest, NeverReadsAResultBeforeItIsAvailable) {
  const ReadCheck check;
  const Hierarchy& h = probe_hierarchy();
  std::vector<QueryRequest> requests;
  for (int rep = 0; rep < 200; ++rep) {
    for (NodeId n = 0; n < h.node_count(); ++n) {
      requests.push_back({0, n, static_cast<std::uint32_t>(requests.size()), QueryKind::Samples});
    }
  }
  std::uint64_t f = 0;
  std::size_t answered = 0;
  // Unfinished frames: results arrive when the GPU gets to them.
  for (int i = 0; i < 200 && answered < requests.size(); ++i) {
    frame(list_of(requests, 1), ++f, i % 7 == 6);
    answered += executor_->results().size();
    executor_->clear_results();
  }
  EXPECT_EQ(answered, requests.size());
  EXPECT_EQ(ReadCheck::violations, 0);
  std::printf("availability checks that said 'not yet': %d\n", ReadCheck::checks_false);
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
    out.queries->push_back(
        {0, 0, static_cast<std::uint32_t>(request_frames.size()), QueryKind::Samples});
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
