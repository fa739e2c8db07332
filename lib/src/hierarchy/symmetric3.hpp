// Eigen-analysis of symmetric 3x3 covariance matrices, as needed for PCA
// normals and surface variation (Pauly, Gross, Kobbelt: "Efficient
// Simplification of Point-Sampled Surfaces", 2002: sigma = l0 / (l0 + l1 + l2)).
#pragma once

#include <algorithm>
#include <cmath>
#include <glm/geometric.hpp>
#include <glm/vec3.hpp>

namespace treecut::detail {

/// Upper triangle of a symmetric matrix: xx xy xz yy yz zz.
/// Accumulated in float: callers add offsets relative to the point itself,
/// so there is no large mean to cancel; the solve below runs in double.
struct Sym3 {
  float xx = 0, xy = 0, xz = 0, yy = 0, yz = 0, zz = 0;
  void add(glm::vec3 d) {
    xx += d.x * d.x, xy += d.x * d.y, xz += d.x * d.z;
    yy += d.y * d.y, yz += d.y * d.z, zz += d.z * d.z;
  }
};

struct Eigen3 {
  double values[3];    ///< ascending
  glm::vec3 smallest;  ///< unit eigenvector of values[0], or zero when undefined
};

/// Closed-form eigenvalues (trigonometric method) and the eigenvector of the
/// smallest one from the largest cross product of two rows of (A - l0 I).
inline Eigen3 eigen_symmetric(const Sym3& a) {
  Eigen3 r{};
  const double p1 = a.xy * a.xy + a.xz * a.xz + a.yz * a.yz;
  const double q = (a.xx + a.yy + a.zz) / 3.0;
  if (p1 <= 1e-30 * (q * q + 1e-300)) {
    double v[3] = {a.xx, a.yy, a.zz};
    std::sort(v, v + 3);
    std::copy(v, v + 3, r.values);
  } else {
    const double p2 =
        (a.xx - q) * (a.xx - q) + (a.yy - q) * (a.yy - q) + (a.zz - q) * (a.zz - q) + 2.0 * p1;
    const double p = std::sqrt(p2 / 6.0);
    const double bxx = (a.xx - q) / p, byy = (a.yy - q) / p, bzz = (a.zz - q) / p;
    const double bxy = a.xy / p, bxz = a.xz / p, byz = a.yz / p;
    const double det = bxx * (byy * bzz - byz * byz) - bxy * (bxy * bzz - byz * bxz) +
                       bxz * (bxy * byz - byy * bxz);
    const double rr = std::clamp(det / 2.0, -1.0, 1.0);
    const double phi = std::acos(rr) / 3.0;
    const double l2 = q + 2.0 * p * std::cos(phi);
    const double l0 = q + 2.0 * p * std::cos(phi + 2.0 * M_PI / 3.0);
    r.values[0] = l0;
    r.values[1] = 3.0 * q - l0 - l2;
    r.values[2] = l2;
  }
  const double l = r.values[0];
  const glm::dvec3 r0(a.xx - l, a.xy, a.xz), r1(a.xy, a.yy - l, a.yz), r2(a.xz, a.yz, a.zz - l);
  const glm::dvec3 c01 = glm::cross(r0, r1), c02 = glm::cross(r0, r2), c12 = glm::cross(r1, r2);
  const double d01 = glm::dot(c01, c01), d02 = glm::dot(c02, c02), d12 = glm::dot(c12, c12);
  glm::dvec3 best = c01;
  double bd = d01;
  if (d02 > bd) best = c02, bd = d02;
  if (d12 > bd) best = c12, bd = d12;
  // A smallest eigenvalue of multiplicity > 1 (a line or a single point) has no
  // unique normal: leave it undefined rather than invent one.
  const double scale = r.values[2] * r.values[2] + 1e-300;
  const bool unique = r.values[1] - r.values[0] > 1e-9 * std::max(r.values[2], 1e-300);
  if (bd > 1e-24 * scale * scale && unique) r.smallest = glm::vec3(best / std::sqrt(bd));
  return r;
}

/// Surface variation l0 / (l0 + l1 + l2), in [0, 1/3].
inline float surface_variation(const Eigen3& e) {
  const double sum = e.values[0] + e.values[1] + e.values[2];
  if (!(sum > 0.0)) return 0.0f;
  return static_cast<float>(std::clamp(e.values[0] / sum, 0.0, 1.0 / 3.0));
}

/// The same from the matrix alone: l0 / trace, with one acos and one cos
/// (the sum of the eigenvalues is the trace, so l1 and l2 are not needed).
inline float surface_variation(const Sym3& a) {
  const double trace = static_cast<double>(a.xx) + a.yy + a.zz;
  if (!(trace > 0.0)) return 0.0f;
  const double q = trace / 3.0;
  const double p1 = static_cast<double>(a.xy) * a.xy + static_cast<double>(a.xz) * a.xz +
                    static_cast<double>(a.yz) * a.yz;
  double l0;
  if (p1 <= 1e-30 * q * q) {
    l0 =
        std::min({static_cast<double>(a.xx), static_cast<double>(a.yy), static_cast<double>(a.zz)});
  } else {
    const double dx = a.xx - q, dy = a.yy - q, dz = a.zz - q;
    const double p = std::sqrt((dx * dx + dy * dy + dz * dz + 2.0 * p1) / 6.0);
    const double bxx = dx / p, byy = dy / p, bzz = dz / p;
    const double bxy = a.xy / p, bxz = a.xz / p, byz = a.yz / p;
    const double det = bxx * (byy * bzz - byz * byz) - bxy * (bxy * bzz - byz * bxz) +
                       bxz * (bxy * byz - byy * bxz);
    const double phi = std::acos(std::clamp(det / 2.0, -1.0, 1.0)) / 3.0;
    l0 = q + 2.0 * p * std::cos(phi + 2.0 * M_PI / 3.0);
  }
  return static_cast<float>(std::clamp(l0 / trace, 0.0, 1.0 / 3.0));
}

}  // namespace treecut::detail
