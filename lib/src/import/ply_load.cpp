// PLY import: our guard, then OpenMesh's reader, then our count checks.
// This file runs the pipeline; its parts are declared in ply_load_parts.hpp
// (elements, the way to OpenMesh, the PointSet contract).
//
// Pipeline: parse_header -> validate the body (binary: exact layout walk;
// ascii: every token parsed and type-checked) -> hand OpenMesh a header we
// wrote plus validated body bytes -> check OpenMesh's counts -> read what
// OpenMesh ignores (radius, non-uchar colours, tristrips) -> drop non-finite
// points -> tidy normals and radii.
//
// Which files go to OpenMesh as they are and which are transcoded first, and
// why: ply_plan.cpp.
#include <string>

#include "file_metadata.hpp"
#include "ply_load_parts.hpp"
#include "treecut/error.hpp"
#include "treecut/file_io.hpp"
#include "treecut/ply.hpp"
#include "whole_file.hpp"

namespace treecut {

namespace {

using ply::Format;
using ply::Header;
using ply_load::BrokenElement;
using ply_load::Elements;
using ply_load::Plan;
using ply_load::plural;
using ply_load::VertexRoles;
using ply_load::Warnings;

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

// BATCH: one batch of a streamed file (load_batch), or null.
PointSet load(std::string_view file, const Warnings& warn, PlyLoadReport& report,
              const std::optional<glm::dvec3>& origin = std::nullopt,
              ply_load::Tidied* batch = nullptr) {
  const Header header = ply::parse_header(file);
  const ply::BinaryLayout layout = validate_body(header, file);
  const std::size_t lost_from =
      layout.broken >= 0 ? static_cast<std::size_t>(layout.broken) : header.elements.size();
  const Elements elements = ply_load::classify(header, warn, lost_from);
  const VertexRoles& roles = elements.roles;
  report.vertices_in_file = static_cast<std::size_t>(header.elements[elements.vertex].count);
  report.had_normals = roles.normals();
  report.had_colors = roles.colors();
  report.had_radius = roles.radius >= 0;

  Plan plan;
  plan.origin = origin;
  plan.strips.vertices = report.vertices_in_file;
  ply_load::plan_openmesh_read(header, layout, file, elements, plan);
  ply_load::warn_ignored(header, elements, plan.broken, warn);
  const bool binary = header.format != Format::ascii;
  if (layout.broken >= 0) {
    warn(layout.problem +
         ply_load::broken_consequence(header, lost_from, binary, elements.faces_lost));
  }
  for (const BrokenElement& b : plan.broken) {
    const int index = static_cast<int>(b.index);
    const bool faces = index == elements.face || index == elements.strips;
    warn(b.problem +
         ply_load::broken_consequence(header, b.index, binary, faces && plan.faces_lost));
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
  PointSet points = ply_load::read_plan(plan, warn, report);
  for (const std::string& comment : header.comments) detail::read_metadata_line(comment, points);
  ply_load::tidy(points, warn, report, plan.finite_beyond_float, batch);
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

PointSet ply_load::load_batch(std::string_view bytes, const std::string& name,
                              PlyLoadReport& report, const WarningSink& warn,
                              const std::optional<glm::dvec3>& origin, Tidied& batch) {
  try {
    return load(bytes, Warnings(name, warn), report, origin, &batch);
  } catch (const ply::Error& e) {
    throw InputError(name + ": " + e.what());
  }
}

PointSet load_ply(const std::filesystem::path& path, PlyLoadReport* report,
                  const WarningSink& warn) {
  const detail::WholeFile file = detail::read_whole_file(path);
  return load_ply_from_memory(file.bytes(), quoted_name(path), report, warn);
}

}  // namespace treecut
