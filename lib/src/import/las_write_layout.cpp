// What a LAS export writes (las_write_layout.hpp): the grid of the integer
// coordinates, the point format and fields, each standard field checked to
// fit (LAS 1.2 and LAS 1.4 R15, tables of the point data record formats).
#include "las_write_layout.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <string>
#include <utility>

#include "treecut/error.hpp"
#include "treecut/file_io.hpp"
#include "typed_values.hpp"

namespace treecut::las_layout {

namespace {

// Point I in the file's coordinates: exact where the reader kept them.
glm::dvec3 file_position(const PointSet& points, std::size_t i) {
  return points.exact_positions.empty() ? points.frame.origin + glm::dvec3(points.positions[i])
                                        : points.exact_positions[i];
}

// The coarsest power of ten (1 to 1e-9) of which every exact coordinate
// on AXIS is a multiple, to the last bits of a double (a PLY or text cloud
// of centimetres: 0.01); 0 when none is.
double decimal_resolution(const std::vector<glm::dvec3>& exact, int axis) {
  for (int k = 0; k <= 9; ++k) {
    const double step = std::pow(10.0, -k);
    bool all = true;
    for (std::size_t i = 0; i < exact.size() && all; ++i) {
      const double v = exact[i][axis];
      const double tolerance = 8.0 * (std::nextafter(std::fabs(v), INFINITY) - std::fabs(v));
      all = std::fabs(v - std::round(v / step) * step) <= tolerance;
    }
    if (all) return step;
  }
  return 0.0;
}

// The scale when none is given: the file's own grid, else the decimal
// resolution of its exact coordinates, else the finest power of ten that
// the float positions resolve (half their spacing at the farthest point),
// so a round trip loses nothing the file held.
double automatic_scale(const PointSet& points, int axis) {
  if (points.frame.resolution[axis] > 0.0) return points.frame.resolution[axis];
  if (!points.exact_positions.empty()) {
    if (const double step = decimal_resolution(points.exact_positions, axis); step > 0.0)
      return step;
  }
  float reach = 0.0f;
  for (const glm::vec3& p : points.positions) reach = std::max(reach, std::fabs(p[axis]));
  const double spacing = double(std::nextafter(reach, INFINITY) - reach);
  return std::clamp(std::pow(10.0, std::floor(std::log10(0.5 * spacing))), 1e-9, 1.0);
}

}  // namespace

// The scale and offset: the file's own grid where it has one and it still
// reaches every point, so the same integers are written; otherwise the
// centre of the points' bounds in whole scale steps, so the integers are
// small. Checked to fit 32 bits.
Grid grid_of(const std::filesystem::path& path, const PointSet& points, double scale) {
  Grid g;
  glm::dvec3 lo(std::numeric_limits<double>::max()), hi(std::numeric_limits<double>::lowest());
  for (std::size_t i = 0; i < points.size(); ++i) {
    const glm::dvec3 q = file_position(points, i);
    lo = glm::min(lo, q), hi = glm::max(hi, q);
  }
  for (int a = 0; a < 3; ++a) {
    g.scale[a] = scale > 0.0 ? scale : automatic_scale(points, a);
    // A scale that cannot reach across the points in 2^31 steps is coarsened.
    while (scale == 0.0 && !points.positions.empty() &&
           std::max(hi[a] - lo[a], 0.0) / g.scale[a] >= 2147483647.0 && g.scale[a] < 1e6)
      g.scale[a] *= 10.0;
  }
  if (points.positions.empty()) return g;
  g.offset = glm::round(0.5 * (lo + hi) / g.scale) * g.scale;
  for (int a = 0; a < 3; ++a) {
    const double own = points.frame.grid_offset[a];
    const bool same_grid = points.frame.resolution[a] == g.scale[a] && std::isfinite(own);
    if (same_grid && std::max(hi[a] - own, own - lo[a]) / g.scale[a] < 2147483647.0)
      g.offset[a] = own;
    const double reach = std::max(hi[a] - g.offset[a], g.offset[a] - lo[a]) / g.scale[a];
    if (!(reach < 2147483647.0)) {
      char scale_text[32];
      std::snprintf(scale_text, sizeof scale_text, "%g", g.scale[a]);
      throw InputError(quoted_name(path) + ": the points span more than 2^31 steps of the scale " +
                       scale_text + " on the " + "xyz"[a] +
                       " axis, more than a LAS file's 32-bit coordinates hold");
    }
  }
  return g;
}

std::array<std::int32_t, 3> integers(const PointSet& points, std::size_t i, const Grid& g) {
  const glm::dvec3 q = file_position(points, i);
  std::array<std::int32_t, 3> xyz{};
  for (int a = 0; a < 3; ++a) {
    xyz[static_cast<std::size_t>(a)] =
        static_cast<std::int32_t>(std::llround((q[a] - g.offset[a]) / g.scale[a]));
  }
  return xyz;
}

namespace {

// Whether some value of A (the file's) passes TEST.
template <class Test>
bool any_value(const PointAttribute* a, std::size_t n, Test&& test) {
  if (a == nullptr) return false;
  if (a->is_constant()) return n > 0 && test(a->constant);
  for (std::size_t i = 0; i < n; ++i) {
    if (test(a->value(i))) return true;
  }
  return false;
}

bool whole(double v) {
  return std::isnan(v) || v == std::round(v);
}

// Format 6 and up when a field needs what only they hold.
bool needs_extended(const Layout& l, std::size_t n) {
  if (l.scanner_channel != nullptr || l.nir != nullptr) return true;
  auto above = [&](const PointAttribute* a, double limit) {
    return any_value(a, n, [&](double v) { return v > limit; });
  };
  const bool overlap = any_value(
      l.flags, n, [](double v) { return !std::isnan(v) && (static_cast<long long>(v) & 8) != 0; });
  const bool fine_angle =
      any_value(l.scan_angle, n, [](double v) { return !whole(v) || v < -128.0 || v > 127.0; });
  return above(l.classification, 31) || above(l.return_number, 7) ||
         above(l.number_of_returns, 7) || overlap || fine_angle;
}

// The type an extra-bytes field is written in: its own, or a double where
// an integer type would have to hold no value (NaN) without a no-data value.
ValueType extra_type(const PointAttribute& a, std::size_t n) {
  if (!is_integer(a.type) || a.no_data) return a.type;
  return detail::has_missing(a, n) ? ValueType::f64 : a.type;
}

}  // namespace

Layout layout_of(const PointSet& points, std::vector<PointAttribute>& widened) {
  Layout l;
  l.rgb = points.has_colors();
  const std::pair<const char*, const PointAttribute**> standard[] = {
      {"intensity", &l.intensity},
      {"return_number", &l.return_number},
      {"number_of_returns", &l.number_of_returns},
      {"scan_direction", &l.scan_direction},
      {"edge_of_flight_line", &l.edge},
      {"classification", &l.classification},
      {"classification_flags", &l.flags},
      {"scan_angle", &l.scan_angle},
      {"user_data", &l.user_data},
      {"point_source_id", &l.point_source_id},
      {"gps_time", &l.gps_time},
      {"scanner_channel", &l.scanner_channel},
      {"nir", &l.nir}};
  const std::size_t n = points.size();
  std::vector<const PointAttribute*> extra;
  for (const PointAttribute& a : points.attributes) {
    if (!a.is_constant() && a.stored() != n) {
      throw std::invalid_argument("save_las: attribute " + a.name + " has " +
                                  std::to_string(a.stored()) + " values for " + std::to_string(n) +
                                  " points");
    }
    bool placed = false;
    for (const auto& [name, slot] : standard) {
      if (a.name == name && *slot == nullptr) *slot = &a, placed = true;
    }
    if (!placed) extra.push_back(&a);
  }
  // NIR has its slot only beside RGB (format 8); without RGB it is an extra field.
  if (l.nir != nullptr && !l.rgb) extra.push_back(l.nir), l.nir = nullptr;
  l.format = needs_extended(l, n) ? (l.nir   ? 8
                                     : l.rgb ? 7
                                             : 6)
                                  : (l.gps_time ? 1 : 0) + (l.rgb ? 2 : 0);
  widened.reserve(extra.size());
  for (const PointAttribute* a : extra) {
    const ValueType t = extra_type(*a, n);
    if (t == a->type) {
      l.extra.push_back(a);
      continue;
    }
    // Written as doubles: a copy that says so, sharing nothing but the values.
    PointAttribute& w = widened.emplace_back(*a);
    w.type = t, w.scale = 1.0, w.base = 0.0;
    l.extra.push_back(&w);
  }
  if (l.record_length() > 65535 || l.extra.size() > 340)
    throw std::invalid_argument("save_las: more extra bytes than a LAS record holds");
  return l;
}

// A standard field's values must fit its slot in the chosen format (a text
// cloud's intensity of -2048 or 0.5, a class of 256): a value that does not
// is refused, naming the file, the field and what LAS holds there, rather
// than clamped or rounded without a word; PLY and PCD hold it as it is.
void check_standard_fields(const std::filesystem::path& path, const Layout& l, std::size_t n) {
  const bool ext = l.extended();
  struct Slot {
    const PointAttribute* a;
    double lo, hi, step;  // step 0: any finite value
  };
  const Slot slots[] = {
      {l.intensity, 0, 65535, 1},
      {l.return_number, 0, ext ? 15.0 : 7.0, 1},
      {l.number_of_returns, 0, ext ? 15.0 : 7.0, 1},
      {l.scan_direction, 0, 1, 1},
      {l.edge, 0, 1, 1},
      {l.classification, 0, ext ? 255.0 : 31.0, 1},
      {l.flags, 0, ext ? 15.0 : 7.0, 1},
      {l.scan_angle, ext ? -32768 * 0.006 : -128.0, ext ? 32767 * 0.006 : 127.0, ext ? 0.006 : 1.0},
      {l.user_data, 0, 255, 1},
      {l.point_source_id, 0, 65535, 1},
      {l.gps_time, -1.7e308, 1.7e308, 0},
      {l.scanner_channel, 0, 3, 1},
      {l.nir, 0, 65535, 1}};
  for (const Slot& s : slots) {
    if (s.a == nullptr) continue;
    double bad = 0.0;
    const bool found = any_value(s.a, n, [&](double v) {
      const double steps = s.step > 0.0 ? v / s.step : 0.0;
      const bool fits = v >= s.lo && v <= s.hi &&
                        (s.step == 0.0 || std::fabs(steps - std::round(steps)) <=
                                              1e-9 * std::max(1.0, std::fabs(steps)));
      if (!fits) bad = v;
      return !fits;  // NaN fits nothing: LAS's standard fields always hold a value
    });
    if (!found) continue;
    char what[160];
    std::snprintf(what, sizeof what, "%s %.17g does not fit LAS's %s (%s from %g to %g)",
                  s.a->name.c_str(), bad, s.a->name.c_str(),
                  s.step == 1.0  ? "whole numbers"
                  : s.step > 0.0 ? "steps of 0.006"
                                 : "numbers",
                  s.lo, s.hi);
    throw InputError(quoted_name(path) + ": " + what +
                     "; export to .ply or .pcd, which hold it as it is");
  }
}

// The file's value of attribute A at point I as an integer in [lo, hi] in
// units of UNIT (NaN, no value: 0).
std::int64_t integer_value(const PointAttribute* a, std::size_t i, std::int64_t lo, std::int64_t hi,
                           double unit) {
  if (a == nullptr) return 0;
  const double v = a->value(i);
  if (std::isnan(v)) return 0;
  return static_cast<std::int64_t>(std::clamp(std::round(v / unit), double(lo), double(hi)));
}

}  // namespace treecut::las_layout
