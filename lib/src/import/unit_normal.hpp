// A file's normal as the PointSet keeps it (point_set.hpp): unit length, or
// zero when it has no direction. In double: squaring a large float
// component must not overflow, nor a tiny one underflow, on the way.
#pragma once

#include <cmath>
#include <glm/vec3.hpp>

namespace treecut::detail {

inline glm::vec3 unit_or_zero(double x, double y, double z) {
  const double length = std::sqrt(x * x + y * y + z * z);
  if (!(std::isfinite(length) && length > 0.0)) return glm::vec3(0.0f);
  return {static_cast<float>(x / length), static_cast<float>(y / length),
          static_cast<float>(z / length)};
}

}  // namespace treecut::detail
