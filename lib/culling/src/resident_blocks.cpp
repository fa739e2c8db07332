// HOQ's HLOD blocks made as the traversal reaches them (Charalambos et al.
// 2007, ../shared/papers/hoq-driven-hlod-refinement.txt): see
// resident_blocks.hpp.
#include "treecut/culling/resident_blocks.hpp"

#include <algorithm>
#include <stdexcept>

#include "block_representation.hpp"

namespace treecut::culling {

void ResidentBlocks::reset(std::uint32_t block_size) {
  if (block_size == 0) throw std::invalid_argument("ResidentBlocks: block_size must be at least 1");
  block_size_ = block_size;
  blocks_.clear();
  below_.clear();
}

void ResidentBlocks::make(const Hierarchy& h, NodeId n, Block& b) {
  const NodeId root = n;
  // HlodBlocks' limit for a one-node block: block_size for both kinds (a
  // leaf block's leaves fit it; an interior block refines within it).
  collect_representation(h, {&root, 1}, block_size_, queue_, b.rep, &b.hidden);
  const auto& a = h.arrays();
  b.box = representation_box(a, b.rep);
  b.error_radius = 0.0f;
  // A leaf block at full detail has no error left; one whose nodes are not
  // all resident has theirs (a parent's shift-up test reads it).
  if (!is_leaf(h, n) || !b.hidden.empty()) {
    for (const NodeId r : b.rep) b.error_radius = std::max(b.error_radius, a.center_radius[r].w);
  }
  b.stale = false;
}

const ResidentBlocks::Block& ResidentBlocks::at(const Hierarchy& h, NodeId n) {
  auto [it, made] = blocks_.try_emplace(n);
  Block& b = it->second;
  if (made) {
    b.parent = n == h.root() ? kNoNode : h.arrays().parent[n];
    below_[b.parent].push_back(n);
  }
  if (made || b.stale) make(h, n, b);
  return b;
}

void ResidentBlocks::mark_stale_up(const Hierarchy& h, NodeId n) {
  // Every block whose representation may reach N: N's and its ancestors'.
  for (NodeId x = n;; x = h.arrays().parent[x]) {
    if (const auto it = blocks_.find(x); it != blocks_.end()) it->second.stale = true;
    if (x == h.root()) return;
  }
}

void ResidentBlocks::drop_below(NodeId n, std::vector<NodeId>& dropped) {
  const auto it = below_.find(n);
  if (it == below_.end()) return;
  const std::vector<NodeId> children = std::move(it->second);
  below_.erase(it);
  for (const NodeId c : children) {
    drop_below(c, dropped);
    blocks_.erase(c);
    dropped.push_back(c);
  }
}

void ResidentBlocks::residency_changed(const Hierarchy& h, std::span<const NodeId> revealed,
                                       std::span<const NodeId> concealed,
                                       std::vector<NodeId>& dropped) {
  for (const NodeId n : revealed) mark_stale_up(h, n);
  for (const NodeId n : concealed) {
    mark_stale_up(h, n);
    drop_below(n, dropped);
  }
}

}  // namespace treecut::culling
