// LAS export (ASPRS LAS 1.2, point data record formats 0 and 2): what `gen`
// and the tests write to make LAS files, and what `treecut export` would
// write. Through an AtomicFile, as save_ply.
#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstring>
#include <limits>
#include <stdexcept>
#include <string>

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
    xyz[static_cast<std::size_t>(a)] = static_cast<std::int32_t>(std::llround((q[a] - g.offset[a]) / scale));
  }
  return xyz;
}

std::string header(const PointSet& points, const Grid& g, double scale, bool rgb) {
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
  put<std::uint16_t>(h, 227);   // header size
  put<std::uint32_t>(h, 227);   // offset to point data: no VLRs
  put<std::uint32_t>(h, 0);     // VLRs
  h.push_back(static_cast<char>(rgb ? 2 : 0));
  put<std::uint16_t>(h, rgb ? 26 : 20);
  put<std::uint32_t>(h, static_cast<std::uint32_t>(points.size()));
  put<std::uint32_t>(h, static_cast<std::uint32_t>(points.size()));  // all first returns
  for (int r = 1; r < 5; ++r) put<std::uint32_t>(h, 0);
  for (int a = 0; a < 3; ++a) put<double>(h, scale);
  for (int a = 0; a < 3; ++a) put<double>(h, g.offset[a]);
  for (int a = 0; a < 3; ++a) {
    put<double>(h, g.max[a]);
    put<double>(h, g.min[a]);
  }
  return h;
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
  const bool rgb = points.has_colors();

  AtomicFile file(path);  // throws "PATH: REASON"
  constexpr std::size_t kChunk = std::size_t{1} << 20;
  std::string chunk = header(points, g, scale, rgb);
  for (std::size_t i = 0; i < points.size(); ++i) {
    for (const std::int32_t v : integers(points, i, g, scale)) put<std::int32_t>(chunk, v);
    put<std::uint16_t>(chunk, 0);  // intensity
    chunk.push_back(0x09);         // return 1 of 1
    chunk.push_back(1);            // classification: unclassified
    chunk.push_back(0);            // scan angle rank
    chunk.push_back(0);            // user data
    put<std::uint16_t>(chunk, 0);  // point source id
    if (rgb) {
      const glm::u8vec4 c = points.colors[i];
      // 8 to 16 bits: 255 becomes 65535.
      put<std::uint16_t>(chunk, static_cast<std::uint16_t>(c.x * 257));
      put<std::uint16_t>(chunk, static_cast<std::uint16_t>(c.y * 257));
      put<std::uint16_t>(chunk, static_cast<std::uint16_t>(c.z * 257));
    }
    if (chunk.size() >= kChunk) {
      file.write(chunk);
      chunk.clear();
    }
  }
  file.write(chunk);
  file.commit();
}

}  // namespace treecut
