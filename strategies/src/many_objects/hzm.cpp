// Occlusion culling with a hierarchical Z-map: Peng & Cao, "Integrating
// Occlusion Culling and Parallel LOD for Rendering Complex 3D Environments on
// GPU", I3D 2013 (../shared/papers/occlusion-culling-with-parallel-lod.txt),
// section 6 (Eq. 2 compactness, Eq. 3 occluder weights, the HZM by
// max-reduction, Eq. 5 levels). Why each step is conservative: hzm.hpp.
#include "treecut/strategies/hzm.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <glm/geometric.hpp>
#include <glm/matrix.hpp>
#include <limits>

namespace treecut::strategies::many {
namespace {

constexpr float kInf = std::numeric_limits<float>::infinity();
constexpr std::size_t kObjectGrain = 4096;

template <class Body>
void for_chunks(WorkerPool* pool, std::size_t n, std::size_t grain, Body&& body) {
  if (pool != nullptr) {
    pool->run(n, grain, body);
  } else {
    const std::size_t chunks = WorkerPool::chunk_count(n, grain);
    for (std::size_t c = 0; c < chunks; ++c) body(c * grain, std::min(n, (c + 1) * grain), c);
  }
}

// Rays of a frame in one box's frame: the direction is affine in NDC.
struct BoxRays {
  glm::vec3 o, qx, qy, q0, half;
  BoxRays(const Obb& b, const FrameView& v) {
    const glm::mat3 t = glm::transpose(b.axes);
    o = t * (v.eye() - b.center);
    qx = t * v.ray_x();
    qy = t * v.ray_y();
    q0 = t * v.ray_0();
    half = b.half;
  }
  [[nodiscard]] RayHit at(float nx, float ny) const {
    return ray_box_local(o, q0 + qy * ny + qx * nx, half);
  }
};

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

  OccluderRaster(const Obb& box, const FrameView& v) {
    const glm::mat3 t = glm::transpose(box.axes);
    const glm::vec3 o = t * (v.eye() - box.center);
    const glm::vec3 qx = t * v.ray_x(), qy = t * v.ray_y(), q0 = t * v.ray_0();
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

// Jacobi eigenvectors of a symmetric 3x3 matrix (columns of the result).
glm::mat3 eigenvectors(glm::dmat3 a) {
  glm::dmat3 v(1.0);
  for (int sweep = 0; sweep < 50; ++sweep) {
    const double off = a[0][1] * a[0][1] + a[0][2] * a[0][2] + a[1][2] * a[1][2];
    if (off < 1e-30) break;
    for (int p = 0; p < 2; ++p) {
      for (int q = p + 1; q < 3; ++q) {
        if (std::abs(a[p][q]) < 1e-300) continue;
        const double theta = (a[q][q] - a[p][p]) / (2.0 * a[p][q]);
        const double t =
            (theta >= 0 ? 1.0 : -1.0) / (std::abs(theta) + std::sqrt(theta * theta + 1));
        const double c = 1.0 / std::sqrt(t * t + 1), s = t * c;
        glm::dmat3 r(1.0);
        r[p][p] = c;
        r[q][q] = c;
        r[q][p] = s;  // column q, row p
        r[p][q] = -s;
        a = glm::transpose(r) * a * r;
        v = v * r;
      }
    }
  }
  return glm::mat3(v);
}

}  // namespace

float compactness(std::span<const glm::vec3> points, const Obb& box) {
  if (points.empty()) return 0.0f;
  const glm::mat3 to_local = glm::transpose(box.axes);
  const glm::vec3 h = box.half;
  double area[3];
  double total = 0.0;
  for (int k = 0; k < 3; ++k) {
    area[k] = 4.0 * double{h[(k + 1) % 3]} * double{h[(k + 2) % 3]};
    total += area[k];
  }
  if (!(total > 0.0)) return 0.0f;
  // One cell side for the three faces: about points / 8 cells in all.
  const double target = std::max(3.0, static_cast<double>(points.size()) / 8.0);
  const double side = std::sqrt(total / target);
  int n[3];
  for (int k = 0; k < 3; ++k) {
    n[k] =
        h[k] > 0.0f ? static_cast<int>(std::clamp(std::ceil(2.0 * h[k] / side), 1.0, 4096.0)) : 1;
  }
  std::vector<std::uint8_t> face[3];
  for (int k = 0; k < 3; ++k) {
    face[k].assign(
        static_cast<std::size_t>(n[(k + 1) % 3]) * static_cast<std::size_t>(n[(k + 2) % 3]), 0);
  }
  const auto cell = [&](float x, int axis) {
    if (!(h[axis] > 0.0f)) return 0;
    // Clamped as a float: a point outside the box must not overflow the cast.
    const float f = std::floor((x + h[axis]) / (2.0f * h[axis]) * static_cast<float>(n[axis]));
    return static_cast<int>(std::clamp(f, 0.0f, static_cast<float>(n[axis] - 1)));
  };
  for (const glm::vec3& p : points) {
    const glm::vec3 l = to_local * (p - box.center);
    const int c[3] = {cell(l.x, 0), cell(l.y, 1), cell(l.z, 2)};
    for (int k = 0; k < 3; ++k) {
      const int a = (k + 1) % 3, b = (k + 2) % 3;
      face[k][static_cast<std::size_t>(c[b]) * static_cast<std::size_t>(n[a]) +
              static_cast<std::size_t>(c[a])] = 1;
    }
  }
  double sum = 0.0;
  for (int k = 0; k < 3; ++k) {
    if (area[k] == 0.0) continue;
    std::size_t occupied = 0;
    for (const std::uint8_t x : face[k]) occupied += x;
    sum += area[k] * static_cast<double>(occupied) / static_cast<double>(face[k].size());
  }
  return static_cast<float>(sum / total);
}

Obb fit_obb(std::span<const glm::vec3> points) {
  Obb box;
  if (points.empty()) return box;
  glm::dvec3 mean(0.0);
  for (const glm::vec3& p : points) mean += glm::dvec3(p);
  mean /= static_cast<double>(points.size());
  glm::dmat3 cov(0.0);
  for (const glm::vec3& p : points) {
    const glm::dvec3 d = glm::dvec3(p) - mean;
    cov += glm::outerProduct(d, d);
  }
  glm::mat3 axes = eigenvectors(cov);
  for (int k = 0; k < 3; ++k) axes[k] = glm::normalize(axes[k]);
  axes[2] = glm::normalize(glm::cross(axes[0], axes[1]));  // right-handed, orthogonal
  axes[1] = glm::cross(axes[2], axes[0]);
  const glm::mat3 to_local = glm::transpose(axes);
  glm::vec3 lo(kInf), hi(-kInf);
  for (const glm::vec3& p : points) {
    const glm::vec3 l = to_local * p;
    lo = glm::min(lo, l);
    hi = glm::max(hi, l);
  }
  box.axes = axes;
  box.half = 0.5f * (hi - lo);
  box.center = axes * (0.5f * (hi + lo));
  return box;
}

std::optional<Obb> inner_box(std::span<const glm::vec3> points, const Obb& box, int cells) {
  const int n = std::max(cells, 3);
  const auto at = [n](int x, int y, int z) {
    return (static_cast<std::size_t>(z) * static_cast<std::size_t>(n) +
            static_cast<std::size_t>(y)) *
               static_cast<std::size_t>(n) +
           static_cast<std::size_t>(x);
  };
  if (!(box.half.x > 0.0f && box.half.y > 0.0f && box.half.z > 0.0f)) return std::nullopt;
  enum : std::uint8_t { kEmpty, kSurface, kOutside };
  std::vector<std::uint8_t> grid(
      static_cast<std::size_t>(n) * static_cast<std::size_t>(n) * static_cast<std::size_t>(n),
      kEmpty);
  const glm::mat3 to_local = glm::transpose(box.axes);
  const glm::vec3 scale = static_cast<float>(n) / (2.0f * box.half);
  for (const glm::vec3& p : points) {
    const glm::vec3 l = (to_local * (p - box.center) + box.half) * scale;
    // Clamped as floats: a point outside the box must not overflow the cast.
    const glm::ivec3 c(
        glm::clamp(glm::floor(l), glm::vec3(0.0f), glm::vec3(static_cast<float>(n - 1))));
    grid[at(c.x, c.y, c.z)] = kSurface;
  }
  // Flood the outside from every empty border cell (6-connected).
  std::vector<glm::ivec3> stack;
  const auto push = [&](int x, int y, int z) {
    if (x < 0 || y < 0 || z < 0 || x >= n || y >= n || z >= n) return;
    std::uint8_t& g = grid[at(x, y, z)];
    if (g != kEmpty) return;
    g = kOutside;
    stack.push_back({x, y, z});
  };
  for (int a = 0; a < n; ++a) {
    for (int b = 0; b < n; ++b) {
      push(0, a, b), push(n - 1, a, b), push(a, 0, b), push(a, n - 1, b), push(a, b, 0),
          push(a, b, n - 1);
    }
  }
  while (!stack.empty()) {
    const glm::ivec3 c = stack.back();
    stack.pop_back();
    push(c.x - 1, c.y, c.z), push(c.x + 1, c.y, c.z), push(c.x, c.y - 1, c.z),
        push(c.x, c.y + 1, c.z), push(c.x, c.y, c.z - 1), push(c.x, c.y, c.z + 1);
  }
  // Inside = still empty. Seed: the inside cell nearest the center.
  glm::ivec3 seed(-1);
  float best = 3e38f;
  for (int z = 0; z < n; ++z)
    for (int y = 0; y < n; ++y)
      for (int x = 0; x < n; ++x) {
        if (grid[at(x, y, z)] != kEmpty) continue;
        const glm::vec3 d = glm::vec3(x, y, z) + 0.5f - 0.5f * static_cast<float>(n);
        if (glm::dot(d, d) < best) {
          best = glm::dot(d, d);
          seed = {x, y, z};
        }
      }
  if (seed.x < 0) return std::nullopt;
  glm::ivec3 lo = seed, hi = seed;  // inclusive cell range
  const auto layer_inside = [&](int axis, int at_index) {
    glm::ivec3 a = lo, b = hi;
    a[axis] = b[axis] = at_index;
    if (at_index < 0 || at_index >= n) return false;
    for (int z = a.z; z <= b.z; ++z)
      for (int y = a.y; y <= b.y; ++y)
        for (int x = a.x; x <= b.x; ++x)
          if (grid[at(x, y, z)] != kEmpty) return false;
    return true;
  };
  for (bool grew = true; grew;) {
    grew = false;
    for (int axis = 0; axis < 3; ++axis) {
      if (layer_inside(axis, lo[axis] - 1)) --lo[axis], grew = true;
      if (layer_inside(axis, hi[axis] + 1)) ++hi[axis], grew = true;
    }
  }
  Obb r;
  r.axes = box.axes;
  const glm::vec3 cell = 2.0f * box.half / static_cast<float>(n);
  const glm::vec3 l0 = glm::vec3(lo) * cell - box.half;
  const glm::vec3 l1 = glm::vec3(hi + 1) * cell - box.half;
  r.half = 0.5f * (l1 - l0);
  r.center = box.center + box.axes * (0.5f * (l0 + l1));
  return r;
}

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

namespace {

// Eq. 3 from an AABB: the one expression of occluder_weight() and the
// frame's loop over the candidates (the same operations, so the same bits).
float eq3_weight(const Aabb& bounds, glm::vec3 normal, const FrameView& view, Facing facing) {
  const glm::vec3 e = view.eye();
  const glm::vec3 outside = glm::max(glm::max(bounds.min - e, e - bounds.max), glm::vec3(0.0f));
  const float distance = glm::length(outside);
  if (!(distance > 0.0f)) return 0.0f;
  const glm::vec3 size = bounds.max - bounds.min;
  const float volume = size.x * size.y * size.z;
  const glm::vec3 e_dir = facing == Facing::ViewDirection
                              ? view.forward()
                              : glm::normalize(0.5f * (bounds.min + bounds.max) - e);
  return volume * std::abs(glm::dot(normal, e_dir)) / distance;
}

}  // namespace

float occluder_weight(const SceneObject& object, glm::vec3 normal, const ScreenRect& rect,
                      const FrameView& view, Facing facing) {
  if (!rect.in_frustum || rect.crosses_near || !object.has_inner) return 0.0f;
  return eq3_weight(object.bounds, normal, view, facing);
}

void HzmCuller::preprocess(std::span<const SceneObject> objects) {
  // The AABBs apart: the projection of every object every frame then reads
  // 24 bytes an object instead of a whole SceneObject's cache lines.
  bounds_.resize(objects.size());
  for (std::size_t i = 0; i < objects.size(); ++i) bounds_[i] = objects[i].bounds;
  cos_.clear();
  by_index_.clear();
  for (std::uint32_t i = 0; i < objects.size(); ++i) {
    if (objects[i].has_inner && objects[i].compactness >= params_.compactness_threshold) {
      cos_.push_back(i);
      // The largest face is across the axis of the smallest extent.
      const Obb& b = objects[i].box;
      int k = 0;
      for (int a = 1; a < 3; ++a)
        if (b.half[a] < b.half[k]) k = a;
      by_index_.push_back({objects[i].bounds, b.axes[k], i});
    }
  }
  std::stable_sort(cos_.begin(), cos_.end(), [&](std::uint32_t a, std::uint32_t b) {
    return objects[a].compactness > objects[b].compactness;
  });
}

void HzmCuller::project(std::span<const SceneObject> objects, const FrameView& view,
                        WorkerPool* pool) {
  rects_.resize(objects.size());
  states_.assign(objects.size(), ObjectState::Outside);
  // The copy from preprocess(), unless the objects changed in number.
  const bool copied = bounds_.size() == objects.size();
  for_chunks(pool, objects.size(), kObjectGrain, [&](std::size_t b, std::size_t e, std::size_t) {
    for (std::size_t i = b; i < e; ++i) {
      rects_[i] = view.project(copied ? bounds_[i] : objects[i].bounds);
    }
  });
}

void HzmCuller::select_occluders(std::span<const SceneObject> objects, const FrameView& view,
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
      const SceneObject* o = copied ? nullptr : &objects[cand.object];
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

void HzmCuller::build_hzm(std::span<const SceneObject> objects, const FrameView& view,
                          WorkerPool* pool) {
  const glm::ivec2 vp = view.viewport();
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
    const SceneObject& o = objects[i];
    const ScreenRect r = view.project(bounds_of(o.inner));
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

void HzmCuller::test(std::span<const SceneObject> objects, WorkerPool* pool) {
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
  // The AOS is visible by definition (and wrote the map itself).
  for (const std::uint32_t i : aos_) {
    states_[i] = ObjectState::Occluder;
    visible_[i] = 1;
  }
}

void HzmCuller::cull(std::span<const SceneObject> objects, const FrameView& view,
                     WorkerPool* pool) {
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

void reference_visibility(std::span<const SceneObject> objects, const FrameView& view,
                          std::vector<std::uint8_t>& visible, WorkerPool* pool,
                          std::vector<std::uint32_t>* ids) {
  const glm::ivec2 vp = view.viewport();
  const std::size_t width = static_cast<std::size_t>(vp.x);
  std::vector<std::uint32_t> local_ids;
  std::vector<std::uint32_t>& id = ids != nullptr ? *ids : local_ids;
  id.assign(width * static_cast<std::size_t>(vp.y), ~0u);
  std::vector<ScreenRect> rects(objects.size());
  for_chunks(pool, objects.size(), kObjectGrain, [&](std::size_t b, std::size_t e, std::size_t) {
    for (std::size_t i = b; i < e; ++i) rects[i] = view.project(objects[i].bounds);
  });
  const float near_plane = view.near_plane(), far_plane = view.far_plane();
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

}  // namespace treecut::strategies::many
