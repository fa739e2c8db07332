// Hierarchical Z-map culling, preprocess (section 6.1): Eq. 2 compactness,
// the fitted box, the inner box an occluder may write, the candidate
// occluder set (COS).
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

std::optional<Obb> inner_box(std::span<const glm::vec3> points, const Obb& box, int cells,
                             int closed_face) {
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
  // Flood the outside from every empty border cell (6-connected), but for
  // the closed face's: the plane beyond them is a wall.
  std::vector<glm::ivec3> stack;
  const auto push = [&](int x, int y, int z) {
    if (x < 0 || y < 0 || z < 0 || x >= n || y >= n || z >= n) return;
    std::uint8_t& g = grid[at(x, y, z)];
    if (g != kEmpty) return;
    g = kOutside;
    stack.push_back({x, y, z});
  };
  const auto seed_border = [&](int face, int x, int y, int z) {
    if (face != closed_face) push(x, y, z);
  };
  for (int a = 0; a < n; ++a) {
    for (int b = 0; b < n; ++b) {
      seed_border(0, 0, a, b), seed_border(1, n - 1, a, b), seed_border(2, a, 0, b),
          seed_border(3, a, n - 1, b), seed_border(4, a, b, 0), seed_border(5, a, b, n - 1);
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

void HzmCuller::preprocess(std::span<const ObjectBounds> objects) {
  // The AABBs apart: the projection of every object every frame then reads
  // 24 bytes an object instead of a whole ObjectBounds's cache lines.
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

}  // namespace treecut::culling
