// Occlusion culling with a hierarchical Z-map: Peng & Cao, "Integrating
// Occlusion Culling and Parallel LOD for Rendering Complex 3D Environments on
// GPU", I3D 2013 (../shared/papers/occlusion-culling-with-parallel-lod.txt),
// section 6 (Eq. 2 compactness, Eq. 3 occluder weights, the HZM by
// max-reduction, Eq. 5 levels). Why each step is conservative: hzm.hpp.
#include "treecut/strategies/hzm.hpp"

#include <algorithm>
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
    const int c = static_cast<int>(
        std::floor((x + h[axis]) / (2.0f * h[axis]) * static_cast<float>(n[axis])));
    return std::clamp(c, 0, n[axis] - 1);
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
  float m = -kInf;
  for (int y = y0 >> l; y <= (y1 >> l); ++y) {
    for (int x = x0 >> l; x <= (x1 >> l); ++x) m = std::max(m, at(l, x, y));
  }
  return m;
}

float occluder_weight(const SceneObject& object, glm::vec3 normal, const ScreenRect& rect,
                      const FrameView& view) {
  if (!rect.in_frustum || rect.crosses_near || !object.has_inner) return 0.0f;
  const glm::vec3 e = view.eye();
  const glm::vec3 outside =
      glm::max(glm::max(object.bounds.min - e, e - object.bounds.max), glm::vec3(0.0f));
  const float distance = glm::length(outside);
  if (!(distance > 0.0f)) return 0.0f;
  const glm::vec3 size = object.bounds.max - object.bounds.min;
  const float volume = size.x * size.y * size.z;
  return volume * std::abs(glm::dot(normal, view.forward())) / distance;
}

void HzmCuller::preprocess(std::span<const SceneObject> objects) {
  cos_.clear();
  for (std::uint32_t i = 0; i < objects.size(); ++i) {
    if (objects[i].has_inner && objects[i].compactness >= params_.compactness_threshold) {
      cos_.push_back(i);
    }
  }
  std::stable_sort(cos_.begin(), cos_.end(), [&](std::uint32_t a, std::uint32_t b) {
    return objects[a].compactness > objects[b].compactness;
  });
  normal_.resize(cos_.size());
  for (std::size_t j = 0; j < cos_.size(); ++j) {
    // The largest face is across the axis of the smallest extent.
    const Obb& b = objects[cos_[j]].box;
    int k = 0;
    for (int a = 1; a < 3; ++a)
      if (b.half[a] < b.half[k]) k = a;
    normal_[j] = b.axes[k];
  }
}

void HzmCuller::project(std::span<const SceneObject> objects, const FrameView& view,
                        WorkerPool* pool) {
  rects_.resize(objects.size());
  states_.assign(objects.size(), ObjectState::Outside);
  for_chunks(pool, objects.size(), kObjectGrain, [&](std::size_t b, std::size_t e, std::size_t) {
    for (std::size_t i = b; i < e; ++i) rects_[i] = view.project(objects[i].bounds);
  });
}

void HzmCuller::select_occluders(std::span<const SceneObject> objects, const FrameView& view,
                                 WorkerPool* pool) {
  const std::size_t n = cos_.size();
  const std::size_t k = params_.active;
  weight_.resize(n);
  // Per chunk: the weights, then the chunk's best k; the best k of those
  // merged are the best k of all (ties by object index: deterministic).
  struct Pick {
    float weight;
    std::uint32_t object;
  };
  const auto better = [](const Pick& a, const Pick& b) {
    return a.weight != b.weight ? a.weight > b.weight : a.object < b.object;
  };
  std::vector<std::vector<Pick>> best(WorkerPool::chunk_count(n, kObjectGrain));
  for_chunks(pool, n, kObjectGrain, [&](std::size_t b, std::size_t e, std::size_t c) {
    std::vector<Pick>& mine = best[c];
    for (std::size_t j = b; j < e; ++j) {
      const std::uint32_t i = cos_[j];
      weight_[j] = occluder_weight(objects[i], normal_[j], rects_[i], view);
      if (weight_[j] > 0.0f) mine.push_back({weight_[j], i});
    }
    if (mine.size() > k) {
      std::nth_element(mine.begin(), mine.begin() + static_cast<std::ptrdiff_t>(k), mine.end(),
                       better);
      mine.resize(k);
    }
  });
  std::vector<Pick> all;
  for (const auto& v : best) all.insert(all.end(), v.begin(), v.end());
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

  struct Occluder {
    BoxRays rays;
    int x0, y0, x1, y1;  // cell range
  };
  std::vector<Occluder> occ;
  occ.reserve(aos_.size());
  const float s = static_cast<float>(cell_);
  for (const std::uint32_t i : aos_) {
    const SceneObject& o = objects[i];
    const ScreenRect r = view.project(bounds_of(o.inner));
    if (!r.in_frustum || r.crosses_near) continue;
    occ.push_back({BoxRays(o.inner, view), static_cast<int>(r.x0 / s), static_cast<int>(r.y0 / s),
                   std::min(depth_dims_.x - 1, static_cast<int>(r.x1 / s)),
                   std::min(depth_dims_.y - 1, static_cast<int>(r.y1 / s))});
  }
  const float vw = static_cast<float>(vp.x), vh = static_cast<float>(vp.y);
  const float to_ndc_x = 2.0f / vw, to_ndc_y = 2.0f / vh;
  // Rows of cells in chunks: each chunk writes only its own rows.
  for_chunks(pool, static_cast<std::size_t>(depth_dims_.y), 4,
             [&](std::size_t b, std::size_t e, std::size_t) {
               for (const Occluder& oc : occ) {
                 const int y_begin = std::max(oc.y0, static_cast<int>(b));
                 const int y_end = std::min(oc.y1 + 1, static_cast<int>(e));
                 for (int y = y_begin; y < y_end; ++y) {
                   // The cell's extreme pixel centers.
                   const float ya = static_cast<float>(y) * s + 0.5f;
                   const float yb = std::min(static_cast<float>(y + 1) * s, vh) - 0.5f;
                   const float na = ya * to_ndc_y - 1.0f, nb = yb * to_ndc_y - 1.0f;
                   float* row = depth_.data() + static_cast<std::size_t>(y) *
                                                    static_cast<std::size_t>(depth_dims_.x);
                   for (int x = oc.x0; x <= oc.x1; ++x) {
                     const float xa = static_cast<float>(x) * s + 0.5f;
                     const float xb = std::min(static_cast<float>(x + 1) * s, vw) - 0.5f;
                     const float ma = xa * to_ndc_x - 1.0f, mb = xb * to_ndc_x - 1.0f;
                     const RayHit h0 = oc.rays.at(ma, na);
                     if (!h0.hit()) continue;
                     const RayHit h1 = oc.rays.at(mb, na);
                     if (!h1.hit()) continue;
                     const RayHit h2 = oc.rays.at(ma, nb);
                     if (!h2.hit()) continue;
                     const RayHit h3 = oc.rays.at(mb, nb);
                     if (!h3.hit()) continue;
                     const float d =
                         std::max(std::max(h0.t_in, h1.t_in), std::max(h2.t_in, h3.t_in));
                     row[x] = std::min(row[x], d);
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
          const float m = hzm_.max_over(x0, y0, x1, y1);
          if (r.depth > m * (1.0f + kDepthMargin)) st = ObjectState::Occluded;
        }
      }
      states_[i] = st;
    }
  });
  // The AOS is visible by definition (and wrote the map itself).
  for (const std::uint32_t i : aos_) states_[i] = ObjectState::Occluder;
  for (std::size_t i = 0; i < objects.size(); ++i) {
    visible_[i] = states_[i] == ObjectState::Visible || states_[i] == ObjectState::Occluder;
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
