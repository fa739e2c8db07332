// Hierarchy build: structural invariants on generated and real models,
// determinism, degenerate inputs.
#include "treecut/hierarchy.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <tuple>

#include "test_support.hpp"
#include "treecut/attributes.hpp"
#include "treecut/model_io.hpp"
#include "treecut/ply.hpp"
#include "treecut/tools/generate.hpp"

using namespace treecut;
using namespace treecut::tools;

namespace {

Hierarchy build(PointSet ps, BuildOptions b = {}) {
  complete_attributes(ps);
  return build_hierarchy(std::move(ps), b);
}

std::vector<glm::vec3> sorted_leaf_centers(const Hierarchy& h) {
  std::vector<glm::vec3> v;
  for (NodeId n = 0; n < h.node_count(); ++n)
    if (h.is_leaf(n)) v.push_back(h.center(n));
  auto less = [](glm::vec3 a, glm::vec3 b) {
    return std::tie(a.x, a.y, a.z) < std::tie(b.x, b.y, b.z);
  };
  std::sort(v.begin(), v.end(), less);
  return v;
}

bool same_bytes(const Hierarchy& a, const Hierarchy& b) {
  auto eq = [](auto x, auto y) {
    return x.size() == y.size() && std::equal(reinterpret_cast<const char*>(x.data()),
                                              reinterpret_cast<const char*>(x.data() + x.size()),
                                              reinterpret_cast<const char*>(y.data()));
  };
  const auto &x = a.arrays(), &y = b.arrays();
  return eq(x.center_radius, y.center_radius) && eq(x.splat_radius, y.splat_radius) &&
         eq(x.normal_cone, y.normal_cone) && eq(x.color, y.color) && eq(x.priority, y.priority) &&
         eq(x.point_count, y.point_count) && eq(x.parent, y.parent) &&
         eq(x.first_child, y.first_child) && eq(x.child_count, y.child_count) &&
         eq(x.depth, y.depth);
}

}  // namespace

class GeneratedModels : public ::testing::TestWithParam<std::string> {};

TEST_P(GeneratedModels, InvariantsHold) {
  const Hierarchy h = build(generate_model(parse_model_kind(GetParam()), 20000, 7));
  EXPECT_EQ(check_invariants(h), "");
  EXPECT_EQ(h.leaf_count(), 20000u);
  EXPECT_GT(h.node_count(), 20000u);
  EXPECT_EQ(h.level_begin(h.level_count()), h.node_count());
}

TEST_P(GeneratedModels, InvariantsHoldWithParentsOnRealPoints) {
  BuildOptions b;
  b.parent_at_real_point = true;
  PointSet ps = generate_model(parse_model_kind(GetParam()), 5000, 3);
  const std::vector<glm::vec3> inputs = ps.positions;
  const Hierarchy h = build(std::move(ps), b);
  EXPECT_EQ(check_invariants(h), "");
  // Every node, not only the leaves, sits on an input point.
  std::vector<glm::vec3> sorted = inputs;
  auto less = [](glm::vec3 a, glm::vec3 c) {
    return std::tie(a.x, a.y, a.z) < std::tie(c.x, c.y, c.z);
  };
  std::sort(sorted.begin(), sorted.end(), less);
  for (NodeId n = 0; n < h.node_count(); n += 97)
    EXPECT_TRUE(std::binary_search(sorted.begin(), sorted.end(), h.center(n), less))
        << "node " << n;
}

INSTANTIATE_TEST_SUITE_P(Kinds, GeneratedModels, ::testing::Values("sphere", "terrain", "city"));

TEST(Hierarchy, LeavesAreExactlyTheInputPoints) {
  PointSet ps = generate_model(ModelKind::Terrain, 3001, 11);
  std::vector<glm::vec3> inputs = ps.positions;
  const Hierarchy h = build(std::move(ps));
  auto less = [](glm::vec3 a, glm::vec3 b) {
    return std::tie(a.x, a.y, a.z) < std::tie(b.x, b.y, b.z);
  };
  std::sort(inputs.begin(), inputs.end(), less);
  EXPECT_EQ(sorted_leaf_centers(h), inputs);
}

// Issue 29: each attribute over the nodes. A leaf holds its point's value;
// a measure's node the point-weighted mean of its children, a category's
// node the children's value with the most points; NaN counts for nothing.
TEST(Hierarchy, AttributesAreSummarizedPerNode) {
  PointSet ps = generate_model(ModelKind::Terrain, 4000, 5);
  PointAttribute intensity{.name = "intensity", .kind = AttributeKind::measure, .offset = 0.0};
  PointAttribute cls{.name = "classification", .kind = AttributeKind::category, .offset = 0.0};
  for (std::size_t i = 0; i < ps.size(); ++i) {
    const glm::vec3 p = ps.positions[i];
    intensity.values.push_back(i % 17 == 0 ? NAN : 100.0f + 50.0f * p.x);
    cls.values.push_back(p.x > 0.2f ? 6.0f : p.y > 0.0f ? 3.0f : 2.0f);
  }
  std::map<std::tuple<float, float, float>, std::pair<float, float>> by_position;
  for (std::size_t i = 0; i < ps.size(); ++i) {
    const glm::vec3 p = ps.positions[i];
    by_position[{p.x, p.y, p.z}] = {intensity.values[i], cls.values[i]};
  }
  ps.attributes = {intensity, cls};
  const Hierarchy h = build(std::move(ps));
  ASSERT_EQ(h.attributes().size(), 2u);
  const NodeAttribute& mean = h.attributes()[0];
  const NodeAttribute& mode = h.attributes()[1];
  EXPECT_EQ(mean.name, "intensity");
  EXPECT_EQ(h.find_attribute("classification"), &mode);
  EXPECT_EQ(h.find_attribute("nothing"), nullptr);
  EXPECT_FLOAT_EQ(mean.min, 100.0f + 50.0f * h.bounds_min().x);
  std::size_t interior = 0;
  for (NodeId n = 0; n < h.node_count(); ++n) {
    if (h.is_leaf(n)) {
      const glm::vec3 c = h.center(n);
      const auto [v, k] = by_position.at({c.x, c.y, c.z});
      EXPECT_TRUE(v == mean.values[n] || (std::isnan(v) && std::isnan(mean.values[n]))) << n;
      EXPECT_EQ(mode.values[n], k) << n;
      continue;
    }
    ++interior;
    double sum = 0, weight = 0;
    std::map<float, std::uint64_t> votes;
    for (NodeId c = h.first_child(n); c < h.first_child(n) + h.child_count(n); ++c) {
      const double w = h.arrays().point_count[c];
      if (!std::isnan(mean.values[c])) sum += w * mean.values[c], weight += w;
      votes[mode.values[c]] += h.arrays().point_count[c];
    }
    if (weight > 0) {
      EXPECT_NEAR(mean.values[n], sum / weight, 1e-3) << n;
    } else {
      EXPECT_TRUE(std::isnan(mean.values[n])) << n;
    }
    std::uint64_t best = 0;
    for (const auto& [value, count] : votes) best = std::max(best, count);
    EXPECT_EQ(votes.at(mode.values[n]), best) << n;
  }
  EXPECT_GT(interior, 1000u);
}

TEST(Hierarchy, SamePointsGiveByteIdenticalArraysForAnyThreadCount) {
  BuildOptions one, many;
  one.threads = 1;
  many.threads = 4;
  const Hierarchy a = build(generate_model(ModelKind::City, 30000, 5), one);
  const Hierarchy b = build(generate_model(ModelKind::City, 30000, 5), many);
  EXPECT_TRUE(same_bytes(a, b));
}

TEST(Hierarchy, DuplicatePointsTerminateWithBoundedDepth) {
  PointSet ps;
  ps.positions.assign(5000, glm::vec3(1.0f, 2.0f, 3.0f));
  const Hierarchy h = build(std::move(ps));
  EXPECT_EQ(check_invariants(h), "");
  EXPECT_LE(h.level_count() - 1, 8);  // ceil(log4 5000) + 1
}

TEST(Hierarchy, ColinearPointsHaveFullConesAndValidStructure) {
  PointSet ps;
  for (int i = 0; i < 1000; ++i)
    ps.positions.emplace_back(0.01f * static_cast<float>(i), 0.0f, 0.0f);
  const Hierarchy h = build(std::move(ps));
  EXPECT_EQ(check_invariants(h), "");
  EXPECT_LT(h.cone_cos(h.root()), -0.99f);
}

TEST(Hierarchy, SinglePointIsOneNode) {
  PointSet ps;
  ps.positions.emplace_back(0.0f);
  const Hierarchy h = build(std::move(ps));
  EXPECT_EQ(h.node_count(), 1u);
  EXPECT_TRUE(h.is_leaf(0));
  EXPECT_EQ(check_invariants(h), "");
}

// A square patch of SIDE x SIDE grid points, SPACING apart, at CORNER.
void add_patch(PointSet& ps, glm::vec3 corner, int side, float spacing) {
  for (int i = 0; i < side; ++i)
    for (int j = 0; j < side; ++j)
      ps.positions.push_back(corner + spacing * glm::vec3(float(i), float(j), 0.0f));
}

// sqrt of the sum of the squared splat radii of the leaves under each node.
std::vector<double> leaf_cover(const Hierarchy& h) {
  std::vector<double> sum(h.node_count(), 0.0);
  for (NodeId n = h.node_count(); n-- > 0;) {
    if (h.is_leaf(n)) sum[n] = double(h.radius(n)) * h.radius(n);
    if (n != h.root()) sum[h.parent(n)] += sum[n];
  }
  for (double& v : sum) v = std::sqrt(v);
  return sum;
}

// Issue 30: on a dense surface an interior node is drawn at its bounding
// sphere, as in QSplat; over scattered clusters (vegetation) at most twice
// the radius of its leaves' discs together, not a disc across the gaps.
TEST(Hierarchy, InteriorSplatsKeepTheirLeavesCoverageWhereTheSubtreeIsSparse) {
  PointSet dense;
  add_patch(dense, glm::vec3(0.0f), 64, 0.01f);
  const Hierarchy surface = build(std::move(dense));
  ASSERT_EQ(check_invariants(surface), "");
  for (NodeId n = 0; n < surface.node_count(); ++n)
    ASSERT_EQ(surface.splat_radius(n), surface.radius(n)) << "node " << n;

  PointSet clusters;
  std::uint64_t state = 7;
  auto next = [&] {  // in [0, 1)
    state = state * 6364136223846793005ull + 1442695040888963407ull;
    return float(state >> 40) / float(1u << 24);
  };
  for (int c = 0; c < 16; ++c)
    add_patch(clusters, 10.0f * glm::vec3(next(), next(), next()), 10, 0.01f);
  const Hierarchy h = build(std::move(clusters));
  ASSERT_EQ(check_invariants(h), "");
  const std::vector<double> cover = leaf_cover(h);
  int smaller = 0;
  for (NodeId n = 0; n < h.node_count(); ++n) {
    const double expected = std::min(double(h.radius(n)), 2.0 * cover[n]);
    ASSERT_NEAR(h.splat_radius(n), expected, 1e-4 * expected) << "node " << n;
    smaller += h.splat_radius(n) < h.radius(n);
  }
  EXPECT_LT(h.splat_radius(h.root()), 0.25f * h.radius(h.root()));
  EXPECT_GE(smaller, 5);  // the root and its children, each over four clusters
}

TEST(Hierarchy, CheckInvariantsDetectsABrokenSphere) {
  PointSet ps = generate_model(ModelKind::Sphere, 500, 1);
  complete_attributes(ps);
  const Hierarchy ok = build_hierarchy(std::move(ps));
  ASSERT_EQ(check_invariants(ok), "");
  // The same arrays with the root's sphere halved: must be reported.
  auto arrays = ok.arrays();
  std::vector<glm::vec4> cr(arrays.center_radius.begin(), arrays.center_radius.end());
  cr[0].w *= 0.5f;
  auto keep = std::make_shared<std::vector<glm::vec4>>(std::move(cr));
  arrays.center_radius = *keep;
  std::vector<NodeId> levels;
  for (int d = 0; d <= ok.level_count(); ++d) levels.push_back(ok.level_begin(d));
  const Hierarchy bad =
      Hierarchy::from_arrays(keep, arrays, levels, ok.bounds_min(), ok.bounds_max());
  EXPECT_NE(check_invariants(bad).find("sphere"), std::string::npos);
}

class RealModels : public ::testing::TestWithParam<std::string> {};

TEST_P(RealModels, InvariantsHoldAndLeavesMatchThePly) {
  TREECUT_REQUIRE_ASSET(path, GetParam());
  PointSet ps = load_ply(path);
  const std::size_t n = ps.size();
  complete_attributes(ps);
  ASSERT_EQ(ps.normals.size(), n);
  ASSERT_EQ(ps.radii.size(), n);
  ASSERT_EQ(ps.curvature.size(), n);
  for (float r : ps.radii) ASSERT_GT(r, 0.0f);
  const Hierarchy h = build_hierarchy(std::move(ps));
  EXPECT_EQ(check_invariants(h), "");
  EXPECT_EQ(h.leaf_count(), n);
}

INSTANTIATE_TEST_SUITE_P(SharedAssets, RealModels,
                         ::testing::Values("bun_zipper.ply", "dragon_vrip_normals.ply",
                                           "dragon_vrip.ply", "lion_takanawa.ply"),
                         [](const auto& param_info) {
                           std::string s = param_info.param;
                           std::replace_if(
                               s.begin(), s.end(), [](char c) { return !std::isalnum(c); }, '_');
                           return s;
                         });
