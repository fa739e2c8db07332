// Budgeted LOD selection (strategies/include/treecut/strategies/budget.hpp;
// Peng & Cao, I3D 2013, section 5, Eq. 1 and PET): the shares follow the
// closed form, never exceed N or an object's points, PET zeroes small
// objects, culled objects give their share to visible ones; each share
// becomes the best cut of that size by the optimization priority (bunny).
#include "treecut/strategies/budget.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <glm/gtc/matrix_transform.hpp>
#include <numeric>
#include <random>
#include <vector>

#include "test_support.hpp"
#include "treecut/culling/hzm.hpp"
#include "treecut/model_io.hpp"
#include "treecut/ply.hpp"
#include "treecut/strategies/optimization.hpp"
#include "treecut/tree_cut.hpp"

namespace treecut::strategies::many {
namespace {

using namespace treecut::culling;

std::uint64_t sum(const std::vector<std::uint32_t>& v) {
  return std::accumulate(v.begin(), v.end(), std::uint64_t{0});
}

// Eq. 1 by hand: N * w_i^(1/alpha) / sum_j w_j^(1/alpha),
// w_i = beta * A_i / D_i * P_i^beta, beta = alpha - 1.
std::vector<double> formula(const std::vector<BudgetItem>& items, double n, double alpha) {
  const double beta = alpha - 1.0;
  std::vector<double> t;
  for (const BudgetItem& it : items) {
    const double w = beta * it.area / it.depth * std::pow(static_cast<double>(it.points), beta);
    t.push_back(std::pow(w, 1.0 / alpha));
  }
  const double s = std::accumulate(t.begin(), t.end(), 0.0);
  for (double& x : t) x = n * x / s;
  return t;
}

TEST(Budget, shares_follow_eq1) {
  // Five objects: near and large, far, small on screen but many points, ...
  const std::vector<BudgetItem> items = {
      {40000.0f, 5.0f, 500000}, {900.0f, 80.0f, 200000},   {12000.0f, 20.0f, 1000000},
      {300.0f, 3.0f, 800000},   {2500.0f, 150.0f, 400000},
  };
  for (const double alpha : {3.0, 2.0, 1.5}) {
    BudgetParams p;
    p.total = 300000;
    p.alpha = alpha;
    p.pet = 1.0;
    std::vector<std::uint32_t> shares;
    const BudgetStats st = allocate_budget(items, p, shares);
    const auto want = formula(items, 300000.0, alpha);
    ASSERT_EQ(shares.size(), items.size());
    for (std::size_t i = 0; i < items.size(); ++i) {
      ASSERT_LT(want[i], items[i].points) << "the hand-made scene should not hit a cap";
      EXPECT_NEAR(shares[i], want[i], 1.0) << "alpha " << alpha << " object " << i;
    }
    EXPECT_EQ(st.total, 300000u);
    EXPECT_EQ(sum(shares), 300000u);
    EXPECT_EQ(st.capped, 0u);
    // eq1_shares is the formula too.
    const auto e = eq1_shares(items, p);
    for (std::size_t i = 0; i < items.size(); ++i) EXPECT_NEAR(e[i], want[i], 1e-6 * want[i]);
  }
  // alpha = 3: the first object's share, worked out: the terms
  // (A / D * P^2)^(1/3) are 2.52e5, 2.11e4, ... (formula above); a larger
  // area, a nearer depth or more points each raise a share.
  BudgetParams p;
  p.total = 300000;
  std::vector<std::uint32_t> base, more;
  allocate_budget(items, p, base);
  for (int change = 0; change < 3; ++change) {
    auto changed = items;
    if (change == 0) changed[1].area *= 2.0f;
    if (change == 1) changed[1].depth *= 0.5f;
    if (change == 2) changed[1].points *= 2;
    allocate_budget(changed, p, more);
    EXPECT_GT(more[1], base[1]) << change;
  }
}

TEST(Budget, pet_zeroes_small_objects) {
  std::vector<BudgetItem> items = {{5000.0f, 10.0f, 100000},
                                   {0.8f, 1.0f, 900000},
                                   {1.5f, 1.0f, 900000},
                                   {3000.0f, 30.0f, 100000}};
  BudgetParams p;
  p.total = 50000;
  p.pet = 2.0;  // square pixels
  std::vector<std::uint32_t> shares;
  const BudgetStats st = allocate_budget(items, p, shares);
  EXPECT_EQ(shares[1], 0u);
  EXPECT_EQ(shares[2], 0u);
  EXPECT_EQ(st.below_pet, 2u);
  EXPECT_GT(shares[0], 0u);
  EXPECT_GT(shares[3], 0u);
  EXPECT_EQ(sum(shares), 50000u);  // what they would have had goes to the others
  // The two left follow Eq. 1 between themselves.
  const auto want = formula({items[0], items[3]}, 50000.0, 3.0);
  EXPECT_NEAR(shares[0], want[0], 1.0);
  EXPECT_NEAR(shares[3], want[1], 1.0);
  // Without the threshold they do get points.
  p.pet = 0.0;
  allocate_budget(items, p, shares);
  EXPECT_GT(shares[1], 0u);
  EXPECT_GT(shares[2], 0u);
}

TEST(Budget, capped_at_available_points_and_redistributed) {
  // Object 0 would get most of the budget but has only 1,000 points.
  const std::vector<BudgetItem> items = {
      {90000.0f, 2.0f, 1000}, {900.0f, 50.0f, 800000}, {4000.0f, 40.0f, 700000}};
  BudgetParams p;
  p.total = 100000;
  std::vector<std::uint32_t> shares;
  const BudgetStats st = allocate_budget(items, p, shares);
  EXPECT_EQ(shares[0], 1000u);
  EXPECT_EQ(st.capped, 1u);
  EXPECT_EQ(sum(shares), 100000u);
  // The other two share the rest by Eq. 1.
  const auto want = formula({items[1], items[2]}, 99000.0, 3.0);
  EXPECT_NEAR(shares[1], want[0], 1.0);
  EXPECT_NEAR(shares[2], want[1], 1.0);
  // A budget above every point: everything, and no more.
  p.total = 10'000'000;
  allocate_budget(items, p, shares);
  EXPECT_EQ(shares, (std::vector<std::uint32_t>{1000, 800000, 700000}));
}

TEST(Budget, total_never_exceeds_n) {
  std::mt19937 rng(21);
  std::uniform_real_distribution<float> area(0.0f, 20000.0f), depth(0.1f, 500.0f);
  std::uniform_int_distribution<std::uint32_t> points(0, 300000);
  WorkerPool pool(2);
  for (int round = 0; round < 40; ++round) {
    const std::size_t m = round < 20 ? 1 + rng() % 50 : 10000 + rng() % 20000;
    std::vector<BudgetItem> items(m);
    std::uint64_t all = 0;
    for (BudgetItem& it : items) {
      it = {rng() % 5 == 0 ? 0.0f : area(rng), depth(rng), points(rng)};
      if (it.area >= 1.0f) all += it.points;
    }
    BudgetParams p;
    p.total = std::uniform_int_distribution<std::uint64_t>(0, 2 * all + 10)(rng);
    p.alpha = std::uniform_real_distribution<double>(1.2, 4.0)(rng);
    std::vector<std::uint32_t> shares, serial;
    const BudgetStats st = allocate_budget(items, p, shares, &pool);
    allocate_budget(items, p, serial, nullptr);
    EXPECT_EQ(shares, serial) << "the thread count changed a share";
    EXPECT_LE(sum(shares), p.total);
    EXPECT_EQ(sum(shares), std::min(p.total, all)) << "round " << round;
    EXPECT_EQ(st.total, sum(shares));
    for (std::size_t i = 0; i < m; ++i) {
      EXPECT_LE(shares[i], items[i].points);
      if (items[i].area < 1.0f) {
        EXPECT_EQ(shares[i], 0u);
      }
    }
  }
}

TEST(Budget, culled_objects_give_their_share_to_visible_ones) {
  // A city street: the culler's visible set into the budget.
  const auto objects = box_city(5000, 8);
  const auto views = city_views(5000, 4, 8, {640, 360});
  WorkerPool pool(2);
  std::size_t culled_total = 0;
  for (const auto& snap : views) {
    const ViewSnapshot& view = snap;
    HzmCuller culler;
    culler.preprocess(objects);
    culler.cull(objects, view, &pool);
    std::vector<BudgetItem> all_items, visible_items;
    budget_items(objects, culler.rects(), {}, all_items);
    budget_items(objects, culler.rects(), culler.visible(), visible_items);
    // A budget the visible objects cannot fill alone (no share is capped).
    std::uint64_t visible_points = 0;
    for (std::size_t i = 0; i < objects.size(); ++i)
      if (culler.visible()[i]) visible_points += objects[i].points;
    BudgetParams p;
    p.total = visible_points / 20;
    std::vector<std::uint32_t> without, with;
    allocate_budget(all_items, p, without, &pool);
    allocate_budget(visible_items, p, with, &pool);
    EXPECT_LE(sum(with), p.total);
    EXPECT_EQ(sum(with), sum(without));  // the same budget, spent elsewhere
    std::uint64_t to_culled = 0;
    for (std::size_t i = 0; i < objects.size(); ++i) {
      if (culler.states()[i] == ObjectState::Occluded) {
        EXPECT_EQ(with[i], 0u);
        to_culled += without[i];
        ++culled_total;
      } else {
        EXPECT_GE(with[i], without[i]) << "a visible object lost points to culling";
      }
      if (culler.states()[i] == ObjectState::Outside) {
        EXPECT_EQ(with[i], 0u);
      }
    }
    // What the culled objects had is now with the visible ones.
    std::uint64_t gained = 0;
    for (std::size_t i = 0; i < objects.size(); ++i)
      if (culler.visible()[i]) gained += with[i] - without[i];
    EXPECT_EQ(gained, to_culled);
  }
  EXPECT_GT(culled_total, 0u);
}

class BunnyCut : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    const auto path = test::shared_asset("bun_zipper.ply");
    if (!path) return;
    hierarchy_ = new Hierarchy(build_from_points(load_ply(*path)));
  }
  static void TearDownTestSuite() {
    delete hierarchy_;
    hierarchy_ = nullptr;
  }
  static Hierarchy* hierarchy_;
};
Hierarchy* BunnyCut::hierarchy_ = nullptr;

TEST_F(BunnyCut, best_cut_of_a_share_by_the_optimization_priority) {
  if (hierarchy_ == nullptr) GTEST_SKIP() << "../shared/assets/bun_zipper.ply is absent";
  const Hierarchy& h = *hierarchy_;
  // The bunny placed in a world by a transform, seen from a world camera.
  const glm::mat4 transform = glm::translate(glm::mat4(1.0f), glm::vec3(10.0f, 0.0f, -3.0f)) *
                              glm::scale(glm::mat4(1.0f), glm::vec3(20.0f));
  const glm::vec3 center =
      glm::vec3(transform * glm::vec4(0.5f * (h.bounds_min() + h.bounds_max()), 1.0f));
  const auto world = ViewSnapshot::look_at(center + glm::vec3(1.0f, 1.0f, 6.0f), center, {800, 600},
                                           0.8f, 0.01f, 100.0f);
  const ViewSnapshot view = object_view(world, transform);
  const CutParams params;
  EXPECT_TRUE(best_cut(h, view, 0, params).empty());
  EXPECT_EQ(best_cut(h, view, 1, params), std::vector<NodeId>{h.root()});
  for (const std::size_t n : {2u, 3u, 100u, 5000u, 20000u, 1000000u}) {
    const std::vector<NodeId> nodes = best_cut(h, view, n, params);
    ASSERT_EQ(TreeCut::validate(h, nodes), "") << n;
    EXPECT_LE(nodes.size(), n);
    const TreeCut cut = TreeCut::from_nodes(h, nodes);
    const auto pr = [&](NodeId x, float* size = nullptr) {
      return OptimizationStrategy::priority(h, view, x, params.curvature_weight, size);
    };
    // Refinable cut nodes (inner, big enough, in view): the best priority
    // by child count; coarsenable parents (every child in the cut).
    float best_refinable[5] = {-1.0f, -1.0f, -1.0f, -1.0f, -1.0f};
    bool any_refinable = false;
    std::vector<NodeId> parents;
    for (const NodeId x : nodes) {
      float size = 0.0f;
      const float p = pr(x, &size);
      if (!h.is_leaf(x) && size >= params.min_size && p > 0.0f) {
        // Maximal: no refinable node still fits.
        EXPECT_GT(nodes.size() + h.child_count(x) - 1, n) << "node " << x << " would fit";
        best_refinable[h.child_count(x)] = std::max(best_refinable[h.child_count(x)], p);
        any_refinable = true;
      }
      if (x != h.root() && h.is_first_child(x) && cut.can_coarsen(h, h.parent(x))) {
        parents.push_back(h.parent(x));
      }
    }
    // Ordered: no coarsenable parent ranks below a refinable node whose
    // children it would make room for (the optimization strategy's fixed point).
    for (const NodeId q : parents) {
      for (unsigned c = 2; c <= h.child_count(q); ++c) {
        EXPECT_GE(pr(q), best_refinable[c]) << "parent " << q << ", children " << c;
      }
    }
    // Enough for everything: refined wherever the priority allows.
    if (n >= h.node_count()) {
      EXPECT_FALSE(any_refinable);
    }
  }
  // The optimization strategy itself, run to convergence at the same budget
  // from the root, reaches a cut of (about) the same size and no better
  // total priority.
  OptimizationStrategy opt;
  opt.set_param("max_nodes", 5000);
  opt.reset(h);
  TreeCut cut = TreeCut::root_cut(h);
  for (int it = 0; it < 200; ++it) {
    std::vector<NodeId> out_nodes;
    std::vector<QueryRequest> queries;
    IterationInput in{h, view, 0, nullptr, opt.params_version()};
    IterationOutput out;
    out.cut = &cut;
    out.nodes = &out_nodes;
    out.queries = &queries;
    opt.iterate(in, out);
    if (out.result.converged) break;
  }
  const auto mine = best_cut(h, view, 5000, params);
  EXPECT_LE(cut.size(), 5000u);
  EXPECT_GE(mine.size() + 3, cut.size());
}

}  // namespace
}  // namespace treecut::strategies::many
