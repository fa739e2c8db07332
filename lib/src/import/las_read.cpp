// LAS import: ASPRS "LAS Specification 1.4 - R15" (2019) and its 1.0-1.3
// predecessors, read as untrusted bytes: the public header block, the VLRs and
// EVLRs (for the coordinate system and the extra bytes' descriptors) and the point
// records of formats 0 to 10 (las_points.cpp). See treecut/las.hpp.
#include <fcntl.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstring>
#include <glm/gtc/type_precision.hpp>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

#include "file_metadata.hpp"
#include "las_fields.hpp"
#include "las_source.hpp"
#include "little_endian.hpp"
#include "position_frame.hpp"
#include "treecut/error.hpp"
#include "treecut/file_io.hpp"
#include "treecut/las.hpp"

namespace treecut {

namespace {

using detail::ByteSource;
using detail::LasError;

template <class T>
T get(const unsigned char* p) {
  return detail::get_le<T>(p);
}

std::string text_field(const unsigned char* p, std::size_t n) {
  std::string s(reinterpret_cast<const char*>(p), n);
  s.resize(std::strlen(s.c_str()));
  while (!s.empty() && s.back() == ' ') s.pop_back();
  return s;
}

// The public header block: 227 bytes up to 1.2, 235 in 1.3, 375 in 1.4.
constexpr std::size_t kHeaderSize[5] = {227, 227, 227, 235, 375};
// Bytes of a point record of each format (the spec's tables 7 to 17).
constexpr std::uint32_t kRecordLength[11] = {20, 28, 26, 34, 57, 63, 30, 36, 38, 59, 67};
constexpr std::size_t kVlrHeader = 54, kEvlrHeader = 60;

std::string number(double v) {
  char b[40];
  std::snprintf(b, sizeof b, "%.17g", v);
  return b;
}

// One variable-length record (VLR or EVLR) whose payload is at `at`: the
// coordinate system's records (kept whole) and the extra bytes.
// Records that describe this file's own encoding, which an export writes
// anew or not at all: the extra bytes' descriptors, the waveform packet
// descriptors, LASzip's and COPC's.
bool encoding_record(const std::string& user, std::uint16_t id) {
  return (user == "LASF_Spec" && (id == 4 || id == 7 || (id >= 100 && id < 355))) ||
         user == "laszip encoded" || user == "copc";
}

// Records kept for an export, at most this many bytes in all.
constexpr std::uint64_t kMaxKeptRecordBytes = std::uint64_t{16} << 20;

void read_record(const ByteSource& f, const std::string& user, std::uint16_t id,
                 const std::string& description, std::uint64_t at, std::uint64_t length,
                 LasInfo& info) {
  // An empty coordinate-system record says nothing: kept as any other
  // record, so an export writes it back as it was.
  const bool projection = user == "LASF_Projection" && length > 0 &&
                          (id == 2112 || id == 34735 || id == 34736 || id == 34737);
  const bool extra = user == "LASF_Spec" && id == 4;
  if (!projection && !extra) {
    std::uint64_t kept = 0;
    for (const FileRecord& r : info.records) kept += r.payload.size();
    if (encoding_record(user, id) || length > kMaxKeptRecordBytes - kept) return;
    FileRecord r{user, id, description, std::string(static_cast<std::size_t>(length), '\0')};
    f.read(at, r.payload.data(), r.payload.size());
    info.records.push_back(std::move(r));
    return;
  }
  // A coordinate system is text of a few kB; the extra bytes 192 a field.
  if (length > (std::uint64_t{1} << 24)) {
    throw LasError("the " + user + " record " + std::to_string(id) + " is " +
                   std::to_string(length) + " bytes long, more than 16 MiB");
  }
  std::string payload(static_cast<std::size_t>(length), '\0');
  f.read(at, payload.data(), payload.size());
  if (projection) {
    CrsRecords& r = info.crs_records;
    (id == 2112    ? r.wkt
     : id == 34735 ? r.geo_keys
     : id == 34736 ? r.geo_doubles
                   : r.geo_ascii) = std::move(payload);
    info.crs = detail::crs_text(r);
    return;
  }
  for (std::size_t d = 0; d + 192 <= payload.size(); d += 192) {
    const auto* e = reinterpret_cast<const unsigned char*>(payload.data()) + d;
    LasExtraBytes field;
    field.data_type = e[2];
    field.options = e[3];
    field.name = text_field(e + 4, 32);
    // no_data, min, max, scale and offset are three 8-byte slots each, one
    // per element of an array; a scalar uses the first (a double, or an
    // integer for integer types).
    const int t = field.data_type;
    const int base = t >= 1 && t <= 30 ? (t - 1) % 10 + 1 : 0;
    const bool integral = base >= 1 && base <= 8;
    for (int k = 0; k < 3; ++k) {
      const unsigned char* slot = e + 40 + 8 * k;
      field.no_data[k] = !integral         ? get<double>(slot)
                         : (base % 2 == 0) ? static_cast<double>(get<std::int64_t>(slot))
                                           : static_cast<double>(get<std::uint64_t>(slot));
      field.scale[k] = get<double>(e + 112 + 8 * k);
      field.offset[k] = get<double>(e + 136 + 8 * k);
      if (!(std::isfinite(field.scale[k]) && field.scale[k] != 0.0 &&
            std::isfinite(field.offset[k]))) {
        field.scale[k] = 1.0, field.offset[k] = 0.0;
        if (k == 0) field.options &= ~24u;
      }
    }
    info.extra_bytes.push_back(std::move(field));
  }
}

void read_vlrs(const ByteSource& f, std::uint64_t header_size, std::uint32_t count,
               std::uint64_t end, LasInfo& info) {
  std::uint64_t at = header_size;
  for (std::uint32_t i = 0; i < count; ++i) {
    if (at + kVlrHeader > end) {
      throw LasError("variable length record " + std::to_string(i + 1) + " of " +
                     std::to_string(count) + " runs past the point data offset " +
                     std::to_string(end));
    }
    unsigned char h[kVlrHeader];
    f.read(at, h, kVlrHeader);
    const std::uint64_t length = get<std::uint16_t>(h + 20);
    if (at + kVlrHeader + length > end) {
      throw LasError("variable length record " + std::to_string(i + 1) + " of " +
                     std::to_string(count) + " (" + std::to_string(length) +
                     " bytes) runs past the point data offset " + std::to_string(end));
    }
    read_record(f, text_field(h + 2, 16), get<std::uint16_t>(h + 18), text_field(h + 22, 32),
                at + kVlrHeader, length, info);
    at += kVlrHeader + length;
  }
}

// Returns where the last record ends.
std::uint64_t read_evlrs(const ByteSource& f, std::uint64_t start, std::uint32_t count,
                         std::uint64_t points_end, LasInfo& info) {
  if (count == 0) return points_end;
  if (start < points_end || start > f.size()) {
    throw LasError("the extended variable length records start at " + std::to_string(start) +
                   ", not between the end of the points (" + std::to_string(points_end) +
                   ") and the end of the file (" + std::to_string(f.size()) + ")");
  }
  std::uint64_t at = start;
  for (std::uint32_t i = 0; i < count; ++i) {
    if (f.size() - at < kEvlrHeader) {
      throw LasError("extended variable length record " + std::to_string(i + 1) + " of " +
                     std::to_string(count) + " runs past the end of the file");
    }
    unsigned char h[kEvlrHeader];
    f.read(at, h, kEvlrHeader);
    const std::uint64_t length = get<std::uint64_t>(h + 20);
    if (length > f.size() - at - kEvlrHeader) {
      throw LasError("extended variable length record " + std::to_string(i + 1) + " of " +
                     std::to_string(count) + " (" + std::to_string(length) +
                     " bytes) runs past the end of the file");
    }
    read_record(f, text_field(h + 2, 16), get<std::uint16_t>(h + 18), text_field(h + 28, 32),
                at + kEvlrHeader, length, info);
    at += kEvlrHeader + length;
  }
  return at;
}

void check_scale_offset(const LasInfo& info) {
  static constexpr const char* kAxis[3] = {"X", "Y", "Z"};
  for (int a = 0; a < 3; ++a) {
    const double s = info.scale[a], o = info.offset[a];
    if (!(s > 0.0) || !std::isfinite(s)) {
      throw LasError(std::string(kAxis[a]) + " scale factor " + number(s) +
                     " (it must be positive and finite)");
    }
    if (!std::isfinite(o)) {
      throw LasError(std::string(kAxis[a]) + " offset " + number(o) + " is not finite");
    }
    // Every integer times the scale plus the offset must stay a coordinate
    // the float arithmetic downstream can take (point_set.hpp).
    if (s * 2147483648.0 + std::fabs(o) > double(kMaxCoordinate)) {
      throw LasError(std::string(kAxis[a]) + " scale factor " + number(s) + " and offset " +
                     number(o) + " reach coordinates beyond 1e18");
    }
  }
}

}  // namespace

detail::LasParsed detail::parse_las_header(const ByteSource& f) {
  LasParsed out;
  LasInfo& info = out.info;
  const std::uint64_t size = f.size();
  if (size < 4) throw LasError("too short for a LAS file (" + std::to_string(size) + " bytes)");
  unsigned char h[375] = {};
  f.read(0, h, 4);
  if (std::memcmp(h, "LASF", 4) != 0) throw LasError("not a LAS file (no LASF signature)");
  if (size < 227) {
    throw LasError("the header is cut off: " + std::to_string(size) +
                   " bytes, a LAS header has at least 227");
  }
  f.read(0, h, static_cast<std::size_t>(std::min<std::uint64_t>(size, 375)));
  info.version_major = h[24];
  info.version_minor = h[25];
  if (info.version_major != 1 || info.version_minor > 4) {
    throw LasError("LAS version " + std::to_string(info.version_major) + "." +
                   std::to_string(info.version_minor) + " is not read (1.0 to 1.4 are)");
  }
  info.file_source_id = get<std::uint16_t>(h + 4);
  info.global_encoding = get<std::uint16_t>(h + 6);
  info.system_identifier = text_field(h + 26, 32);
  info.generating_software = text_field(h + 58, 32);
  const std::uint16_t header_size = get<std::uint16_t>(h + 94);
  const std::size_t need = kHeaderSize[info.version_minor];
  if (header_size < need) {
    throw LasError("header size " + std::to_string(header_size) + " is less than the " +
                   std::to_string(need) + " bytes of a LAS 1." +
                   std::to_string(info.version_minor) + " header");
  }
  if (header_size > size) {
    throw LasError("header size " + std::to_string(header_size) + " is past the end of the file (" +
                   std::to_string(size) + " bytes)");
  }
  out.point_offset = get<std::uint32_t>(h + 96);
  const std::uint32_t vlr_count = get<std::uint32_t>(h + 100);
  const std::uint8_t format_byte = h[104];
  if ((format_byte & 0xC0) != 0) {
    // Bits 7 and 6 mark LASzip compression.
    throw LasError(
        "a LAZ (compressed LAS) file, which treecut does not decode (no LASzip library in "
        "Debian 12); decompress it to LAS first, e.g. 'laszip -i FILE.laz -o FILE.las' or "
        "'pdal translate FILE.laz FILE.las'");
  }
  info.point_format = format_byte;
  if (info.point_format > 10) {
    throw LasError("point data format " + std::to_string(info.point_format) +
                   " is not defined (0 to 10 are)");
  }
  info.record_length = get<std::uint16_t>(h + 105);
  if (info.record_length < kRecordLength[info.point_format]) {
    throw LasError("point data format " + std::to_string(info.point_format) + " has records of " +
                   std::to_string(kRecordLength[info.point_format]) + " bytes; the header says " +
                   std::to_string(info.record_length));
  }
  info.waveform = info.point_format == 4 || info.point_format == 5 || info.point_format >= 9;
  const std::uint64_t legacy = get<std::uint32_t>(h + 107);
  info.point_count = legacy;
  for (int a = 0; a < 3; ++a) {
    info.scale[a] = get<double>(h + 131 + 8 * a);
    info.offset[a] = get<double>(h + 155 + 8 * a);
    info.max[a] = get<double>(h + 179 + 16 * a);
    info.min[a] = get<double>(h + 187 + 16 * a);
  }
  std::uint64_t evlr_start = 0;
  std::uint32_t evlr_count = 0;
  if (info.version_minor >= 4) {
    evlr_start = get<std::uint64_t>(h + 235);
    evlr_count = get<std::uint32_t>(h + 243);
    const std::uint64_t extended = get<std::uint64_t>(h + 247);
    if (extended != 0) info.point_count = extended;
    if (extended != 0 && legacy != 0 && legacy != extended) {
      throw LasError("the legacy point count " + std::to_string(legacy) + " and the point count " +
                     std::to_string(extended) + " disagree");
    }
  }
  if (out.point_offset < header_size || out.point_offset > size) {
    throw LasError("the point data offset " + std::to_string(out.point_offset) +
                   " is not between the header's end (" + std::to_string(header_size) +
                   ") and the end of the file (" + std::to_string(size) + ")");
  }
  check_scale_offset(info);
  if (info.point_count == 0) throw LasError("no points (the header declares none)");
  const std::uint64_t room = (size - out.point_offset) / info.record_length;
  if (info.point_count > room) {
    throw LasError(std::to_string(info.point_count) + " points of " +
                   std::to_string(info.record_length) + " bytes declared from offset " +
                   std::to_string(out.point_offset) + ", the file holds " + std::to_string(room));
  }
  read_vlrs(f, header_size, vlr_count, out.point_offset, info);
  out.end = read_evlrs(f, evlr_start, evlr_count,
                       out.point_offset + info.point_count * info.record_length, info);
  return out;
}

bool is_own_las(const std::filesystem::path& path) {
  try {
    const detail::FileSource source(path, O_NOFOLLOW);
    const detail::LasParsed parsed = detail::parse_las_header(source);
    return parsed.info.generating_software.starts_with("treecut") && parsed.end == source.size();
  } catch (const std::exception&) {
    return false;
  }
}

bool looks_like_las(std::string_view bytes) {
  return bytes.size() >= 4 && bytes.substr(0, 4) == "LASF";
}

}  // namespace treecut
