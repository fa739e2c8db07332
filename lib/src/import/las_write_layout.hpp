// What a LAS export writes (las_write.cpp): the grid its integer
// coordinates are on, and the point format and fields that hold every
// attribute of every point, each standard field checked to fit its slot.
// Private to the LAS writer.
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <glm/glm.hpp>
#include <vector>

#include "treecut/point_set.hpp"

namespace treecut::las_layout {

/// The scale and offset of the integer coordinates, and their range.
struct Grid {
  glm::dvec3 scale{0.001};
  glm::dvec3 offset{0.0};
  glm::dvec3 min{0.0}, max{0.0};  // of the integer coordinates, in file units
};

/// The grid of POINTS (SCALE > 0: that scale on every axis; 0: the file's
/// own grid where it still reaches every point, else the coarsest decimal
/// step of the exact coordinates); throws InputError naming PATH when the
/// points span more than 32-bit integers hold.
Grid grid_of(const std::filesystem::path& path, const PointSet& points, double scale);

/// Point I's integer coordinates on G.
std::array<std::int32_t, 3> integers(const PointSet& points, std::size_t i, const Grid& g);

/// The attributes a record holds: the standard fields by name, the rest as
/// extra bytes; the smallest point format for them.
struct Layout {
  const PointAttribute* intensity = nullptr;
  const PointAttribute* return_number = nullptr;
  const PointAttribute* number_of_returns = nullptr;
  const PointAttribute* scan_direction = nullptr;
  const PointAttribute* edge = nullptr;
  const PointAttribute* classification = nullptr;
  const PointAttribute* flags = nullptr;
  const PointAttribute* scan_angle = nullptr;
  const PointAttribute* user_data = nullptr;
  const PointAttribute* point_source_id = nullptr;
  const PointAttribute* gps_time = nullptr;
  const PointAttribute* scanner_channel = nullptr;
  const PointAttribute* nir = nullptr;
  std::vector<const PointAttribute*> extra;
  bool rgb = false;
  int format = 0;

  [[nodiscard]] bool extended() const { return format >= 6; }
  [[nodiscard]] std::uint16_t base_length() const {
    constexpr std::uint16_t kBase[9] = {20, 28, 26, 34, 0, 0, 30, 36, 38};
    return kBase[format];
  }
  [[nodiscard]] std::size_t record_length() const {
    std::size_t length = base_length();
    for (const PointAttribute* a : extra) length += value_size(a->type);
    return length;
  }
};

/// The layout of POINTS: the standard fields found by name, the rest as
/// extra bytes, the smallest point format that holds them. An integer
/// extra-bytes attribute with missing values and no no-data value is written
/// as a double: its widened copy is kept in WIDENED.
Layout layout_of(const PointSet& points, std::vector<PointAttribute>& widened);

/// Throws InputError naming PATH, the field and what LAS holds there unless
/// every value of every standard field of L (N points) fits its slot.
void check_standard_fields(const std::filesystem::path& path, const Layout& l, std::size_t n);

/// The file's value of attribute A at point I as an integer in [LO, HI] in
/// units of UNIT (NaN, no value, no attribute: 0).
std::int64_t integer_value(const PointAttribute* a, std::size_t i, std::int64_t lo, std::int64_t hi,
                           double unit = 1.0);

}  // namespace treecut::las_layout
