// Which way is up in a model: x, y or z (or their negatives), from the data.
//
// PLY has no up axis. Scans and point clouds (airborne and terrestrial laser
// scans, photogrammetry) are z-up, the Stanford models and most graphics
// meshes y-up, so the file type says nothing. detect_up_axis() looks at the
// points and their normals instead; the rule, in order, first match wins:
//
//  1. A ground or a base: the side of the model where the points pile up in a
//     flat layer. For each of the six directions d, the share of the points in
//     the lowest 2% of the extent along d (extent between the 0.2% and 99.8%
//     quantiles, so a few outliers do not move it); the largest share wins if
//     it is at least 3.5% (a uniform spread gives 2%), the layer spans at
//     least a quarter of the model's cross-section (a pointed tip does not
//     count) and the layer at the other end holds at most half as many (a
//     base is at one end; a regular grid's edge columns are at both).
//     The ground of a scan, the base the Stanford dragon stands on,
//     the flat bottom of the bunny, the street of a city.
//  2. Normals that face one way: the direction d with the largest mean n.d
//     over the points, if at least 0.1. Scanners see surfaces from above and
//     from the side, never from below, and terrain faces up (a terrain, the
//     lion_takanawa photogrammetry cloud).
//  3. A flat model: an extent at most half the next smallest one is up (an
//     airborne scan whose normals, estimated from neighbours, have no
//     consistent orientation).
//  4. Normals that lean one way: the largest mean n.d, if at least 0.015 and
//     1.5 times the next largest (a scanned object with holes underneath).
//  5. Otherwise +z, the convention of scans and of the generated models (a
//     sphere, a closed object with nothing to tell).
// Before all of them, for a hierarchy: a file format that says which way is
// up (LAS, whose z is the height: Hierarchy::frame().z_up) is believed, and
// a depth camera's viewpoint (a PCD's VIEWPOINT, frame().viewpoint): up is
// the camera's -y.
//
// GL-free, deterministic, and cheap: at most about a million points are read.
#pragma once

#include <glm/vec3.hpp>
#include <optional>
#include <span>
#include <string>
#include <string_view>

#include "treecut/hierarchy.hpp"

namespace treecut {

struct UpAxis {
  int axis = 2;           ///< 0 = x, 1 = y, 2 = z
  bool negative = false;  ///< up is minus the axis (a model upside down)
  /// Why detect_up_axis() chose it, one phrase ("a ground or base: ..."), or
  /// empty for an axis given by the user.
  std::string reason;

  [[nodiscard]] glm::vec3 vector() const;
  /// "x", "y", "z", "-x", "-y" or "-z".
  [[nodiscard]] std::string name() const;
  friend bool operator==(const UpAxis& a, const UpAxis& b) {
    return a.axis == b.axis && a.negative == b.negative;
  }
};

/// "x", "y", "z", "-x", "-y", "-z" (a leading '+' is accepted); nullopt otherwise.
std::optional<UpAxis> parse_up_axis(std::string_view text);

/// The rule above on points and their normals (NORMALS empty or of the same
/// size; zero normals count as undefined). POSITIONS must not be empty.
UpAxis detect_up_axis(std::span<const glm::vec3> positions, std::span<const glm::vec3> normals);

/// The rule above on the leaves of a hierarchy (its points, with their
/// normals), sampled evenly when there are more than about a million.
UpAxis detect_up_axis(const Hierarchy& hierarchy);
/// The same on the leaves of the part of it that is KNOWN (sample_leaves:
/// a paged model's root page, its finest nodes there). Unless KNOWN is the
/// whole hierarchy, rule 1 is left out: those nodes are coarse, their
/// centres means of their points, which pile up nowhere.
UpAxis detect_up_axis(const Hierarchy& hierarchy, std::span<const NodeRange> known);

/// The next axis for a key that cycles through them: x -> y -> z -> x (a
/// negative axis goes on to the next positive one).
UpAxis next_up_axis(const UpAxis& current);

}  // namespace treecut
