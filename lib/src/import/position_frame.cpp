// One origin rule for every reader (position_frame.hpp).
#include "position_frame.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <iterator>

namespace treecut::detail {

namespace {

bool within(const glm::dvec3& d, double reach) {
  return std::fabs(d.x) <= reach && std::fabs(d.y) <= reach && std::fabs(d.z) <= reach;
}

// The median of each coordinate of at most ~64k points spread over POINTS;
// of an even count, the middle value nearer zero (of two points, one far
// out, the other decides).
glm::dvec3 median(std::span<const glm::dvec3> points) {
  const std::size_t stride = std::max<std::size_t>(1, points.size() / 65536);
  std::vector<double> axis;
  glm::dvec3 m(0.0);
  for (int a = 0; a < 3; ++a) {
    axis.clear();
    for (std::size_t i = 0; i < points.size(); i += stride) axis.push_back(points[i][a]);
    const auto upper = axis.begin() + static_cast<std::ptrdiff_t>(axis.size() / 2);
    std::nth_element(axis.begin(), upper, axis.end());
    m[a] = *upper;
    if (axis.size() % 2 == 0) {
      const double lower = *std::max_element(axis.begin(), upper);
      if (std::fabs(lower) < std::fabs(m[a])) m[a] = lower;
    }
  }
  return m;
}

}  // namespace

bool near_zero(const glm::dvec3& lo, const glm::dvec3& hi) {
  return within(lo, kNoOriginReach) && within(hi, kNoOriginReach);
}

glm::dvec3 choose_origin(std::span<const glm::dvec3> points) {
  if (points.empty()) return glm::dvec3(0.0);
  const glm::dvec3 m = median(points);
  glm::dvec3 lo(INFINITY), hi(-INFINITY);
  for (const glm::dvec3& p : points) {
    if (!within(p - m, double(kMaxCoordinate)) || !within(p, double(kMaxCoordinate))) continue;
    lo = glm::min(lo, p), hi = glm::max(hi, p);
  }
  if (near_zero(lo, hi)) return glm::dvec3(0.0);
  return glm::round(0.5 * lo + 0.5 * hi);
}

std::string Dropped::far_message(std::size_t first_number) const {
  char at[96];
  std::snprintf(at, sizeof at, "%.6g %.6g %.6g", first_far_at.x, first_far_at.y, first_far_at.z);
  return "dropped " + std::to_string(far) + (far == 1 ? " point" : " points") +
         " beyond the coordinate limit, 1e18 from the others or from zero (the first: point " +
         std::to_string(first_number) + " at " + at + ")";
}

Dropped place_points(std::vector<glm::dvec3>&& doubles, PointSet& points,
                     const std::optional<glm::dvec3>& given) {
  auto finite = [](const glm::dvec3& p) {
    return std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z);
  };
  const glm::dvec3 origin = given ? *given : [&] {
    std::vector<glm::dvec3> usable;
    const bool all_finite = std::all_of(doubles.begin(), doubles.end(), finite);
    if (!all_finite)
      std::copy_if(doubles.begin(), doubles.end(), std::back_inserter(usable), finite);
    return choose_origin(all_finite ? doubles : usable);
  }();
  points.frame.origin = origin;
  points.positions.resize(doubles.size());
  Dropped out;
  std::vector<bool> keep;
  bool exact = true;
  for (std::size_t i = 0; i < doubles.size(); ++i) {
    const glm::dvec3 q = doubles[i] - origin;
    // Within the limit of the origin and of zero (a file's coordinates past
    // 1e18 would make a LAS no reader takes).
    if (within(q, double(kMaxCoordinate)) && within(doubles[i], double(kMaxCoordinate))) {
      points.positions[i] = glm::vec3(q);
      exact = exact && float_exact(points.positions[i], origin, doubles[i]);
      continue;
    }
    if (keep.empty()) keep.assign(doubles.size(), true);
    keep[i] = false;
    if (!finite(doubles[i])) {
      ++out.nonfinite;
    } else if (out.far++ == 0) {
      out.first_far = i, out.first_far_at = doubles[i];
    }
  }
  if (!exact) points.exact_positions = std::move(doubles);
  if (!keep.empty()) points.keep_if(keep);
  return out;
}

}  // namespace treecut::detail
