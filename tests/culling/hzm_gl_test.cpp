// hzm_culling_is_conservative: the `budget` strategy's HZM test
// (strategies/budget_strategy.hpp, hzm.hpp) never culls an object that the
// exact reference sees. The reference is the renderer's own: every object's
// full-detail cut drawn in SplatMode::ObjectId (each pixel the index of the
// object in front) and read back; an object with at least one pixel of its
// id must come out potentially visible. Small scenes made here of generated
// models: a wall of boxes in front of boxes and floorless buildings (the
// open-face occluders), and random layouts of both, seen from several
// cameras. So that the check cannot pass by culling nothing, the wall scene
// must cull some objects.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <glm/gtc/matrix_transform.hpp>
#include <memory>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "test_support.hpp"
#include "treecut/model_io.hpp"
#include "treecut/scene.hpp"
#include "treecut/splat/camera.hpp"
#include "treecut/splat/context.hpp"
#include "treecut/splat/frame.hpp"
#include "treecut/splat/renderer.hpp"
#include "treecut/splat/scene_draw.hpp"
#include "treecut/strategies/budget_strategy.hpp"
#include "treecut/tools/scene_generate.hpp"
#include "treecut/tree_cut.hpp"

namespace treecut {
namespace {

constexpr int kWidth = 320;
constexpr int kHeight = 240;

// Points on the six faces of the unit cube [-0.5, 0.5]^3.
Hierarchy cube_model(std::size_t points, std::uint32_t seed) {
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
  return build_from_points(std::move(p));
}

struct Placed {
  std::uint32_t model = 0;  // 0: cube (centred), 1: building (z up, no floor)
  glm::vec3 at{0.0f};
  glm::vec3 size{1.0f};
};

class HzmCulling : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    static const std::unique_ptr<splat::GlContext> ctx = splat::make_headless_context(kWidth, kHeight);
    ctx->make_current();
  }

  // Checks one scene from one camera; returns the objects the HZM culled.
  std::size_t check(const std::vector<Placed>& placed, const splat::Camera& cam,
                    const std::string& what) {
    // The models are the fixture's: shared pointers that own nothing.
    StageScene scene;
    scene.models = {std::shared_ptr<const Hierarchy>(std::shared_ptr<const Hierarchy>(), &cube_),
                    std::shared_ptr<const Hierarchy>(std::shared_ptr<const Hierarchy>(), &building_)};
    for (const Placed& p : placed) {
      glm::mat4 w = glm::translate(glm::mat4(1.0f), p.at);
      if (p.model == 1) {
        // The building stands on z = 0 with z up: turned so that it stands
        // on the world's y = at.y with y up.
        w = glm::rotate(w, -glm::half_pi<float>(), glm::vec3(1.0f, 0.0f, 0.0f));
      }
      w = glm::scale(w, p.size);
      scene.objects.push_back(place_object(p.model, w));
    }
    const ViewSnapshot view = splat::view_snapshot(cam, {kWidth, kHeight}, splat::Light{});

    strategies::BudgetStrategy s;
    s.set_param("pet", 0.0);
    s.set_param("points", 1000);
    s.reset_scene(scene);
    std::vector<NodeId> nodes;
    std::vector<std::uint32_t> offsets;
    std::vector<QueryRequest> queries;
    const SceneIterationInput in{scene, view, nullptr, s.params_version(), {}, {}};
    SceneIterationOutput out;
    out.nodes = &nodes;
    out.offsets = &offsets;
    out.queries = &queries;
    s.iterate_scene(in, out);

    // The reference: every object at full detail, ids read back.
    const Hierarchy* models[] = {&cube_, &building_};
    renderer_->set_models(models);
    const TreeCut a = TreeCut::leaf_cut(cube_), b = TreeCut::leaf_cut(building_);
    std::vector<std::span<const NodeId>> cuts;
    for (const Placed& p : placed) cuts.push_back(p.model == 0 ? a.nodes() : b.nodes());
    splat::SceneCutBuffer buffer;
    buffer.set_objects(*renderer_, scene.objects);
    buffer.upload(models, cuts);
    splat::RenderSettings ids;
    ids.mode = splat::SplatMode::ObjectId;
    renderer_->draw_scene(buffer, cam, ids, true);
    const std::vector<std::uint8_t> px = renderer_->read_pixels();
    std::vector<std::size_t> seen(placed.size(), 0);
    for (std::size_t i = 0; i < px.size(); i += 4) {
      const std::uint32_t v = px[i] | (px[i + 1] << 8) | (px[i + 2] << 16);
      if (v == 0xffffff) continue;
      EXPECT_LT(v, placed.size()) << what;
      if (v < placed.size()) ++seen[v];
    }
    std::size_t culled = 0, seen_objects = 0;
    for (std::size_t i = 0; i < placed.size(); ++i) {
      seen_objects += seen[i] > 0;
      if (seen[i] > 0) {
        EXPECT_TRUE(s.visible()[i])
            << what << ": object " << i << " has " << seen[i] << " pixels but was culled";
      }
    }
    culled = s.last().occlusion_culled;
    EXPECT_GT(seen_objects, 0u) << what;  // the camera sees something
    return culled;
  }

  Hierarchy cube_ = cube_model(12000, 7);
  Hierarchy building_ = build_from_points(tools::generate_building(12000, 3));
  std::unique_ptr<splat::Renderer> renderer_ =
      std::make_unique<splat::Renderer>(cube_, glm::ivec2(kWidth, kHeight));
};

splat::Camera camera(glm::vec3 eye, glm::vec3 target) {
  splat::Camera c;
  c.eye = eye;
  c.target = target;
  c.up = {0.0f, 1.0f, 0.0f};
  c.fov_y_deg = 60.0f;
  c.near_plane = 0.1f;
  c.far_plane = 200.0f;
  return c;
}

TEST_F(HzmCulling, hzm_culling_is_conservative_behind_a_wall) {
  std::vector<Placed> scene;
  for (int i = 0; i < 5; ++i)
    scene.push_back({0, {-6.0f + 3.0f * float(i), 0.0f, -10.0f}, {3.05f, 5.0f, 0.5f}});
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> x(-9.0f, 9.0f), z(-40.0f, -13.0f), sz(0.5f, 2.5f);
  for (int i = 0; i < 30; ++i) {
    const bool building = i % 3 == 0;
    const glm::vec3 size(sz(rng), sz(rng), sz(rng));
    scene.push_back({building ? 1u : 0u, {x(rng), building ? -2.5f : 0.0f, z(rng)}, size});
  }
  std::size_t culled = 0;
  int k = 0;
  for (const glm::vec3 eye :
       {glm::vec3(0.0f, 0.5f, 0.0f), glm::vec3(-3.0f, 1.0f, 2.0f), glm::vec3(4.0f, -0.5f, -4.0f),
        glm::vec3(7.5f, 0.0f, -3.0f), glm::vec3(0.0f, 3.0f, -6.0f)}) {
    culled += check(scene, camera(eye, eye + glm::vec3(0.1f * float(k), 0.0f, -1.0f)),
                    "wall, camera " + std::to_string(k));
    ++k;
  }
  EXPECT_GT(culled, 10u) << "the wall hides objects: a test that culls nothing proves nothing";
}

TEST_F(HzmCulling, hzm_culling_is_conservative_on_random_layouts) {
  std::size_t culled = 0;
  for (std::uint32_t seed = 1; seed <= 4; ++seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> x(-10.0f, 10.0f), y(-2.0f, 2.0f), z(-35.0f, -4.0f),
        sz(0.4f, 5.0f);
    std::vector<Placed> scene;
    for (int i = 0; i < 60; ++i) {
      scene.push_back({static_cast<std::uint32_t>(i % 2),
                       {x(rng), y(rng), z(rng)},
                       {sz(rng), sz(rng), sz(rng)}});
    }
    culled += check(scene, camera({0.0f, 0.0f, 0.0f}, {0.0f, 0.0f, -1.0f}),
                    "layout " + std::to_string(seed));
    culled += check(scene, camera({-3.0f, 1.0f, -2.0f}, {4.0f, 0.0f, -20.0f}),
                    "layout " + std::to_string(seed) + ", oblique");
  }
  std::printf("random layouts: %zu objects culled in all\n", culled);
}

// `treecut render SCENE -s budget --sync`: through the stage's scene path,
// stats.csv gets the budget columns, filled, with the selected nodes never
// above N; a bad parameter is one line and exit code 2.
TEST(BudgetRender, RenderASceneWithTheBudgetStrategy) {
  const std::filesystem::path dir = test::scratch_dir("budget_render");
  const std::filesystem::path scene = dir / "city.scene", out = dir / "out";
  ASSERT_EQ(test::run_treecut("gen city-block --objects 60 -n 3000 -o " + test::quote(scene)).code,
            0);
  const test::CommandResult r = test::run_treecut(
      "render " + test::quote(scene) +
      " -s budget -p points=20000 --sync --no-png -n 4 --width 160 --height 120 --out " +
      test::quote(out));
  ASSERT_EQ(r.code, 0) << r.out;
  std::ifstream csv(out / "stats.csv");
  std::string header, line;
  ASSERT_TRUE(std::getline(csv, header));
  std::vector<std::string> names;
  {
    std::istringstream in(header);
    for (std::string f; std::getline(in, f, ',');) names.push_back(f);
  }
  const auto column = [&](const std::string& name) {
    const auto it = std::find(names.begin(), names.end(), name);
    EXPECT_NE(it, names.end()) << name;
    return static_cast<std::size_t>(it - names.begin());
  };
  const std::size_t selected = column("budget_selected"), visible = column("budget_visible"),
                    splats = column("splats_drawn");
  int rows = 0;
  while (std::getline(csv, line)) {
    std::vector<std::string> f;
    std::istringstream in(line);
    for (std::string x; std::getline(in, x, ',');) f.push_back(x);
    ASSERT_GT(f.size(), selected) << line;
    EXPECT_LE(std::stoull(f[selected]), 20000u) << line;
    EXPECT_LE(std::stoull(f[splats]), 20000u) << line;
    EXPECT_GT(std::stoull(f[visible]), 0u) << line;
    ++rows;
  }
  EXPECT_EQ(rows, 4);

  const test::CommandResult bad =
      test::run_treecut("render " + test::quote(scene) +
                        " -s budget -p threads=3 --sync -n 1 --out " + test::quote(dir / "bad"));
  EXPECT_EQ(bad.code, 2) << bad.out;
  EXPECT_NE(bad.out.find("threads = 3 is out of range"), std::string::npos) << bad.out;
}

}  // namespace
}  // namespace treecut
