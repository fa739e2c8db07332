// Per-point attributes: normals, splat radii, curvature.
//
// With faces (a mesh): area-weighted face normals, a splat radius that covers
// every incident triangle, and curvature from the covariance of the 1-ring.
// Without faces (a point cloud): PCA over the k nearest neighbours (Hoppe et
// al. 1992) oriented away from the centroid, a radius from the local density
// and the surface variation of Pauly et al. 2002.
#include "treecut/attributes.hpp"

#include <algorithm>
#include <cmath>
#include <glm/geometric.hpp>
#include <vector>

#include "knn_grid.hpp"
#include "symmetric3.hpp"
#include "treecut/parallel.hpp"

namespace treecut {

namespace {

using detail::Sym3;

// Radius that makes the discs of a triangle's corners cover the triangle: the
// circumradius, or half the longest edge when the triangle is obtuse (its
// circumcenter lies outside, and the edge midpoint is the farthest point).
float covering_radius(glm::vec3 a, glm::vec3 b, glm::vec3 c) {
  const float ab = glm::distance(a, b), bc = glm::distance(b, c), ca = glm::distance(c, a);
  const float longest = std::max({ab, bc, ca});
  const float area2 = glm::length(glm::cross(b - a, c - a));  // twice the area
  const float sq = ab * ab + bc * bc + ca * ca;
  const float l2 = longest * longest;
  if (area2 <= 0.0f || 2.0f * l2 >= sq) return 0.5f * longest;  // obtuse or degenerate
  return std::min(ab * bc * ca / (2.0f * area2), longest);
}

float median_positive(const std::vector<float>& v) {
  std::vector<float> pos;
  pos.reserve(v.size());
  for (float x : v)
    if (x > 0.0f && std::isfinite(x)) pos.push_back(x);
  if (pos.empty()) return 0.0f;
  auto mid = pos.begin() + static_cast<std::ptrdiff_t>(pos.size() / 2);
  std::nth_element(pos.begin(), mid, pos.end());
  return *mid;
}

void normalize_normals(std::vector<glm::vec3>& normals) {
  for (auto& n : normals) {
    const float len = glm::length(n);
    n = len > 1e-20f && std::isfinite(len) ? n / len : glm::vec3(0.0f);
  }
}

// Covariance of a neighbourhood given by offsets d from the point itself:
// E[dd^T] - E[d]E[d]^T (the point counts as one offset of zero).
struct Moments {
  Sym3 outer;
  glm::vec3 sum{0.0f};
  std::uint32_t count = 1;
  void add(glm::vec3 d) {
    outer.add(d);
    sum += d;
    ++count;
  }
  [[nodiscard]] Sym3 covariance() const {
    const float inv = 1.0f / static_cast<float>(count);
    const glm::vec3 m = sum * inv;
    Sym3 c = outer;
    c.xx = c.xx * inv - m.x * m.x, c.xy = c.xy * inv - m.x * m.y, c.xz = c.xz * inv - m.x * m.z;
    c.yy = c.yy * inv - m.y * m.y, c.yz = c.yz * inv - m.y * m.z, c.zz = c.zz * inv - m.z * m.z;
    return c;
  }
};

void fill_missing_radii(std::vector<float>& radii) {
  const float fallback = median_positive(radii);
  for (float& r : radii)
    if (!(r > 0.0f) || !std::isfinite(r)) r = fallback > 0.0f ? fallback : 1.0f;
}

// Vertex -> incident faces, as compressed rows (faces ascending per vertex).
struct Incidence {
  std::vector<std::uint32_t> begin;  // size n + 1
  std::vector<std::uint32_t> faces;
};

Incidence incidence(std::size_t n, const std::vector<glm::uvec3>& triangles) {
  Incidence inc;
  inc.begin.assign(n + 1, 0);
  for (const glm::uvec3& t : triangles) ++inc.begin[t.x + 1], ++inc.begin[t.y + 1], ++inc.begin[t.z + 1];
  for (std::size_t i = 0; i < n; ++i) inc.begin[i + 1] += inc.begin[i];
  inc.faces.resize(inc.begin[n]);
  std::vector<std::uint32_t> fill(inc.begin.begin(), inc.begin.end() - 1);
  for (std::size_t f = 0; f < triangles.size(); ++f) {
    const glm::uvec3 t = triangles[f];
    inc.faces[fill[t.x]++] = static_cast<std::uint32_t>(f);
    inc.faces[fill[t.y]++] = static_cast<std::uint32_t>(f);
    inc.faces[fill[t.z]++] = static_cast<std::uint32_t>(f);
  }
  return inc;
}

// Per-face quantities first (parallel over faces), then each vertex gathers
// from its own faces: no write conflicts, and the summation order (ascending
// face index) does not depend on the thread count.
void from_faces(PointSet& ps, bool want_normals, bool want_radii, bool want_curvature) {
  const std::size_t n = ps.size(), nf = ps.triangles.size();
  const Incidence inc = incidence(n, ps.triangles);
  std::vector<glm::vec4> face(nf);  // xyz: normal * 2 * area, w: covering radius
  parallel_for(nf, [&](std::size_t b, std::size_t e) {
    for (std::size_t f = b; f < e; ++f) {
      const glm::uvec3 t = ps.triangles[f];
      const glm::vec3 a = ps.positions[t.x], bb = ps.positions[t.y], c = ps.positions[t.z];
      face[f] = glm::vec4(glm::cross(bb - a, c - a), want_radii ? covering_radius(a, bb, c) : 0.0f);
    }
  });
  if (want_normals) ps.normals.assign(n, glm::vec3(0.0f));
  if (want_radii) ps.radii.assign(n, 0.0f);
  if (want_curvature) ps.curvature.assign(n, 0.0f);
  parallel_for(n, [&](std::size_t b, std::size_t e) {
    for (std::size_t v = b; v < e; ++v) {
      glm::vec4 sum(0.0f);
      Moments ring;
      const glm::vec3 p = ps.positions[v];
      for (std::uint32_t j = inc.begin[v]; j < inc.begin[v + 1]; ++j) {
        const glm::vec4 fq = face[inc.faces[j]];
        sum = glm::vec4(glm::vec3(sum) + glm::vec3(fq), std::max(sum.w, fq.w));
        if (want_curvature) {  // the two other corners, relative to the vertex itself
          const glm::uvec3 t = ps.triangles[inc.faces[j]];
          for (std::uint32_t q : {t.x, t.y, t.z})
            if (q != v) ring.add(ps.positions[q] - p);
        }
      }
      if (want_normals) {
        const float len = glm::length(glm::vec3(sum));
        ps.normals[v] = len > 1e-30f && std::isfinite(len) ? glm::vec3(sum) / len : glm::vec3(0.0f);
      }
      if (want_radii) ps.radii[v] = sum.w;
      if (want_curvature && ring.count >= 3)
        ps.curvature[v] = detail::surface_variation(ring.covariance());
    }
  }, 0, 1024);
  if (want_radii) fill_missing_radii(ps.radii);  // vertices outside every face: the typical radius
}

void from_neighbours(PointSet& ps, int k, bool want_normals, bool want_radii, bool want_curvature) {
  const std::size_t n = ps.size();
  const detail::KnnGrid grid(ps.positions);
  if (want_normals) ps.normals.assign(n, glm::vec3(0.0f));
  if (want_radii) ps.radii.assign(n, 0.0f);
  if (want_curvature) ps.curvature.assign(n, 0.0f);
  glm::dvec3 centroid(0.0);
  for (const auto& p : ps.positions) centroid += glm::dvec3(p);
  const glm::vec3 c = glm::vec3(centroid / static_cast<double>(std::max<std::size_t>(n, 1)));
  grid.for_each_knn(k, [&](std::uint32_t i, int found, const std::uint32_t* idx, const float* d2) {
    const glm::vec3 p = ps.positions[i];
    if (want_radii && found > 0) {
      // Discs of radius r at local density rho = found / (pi d_k^2) leave a
      // fraction exp(-rho pi r^2) of a randomly sampled surface uncovered:
      // r = d_k sqrt(7 / found) -> 0.1%, no visible pinholes.
      ps.radii[i] = std::sqrt(d2[found - 1] * 7.0f / static_cast<float>(found));
    }
    if ((!want_normals && !want_curvature) || found < 2) return;
    Moments m;
    for (int j = 0; j < found; ++j) m.add(ps.positions[idx[j]] - p);
    if (!want_normals) {  // the eigenvalue alone is much cheaper than the full solve
      ps.curvature[i] = detail::surface_variation(m.covariance());
      return;
    }
    const detail::Eigen3 eig = detail::eigen_symmetric(m.covariance());
    if (want_curvature) ps.curvature[i] = detail::surface_variation(eig);
    {
      glm::vec3 nrm = eig.smallest;
      if (glm::dot(nrm, p - c) < 0.0f) nrm = -nrm;  // outward from the centroid
      ps.normals[i] = nrm;
    }
  });
  if (want_radii) fill_missing_radii(ps.radii);
}

}  // namespace

void complete_attributes(PointSet& ps, const AttributeOptions& options) {
  const std::size_t n = ps.size();
  if (options.recompute_normals) ps.normals.clear();
  if (options.recompute_radii) ps.radii.clear();
  if (ps.normals.size() != n) ps.normals.clear();
  if (ps.radii.size() != n) ps.radii.clear();
  if (ps.curvature.size() != n) ps.curvature.clear();
  if (ps.has_normals()) normalize_normals(ps.normals);
  if (ps.has_radii()) fill_missing_radii(ps.radii);
  const bool want_normals = !ps.has_normals(), want_radii = !ps.has_radii(),
             want_curvature = !ps.has_curvature();
  if (!want_normals && !want_radii && !want_curvature) return;
  if (!ps.triangles.empty())
    from_faces(ps, want_normals, want_radii, want_curvature);
  else
    from_neighbours(ps, std::max(3, options.k), want_normals, want_radii, want_curvature);
}

}  // namespace treecut
