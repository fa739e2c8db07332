// Scenes of many objects on OSMesa (Renderer::set_models, SceneCutBuffer,
// Renderer::draw_scene). What holds, in every splat mode:
//  - one object with the identity transform draws exactly the plain draw of
//    its cut (the object records change nothing for a single model);
//  - an object moved by a rigid motion and a uniform scale looks like its
//    model seen from the camera moved back by the inverse transform;
//  - objects of several models draw each at its own transform and from its
//    own model's nodes: the image of two objects is the union of the images
//    of each alone (a wrong baseVertex or baseInstance draws the wrong model
//    or at the wrong place);
//  - the draw calls do not grow with the objects: one per splat pass;
//  - a stretched object (per-axis scale) covers what its stretched points do;
//  - transforms that are not affine and invertible, foreign models and ids
//    past a model are refused before any draw.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <glm/gtc/matrix_transform.hpp>
#include <limits>
#include <memory>
#include <random>
#include <stdexcept>
#include <vector>

#include "image_compare.hpp"
#include "treecut/model.hpp"
#include "treecut/model_io.hpp"
#include "treecut/splat/context.hpp"
#include "treecut/splat/image.hpp"
#include "treecut/splat/renderer.hpp"
#include "treecut/splat/scene_draw.hpp"
#include "treecut/tools/generate.hpp"
#include "treecut/tree_cut.hpp"

namespace treecut::splat {
namespace {

constexpr int kWidth = 240;
constexpr int kHeight = 180;
constexpr float kAspect = float(kWidth) / float(kHeight);

// Refined breadth first (ids are breadth-first) to about `target` nodes.
std::vector<NodeId> bfs_cut(const Hierarchy& h, std::size_t target) {
  TreeCut cut = TreeCut::root_cut(h);
  for (NodeId n = 0; n < h.node_count() && cut.size() < target; ++n) {
    if (cut.contains(n) && !h.is_leaf(n)) cut.refine(h, n);
  }
  return {cut.nodes().begin(), cut.nodes().end()};
}

std::size_t differing_pixels(const Image& a, const Image& b) {
  std::size_t d = 0;
  for (std::size_t i = 0; i < a.rgba.size(); i += 4) {
    d += a.rgba[i] != b.rgba[i] || a.rgba[i + 1] != b.rgba[i + 1] || a.rgba[i + 2] != b.rgba[i + 2];
  }
  return d;
}

bool is_background(const Image& img, std::size_t i, const RenderSettings& s) {
  const auto c = [&](int k) {
    return std::abs(int(img.rgba[i + k]) - int(255 * s.background[k] + 0.5f));
  };
  return c(0) <= 1 && c(1) <= 1 && c(2) <= 1;
}

std::size_t covered_pixels(const Image& img, const RenderSettings& s) {
  std::size_t n = 0;
  for (std::size_t i = 0; i < img.rgba.size(); i += 4) n += !is_background(img, i, s);
  return n;
}

Camera moved(const Camera& c, const glm::mat4& world, float scale) {
  Camera out = c;
  out.eye = glm::vec3(world * glm::vec4(c.eye, 1.0f));
  out.target = glm::vec3(world * glm::vec4(c.target, 1.0f));
  out.up = glm::normalize(glm::vec3(world * glm::vec4(c.up, 0.0f)));
  out.near_plane = c.near_plane * scale;
  out.far_plane = c.far_plane * scale;
  return out;
}

class RenderScene : public ::testing::TestWithParam<SplatMode> {
 protected:
  static void SetUpTestSuite() {
    static const std::unique_ptr<GlContext> ctx = make_headless_context(kWidth, kHeight);
    ctx->make_current();
  }
  void SetUp() override {
    renderer_ = std::make_unique<Renderer>(city_, glm::ivec2(kWidth, kHeight));
    camera_ = default_camera(city_.bounds_min(), city_.bounds_max(), kAspect);
    settings_.mode = GetParam();
    settings_.point_size_px = 3.0f;
  }
  Image plain(const Hierarchy& h, std::span<const NodeId> nodes, const Camera& cam) {
    renderer_->set_hierarchy(h);
    CutBuffer cut;
    cut.upload(h, nodes);
    renderer_->draw(cut, cam, settings_, true);
    return Image{kWidth, kHeight, renderer_->read_pixels()};
  }
  Image scene(std::span<const Hierarchy* const> models, std::span<const SceneObject> objects,
              std::span<const std::span<const NodeId>> cuts, const Camera& cam,
              FrameStats* stats = nullptr) {
    renderer_->set_models(models);
    SceneCutBuffer buffer;
    buffer.set_objects(*renderer_, objects);
    buffer.upload(models, cuts);
    const FrameStats s = renderer_->draw_scene(buffer, cam, settings_, true);
    if (stats != nullptr) *stats = s;
    return Image{kWidth, kHeight, renderer_->read_pixels()};
  }

  Hierarchy city_ = build_from_points(tools::generate_model(tools::ModelKind::City, 30000, 5));
  Hierarchy sphere_ = build_from_points(tools::generate_model(tools::ModelKind::Sphere, 8000, 2));
  std::unique_ptr<Renderer> renderer_;
  Camera camera_;
  RenderSettings settings_;
};

TEST_P(RenderScene, OneObjectWithTheIdentityIsThePlainDraw) {
  const std::vector<NodeId> nodes = bfs_cut(city_, 6000);
  const Image reference = plain(city_, nodes, camera_);
  const Hierarchy* models[] = {&city_};
  const SceneObject objects[] = {place_object(0, glm::mat4(1.0f))};
  const std::span<const NodeId> cuts[] = {nodes};
  FrameStats stats;
  const Image drawn = scene(models, objects, cuts, camera_, &stats);
  EXPECT_EQ(differing_pixels(drawn, reference), 0u);
  EXPECT_EQ(stats.splats, nodes.size());
  EXPECT_GT(stats.points, 0u);
}

TEST_P(RenderScene, AMovedObjectLooksLikeItsModelFromTheCameraMovedBack) {
  const std::vector<NodeId> nodes = bfs_cut(city_, 6000);
  const Image reference = plain(city_, nodes, camera_);
  // A rotation about an oblique axis, a uniform scale and a translation.
  const float scale = 2.5f;
  const glm::mat4 world =
      glm::scale(glm::rotate(glm::translate(glm::mat4(1.0f), glm::vec3(7.0f, -3.0f, 12.0f)), 0.7f,
                             glm::normalize(glm::vec3(0.3f, 1.0f, 0.2f))),
                 glm::vec3(scale));
  const Hierarchy* models[] = {&city_};
  const SceneObject objects[] = {place_object(0, world)};
  const std::span<const NodeId> cuts[] = {nodes};
  const Image drawn = scene(models, objects, cuts, moved(camera_, world, scale));
  // The same image up to float rounding of positions: a splat edge moves by
  // a pixel here and there, hq's blend weights round another way. What must
  // hold on every driver: each pixel's colour is found within a pixel of it
  // in the reference (both ways), with a small tolerance.
  const std::size_t pixels = std::size_t{kWidth} * kHeight;
  const std::size_t differ = differing_pixels(drawn, reference);
  const std::size_t unmatched = test::unmatched_either_way(drawn, reference);
  std::printf("%s: %zu of %zu pixels differ, %zu not within a pixel\n",
              std::string(splat_mode_name(GetParam())).c_str(), differ, pixels, unmatched);
  EXPECT_LE(unmatched, pixels / 500);
  EXPECT_GT(covered_pixels(drawn, settings_), pixels / 10);
}

TEST_P(RenderScene, TwoObjectsOfTwoModelsAreTheUnionOfEachAlone) {
  const std::vector<NodeId> city_nodes = bfs_cut(city_, 5000);
  const std::vector<NodeId> sphere_nodes = bfs_cut(sphere_, 2000);
  const Hierarchy* models[] = {&city_, &sphere_};
  // Side by side, apart: the city on the left, the sphere (radius ~1) at
  // the right, both in view of a camera that frames both.
  const float w = glm::length(city_.bounds_max() - city_.bounds_min());
  const glm::mat4 left = glm::translate(glm::mat4(1.0f), glm::vec3(-0.5f * w, 0.0f, 0.0f));
  const glm::mat4 right =
      glm::scale(glm::translate(glm::mat4(1.0f), glm::vec3(0.6f * w, 0, 0)), glm::vec3(0.25f * w));
  const SceneObject objects[] = {place_object(0, left), place_object(1, right)};
  const glm::vec3 lo = city_.bounds_min() - glm::vec3(w, 0.3f * w, 0.3f * w);
  const glm::vec3 hi = city_.bounds_max() + glm::vec3(w, 0.3f * w, 0.3f * w);
  const Camera cam = fit_camera(lo, hi, kAspect, glm::vec3(0.0f, -1.0f, 0.8f), glm::vec3(0, 0, 1));
  const std::span<const NodeId> none;
  const std::span<const NodeId> both[] = {city_nodes, sphere_nodes};
  const std::span<const NodeId> only_city[] = {city_nodes, none};
  const std::span<const NodeId> only_sphere[] = {none, sphere_nodes};
  const Image all = scene(models, objects, both, cam);
  const Image a = scene(models, objects, only_city, cam);
  const Image b = scene(models, objects, only_sphere, cam);
  // The sphere alone is the sphere model drawn from the camera moved back.
  const std::size_t pixels = std::size_t{kWidth} * kHeight;
  EXPECT_GT(covered_pixels(a, settings_), pixels / 50);
  EXPECT_GT(covered_pixels(b, settings_), pixels / 200);
  std::size_t wrong = 0;
  for (std::size_t i = 0; i < all.rgba.size(); i += 4) {
    const Image& expect = !is_background(a, i, settings_) ? a : b;
    wrong += all.rgba[i] != expect.rgba[i] || all.rgba[i + 1] != expect.rgba[i + 1] ||
             all.rgba[i + 2] != expect.rgba[i + 2];
  }
  EXPECT_EQ(wrong, 0u);
  // Each alone against its model drawn plainly from the moved-back camera.
  const glm::mat4 back = glm::inverse(right);
  const Image sphere_plain = plain(sphere_, sphere_nodes, moved(cam, back, 1.0f / (0.25f * w)));
  EXPECT_LE(differing_pixels(b, sphere_plain), pixels / 100);
}

TEST_P(RenderScene, DrawCallsDoNotGrowWithTheObjects) {
  const std::vector<NodeId> nodes = bfs_cut(sphere_, 300);
  const Hierarchy* models[] = {&sphere_, &city_};
  std::size_t calls[2] = {0, 0};
  const std::size_t counts[2] = {10, 2000};
  for (int k = 0; k < 2; ++k) {
    std::vector<SceneObject> objects;
    std::vector<std::span<const NodeId>> cuts;
    for (std::size_t i = 0; i < counts[k]; ++i) {
      const float x = float(i % 50) * 3.0f, y = float(i / 50) * 3.0f;
      objects.push_back(place_object(0, glm::translate(glm::mat4(1.0f), glm::vec3(x, y, 0.0f))));
      cuts.emplace_back(nodes);
    }
    const Camera cam = fit_camera(glm::vec3(-1.0f), glm::vec3(150.0f, 120.0f, 1.0f), kAspect,
                                  glm::vec3(0.0f, -0.5f, 1.0f), glm::vec3(0, 0, 1));
    FrameStats stats;
    scene(models, objects, cuts, cam, &stats);
    EXPECT_EQ(stats.splats, nodes.size() * counts[k]);
    calls[k] = stats.draw_calls;
  }
  // Fast and fixed: one pass; hq: a visibility and an attribute pass.
  const std::size_t passes = GetParam() == SplatMode::HighQuality ? 2 : 1;
  EXPECT_EQ(calls[0], passes);
  EXPECT_EQ(calls[1], passes);
}

TEST_P(RenderScene, AStretchedObjectCoversWhatItsStretchedPointsDo) {
  // The sphere stretched to an ellipsoid 3 x 1 x 0.6 against a hierarchy
  // built from the stretched points: coverage within a few percent (splats
  // must not leave holes, nor grow far past the surface).
  const glm::vec3 s(3.0f, 1.0f, 0.6f);
  PointSet points = tools::generate_model(tools::ModelKind::Sphere, 8000, 2);
  for (auto& p : points.positions) p *= s;
  for (auto& n : points.normals) n = glm::normalize(n / s);
  points.radii.clear();  // spaced by the build, as the sphere's
  const Hierarchy stretched = build_from_points(std::move(points));
  const Camera cam = default_camera(stretched.bounds_min(), stretched.bounds_max(), kAspect);
  const TreeCut stretched_leaves = TreeCut::leaf_cut(stretched);
  const Image reference = plain(stretched, stretched_leaves.nodes(), cam);
  const Hierarchy* models[] = {&sphere_};
  const SceneObject objects[] = {place_object(0, glm::scale(glm::mat4(1.0f), s))};
  const TreeCut leaves = TreeCut::leaf_cut(sphere_);
  const std::span<const NodeId> cuts[] = {leaves.nodes()};
  const Image drawn = scene(models, objects, cuts, cam);
  const double want = double(covered_pixels(reference, settings_));
  const double got = double(covered_pixels(drawn, settings_));
  std::printf("%s: stretched object %.0f pixels, stretched points %.0f\n",
              std::string(splat_mode_name(GetParam())).c_str(), got, want);
  EXPECT_GE(got, 0.97 * want);
  // Fixed points grow to their splat's footprint (issue 30), a circle of
  // sigma_max r around the ellipse a stretched splat is: the rim spreads
  // a little further than the discs do.
  EXPECT_LE(got, (GetParam() == SplatMode::FixedSize ? 1.2 : 1.15) * want);
}

INSTANTIATE_TEST_SUITE_P(Modes, RenderScene,
                         ::testing::Values(SplatMode::Fast, SplatMode::HighQuality,
                                           SplatMode::FixedSize),
                         [](const ::testing::TestParamInfo<SplatMode>& p) {
                           return std::string(splat_mode_name(p.param));
                         });

class RenderSceneChecks : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    static const std::unique_ptr<GlContext> ctx = make_headless_context(kWidth, kHeight);
    ctx->make_current();
  }
  Hierarchy h_ = build_from_points(tools::generate_model(tools::ModelKind::Sphere, 2000, 1));
  Hierarchy other_ = build_from_points(tools::generate_model(tools::ModelKind::Sphere, 1000, 2));
};

TEST_F(RenderSceneChecks, BadTransformsModelsAndIdsAreRefused) {
  Renderer r(h_, {kWidth, kHeight});
  SceneCutBuffer buffer;
  const auto refuses = [&](const glm::mat4& m, const char* why) {
    const SceneObject objects[] = {place_object(0, glm::mat4(1.0f)), place_object(0, m)};
    try {
      buffer.set_objects(r, objects);
      ADD_FAILURE() << why << ": accepted";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find("object 1: "), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find(why), std::string::npos) << e.what();
    }
  };
  refuses(glm::scale(glm::mat4(1.0f), glm::vec3(1.0f, 0.0f, 1.0f)), "not invertible");
  glm::mat4 projective(1.0f);
  projective[2][3] = -1.0f;
  refuses(projective, "not affine");
  glm::mat4 nan(1.0f);
  nan[3][0] = std::numeric_limits<float>::quiet_NaN();
  refuses(nan, "not finite");

  const SceneObject bad_model[] = {place_object(1, glm::mat4(1.0f))};
  EXPECT_THROW(buffer.set_objects(r, bad_model), std::invalid_argument);

  const SceneObject one[] = {place_object(0, glm::mat4(1.0f))};
  buffer.set_objects(r, one);
  const Hierarchy* models[] = {&h_};
  const std::vector<NodeId> past{static_cast<NodeId>(h_.node_count())};
  const std::span<const NodeId> past_cut[] = {past};
  EXPECT_THROW(buffer.upload(models, past_cut), std::invalid_argument);
  const std::span<const NodeId> two[] = {TreeCut::root_cut(h_).nodes(), {}};
  EXPECT_THROW(buffer.upload(models, two), std::invalid_argument);

  // The renderer's models change: the buffer's objects belong to the old ones.
  const std::vector<NodeId> root{0};
  const std::span<const NodeId> ok[] = {root};
  buffer.upload(models, ok);
  r.set_hierarchy(other_);
  const Camera cam = default_camera(h_.bounds_min(), h_.bounds_max(), kAspect);
  EXPECT_THROW(r.draw_scene(buffer, cam, RenderSettings{}), std::logic_error);
}

// The ObjectId mode, the exact visibility reference of occlusion culling:
// every pixel holds the index of the object in front, and an object's
// pixels are exactly those fast mode covers with it in front.
TEST_F(RenderSceneChecks, ObjectIdPixelsAreTheObjectInFront) {
  Renderer r(h_, {kWidth, kHeight});
  const Hierarchy* models[] = {&h_, &other_};
  r.set_models(models);
  // Object 1 half behind object 0, object 2 apart; all three in view.
  const SceneObject objects[] = {
      place_object(0, glm::mat4(1.0f)),
      place_object(1, glm::translate(glm::mat4(1.0f), glm::vec3(0.8f, 0.0f, -2.0f))),
      place_object(0, glm::translate(glm::mat4(1.0f), glm::vec3(-2.6f, 0.0f, 0.0f)))};
  const TreeCut a = TreeCut::leaf_cut(h_), b = TreeCut::leaf_cut(other_);
  const std::span<const NodeId> none;
  const Camera cam = fit_camera(glm::vec3(-4.0f, -1.5f, -3.5f), glm::vec3(2.5f, 1.5f, 1.5f),
                                kAspect, glm::vec3(0.0f, 0.0f, 1.0f));
  RenderSettings fast;
  fast.background = {1.0f, 0.0f, 1.0f};  // magenta: no lit splat has it
  RenderSettings ids;
  ids.mode = SplatMode::ObjectId;
  const auto draw = [&](std::span<const std::span<const NodeId>> cuts, const RenderSettings& s) {
    SceneCutBuffer buffer;
    buffer.set_objects(r, objects);
    buffer.upload(models, cuts);
    r.draw_scene(buffer, cam, s, true);
    return r.read_pixels();
  };
  const std::span<const NodeId> all[] = {a.nodes(), b.nodes(), a.nodes()};
  const std::vector<std::uint8_t> id = draw(all, ids);
  std::size_t counts[4] = {0, 0, 0, 0};
  for (std::size_t i = 0; i < id.size(); i += 4) {
    const std::uint32_t v = id[i] | (id[i + 1] << 8) | (id[i + 2] << 16);
    ASSERT_TRUE(v <= 2 || v == 0xffffff) << v;
    ++counts[v == 0xffffff ? 3 : v];
  }
  EXPECT_GT(counts[0], 200u);
  EXPECT_GT(counts[1], 200u);
  EXPECT_GT(counts[2], 200u);
  // Each object drawn alone: its id pixels are exactly the pixels fast mode
  // covers (the same discs), and in the whole scene it shows nowhere else.
  for (std::uint32_t k = 0; k < 3; ++k) {
    std::span<const NodeId> alone[3] = {none, none, none};
    alone[k] = all[k];
    const std::vector<std::uint8_t> f = draw(alone, fast);
    const std::vector<std::uint8_t> only = draw(alone, ids);
    std::size_t mismatch = 0, hidden_but_covered = 0;
    for (std::size_t i = 0; i < f.size(); i += 4) {
      const bool covered = !(f[i] == 255 && f[i + 1] == 0 && f[i + 2] == 255);
      const std::uint32_t v = only[i] | (only[i + 1] << 8) | (only[i + 2] << 16);
      mismatch += covered != (v == k);
      const std::uint32_t w = id[i] | (id[i + 1] << 8) | (id[i + 2] << 16);
      hidden_but_covered += w == k && !covered;
    }
    EXPECT_EQ(mismatch, 0u) << "object " << k << " alone: id and fast coverage differ";
    EXPECT_EQ(hidden_but_covered, 0u) << "object " << k;
  }
  // Object 1 is partly behind object 0: fewer of its pixels in the scene
  // than alone.
  std::span<const NodeId> only1[3] = {none, all[1], none};
  const std::vector<std::uint8_t> alone1 = draw(only1, ids);
  std::size_t alone1_count = 0;
  for (std::size_t i = 0; i < alone1.size(); i += 4)
    alone1_count += alone1[i] == 1 && alone1[i + 1] == 0;
  EXPECT_LT(counts[1], alone1_count);
}

TEST(ObjectRecord, TheIdentityIsExactAndSimilaritiesKeepCones) {
  const ObjectRecord id = object_record(glm::mat4(1.0f));
  EXPECT_EQ(id.row0, glm::vec4(1, 0, 0, 0));
  EXPECT_EQ(id.row1, glm::vec4(0, 1, 0, 0));
  EXPECT_EQ(id.row2, glm::vec4(0, 0, 1, 0));
  EXPECT_EQ(id.extra, glm::vec4(1, 1, 1, 0));
  const ObjectRecord rot = object_record(
      glm::scale(glm::rotate(glm::mat4(1.0f), 1.1f, glm::vec3(0, 0, 1)), glm::vec3(2.0f)));
  EXPECT_NEAR(rot.extra.x, 2.0f, 1e-5f);
  EXPECT_EQ(rot.extra.y, 1.0f);
  const ObjectRecord mirror = object_record(glm::scale(glm::mat4(1.0f), glm::vec3(-1, 1, 1)));
  EXPECT_EQ(mirror.extra.z, -1.0f);
  // Per-axis scale (2, 1, 0.5): sigma 2, widening 2 * 1 / 0.25 = 8.
  const ObjectRecord stretch = object_record(glm::scale(glm::mat4(1.0f), glm::vec3(2, 1, 0.5f)));
  EXPECT_NEAR(stretch.extra.x, 2.0f, 1e-4f);
  EXPECT_NEAR(stretch.extra.y, 8.0f, 1e-3f);
  EXPECT_GE(stretch.extra.x, 2.0f);
  EXPECT_GE(stretch.extra.y, 8.0f);
}

}  // namespace
}  // namespace treecut::splat
