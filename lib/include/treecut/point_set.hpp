// PointSet: the points of a model, as loaded from a PLY and completed with the
// per-point attributes the hierarchy needs (normals, splat radii, colors,
// curvature). Plain structure of arrays; every non-empty array has size().
#pragma once

#include <cstddef>
#include <cstdint>
#include <glm/ext/vector_double3.hpp>
#include <glm/gtc/quaternion.hpp>
#include <glm/gtc/type_precision.hpp>
#include <glm/vec3.hpp>
#include <glm/vec4.hpp>
#include <limits>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace treecut {

/// The largest coordinate magnitude treecut works with (models, camera eyes
/// and targets): squared distances and covariances of such points still fit
/// a float. Model points beyond it are dropped on import.
inline constexpr float kMaxCoordinate = 1e18f;

/// What a file says of its coordinate system, kept byte for byte so that an
/// export writes it back (LAS VLRs; PLY and PCD comments): the OGC WKT
/// (LAS record 2112) and the GeoTIFF records (34735 keys, 34736 doubles,
/// 34737 ASCII), each empty when the file has none.
struct CrsRecords {
  std::string wkt, geo_keys, geo_doubles, geo_ascii;
  [[nodiscard]] bool empty() const {
    return wkt.empty() && geo_keys.empty() && geo_doubles.empty() && geo_ascii.empty();
  }
  friend bool operator==(const CrsRecords&, const CrsRecords&) = default;
};

/// A record of the file's that treecut does not read but keeps, so an
/// export writes it back (a LAS VLR or EVLR of another program: a
/// classification lookup, a text description, a vendor's record).
struct FileRecord {
  std::string user;         ///< the LAS user ID (16 bytes at most)
  std::uint16_t id = 0;     ///< the record ID
  std::string description;  ///< 32 bytes at most
  std::string payload;
  friend bool operator==(const FileRecord&, const FileRecord&) = default;
};

/// Where a depth camera stood (a PCD's VIEWPOINT): its position and
/// orientation in the file's coordinates. The camera looks along its +z
/// with +y down, as PCL's viewer takes it.
struct Viewpoint {
  glm::dvec3 position{0.0};
  glm::dquat orientation{1.0, 0.0, 0.0, 0.0};  ///< w, x, y, z
};

/// How a model's positions relate to its file's coordinates: what a PLY
/// leaves at its defaults and a LAS sets (issue 29: map coordinates).
struct CoordinateFrame {
  /// Where positions are measured from, in the file's coordinates (double:
  /// map coordinates of 1e7 m keep millimetres; a float there is 0.5-1 m):
  /// a point's file coordinates are origin + its position. Zero unless the
  /// coordinates need one (choose_origin, position_frame.hpp).
  glm::dvec3 origin{0.0};
  /// The grid of the file's coordinates: multiples of `resolution` from
  /// `grid_offset` per axis (a LAS file's scale and offset), which a LAS
  /// export keeps so that it writes the same integers; resolution 0 where
  /// the file has no grid.
  glm::dvec3 resolution{0.0};
  glm::dvec3 grid_offset{0.0};
  /// The file format says +z is up (LAS: map coordinates, z the height);
  /// false when it says nothing (PLY: detect_up_axis decides).
  bool z_up = false;
  /// The file held no normals: they were estimated from the neighbours
  /// (complete_attributes), so shading by them is a guess; viewers turn
  /// eye-dome lighting on for such models (issue 30).
  bool normals_estimated = false;
  /// The file's coordinate system in words ("EPSG:26915 (projected)",
  /// "WKT: PROJCS[...]", after a reprojection "EPSG:32633, from EPSG:4326");
  /// empty when the file names none.
  std::string crs;
  /// The coordinate system's records as the file holds them (not cached:
  /// export reads the file).
  CrsRecords crs_records;
  /// The sensor's pose (PCD VIEWPOINT), when the file gives one that is not
  /// the identity: the first view opens from it.
  std::optional<Viewpoint> viewpoint;
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

/// How a file stores a scalar (LAS, PLY and PCD types): an export writes
/// each field in a type that holds every value.
enum class ValueType : std::uint8_t { u8, i8, u16, i16, u32, i32, u64, i64, f32, f64 };

[[nodiscard]] bool is_integer(ValueType type);
[[nodiscard]] bool is_signed(ValueType type);
/// Bytes of one value.
[[nodiscard]] std::size_t value_size(ValueType type);
/// "u8" .. "f64".
[[nodiscard]] std::string_view value_type_name(ValueType type);

/// One per-point scalar of the file beyond position, normal, colour and
/// radius (issue 29: every attribute kept), at the precision of the file's
/// type (issue 43): integers exactly, doubles as doubles unless a float
/// relative to `offset` gives every value back bit for bit, and an
/// attribute with one value at every point once.
struct PointAttribute {
  std::string name;  ///< as the file names it ("intensity", "classification")
  AttributeKind kind = AttributeKind::measure;
  /// How the file encodes a value: a `type`, times `scale`, plus `base` (a
  /// LAS extra-bytes field's scale and offset, LAS 1.4's scan angle steps
  /// of 0.006 degrees; 1 and 0 elsewhere), and the raw value that means
  /// none (a LAS no_data), if the file names one.
  ValueType type = ValueType::f64;
  double scale = 1.0, base = 0.0;
  std::optional<double> no_data{};
  /// The values (the file's, scaled; NaN: none), in one of four forms:
  /// floats relative to `offset` where each gives its value back exactly,
  /// else doubles (`wide`), a 64-bit integer field past 2^53 as its
  /// integers, else, all empty, `constant` at every point.
  double offset = 0.0;
  std::vector<float> values{};
  std::vector<double> wide{};
  double constant = std::numeric_limits<double>::quiet_NaN();
  /// A 64-bit integer field (unscaled) with a value past 2^53, where a
  /// double rounds: every raw value exactly (a u64's as its bits).
  std::vector<std::int64_t> integers{};

  [[nodiscard]] bool is_constant() const {
    return values.empty() && wide.empty() && integers.empty();
  }
  /// Point I's value (the file's; NaN: none).
  [[nodiscard]] double value(std::size_t i) const {
    if (!values.empty()) return offset + double(values[i]);
    if (!wide.empty()) return wide[i];
    if (!integers.empty()) {
      return type == ValueType::u64 ? double(static_cast<std::uint64_t>(integers[i]))
                                    : double(integers[i]);
    }
    return constant;
  }
  /// Values stored per point (0: constant).
  [[nodiscard]] std::size_t stored() const { return values.size() + wide.size() + integers.size(); }
};

/// Attributes kept per model; a file with more keeps the first ones and
/// warns about the rest (the cache and the HUD list them all).
inline constexpr std::size_t kMaxAttributes = 64;
/// The longest attribute name kept (the readers cut longer ones).
inline constexpr std::size_t kMaxAttributeName = 47;

struct PointSet {
  CoordinateFrame frame;             ///< the file's coordinates: frame.origin + positions[i]
  std::vector<glm::vec3> positions;  ///< model units, relative to origin, always size()
  /// The file's coordinates (not relative to the origin) where the floats
  /// would not give them back (a LAS grid finer than a float's spacing, a
  /// double PLY); empty otherwise. What an export writes; a build drops
  /// them (the hierarchy is floats).
  std::vector<glm::dvec3> exact_positions;
  std::vector<glm::vec3> normals;   ///< unit length (zero when undefined) or empty
  std::vector<float> radii;         ///< splat radius, model units, > 0, or empty
  std::vector<glm::u8vec4> colors;  ///< sRGB + alpha 255, or empty (the hierarchy uses grey)
  /// The file's colours at 16 bits a channel (LAS, PLY ushort, PCD U2),
  /// where the 8-bit `colors` would not give them back; else empty.
  std::vector<glm::u16vec3> colors16;
  std::vector<float> curvature;            ///< surface variation in [0, 1/3], or empty
  std::vector<glm::uvec3> triangles;       ///< optional faces (indices into positions)
  std::vector<PointAttribute> attributes;  ///< the file's other scalars, each size() values
  /// The file's records treecut keeps without reading them (FileRecord).
  std::vector<FileRecord> records;
  /// LAS global encoding bit 0: the GPS times are adjusted standard GPS time
  /// (seconds since 1980 less 1e9), not seconds of the GPS week.
  bool adjusted_gps_time = false;

  [[nodiscard]] std::size_t size() const { return positions.size(); }
  [[nodiscard]] bool has_normals() const { return !normals.empty(); }
  [[nodiscard]] bool has_radii() const { return !radii.empty(); }
  [[nodiscard]] bool has_colors() const { return !colors.empty(); }
  [[nodiscard]] bool has_curvature() const { return !curvature.empty(); }

  /// Keeps the points whose KEEP entry is true (KEEP has size() entries),
  /// every per-point array in step: positions, normals, radii, colours,
  /// curvature and attributes; the faces that use a dropped point go, the
  /// others are renumbered.
  void keep_if(const std::vector<bool>& keep);

  /// MORE's points after these, as one cloud (issue 44: the tiles of a
  /// survey are one model): its positions moved to this origin, arrays both
  /// have joined (normals, radii, curvature only one has are dropped for
  /// all, as for a file without them; colours a file lacks are grey),
  /// attributes joined by name (NaN where a file has none; one encoding for
  /// both, doubles where types, scales or offsets differ), faces renumbered.
  /// This frame, records and coordinate system stay; the caller checks that
  /// MORE's coordinate system is the same.
  void append(PointSet&& more);
};

}  // namespace treecut
