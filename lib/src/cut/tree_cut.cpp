// TreeCut: an unordered index list with a node -> slot map, so that refine and
// coarsen cost O(children) and the list stays dense for drawing.
#include "treecut/tree_cut.hpp"

#include <algorithm>
#include <bit>
#include <stdexcept>
#include <utility>

#include "support/radix_sort.hpp"

namespace treecut {

TreeCut TreeCut::root_cut(const Hierarchy& h) {
  TreeCut cut;
  cut.slot_.assign(h.node_count(), kNotInCut);
  if (!h.empty()) cut.insert(h.root());
  cut.forget_moves(true);
  return cut;
}

TreeCut TreeCut::leaf_cut(const Hierarchy& h) {
  TreeCut cut;
  cut.slot_.assign(h.node_count(), kNotInCut);
  cut.nodes_.reserve(h.leaf_count());
  // Level by level from the root, not every id: a paged hierarchy's nodes
  // past its resident pages are not in the tree (paged_hierarchy.hpp). The
  // ids are breadth-first, so the leaves come in id order.
  std::vector<NodeId> level{h.root()}, next;
  while (!level.empty()) {
    next.clear();
    for (const NodeId n : level) {
      if (h.is_leaf(n)) cut.insert(n);
      for (NodeId c = h.first_child(n); c < h.first_child(n) + h.child_count(n); ++c)
        next.push_back(c);
    }
    std::swap(level, next);
  }
  cut.forget_moves(true);  // inserted in id order
  return cut;
}

TreeCut TreeCut::from_nodes(const Hierarchy& h, std::span<const NodeId> nodes) {
  if (auto why = validate(h, nodes); !why.empty()) throw std::invalid_argument("TreeCut: " + why);
  TreeCut cut;
  cut.slot_.assign(h.node_count(), kNotInCut);
  cut.nodes_.reserve(nodes.size());
  for (NodeId n : nodes) cut.insert(n);
  cut.forget_moves(std::is_sorted(nodes.begin(), nodes.end()));
  return cut;
}

void TreeCut::sort(std::vector<NodeId>& scratch) {
  const std::size_t size = nodes_.size();
  const auto id_end = static_cast<NodeId>(slot_.size());
  if (scattered_ || moved_.size() * 4 > size) {
    sort_node_ids(nodes_, id_end, scratch);
    // Ascending ids: the slot map is written with ascending addresses. A
    // full sort follows many edits (a quarter of the cut moved), so it is
    // also when the map gives back the blocks the cut has left.
    for (std::uint32_t s = 0; s < size; ++s) slot_.set(nodes_[s], s);
    slot_.release_unused();
  } else {
    // Positions not written since the last sort still hold their nodes in
    // ascending order: pull the written ones out (kNotInCut marks them, and
    // a position written twice is taken once), sort those, merge back.
    scratch.clear();
    for (const std::uint32_t p : moved_) {
      if (p < size && nodes_[p] != kNotInCut) {
        scratch.push_back(nodes_[p]);
        nodes_[p] = kNotInCut;
      }
    }
    // The positions are spent: their buffer is the radix sort's ping-pong,
    // then the merged list.
    moved_.clear();
    if (scratch.size() > 4096) {
      sort_node_ids(scratch, id_end, moved_);
    } else {
      std::sort(scratch.begin(), scratch.end());
    }
    // One forward pass merges and writes the slot map.
    std::vector<NodeId>& merged = moved_;
    merged.clear();
    merged.reserve(nodes_.capacity());
    const auto put = [&](NodeId n) {
      slot_.set(n, static_cast<std::uint32_t>(merged.size()));
      merged.push_back(n);
    };
    std::size_t j = 0;
    for (const NodeId n : nodes_) {
      if (n == kNotInCut) continue;
      while (j < scratch.size() && scratch[j] < n) put(scratch[j++]);
      put(n);
    }
    while (j < scratch.size()) put(scratch[j++]);
    nodes_.swap(merged);
  }
  forget_moves(true);
}

// insert() records every position it writes; a freshly built or sorted list
// starts with no moves, and is either sorted or of unknown order.
void TreeCut::forget_moves(bool sorted) {
  moved_.clear();
  scattered_ = !sorted;
}

bool TreeCut::keep_sorted(std::vector<NodeId>& scratch) {
  // Evaluation time grows about linearly with the scattered fraction while a
  // sort costs a few ns per node; re-sorting at 1/16 keeps the average
  // penalty and the amortized sort both small at the refine/coarsen rates of
  // the strategies (a few per mille of the cut per iteration).
  if (disorder() * 16 <= nodes_.size()) return false;
  sort(scratch);
  return true;
}

std::size_t TreeCut::memory_bytes() const {
  return (nodes_.capacity() + moved_.capacity()) * sizeof(NodeId) + slot_.memory_bytes();
}

void TreeCut::moved(std::uint32_t position) {
  if (scattered_) return;
  // Beyond a quarter of the list a full sort is as cheap: stop tracking.
  if (moved_.size() >= std::max<std::size_t>(64, nodes_.size() / 4)) {
    scattered_ = true;
    moved_.clear();
    return;
  }
  moved_.push_back(position);
}

void sort_node_ids(std::vector<NodeId>& ids, NodeId id_end, std::vector<NodeId>& scratch) {
  detail::radix_sort(ids, 0, static_cast<unsigned>(std::bit_width(std::max<NodeId>(id_end, 1) - 1)),
                     scratch);
}

void TreeCut::insert(NodeId n) {
  const auto s = static_cast<std::uint32_t>(nodes_.size());
  slot_.set(n, s);
  nodes_.push_back(n);
  moved(s);
}

void TreeCut::erase(NodeId n) {
  const std::uint32_t s = slot_[n];
  const NodeId last = nodes_.back();
  nodes_[s] = last;
  slot_.set(last, s);
  nodes_.pop_back();
  slot_.set(n, kNotInCut);
  if (s < nodes_.size()) moved(s);
}

bool TreeCut::refine(const Hierarchy& h, NodeId node) {
  if (!contains(node) || h.is_leaf(node)) return false;
  refine_known(node, h.first_child(node), h.child_count(node));
  return true;
}

bool TreeCut::coarsen(const Hierarchy& h, NodeId parent) {
  if (!can_coarsen(h, parent)) return false;
  coarsen_known(parent, h.first_child(parent), h.child_count(parent));
  return true;
}

void TreeCut::refine_known(NodeId node, NodeId first, unsigned count) {
  // The first child takes the parent's slot; the others are appended.
  const std::uint32_t s = slot_[node];
  slot_.set(node, kNotInCut);
  nodes_[s] = first;
  slot_.set(first, s);
  moved(s);
  for (NodeId c = first + 1; c < first + count; ++c) insert(c);
  ++refinements_;
}

void TreeCut::coarsen_known(NodeId parent, NodeId first, unsigned count) {
  // The parent takes the first child's slot; the other children are erased.
  const std::uint32_t s = slot_[first];
  slot_.set(first, kNotInCut);
  nodes_[s] = parent;
  slot_.set(parent, s);
  moved(s);
  for (NodeId c = first + 1; c < first + count; ++c) erase(c);
  ++coarsenings_;
}

std::string TreeCut::validate(const Hierarchy& h, std::span<const NodeId> nodes) {
  const std::uint32_t M = h.node_count();
  if (M == 0) return nodes.empty() ? std::string{} : "cut over an empty hierarchy";
  // Mark the cut, then walk down from the root: every path must meet exactly
  // one marked node before (or at) a leaf, and every marked node must be met.
  std::vector<std::uint8_t> mark(M, 0);
  for (NodeId n : nodes) {
    if (n >= M) return "node id " + std::to_string(n) + " out of range";
    if (mark[n]) return "node " + std::to_string(n) + " listed twice";
    mark[n] = 1;
  }
  std::size_t reached = 0;
  std::vector<NodeId> stack{h.root()};
  while (!stack.empty()) {
    const NodeId n = stack.back();
    stack.pop_back();
    if (mark[n]) {
      ++reached;
      continue;
    }
    if (h.is_leaf(n)) return "leaf " + std::to_string(n) + " is not covered";
    const NodeId c0 = h.first_child(n);
    for (NodeId c = c0; c < c0 + h.child_count(n); ++c) stack.push_back(c);
  }
  if (reached != nodes.size()) return "a listed node lies below another listed node";
  return {};
}

}  // namespace treecut
