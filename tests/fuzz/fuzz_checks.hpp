// What must hold for any input the loaders accept, shared by the fuzz targets
// (tests/fuzz/*_fuzz.cpp) and the replay of their regressions
// (tests/core/fuzz_regression_test.cpp). Each check returns an empty string or the
// first problem. Header-only: the fuzz targets and the tests build it with
// their own flags.
#pragma once

#include <cmath>
#include <cstddef>
#include <string>
#include <vector>

#include "treecut/attributes.hpp"
#include "treecut/error.hpp"
#include "treecut/hierarchy.hpp"
#include "treecut/las.hpp"
#include "treecut/pcd.hpp"
#include "treecut/ply.hpp"
#include "treecut/point_set.hpp"
#include "treecut/text_cloud.hpp"
#include "treecut/tree_cut.hpp"

namespace treecut::fuzz {

/// The bytes of a point file other than PLY through the reader open_model
/// would choose by its first bytes: LAS ("LASF"), PCD (its header), else a
/// text cloud. Throws InputError as the readers do; LAS says whether it was
/// LAS; the readers' warnings go to WARN.
inline PointSet load_point_bytes(
    std::string_view bytes, LasLoadReport& report, bool& las,
    const WarningSink& warn = [](const std::string&) {}) {
  const WarningSink& quiet = warn;
  las = looks_like_las(bytes);
  if (las) return load_las_from_memory(bytes, "fuzz.las", &report, quiet);
  if (looks_like_pcd(bytes)) return load_pcd_from_memory(bytes, "fuzz.pcd", quiet);
  return load_text_cloud_from_memory(bytes, "fuzz.xyz", quiet);
}

/// The contract of load_ply (ply.hpp, point_set.hpp): every array empty or of
/// size(), positions finite, normals unit or zero, radii finite and > 0,
/// opaque colours, triangle indices in range.
inline std::string check_point_set(const PointSet& p) {
  const std::size_t n = p.size();
  if (n == 0) return "loaded without points";
  auto sized = [n](std::size_t s) { return s == 0 || s == n; };
  if (!sized(p.normals.size()) || !sized(p.radii.size()) || !sized(p.colors.size()) ||
      !sized(p.curvature.size()))
    return "an attribute array is neither empty nor of the point count";
  for (const glm::vec3& v : p.positions)
    if (!std::isfinite(v.x) || !std::isfinite(v.y) || !std::isfinite(v.z))
      return "a non-finite position survived";
  for (const glm::vec3& v : p.normals) {
    const float len2 = v.x * v.x + v.y * v.y + v.z * v.z;
    if (!std::isfinite(len2) || (len2 != 0.0f && std::fabs(len2 - 1.0f) > 1e-3f))
      return "a normal is neither unit nor zero";
  }
  for (float r : p.radii)
    if (!std::isfinite(r) || r <= 0.0f) return "a radius is not finite and positive";
  for (const glm::u8vec4& c : p.colors)
    if (c.w != 255) return "a colour is not opaque";
  for (const glm::uvec3& t : p.triangles)
    if (t.x >= n || t.y >= n || t.z >= n) return "a triangle index is out of range";
  // Attributes (issues 29 and 43): one value a point (stored in one of the
  // three forms), finite or NaN, at most kMaxAttributes of short names,
  // offsets finite; exact positions, where kept, one a point and finite.
  if (p.attributes.size() > kMaxAttributes) return "more attributes than kMaxAttributes";
  for (const PointAttribute& a : p.attributes) {
    if (!a.values.empty() && !a.wide.empty()) return "attribute " + a.name + " is stored twice";
    if (!a.is_constant() && a.stored() != n)
      return "attribute " + a.name + " is not of the point count";
    if (a.name.size() > kMaxAttributeName) return "an attribute name is too long";
    if (!std::isfinite(a.offset)) return "attribute " + a.name + " has a non-finite offset";
    for (std::size_t i = 0; i < a.stored(); ++i) {
      if (std::isinf(a.value(i))) return "attribute " + a.name + " holds an infinity";
    }
    if (std::isinf(a.constant)) return "attribute " + a.name + " is an infinity";
  }
  if (!p.exact_positions.empty() && p.exact_positions.size() != n)
    return "exact positions are not of the point count";
  if (!p.colors16.empty() && p.colors16.size() != n)
    return "16-bit colours are not of the point count";
  for (const glm::dvec3& e : p.exact_positions) {
    if (!std::isfinite(e.x) || !std::isfinite(e.y) || !std::isfinite(e.z))
      return "an exact position is not finite";
  }
  return {};
}

/// What the renderer and the strategies rely on in a hierarchy that
/// load_cache() accepted, whatever the bytes: every node reached exactly once
/// from the root through the child ranges, parent links that point back, the
/// leaf count, and cuts that refine from the root to the leaves and coarsen
/// back. (Geometric invariants are not promised for a file whose checksum
/// was forged; check_invariants() must only not crash on it.)
inline std::string check_loaded_hierarchy(const Hierarchy& h) {
  const std::uint32_t n = h.node_count();
  if (n == 0 || h.level_count() < 1) return "loaded empty";
  if (h.parent(h.root()) != kNoNode) return "the root has a parent";
  for (const NodeAttribute& a : h.attributes()) {
    if (!a.is_constant() && a.values.size() != n)
      return "attribute " + a.name + " is not of the node count";
    // Any float is a value the colouring takes (NaN: none; infinities clamp).
    if (a.name.size() > kMaxAttributeName) return "an attribute name is too long";
  }
  std::vector<bool> seen(n, false);
  std::vector<NodeId> order{h.root()};  // breadth first
  seen[h.root()] = true;
  std::uint32_t leaves = 0;
  for (std::size_t i = 0; i < order.size(); ++i) {
    const NodeId node = order[i];
    if (h.is_leaf(node)) {
      ++leaves;
      continue;
    }
    const NodeId c0 = h.first_child(node);
    const unsigned cc = h.child_count(node);
    if (c0 >= n || cc > n - c0) return "a child range leaves the node arrays";
    for (NodeId c = c0; c < c0 + cc; ++c) {
      if (seen[c]) return "node " + std::to_string(c) + " is the child of two nodes";
      if (h.parent(c) != node) return "node " + std::to_string(c) + " does not point to its parent";
      seen[c] = true;
      order.push_back(c);
    }
  }
  if (order.size() != n) {
    return std::to_string(n - order.size()) + " nodes are not reachable from the root";
  }
  if (h.leaf_count() != leaves) {
    return "leaf_count() is " + std::to_string(h.leaf_count()) + ", the tree has " +
           std::to_string(leaves) + " leaves";
  }

  TreeCut cut = TreeCut::root_cut(h);
  for (NodeId node : order)
    if (!h.is_leaf(node) && !cut.refine(h, node)) return "refine failed";
  if (cut.size() != leaves) return "refining every node does not give the leaves";
  if (std::string why = cut.validate(h); !why.empty()) return "leaf cut: " + why;
  if (std::string why = TreeCut::leaf_cut(h).validate(h); !why.empty()) return "leaf_cut: " + why;
  for (auto it = order.rbegin(); it != order.rend(); ++it)
    if (!h.is_leaf(*it) && !cut.coarsen(h, *it)) return "coarsen failed";
  if (cut.size() != 1 || cut.nodes()[0] != h.root()) return "coarsening does not end at the root";
  (void)check_invariants(h);
  return {};
}

/// A point set load_ply() accepted goes through the rest of the data path:
/// attributes and the hierarchy build, whose invariants must hold.
inline std::string check_builds(PointSet points) {
  complete_attributes(points);
  const Hierarchy h = build_hierarchy(std::move(points));
  if (std::string why = check_invariants(h); !why.empty()) return "built hierarchy: " + why;
  return check_loaded_hierarchy(h);
}

/// Whether a reader's message is about coordinates past kMaxCoordinate
/// (1e18) of the origin: a reader in batches takes the first batch's
/// origin, a whole read one from every point, so such points may be others.
inline bool about_far_points(const std::string& message) {
  return message.find("1e18") != std::string::npos;
}

/// A reader's batches (READER, a PlyReader or PcdReader, over BYTES) against
/// the whole read: the same points in all (WHOLE: the count the whole read
/// kept, or -1 where it refused the file, which the batches must refuse
/// too), but where either read dropped points past 1e18 (WHOLE_FAR: the
/// whole read's warnings or error said so); every batch within the
/// contract and, where the reader streams the file (else it is one batch of
/// the whole read), at most BATCH points.
template <class Reader>
std::string check_batches(std::string_view bytes, long long whole, bool whole_far,
                          std::size_t batch) {
  bool far = whole_far;
  std::size_t points = 0;
  try {
    Reader reader(bytes, "fuzz", [&](const std::string& w) { far = far || about_far_points(w); });
    for (;;) {
      const PointSet b = reader.next(batch);
      if (b.size() == 0) break;
      if (reader.streams() && b.size() > batch) return "a batch past the batch size";
      if (std::string why = check_point_set(b); !why.empty()) return "a batch: " + why;
      points += b.size();
    }
  } catch (const InputError& e) {
    if (far || about_far_points(e.what())) return {};
    return whole < 0 ? "" : "the batches refused a file the whole read took";
  }
  if (far) return {};
  if (whole < 0) return "the batches took a file the whole read refused";
  if (points != static_cast<std::size_t>(whole)) return "the batches hold another count";
  return {};
}

}  // namespace treecut::fuzz
