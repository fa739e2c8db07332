// Hierarchical Z-map culling, per frame (sections 6.2, 6.3): projection and
// frustum culling, the occluder weights of Eq. 3 and the active occluder set,
// and the occluders' depth rasterized into the depth image.
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

// An occluder box's front surface over the screen, as linear functions of
// NDC. Along the ray o + t d (box frame, d affine in NDC, t the eye depth)
// a slab plane x_k = p is met at t = (p - o_k) / d_k, so u = 1 / t =
// d_k / (p - o_k) is linear in NDC. Entry t = the largest t of the near
// planes of the slabs the eye is outside of (u_in = the smallest of their
// u, all > 0 or the ray misses); exit t = the smallest positive t of the
// other planes (u_out = the largest of their u). Hit iff u_in > 0 and
// u_out <= u_in; depth 1 / u_in. Up to 3 entry and 6 exit functions, padded
// with functions that never decide, so that a row is one loop the compiler
// can vectorize.
struct OccluderRaster {
  // u = c0 + cx * nx + cy * ny.
  std::array<glm::vec3, 3> entry{};
  std::array<glm::vec3, 6> exit{};
  float near_depth = 0.0f;
  int x0 = 0, y0 = 0, x1 = -1, y1 = -1;  // cell range

  OccluderRaster(const Obb& box, const ViewSnapshot& v) {
    const glm::mat3 t = glm::transpose(box.axes);
    const glm::vec3 o = t * (v.derived.eye - box.center);
    const glm::vec3 qx = t * v.derived.ray_x, qy = t * v.derived.ray_y, q0 = t * v.derived.ray_0;
    std::size_t ne = 0, nx = 0;
    for (int k = 0; k < 3; ++k) {
      float h = box.half[k];
      // The eye exactly on a face plane would divide by 0: a slightly
      // smaller box is still inside the object.
      if (std::abs(std::abs(o[k]) - h) <= 1e-6f * h) h *= 1.0f - 1e-5f;
      const glm::vec3 d(q0[k], qx[k], qy[k]);
      if (std::abs(o[k]) > h) {
        const float sign = o[k] > 0.0f ? 1.0f : -1.0f;
        entry[ne++] = d / (sign * h - o[k]);
        exit[nx++] = d / (-sign * h - o[k]);
      } else {
        exit[nx++] = d / (h - o[k]);
        exit[nx++] = d / (-h - o[k]);
      }
    }
    for (; ne < 3; ++ne) entry[ne] = glm::vec3(3e38f, 0.0f, 0.0f);
    for (; nx < 6; ++nx) exit[nx] = glm::vec3(0.0f);
  }
  /// Depths (or +inf where the box is missed) at (nx[k], ny).
  void row(float ny, const std::vector<float>& nx, std::vector<float>& out) const {
    float e0[3], ex[3], x0v[6], xx[6];
    for (std::size_t i = 0; i < 3; ++i) {
      e0[i] = entry[i].x + entry[i].z * ny;
      ex[i] = entry[i].y;
    }
    for (std::size_t i = 0; i < 6; ++i) {
      x0v[i] = exit[i].x + exit[i].z * ny;
      xx[i] = exit[i].y;
    }
    const std::size_t n = nx.size();
    const float* in = nx.data();
    float* o = out.data();
    for (std::size_t k = 0; k < n; ++k) {
      const float x = in[k];
      const float u_in =
          std::min(std::min(e0[0] + ex[0] * x, e0[1] + ex[1] * x), e0[2] + ex[2] * x);
      const float u_out = std::max(std::max(std::max(x0v[0] + xx[0] * x, x0v[1] + xx[1] * x),
                                            std::max(x0v[2] + xx[2] * x, x0v[3] + xx[3] * x)),
                                   std::max(x0v[4] + xx[4] * x, x0v[5] + xx[5] * x));
      o[k] = u_in > 0.0f && u_out <= u_in ? 1.0f / u_in : kInf;
    }
  }
};

}  // namespace

namespace {

// Eq. 3 from an AABB: the one expression of occluder_weight() and the
// frame's loop over the candidates (the same operations, so the same bits).
float eq3_weight(const Box& bounds, glm::vec3 normal, const ViewSnapshot& view, Facing facing) {
  const glm::vec3 e = view.derived.eye;
  const glm::vec3 outside = glm::max(glm::max(bounds.lo - e, e - bounds.hi), glm::vec3(0.0f));
  const float distance = glm::length(outside);
  if (!(distance > 0.0f)) return 0.0f;
  const glm::vec3 size = bounds.hi - bounds.lo;
  const float volume = size.x * size.y * size.z;
  const glm::vec3 e_dir = facing == Facing::ViewDirection
                              ? view.derived.forward
                              : glm::normalize(0.5f * (bounds.lo + bounds.hi) - e);
  return volume * std::abs(glm::dot(normal, e_dir)) / distance;
}

}  // namespace

float occluder_weight(const ObjectBounds& object, glm::vec3 normal, const ScreenRect& rect,
                      const ViewSnapshot& view, Facing facing) {
  if (!rect.in_frustum || rect.crosses_near || !object.has_inner) return 0.0f;
  return eq3_weight(object.bounds, normal, view, facing);
}

void HzmCuller::project(std::span<const ObjectBounds> objects, const ViewSnapshot& view,
                        WorkerPool* pool) {
  rects_.resize(objects.size());
  states_.assign(objects.size(), ObjectState::Outside);
  // The copy from preprocess(), unless the objects changed in number.
  const bool copied = bounds_.size() == objects.size();
  for_chunks(pool, objects.size(), kObjectGrain, [&](std::size_t b, std::size_t e, std::size_t) {
    for (std::size_t i = b; i < e; ++i) {
      rects_[i] = project_box(view, copied ? bounds_[i] : objects[i].bounds);
    }
  });
}

void HzmCuller::select_occluders(std::span<const ObjectBounds> objects, const ViewSnapshot& view,
                                 WorkerPool* pool) {
  const std::size_t n = by_index_.size();
  const std::size_t k = params_.active;
  // The AABBs of preprocess(), unless the objects changed in number.
  const bool copied = bounds_.size() == objects.size();
  // Per chunk: the weights, then the chunk's best k; the best k of those
  // merged are the best k of all (a total order: weight, then object index;
  // so the set does not depend on the order the candidates are visited in).
  const auto better = [](const Pick& a, const Pick& b) {
    return a.weight != b.weight ? a.weight > b.weight : a.object < b.object;
  };
  picks_.resize(WorkerPool::chunk_count(n, kObjectGrain));
  for_chunks(pool, n, kObjectGrain, [&](std::size_t b, std::size_t e, std::size_t c) {
    std::vector<Pick>& mine = picks_[c];
    mine.clear();
    for (std::size_t j = b; j < e; ++j) {
      const Candidate& cand = by_index_[j];
      const ScreenRect& r = rects_[cand.object];
      if (!r.in_frustum || r.crosses_near) continue;
      const ObjectBounds* o = copied ? nullptr : &objects[cand.object];
      if (o != nullptr && !o->has_inner) continue;
      const float w =
          eq3_weight(o != nullptr ? o->bounds : cand.bounds, cand.normal, view, params_.facing);
      if (w > 0.0f) mine.push_back({w, cand.object});
    }
    if (mine.size() > k) {
      std::nth_element(mine.begin(), mine.begin() + static_cast<std::ptrdiff_t>(k), mine.end(),
                       better);
      mine.resize(k);
    }
  });
  std::vector<Pick> all;
  for (const auto& v : picks_) all.insert(all.end(), v.begin(), v.end());
  std::sort(all.begin(), all.end(), better);
  if (all.size() > k) all.resize(k);
  aos_.clear();
  for (const Pick& p : all) aos_.push_back(p.object);
}

void HzmCuller::build_hzm(std::span<const ObjectBounds> objects, const ViewSnapshot& view,
                          WorkerPool* pool) {
  const glm::ivec2 vp = view.viewport;
  const int larger = std::max(vp.x, vp.y);
  const int width = static_cast<int>(std::max(1u, params_.depth_width));
  cell_ = std::max(1, (larger + width - 1) / width);
  depth_dims_ = {(vp.x + cell_ - 1) / cell_, (vp.y + cell_ - 1) / cell_};
  depth_.assign(static_cast<std::size_t>(depth_dims_.x) * static_cast<std::size_t>(depth_dims_.y),
                kInf);

  // Occluders front to back (by their nearest depth): a cell an earlier one
  // covered nearer than a later one's nearest point needs no test of it.
  std::vector<OccluderRaster> occ;
  occ.reserve(aos_.size());
  const float s = static_cast<float>(cell_);
  for (const std::uint32_t i : aos_) {
    const ObjectBounds& o = objects[i];
    const ScreenRect r = project_box(view, bounds_of(o.inner));
    if (!r.in_frustum || r.crosses_near) continue;
    OccluderRaster raster(o.inner, view);
    raster.near_depth = r.depth;
    raster.x0 = static_cast<int>(r.x0 / s);
    raster.y0 = static_cast<int>(r.y0 / s);
    raster.x1 = std::min(depth_dims_.x - 1, static_cast<int>(r.x1 / s));
    raster.y1 = std::min(depth_dims_.y - 1, static_cast<int>(r.y1 / s));
    occ.push_back(raster);
  }
  std::stable_sort(occ.begin(), occ.end(), [](const OccluderRaster& a, const OccluderRaster& b) {
    return a.near_depth < b.near_depth;
  });
  const float vw = static_cast<float>(vp.x), vh = static_cast<float>(vp.y);
  const float to_ndc_x = 2.0f / vw, to_ndc_y = 2.0f / vh;
  const std::size_t row_stride = static_cast<std::size_t>(depth_dims_.x);
  // The sample points: with one pixel a cell, its center (exact); with
  // larger cells, the cell corners (the corner x = i * s, kept within the
  // extreme pixel centers of the viewport), shared by neighbouring cells:
  // the square they span holds every pixel center of the cell.
  const bool exact = cell_ == 1;
  const auto sample_x = [&](int i) {
    return exact ? static_cast<float>(i) + 0.5f
                 : std::clamp(static_cast<float>(i) * s, 0.5f, vw - 0.5f);
  };
  const auto sample_y = [&](int j) {
    return exact ? static_cast<float>(j) + 0.5f
                 : std::clamp(static_cast<float>(j) * s, 0.5f, vh - 0.5f);
  };
  // Rows of cells in chunks: each chunk writes only its own rows.
  for_chunks(pool, static_cast<std::size_t>(depth_dims_.y), 4,
             [&](std::size_t b, std::size_t e, std::size_t) {
               std::vector<float> below, above, nx;
               for (const OccluderRaster& oc : occ) {
                 const int y_begin = std::max(oc.y0, static_cast<int>(b));
                 const int y_end = std::min(oc.y1 + 1, static_cast<int>(e));
                 if (y_begin >= y_end) continue;
                 const int samples = oc.x1 - oc.x0 + (exact ? 1 : 2);
                 nx.resize(static_cast<std::size_t>(samples));
                 below.resize(nx.size());
                 above.resize(nx.size());
                 for (int k = 0; k < samples; ++k) {
                   nx[static_cast<std::size_t>(k)] = sample_x(oc.x0 + k) * to_ndc_x - 1.0f;
                 }
                 if (!exact) oc.row(sample_y(y_begin) * to_ndc_y - 1.0f, nx, below);
                 for (int y = y_begin; y < y_end; ++y) {
                   oc.row(sample_y(exact ? y : y + 1) * to_ndc_y - 1.0f, nx, above);
                   float* row = depth_.data() + static_cast<std::size_t>(y) * row_stride;
                   if (exact) {
                     for (int x = oc.x0; x <= oc.x1; ++x) {
                       row[x] = std::min(row[x], above[static_cast<std::size_t>(x - oc.x0)]);
                     }
                   } else {
                     for (int x = oc.x0; x <= oc.x1; ++x) {
                       const std::size_t k = static_cast<std::size_t>(x - oc.x0);
                       const float d = std::max(std::max(below[k], below[k + 1]),
                                                std::max(above[k], above[k + 1]));
                       row[x] = std::min(row[x], d);
                     }
                     std::swap(below, above);
                   }
                 }
               }
             });
  hzm_.build(depth_, depth_dims_.x, depth_dims_.y, pool);
}

}  // namespace treecut::culling
