// Attributes: normals, radii and curvature from faces and from neighbours,
// and the neighbour search they come from.
#include "treecut/attributes.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <glm/geometric.hpp>
#include <mutex>
#include <random>
#include <tuple>
#include <vector>

#include "hierarchy/knn_grid.hpp"
#include "treecut/tools/generate.hpp"

using namespace treecut;
using namespace treecut::tools;

TEST(Attributes, PcaNormalsOfASphereMatchTheTrueNormals) {
  PointSet ps = generate_model(ModelKind::Sphere, 20000, 3);
  const std::vector<glm::vec3> truth = ps.normals;
  ps.normals.clear();
  complete_attributes(ps);
  ASSERT_EQ(ps.normals.size(), truth.size());
  std::size_t good = 0;
  for (std::size_t i = 0; i < truth.size(); ++i) good += glm::dot(ps.normals[i], truth[i]) > 0.99f;
  // Oriented outward and accurate almost everywhere.
  EXPECT_GT(good, truth.size() * 99 / 100);
}

// A survey's ground (a LAS: the format says z is up) faces up even where a
// building above it lifts the centroid, which would turn it down.
TEST(Attributes, SurveyNormalsFaceUpOnTheGround) {
  PointSet ps;
  for (int i = 0; i < 60; ++i) {
    for (int j = 0; j < 60; ++j) ps.positions.push_back({0.1f * float(i), 0.1f * float(j), 0.0f});
  }
  for (int i = 0; i < 20; ++i) {  // a roof well above the ground
    for (int j = 0; j < 20; ++j) {
      ps.positions.push_back({2.0f + 0.1f * float(i), 2.0f + 0.1f * float(j), 30.0f});
    }
  }
  auto ground_facing_up = [](PointSet p) {
    complete_attributes(p);
    std::size_t up = 0;
    for (std::size_t i = 0; i < 3600; ++i) up += p.normals[i].z > 0.9f;
    return up;
  };
  EXPECT_LT(ground_facing_up(ps), 3600u / 2) << "outward from the centroid: down";
  ps.frame.z_up = true;
  EXPECT_EQ(ground_facing_up(ps), 3600u);
}

TEST(Attributes, CurvatureIsHighAtACreaseAndZeroOnFlatParts) {
  // Two perpendicular grid planes meeting along the x axis (z = 0, y >= 0 and
  // y = 0, z >= 0): surface variation peaks at the crease, vanishes away from it.
  PointSet ps;
  const float h = 0.01f;
  for (int a = 0; a < 60; ++a)
    for (int b = 1; b < 40; ++b) {
      ps.positions.emplace_back(h * static_cast<float>(a), h * static_cast<float>(b), 0.0f);
      ps.positions.emplace_back(h * static_cast<float>(a), 0.0f, h * static_cast<float>(b));
    }
  for (int a = 0; a < 60; ++a) ps.positions.emplace_back(h * static_cast<float>(a), 0.0f, 0.0f);
  complete_attributes(ps);
  double crease = 0, crease_n = 0;
  for (std::size_t i = 0; i < ps.size(); ++i) {
    const glm::vec3 p = ps.positions[i];
    if (p.x < 5 * h || p.x > 55 * h) continue;  // away from the open ends
    if (p.y + p.z < 0.5f * h) crease += ps.curvature[i], ++crease_n;
    if (p.y > 5 * h || p.z > 5 * h) {
      ASSERT_NEAR(ps.curvature[i], 0.0f, 1e-4f) << "flat point " << i;
    }
  }
  ASSERT_GT(crease_n, 10);
  EXPECT_GT(crease / crease_n, 0.05);
}

TEST(Attributes, SplatRadiiFromNeighboursCloseThePlane) {
  // A jittered grid of spacing h: discs must at least reach half the diagonal.
  PointSet ps;
  const float h = 0.01f;
  for (int y = 0; y < 100; ++y)
    for (int x = 0; x < 100; ++x)
      ps.positions.emplace_back(h * static_cast<float>(x), h * static_cast<float>(y), 0.0f);
  complete_attributes(ps);
  for (std::size_t i = 0; i < ps.size(); ++i) {
    ASSERT_GE(ps.radii[i], 0.70f * h) << i;
    ASSERT_LE(ps.radii[i], 3.0f * h) << i;
    ASSERT_NEAR(ps.curvature[i], 0.0f, 1e-4f);
    ASSERT_NEAR(std::abs(ps.normals[i].z), 1.0f, 1e-4f);
  }
}

// Issue 30: an isolated point (a leaf of sparse vegetation) gets a disc of at
// most 4 times the model's median radius, not one that reaches its far
// neighbours; the dense part keeps its own. Estimated normals are marked.
TEST(Attributes, RadiiOfIsolatedPointsAreCapped) {
  PointSet ps;
  const float h = 0.01f;
  for (int y = 0; y < 60; ++y)
    for (int x = 0; x < 60; ++x)
      ps.positions.emplace_back(h * static_cast<float>(x), h * static_cast<float>(y), 0.0f);
  // A sparse patch beside it, 8 times the spacing (a shrub's leaves).
  for (int y = 0; y < 6; ++y)
    for (int x = 0; x < 6; ++x)
      ps.positions.emplace_back(0.7f + 8 * h * float(x), 8 * h * float(y), 0.0f);
  complete_attributes(ps);
  EXPECT_TRUE(ps.frame.normals_estimated);
  std::vector<float> dense(ps.radii.begin(), ps.radii.begin() + 3600);
  std::nth_element(dense.begin(), dense.begin() + 1800, dense.end());
  const float median = dense[1800];
  for (std::size_t i = 3600; i < ps.size(); ++i) {
    EXPECT_LE(ps.radii[i], 4.0f * median * 1.0001f) << i;
    EXPECT_GT(ps.radii[i], 3.0f * median) << i << ": capped, not shrunk to the median";
  }
  EXPECT_LE(ps.radii[0], 3.0f * h);
}

TEST(Attributes, MeshNormalsAreAreaWeightedAndRadiiCoverTriangles) {
  // A unit square as two triangles, plus one vertex that no face uses.
  PointSet ps;
  ps.positions = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}, {5, 5, 5}};
  ps.triangles = {{0, 1, 2}, {0, 2, 3}};
  complete_attributes(ps);
  for (int i = 0; i < 4; ++i) EXPECT_NEAR(ps.normals[static_cast<std::size_t>(i)].z, 1.0f, 1e-6f);
  EXPECT_EQ(ps.normals[4], glm::vec3(0.0f)) << "an isolated vertex has no normal";
  // Right triangles: the covering radius is half the hypotenuse.
  for (int i = 0; i < 4; ++i)
    EXPECT_NEAR(ps.radii[static_cast<std::size_t>(i)], std::sqrt(2.0f) / 2.0f, 1e-5f);
  EXPECT_GT(ps.radii[4], 0.0f);
  for (float c : ps.curvature) EXPECT_NEAR(c, 0.0f, 1e-6f);
}

TEST(Attributes, FileNormalsAndRadiiAreKeptUnlessRecomputeIsAsked) {
  PointSet ps = generate_model(ModelKind::Terrain, 2000, 1);
  ps.radii.assign(ps.size(), 0.5f);
  const auto normals = ps.normals;
  complete_attributes(ps);
  for (std::size_t i = 0; i < ps.size(); ++i)
    ASSERT_GT(glm::dot(ps.normals[i], normals[i]), 0.99999f);
  EXPECT_EQ(ps.radii[10], 0.5f);
  AttributeOptions o;
  o.recompute_radii = true;
  complete_attributes(ps, o);
  EXPECT_LT(ps.radii[10], 0.5f);
}

// The neighbour search gives, for every point, the k nearest others within
// the reach, nearest first, ties by position (x, then y, then z): what a
// brute-force search gives, on a lattice (many equal distances), with
// coincident points, and on a scatter around it.
TEST(KnnGrid, NeighboursAreTheBruteForceNearestTiesByPosition) {
  std::vector<glm::vec3> points;
  for (int i = 0; i < 12; ++i)
    for (int j = 0; j < 12; ++j)
      for (int k = 0; k < 3; ++k) points.emplace_back(float(i), float(j), 0.5f * float(k));
  points.emplace_back(3.0f, 3.0f, 0.5f);  // twice where a lattice point is
  std::mt19937 random(7);
  std::uniform_real_distribution<float> u(-1.0f, 13.0f);
  for (int i = 0; i < 1500; ++i) points.emplace_back(u(random), u(random), 0.1f * u(random));
  const detail::KnnGrid grid(points);
  for (const int k : {1, 5, 12, 24}) {
    for (const float reach : {INFINITY, 1.1f}) {
      SCOPED_TRACE(testing::Message() << "k " << k << ", reach " << reach);
      std::mutex mutex;
      std::size_t visited = 0, wrong = 0;
      grid.for_each_knn(
          k,
          [&](std::uint32_t i, glm::vec3 p, int found, const glm::vec3* near, const float* d2) {
            std::vector<std::tuple<float, float, float, float>> all;  // d2, x, y, z
            for (std::uint32_t j = 0; j < points.size(); ++j) {
              if (j == i) continue;
              const glm::vec3 d = points[j] - p;
              const float e = d.x * d.x + d.y * d.y + d.z * d.z;
              if (e <= reach * reach) all.emplace_back(e, points[j].x, points[j].y, points[j].z);
            }
            std::sort(all.begin(), all.end());
            all.resize(std::min(all.size(), std::size_t(k)));
            bool same = std::size_t(found) == all.size();
            for (int f = 0; same && f < found; ++f)
              same = std::tuple(d2[f], near[f].x, near[f].y, near[f].z) == all[std::size_t(f)];
            std::lock_guard lock(mutex);
            ++visited;
            wrong += !same;
          },
          0xffffffffu, reach);
      EXPECT_EQ(visited, points.size());
      EXPECT_EQ(wrong, 0u);
    }
  }
}
