// The up axis from the data (up_axis.hpp): the shared assets (y-up Stanford
// models, the z-up lion cloud) and the generated z-up models, each rotated so
// that every axis in turn is up; the CLI's `info` line.
#include "treecut/up_axis.hpp"

#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "test_support.hpp"
#include "treecut/attributes.hpp"
#include "treecut/cache.hpp"
#include "treecut/model_io.hpp"
#include "treecut/paged_hierarchy.hpp"
#include "treecut/ply.hpp"
#include "treecut/tools/generate.hpp"

namespace {

using treecut::detect_up_axis;
using treecut::PointSet;
using treecut::UpAxis;

UpAxis axis(int a, bool negative = false) {
  UpAxis up;
  up.axis = a;
  up.negative = negative;
  return up;
}

// A proper rotation that carries axis FROM onto axis TO (a cyclic permutation
// of the coordinates, so a model stays a model, not its mirror image).
glm::vec3 permute(glm::vec3 v, int shift) {
  glm::vec3 out;
  for (int k = 0; k < 3; ++k) out[(k + shift) % 3] = v[k];
  return out;
}

PointSet rotated(const PointSet& points, int from, int to) {
  const int shift = (to - from + 3) % 3;
  PointSet out = points;
  for (glm::vec3& p : out.positions) p = permute(p, shift);
  for (glm::vec3& n : out.normals) n = permute(n, shift);
  return out;
}

// Upside down about the axis after UP (a half turn, not a mirror).
PointSet upside_down(const PointSet& points, int up) {
  PointSet out = points;
  const int other = (up + 1) % 3;
  for (glm::vec3& p : out.positions) p[up] = -p[up], p[other] = -p[other];
  for (glm::vec3& n : out.normals) n[up] = -n[up], n[other] = -n[other];
  return out;
}

UpAxis detect(const PointSet& points) {
  return detect_up_axis(points.positions, points.normals);
}

// The model, with UP as its up axis, rotated so that each axis is up in turn.
void expect_upright_on_every_axis(const PointSet& points, int up, const std::string& name) {
  for (int to = 0; to < 3; ++to) {
    const UpAxis found = detect(rotated(points, up, to));
    EXPECT_EQ(found, axis(to)) << name << " with "
                               << "xyz"[to] << " up: found " << found.name() << " (" << found.reason
                               << ")";
    EXPECT_FALSE(found.reason.empty());
  }
}

PointSet completed(PointSet points) {
  treecut::complete_attributes(points);
  return points;
}

TEST(UpAxis, ParseNameVectorAndCycle) {
  ASSERT_TRUE(treecut::parse_up_axis("y"));
  EXPECT_EQ(*treecut::parse_up_axis("y"), axis(1));
  EXPECT_EQ(*treecut::parse_up_axis("+z"), axis(2));
  EXPECT_EQ(*treecut::parse_up_axis("-x"), axis(0, true));
  for (const char* bad : {"", "w", "xy", "--y", "auto", "Y"}) {
    EXPECT_FALSE(treecut::parse_up_axis(bad)) << bad;
  }
  EXPECT_EQ(axis(1, true).name(), "-y");
  EXPECT_EQ(axis(2).name(), "z");
  EXPECT_EQ(axis(1, true).vector(), glm::vec3(0, -1, 0));
  EXPECT_EQ(axis(0).vector(), glm::vec3(1, 0, 0));
  EXPECT_EQ(treecut::next_up_axis(axis(0)), axis(1));
  EXPECT_EQ(treecut::next_up_axis(axis(1)), axis(2));
  EXPECT_EQ(treecut::next_up_axis(axis(2)), axis(0));
  EXPECT_EQ(treecut::next_up_axis(axis(2, true)), axis(0));
}

TEST(UpAxis, GeneratedTerrainAndCityAreUprightOnEveryAxis) {
  using treecut::tools::ModelKind;
  for (ModelKind kind : {ModelKind::Terrain, ModelKind::City}) {
    for (std::size_t n : {std::size_t{3000}, std::size_t{60000}}) {
      const PointSet generated = treecut::tools::generate_model(kind, n, 7);
      const std::string name =
          (kind == ModelKind::Terrain ? "terrain " : "city ") + std::to_string(n);
      expect_upright_on_every_axis(completed(generated), 2, name);
      // Without normals in the file (k-NN normals, oriented away from the
      // centroid, so their sign says little): still upright.
      PointSet cloud = generated;
      cloud.normals.clear();
      expect_upright_on_every_axis(completed(cloud), 2, name + " without normals");
    }
  }
}

TEST(UpAxis, UpsideDownModelsAreFoundUpsideDown) {
  using treecut::tools::ModelKind;
  for (ModelKind kind : {ModelKind::Terrain, ModelKind::City}) {
    const PointSet model = completed(treecut::tools::generate_model(kind, 20000, 3));
    for (int to = 0; to < 3; ++to) {
      const UpAxis found = detect(upside_down(rotated(model, 2, to), to));
      EXPECT_EQ(found, axis(to, true)) << found.name() << " (" << found.reason << ")";
    }
  }
}

TEST(UpAxis, AFewOutliersDoNotMoveTheGround) {
  PointSet city =
      completed(treecut::tools::generate_model(treecut::tools::ModelKind::City, 30000, 2));
  // Birds and multipath returns far below and above the scene: 0.1%.
  for (int i = 0; i < 30; ++i) {
    city.positions.emplace_back(0.01f * i, 0.5f, i % 2 ? -40.0f - i : 55.0f + i);
    city.normals.emplace_back(0.0f, 0.0f, 0.0f);
  }
  expect_upright_on_every_axis(city, 2, "city with outliers");
}

TEST(UpAxis, ASphereHasNoUpAndGetsTheDefault) {
  const PointSet sphere =
      treecut::tools::generate_model(treecut::tools::ModelKind::Sphere, 20000, 1);
  const UpAxis found = detect(sphere);
  EXPECT_EQ(found, axis(2));
  EXPECT_NE(found.reason.find("default z"), std::string::npos) << found.reason;
}

TEST(UpAxis, TheHierarchyGivesWhatItsPointsGive) {
  using treecut::tools::ModelKind;
  for (ModelKind kind : {ModelKind::Terrain, ModelKind::City}) {
    const PointSet model = treecut::tools::generate_model(kind, 40000, 5);
    for (int to = 0; to < 3; ++to) {
      const PointSet turned = rotated(model, 2, to);
      const treecut::Hierarchy h = treecut::build_from_points(turned);
      const UpAxis found = detect_up_axis(h);
      EXPECT_EQ(found, axis(to)) << found.name() << " (" << found.reason << ")";
      EXPECT_EQ(found, detect(completed(turned)));
    }
  }
}

// A paged model when it opens knows its root's page only: the axis comes
// from that page's finest nodes, and the sample names no other node (the
// rest of its arrays is unread: zeros, which gave z whatever the model).
TEST(UpAxis, APagedModelGivesItFromItsRootPage) {
  const auto dir = treecut::test::scratch_dir("up_axis_paged");
  const PointSet model =
      treecut::tools::generate_model(treecut::tools::ModelKind::Terrain, 100000, 5);
  for (int to = 0; to < 2; ++to) {
    const auto cache = dir / ("t" + std::to_string(to) + ".tch");
    treecut::save_cache(treecut::build_from_points(rotated(model, 2, to)), {1, 2, 3}, cache);
    const auto paged = treecut::PagedHierarchy::open(cache);
    ASSERT_GT(paged->pages(), 1u);
    std::vector<treecut::NodeRange> known;
    paged->page_ranges(0, known);
    const std::vector<treecut::NodeId> sample =
        treecut::sample_leaves(paged->hierarchy(), known, 1 << 20);
    ASSERT_FALSE(sample.empty());
    for (const treecut::NodeId n : sample) {
      ASSERT_EQ(paged->page_of(n), 0u) << "node " << n;
    }
    const UpAxis found = detect_up_axis(paged->hierarchy(), known);
    EXPECT_EQ(found, axis(to)) << found.name() << " (" << found.reason << ")";
  }
}

// ---- the shared assets ------------------------------------------------------

TEST(UpAxisSharedAssets, StanfordBunnyAndDragonAreYUpAndUprightOnEveryAxis) {
  for (const char* name : {"bun_zipper.ply", "dragon_vrip_normals.ply"}) {
    TREECUT_REQUIRE_ASSET(path, name);
    const PointSet points = completed(treecut::load_ply(path));
    expect_upright_on_every_axis(points, 1, name);
    const UpAxis found = detect(points);
    EXPECT_NE(found.reason.find("ground or base"), std::string::npos) << found.reason;
  }
}

TEST(UpAxisSharedAssets, LionPointCloudIsZUpAndUprightOnEveryAxis) {
  TREECUT_REQUIRE_ASSET(path, "lion_takanawa.ply");
  const PointSet points = completed(treecut::load_ply(path));
  expect_upright_on_every_axis(points, 2, "lion_takanawa.ply");
}

TEST(UpAxisSharedAssets, AsciiDragonThroughItsHierarchyIsYUp) {
  TREECUT_REQUIRE_ASSET(path, "dragon_vrip.ply");
  treecut::OpenOptions options;
  options.use_cache = false;
  const treecut::OpenedModel model = treecut::open_model(path, options);
  const UpAxis found = detect_up_axis(model.hierarchy);
  EXPECT_EQ(found, axis(1)) << found.name() << " (" << found.reason << ")";
}

// ---- the CLI ----------------------------------------------------------------

TEST(UpAxisCli, InfoShowsTheAxisAndWhy) {
  const auto dir = treecut::test::scratch_dir("up_axis_cli");
  const PointSet terrain =
      treecut::tools::generate_model(treecut::tools::ModelKind::Terrain, 5000, 1);
  const std::vector<std::pair<int, std::string>> cases{{2, "z"}, {0, "x"}, {1, "y"}};
  for (const auto& [to, name] : cases) {
    const auto ply = dir / ("terrain-" + name + "-up.ply");
    treecut::save_ply(ply, rotated(terrain, 2, to));
    const auto cache = dir / (name + ".tch");
    const std::string line =
        "\nup          " + name + " (auto: normals face +" + name + ": mean n." + name + " = ";
    // build prints the summary of what it built; info that of the cache.
    const auto built = treecut::test::run_treecut("build " + treecut::test::quote(ply) + " -o " +
                                                  treecut::test::quote(cache));
    EXPECT_EQ(built.code, 0) << built.out;
    EXPECT_NE(built.out.find(line), std::string::npos) << built.out;
    const auto info = treecut::test::run_treecut("info " + treecut::test::quote(cache));
    EXPECT_EQ(info.code, 0) << info.out;
    EXPECT_NE(info.out.find(line), std::string::npos) << info.out;
  }
}

}  // namespace
