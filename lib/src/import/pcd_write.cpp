// PCD export (treecut/pcd.hpp): a v0.7 header, then the points ascii, packed
// or as LZF-compressed columns (liblzf).
#include <lzf.h>

#include <cstdio>
#include <stdexcept>
#include <string>
#include <vector>

#include "little_endian.hpp"
#include "treecut/file_io.hpp"
#include "treecut/pcd.hpp"

namespace treecut {

namespace {

// Every field is 4 bytes: x y z, the normal, rgb (U), the attributes (F).
struct Columns {
  std::vector<std::string> names;
  std::vector<char> types;
  std::size_t count() const { return names.size(); }
};

Columns columns_of(const PointSet& p) {
  Columns c{{"x", "y", "z"}, {'F', 'F', 'F'}};
  if (p.has_normals()) {
    for (const char* n : {"normal_x", "normal_y", "normal_z"})
      c.names.emplace_back(n), c.types.push_back('F');
  }
  if (p.has_colors()) c.names.emplace_back("rgb"), c.types.push_back('U');
  for (const PointAttribute& a : p.attributes) {
    std::string name = a.name;
    for (char& ch : name) {
      if (ch == ' ' || ch == '\t') ch = '_';
    }
    c.names.push_back(name), c.types.push_back('F');
  }
  return c;
}

// Field K of point I: a float's or the packed colour's 4 bytes.
std::uint32_t bits(const PointSet& p, std::size_t k, std::size_t i) {
  float f = 0.0f;
  if (k < 3) {
    f = p.positions[i][static_cast<glm::length_t>(k)];
  } else if (p.has_normals() && k < 6) {
    f = p.normals[i][static_cast<glm::length_t>(k - 3)];
  } else {
    const std::size_t after = 3 + (p.has_normals() ? 3 : 0);
    if (p.has_colors() && k == after) {
      const glm::u8vec4 c = p.colors[i];
      return 0xff000000u | (std::uint32_t{c.x} << 16) | (std::uint32_t{c.y} << 8) | c.z;
    }
    const PointAttribute& a = p.attributes[k - after - (p.has_colors() ? 1 : 0)];
    f = static_cast<float>(a.offset + double(a.values[i]));
  }
  std::uint32_t u;
  std::memcpy(&u, &f, 4);
  return u;
}

}  // namespace

void save_pcd(const std::filesystem::path& path, const PointSet& points, PcdData data) {
  const std::size_t n = points.size();
  if ((points.has_normals() && points.normals.size() != n) ||
      (points.has_colors() && points.colors.size() != n)) {
    throw std::invalid_argument("save_pcd: normals or colours differ from the point count");
  }
  for (const PointAttribute& a : points.attributes) {
    if (a.values.size() != n)
      throw std::invalid_argument("save_pcd: attribute " + a.name +
                                  " differs from the point count");
  }
  const Columns c = columns_of(points);
  std::string out = "# .PCD v0.7 - Point Cloud Data file format (treecut)\nVERSION 0.7\nFIELDS";
  for (const std::string& name : c.names) out += " " + name;
  out += "\nSIZE";
  for (std::size_t k = 0; k < c.count(); ++k) out += " 4";
  out += "\nTYPE";
  for (const char t : c.types) out += std::string(" ") + t;
  out += "\nCOUNT";
  for (std::size_t k = 0; k < c.count(); ++k) out += " 1";
  out += "\nWIDTH " + std::to_string(n) + "\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS " +
         std::to_string(n) + "\nDATA " +
         (data == PcdData::ascii    ? "ascii"
          : data == PcdData::binary ? "binary"
                                    : "binary_compressed") +
         "\n";
  AtomicFile file(path);  // throws "PATH: REASON"
  if (data == PcdData::ascii) {
    char text[32];
    for (std::size_t i = 0; i < n; ++i) {
      for (std::size_t k = 0; k < c.count(); ++k) {
        const std::uint32_t u = bits(points, k, i);
        float f;
        std::memcpy(&f, &u, 4);
        if (c.types[k] == 'U') {
          std::snprintf(text, sizeof text, "%u", u);
        } else {
          std::snprintf(text, sizeof text, "%.9g", double(f));
        }
        out += (k ? " " : "") + std::string(text);
      }
      out += "\n";
      if (out.size() > (1u << 20)) file.write(out), out.clear();
    }
  } else if (data == PcdData::binary) {
    for (std::size_t i = 0; i < n; ++i) {
      for (std::size_t k = 0; k < c.count(); ++k) detail::put_le(out, bits(points, k, i));
      if (out.size() > (1u << 20)) file.write(out), out.clear();
    }
  } else {
    std::string columns;
    columns.reserve(n * 4 * c.count());
    for (std::size_t k = 0; k < c.count(); ++k) {
      for (std::size_t i = 0; i < n; ++i) detail::put_le(columns, bits(points, k, i));
    }
    if (columns.size() > 0xffffffffu / 2)
      throw std::invalid_argument("save_pcd: more than 2 GiB of points to compress");
    std::vector<char> packed(columns.size() + columns.size() / 16 + 64);
    const unsigned size = columns.empty()
                              ? 0
                              : lzf_compress(columns.data(), static_cast<unsigned>(columns.size()),
                                             packed.data(), static_cast<unsigned>(packed.size()));
    if (size == 0 && !columns.empty())
      throw std::runtime_error("save_pcd: LZF could not compress the points");
    detail::put_le(out, static_cast<std::uint32_t>(size));
    detail::put_le(out, static_cast<std::uint32_t>(columns.size()));
    out.append(packed.data(), size);
  }
  file.write(out);
  file.commit();
}

}  // namespace treecut
