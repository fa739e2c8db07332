// HLOD blocks over the splat hierarchy: the visibility unit of the occlusion
// strategies. Bittner et al., "Coherent Hierarchical Culling: Hardware
// Occlusion Queries Made Useful" (../shared/papers/coherent-hierarchical-culling.tex.txt)
// queries the boxes of a scene hierarchy; Charalambos et al., "Optimized HLOD
// Refinement Driven by Hardware Occlusion Queries"
// (../shared/papers/hoq-driven-hlod-refinement.txt) refines an HLOD tree whose
// nodes each carry a box and a representation of their subtree. Both are built
// here from the QSplat hierarchy; see hlod_blocks.hpp for the definitions.
#include "treecut/culling/hlod_blocks.hpp"

#include <algorithm>
#include <cmath>
#include <functional>
#include <glm/geometric.hpp>
#include <stdexcept>

#include "block_representation.hpp"
#include "treecut/parallel.hpp"

namespace treecut::culling {

// Id order makes a block's cut coarser than (or equal to) each child's: a
// child refines a subset of the subtrees with the same limit, so it stops at
// the same id or later.
void collect_representation(const Hierarchy& h, std::span<const NodeId> roots, std::uint32_t limit,
                            std::vector<NodeId>& queue, std::vector<NodeId>& out,
                            std::vector<NodeId>* hidden) {
  out.clear();
  if (hidden != nullptr) hidden->clear();
  const auto& a = h.arrays();
  std::uint64_t leaves = 0;
  for (const NodeId r : roots) leaves += a.point_count[r];
  if (leaves <= limit) {
    for (const NodeId r : roots) {
      queue.assign(1, r);
      while (!queue.empty()) {
        const NodeId n = queue.back();
        queue.pop_back();
        const unsigned cc = a.child_count[n];
        if (cc == 0) {
          out.push_back(n);
          if (hidden != nullptr && a.point_count[n] > 1) hidden->push_back(n);
          continue;
        }
        for (unsigned c = cc; c-- > 0;) queue.push_back(a.first_child[n] + c);
      }
    }
    return;
  }
  // A min-heap of ids: children have larger ids than their parent, so nodes
  // leave it in ascending id order (with one root: the old FIFO order).
  const auto greater = std::greater<NodeId>();
  queue.assign(roots.begin(), roots.end());
  std::make_heap(queue.begin(), queue.end(), greater);
  std::size_t count = queue.size();
  while (!queue.empty()) {
    std::pop_heap(queue.begin(), queue.end(), greater);
    const NodeId n = queue.back();
    queue.pop_back();
    const unsigned cc = a.child_count[n];
    if (cc == 0) {
      out.push_back(n);
      // A leaf only because its children are not resident: the walk would
      // have gone on below it.
      if (hidden != nullptr && a.point_count[n] > 1) hidden->push_back(n);
      continue;
    }
    if (count + cc - 1 > limit) {
      out.push_back(n);
      // The rest of the frontier stays as it is.
      out.insert(out.end(), queue.begin(), queue.end());
      return;
    }
    count += cc - 1;
    for (unsigned c = 0; c < cc; ++c) {
      queue.push_back(a.first_child[n] + c);
      std::push_heap(queue.begin(), queue.end(), greater);
    }
  }
}

Box representation_box(const HierarchyArrays& a, std::span<const NodeId> rep) {
  glm::vec3 mn(std::numeric_limits<float>::max()), mx(-std::numeric_limits<float>::max());
  float slack = 0.0f;
  for (const NodeId n : rep) {
    const glm::vec4 s = a.center_radius[n];
    const glm::vec3 c(s);
    mn = glm::min(mn, c - s.w);
    mx = glm::max(mx, c + s.w);
    slack = std::max(slack, s.w);
  }
  // Descendants may reach past their ancestor's sphere by the builder's
  // rounding (check_invariants allows 1e-5 of the radius per level); a
  // relative margin keeps the box conservative for them.
  const glm::vec3 margin = glm::vec3(slack * 1e-4f) + 1e-6f * glm::max(glm::abs(mn), glm::abs(mx));
  return {mn - margin, mx + margin};
}

namespace {

std::uint64_t leaves_of(const HierarchyArrays& a, std::span<const NodeId> nodes) {
  std::uint64_t sum = 0;
  for (const NodeId n : nodes) sum += a.point_count[n];
  return sum;
}

// The lowest common ancestor of `nodes` (the block's root node).
NodeId common_ancestor(const Hierarchy& h, std::span<const NodeId> nodes) {
  const auto& a = h.arrays();
  NodeId lca = nodes.front();
  for (const NodeId n0 : nodes.subspan(1)) {
    NodeId x = lca, y = n0;
    while (x != y) {
      // Breadth-first ids: the larger id is never an ancestor of the smaller.
      if (x > y)
        x = a.parent[x];
      else
        y = a.parent[y];
    }
    lca = x;
  }
  return lca;
}

// Splits the subtrees `items` (more than `block_size` leaves together) into
// two groups for the binary tree of blocks, a kD-tree step as in the paper's
// scene hierarchy: a subtree holding more than a quarter of the leaves is
// replaced by its children first (so no side is left with a sliver beside a
// big subtree), then the subtrees are ordered along the longest axis of their
// centers and cut where the left side's leaves come closest to
// floor(k/2)/k of the total, k = ceil(total / block_size): the leaf blocks
// this yields hold total/k > block_size/2 leaves where the subtrees' sizes
// allow it, instead of halving down to slivers.
void split_items(const Hierarchy& h, std::uint32_t block_size, std::vector<NodeId>& items,
                 std::size_t& left_count) {
  const auto& a = h.arrays();
  const std::uint64_t total = leaves_of(a, items);
  for (;;) {
    // The single subtree of a one-node block, else the first dominant one.
    std::size_t pick = items.size();
    for (std::size_t i = 0; i < items.size() && pick == items.size(); ++i) {
      const NodeId n = items[i];
      const bool dominant = 4 * static_cast<std::uint64_t>(a.point_count[n]) > total;
      if (a.child_count[n] != 0 && (items.size() < 2 || dominant)) pick = i;
    }
    if (pick == items.size()) break;
    const NodeId n = items[pick];
    items[pick] = a.first_child[n];
    for (unsigned c = 1; c < a.child_count[n]; ++c) items.push_back(a.first_child[n] + c);
  }
  glm::vec3 mn(std::numeric_limits<float>::max()), mx(-std::numeric_limits<float>::max());
  for (const NodeId n : items) {
    const glm::vec3 c(a.center_radius[n]);
    mn = glm::min(mn, c);
    mx = glm::max(mx, c);
  }
  const glm::vec3 ext = mx - mn;
  const int axis = ext.x >= ext.y && ext.x >= ext.z ? 0 : (ext.y >= ext.z ? 1 : 2);
  std::sort(items.begin(), items.end(), [&](NodeId x, NodeId y) {
    const float cx = a.center_radius[x][axis], cy = a.center_radius[y][axis];
    return cx < cy || (cx == cy && x < y);
  });
  const std::uint64_t k = (total + block_size - 1) / block_size;
  const double target = static_cast<double>(total) * static_cast<double>(k / 2) /
                        static_cast<double>(std::max<std::uint64_t>(k, 2));
  std::uint64_t left = 0;
  double best = std::numeric_limits<double>::max();
  left_count = 1;
  for (std::size_t i = 0; i + 1 < items.size(); ++i) {
    left += a.point_count[items[i]];
    const double d = std::abs(static_cast<double>(left) - target);
    if (d < best) {
      best = d;
      left_count = i + 1;
    }
  }
}

// The fan-out 2 step of a block that is split: its subtrees `own` into two
// groups (split_items), each group's roots in id order (collect_representation's
// heap does not need it; it keeps roots(b) tidy for tests and the LCA cheap).
// `items` ends with the first group's roots, then the second's; returns the
// first group's count.
std::size_t split_in_two(const Hierarchy& h, std::uint32_t block_size, std::span<const NodeId> own,
                         std::vector<NodeId>& items) {
  items.assign(own.begin(), own.end());
  std::size_t left = 0;
  split_items(h, block_size, items, left);
  std::sort(items.begin(), items.begin() + static_cast<std::ptrdiff_t>(left));
  std::sort(items.begin() + static_cast<std::ptrdiff_t>(left), items.end());
  return left;
}

// The representation limit of an interior block: block_size, or its root
// count when that is larger (a cut cannot be coarser than the block's own
// subtrees).
std::uint32_t interior_limit(std::uint32_t block_size, std::span<const NodeId> roots) {
  return std::max<std::uint32_t>(block_size, static_cast<std::uint32_t>(roots.size()));
}

// The node count of each block's representation (the first `count` blocks
// of `b`, whose roots, children and leaf counts are set): a leaf block's is
// its leaf count, an interior block's needs the walk.
std::vector<std::uint64_t> representation_sizes(const Hierarchy& h, const HlodBlocks& b,
                                                std::size_t count, std::uint32_t block_size) {
  std::vector<std::uint64_t> sizes(count);
  parallel_for(
      count,
      [&](std::size_t lo, std::size_t hi) {
        std::vector<NodeId> queue, out;
        for (std::size_t i = lo; i < hi; ++i) {
          const auto id = static_cast<BlockId>(i);
          if (b.is_leaf(id)) {
            sizes[i] = b.leaf_count(id);
            continue;
          }
          collect_representation(h, b.roots(id), interior_limit(block_size, b.roots(id)), queue,
                                 out, nullptr);
          sizes[i] = out.size();
        }
      },
      0, 64);
  return sizes;
}

// Every block writes its representation into its range of `rep` (the
// offsets `rep_begin`) and its box into `box`.
void write_representations(const Hierarchy& h, const HlodBlocks& b, std::size_t count,
                           std::uint32_t block_size, std::span<const std::uint64_t> rep_begin,
                           std::vector<NodeId>& rep, std::vector<Box>& box) {
  parallel_for(
      count,
      [&](std::size_t lo, std::size_t hi) {
        std::vector<NodeId> queue, out;
        for (std::size_t i = lo; i < hi; ++i) {
          const auto id = static_cast<BlockId>(i);
          collect_representation(
              h, b.roots(id), b.is_leaf(id) ? block_size : interior_limit(block_size, b.roots(id)),
              queue, out, nullptr);
          std::copy(out.begin(), out.end(),
                    rep.begin() + static_cast<std::ptrdiff_t>(rep_begin[i]));
          box[i] = representation_box(h.arrays(), out);
        }
      },
      0, 64);
}

}  // namespace

HlodBlocks HlodBlocks::build(const Hierarchy& h, std::uint32_t block_size, unsigned fan_out) {
  if (block_size == 0) throw std::invalid_argument("HlodBlocks: block_size must be at least 1");
  if (fan_out != 2 && fan_out != 4)
    throw std::invalid_argument("HlodBlocks: fan_out must be 2 (binary) or 4 (the hierarchy's)");
  if (h.empty()) throw std::invalid_argument("HlodBlocks: empty hierarchy");
  const auto& a = h.arrays();
  HlodBlocks b;
  b.block_size_ = block_size;
  b.fan_out_ = fan_out;
  b.hierarchy_nodes_ = h.node_count();

  // The tree of blocks, each a set of disjoint subtrees (roots_). A FIFO over
  // the blocks appends a block's children together, which makes the block ids
  // breadth-first with contiguous children. Fan-out 4: a block is one node and
  // its children are the node's children (the hierarchy's upper tree, in id
  // order). Fan-out 2: split_items halves the subtrees (or a single node's
  // children) into two groups, so every interior block has two children.
  b.roots_begin_.push_back(0);
  b.roots_.push_back(h.root());
  b.roots_begin_.push_back(1);
  b.parent_.push_back(kNoBlock);
  std::vector<NodeId> items;
  for (BlockId i = 0; i < b.parent_.size(); ++i) {
    const std::span<const NodeId> own(b.roots_.data() + b.roots_begin_[i],
                                      b.roots_begin_[i + 1] - b.roots_begin_[i]);
    const std::uint64_t leaves = leaves_of(a, own);
    const bool single_leaf = own.size() == 1 && a.child_count[own[0]] == 0;
    if (leaves <= block_size || single_leaf) {
      b.first_child_.push_back(0);
      b.child_count_.push_back(0);
      ++b.leaf_blocks_;
      continue;
    }
    b.first_child_.push_back(static_cast<BlockId>(b.parent_.size()));
    auto add_child = [&](std::span<const NodeId> roots) {
      b.roots_.insert(b.roots_.end(), roots.begin(), roots.end());
      b.roots_begin_.push_back(b.roots_.size());
      b.parent_.push_back(i);
    };
    if (fan_out == 4) {
      const NodeId n = own[0];
      b.child_count_.push_back(a.child_count[n]);
      for (unsigned c = 0; c < a.child_count[n]; ++c) {
        const NodeId child = a.first_child[n] + c;
        add_child({&child, 1});
      }
      continue;
    }
    const std::size_t left = split_in_two(h, block_size, own, items);
    b.child_count_.push_back(2);
    add_child({items.data(), left});
    add_child({items.data() + left, items.size() - left});
  }
  const std::size_t count = b.parent_.size();
  b.leaves_.resize(count);
  b.root_.resize(count);
  for (std::size_t i = 0; i < count; ++i) {
    const auto r = b.roots(static_cast<BlockId>(i));
    b.leaves_[i] = static_cast<std::uint32_t>(leaves_of(a, r));
    b.root_[i] = r.size() == 1 ? r[0] : common_ancestor(h, r);
  }
  b.by_root_.resize(count);
  for (std::size_t i = 0; i < count; ++i) b.by_root_[i] = {b.root_[i], static_cast<BlockId>(i)};
  std::sort(b.by_root_.begin(), b.by_root_.end());

  // Representations: sizes first, then every block writes its own range.
  const std::vector<std::uint64_t> sizes = representation_sizes(h, b, count, block_size);
  b.rep_begin_.assign(count + 1, 0);
  for (std::size_t i = 0; i < count; ++i) b.rep_begin_[i + 1] = b.rep_begin_[i] + sizes[i];
  b.rep_.resize(b.rep_begin_[count]);
  b.box_.resize(count);
  write_representations(h, b, count, block_size, b.rep_begin_, b.rep_, b.box_);
  return b;
}

BlockId HlodBlocks::block_of_root(NodeId n) const {
  // by_root_ is sorted by (root, block): the first entry of n is its highest block.
  const auto it =
      std::lower_bound(by_root_.begin(), by_root_.end(), std::pair<NodeId, BlockId>{n, 0});
  if (it == by_root_.end() || it->first != n) return kNoBlock;
  return it->second;
}

std::vector<BlockId> HlodBlocks::leaf_block_cut() const {
  std::vector<BlockId> cut;
  cut.reserve(leaf_blocks_);
  for (BlockId i = 0; i < block_count(); ++i)
    if (is_leaf(i)) cut.push_back(i);
  return cut;
}

std::string HlodBlocks::validate_cut(std::span<const BlockId> cut) const {
  // Every leaf block must have exactly one block of the cut on its path to the
  // root: mark the cut, then walk down from the root block.
  std::vector<std::uint8_t> in_cut(block_count(), 0);
  for (const BlockId c : cut) {
    if (c >= block_count()) return "block id " + std::to_string(c) + " out of range";
    if (in_cut[c]) return "block " + std::to_string(c) + " listed twice";
    in_cut[c] = 1;
  }
  // covered[b]: some ancestor-or-self of b is in the cut. Parents precede
  // children in breadth-first ids, so one ascending pass decides it.
  std::vector<std::uint8_t> covered(block_count(), 0);
  for (BlockId i = 0; i < block_count(); ++i) {
    const bool above = i != 0 && covered[parent_[i]];
    if (above && in_cut[i])
      return "block " + std::to_string(i) + " lies under another block of the cut";
    covered[i] = above || in_cut[i];
    if (is_leaf(i) && !covered[i])
      return "leaf block " + std::to_string(i) + " is not covered by the cut";
  }
  return {};
}

void HlodBlocks::append_nodes(std::span<const BlockId> cut, std::vector<NodeId>& out) const {
  out.clear();
  std::size_t total = 0;
  for (const BlockId c : cut) total += rep_begin_[c + 1] - rep_begin_[c];
  out.reserve(total);
  for (const BlockId c : cut) {
    const auto r = representation(c);
    out.insert(out.end(), r.begin(), r.end());
  }
}

std::vector<NodeId> HlodBlocks::nodes_of_cut(std::span<const BlockId> cut) const {
  if (const std::string why = validate_cut(cut); !why.empty())
    throw std::invalid_argument("HlodBlocks: invalid block cut: " + why);
  std::vector<NodeId> out;
  append_nodes(cut, out);
  return out;
}

}  // namespace treecut::culling
