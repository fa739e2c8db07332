// The point records of a LAS file, in batches (LasReader, treecut/las.hpp):
// positions relative to an origin fixed when the file opens, RGB and every
// field as an attribute (las_fields.hpp). The header is las_read.cpp's.

#include <algorithm>
#include <cmath>
#include <glm/gtc/type_precision.hpp>
#include <optional>
#include <string>
#include <vector>

#include "attribute_column.hpp"
#include "las_fields.hpp"
#include "las_source.hpp"
#include "little_endian.hpp"
#include "position_frame.hpp"
#include "treecut/error.hpp"
#include "treecut/file_io.hpp"

namespace treecut {

namespace {

using detail::LasError;

template <class T>
T get(const unsigned char* p) {
  return detail::get_le<T>(p);
}

glm::dvec3 record_position(const unsigned char* r, const LasInfo& info) {
  return glm::dvec3(get<std::int32_t>(r), get<std::int32_t>(r + 4), get<std::int32_t>(r + 8)) *
             glm::dvec3(info.scale[0], info.scale[1], info.scale[2]) +
         glm::dvec3(info.offset[0], info.offset[1], info.offset[2]);
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
// some writers store 8-bit values in the 16-bit fields: a file whose
// channels so far all fit 8 bits (DEEP_FILE false) is taken for one.
void keep_colours(std::vector<glm::u16vec3>& rgb16, bool deep_file, PointSet& points) {
  const int shift = deep_file ? 8 : 0;
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

}  // namespace

struct LasReader::State {
  std::unique_ptr<detail::ByteSource> source;
  std::string name;
  WarningSink warn;  // the reader's, each line after the file's name
  detail::LasParsed parsed;
  std::uint64_t next = 0;
  glm::dvec3 origin{0.0};
  bool deep_colours = false;  // a channel past 255 seen: the file's colours are 16-bit
  // The colours are sampled by the first batch, not when the file opens: a
  // reader opened for its header alone (build_memory_estimate, over a
  // folder of thousands of tiles) reads no more than the header.
  bool sampled = false;
  std::vector<std::string> rounded;
  std::vector<unsigned char> chunk;

  State() = default;
  State(const State&) = delete;
  State& operator=(const State&) = delete;

  // The header and the origin; what will not be kept, said once.
  void open() {
    try {
      parsed = detail::parse_las_header(*source);
      const LasInfo& info = parsed.info;
      unsigned char first[12];
      source->read(parsed.point_offset, first, sizeof first);
      origin = choose_origin(info, record_position(first, info));
      std::vector<std::string> not_kept;
      const detail::LasFields fields(info, 0, not_kept);
      if (warn && info.waveform)
        warn("the waveform packets of point format " + std::to_string(info.point_format) +
             " are not read");
      if (warn && !not_kept.empty()) warn("not kept: " + detail::join_some(not_kept));
    } catch (const LasError& e) {
      throw InputError(name + ": " + e.what());
    }
  }

  // Whether the file stores 16-bit colours, as far as records spread over
  // it say (the first and the last among them), so that a batch read
  // before the one with a bright channel takes its colours as the whole
  // file's read does. A batch that sees one decides for the rest.
  [[nodiscard]] bool sampled_colours_are_deep() const {
    const LasInfo& info = parsed.info;
    const std::uint32_t rgb_at = detail::kLasRgbAt[info.point_format];
    if (rgb_at == 0) return false;
    constexpr std::uint64_t kSamples = 1024;
    const std::uint64_t n = info.point_count, step = std::max<std::uint64_t>(1, n / kSamples);
    for (std::uint64_t i = 0; i < n; i = i + step < n || i == n - 1 ? i + step : n - 1) {
      unsigned char c[6];
      source->read(parsed.point_offset + i * info.record_length + rgb_at, c, sizeof c);
      if (std::max({get<std::uint16_t>(c), get<std::uint16_t>(c + 2), get<std::uint16_t>(c + 4)}) >
          255)
        return true;
    }
    return false;
  }

  // The frame every batch shares.
  void frame(PointSet& points) const {
    const LasInfo& info = parsed.info;
    points.frame.z_up = true;  // the LAS convention: x, y on the map, z the height
    points.frame.origin = origin;
    points.frame.crs = info.crs;
    points.frame.crs_records = info.crs_records;
    points.records = info.records;
    points.frame.resolution = glm::dvec3(info.scale[0], info.scale[1], info.scale[2]);
    points.frame.grid_offset = glm::dvec3(info.offset[0], info.offset[1], info.offset[2]);
    points.adjusted_gps_time = (info.global_encoding & 1u) != 0;
  }

  // The next N points into POINTS; their positions alone where
  // POSITIONS_ONLY (no colours, fields or exact positions).
  void read(PointSet& points, std::size_t n, bool positions_only);
};

// N records from `next`, in chunks of about 1 MiB. POSITIONS_ONLY (the
// chunked build's counting pass) takes the same loop and skips the rest.
void LasReader::State::read(PointSet& points, std::size_t n, bool positions_only) {
  const LasInfo& info = parsed.info;
  points.positions.resize(n);
  const std::uint32_t rgb_at = positions_only ? 0 : detail::kLasRgbAt[info.point_format];
  std::vector<glm::u16vec3> rgb16;
  if (rgb_at != 0) rgb16.resize(n);
  if (rgb_at != 0 && !sampled) deep_colours = deep_colours || sampled_colours_are_deep();
  if (!positions_only) sampled = true;
  const std::uint32_t length = info.record_length;
  const std::size_t chunk_points = std::max<std::size_t>(1, (std::size_t{1} << 20) / length);
  chunk.resize(chunk_points * length);
  std::vector<glm::dvec3>& exact = points.exact_positions;
  bool keep_exact = false;
  std::vector<std::string> not_kept;
  std::optional<detail::LasFields> fields;
  if (!positions_only) fields.emplace(info, n, not_kept);
  for (std::size_t begin = 0; begin < n; begin += chunk_points) {
    const std::size_t count = std::min(chunk_points, n - begin);
    source->read(parsed.point_offset + (next + begin) * length, chunk.data(), count * length);
    if (fields) fields->read(chunk.data(), count, length);
    for (std::size_t i = 0; i < count; ++i) {
      const unsigned char* r = chunk.data() + i * length;
      const glm::dvec3 p = record_position(r, info);
      const std::size_t k = begin + i;
      points.positions[k] = glm::vec3(p - origin);
      if (positions_only) continue;
      if (!keep_exact && !detail::float_exact(points.positions[k], origin, p)) {
        // The floats do not give the file's coordinates back here: they are
        // kept for an export (a build drops them).
        keep_exact = true;
        exact.reserve(n);
        for (std::size_t j = 0; j < k; ++j)
          exact.push_back(origin + glm::dvec3(points.positions[j]));
      }
      if (keep_exact) exact.push_back(p);
      if (rgb_at != 0) {
        const glm::u16vec3 c(get<std::uint16_t>(r + rgb_at), get<std::uint16_t>(r + rgb_at + 2),
                             get<std::uint16_t>(r + rgb_at + 4));
        rgb16[k] = c;
        deep_colours = deep_colours || std::max({c.x, c.y, c.z}) > 255;
      }
    }
  }
  if (!fields) return;
  if (rgb_at != 0) keep_colours(rgb16, deep_colours, points);
  for (std::string& r : fields->take(points.attributes)) {
    if (std::find(rounded.begin(), rounded.end(), r) == rounded.end())
      rounded.push_back(std::move(r));
  }
}

LasReader::LasReader(const std::filesystem::path& path, const WarningSink& warn)
    : state_(std::make_unique<State>()) {
  State& s = *state_;
  s.name = quoted_name(path);
  if (warn) s.warn = [warn, name = s.name](const std::string& w) { warn(name + ": " + w); };
  s.source = std::make_unique<detail::FileSource>(path);
  s.open();
}

LasReader::LasReader(std::string_view bytes, const std::string& name, const WarningSink& warn)
    : state_(std::make_unique<State>()) {
  State& s = *state_;
  s.name = name;
  if (warn) s.warn = [warn, name](const std::string& w) { warn(name + ": " + w); };
  s.source = std::make_unique<detail::MemorySource>(bytes);
  s.open();
}

LasReader::~LasReader() = default;
LasReader::LasReader(LasReader&&) noexcept = default;
LasReader& LasReader::operator=(LasReader&&) noexcept = default;

const LasInfo& LasReader::info() const {
  return state_->parsed.info;
}

std::uint64_t LasReader::remaining() const {
  return state_->parsed.info.point_count - state_->next;
}

PointSet LasReader::next(std::size_t max_points, bool positions_only) {
  State& s = *state_;
  const auto n = static_cast<std::size_t>(std::min<std::uint64_t>(max_points, remaining()));
  PointSet points;
  s.frame(points);
  if (n == 0) return points;
  try {
    s.read(points, n, positions_only);
  } catch (const LasError& e) {
    throw InputError(s.name + ": " + e.what());
  }
  s.next += n;
  if (remaining() == 0 && s.warn && !s.rounded.empty())
    s.warn("64-bit integers beyond 2^53 kept to 53 bits: " + detail::join(s.rounded));
  return points;
}

namespace {

PointSet load(LasReader reader, LasLoadReport* report) {
  PointSet points = reader.next(static_cast<std::size_t>(reader.remaining()));
  if (report) report->info = reader.info();
  return points;
}

}  // namespace

PointSet load_las_from_memory(std::string_view bytes, const std::string& name,
                              LasLoadReport* report, const WarningSink& warn) {
  return load(LasReader(bytes, name, warn), report);
}

PointSet load_las(const std::filesystem::path& path, LasLoadReport* report,
                  const WarningSink& warn) {
  return load(LasReader(path, warn), report);
}

}  // namespace treecut
