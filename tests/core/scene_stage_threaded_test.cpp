// The Feedback Stage on a scene (issue 13, docs/architecture.md "Scenes
// through the stage"):
//  - on its own thread with a moving camera while the render side polls,
//    every published list carries a consistent object layout (offsets from
//    0, ascending, ending at the list's size; each object's ids ascending,
//    below its model's node count, covering its model's leaves once): the
//    layout travels in the same buffer as the ids, with the one swap;
//  - a per-object strategy sees the object in model space: an object moved
//    by T gets exactly the cut its model gets from the camera moved by -T;
//  - a scene-level strategy (SceneStrategy) is made once and iterates all
//    objects in one call; its empty lists (objects not drawn) are allowed;
//  - the per-object limit (kMaxPerObjectNodes) is an InputError naming the
//    way out, a scene-level strategy on the same scene is accepted;
//  - a strategy that asks for GPU queries on a scene fails with a
//    StrategyError saying so (never answered for the wrong place);
//  - a strategy switch whose factory fails midway is a StrategyError and
//    the strategy before goes on.
// Runs under TSan in CI (the name ends in _threaded_test).
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <glm/gtc/matrix_transform.hpp>
#include <memory>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "treecut/controller.hpp"
#include "treecut/error.hpp"
#include "treecut/feedback_stage.hpp"
#include "treecut/model.hpp"
#include "treecut/model_io.hpp"
#include "treecut/strategies/optimization.hpp"
#include "treecut/strategies/recursive.hpp"
#include "treecut/tools/generate.hpp"

namespace treecut {
namespace {

std::shared_ptr<const Hierarchy> model_of(tools::ModelKind kind, std::size_t points,
                                          std::uint64_t seed) {
  return std::make_shared<const Hierarchy>(
      build_from_points(tools::generate_model(kind, points, seed)));
}

// `n` objects alternating between two models, on a row along x, turned and
// scaled a little (a stretch on every third one).
std::shared_ptr<const StageScene> row_scene(std::size_t n) {
  auto s = std::make_shared<StageScene>();
  s->models = {model_of(tools::ModelKind::Sphere, 3000, 1),
               model_of(tools::ModelKind::City, 4000, 2)};
  for (std::size_t i = 0; i < n; ++i) {
    glm::mat4 w = glm::translate(glm::mat4(1.0f), glm::vec3(3.0f * float(i), 0.0f, 0.0f));
    w = glm::rotate(w, 0.3f * float(i), glm::vec3(0, 1, 0));
    w = glm::scale(w, i % 3 == 2 ? glm::vec3(1.0f, 1.5f, 0.7f) : glm::vec3(0.8f));
    s->objects.push_back(place_object(static_cast<std::uint32_t>(i % 2), w));
  }
  return s;
}

// Empty when the published list's layout is consistent, else the problem.
std::string layout_problem(const FrontList& list, const StageScene& scene, bool whole_cuts) {
  const std::span<const std::uint32_t> off = list.object_offsets;
  if (list.scene != &scene) return "the list names another scene";
  if (list.hierarchy != nullptr) return "a scene list with a hierarchy";
  if (off.size() != scene.objects.size() + 1) return "offsets: " + std::to_string(off.size());
  if (off.front() != 0 || off.back() != list.nodes.size()) return "offsets do not span the list";
  for (std::size_t i = 0; i < scene.objects.size(); ++i) {
    if (off[i + 1] < off[i]) return "offsets descend at object " + std::to_string(i);
    const Hierarchy& h = *scene.models[scene.objects[i].model];
    const std::span<const NodeId> ids = list.nodes.subspan(off[i], off[i + 1] - off[i]);
    if (!std::is_sorted(ids.begin(), ids.end())) return "object " + std::to_string(i) + " unsorted";
    std::uint64_t points = 0;
    for (const NodeId id : ids) {
      if (id >= h.node_count()) return "object " + std::to_string(i) + ": id past its model";
      points += h.arrays().point_count[id];
    }
    if (whole_cuts && points != h.leaf_count()) {
      return "object " + std::to_string(i) + ": its cut holds " + std::to_string(points) +
             " points of " + std::to_string(h.leaf_count());
    }
  }
  return {};
}

ViewSnapshot camera_at(float t) {
  // Along the row and back, looking at it from the side.
  const float x = 30.0f * (0.5f - 0.5f * std::cos(t));
  return ViewSnapshot::look_at({x, 2.0f, 12.0f}, {x + 4.0f, 0.0f, 0.0f}, {320, 240}, 0.9f, 0.05f,
                               500.0f);
}

void run_moving_camera(const StrategyFactory& factory, bool whole_cuts) {
  const std::shared_ptr<const StageScene> scene = row_scene(24);
  StageOptions options;
  options.launch = Launch::Thread;
  FeedbackStage stage(scene, factory, options);
  // The initial list: every object at its root.
  ASSERT_EQ(layout_problem(stage.front(), *scene, true), "");
  std::uint64_t last_generation = stage.front().generation;
  std::uint64_t exchanged = 0;
  // Bounded in frames (and a generous cap in time for a slow sanitizer run):
  // asserts what each list holds, never how long anything took.
  const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  for (int f = 0; f < 4000 && (exchanged < 40 || f < 400); ++f) {
    ViewSnapshot v = camera_at(0.01f * float(f));
    v.version = static_cast<std::uint64_t>(f + 1);
    stage.set_view(v);
    const FrameLists lists = stage.poll();
    ASSERT_EQ(layout_problem(lists.current, *scene, whole_cuts), "") << "frame " << f;
    ASSERT_GE(lists.current.generation, last_generation);
    if (lists.exchanged) {
      ++exchanged;
      ASSERT_GT(lists.current.generation, last_generation);
    }
    last_generation = lists.current.generation;
    if (std::chrono::steady_clock::now() > give_up) break;
    std::this_thread::yield();
  }
  EXPECT_GT(exchanged, 0u);
  EXPECT_EQ(stage.counters().errors, 0u) << stage.counters().last_error;
  EXPECT_EQ(stage.counters().objects_last, scene->objects.size());
}

TEST(SceneStage, EvolveListsKeepTheirObjectLayoutWhileTheCameraMoves) {
  run_moving_camera([] { return std::make_unique<strategies::OptimizationStrategy>(); }, true);
}

TEST(SceneStage, RebuildListsKeepTheirObjectLayoutWhileTheCameraMoves) {
  run_moving_camera([] { return std::make_unique<strategies::RecursiveStrategy>(); }, true);
}

// Manual stage: request, step, poll until converged; the front list then.
template <class Stage>
void converge(Stage& stage, const ViewSnapshot& view) {
  stage.set_view(view);
  for (int i = 0; i < 200; ++i) {
    (void)stage.poll();
    if (!stage.step() && stage.counters().converged) break;
  }
  (void)stage.poll();
}

TEST(SceneStage, AnObjectIsIteratedInItsModelSpace) {
  const auto sphere = model_of(tools::ModelKind::Sphere, 5000, 3);
  const glm::vec3 t(40.0f, -7.0f, 3.0f);
  auto scene = std::make_shared<StageScene>();
  scene->models = {sphere};
  const glm::mat4 w = glm::translate(glm::mat4(1.0f), t);
  scene->objects.push_back(place_object(0, w));
  StageOptions options;
  options.launch = Launch::Manual;
  const auto make = [] { return std::make_unique<strategies::OptimizationStrategy>(); };
  FeedbackStage on_scene(scene, make, options);
  FeedbackStage on_model(Model{sphere, TreeCut::root_cut(*sphere)}, make(), options);
  const glm::vec3 eye(0.5f, 0.3f, 2.5f), target(0.0f);
  ViewSnapshot world = ViewSnapshot::look_at(eye + t, target + t, {320, 240});
  world.version = 1;
  ViewSnapshot model = ViewSnapshot::look_at(eye, target, {320, 240});
  model.version = 1;
  converge(on_scene, world);
  converge(on_model, model);
  const std::vector<NodeId> a(on_scene.front().nodes.begin(), on_scene.front().nodes.end());
  const std::vector<NodeId> b(on_model.front().nodes.begin(), on_model.front().nodes.end());
  EXPECT_GT(b.size(), 100u);
  // The view matrices differ by float rounding of the translation only.
  const std::size_t common = static_cast<std::size_t>(std::count_if(
      a.begin(), a.end(), [&](NodeId n) { return std::binary_search(b.begin(), b.end(), n); }));
  EXPECT_GE(double(common), 0.98 * double(b.size())) << a.size() << " vs " << b.size();
  EXPECT_NEAR(double(a.size()), double(b.size()), 0.02 * double(b.size()));
}

// A scene-level strategy: object 0 at full detail, every other one not
// drawn; counts its calls.
class EveryFirstStrategy final : public Strategy, public SceneStrategy {
 public:
  explicit EveryFirstStrategy(std::atomic<int>* made) : Strategy({}) { made->fetch_add(1); }
  [[nodiscard]] std::string_view name() const override { return "every_first"; }
  [[nodiscard]] Mode mode() const override { return Mode::Rebuild; }
  void reset(const Hierarchy&) override {}
  void iterate(const IterationInput& in, IterationOutput& out) override {
    const TreeCut all = TreeCut::leaf_cut(in.hierarchy);
    out.nodes->assign(all.nodes().begin(), all.nodes().end());
  }
  void reset_scene(const StageScene& scene) override {
    ++resets;
    objects_seen = scene.objects.size();
  }
  void iterate_scene(const SceneIterationInput& in, SceneIterationOutput& out) override {
    ++iterations;
    const TreeCut all = TreeCut::leaf_cut(in.scene.hierarchy(0));
    out.nodes->assign(all.nodes().rbegin(), all.nodes().rend());  // unsorted: the stage sorts
    out.offsets->assign(in.scene.objects.size() + 1, static_cast<std::uint32_t>(all.size()));
    out.offsets->front() = 0;
    out.result.converged = true;
  }
  int resets = 0, iterations = 0;
  std::size_t objects_seen = 0;
};

TEST(SceneStage, ASceneStrategyIsMadeOnceAndIteratesAllObjectsInOneCall) {
  const std::shared_ptr<const StageScene> scene = row_scene(50);
  std::atomic<int> made{0};
  EveryFirstStrategy* strategy = nullptr;
  StageOptions options;
  options.launch = Launch::Manual;
  FeedbackStage stage(
      scene,
      [&] {
        auto s = std::make_unique<EveryFirstStrategy>(&made);
        strategy = s.get();
        return s;
      },
      options);
  EXPECT_EQ(made.load(), 1);
  converge(stage, camera_at(0.0f));
  ASSERT_NE(strategy, nullptr);
  EXPECT_EQ(strategy->resets, 1);
  EXPECT_EQ(strategy->objects_seen, 50u);
  EXPECT_GE(strategy->iterations, 1);
  const FrontList& f = stage.front();
  EXPECT_EQ(layout_problem(f, *scene, false), "");
  EXPECT_EQ(f.object_offsets[1], scene->models[0]->leaf_count());
  EXPECT_EQ(f.object_offsets.back(), scene->models[0]->leaf_count());
  EXPECT_EQ(stage.counters().errors, 0u) << stage.counters().last_error;
}

TEST(SceneStage, PerObjectStrategiesPastTheLimitAreRefusedNamingTheWayOut) {
  auto scene = std::make_shared<StageScene>();
  scene->models = {model_of(tools::ModelKind::Sphere, 4000, 4)};
  const std::uint64_t nodes = scene->models[0]->node_count();
  const std::size_t n = static_cast<std::size_t>(kMaxPerObjectNodes / nodes) + 1;
  scene->objects.assign(n, SceneObject{});
  ASSERT_GT(scene->object_nodes(), kMaxPerObjectNodes);
  StageOptions options;
  options.launch = Launch::Manual;
  std::atomic<int> instances{0};
  try {
    FeedbackStage stage(
        scene,
        [&] {
          instances.fetch_add(1);
          return std::make_unique<strategies::OptimizationStrategy>();
        },
        options);
    FAIL() << "a per-object strategy over " << scene->object_nodes() << " nodes was accepted";
  } catch (const InputError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find(std::to_string(n) + " objects"), std::string::npos) << what;
    EXPECT_NE(what.find("scene-level strategy"), std::string::npos) << what;
    EXPECT_EQ(what.find('\n'), std::string::npos) << what;
  }
  EXPECT_EQ(instances.load(), 1);  // refused before the per-object instances were made
  // A scene-level strategy keeps no per-object state in the stage: accepted.
  std::atomic<int> made{0};
  FeedbackStage stage(
      scene, [&] { return std::make_unique<EveryFirstStrategy>(&made); }, options);
  EXPECT_EQ(made.load(), 1);
}

class QueryingStrategy final : public Strategy {
 public:
  QueryingStrategy() : Strategy({}) {}
  [[nodiscard]] std::string_view name() const override { return "asks"; }
  [[nodiscard]] Mode mode() const override { return Mode::Evolve; }
  void reset(const Hierarchy&) override {}
  void iterate(const IterationInput& in, IterationOutput& out) override {
    out.queries->push_back(query_about(in, 0, 0, QueryKind::AnySamples));
  }
};

TEST(SceneStage, QueriesOnASceneAreAClearStrategyErrorNotAWrongAnswer) {
  const std::shared_ptr<const StageScene> scene = row_scene(3);
  StageOptions options;
  options.launch = Launch::Manual;
  FeedbackStage stage(
      scene, [] { return std::make_unique<QueryingStrategy>(); }, options);
  ViewSnapshot v = camera_at(0.0f);
  v.version = 1;
  stage.set_view(v);
  (void)stage.poll();
  ASSERT_TRUE(stage.step());
  try {
    (void)stage.poll();
    FAIL() << "no error";
  } catch (const StrategyError& e) {
    EXPECT_NE(std::string(e.what()).find("GPU queries on a scene"), std::string::npos) << e.what();
  }
  // The front list stays the initial one, whole.
  EXPECT_EQ(layout_problem(stage.front(), *scene, true), "");
  EXPECT_EQ(stage.front().generation, 1u);
}

TEST(SceneStage, AStrategySwitchMakesItsInstancesOnTheStageAndKeepsTheLayout) {
  const std::shared_ptr<const StageScene> scene = row_scene(12);
  StageOptions options;
  options.launch = Launch::Manual;
  std::atomic<int> made{0};
  Controller controller(
      scene,
      [&] {
        made.fetch_add(1);
        return std::make_unique<strategies::OptimizationStrategy>();
      },
      camera_at(0.0f), options);
  EXPECT_EQ(made.load(), 12);
  converge(controller.stage(), camera_at(0.5f));
  controller.set_strategy(
      StrategyFactory([] { return std::make_unique<strategies::RecursiveStrategy>(); }));
  EXPECT_EQ(controller.stage().strategy_name(), "recursive");
  ViewSnapshot v = camera_at(1.0f);
  v.version = 99;
  converge(controller.stage(), v);
  EXPECT_EQ(layout_problem(controller.stage().front(), *scene, true), "");
  EXPECT_EQ(controller.stage().counters().errors, 0u) << controller.stage().counters().last_error;
  // set_param reaches every instance: a parameter of the recursive strategy.
  EXPECT_THROW(controller.set_param("no_such_parameter", 1.0), InputError);
}

TEST(SceneStage, AFactoryFailingMidwayLeavesTheStrategyBefore) {
  const std::shared_ptr<const StageScene> scene = row_scene(8);
  StageOptions options;
  options.launch = Launch::Manual;
  FeedbackStage stage(
      scene, [] { return std::make_unique<strategies::OptimizationStrategy>(); }, options);
  converge(stage, camera_at(0.2f));
  int calls = 0;
  // The probe (render thread) and two more on the stage, then a throw.
  stage.set_strategy(StrategyFactory([&]() -> std::unique_ptr<Strategy> {
    if (++calls > 3) throw std::runtime_error("no more instances");
    return std::make_unique<strategies::RecursiveStrategy>();
  }));
  ViewSnapshot v = camera_at(0.4f);
  v.version = 7;
  stage.set_view(v);
  (void)stage.poll();
  ASSERT_TRUE(stage.step());
  EXPECT_THROW((void)stage.poll(), StrategyError);
  EXPECT_EQ(layout_problem(stage.front(), *scene, true), "");
  // The optimization instances go on: the next iterations succeed.
  for (int i = 0; i < 5; ++i) {
    v = camera_at(0.4f + 0.05f * float(i));
    v.version = 8 + static_cast<std::uint64_t>(i);
    stage.set_view(v);
    (void)stage.poll();
    (void)stage.step();
  }
  (void)stage.poll();
  EXPECT_EQ(stage.counters().errors, 1u) << stage.counters().last_error;
  EXPECT_EQ(layout_problem(stage.front(), *scene, true), "");
  EXPECT_EQ(stage.counters().objects_last, 8u);
}

}  // namespace
}  // namespace treecut
