// The readers' way to keep a per-point scalar (PointSet::attributes): values
// arrive as doubles (the file's, scaled) in point order and are kept at the
// precision of the file's type (issue 43): as floats relative to an offset
// the first value fixes while every float gives its value back exactly
// (classes, intensities, a float field), else as doubles (a GPS time, a
// double extra-bytes field of 1e300), and a column with one value at every
// point as that value alone.
//
// Nothing is stored while every value is the same: a LAS record has a dozen
// fields, of which a file often fills half with one value (user data 0,
// point source 1); stored per point they would cost 4 bytes a point each,
// touched twice (the 20 M-point LAS read took 4.6 s instead of 1.3 s when
// every field was stored). The values are stored from the first one that
// differs.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstring>
#include <limits>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "treecut/point_set.hpp"

namespace treecut::detail {

class AttributeColumn {
 public:
  /// NAME is cut to kMaxAttributeName bytes, control bytes made '?'.
  /// EXPECTED: the points to come (reserved once the values differ). TYPE,
  /// SCALE, BASE, NO_DATA: how the file encodes a value (PointAttribute).
  AttributeColumn(std::string name, std::size_t expected, ValueType type = ValueType::f64,
                  double scale = 1.0, double base = 0.0, std::optional<double> no_data = {});

  /// The next point's value (the file's; not finite: no value).
  void push_back(double value) {
    if (!std::isfinite(value)) value = std::numeric_limits<double>::quiet_NaN();
    if (!varying_) {
      if (count_ == 0 || same(value, first_)) {
        if (count_++ == 0) first_ = value;
        return;
      }
      start_varying();
    }
    store(value);
    ++count_;
  }

  /// The next point's raw value of a 64-bit integer field (a u64's bits):
  /// as push_back while a double holds every one exactly, then every value
  /// as its integer (PointAttribute::integers), where the field is unscaled.
  void push_back_raw64(std::uint64_t bits);

  /// The attribute (a constant one as its value alone).
  [[nodiscard]] PointAttribute take();

  /// Values of a 64-bit integer field past 2^53 that a double rounded (a
  /// scaled field's; named in a warning by the reader).
  std::size_t rounded = 0;

 private:
  static bool same(double a, double b) {
    return std::memcmp(&a, &b, sizeof a) == 0 || (std::isnan(a) && std::isnan(b));
  }
  void start_varying();
  void store(double value) {
    if (!attribute_.wide.empty() || wide_) {
      attribute_.wide.push_back(value);
      return;
    }
    if (std::isnan(value)) {
      attribute_.values.push_back(std::numeric_limits<float>::quiet_NaN());
      return;
    }
    if (!offset_fixed_) fix_offset(value);
    const double relative = value - attribute_.offset;
    const auto f = static_cast<float>(relative);
    if (std::fabs(relative) <= double(std::numeric_limits<float>::max()) &&
        attribute_.offset + double(f) == value) {
      attribute_.values.push_back(f);
    } else {
      go_wide();
      attribute_.wide.push_back(value);
    }
  }
  void fix_offset(double value);
  void go_wide();
  void go_integers();

  PointAttribute attribute_;
  std::size_t expected_ = 0;
  std::size_t count_ = 0;
  double first_ = 0.0;
  bool varying_ = false;
  bool offset_fixed_ = false;
  bool wide_ = false;
  bool integers_ = false;
};

/// Moves every column into OUT, in order.
void take_columns(std::vector<AttributeColumn>& columns, std::vector<PointAttribute>& out);

/// "a, b, c".
std::string join(const std::vector<std::string>& items);

/// One warning's text for long lists: the first LIMIT items, then "and N
/// more" (a file may name millions of columns).
std::string join_some(const std::vector<std::string>& items, std::size_t limit = 8);

}  // namespace treecut::detail
