// Hierarchical Z-map culling: the Z pyramid (max-reduction of 2 x 2 cells),
// the level of Eq. 5 and the occlusion test of every object in the frustum.
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

void HierarchicalZMap::build(std::span<const float> base, int width, int height, WorkerPool* pool) {
  dims_.clear();
  dims_.push_back({width, height});
  while (dims_.back().x > 1 || dims_.back().y > 1) {
    dims_.push_back({(dims_.back().x + 1) / 2, (dims_.back().y + 1) / 2});
  }
  levels_.resize(dims_.size());
  levels_[0].assign(base.begin(), base.end());
  for (std::size_t l = 1; l < dims_.size(); ++l) {
    const glm::ivec2 d = dims_[l], s = dims_[l - 1];
    levels_[l].resize(static_cast<std::size_t>(d.x) * static_cast<std::size_t>(d.y));
    const std::vector<float>& src = levels_[l - 1];
    std::vector<float>& dst = levels_[l];
    const auto rows = [&](std::size_t b, std::size_t e, std::size_t) {
      for (std::size_t y = b; y < e; ++y) {
        const std::size_t y0 = 2 * y,
                          y1 = std::min<std::size_t>(2 * y + 1, static_cast<std::size_t>(s.y) - 1);
        for (std::size_t x = 0; x < static_cast<std::size_t>(d.x); ++x) {
          const std::size_t x0 = 2 * x, x1 = std::min<std::size_t>(
                                            2 * x + 1, static_cast<std::size_t>(s.x) - 1);
          const std::size_t w = static_cast<std::size_t>(s.x);
          dst[y * static_cast<std::size_t>(d.x) + x] =
              std::max(std::max(src[y0 * w + x0], src[y0 * w + x1]),
                       std::max(src[y1 * w + x0], src[y1 * w + x1]));
        }
      }
    };
    // Small levels are not worth a hand-over to the workers.
    const std::size_t grain = std::max<std::size_t>(1, 8192 / static_cast<std::size_t>(d.x));
    if (static_cast<std::size_t>(d.x) * static_cast<std::size_t>(d.y) >= 16384) {
      for_chunks(pool, static_cast<std::size_t>(d.y), grain, rows);
    } else {
      rows(0, static_cast<std::size_t>(d.y), 0);
    }
  }
}

int HierarchicalZMap::level_for(int r) const {
  int l = 0;
  while ((1 << l) < r) ++l;
  return std::min(l, levels() - 1);
}

float HierarchicalZMap::max_over(int x0, int y0, int x1, int y1, int* level) const {
  const int l = level_for(std::max(x1 - x0 + 1, y1 - y0 + 1));
  if (level != nullptr) *level = l;
  return max_over_at(l, x0, y0, x1, y1);
}

float HierarchicalZMap::max_over_at(int level, int x0, int y0, int x1, int y1) const {
  const int l = std::clamp(level, 0, levels() - 1);
  float m = -kInf;
  for (int y = y0 >> l; y <= (y1 >> l); ++y) {
    for (int x = x0 >> l; x <= (x1 >> l); ++x) m = std::max(m, at(l, x, y));
  }
  return m;
}

void HzmCuller::test(std::span<const ObjectBounds> objects, WorkerPool* pool) {
  states_.resize(objects.size());
  visible_.resize(objects.size());
  for_chunks(pool, objects.size(), kObjectGrain, [&](std::size_t b, std::size_t e, std::size_t) {
    for (std::size_t i = b; i < e; ++i) {
      const ScreenRect& r = rects_[i];
      ObjectState st = ObjectState::Outside;
      if (r.in_frustum) {
        st = ObjectState::Visible;
        if (!r.crosses_near) {
          // Level-0 cells under every pixel the rectangle touches.
          const int x0 = static_cast<int>(r.x0) / cell_;
          const int y0 = static_cast<int>(r.y0) / cell_;
          const int x1 = std::min(depth_dims_.x - 1, static_cast<int>(r.x1) / cell_);
          const int y1 = std::min(depth_dims_.y - 1, static_cast<int>(r.y1) / cell_);
          int level = 0;
          const float m = hzm_.max_over(x0, y0, x1, y1, &level);
          if (r.depth > m * (1.0f + kDepthMargin)) {
            st = ObjectState::Occluded;
          } else if (params_.finer_levels > 0 && level > 0) {
            const float f = hzm_.max_over_at(level - params_.finer_levels, x0, y0, x1, y1);
            if (r.depth > f * (1.0f + kDepthMargin)) st = ObjectState::Occluded;
          }
        }
      }
      states_[i] = st;
      visible_[i] = st == ObjectState::Visible ? 1 : 0;
    }
  });
  // The paper takes the AOS as visible by definition; added: an occluder is
  // tested like the others, and culled when the others hide it. Its own
  // cells cannot cull it (each holds a depth of its inner box, which lies
  // behind its AABB's nearest depth), so a culled occluder is front-most in
  // no cell: the map without it is the same map, and what it culled stays
  // culled by the occluders in front of it. (19 to 22 of the 32 occluders
  // of a city block's street frame are hidden: docs/many-objects.md.)
  for (const std::uint32_t i : aos_) {
    if (states_[i] == ObjectState::Occluded) continue;
    states_[i] = ObjectState::Occluder;
    visible_[i] = 1;
  }
}

void HzmCuller::cull(std::span<const ObjectBounds> objects, const ViewSnapshot& view,
                     WorkerPool* pool) {
  require_perspective_frustum(view);
  project(objects, view, pool);
  select_occluders(objects, view, pool);
  build_hzm(objects, view, pool);
  test(objects, pool);
}

CullStats HzmCuller::stats() const {
  CullStats s;
  for (const ObjectState st : states_) {
    s.in_frustum += st != ObjectState::Outside;
    s.occluded += st == ObjectState::Occluded;
    s.visible += st == ObjectState::Visible || st == ObjectState::Occluder;
  }
  s.occluders = aos_.size();
  for (const std::uint32_t i : cos_) s.candidates_in_frustum += rects_[i].in_frustum;
  return s;
}

}  // namespace treecut::culling
