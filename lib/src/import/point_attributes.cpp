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

std::vector<std::string> drop_constant_attributes(std::vector<PointAttribute>& attributes) {
  std::vector<std::string> dropped;
  std::erase_if(attributes, [&](const PointAttribute& a) {
    const float* first = nullptr;
    for (const float& v : a.values) {
      if (std::isnan(v)) continue;
      if (first == nullptr) {
        first = &v;
      } else if (v != *first) {
        return false;
      }
    }
    std::ostringstream text;
    text << a.name << " ";
    if (first == nullptr) {
      text << "(none)";
    } else {
      text << std::setprecision(15) << a.offset + double(*first);
    }
    dropped.push_back(text.str());
    return true;
  });
  return dropped;
}

std::string join(const std::vector<std::string>& items) {
  std::string out;
  for (const std::string& item : items) out += (out.empty() ? "" : ", ") + item;
  return out;
}

}  // namespace detail

}  // namespace treecut
