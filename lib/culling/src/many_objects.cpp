// Scenes of many objects: boxes and the camera's view of them.
// After Peng & Cao, "Integrating Occlusion Culling and Parallel LOD for
// Rendering Complex 3D Environments on GPU" (I3D 2013,
// ../shared/papers/occlusion-culling-with-parallel-lod.txt), sections 5-6.
#include "treecut/culling/many_objects.hpp"

#include <cmath>
#include <glm/geometric.hpp>
#include <glm/matrix.hpp>
#include <random>
#include <stdexcept>

#include "treecut/query_proxy.hpp"

namespace treecut::culling {

Box bounds_of(const Obb& box) {
  glm::vec3 e(0.0f);
  for (int k = 0; k < 3; ++k) e += glm::abs(box.axes[k]) * box.half[k];
  return {box.center - e, box.center + e};
}

Obb transformed(const Obb& box, const glm::mat4& transform) {
  Obb r;
  r.center = glm::vec3(transform * glm::vec4(box.center, 1.0f));
  const glm::mat3 m(transform);
  for (int k = 0; k < 3; ++k) {
    const glm::vec3 a = m * box.axes[k];
    const float len = glm::length(a);
    r.axes[k] = len > 0.0f ? a / len : box.axes[k];
    r.half[k] = box.half[k] * len;
  }
  return r;
}

ObjectBounds box_object(const Obb& box, std::uint32_t points) {
  ObjectBounds o;
  o.box = box;
  o.bounds = bounds_of(box);
  o.inner = box;
  o.has_inner = true;
  o.points = points;
  o.compactness = 1.0f;
  return o;
}

RayHit ray_box(const Obb& box, glm::vec3 origin, glm::vec3 direction) {
  const glm::mat3 to_local = glm::transpose(box.axes);
  return ray_box_local(to_local * (origin - box.center), to_local * direction, box.half);
}

ViewSnapshot object_view(const ViewSnapshot& world_view, const glm::mat4& transform) {
  ViewSnapshot v = world_view;
  v.view = world_view.view * transform;
  v.finalize();
  return v;
}

void require_perspective_frustum(const ViewSnapshot& view) {
  if (!is_perspective_frustum(view.projection)) {
    throw std::invalid_argument("many objects: the projection is not a perspective frustum");
  }
  if (view.viewport.x <= 0 || view.viewport.y <= 0) {
    throw std::invalid_argument("many objects: empty viewport");
  }
}

ScreenRect project_box(const ViewSnapshot& view, const Box& box) {
  ScreenRect r;
  const float near_plane = view.derived.near_plane, far_plane = view.derived.far_plane;
  const glm::vec3 center = 0.5f * (box.lo + box.hi);
  const float radius = 0.5f * glm::length(box.hi - box.lo);
  // Most of a large scene is outside the frustum: six planes first.
  if (view.outside_frustum(center, radius)) return r;
  // Eye-space corners as the first one plus edge vectors: 8 corners from
  // one matrix product and three scaled columns.
  const glm::mat4& v = view.view;
  const glm::vec3 c0 = glm::vec3(v * glm::vec4(box.lo, 1.0f));
  const glm::vec3 ex = glm::vec3(v[0]) * (box.hi.x - box.lo.x);
  const glm::vec3 ey = glm::vec3(v[1]) * (box.hi.y - box.lo.y);
  const glm::vec3 ez = glm::vec3(v[2]) * (box.hi.z - box.lo.z);
  glm::vec3 corner[8];
  for (int i = 0; i < 8; ++i) {
    corner[i] = c0 + ((i & 1) ? ex : glm::vec3(0.0f)) + ((i & 2) ? ey : glm::vec3(0.0f)) +
                ((i & 4) ? ez : glm::vec3(0.0f));
  }
  const glm::mat4& p = view.projection;
  float lo_x = 3e38f, lo_y = 3e38f, hi_x = -3e38f, hi_y = -3e38f;
  float min_depth = 3e38f;
  bool front = false, behind = false;
  const auto add = [&](glm::vec3 e) {
    const float ze = -e.z;
    const float inv = 1.0f / ze;
    const float nx = (p[0][0] * e.x + p[2][0] * e.z) * inv;
    const float ny = (p[1][1] * e.y + p[2][1] * e.z) * inv;
    lo_x = std::min(lo_x, nx);
    hi_x = std::max(hi_x, nx);
    lo_y = std::min(lo_y, ny);
    hi_y = std::max(hi_y, ny);
  };
  for (const glm::vec3& e : corner) {
    const float ze = -e.z;
    if (ze >= near_plane) {
      front = true;
      min_depth = std::min(min_depth, ze);
      add(e);
    } else {
      behind = true;
    }
  }
  if (!front) return r;  // wholly on the camera's side of the near plane
  if (behind) {
    // Clip the 12 edges at the near plane: corners i and i ^ bit differ in
    // one coordinate.
    for (int i = 0; i < 8; ++i) {
      for (int bit = 1; bit < 8; bit <<= 1) {
        const int j = i ^ bit;
        if (j < i) continue;
        const float zi = -corner[i].z, zj = -corner[j].z;
        if ((zi >= near_plane) == (zj >= near_plane)) continue;
        const float s = (near_plane - zi) / (zj - zi);
        glm::vec3 e = corner[i] + s * (corner[j] - corner[i]);
        e.z = -near_plane;  // exactly on the plane despite rounding
        add(e);
      }
    }
    min_depth = near_plane;
    r.crosses_near = true;
  }
  r.depth = min_depth;
  if (min_depth > far_plane) return r;
  const float w = static_cast<float>(view.viewport.x), h = static_cast<float>(view.viewport.y);
  r.x0 = std::max(0.0f, (lo_x + 1.0f) * 0.5f * w);
  r.x1 = std::min(w, (hi_x + 1.0f) * 0.5f * w);
  r.y0 = std::max(0.0f, (lo_y + 1.0f) * 0.5f * h);
  r.y1 = std::min(h, (hi_y + 1.0f) * 0.5f * h);
  r.in_frustum = r.x0 < r.x1 && r.y0 < r.y1;
  return r;
}

}  // namespace treecut::culling

namespace treecut::culling {
namespace {

constexpr float kLot = 20.0f;
constexpr float kStreet = 12.0f;
constexpr std::size_t kLotsPerBlock = 4;

std::size_t city_side(std::size_t count) {
  return static_cast<std::size_t>(std::ceil(std::sqrt(static_cast<double>(count))));
}
// The lower corner of lot i along one axis: lots and, after every fourth, a street.
float lot_origin(std::size_t i) {
  return static_cast<float>(i) * kLot + static_cast<float>(i / kLotsPerBlock) * kStreet;
}

}  // namespace

std::vector<ObjectBounds> box_city(std::size_t count, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> unit(0.0f, 1.0f);
  const std::size_t side = city_side(count);
  std::vector<ObjectBounds> objects;
  objects.reserve(count);
  for (std::size_t k = 0; k < count; ++k) {
    const std::size_t i = k % side, j = k / side;
    const float w = 6.0f + 12.0f * unit(rng), d = 6.0f + 12.0f * unit(rng);
    const float u = unit(rng);
    const float height = 4.0f + 76.0f * u * u * u;  // mostly low, a few towers
    Obb box;
    box.half = {0.5f * w, 0.5f * height, 0.5f * d};
    if (unit(rng) < 1.0f / 3.0f) {
      const float yaw = 1.5707964f * unit(rng);
      box.axes = glm::mat3(glm::vec3(std::cos(yaw), 0.0f, -std::sin(yaw)), glm::vec3(0, 1, 0),
                           glm::vec3(std::sin(yaw), 0.0f, std::cos(yaw)));
    }
    // Within its lot (a turned box is shrunk until its AABB fits).
    Box b = bounds_of(box);
    const float fit =
        std::min(1.0f, 0.5f * kLot / std::max(b.hi.x - box.center.x, b.hi.z - box.center.z));
    box.half.x *= fit;
    box.half.z *= fit;
    box.center = {lot_origin(i) + 0.5f * kLot, 0.5f * height, lot_origin(j) + 0.5f * kLot};
    const auto points = static_cast<std::uint32_t>(2000.0f + 198000.0f * unit(rng) * unit(rng));
    objects.push_back(box_object(box, points));
  }
  return objects;
}

std::vector<ViewSnapshot> city_views(std::size_t count, std::size_t views, std::uint32_t seed,
                                     glm::ivec2 viewport) {
  std::mt19937 rng(seed ^ 0x9e3779b9u);
  std::uniform_real_distribution<float> unit(0.0f, 1.0f);
  const std::size_t side = city_side(count);
  const std::size_t streets = std::max<std::size_t>(1, side / kLotsPerBlock);
  const float extent = lot_origin(side);
  std::vector<ViewSnapshot> out;
  for (std::size_t v = 0; v < views; ++v) {
    // On a street (the gap after block s), somewhere along it.
    const std::size_t s =
        std::min(streets - 1, static_cast<std::size_t>(unit(rng) * static_cast<float>(streets)));
    const float across = lot_origin((s + 1) * kLotsPerBlock) - 0.5f * kStreet;
    const float along = extent * (0.1f + 0.8f * unit(rng));
    const bool x_street = unit(rng) < 0.5f;
    const glm::vec3 eye =
        x_street ? glm::vec3(along, 1.7f, across) : glm::vec3(across, 1.7f, along);
    // Along the street, or turned up to 40 degrees off it.
    float heading = (x_street ? 0.0f : 1.5707964f) + (unit(rng) < 0.5f ? 0.0f : 3.1415927f);
    heading += (unit(rng) - 0.5f) * 1.4f * (unit(rng) < 0.5f ? 1.0f : 0.0f);
    const glm::vec3 dir(std::cos(heading), 0.02f, std::sin(heading));
    out.push_back(ViewSnapshot::look_at(eye, eye + dir, viewport, 0.9f, 0.1f, 3000.0f));
  }
  return out;
}

}  // namespace treecut::culling
