// PointSet: the points of a model, as loaded from a PLY and completed with the
// per-point attributes the hierarchy needs (normals, splat radii, colors,
// curvature). Plain structure of arrays; every non-empty array has size().
#pragma once

#include <cstddef>
#include <cstdint>
#include <glm/gtc/type_precision.hpp>
#include <glm/vec3.hpp>
#include <glm/ext/vector_double3.hpp>
#include <glm/vec4.hpp>
#include <string>
#include <vector>

namespace treecut {

/// The largest coordinate magnitude treecut works with (models, camera eyes
/// and targets): squared distances and covariances of such points still fit
/// a float. Model points beyond it are dropped on import.
inline constexpr float kMaxCoordinate = 1e18f;

/// How a model's positions relate to its file's coordinates: what a PLY
/// leaves at its defaults and a LAS sets (issue 29: map coordinates).
struct CoordinateFrame {
  /// Where positions are measured from, in the file's coordinates (double:
  /// map coordinates of 1e7 m keep millimetres; a float there is 0.5-1 m):
  /// a point's file coordinates are origin + its position.
  glm::dvec3 origin{0.0};
  /// The file format says +z is up (LAS: map coordinates, z the height);
  /// false when it says nothing (PLY: detect_up_axis decides).
  bool z_up = false;
  /// The file's coordinate system, as LasInfo::crs words it ("WKT: ...",
  /// "GeoTIFF: EPSG code N"); empty when the file names none.
  std::string crs;
};

struct PointSet {
  CoordinateFrame frame;  ///< the file's coordinates: frame.origin + positions[i]
  std::vector<glm::vec3> positions;   ///< model units, relative to origin, always size()
  std::vector<glm::vec3> normals;     ///< unit length (zero when undefined) or empty
  std::vector<float> radii;           ///< splat radius, model units, > 0, or empty
  std::vector<glm::u8vec4> colors;    ///< sRGB + alpha 255, or empty (the hierarchy uses grey)
  std::vector<float> curvature;       ///< surface variation in [0, 1/3], or empty
  std::vector<glm::uvec3> triangles;  ///< optional faces (indices into positions)

  [[nodiscard]] std::size_t size() const { return positions.size(); }
  [[nodiscard]] bool has_normals() const { return !normals.empty(); }
  [[nodiscard]] bool has_radii() const { return !radii.empty(); }
  [[nodiscard]] bool has_colors() const { return !colors.empty(); }
  [[nodiscard]] bool has_curvature() const { return !curvature.empty(); }
};

}  // namespace treecut
