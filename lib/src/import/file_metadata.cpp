// A file's metadata as comments, and the coordinate system in words
// (file_metadata.hpp).
#include "file_metadata.hpp"

#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>

#include "little_endian.hpp"

namespace treecut::detail {

namespace {

std::string hex(std::string_view bytes) {
  static constexpr char kDigits[] = "0123456789abcdef";
  std::string out;
  out.reserve(2 * bytes.size());
  for (const char c : bytes) {
    const auto u = static_cast<unsigned char>(c);
    out += kDigits[u >> 4], out += kDigits[u & 15];
  }
  return out;
}

int nibble(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}

bool unhex(std::string_view text, std::string& out) {
  if (text.size() % 2 != 0) return false;
  std::string bytes;
  bytes.reserve(text.size() / 2);
  for (std::size_t i = 0; i < text.size(); i += 2) {
    const int hi = nibble(text[i]), lo = nibble(text[i + 1]);
    if (hi < 0 || lo < 0) return false;
    bytes.push_back(static_cast<char>(hi * 16 + lo));
  }
  out = std::move(bytes);
  return true;
}

constexpr std::string_view kPrefix = "treecut ";

// COUNT finite numbers within the coordinate limit, separated by single
// spaces, and nothing else.
bool numbers(std::string_view text, double* out, std::size_t count) {
  for (std::size_t k = 0; k < count; ++k) {
    const std::size_t end = std::min(text.find(' '), text.size());
    const auto [p, ec] = std::from_chars(text.data(), text.data() + end, out[k]);
    if (ec != std::errc() || p != text.data() + end || !std::isfinite(out[k]) ||
        std::fabs(out[k]) > double(kMaxCoordinate))
      return false;
    text.remove_prefix(std::min(end + 1, text.size()));
  }
  return text.empty();
}

// The in-place values of the GeoTIFF keys treecut reads.
struct GeoKeys {
  std::uint16_t model = 0, geographic = 0, projected = 0, vertical = 0;
  std::size_t count = 0;
};

GeoKeys geo_keys(const std::string& keys) {
  GeoKeys g;
  if (keys.size() < 8) return g;
  const auto* p = reinterpret_cast<const unsigned char*>(keys.data());
  g.count = get_le<std::uint16_t>(p + 6);
  for (std::size_t k = 0; k < g.count && 8 + 8 * (k + 1) <= keys.size(); ++k) {
    const unsigned char* e = p + 8 + 8 * k;
    const std::uint16_t id = get_le<std::uint16_t>(e), location = get_le<std::uint16_t>(e + 2);
    if (location != 0) continue;  // the value lives in a parameter record
    const std::uint16_t value = get_le<std::uint16_t>(e + 6);
    if (id == 1024) g.model = value;  // GTModelTypeGeoKey: 1 projected, 2 geographic
    if (id == 2048) g.geographic = value;
    if (id == 3072) g.projected = value;
    if (id == 4096) g.vertical = value;
  }
  return g;
}

std::string code(std::uint16_t value) {
  return value == 32767 ? std::string("user-defined") : "EPSG:" + std::to_string(value);
}

// The WKT's first keyword (PROJCS, GEOGCS, PROJCRS, GEOGCRS, COMPD_CS...).
std::string wkt_keyword(const std::string& wkt) {
  std::size_t at = wkt.find_first_not_of(" \t\r\n");
  if (at == std::string::npos) return {};
  const std::size_t end = wkt.find_first_of("[( \t\r\n", at);
  return wkt.substr(at, end == std::string::npos ? std::string::npos : end - at);
}

}  // namespace

std::vector<std::string> metadata_lines(const PointSet& points, bool relative) {
  std::vector<std::string> lines;
  const glm::dvec3 o = points.frame.origin;
  if (relative && o != glm::dvec3(0.0)) {
    char line[128];
    std::snprintf(line, sizeof line, "treecut origin %.17g %.17g %.17g", o.x, o.y, o.z);
    lines.emplace_back(line);
  }
  const CrsRecords& r = points.frame.crs_records;
  const std::pair<const char*, const std::string*> records[] = {{"crs-wkt", &r.wkt},
                                                                {"geo-keys", &r.geo_keys},
                                                                {"geo-doubles", &r.geo_doubles},
                                                                {"geo-ascii", &r.geo_ascii}};
  for (const auto& [key, bytes] : records) {
    if (!bytes->empty()) lines.push_back(std::string(kPrefix) + key + " " + hex(*bytes));
  }
  if (points.adjusted_gps_time)
    lines.push_back(std::string(kPrefix) + "gps-time adjusted-standard");
  for (const FileRecord& k : points.records) {
    lines.push_back(std::string(kPrefix) + "record " + hex(k.user) + " " + std::to_string(k.id) +
                    " " + hex(k.description) + " " + hex(k.payload) + "x");
  }
  const glm::dvec3 step = points.frame.resolution, g = points.frame.grid_offset;
  if (step.x > 0.0 && step.y > 0.0 && step.z > 0.0 && !relative) {
    char line[256];
    std::snprintf(line, sizeof line, "treecut grid %.17g %.17g %.17g %.17g %.17g %.17g", step.x,
                  step.y, step.z, g.x, g.y, g.z);
    lines.emplace_back(line);
  }
  return lines;
}

std::string name_line(const std::string& written, const std::string& original) {
  return std::string(kPrefix) + "name " + written + " " + hex(original);
}

bool read_metadata_line(std::string_view text, PointSet& points) {
  if (!text.starts_with(kPrefix)) return false;
  text.remove_prefix(kPrefix.size());
  const std::size_t space = text.find(' ');
  if (space == std::string_view::npos) return false;
  const std::string_view key = text.substr(0, space), value = text.substr(space + 1);
  CrsRecords& r = points.frame.crs_records;
  std::string* record = key == "crs-wkt"       ? &r.wkt
                        : key == "geo-keys"    ? &r.geo_keys
                        : key == "geo-doubles" ? &r.geo_doubles
                        : key == "geo-ascii"   ? &r.geo_ascii
                                               : nullptr;
  if (record != nullptr) {
    // A record is at most 64 kB in a VLR; a comment that claims more is not ours.
    if (value.size() > 2 * 65535 || !unhex(value, *record)) return false;
    points.frame.crs = crs_text(r);
    return true;
  }
  if (key == "origin" || key == "grid") {
    double v[6];
    const std::size_t count = key == "origin" ? 3 : 6;
    if (!numbers(value, v, count)) return false;
    if (key == "origin") {
      points.frame.origin += glm::dvec3(v[0], v[1], v[2]);
    } else {
      if (!(v[0] > 0.0 && v[1] > 0.0 && v[2] > 0.0)) return false;
      points.frame.resolution = glm::dvec3(v[0], v[1], v[2]);
      points.frame.grid_offset = glm::dvec3(v[3], v[4], v[5]);
    }
    return true;
  }
  if (key == "name") {
    const std::size_t gap = value.find(' ');
    if (gap == std::string_view::npos) return false;
    std::string original;
    if (!unhex(value.substr(gap + 1), original) || original.empty() ||
        original.size() > kMaxAttributeName)
      return false;
    for (PointAttribute& a : points.attributes) {
      if (a.name == value.substr(0, gap)) {
        a.name = original;
        a.kind = attribute_kind_for(original);
        return true;
      }
    }
    return false;
  }
  if (key == "record") {
    // USER ID DESCRIPTION PAYLOAD, hex but the ID; the payload ends in 'x'
    // (it may be empty).
    FileRecord k;
    std::string_view rest = value;
    auto word = [&] {
      const std::size_t end = std::min(rest.find(' '), rest.size());
      const std::string_view w = rest.substr(0, end);
      rest.remove_prefix(std::min(end + 1, rest.size()));
      return w;
    };
    const std::string_view user = word(), id = word(), description = word(), payload = word();
    unsigned number = 0;
    const auto [p, ec] = std::from_chars(id.data(), id.data() + id.size(), number);
    if (!rest.empty() || ec != std::errc() || p != id.data() + id.size() || number > 65535 ||
        !payload.ends_with('x') || !unhex(user, k.user) || k.user.size() > 16 ||
        !unhex(description, k.description) || k.description.size() > 32 ||
        !unhex(payload.substr(0, payload.size() - 1), k.payload))
      return false;
    k.id = static_cast<std::uint16_t>(number);
    points.records.push_back(std::move(k));
    return true;
  }
  if (key == "gps-time" && value == "adjusted-standard") {
    points.adjusted_gps_time = true;
    return true;
  }
  return false;
}

std::string crs_text(const CrsRecords& r) {
  if (!r.wkt.empty()) {
    std::string wkt = r.wkt.substr(0, std::strlen(r.wkt.c_str()));
    if (wkt.size() > 400) wkt = wkt.substr(0, 400) + "...";
    return "WKT: " + wkt;
  }
  if (r.geo_keys.empty()) return {};
  const GeoKeys g = geo_keys(r.geo_keys);
  std::string out;
  if (g.projected != 0) {
    out = code(g.projected) + " (projected)";
  } else if (g.geographic != 0) {
    out = code(g.geographic) + " (geographic)";
  } else if (g.model == 1 || g.model == 2) {
    out = std::string("user-defined (") + (g.model == 1 ? "projected" : "geographic") + ")";
  } else {
    return "GeoTIFF: " + std::to_string(g.count) + " keys";
  }
  if (g.vertical != 0) out += ", vertical " + code(g.vertical);
  return out;
}

bool crs_is_geographic(const CrsRecords& r) {
  if (!r.wkt.empty()) {
    const std::string k = wkt_keyword(r.wkt);
    return k == "GEOGCS" || k == "GEOGCRS" || k == "GEOGRAPHICCRS";
  }
  const GeoKeys g = geo_keys(r.geo_keys);
  return g.projected == 0 && (g.model == 2 || g.geographic != 0);
}

}  // namespace treecut::detail
