// The faster paths of the budget strategy's frame (docs/many-objects.md,
// "Benchmark"; Peng & Cao, I3D 2013, ../shared/papers/
// occlusion-culling-with-parallel-lod.txt, sections 5 and 6) give what the
// plain definitions give:
//   - the active occluder set, chosen per chunk by nth_element over the
//     candidates in object order, is the full sort of the Eq. 3 weights over
//     the COS (compactness order, several chunks, 1 and 2 threads);
//   - best_cut into a reused list (and a reused per-thread heap) is the cut
//     best_cut returns fresh, one view and share after another;
//   - budget_items from an array of P_i is budget_items from the objects.
#include <gtest/gtest.h>

#include <algorithm>
#include <glm/gtc/matrix_transform.hpp>
#include <random>
#include <vector>

#include "test_support.hpp"
#include "treecut/culling/hzm.hpp"
#include "treecut/model_io.hpp"
#include "treecut/ply.hpp"
#include "treecut/strategies/budget.hpp"

namespace treecut::culling {
namespace {

using namespace treecut::strategies::many;

TEST(ManyObjectsSelect, nth_element_per_chunk_picks_the_full_sorts_occluders) {
  // 20,000 buildings: five chunks of candidates. Compactness spread so that
  // the COS (compactness order) is not the object order and some objects
  // fall below CT; a few without an inner box.
  std::vector<ObjectBounds> objects = box_city(20000, 3);
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> unit(0.0f, 1.0f);
  for (ObjectBounds& o : objects) {
    o.compactness = 0.3f + 0.7f * unit(rng);
    if (unit(rng) < 0.05f) o.has_inner = false;
  }
  const auto views = city_views(20000, 6, 3, {1280, 720});
  for (const unsigned threads : {1u, 2u}) {
    WorkerPool pool(threads);
    for (const std::size_t active : {std::size_t{1}, std::size_t{32}, std::size_t{300}}) {
      HzmParams params;
      params.active = active;
      HzmCuller culler(params);
      culler.preprocess(objects);
      for (const ViewSnapshot& snap : views) {
        const ViewSnapshot& view = snap;
        culler.project(objects, view, &pool);
        culler.select_occluders(objects, view, &pool);
        // The definition: every COS member's Eq. 3 weight, all sorted.
        std::vector<std::pair<float, std::uint32_t>> w;
        for (const std::uint32_t i : culler.candidates()) {
          const ObjectBounds& o = objects[i];
          int k = 0;
          for (int a = 1; a < 3; ++a)
            if (o.box.half[a] < o.box.half[k]) k = a;
          const float x = occluder_weight(o, o.box.axes[k], culler.rects()[i], view);
          if (x > 0.0f) w.push_back({x, i});
        }
        std::sort(w.begin(), w.end(), [](auto a, auto b) {
          return a.first != b.first ? a.first > b.first : a.second < b.second;
        });
        if (w.size() > active) w.resize(active);
        ASSERT_GT(w.size(), 0u);
        ASSERT_EQ(culler.active().size(), w.size()) << threads << " threads, AOS " << active;
        for (std::size_t k = 0; k < w.size(); ++k) {
          EXPECT_EQ(culler.active()[k], w[k].second) << threads << " threads, rank " << k;
        }
      }
    }
  }
}

TEST(ManyObjectsSelect, budget_items_from_an_array_of_points) {
  const std::vector<ObjectBounds> objects = box_city(10000, 4);
  const ViewSnapshot view = city_views(10000, 1, 4, {1280, 720})[0];
  HzmCuller culler;
  culler.preprocess(objects);
  WorkerPool pool(2);
  culler.cull(objects, view, &pool);
  std::vector<std::uint32_t> points;
  for (const ObjectBounds& o : objects) points.push_back(o.points);
  std::vector<BudgetItem> a, b;
  budget_items(objects, culler.rects(), culler.visible(), a, &pool);
  budget_items(points, culler.rects(), culler.visible(), b, &pool);
  ASSERT_EQ(a.size(), b.size());
  std::size_t nonzero = 0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    EXPECT_EQ(a[i].area, b[i].area) << i;
    EXPECT_EQ(a[i].depth, b[i].depth) << i;
    EXPECT_EQ(a[i].points, b[i].points) << i;
    nonzero += a[i].points > 0;
  }
  EXPECT_GT(nonzero, 10u);
}

TEST(ManyObjectsSelect, best_cut_into_a_reused_list_is_the_fresh_cut) {
  const auto path = test::shared_asset("bun_zipper.ply");
  if (!path) GTEST_SKIP() << "../shared/assets/bun_zipper.ply is absent";
  const Hierarchy h = build_from_points(load_ply(*path));
  const glm::vec3 center = 0.5f * (h.bounds_min() + h.bounds_max());
  std::vector<NodeId> reused;
  std::size_t compared = 0;
  // Shares up and down, near and far: the reused list and heap hold the
  // previous object's nodes each time.
  for (const float distance : {0.15f, 0.4f, 1.5f}) {
    const auto view = ViewSnapshot::look_at(center + glm::vec3(0.0f, 0.05f, distance), center,
                                            {800, 600}, 0.8f, 0.01f, 100.0f);
    for (const std::size_t n : {20000u, 3u, 5000u, 0u, 1u, 100u, 35000u}) {
      best_cut(h, view, n, reused);
      EXPECT_EQ(reused, best_cut(h, view, n)) << distance << " " << n;
      compared += reused.size();
    }
  }
  EXPECT_GT(compared, 1000u);
}

}  // namespace
}  // namespace treecut::culling
