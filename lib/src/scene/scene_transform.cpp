// Singular values of an object's transform (scene.hpp): what the renderer
// sizes splats by and the stage widens a per-object strategy's size test by.
#include <algorithm>
#include <cmath>
#include <functional>
#include <glm/mat3x3.hpp>
#include <glm/matrix.hpp>

#include "treecut/scene.hpp"

namespace treecut {

std::array<double, 3> singular_values(const glm::mat4& world) {
  const glm::dmat3 l{glm::mat3(world)};
  const glm::dmat3 a = glm::transpose(l) * l;
  const double p1 = a[0][1] * a[0][1] + a[0][2] * a[0][2] + a[1][2] * a[1][2];
  std::array<double, 3> e{};
  if (p1 == 0.0) {
    e = {a[0][0], a[1][1], a[2][2]};
  } else {
    const double q = (a[0][0] + a[1][1] + a[2][2]) / 3.0;
    const double p2 = (a[0][0] - q) * (a[0][0] - q) + (a[1][1] - q) * (a[1][1] - q) +
                      (a[2][2] - q) * (a[2][2] - q) + 2.0 * p1;
    const double p = std::sqrt(p2 / 6.0);
    const glm::dmat3 b = (a - q * glm::dmat3(1.0)) * (1.0 / p);
    const double r = std::clamp(glm::determinant(b) / 2.0, -1.0, 1.0);
    const double phi = std::acos(r) / 3.0;
    constexpr double kThird = 2.0943951023931954923;  // 2 pi / 3
    e[0] = q + 2.0 * p * std::cos(phi);
    e[2] = q + 2.0 * p * std::cos(phi + kThird);
    e[1] = 3.0 * q - e[0] - e[2];
  }
  std::sort(e.begin(), e.end(), std::greater<>());
  return {std::sqrt(std::max(e[0], 0.0)), std::sqrt(std::max(e[1], 0.0)),
          std::sqrt(std::max(e[2], 0.0))};
}

bool invertible_transform(const glm::dmat3& a) {
  const double c0 = glm::length(a[0]), c1 = glm::length(a[1]), c2 = glm::length(a[2]);
  const double longest = std::max({c0, c1, c2});
  const double det = glm::determinant(a);
  constexpr double kTiny = 1e-30;
  return std::isfinite(det) && std::isfinite(longest) && c0 > kTiny && c1 > kTiny && c2 > kTiny &&
         std::abs(det) > 1e-9 * c0 * c1 * c2 && std::abs(det) > 1e-12 * longest * longest * longest;
}

}  // namespace treecut
