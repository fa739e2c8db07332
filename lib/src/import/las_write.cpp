// LAS export (ASPRS LAS 1.2, point data record formats 0 to 3): what `gen`
// and the tests write to make LAS files, and what `treecut export` writes.
// The standard fields come from the attributes of those names (as the reader
// names them); every other attribute goes into the extra bytes, as a float
// with its offset in the descriptor, so a round trip keeps it exactly.
// Through an AtomicFile, as save_ply.
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
#include "treecut/file_io.hpp"
#include "treecut/las.hpp"

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

struct Grid {
  glm::dvec3 offset{0.0};
  glm::dvec3 min{0.0}, max{0.0};  // of the integer coordinates, in file units
};

// The offset: the centre of the points' bounds in whole scale steps, so the
// integers are small; checked to fit 32 bits.
Grid grid_of(const PointSet& points, double scale) {
  glm::dvec3 lo(std::numeric_limits<double>::max()), hi(std::numeric_limits<double>::lowest());
  for (const glm::vec3& p : points.positions) {
    const glm::dvec3 q = points.frame.origin + glm::dvec3(p);
    lo = glm::min(lo, q), hi = glm::max(hi, q);
  }
  Grid g;
  if (points.positions.empty()) return g;
  g.offset = glm::round(0.5 * (lo + hi) / scale) * scale;
  for (int a = 0; a < 3; ++a) {
    const double reach = std::max(hi[a] - g.offset[a], g.offset[a] - lo[a]) / scale;
    if (!(reach < 2147483647.0)) {
      throw std::invalid_argument("save_las: the points span more than 2^31 steps of the scale " +
                                  std::to_string(scale) + " on one axis");
    }
  }
  return g;
}

std::array<std::int32_t, 3> integers(const PointSet& points, std::size_t i, const Grid& g,
                                     double scale) {
  const glm::dvec3 q = points.frame.origin + glm::dvec3(points.positions[i]);
  std::array<std::int32_t, 3> xyz{};
  for (int a = 0; a < 3; ++a) {
    xyz[static_cast<std::size_t>(a)] =
        static_cast<std::int32_t>(std::llround((q[a] - g.offset[a]) / scale));
  }
  return xyz;
}

// The attributes a record holds: the standard fields by name, the rest as
// extra bytes.
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
  std::vector<const PointAttribute*> extra;
  bool rgb = false;

  [[nodiscard]] int format() const { return (gps_time ? 1 : 0) + (rgb ? 2 : 0); }
  [[nodiscard]] std::uint16_t record_length() const {
    constexpr std::uint16_t kBase[4] = {20, 28, 26, 34};
    return static_cast<std::uint16_t>(kBase[format()] + 4 * extra.size());
  }
};

Layout layout_of(const PointSet& points) {
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
      {"gps_time", &l.gps_time}};
  for (const PointAttribute& a : points.attributes) {
    if (a.values.size() != points.size()) {
      throw std::invalid_argument("save_las: attribute " + a.name + " has " +
                                  std::to_string(a.values.size()) + " values for " +
                                  std::to_string(points.size()) + " points");
    }
    bool placed = false;
    for (const auto& [name, slot] : standard) {
      if (a.name == name && *slot == nullptr) *slot = &a, placed = true;
    }
    if (!placed) l.extra.push_back(&a);
  }
  if (l.extra.size() > 1000) throw std::invalid_argument("save_las: more than 1000 attributes");
  return l;
}

// The file's value of attribute A at point I as an integer in [lo, hi]
// (NaN, no value: 0).
std::int64_t integer_value(const PointAttribute* a, std::size_t i, std::int64_t lo, std::int64_t hi,
                           double unit = 1.0) {
  if (a == nullptr || std::isnan(a->values[i])) return 0;
  const double v = std::round((a->offset + double(a->values[i])) / unit);
  return static_cast<std::int64_t>(std::clamp(v, double(lo), double(hi)));
}

// The extra-bytes VLR (LAS 1.4 R15, 2.5.13; readers of 1.2 files accept it):
// one 192-byte descriptor per extra attribute, a float with its offset.
std::string extra_bytes_vlr(const Layout& l) {
  std::string v;
  if (l.extra.empty()) return v;
  put<std::uint16_t>(v, 0);  // reserved
  put_text(v, "LASF_Spec", 16);
  put<std::uint16_t>(v, 4);  // record id: extra bytes
  put<std::uint16_t>(v, static_cast<std::uint16_t>(192 * l.extra.size()));
  put_text(v, "extra bytes", 32);
  for (const PointAttribute* a : l.extra) {
    std::string d;
    put<std::uint16_t>(d, 0);
    d.push_back(9);   // float
    d.push_back(16);  // options: the offset applies
    put_text(d, a->name, 32);
    d.append(4 + 24 * 4, '\0');  // unused, no_data, min, max, scale
    put<double>(d, a->offset);
    d.append(16, '\0');
    put_text(d, a->name, 32);  // description
    v += d;
  }
  return v;
}

std::string header(const PointSet& points, const Grid& g, double scale, const Layout& l) {
  std::string h;
  h += "LASF";
  put<std::uint16_t>(h, 0);  // file source id
  put<std::uint16_t>(h, 0);  // global encoding
  h.append(16, '\0');        // project GUID
  h.push_back(1);            // version 1.2
  h.push_back(2);
  put_text(h, "treecut", 32);
  put_text(h, "treecut save_las", 32);
  put<std::uint16_t>(h, 1);     // creation day of year
  put<std::uint16_t>(h, 2026);  // creation year
  const std::string vlr = extra_bytes_vlr(l);
  put<std::uint16_t>(h, 227);                                           // header size
  put<std::uint32_t>(h, static_cast<std::uint32_t>(227 + vlr.size()));  // offset to point data
  put<std::uint32_t>(h, vlr.empty() ? 0 : 1);                           // VLRs
  h.push_back(static_cast<char>(l.format()));
  put<std::uint16_t>(h, l.record_length());
  put<std::uint32_t>(h, static_cast<std::uint32_t>(points.size()));
  // Points by return: counted when the attribute is there, else all first.
  std::array<std::uint32_t, 5> by_return{};
  for (std::size_t i = 0; i < points.size(); ++i) {
    const std::int64_t r = l.return_number ? integer_value(l.return_number, i, 0, 7) : 1;
    if (r >= 1 && r <= 5) ++by_return[static_cast<std::size_t>(r - 1)];
  }
  for (const std::uint32_t count : by_return) put<std::uint32_t>(h, count);
  for (int a = 0; a < 3; ++a) put<double>(h, scale);
  for (int a = 0; a < 3; ++a) put<double>(h, g.offset[a]);
  for (int a = 0; a < 3; ++a) {
    put<double>(h, g.max[a]);
    put<double>(h, g.min[a]);
  }
  return h + vlr;
}

}  // namespace

void save_las(const std::filesystem::path& path, const PointSet& points,
              const LasWriteOptions& options) {
  const double scale = options.scale;
  if (!(scale > 0.0) || !std::isfinite(scale)) {
    throw std::invalid_argument("save_las: the scale must be positive and finite");
  }
  if (points.has_colors() && points.colors.size() != points.size()) {
    throw std::invalid_argument("save_las: colors has " + std::to_string(points.colors.size()) +
                                " entries for " + std::to_string(points.size()) + " points");
  }
  if (points.size() > std::numeric_limits<std::uint32_t>::max()) {
    throw std::invalid_argument("save_las: more points than LAS 1.2 counts (2^32 - 1)");
  }
  Grid g = grid_of(points, scale);
  // The header's bounds are the written integers' (what a reader checks).
  glm::dvec3 lo(std::numeric_limits<double>::max()), hi(std::numeric_limits<double>::lowest());
  for (std::size_t i = 0; i < points.size(); ++i) {
    const auto xyz = integers(points, i, g, scale);
    for (int a = 0; a < 3; ++a) {
      const double v = double(xyz[static_cast<std::size_t>(a)]) * scale + g.offset[a];
      lo[a] = std::min(lo[a], v), hi[a] = std::max(hi[a], v);
    }
  }
  if (points.size() > 0) g.min = lo, g.max = hi;
  const Layout l = layout_of(points);

  AtomicFile file(path);  // throws "PATH: REASON"
  constexpr std::size_t kChunk = std::size_t{1} << 20;
  std::string chunk = header(points, g, scale, l);
  for (std::size_t i = 0; i < points.size(); ++i) {
    for (const std::int32_t v : integers(points, i, g, scale)) put<std::int32_t>(chunk, v);
    put<std::uint16_t>(chunk, static_cast<std::uint16_t>(integer_value(l.intensity, i, 0, 65535)));
    // Without the attributes: return 1 of 1, unclassified (1).
    const auto ret = l.return_number ? integer_value(l.return_number, i, 0, 7) : 1;
    const auto of = l.number_of_returns ? integer_value(l.number_of_returns, i, 0, 7) : 1;
    chunk.push_back(static_cast<char>(ret | (of << 3) |
                                      (integer_value(l.scan_direction, i, 0, 1) << 6) |
                                      (integer_value(l.edge, i, 0, 1) << 7)));
    const auto cls = l.classification ? integer_value(l.classification, i, 0, 31) : 1;
    chunk.push_back(static_cast<char>(cls | (integer_value(l.flags, i, 0, 7) << 5)));
    chunk.push_back(static_cast<char>(integer_value(l.scan_angle, i, -90, 90)));
    chunk.push_back(static_cast<char>(integer_value(l.user_data, i, 0, 255)));
    put<std::uint16_t>(chunk,
                       static_cast<std::uint16_t>(integer_value(l.point_source_id, i, 0, 65535)));
    if (l.gps_time) {
      const PointAttribute& t = *l.gps_time;
      put<double>(chunk, std::isnan(t.values[i]) ? 0.0 : t.offset + double(t.values[i]));
    }
    if (l.rgb) {
      const glm::u8vec4 c = points.colors[i];
      // 8 to 16 bits: 255 becomes 65535.
      put<std::uint16_t>(chunk, static_cast<std::uint16_t>(c.x * 257));
      put<std::uint16_t>(chunk, static_cast<std::uint16_t>(c.y * 257));
      put<std::uint16_t>(chunk, static_cast<std::uint16_t>(c.z * 257));
    }
    for (const PointAttribute* a : l.extra) put<float>(chunk, a->values[i]);
    if (chunk.size() >= kChunk) {
      file.write(chunk);
      chunk.clear();
    }
  }
  file.write(chunk);
  file.commit();
}

}  // namespace treecut
