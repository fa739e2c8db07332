// The PointSet contract after OpenMesh's read (ply_load_parts.hpp): points
// with a non-finite or out-of-range coordinate dropped with their faces,
// normals unit or zero, radii all positive or none.
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <tuple>

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

Tidied& Tidied::operator+=(const Tidied& o) {
  read += o.read, nonfinite += o.nonfinite, huge += o.huge, dropped_faces += o.dropped_faces;
  undefined_normals += o.undefined_normals, bad_radii += o.bad_radii, radii += o.radii;
  return *this;
}

std::string no_usable_points(const Tidied& t) {
  // One line that names the real problem, not a warning about dropping
  // every point followed by an error about having none.
  const std::string which = t.read == 1 ? std::string("the only vertex is")
                                        : "all " + std::to_string(t.read) + " vertices are";
  if (t.nonfinite == 0)
    return "no usable points (" + which +
           " finite but beyond the coordinate limit, 1e18 in magnitude)";
  if (t.huge == 0) return "no finite points (" + which + " NaN or infinite)";
  return "no usable points (" + which +
         " NaN, infinite or beyond 1e18: " + std::to_string(t.nonfinite) + " not finite, " +
         std::to_string(t.huge) + " too large)";
}

void say(const Tidied& t, const Warnings& warn) {
  if (const std::size_t dropped = t.nonfinite + t.huge; dropped > 0) {
    warn("dropped " + plural(dropped, "point") + " with non-finite" +
         (t.huge > 0 ? " or out-of-range (beyond 1e18)" : "") + " coordinates" +
         (t.dropped_faces > 0 ? " and " + plural(t.dropped_faces, "face") + " using them" : ""));
  }
  if (t.undefined_normals > 0)
    warn(plural(t.undefined_normals, "normal") + " not finite, set to zero");
  if (t.bad_radii > 0) {
    warn("ignoring the radius property: " + std::to_string(t.bad_radii) + " of " +
         std::to_string(t.radii) + " radii are not positive finite numbers");
  }
}

void tidy(PointSet& points, const Warnings& warn, PlyLoadReport& report,
          std::size_t finite_beyond_float, Tidied* batch) {
  Tidied t;
  t.read = points.size();
  for (const glm::vec3& p : points.positions) {
    if (!out_of_range(p)) continue;
    if (std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z))
      ++t.huge;
    else
      ++t.nonfinite;
  }
  // Those were finite in the file: too large, not infinite.
  const std::size_t beyond = std::min(finite_beyond_float, t.nonfinite);
  t.nonfinite -= beyond;
  t.huge += beyond;
  if (!batch && t.huge + t.nonfinite == t.read) throw ply::Error(no_usable_points(t));
  std::size_t dropped_points = 0;
  std::tie(dropped_points, t.dropped_faces) = drop_nonfinite(points);
  report.dropped_nonfinite = dropped_points;

  if (points.has_normals()) {
    for (glm::vec3& n : points.normals) {
      if (!(std::isfinite(n.x) && std::isfinite(n.y) && std::isfinite(n.z))) ++t.undefined_normals;
      n = detail::unit_or_zero(n.x, n.y, n.z);
    }
  }
  if (points.has_radii()) {
    t.radii = points.radii.size();
    t.bad_radii = static_cast<std::size_t>(
        std::count_if(points.radii.begin(), points.radii.end(),
                      [](float r) { return !(std::isfinite(r) && r > 0.0f); }));
    if (t.bad_radii > 0) points.radii.clear();
  }
  if (batch) {
    *batch += t;
  } else {
    say(t, warn);
  }
}

}  // namespace treecut::ply_load
