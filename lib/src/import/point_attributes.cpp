// What kind of scalar a file's attribute is, by its name (point_set.hpp).
#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <string>

#include "attribute_column.hpp"
#include "treecut/point_set.hpp"

namespace treecut {

AttributeKind attribute_kind_for(std::string_view name) {
  std::string n(name);
  for (char& c : n) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  std::replace(n.begin(), n.end(), ' ', '_');
  // LAS's standard names (as the LAS reader words them) and the usual PLY,
  // PCD and text spellings of labels.
  static constexpr std::array<std::string_view, 19> kCategories = {"classification",
                                                                   "classification_flags",
                                                                   "class",
                                                                   "label",
                                                                   "return_number",
                                                                   "number_of_returns",
                                                                   "user_data",
                                                                   "point_source_id",
                                                                   "scanner_channel",
                                                                   "scan_direction",
                                                                   "edge_of_flight_line",
                                                                   "synthetic",
                                                                   "key_point",
                                                                   "withheld",
                                                                   "overlap",
                                                                   "segment",
                                                                   "segment_id",
                                                                   "instance",
                                                                   "object_id"};
  return std::find(kCategories.begin(), kCategories.end(), n) != kCategories.end()
             ? AttributeKind::category
             : AttributeKind::measure;
}

namespace detail {

AttributeColumn::AttributeColumn(std::string name, std::size_t expected, ValueType type,
                                 double scale, double base, std::optional<double> no_data)
    : expected_(expected) {
  if (name.size() > kMaxAttributeName) name.resize(kMaxAttributeName);
  for (char& c : name) {
    if (static_cast<unsigned char>(c) < 0x20 || c == 0x7f) c = '?';
  }
  attribute_.kind = attribute_kind_for(name);
  attribute_.name = std::move(name);
  attribute_.type = type;
  attribute_.scale = scale;
  attribute_.base = base;
  attribute_.no_data = no_data;
}

// The first COUNT_ values were all FIRST_: stored now, in the form the
// first one takes.
void AttributeColumn::start_varying() {
  varying_ = true;
  const std::size_t n = count_;
  store(first_);
  if (!attribute_.wide.empty()) {
    attribute_.wide.reserve(std::max(expected_, n + 1));
    attribute_.wide.resize(n, attribute_.wide.back());
  } else {
    attribute_.values.reserve(std::max(expected_, n + 1));
    attribute_.values.resize(n, attribute_.values.back());
  }
}

// Below 2^24 a float holds every integer: no offset, so the stored values
// read as the file's; a float field is its own exact value. Past that the
// first value, rounded, so that integers and times near it stay exact.
void AttributeColumn::fix_offset(double value) {
  offset_fixed_ = true;
  const bool small = std::fabs(value) < 16777216.0;
  attribute_.offset = attribute_.type == ValueType::f32 || small ? 0.0 : std::round(value);
}

// A value a float does not give back: every value from now on as a double.
void AttributeColumn::go_wide() {
  wide_ = true;
  std::vector<double>& wide = attribute_.wide;
  wide.reserve(std::max(expected_, attribute_.values.size() + 1));
  for (const float f : attribute_.values) wide.push_back(attribute_.offset + double(f));
  std::vector<float>().swap(attribute_.values);
  attribute_.offset = 0.0;
}

void AttributeColumn::push_back_raw64(std::uint64_t bits) {
  const bool is_unsigned = attribute_.type == ValueType::u64;
  const double raw = is_unsigned ? double(bits) : double(static_cast<std::int64_t>(bits));
  if (!integers_) {
    // A double's integers reach 2^53; decided on the integer, since 2^53 + 1
    // as a double is 2^53.
    constexpr std::int64_t kExact = std::int64_t{1} << 53;
    const auto value = static_cast<std::int64_t>(bits);
    const bool exact =
        is_unsigned ? bits <= std::uint64_t(kExact) : value >= -kExact && value <= kExact;
    const bool unscaled = attribute_.scale == 1.0 && attribute_.base == 0.0;
    if (exact || !unscaled) {
      if (!exact) ++rounded;
      push_back(raw * attribute_.scale + attribute_.base);
      return;
    }
    go_integers();
  }
  attribute_.integers.push_back(static_cast<std::int64_t>(bits));
  ++count_;
}

// A value past 2^53: every value from now on as its integer, those before
// (exact as doubles) converted.
void AttributeColumn::go_integers() {
  integers_ = true;
  const bool is_unsigned = attribute_.type == ValueType::u64;
  std::vector<std::int64_t>& out = attribute_.integers;
  out.reserve(std::max(expected_, count_ + 1));
  for (std::size_t i = 0; i < count_; ++i) {
    const double v = !varying_                    ? first_
                     : !attribute_.values.empty() ? attribute_.offset + double(attribute_.values[i])
                                                  : attribute_.wide[i];
    out.push_back(is_unsigned ? static_cast<std::int64_t>(static_cast<std::uint64_t>(v))
                              : static_cast<std::int64_t>(v));
  }
  std::vector<float>().swap(attribute_.values);
  std::vector<double>().swap(attribute_.wide);
  attribute_.offset = 0.0;
  varying_ = true;
}

PointAttribute AttributeColumn::take() {
  if (!varying_)
    attribute_.constant = count_ == 0 ? std::numeric_limits<double>::quiet_NaN() : first_;
  return std::move(attribute_);
}

void take_columns(std::vector<AttributeColumn>& columns, std::vector<PointAttribute>& out) {
  for (AttributeColumn& c : columns) out.push_back(c.take());
  columns.clear();
}

std::string join(const std::vector<std::string>& items) {
  std::string out;
  for (const std::string& item : items) out += (out.empty() ? "" : ", ") + item;
  return out;
}

std::string join_some(const std::vector<std::string>& items, std::size_t limit) {
  if (items.size() <= limit) return join(items);
  const std::vector<std::string> first(items.begin(),
                                       items.begin() + static_cast<std::ptrdiff_t>(limit));
  return join(first) + " and " + std::to_string(items.size() - limit) + " more";
}

}  // namespace detail

}  // namespace treecut
