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

#include "file_metadata.hpp"
#include "little_endian.hpp"
#include "ply_format.hpp"
#include "treecut/file_io.hpp"
#include "treecut/ply.hpp"
#include "typed_values.hpp"

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
  check(points.colors16.size(), "colors16");
  check(points.exact_positions.size(), "exact_positions");
  check(points.radii.size(), "radii");
  for (const PointAttribute& a : points.attributes) check(a.stored(), "an attribute");
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

std::string_view ply_type(ValueType type) {
  static constexpr std::string_view kName[10] = {"uchar", "char",   "ushort", "short", "uint",
                                                 "int",   "double", "double", "float", "double"};
  return kName[static_cast<std::size_t>(type)];
}

// What a row holds: positions in double where the model has an origin (a
// PLY has none: the file's coordinates, as LAS's), each attribute in a
// type that holds it.
struct Layout {
  bool doubles = false;
  std::vector<ValueType> types;
};

Layout layout_of(const PointSet& points, const SaveOptions& options) {
  Layout l;
  l.doubles = (points.frame.origin != glm::dvec3(0.0) || !points.exact_positions.empty()) &&
              !options.relative;
  for (const PointAttribute& a : points.attributes)
    l.types.push_back(detail::output_type(a, points.size(), /*no_int64=*/true));
  return l;
}

std::string header(const PointSet& points, const Layout& l, const SaveOptions& options) {
  std::string out = "ply\nformat binary_little_endian 1.0\ncomment written by treecut\n";
  for (const std::string& line : detail::metadata_lines(points, options.relative))
    out += "comment " + line + "\n";
  const std::vector<std::string> names = attribute_names(points);
  for (std::size_t k = 0; k < names.size(); ++k) {
    if (names[k] != points.attributes[k].name)
      out += "comment " + detail::name_line(names[k], points.attributes[k].name) + "\n";
  }
  out += "element vertex " + std::to_string(points.size()) + "\n";
  out += l.doubles ? "property double x\nproperty double y\nproperty double z\n"
                   : "property float x\nproperty float y\nproperty float z\n";
  if (points.has_normals()) out += "property float nx\nproperty float ny\nproperty float nz\n";
  if (points.has_colors()) {
    out += points.colors16.empty()
               ? "property uchar red\nproperty uchar green\nproperty uchar blue\n"
               : "property ushort red\nproperty ushort green\nproperty ushort blue\n";
  }
  if (points.has_radii()) out += "property float radius\n";
  for (std::size_t k = 0; k < names.size(); ++k)
    out += "property " + std::string(ply_type(l.types[k])) + " " + names[k] + "\n";
  if (!points.triangles.empty()) {
    out += "element face " + std::to_string(points.triangles.size()) + "\n";
    out += "property list uchar int vertex_indices\n";
  }
  out += "end_header\n";
  return out;
}

}  // namespace

void save_ply(const std::filesystem::path& path, const PointSet& points,
              const SaveOptions& options) {
  check_sizes(points);
  const Layout l = layout_of(points, options);
  AtomicFile file(path);  // throws "PATH: REASON" (a directory or FIFO at PATH, a read-only folder)

  // Rows are encoded into a chunk and written in large blocks.
  constexpr std::size_t kChunk = std::size_t{1} << 20;
  std::string chunk = header(points, l, options);
  auto flush = [&](bool force) {
    if (chunk.size() < kChunk && !force) return;
    file.write(chunk);
    chunk.clear();
  };
  const glm::dvec3 origin = points.frame.origin;
  for (std::size_t i = 0; i < points.size(); ++i) {
    const glm::vec3& p = points.positions[i];
    if (l.doubles) {
      const glm::dvec3 q =
          points.exact_positions.empty() ? origin + glm::dvec3(p) : points.exact_positions[i];
      put_le(chunk, q.x), put_le(chunk, q.y), put_le(chunk, q.z);
    } else {
      put_le(chunk, p.x), put_le(chunk, p.y), put_le(chunk, p.z);
    }
    if (points.has_normals()) {
      const glm::vec3& n = points.normals[i];
      put_le(chunk, n.x), put_le(chunk, n.y), put_le(chunk, n.z);
    }
    if (points.has_colors() && points.colors16.empty()) {
      const glm::u8vec4& c = points.colors[i];
      chunk.push_back(static_cast<char>(c.x));
      chunk.push_back(static_cast<char>(c.y));
      chunk.push_back(static_cast<char>(c.z));
    } else if (points.has_colors()) {
      const glm::u16vec3& c = points.colors16[i];
      put_le(chunk, c.x), put_le(chunk, c.y), put_le(chunk, c.z);
    }
    if (points.has_radii()) put_le(chunk, points.radii[i]);
    for (std::size_t k = 0; k < points.attributes.size(); ++k)
      detail::put_value(chunk, l.types[k], points.attributes[k].value(i));
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

bool is_own_ply(const std::filesystem::path& path) {
  // The header (at most 64 KiB here) and the size it implies: rows of a
  // fixed stride and triangles of 13 bytes, as save_ply writes them.
  const FileHead head = read_file_head(path, 65536);
  if (!head.bytes.starts_with("ply\nformat binary_little_endian 1.0\ncomment written by treecut\n"))
    return false;
  try {
    const ply::Header h = ply::parse_header(head.bytes);
    std::uint64_t size = h.body_offset;
    for (const ply::Element& e : h.elements) {
      if (e.name == "face" && e.properties.size() == 1 && e.properties[0].is_list) {
        size += e.count * 13;
      } else if (!e.has_lists()) {
        size += e.count * e.fixed_stride();
      } else {
        return false;
      }
    }
    return head.size == size;
  } catch (const std::exception&) {
    return false;
  }
}

}  // namespace treecut
