// Hierarchical Z-map culling: the exact CPU reference (every object's box ray
// cast at the pixel centers) and the accuracy count against it (the paper's
// Table 4 ratio).
// Peng & Cao, "Integrating Occlusion Culling and Parallel LOD for Rendering
// Complex 3D Environments on GPU", I3D 2013
// (../shared/papers/occlusion-culling-with-parallel-lod.txt), section 6,
// on the CPU cores. What each step does and why it is conservative: hzm.hpp
// and docs/many-objects.md, "Occlusion culling with a hierarchical Z-map".
#include <algorithm>
#include <array>
#include <cmath>
#include <glm/geometric.hpp>
#include <glm/matrix.hpp>
#include <limits>
#include <vector>

#include "hzm_internal.hpp"
#include "treecut/culling/hzm.hpp"

namespace treecut::culling {
using detail::kInf;
using detail::kObjectGrain;

namespace {

// Rays of a frame in one box's frame: the direction is affine in NDC.
struct BoxRays {
  glm::vec3 o, qx, qy, q0, half;
  BoxRays(const Obb& b, const ViewSnapshot& v) {
    const glm::mat3 t = glm::transpose(b.axes);
    o = t * (v.derived.eye - b.center);
    qx = t * v.derived.ray_x;
    qy = t * v.derived.ray_y;
    q0 = t * v.derived.ray_0;
    half = b.half;
  }
  [[nodiscard]] RayHit at(float nx, float ny) const {
    return ray_box_local(o, q0 + qy * ny + qx * nx, half);
  }
};

}  // namespace

void reference_visibility(std::span<const ObjectBounds> objects, const ViewSnapshot& view,
                          std::vector<std::uint8_t>& visible, WorkerPool* pool,
                          std::vector<std::uint32_t>* ids) {
  require_perspective_frustum(view);
  const glm::ivec2 vp = view.viewport;
  const std::size_t width = static_cast<std::size_t>(vp.x);
  std::vector<std::uint32_t> local_ids;
  std::vector<std::uint32_t>& id = ids != nullptr ? *ids : local_ids;
  id.assign(width * static_cast<std::size_t>(vp.y), ~0u);
  std::vector<ScreenRect> rects(objects.size());
  for_chunks(pool, objects.size(), kObjectGrain, [&](std::size_t b, std::size_t e, std::size_t) {
    for (std::size_t i = b; i < e; ++i) rects[i] = project_box(view, objects[i].bounds);
  });
  const float near_plane = view.derived.near_plane, far_plane = view.derived.far_plane;
  const float to_ndc_x = 2.0f / static_cast<float>(vp.x),
              to_ndc_y = 2.0f / static_cast<float>(vp.y);
  // Bands of rows: each band owns its rows of the id and depth buffers.
  for_chunks(
      pool, static_cast<std::size_t>(vp.y), 16, [&](std::size_t b, std::size_t e, std::size_t) {
        std::vector<float> depth((e - b) * width, kInf);
        for (std::size_t i = 0; i < objects.size(); ++i) {
          const ScreenRect& r = rects[i];
          if (!r.in_frustum) continue;
          // Pixel centers inside the rectangle (edges included).
          const int py0 = std::max(static_cast<int>(b), static_cast<int>(std::ceil(r.y0 - 0.5f)));
          const int py1 =
              std::min(static_cast<int>(e) - 1, static_cast<int>(std::floor(r.y1 - 0.5f)));
          if (py0 > py1) continue;
          const int px0 = std::max(0, static_cast<int>(std::ceil(r.x0 - 0.5f)));
          const int px1 = std::min(vp.x - 1, static_cast<int>(std::floor(r.x1 - 0.5f)));
          if (px0 > px1) continue;
          const BoxRays rays(objects[i].box, view);
          for (int py = py0; py <= py1; ++py) {
            const float ny = (static_cast<float>(py) + 0.5f) * to_ndc_y - 1.0f;
            float* drow = depth.data() + (static_cast<std::size_t>(py) - b) * width;
            std::uint32_t* irow = id.data() + static_cast<std::size_t>(py) * width;
            for (int px = px0; px <= px1; ++px) {
              const float nx = (static_cast<float>(px) + 0.5f) * to_ndc_x - 1.0f;
              const RayHit hit = rays.at(nx, ny);
              if (!hit.hit()) continue;
              // The first surface at or beyond the near plane: the front, or the
              // back faces of a box the near plane cuts (drawn without culling).
              const float t = hit.t_in >= near_plane ? hit.t_in : hit.t_out;
              if (t < near_plane || t > far_plane) continue;
              if (t < drow[px]) {
                drow[px] = t;
                irow[px] = static_cast<std::uint32_t>(i);
              }
            }
          }
        }
      });
  visible.assign(objects.size(), 0);
  for (const std::uint32_t i : id)
    if (i != ~0u) visible[i] = 1;
}

CullAccuracy cull_accuracy(const HzmCuller& culler, std::span<const std::uint8_t> reference) {
  CullAccuracy a;
  const auto states = culler.states();
  const auto rects = culler.rects();
  for (std::size_t i = 0; i < states.size(); ++i) {
    if (states[i] == ObjectState::Outside) continue;
    const bool seen = reference[i] != 0;
    if (!seen) {
      ++a.hidden;
      const ScreenRect& r = rects[i];
      if (std::ceil(r.x0 - 0.5f) > std::floor(r.x1 - 0.5f) ||
          std::ceil(r.y0 - 0.5f) > std::floor(r.y1 - 0.5f)) {
        ++a.subpixel;
      }
    }
    if (states[i] == ObjectState::Occluded) {
      ++a.culled;
      if (seen) ++a.wrongly;
    }
  }
  return a;
}

}  // namespace treecut::culling
