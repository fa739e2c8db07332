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

// A continuous source's value per node (relative) and its offset to the file's.
struct Values {
  std::vector<float> own;           // elevation: computed here
  std::span<const float> of_nodes;  // the attribute's, or `own`
  double offset = 0.0;
};

void color_continuous(const Hierarchy& h, const ColorBy& by, const Values& v,
                      std::span<const NodeId> sample, Coloring& out) {
  std::vector<double> finite;
  finite.reserve(sample.size());
  for (const NodeId n : sample) {
    if (std::isfinite(v.of_nodes[n])) finite.push_back(double(v.of_nodes[n]));
  }
  double lo = by.low ? *by.low - v.offset : quantile(finite, 0.02);
  double hi = by.high ? *by.high - v.offset : quantile(finite, 0.98);
  if (!(hi > lo)) lo -= 0.5, hi += 0.5;  // one value: the middle of the map
  Legend& legend = out.legend;
  legend.map =
      by.map == ColorMap::automatic || by.map == ColorMap::classes ? ColorMap::viridis : by.map;
  legend.continuous = true;
  legend.low = lo + v.offset;
  legend.high = hi + v.offset;
  const double scale = 1.0 / (hi - lo);
  for (std::size_t n = 0; n < h.node_count(); ++n) {
    const float x = v.of_nodes[n];
    out.colors[n] = std::isnan(x)
                        ? kNoValue
                        : map_color(legend.map, static_cast<float>((double(x) - lo) * scale));
  }
}

// The legend's shares are counted over every leaf (the points), exact: a
// sample of node ids gave 77.1 / 22.9 % for a file of 76.27 / 23.73.
void color_categories(const Hierarchy& h, const NodeAttribute& a, ColorMap map, Coloring& out) {
  const bool asprs = a.name == "classification" && a.offset == 0.0;
  // The node's value relative to the offset, as stored.
  auto color_of = [&](float v) {
    if (std::isnan(v)) return kNoValue;
    if (map == ColorMap::classes)
      return category_color(class_of(v) + static_cast<int>(a.offset), asprs);
    const double x = a.offset + double(v);
    return map_color(map, a.max > a.min ? static_cast<float>((x - a.min) / (a.max - a.min)) : 0.5f);
  };
  std::map<int, std::size_t> counts;
  const auto& child_count = h.arrays().child_count;
  if (a.is_constant()) {
    counts[class_of(a.constant)] = h.leaf_count();
  } else {
    for (std::size_t n = 0; n < h.node_count(); ++n) {
      if (child_count[n] == 0) ++counts[class_of(a.values[n])];
    }
  }
  for (std::size_t n = 0; n < h.node_count(); ++n)
    out.colors[n] = color_of(a.value(static_cast<NodeId>(n)));
  Legend& legend = out.legend;
  legend.map = map;
  legend.continuous = false;
  std::vector<std::pair<std::size_t, int>> by_share;
  for (const auto& [c, count] : counts) by_share.emplace_back(count, c);
  std::sort(by_share.begin(), by_share.end(), std::greater<>());
  if (by_share.size() > 32) by_share.resize(32);
  for (const auto& [count, c] : by_share) {
    Legend::Entry e;
    const double value = c < 0 ? NAN : double(c) + a.offset;
    e.value = value;
    e.label = c < 0 ? "no value" : std::to_string(static_cast<long long>(value));
    if (asprs && c >= 0 && !asprs_class_name(c).empty())
      e.label += " " + std::string(asprs_class_name(c));
    e.color = color_of(c < 0 ? NAN : static_cast<float>(c));
    e.share = double(count) / double(std::max<std::uint32_t>(h.leaf_count(), 1));
    legend.entries.push_back(e);
  }
  std::sort(legend.entries.begin(), legend.entries.end(),
            [](const Legend::Entry& l, const Legend::Entry& r) {
              return std::isnan(r.value) || (!std::isnan(l.value) && l.value < r.value);
            });
}

void hide_classes(const Hierarchy& h, const ColorBy& by, Coloring& out) {
  if (by.show_classes.empty() && by.hide_classes.empty()) return;
  const NodeAttribute* cls = h.find_attribute("classification");
  for (std::size_t n = 0; n < h.node_count(); ++n) {
    const int c = class_of(cls->value(static_cast<NodeId>(n)));
    if (class_hidden(by, c)) {
      out.colors[n].w = 0, ++out.hidden_nodes;
    }
  }
  if (out.legend.title == "classification") {
    for (Legend::Entry& e : out.legend.entries) {
      const int c = std::isnan(e.value) ? -1 : static_cast<int>(e.value);
      e.hidden = class_hidden(by, c);
    }
  }
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

ColorBy resolve_auto_color(const Hierarchy& h, ColorBy by, std::string* note) {
  if (note) note->clear();
  if (by.source != "auto") return by;
  // The leaves' colours are the points': the RGB is usable where two differ.
  const auto& color = h.arrays().color;
  const auto& child_count = h.arrays().child_count;
  std::optional<glm::u8vec4> first;
  bool varies = false;
  for (std::size_t n = 0; n < h.node_count() && !varies; ++n) {
    if (child_count[n] != 0) continue;
    if (!first) first = color[n];
    varies = color[n] != *first;
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

Coloring color_nodes(const Hierarchy& h, const ColorBy& by, glm::vec3 up) {
  check_color_by(h, by);
  Coloring out;
  const auto& arrays = h.arrays();
  out.colors.assign(arrays.color.begin(), arrays.color.end());
  out.legend.title = by.source;
  const std::vector<NodeId> sample = sample_leaves(h);
  if (by.source == "elevation") {
    Values v;
    v.own.resize(h.node_count());
    for (std::size_t n = 0; n < h.node_count(); ++n) {
      v.own[n] = glm::dot(h.center(static_cast<NodeId>(n)), up);
    }
    v.of_nodes = v.own;
    v.offset = glm::dot(h.frame().origin, glm::dvec3(up));
    color_continuous(h, by, v, sample, out);
  } else if (by.source != "rgb") {
    const NodeAttribute* a = h.find_attribute(by.source);
    const bool category = a->kind == AttributeKind::category;
    const ColorMap map = by.map != ColorMap::automatic ? by.map
                         : category                    ? ColorMap::classes
                                                       : ColorMap::viridis;
    if (category && !by.low && !by.high) {
      color_categories(h, *a, map, out);
    } else {
      Values v;
      if (a->is_constant()) v.own.assign(h.node_count(), a->constant);
      v.of_nodes = a->is_constant() ? std::span<const float>(v.own) : a->values;
      v.offset = a->offset;
      ColorBy continuous = by;
      continuous.map = map == ColorMap::classes ? ColorMap::viridis : map;
      color_continuous(h, continuous, v, sample, out);
    }
  }
  hide_classes(h, by, out);
  return out;
}

}  // namespace treecut::splat
