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

#include "las_write_layout.hpp"
#include "little_endian.hpp"
#include "treecut/error.hpp"
#include "treecut/file_io.hpp"
#include "treecut/las.hpp"
#include "typed_values.hpp"

namespace treecut {

using namespace las_layout;

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
