// The levels above subtrees built on their own (the chunks of the chunked
// build, issue 44; PotreeConverter 2's "top hierarchy over the chunks"):
// QSplat's median splits over the subtrees' roots, and its bottom-up pass
// from them (Rusinkiewicz & Levoy 2000, section 3.1), so that every node
// above a chunk is what the builder makes of its children. Private to the
// library (hierarchy.cpp builds them, chunked_build.cpp uses them).
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "treecut/hierarchy.hpp"

namespace treecut::detail {

/// A subtree's root as the levels above see it.
struct SubtreeRoot {
  glm::vec4 center_radius{0.0f};  ///< as its page decodes it
  /// The cover of its leaves' discs: the square root of the sum of their
  /// splat radii squared (what the builder's parents add up).
  float cover = 0.0f;
  glm::i16vec4 normal_cone{0};
  glm::u8vec4 color{0};
  float priority = 0.0f;
  std::uint32_t point_count = 0;
  /// Each attribute's value at the root, in the order of the attributes
  /// (a constant one's ignored).
  std::vector<float> values;
};

struct TopLevels {
  Hierarchy hierarchy;  ///< its leaves are the roots (their values as given)
  /// Each node's root (an index into the roots), kNoNode for the nodes
  /// above them.
  std::vector<NodeId> root_of;
};

/// The levels over ROOTS (at least one): nodes of two to four children by
/// median splits of the roots' centers, each filled from its children as
/// build_hierarchy fills them. ATTRIBUTES give each attribute's name, kind,
/// offset, range and, when constant, its value (their values are ignored).
TopLevels build_over_roots(std::span<const SubtreeRoot> roots,
                           const std::vector<NodeAttribute>& attributes, CoordinateFrame frame,
                           bool parent_at_real_point);

}  // namespace treecut::detail
