// What a PLY file holds, as load_ply uses it: the vertex properties by
// meaning (position, normal, colour, radius), the elements read and ignored,
// and the warnings that name what is ignored or lost (ply_load_parts.hpp).
#include <algorithm>
#include <cstdint>
#include <limits>
#include <string>

#include "ply_load_parts.hpp"

namespace treecut::ply_load {

namespace {

int scalar_property(const Element& element, std::string_view name) {
  int p = element.find(name);
  if (p >= 0 && element.properties[static_cast<std::size_t>(p)].is_list) return -1;
  return p;
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

  std::vector<std::string> not_kept;
  for (int p = 0; p < static_cast<int>(vertex.properties.size()); ++p) {
    const Property& prop = property(vertex, p);
    const bool used = p == roles.x || p == roles.y || p == roles.z || p == roles.nx ||
                      p == roles.ny || p == roles.nz || p == roles.red || p == roles.green ||
                      p == roles.blue || p == roles.radius;
    if (used || prop.name == "alpha" || prop.name == "diffuse_alpha") continue;
    if (prop.is_list || roles.attributes.size() >= kMaxAttributes) {
      not_kept.push_back("'" + ply::printable(prop.name) + "'" + (prop.is_list ? " (a list)" : ""));
    } else {
      roles.attributes.push_back(p);
    }
  }
  if (!not_kept.empty()) warn("vertex properties not kept: " + detail::join(not_kept));
  return roles;
}

}  // namespace

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

std::string broken_consequence(const Header& header, std::size_t index, bool binary,
                               bool faces_lost) {
  const std::size_t after = binary ? header.elements.size() - index - 1 : 0;
  std::string text =
      "; ignoring element '" + ply::printable(header.elements[index].name) + "'" +
      (after > 0 ? " and the " + plural(after, "element") + " after it" : std::string());
  if (faces_lost) text += "; the points load without faces, as a point cloud";
  return text;
}

}  // namespace treecut::ply_load
