// The PointSet contract after OpenMesh's read (ply_load_parts.hpp): points
// with a non-finite or out-of-range coordinate dropped with their faces,
// normals unit or zero, radii all positive or none.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>

#include "ply_load_parts.hpp"
#include "unit_normal.hpp"

namespace treecut::ply_load {

namespace {

// Beyond kMaxCoordinate (point_set.hpp) the float arithmetic of attributes
// and build (squared distances, covariances) overflows: such points are as
// unusable as NaNs.
bool out_of_range(const glm::vec3& p) {
  return !(std::fabs(p.x) <= kMaxCoordinate && std::fabs(p.y) <= kMaxCoordinate &&
           std::fabs(p.z) <= kMaxCoordinate);
}

// Drops points with a non-finite or out-of-range coordinate from every array,
// and the faces that use them (PointSet::keep_if). Returns {points, faces}
// dropped.
std::pair<std::size_t, std::size_t> drop_nonfinite(PointSet& points) {
  std::vector<bool> keep(points.size());
  std::size_t bad = 0;
  for (std::size_t i = 0; i < keep.size(); ++i) {
    keep[i] = !out_of_range(points.positions[i]);
    bad += !keep[i];
  }
  if (bad == 0) return {0, 0};
  const std::size_t faces = points.triangles.size();
  points.keep_if(keep);
  return {bad, faces - points.triangles.size()};
}

}  // namespace

void tidy(PointSet& points, const Warnings& warn, PlyLoadReport& report,
          std::size_t finite_beyond_float) {
  std::size_t huge_count = 0, nonfinite_count = 0;
  for (const glm::vec3& p : points.positions) {
    if (!out_of_range(p)) continue;
    if (std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z))
      ++huge_count;
    else
      ++nonfinite_count;
  }
  // Those were finite in the file: too large, not infinite.
  const std::size_t beyond = std::min(finite_beyond_float, nonfinite_count);
  nonfinite_count -= beyond;
  huge_count += beyond;
  const bool huge = huge_count > 0;
  const std::size_t read = points.size();
  if (huge_count + nonfinite_count == read) {
    // One line that names the real problem, not a warning about dropping
    // every point followed by an error about having none.
    const std::string which = read == 1 ? std::string("the only vertex is")
                                        : "all " + std::to_string(read) + " vertices are";
    if (nonfinite_count == 0)
      throw ply::Error("no usable points (" + which +
                       " finite but beyond the coordinate limit, 1e18 in magnitude)");
    if (huge_count == 0) throw ply::Error("no finite points (" + which + " NaN or infinite)");
    throw ply::Error("no usable points (" + which +
                     " NaN, infinite or beyond 1e18: " + std::to_string(nonfinite_count) +
                     " not finite, " + std::to_string(huge_count) + " too large)");
  }
  const auto [dropped_points, dropped_faces] = drop_nonfinite(points);
  report.dropped_nonfinite = dropped_points;
  if (dropped_points > 0) {
    warn("dropped " + plural(dropped_points, "point") + " with non-finite" +
         (huge ? " or out-of-range (beyond 1e18)" : "") + " coordinates" +
         (dropped_faces > 0 ? " and " + plural(dropped_faces, "face") + " using them" : ""));
  }

  if (points.has_normals()) {
    std::size_t undefined = 0;
    for (glm::vec3& n : points.normals) {
      if (!(std::isfinite(n.x) && std::isfinite(n.y) && std::isfinite(n.z))) ++undefined;
      n = detail::unit_or_zero(n.x, n.y, n.z);
    }
    if (undefined > 0) warn(plural(undefined, "normal") + " not finite, set to zero");
  }
  if (points.has_radii()) {
    const auto bad = static_cast<std::size_t>(
        std::count_if(points.radii.begin(), points.radii.end(),
                      [](float r) { return !(std::isfinite(r) && r > 0.0f); }));
    if (bad > 0) {
      warn("ignoring the radius property: " + std::to_string(bad) + " of " +
           std::to_string(points.radii.size()) + " radii are not positive finite numbers");
      points.radii.clear();
    }
  }
}

}  // namespace treecut::ply_load
