// Occlusion culling with a hierarchical Z-map (strategies/include/treecut/
// strategies/hzm.hpp; Peng & Cao, I3D 2013, section 6): conservative against
// an exact reference, the max-reduction levels, the level of Eq. 5, the
// compactness of Eq. 2, the occluder weights of Eq. 3, the screen rectangles.
#include "treecut/culling/hzm.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <glm/geometric.hpp>
#include <limits>
#include <numbers>
#include <random>
#include <vector>

#include "treecut/culling/many_objects.hpp"

namespace treecut::culling {
namespace {

Obb axis_box(glm::vec3 center, glm::vec3 half) {
  Obb b;
  b.center = center;
  b.half = half;
  return b;
}

Obb turned_box(glm::vec3 center, glm::vec3 half, float yaw) {
  Obb b = axis_box(center, half);
  b.axes = glm::mat3(glm::vec3(std::cos(yaw), 0.0f, -std::sin(yaw)), glm::vec3(0, 1, 0),
                     glm::vec3(std::sin(yaw), 0.0f, std::cos(yaw)));
  return b;
}

// Random boxes in a cube of side 40 around the origin, some turned.
std::vector<ObjectBounds> random_boxes(std::size_t n, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> pos(-20.0f, 20.0f), size(0.2f, 4.0f), unit(0.0f, 1.0f);
  std::vector<ObjectBounds> out;
  for (std::size_t i = 0; i < n; ++i) {
    const glm::vec3 c(pos(rng), pos(rng), pos(rng));
    const glm::vec3 h(size(rng), size(rng), size(rng));
    out.push_back(box_object(
        unit(rng) < 0.4f ? turned_box(c, h, 6.2831853f * unit(rng)) : axis_box(c, h), 1000));
  }
  return out;
}

// A wall of boxes at z = 0 (a 6 x 4 grid of 2-unit boxes with 0.1 gaps) in
// front of a field of small boxes behind it (z from -5 to -40).
std::vector<ObjectBounds> wall_scene(std::uint32_t seed) {
  std::vector<ObjectBounds> out;
  for (int i = 0; i < 6; ++i) {
    for (int j = 0; j < 4; ++j) {
      out.push_back(box_object(axis_box({-6.3f + 2.1f * static_cast<float>(i) + 1.0f,
                                         2.1f * static_cast<float>(j) + 1.0f, 0.0f},
                                        {1.0f, 1.0f, 0.5f}),
                               5000));
    }
  }
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> x(-10.0f, 10.0f), y(0.0f, 10.0f), z(-40.0f, -5.0f),
      s(0.1f, 0.6f);
  for (int k = 0; k < 300; ++k) {
    out.push_back(box_object(axis_box({x(rng), y(rng), z(rng)}, {s(rng), s(rng), s(rng)}), 1000));
  }
  return out;
}

// Every object the reference sees is potentially visible; returns how many
// were culled (so a caller can also require that culling happened).
std::size_t expect_conservative(const std::vector<ObjectBounds>& objects, const ViewSnapshot& snap,
                                const HzmParams& params, WorkerPool* pool) {
  const ViewSnapshot& view = snap;
  HzmCuller culler(params);
  culler.preprocess(objects);
  culler.cull(objects, view, pool);
  std::vector<std::uint8_t> seen;
  reference_visibility(objects, view, seen, pool);
  std::size_t culled = 0;
  for (std::size_t i = 0; i < objects.size(); ++i) {
    if (seen[i]) {
      EXPECT_NE(culler.states()[i], ObjectState::Occluded)
          << "object " << i << " is seen by the reference but culled";
      EXPECT_NE(culler.states()[i], ObjectState::Outside)
          << "object " << i << " is seen by the reference but frustum culled";
    }
    culled += culler.states()[i] == ObjectState::Occluded;
  }
  const CullAccuracy a = cull_accuracy(culler, seen);
  EXPECT_EQ(a.wrongly, 0u);
  EXPECT_LE(a.culled, a.hidden);
  return culled;
}

TEST(Hzm, hzm_culling_is_conservative) {
  WorkerPool pool(2);
  std::size_t culled_total = 0;
  for (std::uint32_t seed = 1; seed <= 6; ++seed) {
    const auto objects = random_boxes(400, seed);
    std::mt19937 rng(seed * 77);
    std::uniform_real_distribution<float> a(0.0f, 6.2831853f);
    for (int v = 0; v < 4; ++v) {
      // Outside the cloud, inside it (boxes crossing the near plane), close up.
      const float r = v == 0 ? 60.0f : v == 1 ? 25.0f : v == 2 ? 5.0f : 1.0f;
      const float t = a(rng), p = 0.6f * (a(rng) / 6.2831853f - 0.5f);
      const glm::vec3 eye =
          r * glm::vec3(std::cos(t) * std::cos(p), std::sin(p), std::sin(t) * std::cos(p));
      const auto snap =
          ViewSnapshot::look_at(eye, glm::vec3(0.0f), {320, 200}, 0.9f, 0.05f, 500.0f);
      HzmParams params;
      params.active = 16;
      params.depth_width = seed % 2 ? 64 : 320;                    // cells of 5 pixels, and of one
      params.finer_levels = v % 3 == 0 ? 0 : v % 3 == 1 ? 2 : 10;  // the paper's test, finer
      culled_total += expect_conservative(objects, snap, params, &pool);
    }
  }
  for (std::uint32_t seed = 1; seed <= 4; ++seed) {
    const auto objects = wall_scene(seed);
    for (const glm::vec3 eye : {glm::vec3(0.0f, 4.0f, 12.0f), glm::vec3(3.0f, 2.0f, 4.0f),
                                glm::vec3(-8.0f, 5.0f, 10.0f), glm::vec3(0.0f, 12.0f, 10.0f)}) {
      const auto snap =
          ViewSnapshot::look_at(eye, {0.0f, 4.0f, -10.0f}, {400, 300}, 0.9f, 0.05f, 500.0f);
      HzmParams params;
      params.active = 24;
      params.depth_width = seed % 2 ? 100 : 400;
      params.finer_levels = static_cast<int>(seed) - 1;
      culled_total += expect_conservative(objects, snap, params, &pool);
    }
  }
  // Not vacuous: the wall hides most of the field from the front.
  EXPECT_GT(culled_total, 300u);
}

// The wall scene from the front, and the culler's settings for it: one
// depth cell a pixel, an AOS of `active`.
ViewSnapshot wall_front_view() {
  return ViewSnapshot::look_at({0.0f, 4.0f, 12.0f}, {0.0f, 4.0f, -10.0f}, {400, 300}, 0.9f, 0.05f,
                               500.0f);
}
HzmParams wall_params(std::size_t active) {
  HzmParams params;
  params.depth_width = 400;
  params.active = active;
  params.compactness_threshold = 0.5f;
  return params;
}

TEST(Hzm, wall_culls_what_it_hides) {
  const auto objects = wall_scene(3);
  const ViewSnapshot view = wall_front_view();
  HzmParams params = wall_params(24);
  params.finer_levels = 0;  // the paper's test
  HzmCuller culler(params);
  culler.preprocess(objects);
  culler.cull(objects, view, nullptr);
  std::vector<std::uint8_t> seen;
  reference_visibility(objects, view, seen, nullptr);
  const CullAccuracy a = cull_accuracy(culler, seen);
  EXPECT_EQ(a.wrongly, 0u);
  EXPECT_GT(a.hidden, 50u);
  EXPECT_GE(a.ratio(), 0.6) << a.culled << " culled of " << a.hidden << " hidden";
  std::printf("wall: %zu culled of %zu hidden\n", a.culled, a.hidden);
  // The 24 wall boxes are the active occluders (the largest, nearest, facing).
  EXPECT_EQ(culler.active().size(), 24u);
  for (const std::uint32_t i : culler.active()) EXPECT_LT(i, 24u);
}

// More occluders than the wall: the AOS takes field boxes behind the wall
// too. Those the wall hides are culled like any object (the paper keeps the
// AOS visible), those it does not are kept, none the reference sees is
// culled, and the map is the one the visible occluders alone would build.
TEST(Hzm, an_occluder_the_others_hide_is_culled) {
  const auto objects = wall_scene(3);
  const ViewSnapshot view = wall_front_view();
  const HzmParams params = wall_params(80);
  HzmCuller culler(params);
  culler.preprocess(objects);
  culler.cull(objects, view, nullptr);
  std::vector<std::uint8_t> seen;
  reference_visibility(objects, view, seen, nullptr);
  std::size_t hidden_occluders = 0, culled_occluders = 0;
  for (const std::uint32_t i : culler.active()) {
    const ObjectState st = culler.states()[i];
    if (seen[i]) {
      EXPECT_EQ(st, ObjectState::Occluder) << "seen occluder " << i << " culled";
    }
    hidden_occluders += seen[i] == 0;
    culled_occluders += st == ObjectState::Occluded;
    EXPECT_EQ(culler.visible()[i], st == ObjectState::Occluder ? 1 : 0);
  }
  EXPECT_EQ(culler.active().size(), 80u);
  EXPECT_GT(culled_occluders, 10u) << "of " << hidden_occluders << " hidden occluders";
  EXPECT_EQ(cull_accuracy(culler, seen).wrongly, 0u);
  // Culling them changed nothing: a culler whose AOS holds only the kept
  // occluders (the culled ones no candidates, the AOS that much smaller: the
  // top weights of the rest are the kept ones) builds the same map.
  std::vector<ObjectBounds> kept = objects;
  for (const std::uint32_t i : culler.active()) {
    if (culler.states()[i] == ObjectState::Occluded) kept[i].has_inner = false;
  }
  HzmParams fewer = params;
  fewer.active = params.active - culled_occluders;
  HzmCuller alone(fewer);
  alone.preprocess(kept);
  alone.cull(kept, view, nullptr);
  ASSERT_EQ(alone.depth_image().size(), culler.depth_image().size());
  EXPECT_TRUE(std::equal(alone.depth_image().begin(), alone.depth_image().end(),
                         culler.depth_image().begin()))
      << "a culled occluder was front-most in a cell";
}

// The depth image against ray casting of the active occluders' inner boxes:
// one cell a pixel, the front surface at the pixel center; larger cells,
// never nearer than the front surface at any pixel center under them, and
// empty where a pixel center sees no occluder.
TEST(Hzm, depth_image_bounds_the_occluders_front_surface) {
  const auto objects = random_boxes(300, 17);
  const auto snap =
      ViewSnapshot::look_at({30.0f, 8.0f, 35.0f}, glm::vec3(0.0f), {160, 120}, 0.9f, 0.05f, 500.0f);
  const ViewSnapshot& view = snap;
  for (const unsigned width : {160u, 40u, 23u}) {
    HzmParams params;
    params.depth_width = width;
    params.active = 20;
    HzmCuller culler(params);
    culler.preprocess(objects);
    culler.cull(objects, view, nullptr);
    ASSERT_EQ(culler.active().size(), 20u);
    const int s = culler.cell_pixels();
    EXPECT_EQ(s, (160 + static_cast<int>(width) - 1) / static_cast<int>(width));
    const glm::ivec2 dims = culler.depth_size();
    std::size_t exact_cells = 0;
    for (int cy = 0; cy < dims.y; ++cy) {
      for (int cx = 0; cx < dims.x; ++cx) {
        const float cell = culler.depth_image()[static_cast<std::size_t>(cy * dims.x + cx)];
        float farthest = 0.0f;  // the largest front depth over the cell's pixel centers
        for (int py = cy * s; py < std::min(120, (cy + 1) * s); ++py) {
          for (int px = cx * s; px < std::min(160, (cx + 1) * s); ++px) {
            const glm::vec3 d =
                view.ray_direction(static_cast<float>(px) + 0.5f, static_cast<float>(py) + 0.5f);
            float front = std::numeric_limits<float>::infinity();
            for (const std::uint32_t i : culler.active()) {
              const RayHit h = ray_box(objects[i].inner, view.derived.eye, d);
              if (h.hit() && h.t_in > 0.0f) front = std::min(front, h.t_in);
            }
            farthest = std::max(farthest, front);
          }
        }
        if (std::isinf(cell)) continue;  // nothing written: never wrong
        EXPECT_GE(cell, farthest * (1.0f - 1e-5f))
            << "cell " << cx << "," << cy << " width " << width;
        if (s == 1) {
          EXPECT_NEAR(cell, farthest, 1e-4f * farthest);
          ++exact_cells;
        }
      }
    }
    if (s == 1) {
      EXPECT_GT(exact_cells, 1000u);  // the occluders cover much of the view
    }
  }
}

TEST(Hzm, max_reduction_levels) {
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> d(1.0f, 100.0f);
  for (const glm::ivec2 size :
       {glm::ivec2(13, 7), glm::ivec2(16, 16), glm::ivec2(1, 9), glm::ivec2(33, 2)}) {
    std::vector<float> base(static_cast<std::size_t>(size.x * size.y));
    for (float& x : base) x = d(rng);
    base[3 % base.size()] = std::numeric_limits<float>::infinity();  // an empty cell
    WorkerPool pool(2);
    HierarchicalZMap hzm;
    hzm.build(base, size.x, size.y, &pool);
    ASSERT_GE(hzm.levels(), 1);
    EXPECT_EQ(hzm.width(hzm.levels() - 1), 1);
    EXPECT_EQ(hzm.height(hzm.levels() - 1), 1);
    for (int l = 0; l < hzm.levels(); ++l) {
      EXPECT_EQ(hzm.width(l), (size.x + (1 << l) - 1) >> l);
      EXPECT_EQ(hzm.height(l), (size.y + (1 << l) - 1) >> l);
      for (int y = 0; y < hzm.height(l); ++y) {
        for (int x = 0; x < hzm.width(l); ++x) {
          // The max over the level-0 cells it covers.
          float m = -1.0f;
          for (int by = y << l; by < std::min(size.y, (y + 1) << l); ++by)
            for (int bx = x << l; bx < std::min(size.x, (x + 1) << l); ++bx)
              m = std::max(m, base[static_cast<std::size_t>(by * size.x + bx)]);
          EXPECT_EQ(hzm.at(l, x, y), m) << "level " << l << " cell " << x << "," << y;
        }
      }
    }
  }
}

TEST(Hzm, eq5_level_choice) {
  std::vector<float> base(256 * 256, 1.0f);
  HierarchicalZMap hzm;
  hzm.build(base, 256, 256, nullptr);
  EXPECT_EQ(hzm.levels(), 9);  // log2 256 + 1, as the paper's count
  EXPECT_EQ(hzm.level_for(1), 0);
  EXPECT_EQ(hzm.level_for(2), 1);
  EXPECT_EQ(hzm.level_for(3), 2);
  EXPECT_EQ(hzm.level_for(4), 2);
  EXPECT_EQ(hzm.level_for(5), 3);
  EXPECT_EQ(hzm.level_for(256), 8);
  EXPECT_EQ(hzm.level_for(1000), 8);  // clamped to the coarsest
  // A square of R cells lies on 1 to 4 cells of its level, anywhere; one
  // level finer it may need more (the level is the finest that bounds it).
  std::mt19937 rng(9);
  std::uniform_int_distribution<int> pos(0, 255), len(1, 100);
  bool finer_needs_more = false;
  for (int k = 0; k < 2000; ++k) {
    const int r = len(rng);
    const int x0 = std::min(pos(rng), 256 - r), y0 = std::min(pos(rng), 256 - r);
    const int x1 = x0 + r - 1, y1 = y0 + r - 1;
    const int l = hzm.level_for(r);
    EXPECT_LE((x1 >> l) - (x0 >> l) + 1, 2);
    EXPECT_LE((y1 >> l) - (y0 >> l) + 1, 2);
    EXPECT_GE(1 << l, r);
    if (l > 0) finer_needs_more |= (x1 >> (l - 1)) - (x0 >> (l - 1)) + 1 > 2;
    int used = -1;
    EXPECT_EQ(hzm.max_over(x0, y0, x1, y1, &used), 1.0f);
    EXPECT_EQ(used, l);
  }
  EXPECT_TRUE(finer_needs_more);
}

TEST(Hzm, max_over_reads_every_cell_under_the_rectangle) {
  std::vector<float> base(64 * 32, 1.0f);
  base[static_cast<std::size_t>(10 * 64 + 37)] = 9.0f;
  HierarchicalZMap hzm;
  hzm.build(base, 64, 32, nullptr);
  EXPECT_EQ(hzm.max_over(37, 10, 37, 10), 9.0f);
  EXPECT_EQ(hzm.max_over(30, 5, 40, 12), 9.0f);
  EXPECT_EQ(hzm.max_over(0, 0, 20, 20), 1.0f);
}

TEST(Hzm, compactness_eq2) {
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  // Points on the surface of a 4 x 2 x 1 box, turned.
  const glm::vec3 h(2.0f, 1.0f, 0.5f);
  const Obb truth = turned_box({3.0f, 1.0f, -2.0f}, h, 0.7f);
  std::vector<glm::vec3> box_points;
  for (int k = 0; k < 60000; ++k) {
    glm::vec3 l(u(rng) * h.x, u(rng) * h.y, u(rng) * h.z);
    const int face = k % 3;
    l[face] = (k / 3) % 2 ? h[face] : -h[face];
    box_points.push_back(truth.center + truth.axes * l);
  }
  const Obb fit = fit_obb(box_points);
  std::vector<float> got{fit.half.x, fit.half.y, fit.half.z}, want{h.x, h.y, h.z};
  std::sort(got.begin(), got.end());
  std::sort(want.begin(), want.end());
  for (int k = 0; k < 3; ++k)
    EXPECT_NEAR(got[static_cast<std::size_t>(k)], want[static_cast<std::size_t>(k)], 0.02f);
  EXPECT_NEAR(glm::length(fit.center - truth.center), 0.0f, 0.02f);
  EXPECT_GT(compactness(box_points, fit), 0.97f);

  // A sphere's surface fills pi/4 of each face.
  std::vector<glm::vec3> sphere;
  std::normal_distribution<float> g(0.0f, 1.0f);
  for (int k = 0; k < 60000; ++k)
    sphere.push_back(glm::normalize(glm::vec3(g(rng), g(rng), g(rng))));
  const float cs = compactness(sphere, fit_obb(sphere));
  EXPECT_NEAR(cs, std::numbers::pi_v<float> / 4.0f, 0.05f);

  // A thin plus sign (two crossed rods in a plane) fills little.
  std::vector<glm::vec3> plus;
  for (int k = 0; k < 20000; ++k) {
    const float t = u(rng) * 5.0f, w = u(rng) * 0.1f;
    plus.push_back(k % 2 ? glm::vec3(t, w, 0.0f) : glm::vec3(w, t, 0.0f));
  }
  const float cp = compactness(plus, fit_obb(plus));
  EXPECT_LT(cp, 0.3f);
  EXPECT_GT(cp, 0.0f);
  // The candidate set follows the threshold.
  std::vector<ObjectBounds> objects(3);
  objects[0] = box_object(truth, 100);
  objects[1] = box_object(truth, 100);
  objects[1].compactness = cs;
  objects[2] = box_object(truth, 100);
  objects[2].compactness = cp;
  HzmCuller culler({64, 4, 0.55f});
  culler.preprocess(objects);
  ASSERT_EQ(culler.candidates().size(), 2u);
  EXPECT_EQ(culler.candidates()[0], 0u);  // compactness descending
  EXPECT_EQ(culler.candidates()[1], 1u);
}

TEST(Hzm, inner_box_lies_inside_a_closed_surface) {
  std::mt19937 rng(4);
  std::normal_distribution<float> g(0.0f, 1.0f);
  // A sphere of radius 2 at (1, 2, 3): the inner box's corners are inside it,
  // and it is not tiny.
  std::vector<glm::vec3> sphere;
  for (int k = 0; k < 100000; ++k) {
    sphere.push_back(glm::vec3(1.0f, 2.0f, 3.0f) +
                     2.0f * glm::normalize(glm::vec3(g(rng), g(rng), g(rng))));
  }
  const Obb fit = fit_obb(sphere);
  const auto inner = inner_box(sphere, fit);
  ASSERT_TRUE(inner.has_value());
  for (int c = 0; c < 8; ++c) {
    const glm::vec3 l((c & 1) ? inner->half.x : -inner->half.x,
                      (c & 2) ? inner->half.y : -inner->half.y,
                      (c & 4) ? inner->half.z : -inner->half.z);
    EXPECT_LT(glm::length(inner->center + inner->axes * l - glm::vec3(1.0f, 2.0f, 3.0f)), 2.0f);
  }
  // At most the inscribed cube, (4 / sqrt 3)^3 = 12.3; the greedy growth gets most of it.
  EXPECT_GT(8.0f * inner->half.x * inner->half.y * inner->half.z, 0.6f * 12.3f);
  // The surface of a box: nearly the box.
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  const glm::vec3 h(3.0f, 1.0f, 2.0f);
  std::vector<glm::vec3> box_points;
  for (int k = 0; k < 100000; ++k) {
    glm::vec3 l(u(rng) * h.x, u(rng) * h.y, u(rng) * h.z);
    const int face = k % 3;
    l[face] = (k / 3) % 2 ? h[face] : -h[face];
    box_points.push_back(l);
  }
  const auto bi = inner_box(box_points, axis_box(glm::vec3(0.0f), h));
  ASSERT_TRUE(bi.has_value());
  for (int k = 0; k < 3; ++k) {
    EXPECT_LE(bi->half[k], h[k]);
    EXPECT_GE(bi->half[k], h[k] * (1.0f - 4.0f / 32.0f));
  }
  // An open surface (a hemisphere's shell) encloses nothing: no inner box.
  std::vector<glm::vec3> open;
  for (const glm::vec3& p : sphere)
    if (p.y > 2.0f) open.push_back(p);
  EXPECT_FALSE(inner_box(open, fit_obb(open)).has_value());
}

TEST(Hzm, inner_box_of_a_surface_open_on_one_face_reaches_the_closing_plane) {
  std::mt19937 rng(9);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  const glm::vec3 h(3.0f, 2.0f, 4.0f);
  const Obb box = axis_box(glm::vec3(0.0f), h);
  // A box's surface without its floor (z = -h.z): walls and a roof.
  const auto floorless = [&](std::vector<glm::vec3>& out, float floor_z, int count) {
    for (int k = 0; k < count; ++k) {
      glm::vec3 l(u(rng) * h.x, u(rng) * h.y, floor_z + (h.z - floor_z) * 0.5f * (u(rng) + 1.0f));
      const int face = k % 5;  // -x, +x, -y, +y, +z
      if (face < 4)
        l[face / 2] = face % 2 ? h[face / 2] : -h[face / 2];
      else
        l.z = h.z;
      out.push_back(l);
    }
  };
  std::vector<glm::vec3> open;
  floorless(open, -h.z, 100000);
  EXPECT_FALSE(inner_box(open, box).has_value()) << "the outside floods in through the floor";
  EXPECT_FALSE(inner_box(open, box, 32, 5).has_value()) << "closing the roof does not close it";
  const auto closed = inner_box(open, box, 32, 4);
  ASSERT_TRUE(closed.has_value());
  // Down to the plane of the open face, the other sides a cell or two in.
  EXPECT_FLOAT_EQ(closed->center.z - closed->half.z, -h.z);
  EXPECT_LE(closed->center.z + closed->half.z, h.z);
  for (int k = 0; k < 2; ++k) {
    EXPECT_LE(closed->half[k], h[k]);
    EXPECT_GE(closed->half[k], h[k] * (1.0f - 4.0f / 32.0f));
  }
  // On stilts: the floorless box's walls stop at z = 0 and there is a floor
  // plate there; below it the air is open to the street on every side.
  // Closing the face at z = -h.z must not claim that air.
  std::vector<glm::vec3> stilts;
  floorless(stilts, 0.0f, 100000);
  for (int k = 0; k < 40000; ++k) stilts.push_back({u(rng) * h.x, u(rng) * h.y, 0.0f});
  const auto raised = inner_box(stilts, box, 32, 4);
  ASSERT_TRUE(raised.has_value());  // the closed upper part
  EXPECT_GT(raised->center.z - raised->half.z, 0.0f);
}

TEST(Hzm, occluders_are_the_top_weights_of_eq3) {
  const auto objects = random_boxes(500, 11);
  const auto snap =
      ViewSnapshot::look_at({0.0f, 0.0f, 45.0f}, glm::vec3(0.0f), {320, 240}, 0.9f, 0.05f, 500.0f);
  const ViewSnapshot& view = snap;
  // Both readings of E: the viewing direction, the eye to the AABB's center.
  for (const Facing facing : {Facing::ViewDirection, Facing::EyeToObject}) {
    HzmParams params{64, 10, 0.5f};
    params.facing = facing;
    HzmCuller culler(params);
    culler.preprocess(objects);
    culler.project(objects, view, nullptr);
    culler.select_occluders(objects, view, nullptr);
    ASSERT_EQ(culler.active().size(), 10u);
    // The weights by hand: AABB volume * |N . E| / distance to the AABB.
    std::vector<std::pair<float, std::uint32_t>> w;
    for (std::uint32_t i = 0; i < objects.size(); ++i) {
      const ObjectBounds& o = objects[i];
      const ScreenRect r = project_box(view, o.bounds);
      if (!r.in_frustum || r.crosses_near) continue;
      int k = 0;
      for (int a = 1; a < 3; ++a)
        if (o.box.half[a] < o.box.half[k]) k = a;
      const glm::vec3 e = view.derived.eye;
      const glm::vec3 out = glm::max(glm::max(o.bounds.lo - e, e - o.bounds.hi), glm::vec3(0.0f));
      const glm::vec3 s = o.bounds.hi - o.bounds.lo;
      const glm::vec3 dir = facing == Facing::ViewDirection
                                ? view.derived.forward
                                : glm::normalize(0.5f * (o.bounds.lo + o.bounds.hi) - e);
      const float weight =
          s.x * s.y * s.z * std::abs(glm::dot(o.box.axes[k], dir)) / glm::length(out);
      EXPECT_FLOAT_EQ(weight, occluder_weight(o, o.box.axes[k], r, view, facing));
      w.push_back({weight, i});
    }
    std::sort(w.begin(), w.end(), [](auto a, auto b) {
      return a.first != b.first ? a.first > b.first : a.second < b.second;
    });
    for (std::size_t k = 0; k < 10; ++k) EXPECT_EQ(culler.active()[k], w[k].second);
    // Nothing behind the camera or outside the frustum is chosen.
    for (const std::uint32_t i : culler.active()) EXPECT_TRUE(culler.rects()[i].in_frustum);
  }
}

TEST(Hzm, screen_rectangles_and_near_plane) {
  const auto snap =
      ViewSnapshot::look_at({0.0f, 0.0f, 10.0f}, glm::vec3(0.0f), {200, 100}, 0.9f, 0.5f, 100.0f);
  const ViewSnapshot& view = snap;
  EXPECT_NEAR(view.derived.near_plane, 0.5f, 1e-4f);
  EXPECT_NEAR(view.derived.far_plane, 100.0f, 0.05f);
  // In front: the rectangle of the projected corners, depth of the nearest.
  const ScreenRect r = project_box(view, {{-1.0f, -1.0f, -1.0f}, {1.0f, 1.0f, 1.0f}});
  ASSERT_TRUE(r.in_frustum);
  EXPECT_FALSE(r.crosses_near);
  EXPECT_NEAR(r.depth, 9.0f, 1e-4f);
  const float f = 1.0f / std::tan(0.45f);  // projection[1][1]
  const float half_h = 1.0f * f / 9.0f * 50.0f, half_w = 1.0f * f / 9.0f * 50.0f;
  EXPECT_NEAR(r.x1 - r.x0, 2.0f * half_w, 1e-2f);
  EXPECT_NEAR(r.y1 - r.y0, 2.0f * half_h, 1e-2f);
  EXPECT_NEAR(0.5f * (r.x0 + r.x1), 100.0f, 1e-3f);
  EXPECT_NEAR(r.area(), (r.x1 - r.x0) * (r.y1 - r.y0), 1e-3f);
  // Behind the camera: culled.
  EXPECT_FALSE(project_box(view, {{-1.0f, -1.0f, 20.0f}, {1.0f, 1.0f, 22.0f}}).in_frustum);
  // Beyond the far plane: culled.
  EXPECT_FALSE(project_box(view, {{-1.0f, -1.0f, -200.0f}, {1.0f, 1.0f, -190.0f}}).in_frustum);
  // Off to the side: culled.
  EXPECT_FALSE(project_box(view, {{50.0f, -1.0f, -1.0f}, {52.0f, 1.0f, 1.0f}}).in_frustum);
  // Crossing the near plane: depth = near, the rectangle of the part in
  // front (clipped to the viewport), never culled by the HZM.
  const ScreenRect c = project_box(view, {{-0.2f, -0.2f, 9.0f}, {0.2f, 0.2f, 11.0f}});
  ASSERT_TRUE(c.in_frustum);
  EXPECT_TRUE(c.crosses_near);
  EXPECT_FLOAT_EQ(c.depth, view.derived.near_plane);
  const float at_near = 0.2f * f / 0.5f * 50.0f;  // half size at the near plane, pixels
  EXPECT_NEAR(c.y1 - c.y0, std::min(100.0f, 2.0f * at_near), 1e-2f);
}

TEST(Hzm, independent_of_the_thread_count) {
  const auto objects = box_city(3000, 4);
  const auto views = city_views(3000, 3, 4, {320, 180});
  WorkerPool one(1), two(2);
  for (const auto& snap : views) {
    const ViewSnapshot& view = snap;
    HzmCuller a, b;
    a.preprocess(objects);
    b.preprocess(objects);
    a.cull(objects, view, &one);
    b.cull(objects, view, &two);
    EXPECT_TRUE(std::equal(a.states().begin(), a.states().end(), b.states().begin()));
    EXPECT_TRUE(
        std::equal(a.active().begin(), a.active().end(), b.active().begin(), b.active().end()));
    std::vector<std::uint8_t> ra, rb;
    reference_visibility(objects, view, ra, &one);
    reference_visibility(objects, view, rb, &two);
    EXPECT_EQ(ra, rb);
    const CullAccuracy acc = cull_accuracy(b, rb);
    EXPECT_EQ(acc.wrongly, 0u);
  }
}

TEST(Hzm, worker_pool_runs_every_chunk_once_and_rethrows) {
  WorkerPool pool(2);
  EXPECT_EQ(pool.threads(), 2u);
  for (int round = 0; round < 50; ++round) {
    std::vector<int> hits(10007, 0);
    pool.run(hits.size(), 100, [&](std::size_t b, std::size_t e, std::size_t c) {
      EXPECT_EQ(b, c * 100);
      for (std::size_t i = b; i < e; ++i) ++hits[i];
    });
    EXPECT_TRUE(std::all_of(hits.begin(), hits.end(), [](int h) { return h == 1; }));
  }
  EXPECT_THROW(pool.run(1000, 10,
                        [](std::size_t b, std::size_t, std::size_t) {
                          if (b == 500) throw std::runtime_error("chunk 50");
                        }),
               std::runtime_error);
  // Still usable after an exception.
  std::atomic<int> n{0};
  pool.run(100, 1, [&](std::size_t, std::size_t, std::size_t) { ++n; });
  EXPECT_EQ(n.load(), 100);
  // Many small jobs in a row: a worker that wakes after its job is done
  // must not run a chunk of the next one with the old body.
  for (int round = 0; round < 5000; ++round) {
    std::vector<int> hits(3, 0);
    // (An old body would bump a destroyed vector: ASan; and leave these at 0.)
    pool.run(3, 1, [&hits](std::size_t b, std::size_t, std::size_t) { ++hits[b]; });
    ASSERT_EQ(hits, (std::vector<int>{1, 1, 1})) << "round " << round;
  }
}

}  // namespace
}  // namespace treecut::culling
