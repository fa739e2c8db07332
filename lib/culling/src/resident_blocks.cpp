// HOQ's HLOD blocks made as the traversal reaches them (Charalambos et al.
// 2007, ../shared/papers/hoq-driven-hlod-refinement.txt): see
// resident_blocks.hpp.
#include "treecut/culling/resident_blocks.hpp"

#include <algorithm>
#include <stdexcept>

#include "block_representation.hpp"

namespace treecut::culling {

void ResidentBlocks::reset(const Hierarchy& h, std::uint32_t block_size) {
  if (block_size == 0) throw std::invalid_argument("ResidentBlocks: block_size must be at least 1");
  block_size_ = block_size;
  slot_of_.assign(h.node_count(), 0);
  blocks_.clear();
  free_.clear();
}

void ResidentBlocks::make(const Hierarchy& h, Block& b) {
  const NodeId root = b.node;
  // HlodBlocks' limit for a one-node block: block_size for both kinds (a
  // leaf block's leaves fit it; an interior block refines within it).
  collect_representation(h, {&root, 1}, block_size_, queue_, b.rep, &b.hidden);
  const auto& a = h.arrays();
  b.box = representation_box(a, b.rep);
  b.error_radius = 0.0f;
  // A leaf block at full detail has no error left; one whose nodes are not
  // all resident has theirs (a parent's shift-up test reads it).
  if (!is_leaf(h, root) || !b.hidden.empty()) {
    for (const NodeId r : b.rep) b.error_radius = std::max(b.error_radius, a.center_radius[r].w);
  }
  b.stale = false;
}

const ResidentBlocks::Block& ResidentBlocks::at(const Hierarchy& h, NodeId n) {
  if (const std::uint32_t slot = find(n); slot != kNoSlot) {
    Block& b = blocks_[slot];
    if (b.stale) make(h, b);
    return b;
  }
  std::uint32_t slot = static_cast<std::uint32_t>(blocks_.size());
  if (!free_.empty()) {
    slot = free_.back();
    free_.pop_back();
  } else {
    blocks_.emplace_back();
  }
  Block& b = blocks_[slot];
  b.node = n;
  b.slot = slot;
  if (n != h.root())
    if (const std::uint32_t parent = find(h.arrays().parent[n]); parent != kNoSlot)
      blocks_[parent].children.push_back(slot);
  slot_of_.set(n, slot + 1);
  make(h, b);
  return b;
}

void ResidentBlocks::mark_stale_up(const Hierarchy& h, NodeId n) {
  // Every block whose representation may reach N: N's and its ancestors'.
  for (NodeId x = n;; x = h.arrays().parent[x]) {
    if (const std::uint32_t slot = find(x); slot != kNoSlot) blocks_[slot].stale = true;
    if (x == h.root()) return;
  }
}

void ResidentBlocks::drop_below(Block& b, std::vector<std::uint32_t>& dropped) {
  for (const std::uint32_t c : b.children) {
    Block& child = blocks_[c];
    drop_below(child, dropped);
    slot_of_.set(child.node, 0);
    child = Block{};
    free_.push_back(c);
    dropped.push_back(c);
  }
  b.children.clear();
}

void ResidentBlocks::residency_changed(const Hierarchy& h, std::span<const NodeId> revealed,
                                       std::span<const NodeId> concealed,
                                       std::vector<std::uint32_t>& dropped) {
  for (const NodeId n : revealed) mark_stale_up(h, n);
  for (const NodeId n : concealed) {
    mark_stale_up(h, n);
    if (const std::uint32_t slot = find(n); slot != kNoSlot) drop_below(blocks_[slot], dropped);
  }
}

}  // namespace treecut::culling
