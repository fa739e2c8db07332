// The scenes with depth complexity (generate.hpp, demo/tools/src/generate_{city,plant,field}.cpp):
// determinism per seed, exact counts, unit normals, points on the intended
// surfaces, walkthroughs that stay in the free lanes and see occlusion at
// street level, and the committed assets/paths/*_walk.campath reproduced.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <glm/geometric.hpp>
#include <unordered_set>

#include "test_support.hpp"
#include "treecut/attributes.hpp"
#include "treecut/error.hpp"
#include "treecut/ply.hpp"
#include "treecut/splat/camera_path.hpp"
#include "treecut/tools/generate.hpp"

namespace {

using treecut::PointSet;
using treecut::tools::ModelKind;

PointSet sphere_source() {
  PointSet s = treecut::tools::generate_model(ModelKind::Sphere, 3000, 1);
  treecut::complete_attributes(s);
  return s;
}

PointSet scene(ModelKind kind, std::size_t n, std::uint64_t seed) {
  if (kind == ModelKind::Field) {
    static const treecut::tools::FieldSource src =
        treecut::tools::prepare_field_source(sphere_source());
    return treecut::tools::generate_field(src, n, seed);
  }
  return treecut::tools::generate_model(kind, n, seed);
}

bool same(const PointSet& a, const PointSet& b) {
  return a.positions == b.positions && a.normals == b.normals && a.colors == b.colors;
}

class Scenes : public ::testing::TestWithParam<ModelKind> {};

TEST_P(Scenes, DeterministicPerSeedWithExactCounts) {
  const ModelKind kind = GetParam();
  for (std::size_t n : {std::size_t{1}, std::size_t{7}, std::size_t{12345}}) {
    const PointSet a = scene(kind, n, 3);
    EXPECT_EQ(a.size(), n);
    EXPECT_EQ(a.normals.size(), n);
    EXPECT_EQ(a.colors.size(), n);
  }
  EXPECT_TRUE(same(scene(kind, 20000, 3), scene(kind, 20000, 3)));
  EXPECT_FALSE(same(scene(kind, 20000, 3), scene(kind, 20000, 4)));
  EXPECT_THROW((void)scene(kind, 0, 3), treecut::InputError);
}

TEST_P(Scenes, UnitNormalsAndFinitePointsInTheExtent) {
  const PointSet s = scene(GetParam(), 50000, 1);
  for (std::size_t i = 0; i < s.size(); ++i) {
    ASSERT_NEAR(glm::length(s.normals[i]), 1.0f, 1e-4f) << i;
    const glm::vec3 p = s.positions[i];
    ASSERT_TRUE(std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z));
    ASSERT_LE(std::abs(p.x), 1.0f + 1e-5f) << i;
    ASSERT_LE(std::abs(p.y), 1.0f + 1e-5f) << i;
    ASSERT_GE(p.z, -1e-6f) << i;
  }
}

INSTANTIATE_TEST_SUITE_P(Kinds, Scenes,
                         ::testing::Values(ModelKind::City, ModelKind::Plant, ModelKind::Field),
                         [](const auto& param_info) {
                           return std::string(param_info.param == ModelKind::City    ? "city"
                                              : param_info.param == ModelKind::Plant ? "plant"
                                                                                     : "field");
                         });

constexpr float kTol = 2e-5f;

TEST(City, PointsLieOnTheGroundOrOnABuildingFace) {
  const auto layout = treecut::tools::city_layout(1);
  ASSERT_GT(layout.buildings.size(), 100u);
  const PointSet s = treecut::tools::generate_city(60000, 1);
  std::size_t ground = 0, walls = 0, roofs = 0;
  for (std::size_t i = 0; i < s.size(); ++i) {
    const glm::vec3 p = s.positions[i], n = s.normals[i];
    if (std::abs(p.z) <= kTol && n == glm::vec3(0, 0, 1)) {
      ++ground;
      continue;
    }
    bool found = false;
    for (const auto& b : layout.buildings) {
      const bool inside = p.x >= b.lo.x - kTol && p.x <= b.hi.x + kTol && p.y >= b.lo.y - kTol &&
                          p.y <= b.hi.y + kTol && p.z >= -kTol && p.z <= b.hi.z + kTol;
      if (!inside) continue;
      // On the face its normal names.
      const bool on = (n.z > 0.5f && std::abs(p.z - b.hi.z) <= kTol) ||
                      (n.x > 0.5f && std::abs(p.x - b.hi.x) <= kTol) ||
                      (n.x < -0.5f && std::abs(p.x - b.lo.x) <= kTol) ||
                      (n.y > 0.5f && std::abs(p.y - b.hi.y) <= kTol) ||
                      (n.y < -0.5f && std::abs(p.y - b.lo.y) <= kTol);
      if (on) {
        found = true;
        (n.z > 0.5f ? roofs : walls) += 1;
        break;
      }
    }
    ASSERT_TRUE(found) << "point " << i << " (" << p.x << ", " << p.y << ", " << p.z << ")";
  }
  // Walls dominate (streets are canyons), then the free ground, then roofs.
  EXPECT_GT(walls, ground);
  EXPECT_GT(ground, roofs);
  EXPECT_GT(roofs, 0u);
}

TEST(City, GroundPointsAvoidTheFootprints) {
  const auto layout = treecut::tools::city_layout(1);
  const PointSet s = treecut::tools::generate_city(60000, 1);
  for (std::size_t i = 0; i < s.size(); ++i) {
    const glm::vec3 p = s.positions[i];
    if (p.z != 0.0f || s.normals[i] != glm::vec3(0, 0, 1)) continue;
    for (const auto& b : layout.buildings)
      ASSERT_FALSE(p.x > b.lo.x && p.x < b.hi.x && p.y > b.lo.y && p.y < b.hi.y)
          << "ground point " << i << " under a building";
  }
}

TEST(Plant, PointsLieOnTheGroundOrOnACylinderOrACap) {
  const auto layout = treecut::tools::plant_layout(1);
  ASSERT_GT(layout.cylinders.size(), 100u);
  const PointSet s = treecut::tools::generate_plant(60000, 1);
  for (std::size_t i = 0; i < s.size(); ++i) {
    const glm::vec3 p = s.positions[i], n = s.normals[i];
    if (std::abs(p.z) <= kTol && n == glm::vec3(0, 0, 1)) continue;
    bool found = false;
    for (const auto& c : layout.cylinders) {
      const glm::vec3 d = p - c.base;
      const float along = glm::dot(d, c.axis);
      const glm::vec3 radial = d - along * c.axis;
      const float r = glm::length(radial);
      const bool side = along >= -kTol && along <= c.length + kTol &&
                        std::abs(r - c.radius) <= 4 * kTol &&
                        glm::dot(n, radial / std::max(r, 1e-9f)) > 0.999f;
      const bool cap = c.tank && std::abs(along - c.length) <= kTol && r <= c.radius + kTol &&
                       glm::dot(n, c.axis) > 0.999f;
      if (side || cap) {
        found = true;
        break;
      }
    }
    ASSERT_TRUE(found) << "point " << i << " (" << p.x << ", " << p.y << ", " << p.z << ")";
  }
}

TEST(Field, CopiesAreTurnedScaledCopiesOfTheSource) {
  // The sphere source becomes a unit sphere standing on the ground, centre
  // (0, 0, 1); each copy is it turned and scaled: map every point back.
  const auto layout = treecut::tools::field_layout(1);
  ASSERT_GT(layout.copies.size(), 50u);
  const PointSet s = scene(ModelKind::Field, 40000, 1);
  std::size_t on_copies = 0;
  for (std::size_t i = 0; i < s.size(); ++i) {
    const glm::vec3 p = s.positions[i];
    if (p.z == 0.0f && s.normals[i] == glm::vec3(0, 0, 1)) continue;
    const treecut::tools::FieldLayout::Copy* best = nullptr;
    for (const auto& c : layout.copies)
      if (glm::length(glm::vec2(p) - c.centre) <= c.radius * 1.03f) best = &c;  // + jitter
    ASSERT_NE(best, nullptr) << "point " << i << " is on no copy";
    const glm::vec3 local = (p - glm::vec3(best->centre, 0.0f)) / best->radius;
    const float cs = std::cos(-best->angle), sn = std::sin(-best->angle);
    const glm::vec3 unit(cs * local.x - sn * local.y, sn * local.x + cs * local.y, local.z);
    // On the sphere up to the tangential jitter within a splat (sagitta).
    EXPECT_NEAR(glm::length(unit - glm::vec3(0, 0, 1)), 1.0f, 0.01f) << i;
    ++on_copies;
  }
  EXPECT_GT(on_copies, s.size() / 10);
}

TEST(Field, FacedSourceSamplesItsSurface) {
  TREECUT_REQUIRE_ASSET(bunny, "bun_zipper.ply");
  PointSet src = treecut::load_ply(bunny);
  treecut::complete_attributes(src);
  const auto prepared = treecut::tools::prepare_field_source(src);
  double copies = 0.0;
  for (const auto& c : treecut::tools::field_layout(1).copies) copies += c.radius * c.radius;
  std::printf("field of bun_zipper.ply at seed 1: copies' area %.2f\n",
              prepared.unit_area * copies);
  const PointSet a = treecut::tools::generate_field(prepared, 30000, 2);
  const PointSet b = treecut::tools::generate_field(prepared, 30000, 2);
  EXPECT_EQ(a.size(), 30000u);
  EXPECT_TRUE(same(a, b));
  // The bunny stands: its copies rise above the ground, none sink below it.
  float top = 0.0f;
  for (const auto& p : a.positions) {
    top = std::max(top, p.z);
    ASSERT_GE(p.z, -1e-5f);
  }
  EXPECT_GT(top, 0.05f);
}

TEST(Field, NeedsASourceModel) {
  EXPECT_THROW((void)treecut::tools::generate_model(ModelKind::Field, 100, 1), treecut::InputError);
  const auto r = treecut::test::run_treecut(
      "gen field -n 100 -o " +
      treecut::test::quote(treecut::test::scratch_dir("field_nosrc") / "f.ply"));
  EXPECT_EQ(r.code, 2) << r.out;
  EXPECT_EQ(r.out, "treecut: gen field: needs --source PLY (the model to copy)\n");
}

TEST(GenWalk, WritesTheWalkthroughAndRefusesToOverwriteOtherFiles) {
  namespace fs = std::filesystem;
  using treecut::test::quote;
  const fs::path dir = treecut::test::scratch_dir("gen_walk");
  auto r = treecut::test::run_treecut("gen plant -n 500 -o " + quote(dir / "p.ply") + " --walk " +
                                      quote(dir / "w.campath"));
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_EQ(treecut::splat::load_camera_path(dir / "w.campath").keys.size(),
            treecut::tools::scene_walkthrough(ModelKind::Plant).size());
  // Again over its own output: a camera path may be replaced.
  r = treecut::test::run_treecut("gen plant -n 500 -o " + quote(dir / "p.ply") + " --walk " +
                                 quote(dir / "w.campath"));
  EXPECT_EQ(r.code, 0) << r.out;
  // Not over a file of the user's: refused before anything is written.
  {
    std::FILE* f = std::fopen((dir / "notes.txt").c_str(), "w");
    ASSERT_NE(f, nullptr);
    std::fputs("mine\n", f);
    std::fclose(f);
  }
  r = treecut::test::run_treecut("gen city -n 500 -o " + quote(dir / "c.ply") + " --walk " +
                                 quote(dir / "notes.txt"));
  EXPECT_EQ(r.code, 2) << r.out;
  EXPECT_EQ(r.out,
            "treecut: " + (dir / "notes.txt").string() +
                ": exists and is not a camera path treecut wrote; refusing to overwrite it\n");
  EXPECT_FALSE(fs::exists(dir / "c.ply"));
  EXPECT_EQ(fs::file_size(dir / "notes.txt"), 5u);
  r = treecut::test::run_treecut("gen sphere -n 500 -o " + quote(dir / "s.ply") + " --walk " +
                                 quote(dir / "s.campath"));
  EXPECT_EQ(r.code, 2) << r.out;
  EXPECT_EQ(r.out, "treecut: gen sphere: --walk is only for city, field and plant\n");
}

// ---------------------------------------------------------------- walkthroughs

class Walks : public ::testing::TestWithParam<ModelKind> {};

std::string name_of(ModelKind k) {
  return k == ModelKind::City ? "city" : k == ModelKind::Plant ? "plant" : "field";
}

// An occupancy grid of the scene's points above the ground (cells of 0.01).
struct Grid {
  std::unordered_set<std::uint64_t> cells;
  static std::uint64_t key(glm::vec3 p) {
    auto c = [](float v) { return static_cast<std::uint64_t>(std::floor(v / 0.01f) + 2048.0f); };
    return c(p.x) | c(p.y) << 16 | c(p.z) << 32;
  }
  explicit Grid(const PointSet& s) {
    for (const auto& p : s.positions)
      if (p.z > 1e-4f) cells.insert(key(p));
  }
  // Distance to the first occupied cell along the ray, or `far` when none.
  float cast(glm::vec3 o, glm::vec3 d, float far) const {
    for (float t = 0.0025f; t < far; t += 0.0025f)
      if (cells.count(key(o + t * d))) return t;
    return far;
  }
};

TEST_P(Walks, TheCommittedCampathIsWhatTheGeneratorMakes) {
  const ModelKind kind = GetParam();
  const auto file = std::filesystem::path(TREECUT_SOURCE_DIR) / "assets" / "paths" /
                    (name_of(kind) + "_walk.campath");
  const auto path = treecut::splat::load_camera_path(file);
  const auto keys = treecut::tools::scene_walkthrough(kind);
  ASSERT_EQ(path.keys.size(), keys.size()) << file << ": regenerate it (docs/scenes.md)";
  for (std::size_t i = 0; i < keys.size(); ++i) {
    const auto& c = path.keys[i].camera;
    ASSERT_NEAR(path.keys[i].time, keys[i].time, 1e-6) << i;
    ASSERT_LT(glm::length(c.eye - keys[i].eye), 1e-5f) << i;
    ASSERT_LT(glm::length(c.target - keys[i].target), 1e-5f) << i;
  }
}

TEST_P(Walks, TheEyeStaysOutOfEveryObject) {
  const ModelKind kind = GetParam();
  const auto keys = treecut::tools::scene_walkthrough(kind);
  const float margin = 0.004f;
  for (std::size_t i = 0; i < keys.size(); ++i) {
    const glm::vec3 e = keys[i].eye;
    ASSERT_GE(e.z, treecut::tools::walk_eye_height(kind) - 1e-6f)
        << "key " << i << " below eye level";
    if (kind == ModelKind::City) {
      for (const auto& b : treecut::tools::city_layout(1).buildings)
        ASSERT_FALSE(e.x > b.lo.x - margin && e.x < b.hi.x + margin && e.y > b.lo.y - margin &&
                     e.y < b.hi.y + margin && e.z < b.hi.z + margin)
            << "key " << i;
    } else if (kind == ModelKind::Plant) {
      for (const auto& c : treecut::tools::plant_layout(1).cylinders) {
        const glm::vec3 d = e - c.base;
        const float along = std::clamp(glm::dot(d, c.axis), 0.0f, c.length);
        ASSERT_GT(glm::length(d - along * c.axis), c.radius + margin) << "key " << i;
      }
    } else {
      for (const auto& c : treecut::tools::field_layout(1).copies) {
        if (e.z < 0.3f) {
          ASSERT_GT(glm::length(glm::vec2(e) - c.centre), c.radius + margin) << i;
        }
      }
    }
  }
}

TEST_P(Walks, StreetLevelIsOccludedAndTheOverviewIsOpen) {
  const ModelKind kind = GetParam();
  const Grid grid(scene(kind, 400000, 1));
  const auto keys = treecut::tools::scene_walkthrough(kind);
  const float eye = treecut::tools::walk_eye_height(kind);
  // Rays in the view's direction (yaw within 40 degrees of it, pitch 0..20
  // degrees up, so the ground never counts) from keys along the walk.
  std::size_t rays = 0, near_hits = 0, walk_keys = 0;
  for (std::size_t i = 0; i < keys.size(); i += 10) {
    const auto& k = keys[i];
    if (std::abs(k.eye.z - eye) > 1e-6f) continue;
    ++walk_keys;
    const glm::vec3 f = glm::normalize(glm::vec3(glm::vec2(k.target - k.eye), 0.0f));
    for (int yaw = -40; yaw <= 40; yaw += 10)
      for (int pitch = 0; pitch <= 20; pitch += 5) {
        const float a = glm::radians(static_cast<float>(yaw));
        const float b = glm::radians(static_cast<float>(pitch));
        const glm::vec3 h(f.x * std::cos(a) - f.y * std::sin(a),
                          f.x * std::sin(a) + f.y * std::cos(a), 0.0f);
        const glm::vec3 d = std::cos(b) * h + glm::vec3(0, 0, std::sin(b));
        ++rays;
        if (grid.cast(k.eye, d, 0.3f) < 0.3f) ++near_hits;
      }
  }
  ASSERT_GT(walk_keys, 20u);
  const double share = static_cast<double>(near_hits) / static_cast<double>(rays);
  std::printf("%s: %zu of %zu street-level rays hit within 0.3 (%.2f)\n", name_of(kind).c_str(),
              near_hits, rays, share);
  // Measured at seed 1: city 0.73, plant 0.70, field 0.69 (an open plain: 0).
  EXPECT_GT(share, 0.6) << near_hits << " of " << rays;
  // The first key looks at the scene from far above: nothing within 1.0.
  const auto& first = keys.front();
  EXPECT_GE(grid.cast(first.eye, glm::normalize(first.target - first.eye), 1.0f), 1.0f);
}

INSTANTIATE_TEST_SUITE_P(Kinds, Walks,
                         ::testing::Values(ModelKind::City, ModelKind::Plant, ModelKind::Field),
                         [](const auto& param_info) { return name_of(param_info.param); });

}  // namespace

namespace {

// The surface areas behind the densities of docs/scenes.md (spacing =
// sqrt(area / points); splat radius from complete_attributes ~1.5 spacings).
TEST(SceneAreas, MatchTheDocumentedFigures) {
  double city = 4.0;
  for (const auto& b : treecut::tools::city_layout(1).buildings) {
    const glm::vec3 d = b.hi - b.lo;
    city += 2.0 * d.z * (d.x + d.y);  // walls; the roof replaces the ground below
  }
  double plant = 4.0;
  for (const auto& c : treecut::tools::plant_layout(1).cylinders)
    plant += 2.0 * 3.14159265 * c.radius * c.length;  // caps replace the ground below
  std::printf("area at seed 1: city %.2f, plant %.2f\n", city, plant);
  EXPECT_NEAR(city, 9.0, 1.0);
  EXPECT_NEAR(plant, 13.7, 1.0);
}

}  // namespace
