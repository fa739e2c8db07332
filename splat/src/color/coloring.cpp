// Node colours by RGB, elevation or an attribute (treecut/splat/coloring.hpp).
#include "treecut/splat/coloring.hpp"

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <glm/common.hpp>
#include <glm/geometric.hpp>
#include <map>
#include <optional>

#include "treecut/error.hpp"

namespace treecut::splat {

namespace {

// Viridis at nine evenly spaced stops (matplotlib's table, sRGB); linear
// between them is within 2 of the full 256-entry table.
constexpr std::array<glm::u8vec3, 9> kViridis = {{{68, 1, 84},
                                                  {71, 44, 122},
                                                  {59, 81, 139},
                                                  {44, 113, 142},
                                                  {33, 144, 141},
                                                  {39, 173, 129},
                                                  {92, 200, 99},
                                                  {170, 220, 50},
                                                  {253, 231, 37}}};

struct AsprsClass {
  const char* name;
  glm::u8vec3 color;
};
// LAS 1.4 R15, table 17 (classes 0-18).
constexpr std::array<AsprsClass, 19> kAsprs = {{
    {"never classified", {150, 150, 150}},
    {"unclassified", {190, 190, 190}},
    {"ground", {170, 125, 80}},
    {"low vegetation", {150, 220, 90}},
    {"medium vegetation", {60, 180, 60}},
    {"high vegetation", {20, 110, 40}},
    {"building", {220, 60, 60}},
    {"low point (noise)", {230, 40, 200}},
    {"model key-point", {250, 60, 60}},
    {"water", {40, 110, 230}},
    {"rail", {120, 70, 40}},
    {"road surface", {90, 90, 100}},
    {"overlap", {250, 230, 60}},
    {"wire - guard", {255, 200, 220}},
    {"wire - conductor", {255, 160, 190}},
    {"transmission tower", {130, 40, 160}},
    {"wire connector", {200, 120, 255}},
    {"bridge deck", {210, 190, 150}},
    {"high noise", {255, 0, 120}},
}};

// Ten distinct colours (matplotlib's tab10) for categories without a palette.
constexpr std::array<glm::u8vec3, 10> kDistinct = {{{31, 119, 180},
                                                    {255, 127, 14},
                                                    {44, 160, 44},
                                                    {214, 39, 40},
                                                    {148, 103, 189},
                                                    {140, 86, 75},
                                                    {227, 119, 194},
                                                    {127, 127, 127},
                                                    {188, 189, 34},
                                                    {23, 190, 207}}};

constexpr glm::u8vec4 kNoValue{128, 128, 128, 255};

// At most ~64k leaves, spread over the nodes: the percentiles of a
// continuous map from them.
std::vector<NodeId> sample_leaves(const Hierarchy& h) {
  const std::size_t n = h.node_count();
  const std::size_t stride = std::max<std::size_t>(1, n / 65536);
  std::vector<NodeId> out;
  out.reserve(n / stride + 1);
  for (std::size_t i = 0; i < n; i += stride) {
    if (h.is_leaf(static_cast<NodeId>(i))) out.push_back(static_cast<NodeId>(i));
  }
  return out;
}

// The Q-quantile of VALUES (finite ones; reorders them).
double quantile(std::vector<double>& values, double q) {
  if (values.empty()) return 0.0;
  const auto k = static_cast<std::size_t>(q * double(values.size() - 1) + 0.5);
  std::nth_element(values.begin(), values.begin() + static_cast<std::ptrdiff_t>(k), values.end());
  return values[k];
}

int class_of(float v) {
  return std::isnan(v) ? -1 : static_cast<int>(std::lround(v));
}

bool contains(const std::vector<int>& list, int value) {
  return std::find(list.begin(), list.end(), value) != list.end();
}

std::string attribute_names(const Hierarchy& h) {
  std::string names = "rgb, elevation";
  for (const NodeAttribute& a : h.attributes()) names += ", " + a.name;
  return names;
}

}  // namespace

bool class_hidden(const ColorBy& by, int value) {
  return by.show_classes.empty() ? contains(by.hide_classes, value)
                                 : !contains(by.show_classes, value);
}

std::string_view color_map_name(ColorMap map) {
  switch (map) {
    case ColorMap::automatic:
      return "auto";
    case ColorMap::viridis:
      return "viridis";
    case ColorMap::grey:
      return "grey";
    case ColorMap::classes:
      return "classes";
  }
  return "auto";
}

ColorMap parse_color_map(std::string_view name) {
  if (name == "auto") return ColorMap::automatic;
  if (name == "viridis") return ColorMap::viridis;
  if (name == "grey" || name == "gray") return ColorMap::grey;
  if (name == "classes") return ColorMap::classes;
  throw InputError("unknown colour map '" + std::string(name) +
                   "' (auto, viridis, grey or classes)");
}

void parse_class_filter(std::string_view text, ColorBy& by) {
  by.show_classes.clear();
  by.hide_classes.clear();
  std::size_t at = 0;
  while (at <= text.size()) {
    const std::size_t end = std::min(text.find(',', at), text.size());
    std::string_view item = text.substr(at, end - at);
    const bool hide = !item.empty() && item.front() == '-';
    if (hide) item.remove_prefix(1);
    int value = -1;
    const auto [p, ec] = std::from_chars(item.data(), item.data() + item.size(), value);
    if (item.empty() || ec != std::errc() || p != item.data() + item.size() || value < 0 ||
        value > 255) {
      throw InputError("--classes '" + std::string(text) +
                       "': expected class numbers 0-255, e.g. 2,6 (show only those) or -7,-18 "
                       "(hide those)");
    }
    (hide ? by.hide_classes : by.show_classes).push_back(value);
    at = end + 1;
  }
  if (!by.show_classes.empty() && !by.hide_classes.empty()) {
    throw InputError("--classes '" + std::string(text) +
                     "': either classes to show (2,6) or classes to hide (-7,-18), not both");
  }
}

glm::u8vec4 map_color(ColorMap map, float t) {
  t = std::isnan(t) ? 0.5f : std::clamp(t, 0.0f, 1.0f);
  if (map == ColorMap::grey) {
    const auto g = static_cast<std::uint8_t>(std::lround(30.0f + 225.0f * t));
    return {g, g, g, 255};
  }
  const float x = t * float(kViridis.size() - 1);
  const auto i = std::min<std::size_t>(static_cast<std::size_t>(x), kViridis.size() - 2);
  const glm::vec3 c = glm::mix(glm::vec3(kViridis[i]), glm::vec3(kViridis[i + 1]), x - float(i));
  return {glm::u8vec3(glm::round(c)), 255};
}

glm::u8vec4 category_color(int value, bool asprs) {
  if (asprs && value >= 0 && value < static_cast<int>(kAsprs.size())) {
    return {kAsprs[static_cast<std::size_t>(value)].color, 255};
  }
  const auto k = static_cast<std::size_t>(((value % 10) + 10) % 10);
  return {kDistinct[k], 255};
}

std::string_view asprs_class_name(int value) {
  if (value < 0 || value >= static_cast<int>(kAsprs.size())) return {};
  return kAsprs[static_cast<std::size_t>(value)].name;
}

ColorBy resolve_auto_color(const Hierarchy& h, ColorBy by, std::string* note,
                           std::span<const NodeId> leaves) {
  if (note) note->clear();
  if (by.source != "auto") return by;
  // The leaves' colours are the points': the RGB is usable where two differ.
  const auto& color = h.arrays().color;
  const auto& child_count = h.arrays().child_count;
  std::optional<glm::u8vec4> first;
  bool varies = false;
  const auto look = [&](NodeId n) {
    if (!first) first = color[n];
    varies = color[n] != *first;
  };
  for (std::size_t i = 0; i < leaves.size() && !varies; ++i) look(leaves[i]);
  for (std::size_t n = 0; leaves.empty() && n < h.node_count() && !varies; ++n) {
    if (child_count[n] == 0) look(static_cast<NodeId>(n));
  }
  if (varies) {
    by.source = "rgb";
    return by;
  }
  const NodeAttribute* intensity = h.find_attribute("intensity");
  by.source = intensity && !intensity->is_constant() && intensity->min < intensity->max
                  ? "intensity"
                  : "elevation";
  if (note) {
    char what[64] = "none in the file";
    if (first && *first != kUncoloured)
      std::snprintf(what, sizeof what, "every point %d %d %d", first->x, first->y, first->z);
    *note = std::string("no usable RGB (") + what + "): coloured by " + by.source;
  }
  return by;
}

void check_color_by(const Hierarchy& h, const ColorBy& by) {
  if (by.source != "rgb" && by.source != "elevation" && by.source != "auto" &&
      h.find_attribute(by.source) == nullptr) {
    throw InputError("--color '" + by.source + "': the model has no such attribute (it has " +
                     attribute_names(h) + ")");
  }
  if ((!by.show_classes.empty() || !by.hide_classes.empty()) &&
      h.find_attribute("classification") == nullptr) {
    throw InputError("--classes: the model has no classification attribute (it has " +
                     attribute_names(h) + ")");
  }
}

NodeColoring::NodeColoring(const Hierarchy& h, const ColorBy& by, glm::vec3 up,
                           std::span<const NodeId> sample, bool partial)
    : h_(&h), by_(by), up_(up) {
  check_color_by(h, by);
  legend_.title = by.source;
  if (filtered()) classification_ = h.find_attribute("classification");
  if (by.source != "rgb") {
    // A continuous source's values at the sample, relative to its offset to
    // the file's.
    std::vector<double> finite;
    finite.reserve(sample.size());
    const auto take = [&](float x) {
      if (std::isfinite(x)) finite.push_back(double(x));
    };
    double offset = 0.0;
    // The points' extremes (relative), for a model known in part.
    double least = NAN, most = NAN;
    if (by.source == "elevation") {
      kind_ = Kind::elevation;
      for (const NodeId n : sample) take(glm::dot(h.center(n), up));
      offset = glm::dot(h.frame().origin, glm::dvec3(up));
      const glm::vec3 lo = h.bounds_min(), hi = h.bounds_max();
      for (int c = 0; c < 8; ++c) {
        const glm::vec3 corner(c & 1 ? hi.x : lo.x, c & 2 ? hi.y : lo.y, c & 4 ? hi.z : lo.z);
        const double e = glm::dot(corner, up);
        least = c == 0 ? e : std::min(least, e);
        most = c == 0 ? e : std::max(most, e);
      }
    } else {
      source_ = h.find_attribute(by.source);
      const bool category = source_->kind == AttributeKind::category;
      const ColorMap map = by.map != ColorMap::automatic ? by.map
                           : category                    ? ColorMap::classes
                                                         : ColorMap::viridis;
      if (category && !by.low && !by.high) {
        kind_ = Kind::category;
        asprs_ = source_->name == "classification" && source_->offset == 0.0;
        legend_.map = map;
        legend_.continuous = false;
        count_categories(sample, partial);
      } else {
        kind_ = Kind::measure;
        by_.map = map == ColorMap::classes ? ColorMap::viridis : map;
        for (const NodeId n : sample) take(source_->value(n));
        offset = source_->offset;
        least = source_->min - offset, most = source_->max - offset;
      }
    }
    if (kind_ != Kind::category) {
      // Known in part: the sample's coarse nodes average their points
      // (their percentiles spanned 631-1707 of a survey tile's intensity,
      // the points' 307-2345), so the points' extremes (160-2400) instead.
      const bool extremes = partial && std::isfinite(least) && std::isfinite(most);
      double lo = by.low ? *by.low - offset : extremes ? least : quantile(finite, 0.02);
      double hi = by.high ? *by.high - offset : extremes ? most : quantile(finite, 0.98);
      if (!(hi > lo)) lo -= 0.5, hi += 0.5;  // one value: the middle of the map
      legend_.map = by_.map == ColorMap::automatic || by_.map == ColorMap::classes
                        ? ColorMap::viridis
                        : by_.map;
      legend_.continuous = true;
      legend_.low = lo + offset;
      legend_.high = hi + offset;
      low_ = lo;
      scale_ = 1.0 / (hi - lo);
    }
  }
  if (filtered() && legend_.title == "classification") {
    for (Legend::Entry& e : legend_.entries) {
      e.hidden = class_hidden(by_, std::isnan(e.value) ? -1 : static_cast<int>(e.value));
    }
  }
}

// The shares are counted over every leaf (the points), exact: a sample of
// node ids gave 77.1 / 22.9 % for a file of 76.27 / 23.73. A model known in
// part lists the categories of its known leaves, uncounted: they are modes
// of their children (a survey tile's root page: 93.8 % ground by points,
// the points 42.8 %), and the categories found only further down are
// missing.
void NodeColoring::count_categories(std::span<const NodeId> sample, bool partial) {
  const NodeAttribute& a = *source_;
  const HierarchyArrays& arrays = h_->arrays();
  std::map<int, double> counts;
  const double total = partial ? NAN : std::max<std::uint32_t>(h_->leaf_count(), 1);
  if (a.is_constant()) {
    counts[class_of(a.constant)] = h_->leaf_count();
  } else if (!partial) {
    for (std::size_t n = 0; n < h_->node_count(); ++n) {
      if (arrays.child_count[n] == 0) ++counts[class_of(a.values[n])];
    }
  } else {
    // By the points the known leaves hold: the legend's order.
    for (const NodeId n : sample) counts[class_of(a.values[n])] += arrays.point_count[n];
  }
  std::vector<std::pair<double, int>> by_share;
  for (const auto& [c, count] : counts) by_share.emplace_back(count, c);
  std::sort(by_share.begin(), by_share.end(), std::greater<>());
  if (by_share.size() > 32) by_share.resize(32);
  for (const auto& [count, c] : by_share) {
    Legend::Entry e;
    const double value = c < 0 ? NAN : double(c) + a.offset;
    e.value = value;
    e.label = c < 0 ? "no value" : std::to_string(static_cast<long long>(value));
    if (asprs_ && c >= 0 && !asprs_class_name(c).empty())
      e.label += " " + std::string(asprs_class_name(c));
    e.color = category(c < 0 ? NAN : static_cast<float>(c));
    e.share = count / total;
    legend_.entries.push_back(e);
  }
  std::sort(legend_.entries.begin(), legend_.entries.end(),
            [](const Legend::Entry& l, const Legend::Entry& r) {
              return std::isnan(r.value) || (!std::isnan(l.value) && l.value < r.value);
            });
}

// A category's colour: V is the node's value relative to the offset, as stored.
glm::u8vec4 NodeColoring::category(float v) const {
  const NodeAttribute& a = *source_;
  if (std::isnan(v)) return kNoValue;
  if (legend_.map == ColorMap::classes)
    return category_color(class_of(v) + static_cast<int>(a.offset), asprs_);
  const double x = a.offset + double(v);
  return map_color(legend_.map,
                   a.max > a.min ? static_cast<float>((x - a.min) / (a.max - a.min)) : 0.5f);
}

bool NodeColoring::hidden(NodeId n) const {
  return filtered() && class_hidden(by_, class_of(classification_->value(n)));
}

glm::u8vec4 NodeColoring::operator()(NodeId n) const {
  glm::u8vec4 c;
  float x = 0.0f;
  switch (kind_) {
    case Kind::own:
      c = h_->arrays().color[n];
      break;
    case Kind::category:
      c = category(source_->value(n));
      break;
    case Kind::elevation:
    case Kind::measure:
      x = kind_ == Kind::elevation ? glm::dot(h_->center(n), up_) : source_->value(n);
      c = std::isnan(x) ? kNoValue
                        : map_color(legend_.map, static_cast<float>((double(x) - low_) * scale_));
      break;
  }
  if (hidden(n)) c.w = 0;
  return c;
}

Coloring color_nodes(const Hierarchy& h, const ColorBy& by, glm::vec3 up) {
  const NodeColoring rule(h, by, up, sample_leaves(h), false);
  Coloring out;
  out.colors.resize(h.node_count());
  for (std::size_t n = 0; n < h.node_count(); ++n) {
    out.colors[n] = rule(static_cast<NodeId>(n));
    out.hidden_nodes += rule.hidden(static_cast<NodeId>(n));
  }
  out.legend = rule.legend();
  return out;
}

}  // namespace treecut::splat
