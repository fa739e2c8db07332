// HLOD blocks over the splat hierarchy: the visibility unit of the occlusion
// strategies. Bittner et al., "Coherent Hierarchical Culling: Hardware
// Occlusion Queries Made Useful" (../shared/papers/coherent-hierarchical-culling.tex.txt)
// queries the boxes of a scene hierarchy; Charalambos et al., "Optimized HLOD
// Refinement Driven by Hardware Occlusion Queries"
// (../shared/papers/hoq-driven-hlod-refinement.txt) refines an HLOD tree whose
// nodes each carry a box and a representation of their subtree. Both are built
// here from the QSplat hierarchy; see hlod_blocks.hpp for the definitions.
#include <algorithm>
#include <glm/geometric.hpp>
#include <stdexcept>

#include "treecut/parallel.hpp"
#include "treecut/strategies/hlod_blocks.hpp"

namespace treecut::strategies {

bool Box::contains_sphere(glm::vec3 c, float r) const {
  return c.x - r >= lo.x && c.y - r >= lo.y && c.z - r >= lo.z && c.x + r <= hi.x &&
         c.y + r <= hi.y && c.z + r <= hi.z;
}

float Box::distance_to(glm::vec3 p) const {
  const glm::vec3 d = glm::max(glm::max(lo - p, p - hi), glm::vec3(0.0f));
  return glm::length(d);
}

FrustumPlanes::FrustumPlanes(const glm::mat4& m) {
  const glm::vec4 r0(m[0][0], m[1][0], m[2][0], m[3][0]);
  const glm::vec4 r1(m[0][1], m[1][1], m[2][1], m[3][1]);
  const glm::vec4 r2(m[0][2], m[1][2], m[2][2], m[3][2]);
  const glm::vec4 r3(m[0][3], m[1][3], m[2][3], m[3][3]);
  planes[0] = r3 + r0;
  planes[1] = r3 - r0;
  planes[2] = r3 + r1;
  planes[3] = r3 - r1;
  planes[4] = r3 + r2;
  planes[5] = r3 - r2;
}

bool FrustumPlanes::may_contain(const Box& box) const {
  for (const glm::vec4& p : planes) {
    const glm::vec3 corner(p.x >= 0.0f ? box.hi.x : box.lo.x, p.y >= 0.0f ? box.hi.y : box.lo.y,
                           p.z >= 0.0f ? box.hi.z : box.lo.z);
    if (p.x * corner.x + p.y * corner.y + p.z * corner.z + p.w < 0.0f) return false;
  }
  return true;
}

namespace {

// The representation of the block rooted at `r`: for a leaf block every leaf
// of the subtree, else the root refined breadth first while the node count
// stays <= limit. The first node that does not fit ends the refinement, so the
// cut stays breadth-first (the biggest splats are refined first) instead of
// refining small nodes deep in one corner.
void collect_representation(const Hierarchy& h, NodeId r, std::uint32_t limit,
                            std::vector<NodeId>& queue, std::vector<NodeId>& out) {
  out.clear();
  const auto& a = h.arrays();
  if (a.point_count[r] <= limit) {
    queue.assign(1, r);
    while (!queue.empty()) {
      const NodeId n = queue.back();
      queue.pop_back();
      const unsigned cc = a.child_count[n];
      if (cc == 0) {
        out.push_back(n);
        continue;
      }
      for (unsigned c = cc; c-- > 0;) queue.push_back(a.first_child[n] + c);
    }
    return;
  }
  // FIFO in a vector: `head` walks it; nodes before head were processed.
  queue.assign(1, r);
  std::size_t head = 0;
  std::size_t count = 1;
  while (head < queue.size()) {
    const NodeId n = queue[head++];
    const unsigned cc = a.child_count[n];
    if (cc == 0) {
      out.push_back(n);
      continue;
    }
    if (count + cc - 1 > limit) {
      out.push_back(n);
      // The rest of the frontier stays as it is.
      out.insert(out.end(), queue.begin() + static_cast<std::ptrdiff_t>(head), queue.end());
      return;
    }
    count += cc - 1;
    for (unsigned c = 0; c < cc; ++c) queue.push_back(a.first_child[n] + c);
  }
}

}  // namespace

HlodBlocks HlodBlocks::build(const Hierarchy& h, std::uint32_t block_size) {
  if (block_size == 0) throw std::invalid_argument("HlodBlocks: block_size must be at least 1");
  if (h.empty()) throw std::invalid_argument("HlodBlocks: empty hierarchy");
  const auto& a = h.arrays();
  HlodBlocks b;
  b.block_size_ = block_size;
  b.hierarchy_nodes_ = h.node_count();

  // The tree of blocks: the nodes above the leaf blocks (more than block_size
  // leaves) and their children. A FIFO walk from the root visits them in
  // ascending id order (ids are breadth-first, children contiguous), which
  // makes the block ids breadth-first with contiguous children as well.
  b.root_.push_back(h.root());
  b.parent_.push_back(kNoBlock);
  for (BlockId i = 0; i < b.root_.size(); ++i) {
    const NodeId n = b.root_[i];
    if (a.point_count[n] <= block_size || a.child_count[n] == 0) {
      b.first_child_.push_back(0);
      b.child_count_.push_back(0);
      ++b.leaf_blocks_;
      continue;
    }
    b.first_child_.push_back(static_cast<BlockId>(b.root_.size()));
    b.child_count_.push_back(a.child_count[n]);
    for (unsigned c = 0; c < a.child_count[n]; ++c) {
      b.root_.push_back(a.first_child[n] + c);
      b.parent_.push_back(i);
    }
  }
  const std::size_t count = b.root_.size();
  b.leaves_.resize(count);
  for (std::size_t i = 0; i < count; ++i) b.leaves_[i] = a.point_count[b.root_[i]];

  // Representations: sizes first (a leaf block's is its leaf count; an
  // interior block's needs the walk), then every block writes its own range.
  std::vector<std::uint64_t> sizes(count);
  parallel_for(
      count,
      [&](std::size_t lo, std::size_t hi) {
        std::vector<NodeId> queue, out;
        for (std::size_t i = lo; i < hi; ++i) {
          if (b.child_count_[i] == 0) {
            sizes[i] = b.leaves_[i];
            continue;
          }
          collect_representation(h, b.root_[i], block_size, queue, out);
          sizes[i] = out.size();
        }
      },
      0, 64);
  b.rep_begin_.assign(count + 1, 0);
  for (std::size_t i = 0; i < count; ++i) b.rep_begin_[i + 1] = b.rep_begin_[i] + sizes[i];
  b.rep_.resize(b.rep_begin_[count]);
  b.box_.resize(count);
  parallel_for(
      count,
      [&](std::size_t lo, std::size_t hi) {
        std::vector<NodeId> queue, out;
        for (std::size_t i = lo; i < hi; ++i) {
          collect_representation(h, b.root_[i], block_size, queue, out);
          std::copy(out.begin(), out.end(),
                    b.rep_.begin() + static_cast<std::ptrdiff_t>(b.rep_begin_[i]));
          glm::vec3 mn(std::numeric_limits<float>::max()), mx(-std::numeric_limits<float>::max());
          float slack = 0.0f;
          for (const NodeId n : out) {
            const glm::vec4 s = a.center_radius[n];
            const glm::vec3 c(s);
            mn = glm::min(mn, c - s.w);
            mx = glm::max(mx, c + s.w);
            slack = std::max(slack, s.w);
          }
          // Descendants may reach past their ancestor's sphere by the
          // builder's rounding (check_invariants allows 1e-5 of the radius per
          // level); a relative margin keeps the box conservative for them.
          const glm::vec3 margin =
              glm::vec3(slack * 1e-4f) + 1e-6f * glm::max(glm::abs(mn), glm::abs(mx));
          b.box_[i] = {mn - margin, mx + margin};
        }
      },
      0, 64);
  return b;
}

BlockId HlodBlocks::block_of_root(NodeId n) const {
  const auto it = std::lower_bound(root_.begin(), root_.end(), n);
  if (it == root_.end() || *it != n) return kNoBlock;
  return static_cast<BlockId>(it - root_.begin());
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

}  // namespace treecut::strategies
