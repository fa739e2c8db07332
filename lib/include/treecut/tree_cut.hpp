// TreeCut: the current level of detail, an unordered index list of hierarchy
// nodes such that every leaf of the hierarchy lies under exactly one of them.
//
// refine() and coarsen() are O(children) thanks to a node -> slot map; the
// index list itself (nodes()) is what the renderer draws. Not thread-safe: the
// Feedback Stage works on its own copy and the exchange swaps whole cuts.
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "treecut/hierarchy.hpp"

namespace treecut {

class TreeCut {
 public:
  TreeCut() = default;
  /// The cut holding only the root.
  static TreeCut root_cut(const Hierarchy& h);
  /// The cut holding every leaf (full detail).
  static TreeCut leaf_cut(const Hierarchy& h);
  /// A cut from an explicit list; throws std::invalid_argument unless valid.
  static TreeCut from_nodes(const Hierarchy& h, std::span<const NodeId> nodes);

  [[nodiscard]] std::span<const NodeId> nodes() const { return nodes_; }
  [[nodiscard]] std::size_t size() const { return nodes_.size(); }
  [[nodiscard]] bool contains(NodeId n) const { return n < slot_.size() && slot_[n] != kNotInCut; }

  /// Replaces `node` (which must be in the cut and not a leaf) by its children.
  /// Returns false and changes nothing otherwise.
  bool refine(const Hierarchy& h, NodeId node);
  /// Replaces the children of `parent` (all of which must be in the cut) by
  /// `parent`. Returns false and changes nothing otherwise.
  bool coarsen(const Hierarchy& h, NodeId parent);
  /// True when every child of `parent` is in the cut, so coarsen() would succeed.
  [[nodiscard]] bool can_coarsen(const Hierarchy& h, NodeId parent) const;

  /// Refinements and coarsenings applied since construction or reset_counters().
  [[nodiscard]] std::uint64_t refinements() const { return refinements_; }
  [[nodiscard]] std::uint64_t coarsenings() const { return coarsenings_; }
  void reset_counters() { refinements_ = coarsenings_ = 0; }

  /// Full O(nodes) validity check of an index list against a hierarchy: every
  /// leaf covered by exactly one listed node, no duplicates, ids in range.
  /// Returns an empty string or the first problem.
  static std::string validate(const Hierarchy& h, std::span<const NodeId> nodes);
  [[nodiscard]] std::string validate(const Hierarchy& h) const { return validate(h, nodes_); }

 private:
  static constexpr std::uint32_t kNotInCut = 0xffffffffu;
  void insert(NodeId n);
  void erase(NodeId n);

  std::vector<NodeId> nodes_;
  std::vector<std::uint32_t> slot_;  // node id -> index in nodes_, or kNotInCut
  std::uint64_t refinements_ = 0;
  std::uint64_t coarsenings_ = 0;
};

}  // namespace treecut
