// PointSet: the points of a model, as loaded from a PLY and completed with the
// per-point attributes the hierarchy needs (normals, splat radii, colors,
// curvature). Plain structure of arrays; every non-empty array has size().
#pragma once

#include <cstddef>
#include <cstdint>
#include <glm/ext/vector_double3.hpp>
#include <glm/gtc/type_precision.hpp>
#include <glm/vec3.hpp>
#include <glm/vec4.hpp>
#include <string>
#include <string_view>
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
  /// The file held no normals: they were estimated from the neighbours
  /// (complete_attributes), so shading by them is a guess; viewers turn
  /// eye-dome lighting on for such models (issue 30).
  bool normals_estimated = false;
  /// The file's coordinate system, as LasInfo::crs words it ("WKT: ...",
  /// "GeoTIFF: EPSG code N"); empty when the file names none.
  std::string crs;
};

/// How a per-point scalar is summarized over a hierarchy node and coloured:
/// a measure (intensity, GPS time, scan angle) by its point-weighted mean on
/// a continuous colour map, a category (classification, return number, point
/// source id) by its most frequent value on a palette of distinct colours.
enum class AttributeKind : std::uint8_t { measure = 0, category = 1 };

/// The kind a scalar named NAME is taken for: a category for the names that
/// count or label (classification, class, label, return_number,
/// number_of_returns, user_data, point_source_id, scanner_channel, the LAS
/// flags, segment ids), a measure for everything else.
[[nodiscard]] AttributeKind attribute_kind_for(std::string_view name);

/// One per-point scalar of the file beyond position, normal, colour and
/// radius (issue 29: every attribute kept), in float relative to `offset`
/// so that a GPS time of 3e8 s keeps milliseconds. Non-finite values are
/// NaN: no value.
struct PointAttribute {
  std::string name;  ///< as the file names it ("intensity", "classification")
  AttributeKind kind = AttributeKind::measure;
  double offset = 0.0;        ///< the file's value is offset + values[i]
  std::vector<float> values;  ///< one per point (PointSet::size())
};

/// Attributes kept per model; a file with more keeps the first ones and
/// warns about the rest (the cache and the HUD list them all).
inline constexpr std::size_t kMaxAttributes = 64;
/// The longest attribute name kept (the readers cut longer ones).
inline constexpr std::size_t kMaxAttributeName = 47;

struct PointSet {
  CoordinateFrame frame;                   ///< the file's coordinates: frame.origin + positions[i]
  std::vector<glm::vec3> positions;        ///< model units, relative to origin, always size()
  std::vector<glm::vec3> normals;          ///< unit length (zero when undefined) or empty
  std::vector<float> radii;                ///< splat radius, model units, > 0, or empty
  std::vector<glm::u8vec4> colors;         ///< sRGB + alpha 255, or empty (the hierarchy uses grey)
  std::vector<float> curvature;            ///< surface variation in [0, 1/3], or empty
  std::vector<glm::uvec3> triangles;       ///< optional faces (indices into positions)
  std::vector<PointAttribute> attributes;  ///< the file's other scalars, each size() values

  [[nodiscard]] std::size_t size() const { return positions.size(); }
  [[nodiscard]] bool has_normals() const { return !normals.empty(); }
  [[nodiscard]] bool has_radii() const { return !radii.empty(); }
  [[nodiscard]] bool has_colors() const { return !colors.empty(); }
  [[nodiscard]] bool has_curvature() const { return !curvature.empty(); }
};

}  // namespace treecut
