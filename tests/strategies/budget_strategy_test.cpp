// The `budget` strategy (strategies/budget_strategy.hpp; Peng & Cao 2013,
// sections 5 and 6): driven directly through SceneStrategy and through a
// Feedback Stage on a scene:
//  - over a walkthrough the objects' cuts never hold more than N nodes in
//    all, and every non-empty list is a valid cut of its object's model;
//  - an object behind a wall is culled by the HZM, gets nothing, and the
//    share it had without culling goes to the visible objects;
//  - an object behind the camera gets nothing;
//  - PET zeroes a small far object that PET 0 draws;
//  - on a single model it is the best cut of at most N points.
#include "treecut/strategies/budget_strategy.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <glm/gtc/matrix_transform.hpp>
#include <memory>
#include <numeric>
#include <random>
#include <string>
#include <vector>

#include "treecut/feedback_stage.hpp"
#include "treecut/model_io.hpp"
#include "treecut/strategies/builtin.hpp"
#include "treecut/tools/generate.hpp"

namespace treecut {
namespace {

using strategies::BudgetStrategy;

// Points on the six faces of the unit cube [-0.5, 0.5]^3 (a closed surface:
// the culler finds an inner box and takes it as an occluder).
std::shared_ptr<const Hierarchy> cube_model(std::size_t points, std::uint32_t seed) {
  PointSet p;
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> u(-0.5f, 0.5f);
  for (std::size_t i = 0; i < points; ++i) {
    const int face = static_cast<int>(i % 6);
    const int axis = face / 2;
    glm::vec3 q(u(rng), u(rng), u(rng));
    q[axis] = face % 2 ? 0.5f : -0.5f;
    glm::vec3 n(0.0f);
    n[axis] = face % 2 ? 1.0f : -1.0f;
    p.positions.push_back(q);
    p.normals.push_back(n);
  }
  return std::make_shared<const Hierarchy>(build_from_points(std::move(p)));
}

// An object of scene model `model` at `at`, scaled.
SceneObject object(std::uint32_t model, glm::vec3 at, glm::vec3 scale) {
  return place_object(model, glm::scale(glm::translate(glm::mat4(1.0f), at), scale));
}

// Empty when `ids` is a cut of `h` (every leaf under exactly one id).
std::string cut_problem(const Hierarchy& h, std::span<const NodeId> ids) {
  std::vector<std::uint8_t> in(h.node_count(), 0);
  std::uint64_t points = 0;
  for (const NodeId id : ids) {
    if (id >= h.node_count()) return "id past the model";
    if (in[id]) return "id twice";
    in[id] = 1;
    points += h.arrays().point_count[id];
  }
  for (const NodeId id : ids) {
    for (NodeId p = h.parent(id); p != kNoNode; p = h.parent(p)) {
      if (in[p]) return "a node and its ancestor";
    }
  }
  if (points != h.leaf_count()) return "covers " + std::to_string(points) + " points";
  return {};
}

struct Lists {
  std::vector<NodeId> nodes;
  std::vector<std::uint32_t> offsets;
  IterationResult result;
  [[nodiscard]] std::span<const NodeId> of(std::size_t i) const {
    return std::span<const NodeId>(nodes).subspan(offsets[i], offsets[i + 1] - offsets[i]);
  }
};

Lists run(BudgetStrategy& s, const StageScene& scene, const ViewSnapshot& view,
          const Lists* previous = nullptr) {
  Lists out;
  std::vector<QueryRequest> queries;
  const SceneIterationInput in{
      scene,
      view,
      nullptr,
      s.params_version(),
      previous ? std::span<const NodeId>(previous->nodes) : std::span<const NodeId>(),
      previous ? std::span<const std::uint32_t>(previous->offsets)
               : std::span<const std::uint32_t>()};
  SceneIterationOutput o;
  o.nodes = &out.nodes;
  o.offsets = &out.offsets;
  o.queries = &queries;
  s.iterate_scene(in, o);
  out.result = o.result;
  return out;
}

std::size_t cut_total(const Lists& l) {
  return l.nodes.size();
}

TEST(BudgetStrategy, WalkthroughNeverExceedsTheBudgetAndListsAreCuts) {
  const auto cube = cube_model(3000, 1);
  const auto sphere = std::make_shared<const Hierarchy>(
      build_from_points(tools::generate_model(tools::ModelKind::Sphere, 2500, 2)));
  StageScene scene;
  scene.models = {cube, sphere};
  for (int x = 0; x < 8; ++x) {
    for (int z = 0; z < 8; ++z) {
      const bool c = (x + z) % 2 == 0;
      scene.objects.push_back(object(c ? 0 : 1,
                               {4.0f * float(x), 0.0f, -4.0f * float(z)},
                               glm::vec3(c ? 2.0f : 1.0f, c ? 3.0f : 1.0f, 2.0f)));
    }
  }
  for (const double n : {500.0, 20'000.0, 1'000'000.0}) {
    for (const double threads : {1.0, 2.0}) {
      BudgetStrategy s;
      s.set_param("points", n);
      s.set_param("threads", threads);
      s.reset_scene(scene);
      for (int f = 0; f < 30; ++f) {
        const float t = float(f) / 29.0f;
        const glm::vec3 eye(-4.0f + 20.0f * t, 1.0f, 6.0f - 12.0f * t);
        const ViewSnapshot v = ViewSnapshot::look_at(eye, eye + glm::vec3(0.6f, -0.05f, -1.0f),
                                                     {320, 240}, 1.0f, 0.05f, 500.0f);
        const Lists l = run(s, scene, v);
        ASSERT_EQ(l.offsets.size(), scene.objects.size() + 1);
        EXPECT_LE(cut_total(l), static_cast<std::size_t>(n)) << "frame " << f;
        EXPECT_EQ(s.last().selected, cut_total(l));
        EXPECT_LE(s.last().shares, static_cast<std::uint64_t>(n));
        EXPECT_EQ(s.last().visible + s.last().frustum_culled + s.last().occlusion_culled,
                  scene.objects.size());
        std::size_t drawn = 0;
        for (std::size_t i = 0; i < scene.objects.size(); ++i) {
          const auto ids = l.of(i);
          if (ids.empty()) continue;
          ++drawn;
          ASSERT_EQ(cut_problem(scene.hierarchy(i), ids), "")
              << "frame " << f << " object " << i;
          EXPECT_LE(ids.size(), s.shares()[i]);
          EXPECT_TRUE(s.visible()[i]);
        }
        EXPECT_EQ(drawn, s.last().receiving);
        EXPECT_GT(drawn, 0u) << "frame " << f;
      }
    }
  }
}

// A wall of cubes (wide, tall, thin) in front of a small cube, two cubes
// beside the wall in view, one cube behind the camera.
struct WallScene {
  std::shared_ptr<const Hierarchy> cube = cube_model(6000, 3);
  StageScene scene{{cube},
                   {
                       object(0, {0.0f, 0.0f, -10.0f}, {12.0f, 8.0f, 0.5f}),  // 0: the wall
                       object(0, {0.0f, 0.0f, -20.0f}, {1.0f, 1.0f, 1.0f}),   // 1: behind it
                       object(0, {-4.5f, 0.0f, -6.0f}, {1.0f, 1.0f, 1.0f}),   // 2: left, seen
                       object(0, {4.5f, 0.0f, -6.0f}, {1.0f, 1.0f, 1.0f}),    // 3: right, seen
                       object(0, {0.0f, 0.0f, 10.0f}, {1.0f, 1.0f, 1.0f}),    // 4: behind the camera
                   }};
  ViewSnapshot view = ViewSnapshot::look_at({0.0f, 0.0f, 0.0f}, {0.0f, 0.0f, -1.0f}, {400, 300},
                                            1.2f, 0.1f, 200.0f);
};

TEST(BudgetStrategy, CulledObjectGetsNothingAndItsShareGoesToVisibleOnes) {
  WallScene w;
  const double n = 3000;  // well below the points of the visible cubes: all of N is spent
  BudgetStrategy on, off;
  for (BudgetStrategy* s : {&on, &off}) {
    s->set_param("points", n);
    s->set_param("pet", 0.0);
    s->set_param("ct", 0.5);
  }
  off.set_param("culling", 0);
  on.reset_scene(w.scene);
  off.reset_scene(w.scene);
  const Lists lon = run(on, w.scene, w.view);
  const Lists loff = run(off, w.scene, w.view);

  EXPECT_GE(on.last().occluders, 1u);
  EXPECT_EQ(on.last().occlusion_culled, 1u);
  EXPECT_EQ(on.last().frustum_culled, 1u);
  EXPECT_EQ(off.last().frustum_culled, 1u);
  EXPECT_FALSE(on.visible()[1]);
  EXPECT_TRUE(off.visible()[1]);
  EXPECT_TRUE(lon.of(1).empty());
  EXPECT_EQ(on.shares()[1], 0u);
  ASSERT_GT(off.shares()[1], 0u);  // without culling it had a share
  EXPECT_FALSE(loff.of(1).empty());
  // Behind the camera: nothing in either.
  EXPECT_EQ(on.shares()[4], 0u);
  EXPECT_TRUE(lon.of(4).empty());
  EXPECT_TRUE(loff.of(4).empty());
  // The whole budget is spent both times; the visible ones got the hidden
  // one's share.
  const auto visible_sum = [](const BudgetStrategy& s) {
    return std::uint64_t{s.shares()[0]} + s.shares()[2] + s.shares()[3];
  };
  EXPECT_EQ(on.last().shares, static_cast<std::uint64_t>(n));
  EXPECT_EQ(off.last().shares, static_cast<std::uint64_t>(n));
  EXPECT_EQ(visible_sum(on), visible_sum(off) + off.shares()[1]);
  for (const std::size_t i : {0u, 2u, 3u}) EXPECT_GE(on.shares()[i], off.shares()[i]);
}

TEST(BudgetStrategy, PetZeroesSmallObjects) {
  const auto cube = cube_model(2000, 4);
  const StageScene scene{{cube},
                         {
                             object(0, {0.0f, 0.0f, -5.0f}, glm::vec3(1.0f)),    // near: large on screen
                             object(0, {3.0f, 0.0f, -150.0f}, glm::vec3(0.2f)),  // far and small: ~1 px^2
                         }};
  const ViewSnapshot v = ViewSnapshot::look_at({0.0f, 0.0f, 0.0f}, {0.0f, 0.0f, -1.0f}, {320, 240},
                                               1.0f, 0.1f, 500.0f);
  BudgetStrategy s;
  s.set_param("points", 1500);
  s.set_param("culling", 0);
  s.set_param("pet", 0.0);
  s.reset_scene(scene);
  Lists l = run(s, scene, v);
  ASSERT_GT(s.shares()[1], 0u) << "PET 0 draws the small object";
  EXPECT_FALSE(l.of(1).empty());
  s.set_param("pet", 50.0);
  l = run(s, scene, v);
  EXPECT_EQ(s.shares()[1], 0u);
  EXPECT_TRUE(l.of(1).empty());
  EXPECT_EQ(s.last().below_pet, 1u);
  EXPECT_GT(s.shares()[0], 0u);
  EXPECT_EQ(s.last().shares, 1500u);  // the small one's share went to the near one
}

TEST(BudgetStrategy, ThroughTheFeedbackStageOnAScene) {
  WallScene w;
  auto scene = std::make_shared<StageScene>(w.scene);
  const StrategyRegistry registry = strategies::builtin_registry();
  const StrategyFactory factory = [&registry] {
    auto s = registry.create("budget");
    s->set_param("points", 2000);
    return s;
  };
  StageOptions options;
  options.launch = Launch::Manual;
  FeedbackStage stage(scene, factory, options);
  for (int f = 0; f < 6; ++f) {
    ViewSnapshot v = w.view;
    v.view = glm::translate(v.view, glm::vec3(0.4f * float(f), 0.0f, 0.0f));
    v.version = static_cast<std::uint64_t>(f + 1);
    v.finalize();
    stage.set_view(v);
    (void)stage.poll();
    stage.step();
    const FrameLists lists = stage.poll();
    const FrontList& front = lists.current;
    ASSERT_EQ(front.object_offsets.size(), w.scene.objects.size() + 1);
    if (f > 0) {
      EXPECT_LE(front.nodes.size(), 2000u) << "frame " << f;
      EXPECT_TRUE(front.object_offsets[2] == front.object_offsets[1]) << "the hidden cube drawn";
    }
    for (std::size_t i = 0; i < w.scene.objects.size(); ++i) {
      const auto ids = front.nodes.subspan(front.object_offsets[i],
                                           front.object_offsets[i + 1] - front.object_offsets[i]);
      if (!ids.empty()) {
        ASSERT_EQ(cut_problem(*w.cube, ids), "") << "frame " << f;
      }
    }
  }
  EXPECT_GT(stage.counters().iterations, 0u);
}

TEST(BudgetStrategy, OnASingleModelTheBestCutOfNPoints) {
  const auto cube = cube_model(4000, 5);
  BudgetStrategy s;
  s.reset(*cube);
  const ViewSnapshot v =
      ViewSnapshot::look_at({0.0f, 0.0f, 3.0f}, {0.0f, 0.0f, 0.0f}, {320, 240}, 1.0f, 0.1f, 100.0f);
  for (const double n : {0.0, 1.0, 200.0, 1e6}) {
    s.set_param("points", n);
    TreeCut cut = TreeCut::root_cut(*cube);
    std::vector<NodeId> nodes;
    std::vector<QueryRequest> queries;
    const IterationInput in{*cube, v};
    IterationOutput out;
    out.cut = &cut;
    out.nodes = &nodes;
    out.queries = &queries;
    s.iterate(in, out);
    EXPECT_EQ(cut_problem(*cube, nodes), "") << "N = " << n;
    EXPECT_LE(nodes.size(), std::max<std::size_t>(1, static_cast<std::size_t>(n)));
    if (n >= 200) {
      EXPECT_GT(nodes.size(), 100u);
    }
  }
}

}  // namespace
}  // namespace treecut
