// TreeCut: an unordered index list with a node -> slot map, so that refine and
// coarsen cost O(children) and the list stays dense for drawing.
#include "treecut/tree_cut.hpp"

#include <stdexcept>

namespace treecut {

TreeCut TreeCut::root_cut(const Hierarchy& h) {
  TreeCut cut;
  cut.slot_.assign(h.node_count(), kNotInCut);
  if (!h.empty()) cut.insert(h.root());
  return cut;
}

TreeCut TreeCut::leaf_cut(const Hierarchy& h) {
  TreeCut cut;
  cut.slot_.assign(h.node_count(), kNotInCut);
  cut.nodes_.reserve(h.leaf_count());
  for (NodeId n = 0; n < h.node_count(); ++n)
    if (h.is_leaf(n)) cut.insert(n);
  return cut;
}

TreeCut TreeCut::from_nodes(const Hierarchy& h, std::span<const NodeId> nodes) {
  if (auto why = validate(h, nodes); !why.empty()) throw std::invalid_argument("TreeCut: " + why);
  TreeCut cut;
  cut.slot_.assign(h.node_count(), kNotInCut);
  cut.nodes_.reserve(nodes.size());
  for (NodeId n : nodes) cut.insert(n);
  return cut;
}

void TreeCut::insert(NodeId n) {
  slot_[n] = static_cast<std::uint32_t>(nodes_.size());
  nodes_.push_back(n);
}

void TreeCut::erase(NodeId n) {
  const std::uint32_t s = slot_[n];
  const NodeId last = nodes_.back();
  nodes_[s] = last;
  slot_[last] = s;
  nodes_.pop_back();
  slot_[n] = kNotInCut;
}

bool TreeCut::refine(const Hierarchy& h, NodeId node) {
  if (!contains(node) || h.is_leaf(node)) return false;
  const NodeId c0 = h.first_child(node);
  const unsigned cc = h.child_count(node);
  // The first child takes the parent's slot; the others are appended.
  const std::uint32_t s = slot_[node];
  slot_[node] = kNotInCut;
  nodes_[s] = c0;
  slot_[c0] = s;
  for (NodeId c = c0 + 1; c < c0 + cc; ++c) insert(c);
  ++refinements_;
  return true;
}

bool TreeCut::can_coarsen(const Hierarchy& h, NodeId parent) const {
  if (parent >= h.node_count() || h.is_leaf(parent) || contains(parent)) return false;
  const NodeId c0 = h.first_child(parent);
  for (NodeId c = c0; c < c0 + h.child_count(parent); ++c)
    if (!contains(c)) return false;
  return true;
}

bool TreeCut::coarsen(const Hierarchy& h, NodeId parent) {
  if (!can_coarsen(h, parent)) return false;
  const NodeId c0 = h.first_child(parent);
  const std::uint32_t s = slot_[c0];
  slot_[c0] = kNotInCut;
  nodes_[s] = parent;
  slot_[parent] = s;
  for (NodeId c = c0 + 1; c < c0 + h.child_count(parent); ++c) erase(c);
  ++coarsenings_;
  return true;
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
