// What kind of scalar a file's attribute is, by its name (point_set.hpp).
#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <iomanip>
#include <sstream>
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

std::string AttributeColumn::constant_text() const {
  std::ostringstream text;
  text << attribute_.name << " ";
  if (count_ == 0 || std::isnan(first_)) {
    text << "(none)";
  } else {
    text << std::setprecision(15) << attribute_.offset + double(first_);
  }
  return text.str();
}

std::vector<std::string> keep_varying(std::vector<AttributeColumn>& columns,
                                      std::vector<PointAttribute>& out) {
  std::vector<std::string> constant;
  for (AttributeColumn& c : columns) {
    if (c.constant()) {
      constant.push_back(c.constant_text());
    } else {
      out.push_back(c.take());
    }
  }
  columns.clear();
  return constant;
}

std::string join(const std::vector<std::string>& items) {
  std::string out;
  for (const std::string& item : items) out += (out.empty() ? "" : ", ") + item;
  return out;
}

}  // namespace detail

}  // namespace treecut
