// The HLOD blocks of `hoq` made as its traversal reaches them, over the
// hierarchy as far as it is resident: the fan-out-4 blocks of
// hlod_blocks.hpp (a block is one node, its children the node's children;
// a node of at most block_size leaves, or a leaf, is a leaf block), with
// the same representation and box, computed for a block when it is first
// asked for and kept until the pages below it change. Charalambos,
// Bittner, Wimmer, Romero, "Optimized HLOD Refinement Driven by Hardware
// Occlusion Queries", ISVC 2007 (../shared/papers/hoq-driven-hlod-refinement.txt):
// an HLOD tree whose every node has a box and a representation of its
// subtree.
//
// Why not HlodBlocks::build: it groups every node of the hierarchy at once,
// which a model drawn from its pages does not hold (issue 45). Here memory
// follows the blocks a traversal has reached among the resident nodes; a
// block over nodes whose children are not resident draws them as they are
// and names them (Block::hidden), what the strategy asks the pages for. On a
// model held whole the blocks are HlodBlocks::build(h, block_size, 4)'s,
// node for node (a test).
//
// One thread (the strategy's). Blocks are made top-down: a block is asked
// for only after its parent (the traversal reaches children through their
// parent), which is what lets a concealed node's blocks below it be found.
#pragma once

#include <cstdint>
#include <deque>
#include <limits>
#include <span>
#include <vector>

#include "treecut/culling/box.hpp"
#include "treecut/hierarchy.hpp"
#include "treecut/sparse_node_array.hpp"

namespace treecut::culling {

class ResidentBlocks {
 public:
  static constexpr std::uint32_t kNoSlot = std::numeric_limits<std::uint32_t>::max();

  struct Block {
    Box box;                     ///< around every node of the representation
    float error_radius = 0.0f;   ///< its largest splat radius (0: a leaf block at full detail)
    std::vector<NodeId> rep;     ///< the nodes drawn for the block at its level
    std::vector<NodeId> hidden;  ///< nodes of rep the block would refine past (not resident)
    NodeId node = kNoNode;       ///< the block's node
    /// Its place among the blocks made (dense: a caller's per-block state
    /// lives at this index; reused after the block is dropped).
    std::uint32_t slot = kNoSlot;
    std::vector<std::uint32_t> children;  ///< the slots of its child blocks made so far
    bool stale = false;                   ///< the pages below changed: made again when asked for
  };

  /// Forgets every block, for H; block_size >= 1 leaves per leaf block.
  void reset(const Hierarchy& h, std::uint32_t block_size);
  [[nodiscard]] std::uint32_t block_size() const { return block_size_; }

  /// Whether node N's block is a leaf block (nothing to refine into).
  [[nodiscard]] bool is_leaf(const Hierarchy& h, NodeId n) const {
    return h.arrays().child_count[n] == 0 || h.arrays().point_count[n] <= block_size_;
  }
  /// Node N's block (N the root or a child of an interior block's node),
  /// made now if it is new or stale. References stay valid until the block
  /// is dropped or reset() is called.
  const Block& at(const Hierarchy& h, NodeId n);
  /// The block in SLOT, as it was made (a slot of at() this iteration).
  [[nodiscard]] const Block& block(std::uint32_t slot) const { return blocks_[slot]; }
  /// The slot of node N's block, or kNoSlot when none is made (two loads).
  [[nodiscard]] std::uint32_t find(NodeId n) const { return slot_of_[n] - 1; }

  /// The pages below REVEALED and CONCEALED changed (IterationInput): the
  /// blocks at and above them are made again when next asked for; those
  /// below a concealed node are dropped (their nodes are no longer
  /// resident), their slots appended to DROPPED.
  void residency_changed(const Hierarchy& h, std::span<const NodeId> revealed,
                         std::span<const NodeId> concealed, std::vector<std::uint32_t>& dropped);

  /// Blocks held.
  [[nodiscard]] std::size_t size() const { return blocks_.size() - free_.size(); }

 private:
  void make(const Hierarchy& h, Block& b);
  void mark_stale_up(const Hierarchy& h, NodeId n);
  void drop_below(Block& b, std::vector<std::uint32_t>& dropped);

  std::uint32_t block_size_ = 1;
  SparseNodeArray<std::uint32_t> slot_of_;  // a node's block's slot + 1 (0: none)
  std::deque<Block> blocks_;                // by slot (a deque: references stay valid)
  std::vector<std::uint32_t> free_;         // slots of dropped blocks
  std::vector<NodeId> queue_;               // scratch of collect_representation
};

}  // namespace treecut::culling
