// Scenes of many objects: the common ground of the budgeted LOD selection
// (budget.hpp) and the hierarchical Z-map culling (hzm.hpp), after
//   X. Peng, Y. Cao, "Integrating Occlusion Culling and Parallel LOD for
//   Rendering Complex 3D Environments on GPU", I3D 2013
//   (../shared/papers/occlusion-culling-with-parallel-lod.txt, sections 5, 6),
// on the CPU cores instead of CUDA.
//
// The input is a plain array of objects (ObjectBounds: a world oriented box,
// its world AABB, the points it has, its compactness), so a scene loader
// plugs in later by filling that array. Everything here is world space: the
// camera is a ViewSnapshot whose `view` maps world to eye (no model matrix
// folded in); object_view() folds one object's transform in for the
// per-object cut (budget.hpp, best_cut).
//
// Screen conventions, shared by the culler and the exact reference so that
// both speak about the same pixels: pixel (x, y) covers [x, x+1) x [y, y+1)
// with y up (OpenGL's window coordinates) and is sampled at its center, as
// the rasterizer does. Depth is the eye-space distance along the view axis
// (z_e = -z_eye > 0 in front of the camera), not the window depth.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <glm/mat3x3.hpp>
#include <glm/mat4x4.hpp>
#include <glm/vec2.hpp>
#include <glm/vec3.hpp>
#include <vector>

#include "treecut/culling/box.hpp"
#include "treecut/parallel.hpp"
#include "treecut/view_snapshot.hpp"

namespace treecut::culling {

/// Oriented box: center, unit orthogonal axes (columns of `axes`), half
/// extents along them.
struct Obb {
  glm::vec3 center{0.0f};
  glm::mat3 axes{1.0f};
  glm::vec3 half{0.0f};
};

/// The world AABB of an oriented box (exact: the box's extreme corners).
Box bounds_of(const Obb& box);
/// `box` moved by an affine transform (rotation, translation and scale per
/// axis are kept exactly; a shear makes the result the box of the transformed
/// axes, which then contains the transformed box only approximately).
Obb transformed(const Obb& box, const glm::mat4& transform);

/// The culling geometry of one scene object (treecut::SceneObject, the one
/// scene object, is the object; this is what the budget and the culler read
/// of it, kept in a dense array of their own, indexed as the scene's objects).
struct ObjectBounds {
  /// The object's oriented bounding box in world space (object OBB moved by
  /// its transform): what the exact reference draws for a box object.
  Obb box;
  /// World AABB containing `box`; the run-time tests use it (the paper:
  /// "we always use AABBs during run-time").
  Box bounds;
  /// A box inside the object's solid: what the object may write into the
  /// occluders' depth image (conservative: every ray that reaches it has hit
  /// the object already). For a box object (compactness 1) it is `box`.
  /// `has_inner` false: the object never occludes.
  Obb inner;
  bool has_inner = false;
  std::uint32_t points = 0;  ///< P_i: available points (the hierarchy's leaves)
  float compactness = 0.0f;  ///< Eq. 2, in [0, 1] (hzm.hpp, compactness())
};

/// A box object (a building): box, bounds and inner box all the same box,
/// compactness 1.
ObjectBounds box_object(const Obb& box, std::uint32_t points);

/// A seeded city of `count` box buildings (y up, ground at y = 0): lots of
/// 20 x 20 units on a square grid, a street of 12 units after every fourth
/// lot in both directions, one building per lot with a random footprint of
/// 6 to 18 units, a height of 4 to 80 (mostly low, a few towers), a third of
/// them turned about the vertical axis, and 2,000 to 200,000 points. The
/// same seed gives the same city. For the tests and the benchmark; scene
/// files come with the scene loader.
std::vector<ObjectBounds> box_city(std::size_t count, std::uint32_t seed);
/// Street-level cameras of a box_city(count, ...): `views` eyes at 1.7
/// units along and across the streets, looking along them or obliquely,
/// seeded.
std::vector<ViewSnapshot> city_views(std::size_t count, std::size_t views, std::uint32_t seed,
                                     glm::ivec2 viewport = {1280, 720});

/// What a camera sees of an AABB: its screen rectangle and nearest depth.
struct ScreenRect {
  /// The bounding rectangle of the projected box, clipped to the viewport,
  /// in pixels (x0 < x1 and y0 < y1 when not empty).
  float x0 = 0, y0 = 0, x1 = 0, y1 = 0;
  /// D_i: the smallest eye depth of the box's corners, or the near plane's
  /// when the box crosses it.
  float depth = 0;
  bool crosses_near = false;  ///< a corner lies in front of the near plane
  /// False when frustum culled: the box lies outside the viewport's
  /// rectangle, behind the near plane or beyond the far plane.
  bool in_frustum = false;
  /// A_i: area of the clipped rectangle in square pixels (0 when culled).
  [[nodiscard]] float area() const { return in_frustum ? (x1 - x0) * (y1 - y0) : 0.0f; }
};

/// Throws std::invalid_argument unless `view` is a perspective frustum with
/// a viewport (ViewSnapshot::perspective_frustum()): what the screen
/// rectangles and pixel rays of the culler need. The budget strategy checks
/// its view with this, so the stage names a bad view as the strategy's error.
void require_perspective_frustum(const ViewSnapshot& view);

/// The clipped screen rectangle and nearest depth of a world AABB seen by
/// `view` (finalized, a perspective frustum). A box crossing the near plane:
/// its 12 edges are clipped at the near plane and the rectangle bounds the
/// projected corners in front plus the edges' crossing points (the rectangle
/// of the box's part in front of the near plane, exact), and its depth is
/// the near plane's.
[[nodiscard]] ScreenRect project_box(const ViewSnapshot& view, const Box& box);

/// Entry and exit parameters of the ray o + t d through an oriented box
/// whose frame is given as (origin in box coordinates, direction in box
/// coordinates): t_in <= t_out when it hits. Slab method.
struct RayHit {
  float t_in = 0.0f;
  float t_out = -1.0f;
  [[nodiscard]] bool hit() const { return t_in <= t_out; }
};
[[gnu::always_inline]] inline RayHit ray_box_local(glm::vec3 o, glm::vec3 d, glm::vec3 half) {
  RayHit r{-3.0e38f, 3.0e38f};
  for (int k = 0; k < 3; ++k) {
    if (d[k] == 0.0f) {
      // Parallel to the slab: inside it or never.
      if (o[k] < -half[k] || o[k] > half[k]) return RayHit{};
      continue;
    }
    const float inv = 1.0f / d[k];
    float a = (-half[k] - o[k]) * inv;
    float b = (half[k] - o[k]) * inv;
    if (a > b) std::swap(a, b);
    r.t_in = std::max(r.t_in, a);
    r.t_out = std::min(r.t_out, b);
  }
  return r;
}
/// The same in world space.
RayHit ray_box(const Obb& box, glm::vec3 origin, glm::vec3 direction);

/// A ViewSnapshot for one object: the world camera with the object's
/// transform (object to world) folded into `view`, finalized; what the
/// single-model code (priorities, best_cut) expects.
ViewSnapshot object_view(const ViewSnapshot& world_view, const glm::mat4& transform);

}  // namespace treecut::culling
