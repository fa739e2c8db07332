// The readers' way to keep a per-point scalar (PointSet::attributes): values
// arrive as doubles in point order and are stored as floats relative to an
// offset the first finite value fixes, so large values (a GPS time of 3e8 s)
// keep their resolution and small ones (classes, intensities) stay exact.
#pragma once

#include <cmath>
#include <cstddef>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "treecut/point_set.hpp"

namespace treecut::detail {

class AttributeColumn {
 public:
  /// NAME is cut to kMaxAttributeName bytes, control bytes made '?'.
  AttributeColumn(std::string name, std::size_t points) {
    if (name.size() > kMaxAttributeName) name.resize(kMaxAttributeName);
    for (char& c : name) {
      if (static_cast<unsigned char>(c) < 0x20 || c == 0x7f) c = '?';
    }
    attribute_.kind = attribute_kind_for(name);
    attribute_.name = std::move(name);
    attribute_.values.resize(points);
  }

  void set(std::size_t point, double value) {
    if (!std::isfinite(value)) {
      attribute_.values[point] = std::numeric_limits<float>::quiet_NaN();
      return;
    }
    if (!offset_fixed_) {
      // Below 1e6 a float keeps 1/16 and integers exactly: no offset, so
      // the stored values read as the file's.
      attribute_.offset = std::fabs(value) < 1e6 ? 0.0 : std::round(value);
      offset_fixed_ = true;
    }
    const double relative = value - attribute_.offset;
    attribute_.values[point] = std::fabs(relative) <= double(std::numeric_limits<float>::max())
                                   ? static_cast<float>(relative)
                                   : std::numeric_limits<float>::quiet_NaN();
  }

  void push_back(double value) {
    attribute_.values.emplace_back();
    set(attribute_.values.size() - 1, value);
  }

  [[nodiscard]] PointAttribute take() { return std::move(attribute_); }

 private:
  PointAttribute attribute_;
  bool offset_fixed_ = false;
};

/// Removes the attributes without two different values (NaN: none) and
/// returns "name value" for each, for one warning: a constant colours
/// nothing and would cost 4 bytes a point in every node and cache.
std::vector<std::string> drop_constant_attributes(std::vector<PointAttribute>& attributes);

/// "a, b, c".
std::string join(const std::vector<std::string>& items);

}  // namespace treecut::detail
