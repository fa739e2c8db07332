// TreeCut: the current level of detail, an unordered index list of hierarchy
// nodes such that every leaf of the hierarchy lies under exactly one of them.
//
// refine() and coarsen() are O(children) thanks to a node -> slot map; the
// index list itself (nodes()) is what the renderer draws. The map is sparse
// (SparseNodeArray): its memory follows the cut, not the hierarchy (issue
// 45). Not thread-safe: the Feedback Stage works on its own copy and the
// exchange swaps whole cuts.
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "treecut/hierarchy.hpp"
#include "treecut/sparse_node_array.hpp"

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
  /// Bytes the cut holds: the list, the moves tracked and the slot map's
  /// blocks (about the cut's size, not the hierarchy's).
  [[nodiscard]] std::size_t memory_bytes() const;
  /// A hint that refine/coarsen/contains will soon read n's entry of the
  /// node -> slot map: the event queue edits the cut at nodes in random order,
  /// and that map's cache miss was half of refine()'s time.
  void prefetch(NodeId n) const {
    if (n < slot_.size()) slot_.prefetch(n);
  }
  /// The next step for a cut node whose slot entry is in cache (after
  /// prefetch(n)): its position in the list, which refine and coarsen write.
  void prefetch_position(NodeId n) const {
    if (n < slot_.size() && slot_[n] != kNotInCut) __builtin_prefetch(nodes_.data() + slot_[n], 1);
  }

  /// Replaces `node` (which must be in the cut and not a leaf) by its children.
  /// Returns false and changes nothing otherwise.
  bool refine(const Hierarchy& h, NodeId node);
  /// Replaces the children of `parent` (all of which must be in the cut) by
  /// `parent`. Returns false and changes nothing otherwise.
  bool coarsen(const Hierarchy& h, NodeId parent);
  /// refine() and coarsen() for a caller that has the node's children range
  /// [first, first + count) at hand (exactly the hierarchy's) and has checked
  /// the precondition (node in the cut and not a leaf; every child in the
  /// cut): the same edits without reading the hierarchy's arrays, which were
  /// two more cache misses per edit for the event queue (it keeps a copy of
  /// the range beside each node's sphere).
  void refine_known(NodeId node, NodeId first, unsigned count);
  void coarsen_known(NodeId parent, NodeId first, unsigned count);
  /// True when every child of `parent` is in the cut, so coarsen() would succeed.
  /// Inline: the strategies ask it in their per-node pass.
  [[nodiscard]] bool can_coarsen(const Hierarchy& h, NodeId parent) const {
    if (parent >= h.node_count() || h.is_leaf(parent) || contains(parent)) return false;
    const NodeId c0 = h.first_child(parent);
    for (NodeId c = c0; c < c0 + h.child_count(parent); ++c) {
      if (!contains(c)) return false;
    }
    return true;
  }

  /// List positions written since the list was last sorted (refine and
  /// coarsen write one per child), or size() when too many to track.
  [[nodiscard]] std::size_t disorder() const { return scattered_ ? nodes_.size() : moved_.size(); }
  /// Reorders the list by ascending node id and rebuilds the slot map. Ids are
  /// breadth-first over a spatial tree, so a sorted cut walks the node arrays
  /// with ascending addresses: neighbours share cache lines and the prefetcher
  /// follows. A scattered cut of a large model misses the cache at every node
  /// (3x slower evaluation, tests/bench/strategy_bench). The positions written
  /// since the last sort are tracked, so sorting a nearly sorted list costs a
  /// sort of the moved nodes and one merge pass; otherwise a radix sort.
  /// `scratch` is a reusable buffer.
  void sort(std::vector<NodeId>& scratch);
  /// sort() once disorder() exceeds 1/16 of the size: evolving strategies call
  /// it before their pass, so the sort is amortized over many iterations.
  /// Returns true when it sorted.
  bool keep_sorted(std::vector<NodeId>& scratch);

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
  void moved(std::uint32_t position);
  void forget_moves(bool sorted);

  std::vector<NodeId> nodes_;
  SparseNodeArray<std::uint32_t> slot_;  // node id -> index in nodes_, or kNotInCut
  std::vector<std::uint32_t> moved_;     // positions written since the last sort
  bool scattered_ = false;               // moved_ overflowed: order unknown
  std::uint64_t refinements_ = 0;
  std::uint64_t coarsenings_ = 0;
};

/// Sorts `ids` (all below `id_end`) ascending in place: LSD radix sort with
/// 11-bit digits, one O(n) pass per digit. `scratch` is the ping-pong buffer;
/// both vectors keep their capacity.
void sort_node_ids(std::vector<NodeId>& ids, NodeId id_end, std::vector<NodeId>& scratch);

}  // namespace treecut
