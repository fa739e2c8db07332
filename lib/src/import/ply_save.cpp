// PLY export: binary little-endian, written through an AtomicFile (temporary
// beside the target, every write checked, renamed into place when complete),
// so a concurrent reader sees either the old file or the new one and a full
// disk leaves no truncated model behind.
#include <algorithm>
#include <bit>
#include <cstring>
#include <limits>
#include <stdexcept>
#include <string>

#include "little_endian.hpp"
#include "treecut/file_io.hpp"
#include "treecut/ply.hpp"

namespace treecut {

namespace {

using detail::put_le;

void check_sizes(const PointSet& points) {
  const std::size_t n = points.size();
  auto check = [n](std::size_t size, const char* what) {
    if (size != 0 && size != n) {
      throw std::invalid_argument(std::string("save_ply: ") + what + " has " +
                                  std::to_string(size) + " entries for " + std::to_string(n) +
                                  " points");
    }
  };
  check(points.normals.size(), "normals");
  check(points.colors.size(), "colors");
  check(points.radii.size(), "radii");
  for (const PointAttribute& a : points.attributes) {
    if (a.values.size() != n) check(a.values.size(), "an attribute");
  }
  if (n > static_cast<std::size_t>(std::numeric_limits<std::int32_t>::max())) {
    throw std::invalid_argument("save_ply: too many points for 32-bit face indices");
  }
  for (const glm::uvec3& t : points.triangles) {
    if (t.x >= n || t.y >= n || t.z >= n) {
      throw std::invalid_argument("save_ply: a triangle refers to a point that does not exist");
    }
  }
}

// The attributes' property names: one token, unique beside the roles
// ("height above ground" -> height_above_ground; a LAS extra-bytes field
// called red beside the colour's red -> red_attribute).
std::vector<std::string> attribute_names(const PointSet& points) {
  std::vector<std::string> used = {"x",   "y",     "z",    "nx",     "ny",   "nz",
                                   "red", "green", "blue", "radius", "alpha"};
  std::vector<std::string> names;
  for (const PointAttribute& a : points.attributes) {
    std::string name = a.name.empty() ? "attribute" : a.name;
    for (char& c : name) {
      if (c == ' ' || c == '\t' || static_cast<unsigned char>(c) < 0x20) c = '_';
    }
    while (std::find(used.begin(), used.end(), name) != used.end()) name += "_attribute";
    used.push_back(name);
    names.push_back(name);
  }
  return names;
}

std::string header(const PointSet& points) {
  std::string out = "ply\nformat binary_little_endian 1.0\ncomment written by treecut\n";
  out += "element vertex " + std::to_string(points.size()) + "\n";
  out += "property float x\nproperty float y\nproperty float z\n";
  if (points.has_normals()) out += "property float nx\nproperty float ny\nproperty float nz\n";
  if (points.has_colors()) out += "property uchar red\nproperty uchar green\nproperty uchar blue\n";
  if (points.has_radii()) out += "property float radius\n";
  // An attribute with an offset (a GPS time of 3e8 s) as a double: a float
  // of the file's value would lose what the offset keeps.
  const std::vector<std::string> names = attribute_names(points);
  for (std::size_t k = 0; k < names.size(); ++k) {
    out += std::string("property ") + (points.attributes[k].offset != 0.0 ? "double " : "float ") +
           names[k] + "\n";
  }
  if (!points.triangles.empty()) {
    out += "element face " + std::to_string(points.triangles.size()) + "\n";
    out += "property list uchar int vertex_indices\n";
  }
  out += "end_header\n";
  return out;
}

}  // namespace

void save_ply(const std::filesystem::path& path, const PointSet& points) {
  check_sizes(points);
  AtomicFile file(path);  // throws "PATH: REASON" (a directory or FIFO at PATH, a read-only folder)

  // Rows are encoded into a chunk and written in large blocks.
  constexpr std::size_t kChunk = std::size_t{1} << 20;
  std::string chunk = header(points);
  auto flush = [&](bool force) {
    if (chunk.size() < kChunk && !force) return;
    file.write(chunk);
    chunk.clear();
  };
  for (std::size_t i = 0; i < points.size(); ++i) {
    const glm::vec3& p = points.positions[i];
    put_le(chunk, p.x);
    put_le(chunk, p.y);
    put_le(chunk, p.z);
    if (points.has_normals()) {
      const glm::vec3& n = points.normals[i];
      put_le(chunk, n.x);
      put_le(chunk, n.y);
      put_le(chunk, n.z);
    }
    if (points.has_colors()) {
      const glm::u8vec4& c = points.colors[i];
      chunk.push_back(static_cast<char>(c.x));
      chunk.push_back(static_cast<char>(c.y));
      chunk.push_back(static_cast<char>(c.z));
    }
    if (points.has_radii()) put_le(chunk, points.radii[i]);
    for (const PointAttribute& a : points.attributes) {
      if (a.offset != 0.0) {
        put_le(chunk, a.offset + double(a.values[i]));
      } else {
        put_le(chunk, a.values[i]);
      }
    }
    flush(false);
  }
  for (const glm::uvec3& t : points.triangles) {
    chunk.push_back(3);
    put_le(chunk, static_cast<std::int32_t>(t.x));
    put_le(chunk, static_cast<std::int32_t>(t.y));
    put_le(chunk, static_cast<std::int32_t>(t.z));
    flush(false);
  }
  flush(true);
  file.commit();
}

}  // namespace treecut
