// PLY import: our guard, then OpenMesh's reader, then our count checks.
//
// Pipeline: parse_header -> validate the body (binary: exact layout walk;
// ascii: every token parsed and type-checked) -> hand OpenMesh a header we
// wrote plus validated body bytes -> check OpenMesh's counts -> read what
// OpenMesh ignores (radius, non-uchar colours, tristrips) -> drop non-finite
// points -> tidy normals and radii.
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
#include <cstring>
#include <fstream>
#include <limits>
#include <memory>
#include <optional>

#include "ply_format.hpp"
#include "ply_openmesh.hpp"
#include "treecut/error.hpp"
#include "treecut/ply.hpp"

namespace treecut {

namespace {

using ply::Element;
using ply::Format;
using ply::Header;
using ply::Property;
using ply::Row;
using ply::Type;

// Vertex properties by meaning; -1 when absent. Normals and colours count only
// when all three components are present as scalars.
struct VertexRoles {
  int x = -1, y = -1, z = -1;
  int nx = -1, ny = -1, nz = -1;
  int red = -1, green = -1, blue = -1;
  int radius = -1;

  [[nodiscard]] bool normals() const { return nx >= 0; }
  [[nodiscard]] bool colors() const { return red >= 0; }
};

class Warnings {
 public:
  Warnings(const std::string& name, const WarningSink& sink) : name_(name), sink_(sink) {}
  void operator()(const std::string& message) const {
    if (sink_) sink_(name_ + ": " + message);
  }

 private:
  const std::string& name_;
  const WarningSink& sink_;
};

int scalar_property(const Element& element, std::string_view name) {
  int p = element.find(name);
  if (p >= 0 && element.properties[static_cast<std::size_t>(p)].is_list) return -1;
  return p;
}

const Property& property(const Element& element, int index) {
  return element.properties[static_cast<std::size_t>(index)];
}

VertexRoles find_roles(const Element& vertex, const Warnings& warn) {
  VertexRoles roles;
  roles.x = scalar_property(vertex, "x");
  roles.y = scalar_property(vertex, "y");
  roles.z = scalar_property(vertex, "z");

  const int nx = scalar_property(vertex, "nx");
  const int ny = scalar_property(vertex, "ny");
  const int nz = scalar_property(vertex, "nz");
  if (nx >= 0 && ny >= 0 && nz >= 0) {
    roles.nx = nx;
    roles.ny = ny;
    roles.nz = nz;
  } else if (vertex.find("nx") >= 0 || vertex.find("ny") >= 0 || vertex.find("nz") >= 0) {
    warn("ignoring normals: nx, ny and nz must all be scalar properties");
  }

  for (std::string_view prefix : {"", "diffuse_"}) {
    const int r = scalar_property(vertex, std::string(prefix) + "red");
    const int g = scalar_property(vertex, std::string(prefix) + "green");
    const int b = scalar_property(vertex, std::string(prefix) + "blue");
    if (r >= 0 && g >= 0 && b >= 0) {
      roles.red = r;
      roles.green = g;
      roles.blue = b;
      break;
    }
  }
  if (!roles.colors() &&
      (vertex.find("red") >= 0 || vertex.find("green") >= 0 || vertex.find("blue") >= 0)) {
    warn("ignoring colors: red, green and blue must all be scalar properties");
  }

  roles.radius = scalar_property(vertex, "radius");
  if (roles.radius < 0 && vertex.find("radius") >= 0) warn("ignoring radius: it is a list");
  return roles;
}

int index_property(const Element& element) {
  int p = element.find("vertex_indices");
  return p >= 0 ? p : element.find("vertex_index");
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

// Collects tristrips as triangles. A negative index restarts the strip; odd
// triangles are flipped to keep the winding; the degenerate triangles strips
// use as stitches are skipped.
struct StripSink {
  std::size_t vertices = 0;
  std::vector<glm::uvec3> triangles;
  std::size_t out_of_range = 0;
  std::vector<double> strip;

  void row(const Row& row, int indices) {
    const auto p = static_cast<std::size_t>(indices);
    strip.clear();
    for (std::size_t k = 0; k < row.size[p]; ++k) {
      const double v = row.values[row.first[p] + k];
      if (v < 0) {
        flush();
        strip.clear();
      } else {
        strip.push_back(v);
      }
    }
    flush();
  }

  void flush() {
    for (std::size_t k = 0; k + 2 < strip.size(); ++k) {
      double a = strip[k];
      double b = strip[k + 1];
      const double c = strip[k + 2];
      if (k % 2 == 1) std::swap(a, b);
      if (a == b || b == c || a == c) continue;
      const auto n = static_cast<double>(vertices);
      if (a >= n || b >= n || c >= n) {
        ++out_of_range;
        continue;
      }
      triangles.emplace_back(static_cast<unsigned>(a), static_cast<unsigned>(b),
                             static_cast<unsigned>(c));
    }
  }
};

// The elements load_ply uses, by index into Header::elements.
struct Elements {
  std::size_t vertex = 0;
  int face = -1;    ///< "face" with an index list, or -1
  int strips = -1;  ///< "tristrips" with an index list, or -1
  VertexRoles roles;
  std::vector<std::size_t> ignored;  ///< elements read past, in header order
  /// A face or tristrips element sits at or after a binary element that does
  /// not match its header: no faces are read, the points load as a cloud.
  bool faces_lost = false;
};

// An element after the vertex element that does not match its header.
struct BrokenElement {
  std::size_t index = 0;
  std::string problem;
};

// Everything the read needs: OpenMesh's input, the transcoded body it may
// point into, and what we read ourselves because OpenMesh does not.
struct Plan {
  ply::OpenMeshInput input;
  std::string vertex_bytes;  ///< transcoded vertex rows (unused when direct)
  std::string face_bytes;    ///< transcoded face rows (unused when direct)
  std::vector<float> radii;
  std::vector<glm::u8vec4> colors;  ///< colours OpenMesh does not read, or empty
  StripSink strips;
  std::vector<BrokenElement> broken;  ///< ascii elements whose rows do not match
  bool faces_lost = false;            ///< a face element is among them
  std::size_t trailing_lines = 0;     ///< ascii: non-blank lines after the last row
};

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

  void vertex_row(const Row& row) {
    std::string& out = plan.vertex_bytes;
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

std::string plural(std::size_t n, const std::string& word) {
  return std::to_string(n) + " " + word + (n == 1 ? "" : "s");
}

// Beyond this magnitude the float arithmetic of attributes and build (squared
// distances, covariances) overflows: such points are as unusable as NaNs.
constexpr float kMaxCoordinate = 1e18f;

bool out_of_range(const glm::vec3& p) {
  return !(std::fabs(p.x) <= kMaxCoordinate && std::fabs(p.y) <= kMaxCoordinate &&
           std::fabs(p.z) <= kMaxCoordinate);
}

// Drops points with a non-finite or out-of-range coordinate from every array,
// and the faces that use them; remaps the remaining indices. Returns {points,
// faces} dropped.
std::pair<std::size_t, std::size_t> drop_nonfinite(PointSet& points) {
  const std::size_t n = points.size();
  std::size_t bad = 0;
  for (const glm::vec3& p : points.positions) {
    if (out_of_range(p)) ++bad;
  }
  if (bad == 0) return {0, 0};

  constexpr auto kDropped = std::numeric_limits<std::uint32_t>::max();
  std::vector<std::uint32_t> remap(n, kDropped);
  std::size_t kept = 0;
  for (std::size_t i = 0; i < n; ++i) {
    if (out_of_range(points.positions[i])) continue;
    remap[i] = static_cast<std::uint32_t>(kept);
    points.positions[kept] = points.positions[i];
    if (points.has_normals()) points.normals[kept] = points.normals[i];
    if (points.has_colors()) points.colors[kept] = points.colors[i];
    if (points.has_radii()) points.radii[kept] = points.radii[i];
    ++kept;
  }
  points.positions.resize(kept);
  if (points.has_normals()) points.normals.resize(kept);
  if (points.has_colors()) points.colors.resize(kept);
  if (points.has_radii()) points.radii.resize(kept);

  std::size_t faces_kept = 0;
  const std::size_t faces = points.triangles.size();
  for (const glm::uvec3& t : points.triangles) {
    const glm::uvec3 r(remap[t.x], remap[t.y], remap[t.z]);
    if (r.x == kDropped || r.y == kDropped || r.z == kDropped) continue;
    points.triangles[faces_kept++] = r;
  }
  points.triangles.resize(faces_kept);
  return {bad, faces - faces_kept};
}

// Binary: the exact layout, walked byte for byte. Ascii: a capacity bound
// (every token is checked later, while transcoding). Either way nothing is
// sized from a header count before this has passed.
ply::BinaryLayout validate_body(const Header& header, std::string_view file) {
  if (header.format == Format::ascii) {
    ply::check_ascii_capacity(header, file);
    return {};
  }
  return ply::binary_layout(header, file);
}

// Elements from LOST_FROM on could not be located (a binary element that does
// not match its header); they are neither read nor listed as ignored.
Elements classify(const Header& header, const Warnings& warn, std::size_t lost_from) {
  Elements elements;
  elements.vertex = static_cast<std::size_t>(header.find("vertex"));
  const Element& vertex = header.elements[elements.vertex];
  if (vertex.count > static_cast<std::uint64_t>(std::numeric_limits<std::int32_t>::max())) {
    // OpenMesh's vertex handles and our triangle indices are 32-bit.
    throw ply::Error("too many vertices (" + std::to_string(vertex.count) + ")");
  }
  elements.roles = find_roles(vertex, warn);

  for (std::size_t e = 0; e < header.elements.size(); ++e) {
    const Element& element = header.elements[e];
    if (e == elements.vertex) continue;
    const bool has_indices = index_property(element) >= 0;
    const bool triangles = (element.name == "face" || element.name == "tristrips") && has_indices;
    if (e >= lost_from) {
      elements.faces_lost |= triangles;
    } else if (triangles) {
      (element.name == "face" ? elements.face : elements.strips) = static_cast<int>(e);
    } else {
      elements.ignored.push_back(e);
    }
  }
  // Faces from only some of the elements would make a partial mesh; the
  // points are better served as a point cloud (attributes from neighbours).
  if (elements.faces_lost) elements.face = elements.strips = -1;
  return elements;
}

// One warning for all ignored elements, naming the first few: a header may
// declare thousands. Elements that did not match their header have a warning
// of their own and are not listed again.
void warn_ignored(const Header& header, const Elements& elements,
                  const std::vector<BrokenElement>& broken, const Warnings& warn) {
  constexpr std::size_t kNamed = 4;
  std::string ignored;
  std::size_t ignored_count = 0;
  for (std::size_t e : elements.ignored) {
    if (std::any_of(broken.begin(), broken.end(),
                    [e](const BrokenElement& b) { return b.index == e; })) {
      continue;
    }
    const Element& element = header.elements[e];
    if (++ignored_count > kNamed) continue;
    if (!ignored.empty()) ignored += ", ";
    ignored +=
        "'" + ply::printable(element.name) + "' (" +
        plural(static_cast<std::size_t>(element.count), "row") +
        (element.name == "face" || element.name == "tristrips" ? ", no vertex_indices" : "") + ")";
  }
  if (ignored_count > kNamed) ignored += " and " + std::to_string(ignored_count - kNamed) + " more";
  if (ignored_count > 0) {
    warn(std::string(ignored_count > 1 ? "ignoring elements " : "ignoring element ") + ignored);
  }
}

// What a later element that does not match its header costs, appended to its
// problem: the element (and, binary, every element after it, which can no
// longer be located) and, when it held faces, the faces.
std::string broken_consequence(const Header& header, std::size_t index, bool binary,
                               bool faces_lost) {
  const std::size_t after = binary ? header.elements.size() - index - 1 : 0;
  std::string text =
      "; ignoring element '" + ply::printable(header.elements[index].name) + "'" +
      (after > 0 ? " and the " + plural(after, "element") + " after it" : std::string());
  if (faces_lost) text += "; the points load without faces, as a point cloud";
  return text;
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
  if (roles.colors() && !u8_colors) {
    plan.colors.assign(vertex_count, glm::u8vec4(0, 0, 0, 255));
    const std::array<int, 3> channels{roles.red, roles.green, roles.blue};
    for (std::size_t c = 0; c < 3; ++c) {
      const Type type = property(vertex, channels[c]).type;
      for_each_fixed(vertex_bytes, vertex, channels[c], big_endian, [&](std::size_t i, double x) {
        plan.colors[i][static_cast<glm::length_t>(c)] = ply::color_channel(x, type);
      });
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

  // Reserve only what the validated body can hold: binary counts were
  // checked byte for byte, ascii counts against the token capacity.
  constexpr std::size_t kCanonicalVertexBytes = 27;
  const auto vertex_count = static_cast<std::size_t>(vertex.count);
  plan.vertex_bytes.reserve(vertex_count * kCanonicalVertexBytes);
  if (elements.roles.radius >= 0) plan.radii.reserve(vertex_count);

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

// Runs OpenMesh, checks that it read exactly the rows it was given, and adds
// what we read ourselves.
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
  if (!plan.radii.empty()) points.radii = std::move(plan.radii);

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

// Makes the PointSet contract hold: finite positions, unit (or zero)
// normals, radii all positive or none.
void tidy(PointSet& points, const Warnings& warn, PlyLoadReport& report) {
  const bool huge =
      std::any_of(points.positions.begin(), points.positions.end(), [](const glm::vec3& p) {
        return std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z) && out_of_range(p);
      });
  const std::size_t read = points.size();
  if (std::all_of(points.positions.begin(), points.positions.end(), out_of_range)) {
    // One line that names the real problem, not a warning about dropping
    // every point followed by an error about having none.
    throw ply::Error("no finite points (" +
                     (read == 1 ? std::string("the only vertex is")
                                : "all " + std::to_string(read) + " vertices are") +
                     " NaN or infinite" + (huge ? " or beyond 1e18" : "") + ")");
  }
  const auto [dropped_points, dropped_faces] = drop_nonfinite(points);
  report.dropped_nonfinite = dropped_points;
  if (dropped_points > 0) {
    warn("dropped " + plural(dropped_points, "point") + " with non-finite" +
         (huge ? " or out-of-range (beyond 1e18)" : "") + " coordinates" +
         (dropped_faces > 0 ? " and " + plural(dropped_faces, "face") + " using them" : ""));
  }

  if (points.has_normals()) {
    std::size_t undefined = 0;
    for (glm::vec3& n : points.normals) {
      // In double: squaring a large finite float component must not overflow.
      const double x = n.x;
      const double y = n.y;
      const double z = n.z;
      const double length = std::sqrt(x * x + y * y + z * z);
      if (std::isfinite(length) && length > 0.0) {
        n = glm::vec3(static_cast<float>(x / length), static_cast<float>(y / length),
                      static_cast<float>(z / length));
      } else {
        if (!std::isfinite(length)) ++undefined;
        n = glm::vec3(0.0f);
      }
    }
    if (undefined > 0) warn(plural(undefined, "normal") + " not finite, set to zero");
  }
  if (points.has_radii()) {
    const auto bad = static_cast<std::size_t>(
        std::count_if(points.radii.begin(), points.radii.end(),
                      [](float r) { return !(std::isfinite(r) && r > 0.0f); }));
    if (bad > 0) {
      warn("ignoring the radius property: " + std::to_string(bad) + " of " +
           std::to_string(points.radii.size()) + " radii are not positive finite numbers");
      points.radii.clear();
    }
  }
}

PointSet load(std::string_view file, const Warnings& warn, PlyLoadReport& report) {
  const Header header = ply::parse_header(file);
  const ply::BinaryLayout layout = validate_body(header, file);
  const std::size_t lost_from =
      layout.broken >= 0 ? static_cast<std::size_t>(layout.broken) : header.elements.size();
  const Elements elements = classify(header, warn, lost_from);
  const VertexRoles& roles = elements.roles;
  report.vertices_in_file = static_cast<std::size_t>(header.elements[elements.vertex].count);
  report.had_normals = roles.normals();
  report.had_colors = roles.colors();
  report.had_radius = roles.radius >= 0;

  Plan plan;
  plan.strips.vertices = report.vertices_in_file;
  if (openmesh_reads_directly(header, roles, elements.face)) {
    plan_direct(header, layout, file, elements, plan);
  } else {
    plan_transcoded(header, layout, file, elements, plan);
  }
  warn_ignored(header, elements, plan.broken, warn);
  const bool binary = header.format != Format::ascii;
  if (layout.broken >= 0) {
    warn(layout.problem + broken_consequence(header, lost_from, binary, elements.faces_lost));
  }
  for (const BrokenElement& b : plan.broken) {
    const int index = static_cast<int>(b.index);
    const bool faces = index == elements.face || index == elements.strips;
    warn(b.problem + broken_consequence(header, b.index, binary, faces && plan.faces_lost));
  }
  report.faces_lost = elements.faces_lost || plan.faces_lost;
  // After an element that does not match its header, what follows the last
  // row is part of the same problem, not news.
  if (layout.broken < 0 && plan.broken.empty()) {
    if (layout.trailing_bytes > 0) {
      warn("ignoring " + plural(layout.trailing_bytes, "byte") + " after the last element");
    }
    if (plan.trailing_lines > 0) {
      warn("ignoring " + plural(plan.trailing_lines, "line") + " after the last element");
    }
  }
  PointSet points = read_plan(plan, warn, report);
  tidy(points, warn, report);
  return points;
}

}  // namespace

PointSet load_ply_from_memory(std::string_view bytes, const std::string& name,
                              PlyLoadReport* report, const WarningSink& warn) {
  PlyLoadReport local;
  try {
    PointSet points = load(bytes, Warnings(name, warn), local);
    if (report) *report = local;
    return points;
  } catch (const ply::Error& e) {
    throw InputError(name + ": " + e.what());
  }
}

PointSet load_ply(const std::filesystem::path& path, PlyLoadReport* report,
                  const WarningSink& warn) {
  const std::string name = path.string();
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) {
    throw InputError(name + ": " + (ec ? ec.message() : "not a regular file"));
  }
  const std::uintmax_t size = std::filesystem::file_size(path, ec);
  if (ec) throw InputError(name + ": " + ec.message());
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(name + ": cannot open for reading");
  // Uninitialized: the buffer is overwritten by the read right away.
  auto buffer = std::make_unique_for_overwrite<char[]>(static_cast<std::size_t>(size));
  in.read(buffer.get(), static_cast<std::streamsize>(size));
  if (static_cast<std::uintmax_t>(in.gcount()) != size) {
    throw InputError(name + ": cannot read the whole file");
  }
  return load_ply_from_memory(std::string_view(buffer.get(), static_cast<std::size_t>(size)), name,
                              report, warn);
}

}  // namespace treecut
