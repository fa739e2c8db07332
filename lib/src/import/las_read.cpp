// LAS import: ASPRS "LAS Specification 1.4 - R15" (2019) and its 1.0-1.3
// predecessors, read as untrusted bytes: the public header block, the VLRs and
// EVLRs (for the coordinate system and the extra bytes' descriptors) and the point
// records of formats 0 to 10, in chunks. See treecut/las.hpp.
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <glm/gtc/type_precision.hpp>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

#include "file_metadata.hpp"
#include "las_fields.hpp"
#include "little_endian.hpp"
#include "position_frame.hpp"
#include "treecut/error.hpp"
#include "treecut/file_io.hpp"
#include "treecut/las.hpp"

namespace treecut {

namespace {

// A problem with the bytes, without the file's name (added by the caller).
class LasError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Where the bytes come from: memory (fuzzing, tests) or a file read in
// pieces (a 20 M-point LAS is not read into memory whole).
class Source {
 public:
  virtual ~Source() = default;
  [[nodiscard]] virtual std::uint64_t size() const = 0;
  // Exactly n bytes at `at`; the caller checked at + n <= size().
  virtual void read(std::uint64_t at, void* out, std::size_t n) const = 0;
};

class MemorySource final : public Source {
 public:
  explicit MemorySource(std::string_view bytes) : bytes_(bytes) {}
  [[nodiscard]] std::uint64_t size() const override { return bytes_.size(); }
  void read(std::uint64_t at, void* out, std::size_t n) const override {
    if (n > 0) std::memcpy(out, bytes_.data() + at, n);
  }

 private:
  std::string_view bytes_;
};

class FileSource final : public Source {
 public:
  FileSource(int fd, std::uint64_t size, std::filesystem::path path)
      : fd_(fd), size_(size), path_(std::move(path)) {}
  [[nodiscard]] std::uint64_t size() const override { return size_; }
  void read(std::uint64_t at, void* out, std::size_t n) const override {
    auto* p = static_cast<char*>(out);
    while (n > 0) {
      const ssize_t got = ::pread(fd_, p, n, static_cast<off_t>(at));
      if (got < 0 && errno == EINTR) continue;
      if (got < 0) throw InputError(system_error_text(path_, errno));
      if (got == 0) {
        throw FileChangedError(quoted_name(path_) + ": changed while being read (it got shorter)");
      }
      p += got, at += static_cast<std::uint64_t>(got), n -= static_cast<std::size_t>(got);
    }
  }

 private:
  int fd_;
  std::uint64_t size_;
  std::filesystem::path path_;
};

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
// Where RGB starts in a record (0: no RGB).
constexpr std::uint32_t kRgbAt[11] = {0, 0, 20, 28, 0, 28, 0, 30, 30, 0, 30};
constexpr std::size_t kVlrHeader = 54, kEvlrHeader = 60;

std::string number(double v) {
  char b[40];
  std::snprintf(b, sizeof b, "%.17g", v);
  return b;
}

struct Parsed {
  LasInfo info;
  std::uint64_t point_offset = 0;
  std::uint64_t end = 0;  // of the last thing the header locates (points or EVLRs)
};

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

void read_record(const Source& f, const std::string& user, std::uint16_t id,
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

void read_vlrs(const Source& f, std::uint64_t header_size, std::uint32_t count, std::uint64_t end,
               LasInfo& info) {
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
std::uint64_t read_evlrs(const Source& f, std::uint64_t start, std::uint32_t count,
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

Parsed parse_header(const Source& f) {
  Parsed out;
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

// The origin of the positions: the centre of the header's bounds, in whole
// units, when the first point lies inside them and they lie inside what the
// integers can reach (a header may lie: then the first point itself,
// rounded). Either way every point is within twice the integers' reach of
// it, which check_scale_offset keeps below 1e18: finite floats. Bounds
// within 32,768 units of zero need no origin (position_frame.hpp).
glm::dvec3 choose_origin(const LasInfo& info, glm::dvec3 first) {
  bool inside = true;
  glm::dvec3 centre;
  for (int a = 0; a < 3; ++a) {
    const double lo = info.min[a], hi = info.max[a];
    const double reach = info.scale[a] * 2147483648.0;
    inside = inside && std::isfinite(lo) && std::isfinite(hi) && lo <= first[a] + info.scale[a] &&
             first[a] - info.scale[a] <= hi && lo >= info.offset[a] - reach &&
             hi <= info.offset[a] + reach;
    centre[a] = 0.5 * (lo + hi);
  }
  const glm::dvec3 lo(info.min[0], info.min[1], info.min[2]);
  const glm::dvec3 hi(info.max[0], info.max[1], info.max[2]);
  if (inside && detail::near_zero(lo, hi)) return glm::dvec3(0.0);
  return glm::round(inside ? centre : first);
}

// The colours: 8 bits for drawing, and the file's 16 bits where the 8 do
// not give them back. The spec scales colours to 16 bits (255 -> 65535);
// some writers store 8-bit values in the 16-bit fields.
void keep_colours(std::vector<glm::u16vec3>& rgb16, std::uint16_t max_channel, PointSet& points) {
  const int shift = max_channel <= 255 ? 0 : 8;
  points.colors.resize(rgb16.size());
  bool deep = false;
  for (std::size_t i = 0; i < rgb16.size(); ++i) {
    const glm::u16vec3 c = rgb16[i];
    points.colors[i] = glm::u8vec4(glm::u16vec3(c >> std::uint16_t(shift)), 255);
    // What an export writes from 8 bits: c * 257.
    deep = deep || c != glm::u16vec3(points.colors[i]) * std::uint16_t(257);
  }
  if (deep) points.colors16 = std::move(rgb16);
}

PointSet read_points(const Source& f, const Parsed& parsed, const WarningSink& warn) {
  const LasInfo& info = parsed.info;
  PointSet points;
  points.frame.z_up = true;  // the LAS convention: x, y on the map, z the height
  const std::uint64_t n = info.point_count;
  points.positions.resize(static_cast<std::size_t>(n));
  const std::uint32_t rgb_at = kRgbAt[info.point_format];
  std::vector<glm::u16vec3> rgb16;
  if (rgb_at != 0) rgb16.resize(static_cast<std::size_t>(n));
  const std::uint32_t length = info.record_length;
  const std::size_t chunk_points = std::max<std::size_t>(1, (std::size_t{1} << 20) / length);
  std::vector<unsigned char> chunk(chunk_points * length);
  const glm::dvec3 scale(info.scale[0], info.scale[1], info.scale[2]);
  const glm::dvec3 offset(info.offset[0], info.offset[1], info.offset[2]);
  glm::dvec3 origin(0.0);
  std::uint16_t max_channel = 0;
  std::vector<glm::dvec3>& exact = points.exact_positions;
  bool keep_exact = false;
  std::vector<std::string> not_kept;
  detail::LasFields fields(info, static_cast<std::size_t>(n), not_kept);
  for (std::uint64_t begin = 0; begin < n; begin += chunk_points) {
    const std::size_t count =
        static_cast<std::size_t>(std::min<std::uint64_t>(chunk_points, n - begin));
    f.read(parsed.point_offset + begin * length, chunk.data(), count * length);
    fields.read(chunk.data(), count, length);
    for (std::size_t i = 0; i < count; ++i) {
      const unsigned char* r = chunk.data() + i * length;
      const glm::dvec3 p =
          glm::dvec3(get<std::int32_t>(r), get<std::int32_t>(r + 4), get<std::int32_t>(r + 8)) *
              scale +
          offset;
      if (begin + i == 0) {
        origin = choose_origin(info, p);
        points.frame.origin = origin;
      }
      const std::size_t k = static_cast<std::size_t>(begin) + i;
      points.positions[k] = glm::vec3(p - origin);
      if (!keep_exact && !detail::float_exact(points.positions[k], origin, p)) {
        // The floats do not give the file's coordinates back here: they are
        // kept for an export (a build drops them).
        keep_exact = true;
        exact.reserve(static_cast<std::size_t>(n));
        for (std::size_t j = 0; j < k; ++j)
          exact.push_back(origin + glm::dvec3(points.positions[j]));
      }
      if (keep_exact) exact.push_back(p);
      if (rgb_at != 0) {
        const glm::u16vec3 c(get<std::uint16_t>(r + rgb_at), get<std::uint16_t>(r + rgb_at + 2),
                             get<std::uint16_t>(r + rgb_at + 4));
        rgb16[static_cast<std::size_t>(begin) + i] = c;
        max_channel = std::max({max_channel, c.x, c.y, c.z});
      }
    }
  }
  if (rgb_at != 0) keep_colours(rgb16, max_channel, points);
  const std::vector<std::string> rounded = fields.take(points.attributes);
  if (warn) {
    if (info.waveform)
      warn("the waveform packets of point format " + std::to_string(info.point_format) +
           " are not read");
    if (!not_kept.empty()) warn("not kept: " + detail::join_some(not_kept));
    if (!rounded.empty())
      warn("64-bit integers beyond 2^53 kept to 53 bits: " + detail::join(rounded));
  }
  return points;
}

PointSet load(const Source& f, const std::string& name, LasLoadReport* report,
              const WarningSink& warn) {
  try {
    const Parsed parsed = parse_header(f);
    const WarningSink named = [&](const std::string& w) {
      if (warn) warn(name + ": " + w);
    };
    PointSet points = read_points(f, parsed, warn ? named : WarningSink{});
    points.frame.crs = parsed.info.crs;
    points.frame.crs_records = parsed.info.crs_records;
    points.records = parsed.info.records;
    points.frame.resolution =
        glm::dvec3(parsed.info.scale[0], parsed.info.scale[1], parsed.info.scale[2]);
    points.frame.grid_offset =
        glm::dvec3(parsed.info.offset[0], parsed.info.offset[1], parsed.info.offset[2]);
    points.adjusted_gps_time = (parsed.info.global_encoding & 1u) != 0;
    if (report) report->info = parsed.info;
    return points;
  } catch (const LasError& e) {
    throw InputError(name + ": " + e.what());
  }
}

}  // namespace

bool is_own_las(const std::filesystem::path& path) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC | O_NONBLOCK | O_NOFOLLOW);
  if (fd < 0) return false;
  struct Close {
    int fd;
    ~Close() { ::close(fd); }
  } closer{fd};
  struct stat st {};
  if (::fstat(fd, &st) != 0 || !S_ISREG(st.st_mode)) return false;
  try {
    const FileSource source(fd, static_cast<std::uint64_t>(st.st_size), path);
    const Parsed parsed = parse_header(source);
    return parsed.info.generating_software.starts_with("treecut") &&
           parsed.end == static_cast<std::uint64_t>(st.st_size);
  } catch (const std::exception&) {
    return false;
  }
}

bool looks_like_las(std::string_view bytes) {
  return bytes.size() >= 4 && bytes.substr(0, 4) == "LASF";
}

PointSet load_las_from_memory(std::string_view bytes, const std::string& name,
                              LasLoadReport* report, const WarningSink& warn) {
  return load(MemorySource(bytes), name, report, warn);
}

PointSet load_las(const std::filesystem::path& path, LasLoadReport* report,
                  const WarningSink& warn) {
  const std::string name = quoted_name(path);
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC | O_NONBLOCK);
  if (fd < 0) throw InputError(system_error_text(path, errno));
  struct Close {
    int fd;
    ~Close() { ::close(fd); }
  } closer{fd};
  struct stat st {};
  if (::fstat(fd, &st) != 0) throw InputError(system_error_text(path, errno));
  if (!S_ISREG(st.st_mode)) throw InputError(name + ": not a regular file");
  const FileSource source(fd, static_cast<std::uint64_t>(st.st_size), path);
  return load(source, name, report, warn);
}

}  // namespace treecut
