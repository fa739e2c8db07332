// LAS export (ASPRS LAS 1.2 formats 0-3 and LAS 1.4 R15 formats 6-8): what
// `gen` and the tests write to make LAS files, and what `treecut export`
// writes. Nothing a file held is lost on the way (issue 43): the point
// format is the smallest that holds every field of every point, the
// standard fields come from the attributes of those names (as the reader
// names them), every other attribute goes into the extra bytes in its own
// type, scale and offset, RGB keeps its 16 bits, and the coordinate
// system's records and the GPS time type are written back. Through an
// AtomicFile, as save_ply.
#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstring>
#include <limits>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "little_endian.hpp"
#include "treecut/error.hpp"
#include "treecut/file_io.hpp"
#include "treecut/las.hpp"
#include "typed_values.hpp"

namespace treecut {

namespace {

template <class T>
void put(std::string& out, T value) {
  detail::put_le(out, value);
}

void put_text(std::string& out, std::string_view text, std::size_t width) {
  std::string field(width, '\0');
  std::memcpy(field.data(), text.data(), std::min(text.size(), width));
  out += field;
}

constexpr char kSoftware[] = "treecut save_las";

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

struct Grid {
  glm::dvec3 scale{0.001};
  glm::dvec3 offset{0.0};
  glm::dvec3 min{0.0}, max{0.0};  // of the integer coordinates, in file units
};

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

// The attributes a record holds: the standard fields by name, the rest as
// extra bytes; the smallest point format for them.
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
                           double unit = 1.0) {
  if (a == nullptr) return 0;
  const double v = a->value(i);
  if (std::isnan(v)) return 0;
  return static_cast<std::int64_t>(std::clamp(std::round(v / unit), double(lo), double(hi)));
}

// One variable-length record (LAS 1.4 R15, 2.5): a 54-byte header, then PAYLOAD.
std::string vlr(std::string_view user, std::uint16_t id, std::string_view description,
                const std::string& payload) {
  std::string v;
  put<std::uint16_t>(v, 0);  // reserved
  put_text(v, user, 16);
  put<std::uint16_t>(v, id);
  put<std::uint16_t>(v, static_cast<std::uint16_t>(payload.size()));
  put_text(v, description, 32);
  return v + payload;
}

// An extended one (1.4): a 60-byte header with a 64-bit length.
std::string evlr(std::string_view user, std::uint16_t id, std::string_view description,
                 const std::string& payload) {
  std::string v;
  put<std::uint16_t>(v, 0);
  put_text(v, user, 16);
  put<std::uint16_t>(v, id);
  put<std::uint64_t>(v, payload.size());
  put_text(v, description, 32);
  return v + payload;
}

// The extra-bytes descriptors (LAS 1.4 R15, 2.5.13; readers of 1.2 files
// accept them): one 192-byte record per field, in its own type, with its
// scale, offset and no-data value.
std::string extra_bytes_payload(const Layout& l) {
  std::string v;
  for (const PointAttribute* a : l.extra) {
    std::string d;
    put<std::uint16_t>(d, 0);
    d.push_back(static_cast<char>(static_cast<int>(a->type) + 1));
    const bool scaled = a->scale != 1.0, offset = a->base != 0.0;
    d.push_back(static_cast<char>((a->no_data ? 1 : 0) | (scaled ? 8 : 0) | (offset ? 16 : 0)));
    put_text(d, a->name, 32);
    d.append(4, '\0');  // unused
    // no_data, min, max: an 8-byte slot each, in the field's own kind.
    if (a->no_data && is_integer(a->type) && is_signed(a->type)) {
      put<std::int64_t>(d, static_cast<std::int64_t>(*a->no_data));
    } else if (a->no_data && is_integer(a->type)) {
      put<std::uint64_t>(d, static_cast<std::uint64_t>(*a->no_data));
    } else {
      put<double>(d, a->no_data.value_or(0.0));
    }
    d.append(16 + 24 + 24, '\0');  // min, max; the deprecated second and third slots
    put<double>(d, a->scale);
    d.append(16, '\0');
    put<double>(d, a->base);
    d.append(16, '\0');
    put_text(d, a->name, 32);  // description
    v += d;
  }
  return v;
}

// The records after the header: the coordinate system and the extra bytes
// (VLRs), and in LAS 1.4 what a VLR's 16-bit length cannot hold (EVLRs).
struct Records {
  std::string vlrs, evlrs;
  std::uint32_t vlr_count = 0, evlr_count = 0;
};

Records records_of(const PointSet& points, const Layout& l, bool v14) {
  Records r;
  auto add = [&](std::string_view user, std::uint16_t id, std::string_view what,
                 const std::string& payload, bool keep_empty = false) {
    if (payload.empty() && !keep_empty) return;
    if (payload.size() <= 65535) {
      r.vlrs += vlr(user, id, what, payload), ++r.vlr_count;
    } else if (v14) {
      r.evlrs += evlr(user, id, what, payload), ++r.evlr_count;
    } else {
      throw std::invalid_argument("save_las: a " + std::string(what) + " record of " +
                                  std::to_string(payload.size()) + " bytes (LAS 1.2 holds 65535)");
    }
  };
  const CrsRecords& crs = points.frame.crs_records;
  add("LASF_Projection", 2112, "OGC coordinate system WKT", crs.wkt);
  add("LASF_Projection", 34735, "GeoKeyDirectoryTag", crs.geo_keys);
  add("LASF_Projection", 34736, "GeoDoubleParamsTag", crs.geo_doubles);
  add("LASF_Projection", 34737, "GeoAsciiParamsTag", crs.geo_ascii);
  add("LASF_Spec", 4, "extra bytes", extra_bytes_payload(l));
  for (const FileRecord& k : points.records) add(k.user, k.id, k.description, k.payload, true);
  return r;
}

std::string header(const PointSet& points, const Grid& g, const Layout& l, const Records& r) {
  const bool v14 = l.extended() || r.evlr_count > 0 || !points.frame.crs_records.wkt.empty();
  const std::uint16_t header_size = v14 ? 375 : 227;
  const std::size_t n = points.size();
  std::string h;
  h += "LASF";
  put<std::uint16_t>(h, 0);  // file source id
  // Global encoding: bit 0 the GPS time type, bit 4 a WKT coordinate system.
  const bool wkt = !points.frame.crs_records.wkt.empty();
  put<std::uint16_t>(
      h, static_cast<std::uint16_t>((points.adjusted_gps_time ? 1 : 0) | (wkt && v14 ? 16 : 0)));
  h.append(16, '\0');  // project GUID
  h.push_back(1);
  h.push_back(v14 ? 4 : 2);
  put_text(h, "treecut", 32);
  put_text(h, kSoftware, 32);
  put<std::uint16_t>(h, 1);     // creation day of year
  put<std::uint16_t>(h, 2026);  // creation year
  put<std::uint16_t>(h, header_size);
  put<std::uint32_t>(h, static_cast<std::uint32_t>(header_size + r.vlrs.size()));
  put<std::uint32_t>(h, r.vlr_count);
  h.push_back(static_cast<char>(l.format));
  put<std::uint16_t>(h, static_cast<std::uint16_t>(l.record_length()));
  // Points by return: counted when the attribute is there, else all first.
  std::array<std::uint64_t, 15> by_return{};
  for (std::size_t i = 0; i < n; ++i) {
    const std::int64_t ret = l.return_number ? integer_value(l.return_number, i, 0, 15) : 1;
    if (ret >= 1) ++by_return[static_cast<std::size_t>(ret - 1)];
  }
  // The legacy counts only where a legacy reader can take them.
  const bool legacy = !l.extended() && n <= std::numeric_limits<std::uint32_t>::max();
  put<std::uint32_t>(h, legacy ? static_cast<std::uint32_t>(n) : 0);
  for (int k = 0; k < 5; ++k)
    put<std::uint32_t>(h, legacy ? static_cast<std::uint32_t>(by_return[k]) : 0);
  for (int a = 0; a < 3; ++a) put<double>(h, g.scale[a]);
  for (int a = 0; a < 3; ++a) put<double>(h, g.offset[a]);
  for (int a = 0; a < 3; ++a) {
    put<double>(h, g.max[a]);
    put<double>(h, g.min[a]);
  }
  if (v14) {
    put<std::uint64_t>(h, 0);  // waveform data packet record
    const std::uint64_t points_end =
        header_size + r.vlrs.size() + std::uint64_t{l.record_length()} * n;
    put<std::uint64_t>(h, r.evlr_count > 0 ? points_end : 0);
    put<std::uint32_t>(h, r.evlr_count);
    put<std::uint64_t>(h, n);
    for (const std::uint64_t c : by_return) put<std::uint64_t>(h, c);
  }
  return h + r.vlrs;
}

// One extra-bytes value in its type: (value - base) / scale, rounded for
// integers; NaN is the no-data value.
void put_extra(std::string& out, const PointAttribute& a, std::size_t i) {
  if (!a.integers.empty()) {  // a 64-bit field past 2^53, exactly (unscaled)
    detail::put_le(out, a.integers[i]);
    return;
  }
  const double v = a.value(i);
  detail::put_value(out, a.type, std::isnan(v) ? a.no_data.value_or(v) : (v - a.base) / a.scale);
}

// One point record of format L.format.
void put_record(std::string& out, const PointSet& points, std::size_t i, const Grid& g,
                const Layout& l) {
  for (const std::int32_t v : integers(points, i, g)) put<std::int32_t>(out, v);
  put<std::uint16_t>(out, static_cast<std::uint16_t>(integer_value(l.intensity, i, 0, 65535)));
  // Without the attributes: return 1 of 1, unclassified (1).
  const auto ret = l.return_number ? integer_value(l.return_number, i, 0, 15) : 1;
  const auto of = l.number_of_returns ? integer_value(l.number_of_returns, i, 0, 15) : 1;
  const auto cls = l.classification ? integer_value(l.classification, i, 0, 255) : 1;
  const auto flags = integer_value(l.flags, i, 0, 15);
  const auto direction = integer_value(l.scan_direction, i, 0, 1);
  const auto edge = integer_value(l.edge, i, 0, 1);
  if (!l.extended()) {
    out.push_back(static_cast<char>(std::min<std::int64_t>(ret, 7) |
                                    (std::min<std::int64_t>(of, 7) << 3) | (direction << 6) |
                                    (edge << 7)));
    out.push_back(static_cast<char>(std::min<std::int64_t>(cls, 31) | ((flags & 7) << 5)));
    out.push_back(static_cast<char>(integer_value(l.scan_angle, i, -128, 127)));
    out.push_back(static_cast<char>(integer_value(l.user_data, i, 0, 255)));
    put<std::uint16_t>(out,
                       static_cast<std::uint16_t>(integer_value(l.point_source_id, i, 0, 65535)));
    if (l.gps_time) {
      const double t = l.gps_time->value(i);
      put<double>(out, std::isnan(t) ? 0.0 : t);
    }
  } else {
    out.push_back(static_cast<char>(ret | (of << 4)));
    out.push_back(static_cast<char>(flags | (integer_value(l.scanner_channel, i, 0, 3) << 4) |
                                    (direction << 6) | (edge << 7)));
    out.push_back(static_cast<char>(cls));
    out.push_back(static_cast<char>(integer_value(l.user_data, i, 0, 255)));
    // Steps of 0.006 degrees.
    put<std::int16_t>(
        out, static_cast<std::int16_t>(integer_value(l.scan_angle, i, -32768, 32767, 0.006)));
    put<std::uint16_t>(out,
                       static_cast<std::uint16_t>(integer_value(l.point_source_id, i, 0, 65535)));
    const double t = l.gps_time ? l.gps_time->value(i) : 0.0;
    put<double>(out, std::isnan(t) ? 0.0 : t);
  }
  if (l.rgb) {
    // 16 bits as the file had them, else 8 to 16 bits: 255 becomes 65535.
    const glm::u16vec3 c = points.colors16.empty()
                               ? glm::u16vec3(glm::u8vec3(points.colors[i])) * std::uint16_t(257)
                               : points.colors16[i];
    put<std::uint16_t>(out, c.x), put<std::uint16_t>(out, c.y), put<std::uint16_t>(out, c.z);
  }
  if (l.nir) put<std::uint16_t>(out, static_cast<std::uint16_t>(integer_value(l.nir, i, 0, 65535)));
  for (const PointAttribute* a : l.extra) put_extra(out, *a, i);
}

}  // namespace

void save_las(const std::filesystem::path& path, const PointSet& points,
              const LasWriteOptions& options) {
  const double scale = options.scale;
  if (!(scale >= 0.0) || !std::isfinite(scale)) {
    throw std::invalid_argument(
        "save_las: the scale must be positive and finite (or 0: automatic)");
  }
  const std::size_t n = points.size();
  if ((points.has_colors() && points.colors.size() != n) ||
      (!points.colors16.empty() && points.colors16.size() != n)) {
    throw std::invalid_argument("save_las: colours differ from the point count");
  }
  Grid g = grid_of(path, points, scale);
  // The header's bounds are the written integers' (what a reader checks).
  glm::dvec3 lo(std::numeric_limits<double>::max()), hi(std::numeric_limits<double>::lowest());
  for (std::size_t i = 0; i < n; ++i) {
    const auto xyz = integers(points, i, g);
    for (int a = 0; a < 3; ++a) {
      const double v = double(xyz[static_cast<std::size_t>(a)]) * g.scale[a] + g.offset[a];
      lo[a] = std::min(lo[a], v), hi[a] = std::max(hi[a], v);
    }
  }
  if (n > 0) g.min = lo, g.max = hi;
  std::vector<PointAttribute> widened;
  const Layout l = layout_of(points, widened);
  check_standard_fields(path, l, n);
  if (!l.extended() && n > std::numeric_limits<std::uint32_t>::max())
    throw std::invalid_argument("save_las: more points than LAS 1.2 counts (2^32 - 1)");
  const bool v14 = l.extended() || !points.frame.crs_records.wkt.empty();
  const Records records = records_of(points, l, v14);

  AtomicFile file(path);  // throws "PATH: REASON"
  constexpr std::size_t kChunk = std::size_t{1} << 20;
  std::string chunk = header(points, g, l, records);
  for (std::size_t i = 0; i < n; ++i) {
    put_record(chunk, points, i, g, l);
    if (chunk.size() >= kChunk) {
      file.write(chunk);
      chunk.clear();
    }
  }
  chunk += records.evlrs;
  file.write(chunk);
  file.commit();
}

}  // namespace treecut
