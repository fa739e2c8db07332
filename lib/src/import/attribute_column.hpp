// The readers' way to keep a per-point scalar (PointSet::attributes): values
// arrive as doubles in point order and are stored as floats relative to an
// offset the first finite value fixes, so large values (a GPS time of 3e8 s)
// keep their resolution and small ones (classes, intensities) stay exact.
//
// Nothing is stored while every value is the same: a LAS record has a dozen
// fields, of which a file often fills half with one value (user data 0,
// point source 1); they would cost 4 bytes a point each, touched twice (the
// 20 M-point LAS read took 4.6 s instead of 1.3 s when every field was
// stored). The values are stored from the first one that differs.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstring>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "treecut/point_set.hpp"

namespace treecut::detail {

class AttributeColumn {
 public:
  /// NAME is cut to kMaxAttributeName bytes, control bytes made '?'.
  /// EXPECTED: the points to come (reserved once the values differ).
  AttributeColumn(std::string name, std::size_t expected) : expected_(expected) {
    if (name.size() > kMaxAttributeName) name.resize(kMaxAttributeName);
    for (char& c : name) {
      if (static_cast<unsigned char>(c) < 0x20 || c == 0x7f) c = '?';
    }
    attribute_.kind = attribute_kind_for(name);
    attribute_.name = std::move(name);
  }

  /// The next point's value (the file's: the offset is taken off here).
  void push_back(double value) {
    float f = std::numeric_limits<float>::quiet_NaN();
    if (std::isfinite(value)) {
      if (!offset_fixed_) {
        // Below 1e6 a float keeps 1/16 and integers exactly: no offset, so
        // the stored values read as the file's.
        attribute_.offset = std::fabs(value) < 1e6 ? 0.0 : std::round(value);
        offset_fixed_ = true;
      }
      const double relative = value - attribute_.offset;
      if (std::fabs(relative) <= double(std::numeric_limits<float>::max())) {
        f = static_cast<float>(relative);
      }
    }
    if (!stored_) {
      if (count_ == 0 || same(f, first_)) {
        if (count_++ == 0) first_ = f;
        return;
      }
      attribute_.values.reserve(std::max(expected_, count_ + 1));
      attribute_.values.assign(count_, first_);
      stored_ = true;
    }
    attribute_.values.push_back(f);
    ++count_;
  }

  /// No two values differ (NaN counts as a value: none).
  [[nodiscard]] bool constant() const { return !stored_; }
  /// "name value" of a constant column, for a warning.
  [[nodiscard]] std::string constant_text() const;

  /// The attribute with every value (a constant one filled in).
  [[nodiscard]] PointAttribute take() {
    if (!stored_) attribute_.values.assign(count_, first_);
    return std::move(attribute_);
  }

 private:
  static bool same(float a, float b) {
    return std::memcmp(&a, &b, sizeof a) == 0 || (std::isnan(a) && std::isnan(b));
  }

  PointAttribute attribute_;
  std::size_t expected_ = 0;
  std::size_t count_ = 0;
  float first_ = 0.0f;
  bool offset_fixed_ = false;
  bool stored_ = false;
};

/// Moves the columns with values that differ into OUT (in order) and
/// returns "name value" for each constant one, for one warning: a constant
/// colours nothing and would cost 4 bytes a point in every node and cache.
std::vector<std::string> keep_varying(std::vector<AttributeColumn>& columns,
                                      std::vector<PointAttribute>& out);

/// "a, b, c".
std::string join(const std::vector<std::string>& items);

}  // namespace treecut::detail
