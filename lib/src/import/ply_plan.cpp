// The way to OpenMesh (ply_load_parts.hpp): which layouts its PLY reader
// decodes correctly, and for those our header over the file's own bytes; for
// everything else a canonical binary body transcoded from the validated rows.
// Then OpenMesh's read, checked against the rows it was given. Everything
// this project knows about OpenMesh's fragilities is in this file.
//
// Two ways to OpenMesh. A binary file whose vertex and face layout OpenMesh's
// reader decodes correctly goes straight through (our header, the file's body
// bytes, no copy). Everything else is transcoded to a canonical binary body
// first: ascii bodies (OpenMesh reads them with istream >>, which cannot parse
// "nan"/"inf" or a leading '+', and whose failbit silently zeroes every later
// value), and binary files with list properties in vertices, extra lists in
// faces or integer coordinates (OpenMesh mis-sizes or skips those).
#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <optional>
#include <string>
#include <type_traits>

#include "ply_load_parts.hpp"
#include "position_frame.hpp"

namespace treecut::ply_load {

namespace {

bool colors_are_u16(const Element& vertex, const VertexRoles& roles) {
  return roles.colors() && property(vertex, roles.red).type == Type::u16 &&
         property(vertex, roles.green).type == Type::u16 &&
         property(vertex, roles.blue).type == Type::u16;
}

// Positions of these types are read as doubles: a float does not hold them.
bool positions_need_doubles(const Element& vertex, const VertexRoles& roles) {
  for (int p : {roles.x, roles.y, roles.z}) {
    const Type t = property(vertex, p).type;
    if (t == Type::f64 || t == Type::i32 || t == Type::u32) return true;
  }
  return false;
}

bool colors_are_u8(const Element& vertex, const VertexRoles& roles) {
  return roles.colors() && property(vertex, roles.red).type == Type::u8 &&
         property(vertex, roles.green).type == Type::u8 &&
         property(vertex, roles.blue).type == Type::u8;
}

// The layouts OpenMesh's binary reader decodes correctly, in every OpenMesh
// release we know of (the reader changed between releases):
// - positions and normals float32: some releases read nothing for double or
//   integer coordinates, leaving the stream misaligned;
// - no list in the vertex element: it skips one scalar for a list;
// - in the face element, the index list first (some releases drop the
//   declarations before it, yet not the bytes), no other list, lengths of 1 or
//   4 bytes and indices of 1 or 4 bytes (16-bit ones are not read everywhere).
// Anything else is transcoded to a canonical body first.
bool openmesh_reads_directly(const Header& header, const VertexRoles& roles, int face) {
  if (header.format == Format::ascii) return false;
  const Element& vertex = header.elements[static_cast<std::size_t>(header.find("vertex"))];
  if (vertex.has_lists()) return false;
  for (int p : {roles.x, roles.y, roles.z}) {
    if (property(vertex, p).type != Type::f32) return false;
  }
  if (roles.normals()) {
    for (int p : {roles.nx, roles.ny, roles.nz}) {
      if (property(vertex, p).type != Type::f32) return false;
    }
  }
  if (face >= 0) {
    const Element& faces = header.elements[static_cast<std::size_t>(face)];
    if (index_property(faces) != 0) return false;
    const Property& indices = faces.properties.front();
    const std::size_t count_size = ply::type_size(indices.count_type);
    const std::size_t index_size = ply::type_size(indices.type);
    if ((count_size != 1 && count_size != 4) || (index_size != 1 && index_size != 4)) return false;
    for (std::size_t i = 1; i < faces.properties.size(); ++i) {
      if (faces.properties[i].is_list) return false;
    }
  }
  return true;
}

std::string format_line(Format format) {
  return format == Format::binary_big_endian ? "format binary_big_endian 1.0\n"
                                             : "format binary_little_endian 1.0\n";
}

// OpenMesh accepts only uchar/uint8/uint16/int as list length types; any
// integer type of the same width reads the same bytes, and negative lengths
// were already rejected by the layout walk (only widths 1 and 4 come here).
std::string_view length_type_alias(Type type) {
  return ply::type_size(type) == 1 ? "uchar" : "int";
}

// A property name OpenMesh does not interpret (it skips such a property by
// the size of its type).
std::string neutral_name(std::size_t index) {
  std::string name(1, '_');
  name += std::to_string(index);
  return name;
}

// Our header for a body OpenMesh reads in place: the file's own vertex and
// face layouts, with every property OpenMesh should not interpret renamed to
// a neutral name so it is skipped by size.
std::string direct_header(const Header& header, const VertexRoles& roles, bool u8_colors,
                          int face) {
  const Element& vertex = header.elements[static_cast<std::size_t>(header.find("vertex"))];
  std::string out = "ply\n" + format_line(header.format);
  out += "element vertex " + std::to_string(vertex.count) + "\n";
  for (std::size_t i = 0; i < vertex.properties.size(); ++i) {
    const int p = static_cast<int>(i);
    std::string name = neutral_name(i);
    if (p == roles.x) name = "x";
    if (p == roles.y) name = "y";
    if (p == roles.z) name = "z";
    if (roles.normals() && p == roles.nx) name = "nx";
    if (roles.normals() && p == roles.ny) name = "ny";
    if (roles.normals() && p == roles.nz) name = "nz";
    if (u8_colors && p == roles.red) name = "red";
    if (u8_colors && p == roles.green) name = "green";
    if (u8_colors && p == roles.blue) name = "blue";
    out += "property " + std::string(ply::type_name(vertex.properties[i].type)) + " " + name + "\n";
  }
  if (face >= 0) {
    const Element& faces = header.elements[static_cast<std::size_t>(face)];
    const int indices = index_property(faces);
    out += "element face " + std::to_string(faces.count) + "\n";
    for (std::size_t i = 0; i < faces.properties.size(); ++i) {
      const Property& p = faces.properties[i];
      if (static_cast<int>(i) == indices) {
        out += "property list " + std::string(length_type_alias(p.count_type)) + " " +
               std::string(ply::type_name(p.type)) + " vertex_indices\n";
      } else {
        out += "property " + std::string(ply::type_name(p.type)) + " " + neutral_name(i) + "\n";
      }
    }
  }
  out += "end_header\n";
  return out;
}

template <class T>
void append_le(std::string& out, T value) {
  static_assert(std::is_arithmetic_v<T>);
  char bytes[sizeof(T)];
  std::memcpy(bytes, &value, sizeof(T));
  if constexpr (std::endian::native == std::endian::big) std::reverse(bytes, bytes + sizeof(T));
  out.append(bytes, sizeof(T));
}

// 1 when a position is finite but past the float range (it becomes an
// infinity as a float), else 0.
int finite_beyond_float(double x, double y, double z) {
  constexpr double kMax = std::numeric_limits<float>::max();
  const bool finite = std::isfinite(x) && std::isfinite(y) && std::isfinite(z);
  return finite && (std::fabs(x) > kMax || std::fabs(y) > kMax || std::fabs(z) > kMax) ? 1 : 0;
}

// The canonical body for OpenMesh when it cannot read the file's own:
// little-endian float positions (and normals), uchar colours, faces as
// "list int int". Radii go straight to the plan.
struct Transcoder {
  const Element& vertex;
  const VertexRoles& roles;
  int face_indices;  ///< index list of the face element, or -1
  Plan& plan;
  std::size_t vertex_rows = 0;
  std::size_t face_rows = 0;

  bool doubles = false;   ///< positions_need_doubles
  bool colors16 = false;  ///< colors_are_u16

  void vertex_row(const Row& row) {
    std::string& out = plan.vertex_bytes;
    plan.finite_beyond_float +=
        finite_beyond_float(row.scalar(roles.x), row.scalar(roles.y), row.scalar(roles.z));
    if (doubles)
      plan.doubles.emplace_back(row.scalar(roles.x), row.scalar(roles.y), row.scalar(roles.z));
    if (colors16) {
      plan.colors16.emplace_back(row.scalar(roles.red), row.scalar(roles.green),
                                 row.scalar(roles.blue));
    }
    for (int p : {roles.x, roles.y, roles.z}) append_le(out, ply::to_float(row.scalar(p)));
    if (roles.normals()) {
      for (int p : {roles.nx, roles.ny, roles.nz}) append_le(out, ply::to_float(row.scalar(p)));
    }
    if (roles.colors()) {
      for (int p : {roles.red, roles.green, roles.blue}) {
        append_le(out, ply::color_channel(row.scalar(p), property(vertex, p).type));
      }
    }
    if (roles.radius >= 0) plan.radii.push_back(ply::to_float(row.scalar(roles.radius)));
    for (std::size_t k = 0; k < roles.attributes.size(); ++k) {
      plan.attributes[k].push_back(row.scalar(roles.attributes[k]));
    }
    ++vertex_rows;
  }

  void face_row(const Row& row) {
    const auto p = static_cast<std::size_t>(face_indices);
    append_le(plan.face_bytes, static_cast<std::int32_t>(row.size[p]));
    for (std::size_t k = 0; k < row.size[p]; ++k) {
      const double v = row.values[row.first[p] + k];
      // Anything that is not a vertex index becomes -1, which the importer
      // counts as out of range.
      const bool index = v >= 0 && v <= std::numeric_limits<std::int32_t>::max();
      append_le(plan.face_bytes, index ? static_cast<std::int32_t>(v) : std::int32_t{-1});
    }
    ++face_rows;
  }

  [[nodiscard]] std::string header() const {
    std::string out = "ply\nformat binary_little_endian 1.0\n";
    out += "element vertex " + std::to_string(vertex_rows) + "\n";
    out += "property float x\nproperty float y\nproperty float z\n";
    if (roles.normals()) out += "property float nx\nproperty float ny\nproperty float nz\n";
    if (roles.colors()) out += "property uchar red\nproperty uchar green\nproperty uchar blue\n";
    if (face_indices >= 0) {
      out += "element face " + std::to_string(face_rows) + "\n";
      out += "property list int int vertex_indices\n";
    }
    out += "end_header\n";
    return out;
  }
};

// Reads scalar property P of every row of a fixed-stride binary element.
template <class F>
void for_each_fixed(std::string_view bytes, const Element& element, int p, bool big_endian, F&& f) {
  const std::size_t stride = element.fixed_stride();
  std::size_t offset = 0;
  for (int i = 0; i < p; ++i) offset += ply::type_size(property(element, i).type);
  const Type type = property(element, p).type;
  for (std::size_t row = 0; row < element.count; ++row) {
    f(row, ply::load_scalar(bytes.data() + row * stride + offset, type, big_endian));
  }
}

std::string_view element_bytes(std::string_view file, const ply::BinaryLayout& layout,
                               std::size_t element) {
  const ply::Range range = layout.elements[element];
  return file.substr(range.begin, range.end - range.begin);
}

// OpenMesh reads the file's own vertex and face bytes; we read radius,
// non-uchar colours and tristrips from the same validated ranges.
void plan_direct(const Header& header, const ply::BinaryLayout& layout, std::string_view file,
                 const Elements& elements, Plan& plan) {
  const Element& vertex = header.elements[elements.vertex];
  const VertexRoles& roles = elements.roles;
  const bool big_endian = header.format == Format::binary_big_endian;
  const bool u8_colors = colors_are_u8(vertex, roles);
  const std::string_view vertex_bytes = element_bytes(file, layout, elements.vertex);
  const auto vertex_count = static_cast<std::size_t>(vertex.count);

  ply::OpenMeshInput& input = plan.input;
  input.header = direct_header(header, roles, u8_colors, elements.face);
  input.body.push_back(vertex_bytes);
  input.vertices = vertex_count;
  if (elements.face >= 0) {
    const auto face = static_cast<std::size_t>(elements.face);
    input.body.push_back(element_bytes(file, layout, face));
    input.faces = static_cast<std::size_t>(header.elements[face].count);
  }
  input.normals = roles.normals();
  input.colors = u8_colors;

  if (roles.radius >= 0) {
    plan.radii.resize(vertex_count);
    for_each_fixed(vertex_bytes, vertex, roles.radius, big_endian,
                   [&](std::size_t i, double r) { plan.radii[i] = ply::to_float(r); });
  }
  for (const int p : roles.attributes) {
    detail::AttributeColumn& column = plan.attributes.emplace_back(
        property(vertex, p).name, vertex_count, value_type(property(vertex, p).type));
    for_each_fixed(vertex_bytes, vertex, p, big_endian,
                   [&](std::size_t, double v) { column.push_back(v); });
  }
  if (roles.colors() && !u8_colors) {
    plan.colors.assign(vertex_count, glm::u8vec4(0, 0, 0, 255));
    const std::array<int, 3> channels{roles.red, roles.green, roles.blue};
    for (std::size_t c = 0; c < 3; ++c) {
      const Type type = property(vertex, channels[c]).type;
      for_each_fixed(vertex_bytes, vertex, channels[c], big_endian, [&](std::size_t i, double x) {
        plan.colors[i][static_cast<glm::length_t>(c)] = ply::color_channel(x, type);
      });
    }
    if (colors_are_u16(vertex, roles)) {
      plan.colors16.resize(vertex_count);
      for (std::size_t c = 0; c < 3; ++c) {
        for_each_fixed(vertex_bytes, vertex, channels[c], big_endian, [&](std::size_t i, double x) {
          plan.colors16[i][static_cast<glm::length_t>(c)] = static_cast<std::uint16_t>(x);
        });
      }
    }
  }
  if (elements.strips >= 0) {
    const auto strips = static_cast<std::size_t>(elements.strips);
    const Element& element = header.elements[strips];
    ply::BinaryRows rows(element, element_bytes(file, layout, strips), big_endian);
    Row row;
    for (std::uint64_t r = 0; r < element.count; ++r) {
      rows.next(row);
      plan.strips.row(row, index_property(element));
    }
  }
}

// Decodes every row we need (ascii: every row, each token checked) and
// writes the canonical body OpenMesh then reads.
void plan_transcoded(const Header& header, const ply::BinaryLayout& layout, std::string_view file,
                     const Elements& elements, Plan& plan) {
  const bool binary = header.format != Format::ascii;
  const bool big_endian = header.format == Format::binary_big_endian;
  const Element& vertex = header.elements[elements.vertex];
  const int face_indices =
      elements.face >= 0 ? index_property(header.elements[static_cast<std::size_t>(elements.face)])
                         : -1;
  Transcoder transcoder{vertex, elements.roles, face_indices, plan};
  transcoder.doubles = positions_need_doubles(vertex, elements.roles);
  transcoder.colors16 = colors_are_u16(vertex, elements.roles);
  if (transcoder.doubles) plan.doubles.reserve(static_cast<std::size_t>(vertex.count));

  // Reserve only what the validated body can hold: binary counts were
  // checked byte for byte, ascii counts against the token capacity.
  constexpr std::size_t kCanonicalVertexBytes = 27;
  const auto vertex_count = static_cast<std::size_t>(vertex.count);
  plan.vertex_bytes.reserve(vertex_count * kCanonicalVertexBytes);
  if (elements.roles.radius >= 0) plan.radii.reserve(vertex_count);
  for (const int p : elements.roles.attributes)
    plan.attributes.emplace_back(property(vertex, p).name, vertex_count,
                                 value_type(property(vertex, p).type));

  ply::AsciiRows ascii(file, header);
  Row row;
  for (std::size_t e = 0; e < header.elements.size(); ++e) {
    const Element& element = header.elements[e];
    const bool is_face = static_cast<int>(e) == elements.face;
    const bool is_strips = static_cast<int>(e) == elements.strips;
    const bool wanted = e == elements.vertex || is_face || is_strips;
    // A binary element we do not want was validated by the layout walk.
    if (binary && !wanted) continue;
    std::optional<ply::BinaryRows> rows;
    if (binary) rows.emplace(element, element_bytes(file, layout, e), big_endian);
    std::uint64_t r = 0;
    try {
      for (; r < element.count; ++r) {
        if (!wanted) {
          ascii.skip(element, r);
          continue;
        }
        if (rows) {
          rows->next(row);
        } else {
          ascii.next(element, r, row);
        }
        if (is_face) {
          transcoder.face_row(row);
        } else if (is_strips) {
          plan.strips.row(row, index_property(element));
        } else {
          transcoder.vertex_row(row);
        }
      }
    } catch (const ply::Error& error) {
      // Only the vertex element decides whether a file loads (binary rows
      // were validated by the layout walk, so only ascii gets here).
      if (binary || e == elements.vertex) throw;
      plan.broken.push_back({e, error.what()});
      plan.faces_lost |= is_face || is_strips;
      // The rest of the element line by line (ascii holds one row per line),
      // so that the next element, perhaps the vertex element, starts in step.
      for (++r; r < element.count && ascii.skip_line(); ++r) {
      }
    }
  }
  if (!binary) plan.trailing_lines = ascii.trailing_lines();
  if (plan.faces_lost) {
    transcoder.face_indices = -1;
    transcoder.face_rows = 0;
    plan.face_bytes.clear();
    plan.strips.triangles.clear();
    plan.strips.out_of_range = 0;
  }

  ply::OpenMeshInput& input = plan.input;
  input.header = transcoder.header();
  input.body = {plan.vertex_bytes, plan.face_bytes};
  input.vertices = transcoder.vertex_rows;
  input.faces = transcoder.face_rows;
  input.normals = elements.roles.normals();
  input.colors = elements.roles.colors();
}

}  // namespace

ValueType value_type(Type type) {
  switch (type) {
    case Type::i8:
      return ValueType::i8;
    case Type::u8:
      return ValueType::u8;
    case Type::i16:
      return ValueType::i16;
    case Type::u16:
      return ValueType::u16;
    case Type::i32:
      return ValueType::i32;
    case Type::u32:
      return ValueType::u32;
    case Type::f32:
      return ValueType::f32;
    case Type::f64:
      return ValueType::f64;
  }
  return ValueType::f64;
}

void plan_openmesh_read(const Header& header, const ply::BinaryLayout& layout,
                        std::string_view file, const Elements& elements, Plan& plan) {
  if (openmesh_reads_directly(header, elements.roles, elements.face)) {
    plan_direct(header, layout, file, elements, plan);
  } else {
    plan_transcoded(header, layout, file, elements, plan);
  }
}

PointSet read_plan(Plan& plan, const Warnings& warn, PlyLoadReport& report) {
  PointSet points;
  const ply::OpenMeshInput& input = plan.input;
  const ply::OpenMeshResult read = ply::read_with_openmesh(input, points);
  if (!read.reader_ok || read.vertices_read != input.vertices || read.faces_read != input.faces) {
    throw ply::Error("OpenMesh read " + std::to_string(read.vertices_read) + " of " +
                     std::to_string(input.vertices) + " vertices and " +
                     std::to_string(read.faces_read) + " of " + std::to_string(input.faces) +
                     " faces" + (read.reader_ok ? "" : " and reported failure"));
  }
  if (!plan.colors.empty()) points.colors = std::move(plan.colors);
  if (!plan.colors16.empty()) points.colors16 = std::move(plan.colors16);
  if (!plan.radii.empty()) points.radii = std::move(plan.radii);
  detail::take_columns(plan.attributes, points.attributes);
  if (!plan.doubles.empty()) {
    // Map coordinates in double: relative to an origin (position_frame.hpp);
    // what is not finite or too far stays so for tidy() to drop and name.
    std::vector<glm::dvec3> finite;
    for (const glm::dvec3& d : plan.doubles) {
      if (!plan.origin && std::isfinite(d.x) && std::isfinite(d.y) && std::isfinite(d.z))
        finite.push_back(d);
    }
    const glm::dvec3 origin = plan.origin ? *plan.origin : detail::choose_origin(finite);
    points.frame.origin = origin;
    bool exact = true;
    for (std::size_t i = 0; i < plan.doubles.size(); ++i) {
      const glm::dvec3 q = plan.doubles[i] - origin;
      points.positions[i] = glm::vec3(ply::to_float(q.x), ply::to_float(q.y), ply::to_float(q.z));
      exact = exact && detail::float_exact(points.positions[i], origin, plan.doubles[i]);
    }
    if (!exact) points.exact_positions = std::move(plan.doubles);
  }

  const StripSink& strips = plan.strips;
  points.triangles.insert(points.triangles.end(), strips.triangles.begin(), strips.triangles.end());
  report.faces_in_file = input.faces + strips.triangles.size() + strips.out_of_range;
  if (read.faces_out_of_range + strips.out_of_range > 0) {
    warn("ignoring " + plural(read.faces_out_of_range + strips.out_of_range, "face") +
         " with vertex indices out of range");
  }
  if (read.faces_degenerate > 0) {
    warn("ignoring " + plural(read.faces_degenerate, "face") + " with fewer than 3 vertices");
  }
  return points;
}

}  // namespace treecut::ply_load
