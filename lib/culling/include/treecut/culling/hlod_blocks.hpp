// HLOD blocks: the hierarchy grouped into subtrees of about `block_size`
// splats, the unit of visibility for occlusion culling.
//
// One occlusion query per splat is far too fine (a query costs about as much
// as drawing a thousand splats), so the occlusion strategies query and decide
// per block, as both papers do with their scene hierarchies:
//   - J. Bittner, M. Wimmer, H. Piringer, W. Purgathofer, "Coherent
//     Hierarchical Culling: Hardware Occlusion Queries Made Useful",
//     Eurographics 2004 (../shared/papers/coherent-hierarchical-culling.tex.txt):
//     a hierarchy of bounding boxes, queried front to back, whose leaves hold
//     the geometry.
//   - L. Charalambos, J. Bittner, M. Wimmer, E. Romero, "Optimized HLOD
//     Refinement Driven by Hardware Occlusion Queries", ISVC 2007
//     (../shared/papers/hoq-driven-hlod-refinement.txt): an HLOD tree whose
//     every node has a box and a representation of its whole subtree at that
//     node's level; a cut of the HLOD tree is what is drawn.
//
// The blocks (fan_out 2: a binary, balanced tree like the CHC paper's
// kD-tree; fan_out 4: the hierarchy's own upper tree, the first form):
//   - Every block is a set of disjoint subtrees of the hierarchy (roots(b));
//     the root block is the hierarchy root. A block holding <= block_size
//     leaves (or a single leaf) is a leaf block, and its representation is
//     its leaves (full detail). Every leaf of the hierarchy is in exactly one
//     leaf block.
//   - fan_out 2: an interior block's two children split its subtrees (a
//     single subtree first becomes its root's children; a subtree with more
//     than a quarter of the leaves is replaced by its children) along the
//     longest axis of their centers, where the near side's leaves come
//     closest to floor(k/2)/k of the block's, k = ceil(leaves / block_size):
//     leaf blocks hold about leaves / k, more than block_size / 2 where the
//     subtrees' sizes allow it, instead of the slivers the hierarchy's
//     fan-out leaves (a parent just over block_size gave four quarters).
//     fan_out 4: a block is one node; its children are its node's children.
//   - root(b) is the lowest common ancestor of the block's subtrees (the
//     node itself for a one-node block): its sphere contains the block, but
//     is looser than the box for a block of several subtrees.
//   - An interior block's representation is a cut of its subtrees of at most
//     block_size nodes (or its subtree count, when larger): the roots refined
//     in id order (breadth first: the biggest splats first) while the count
//     fits. It is coarser than (or equal to) its children's representations
//     together, so never larger than their sum.
//   - Block ids are breadth-first over the tree of blocks (block 0 is the root
//     block; children of a block are a contiguous id range).
//   - Each block has an axis-aligned box containing the sphere of every node of
//     its representation and so (children lie inside their parent's sphere,
//     check_invariants) of every node below it: whatever the block draws at its
//     level or finer lies inside the box. Not the root's own sphere when the
//     representation is finer than the root: that splat is never drawn for it.
//
// A cut of blocks (every leaf block under exactly one block of the list) maps to
// a TreeCut index list (the concatenated representations), so everything
// downstream still sees an index list.
//
// Immutable once built; all const members may be called from any thread. Build
// cost: linear in the leaves plus block_size per interior block, parallel
// (tests/bench/blocks_bench.cpp; figures in docs/scenes.md): cheap enough to
// rebuild at load, so blocks are not cached.
#pragma once

#include <cstdint>
#include <glm/mat4x4.hpp>
#include <glm/vec3.hpp>
#include <glm/vec4.hpp>
#include <limits>
#include <memory>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "treecut/culling/box.hpp"
#include "treecut/hierarchy.hpp"

namespace treecut::culling {

using BlockId = std::uint32_t;
inline constexpr BlockId kNoBlock = std::numeric_limits<BlockId>::max();
inline constexpr std::uint32_t kDefaultBlockSize = 1000;
/// Children per interior block: 2, binary and balanced (the CHC paper's
/// kD-tree: CHC and `treecut bench occlusion` use it), or 4, the hierarchy's
/// own children (the first form). build()'s default stays 4 for the `hoq`
/// strategy: its queries go through the View's executor, which tests a
/// node's sphere, and the node of a binary block made of several subtrees is
/// their common ancestor, whose sphere is looser than the block (its relative
/// visibility is that of a bigger region).
inline constexpr unsigned kBinaryFanOut = 2;
inline constexpr unsigned kHierarchyFanOut = 4;

class HlodBlocks {
 public:
  HlodBlocks() = default;

  /// Groups `h` into blocks of at most `block_size` (>= 1) leaves, interior
  /// blocks with `fan_out` 2 (binary) or 4 (the hierarchy's children) children;
  /// throws std::invalid_argument for block_size 0, another fan_out or an
  /// empty hierarchy. Parallel.
  static HlodBlocks build(const Hierarchy& h, std::uint32_t block_size = kDefaultBlockSize,
                          unsigned fan_out = kHierarchyFanOut);

  [[nodiscard]] std::uint32_t block_size() const { return block_size_; }
  [[nodiscard]] unsigned fan_out() const { return fan_out_; }
  [[nodiscard]] std::uint32_t block_count() const {
    return static_cast<std::uint32_t>(root_.size());
  }
  [[nodiscard]] std::uint32_t leaf_block_count() const { return leaf_blocks_; }
  /// The hierarchy's node count the blocks were built for (a cheap identity check).
  [[nodiscard]] std::uint32_t hierarchy_nodes() const { return hierarchy_nodes_; }

  /// The lowest common ancestor of roots(b) (see above).
  [[nodiscard]] NodeId root(BlockId b) const { return root_[b]; }
  /// The disjoint subtrees the block is made of, in id order.
  [[nodiscard]] std::span<const NodeId> roots(BlockId b) const {
    return {roots_.data() + roots_begin_[b], roots_begin_[b + 1] - roots_begin_[b]};
  }
  [[nodiscard]] BlockId parent(BlockId b) const { return parent_[b]; }
  [[nodiscard]] BlockId first_child(BlockId b) const { return first_child_[b]; }
  [[nodiscard]] unsigned child_count(BlockId b) const { return child_count_[b]; }
  [[nodiscard]] bool is_leaf(BlockId b) const { return child_count_[b] == 0; }
  /// Leaves of the hierarchy in the block (its subtrees' point_count).
  [[nodiscard]] std::uint32_t leaf_count(BlockId b) const { return leaves_[b]; }
  [[nodiscard]] const Box& box(BlockId b) const { return box_[b]; }
  /// The nodes drawn for the block at its level: a cut of its root's subtree.
  [[nodiscard]] std::span<const NodeId> representation(BlockId b) const {
    return {rep_.data() + rep_begin_[b], rep_begin_[b + 1] - rep_begin_[b]};
  }
  /// The highest block whose root() is `n`, or kNoBlock (binary search).
  [[nodiscard]] BlockId block_of_root(NodeId n) const;

  /// The cut holding only the root block.
  [[nodiscard]] std::vector<BlockId> root_block_cut() const { return {0}; }
  /// Every leaf block (the full refinement).
  [[nodiscard]] std::vector<BlockId> leaf_block_cut() const;

  /// Empty when `cut` covers every leaf block exactly once with valid ids,
  /// else the first problem.
  [[nodiscard]] std::string validate_cut(std::span<const BlockId> cut) const;
  /// The TreeCut index list of a block cut: the representations, concatenated
  /// in the cut's order. Throws std::invalid_argument unless validate_cut passes.
  [[nodiscard]] std::vector<NodeId> nodes_of_cut(std::span<const BlockId> cut) const;
  /// The same without the check (the per-frame path; `out` is cleared first).
  void append_nodes(std::span<const BlockId> cut, std::vector<NodeId>& out) const;

 private:
  std::uint32_t block_size_ = 0;
  unsigned fan_out_ = kHierarchyFanOut;
  std::uint32_t leaf_blocks_ = 0;
  std::uint32_t hierarchy_nodes_ = 0;
  std::vector<NodeId> root_;
  std::vector<NodeId> roots_;                        // the subtrees of every block, concatenated
  std::vector<std::size_t> roots_begin_;             // block_count() + 1 offsets into roots_
  std::vector<std::pair<NodeId, BlockId>> by_root_;  // (root_, id), sorted
  std::vector<BlockId> parent_;
  std::vector<BlockId> first_child_;
  std::vector<std::uint8_t> child_count_;
  std::vector<std::uint32_t> leaves_;
  std::vector<Box> box_;
  std::vector<std::uint64_t> rep_begin_;  // block_count() + 1 offsets into rep_
  std::vector<NodeId> rep_;
};

}  // namespace treecut::culling
