// PCD export (treecut/pcd.hpp): a v0.7 header, then the points ascii, packed
// or as LZF-compressed columns (liblzf). Every field in a type that holds it
// (issue 43): x y z as doubles where the model has an origin, the
// attributes in their own types, 16-bit colours as red green blue fields.
#include <lzf.h>

#include <algorithm>
#include <cctype>
#include <cstdio>
#include <stdexcept>
#include <string>
#include <vector>

#include "file_metadata.hpp"
#include "little_endian.hpp"
#include "treecut/file_io.hpp"
#include "treecut/pcd.hpp"
#include "typed_values.hpp"

namespace treecut {

namespace {

// One field: its name, type and where its values come from.
struct Column {
  std::string name;
  ValueType type = ValueType::f32;
  enum class Source : std::uint8_t { position, normal, packed_rgb, rgb16, attribute } source{};
  int index = 0;  // the axis, channel or attribute
};

std::vector<Column> columns_of(const PointSet& p, const SaveOptions& options) {
  std::vector<Column> c;
  const bool doubles =
      (p.frame.origin != glm::dvec3(0.0) || !p.exact_positions.empty()) && !options.relative;
  const ValueType position = doubles ? ValueType::f64 : ValueType::f32;
  for (int a = 0; a < 3; ++a)
    c.push_back({std::string(1, "xyz"[a]), position, Column::Source::position, a});
  if (p.has_normals()) {
    for (int a = 0; a < 3; ++a)
      c.push_back({std::string("normal_") + "xyz"[a], ValueType::f32, Column::Source::normal, a});
  }
  if (p.has_colors() && p.colors16.empty()) {
    c.push_back({"rgb", ValueType::u32, Column::Source::packed_rgb, 0});
  } else if (p.has_colors()) {
    static constexpr const char* kChannel[3] = {"red", "green", "blue"};
    for (int k = 0; k < 3; ++k)
      c.push_back({kChannel[k], ValueType::u16, Column::Source::rgb16, k});
  }
  // A field name is one token, and not one the reader takes for a role
  // (without regard to case): "height above ground" -> height_above_ground,
  // an extra-bytes field called Red -> Red_attribute. The name comes back
  // through a treecut comment (header()).
  std::vector<std::string> used = {"x",     "y",    "z",  "normal_x", "normal_y", "normal_z",
                                   "nx",    "ny",   "nz", "rgb",      "rgba",     "red",
                                   "green", "blue", "r",  "g",        "b",        "_"};
  auto lower = [](std::string t) {
    for (char& ch : t) ch = static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
    return t;
  };
  for (std::size_t k = 0; k < p.attributes.size(); ++k) {
    const PointAttribute& a = p.attributes[k];
    std::string name = a.name.empty() ? "attribute" : a.name;
    for (char& ch : name) {
      if (ch == ' ' || ch == '\t' || static_cast<unsigned char>(ch) < 0x20) ch = '_';
    }
    while (std::find(used.begin(), used.end(), lower(name)) != used.end()) name += "_attribute";
    used.push_back(lower(name));
    c.push_back({name, detail::output_type(a, p.size(), /*no_int64=*/false),
                 Column::Source::attribute, static_cast<int>(k)});
  }
  return c;
}

// Field C of point I, as a double (the packed colour's 32 bits as an integer).
double value_of(const PointSet& p, const Column& c, std::size_t i, bool relative) {
  switch (c.source) {
    case Column::Source::position:
      if (relative || c.type == ValueType::f32) return double(p.positions[i][c.index]);
      return p.exact_positions.empty() ? p.frame.origin[c.index] + double(p.positions[i][c.index])
                                       : p.exact_positions[i][c.index];
    case Column::Source::normal:
      return p.normals[i][c.index];
    case Column::Source::packed_rgb: {
      const glm::u8vec4 k = p.colors[i];
      return double(0xff000000u | (std::uint32_t{k.x} << 16) | (std::uint32_t{k.y} << 8) | k.z);
    }
    case Column::Source::rgb16:
      return p.colors16[i][c.index];
    case Column::Source::attribute:
      return p.attributes[static_cast<std::size_t>(c.index)].value(i);
  }
  return 0.0;
}

std::string header(const PointSet& points, const std::vector<Column>& c, PcdData data,
                   const SaveOptions& options) {
  std::string out(kPcdSignature);
  for (const std::string& line : detail::metadata_lines(points, options.relative))
    out += "# " + line + "\n";
  for (const Column& k : c) {
    if (k.source != Column::Source::attribute) continue;
    const std::string& original = points.attributes[static_cast<std::size_t>(k.index)].name;
    if (k.name != original) out += "# " + detail::name_line(k.name, original) + "\n";
  }
  out += "VERSION 0.7\nFIELDS";
  for (const Column& k : c) out += " " + k.name;
  out += "\nSIZE";
  for (const Column& k : c) out += " " + std::to_string(value_size(k.type));
  out += "\nTYPE";
  for (const Column& k : c) out += !is_integer(k.type) ? " F" : is_signed(k.type) ? " I" : " U";
  out += "\nCOUNT";
  for (std::size_t k = 0; k < c.size(); ++k) out += " 1";
  const std::string n = std::to_string(points.size());
  out += "\nWIDTH " + n + "\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS " + n + "\nDATA " +
         (data == PcdData::ascii    ? "ascii"
          : data == PcdData::binary ? "binary"
                                    : "binary_compressed") +
         "\n";
  return out;
}

}  // namespace

void save_pcd(const std::filesystem::path& path, const PointSet& points, PcdData data,
              const SaveOptions& options) {
  const std::size_t n = points.size();
  if ((points.has_normals() && points.normals.size() != n) ||
      (points.has_colors() && points.colors.size() != n) ||
      (!points.colors16.empty() && points.colors16.size() != n)) {
    throw std::invalid_argument("save_pcd: normals or colours differ from the point count");
  }
  for (const PointAttribute& a : points.attributes) {
    if (!a.is_constant() && a.stored() != n)
      throw std::invalid_argument("save_pcd: attribute " + a.name +
                                  " differs from the point count");
  }
  const std::vector<Column> c = columns_of(points, options);
  const bool relative = options.relative;
  std::string out = header(points, c, data, options);
  AtomicFile file(path);  // throws "PATH: REASON"
  // A 64-bit integer field past 2^53 is written from its integers, exactly.
  auto exact = [&](const Column& k) -> const std::vector<std::int64_t>* {
    if (k.source != Column::Source::attribute || value_size(k.type) != 8 || !is_integer(k.type))
      return nullptr;
    const auto& integers = points.attributes[static_cast<std::size_t>(k.index)].integers;
    return integers.empty() ? nullptr : &integers;
  };
  auto put = [&](std::string& to, const Column& k, std::size_t i) {
    if (const auto* integers = exact(k)) {
      detail::put_le(to, (*integers)[i]);
    } else {
      detail::put_value(to, k.type, value_of(points, k, i, relative));
    }
  };
  if (data == PcdData::ascii) {
    for (std::size_t i = 0; i < n; ++i) {
      for (std::size_t k = 0; k < c.size(); ++k) {
        const auto* integers = exact(c[k]);
        out += k ? " " : "";
        out += !integers ? detail::value_text(c[k].type, value_of(points, c[k], i, relative))
               : c[k].type == ValueType::u64
                   ? std::to_string(static_cast<std::uint64_t>((*integers)[i]))
                   : std::to_string((*integers)[i]);
      }
      out += "\n";
      if (out.size() > (1u << 20)) file.write(out), out.clear();
    }
  } else if (data == PcdData::binary) {
    for (std::size_t i = 0; i < n; ++i) {
      for (const Column& k : c) put(out, k, i);
      if (out.size() > (1u << 20)) file.write(out), out.clear();
    }
  } else {
    std::size_t record = 0;
    for (const Column& k : c) record += value_size(k.type);
    std::string columns;
    columns.reserve(n * record);
    for (const Column& k : c) {
      for (std::size_t i = 0; i < n; ++i) put(columns, k, i);
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
