// HLOD blocks (strategies/include/treecut/culling/hlod_blocks.hpp): the
// partition of the leaves, conservative boxes, block sizes, the tree of blocks
// (binary and balanced with fan-out 2, the hierarchy's own with fan-out 4)
// and the mapping of block cuts to valid TreeCuts.
#include "treecut/culling/hlod_blocks.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <limits>
#include <random>
#include <span>

#include "strategy_fixtures.hpp"
#include "treecut/culling/resident_blocks.hpp"
#include "treecut/tree_cut.hpp"

namespace {

using treecut::Hierarchy;
using treecut::NodeId;
using treecut::TreeCut;
using treecut::culling::BlockId;
using treecut::culling::HlodBlocks;
using treecut::culling::kNoBlock;
using treecut::test::small_hierarchy;
using treecut::tools::ModelKind;

// Leaves of the subtree of n, collected depth first.
void subtree(const Hierarchy& h, NodeId n, std::vector<NodeId>& all) {
  all.push_back(n);
  for (unsigned c = 0; c < h.child_count(n); ++c) subtree(h, h.first_child(n) + c, all);
}

struct Case {
  ModelKind kind;
  std::size_t points;
  std::uint32_t block_size;
  unsigned fan_out = 2;
};

// Whether `n` lies in the subtree of `r`.
bool under(const Hierarchy& h, NodeId n, NodeId r) {
  while (n != r && n != treecut::kNoNode) n = h.parent(n);
  return n == r;
}

bool under_any(const Hierarchy& h, NodeId n, std::span<const NodeId> roots) {
  return std::any_of(roots.begin(), roots.end(), [&](NodeId r) { return under(h, n, r); });
}

HlodBlocks build(const Case& c) {
  return HlodBlocks::build(*small_hierarchy(c.kind, c.points), c.block_size, c.fan_out);
}

class Blocks : public ::testing::TestWithParam<Case> {};

TEST_P(Blocks, EveryLeafIsInExactlyOneLeafBlock) {
  const auto h = small_hierarchy(GetParam().kind, GetParam().points);
  const HlodBlocks b = build(GetParam());
  std::vector<int> owner_count(h->node_count(), 0);
  std::uint64_t leaves = 0;
  for (BlockId i = 0; i < b.block_count(); ++i) {
    if (!b.is_leaf(i)) continue;
    std::vector<NodeId> all;
    for (const NodeId r : b.roots(i)) subtree(*h, r, all);
    for (NodeId n : all)
      if (h->is_leaf(n)) ++owner_count[n], ++leaves;
  }
  EXPECT_EQ(leaves, h->leaf_count());
  for (NodeId n = 0; n < h->node_count(); ++n)
    if (h->is_leaf(n)) {
      ASSERT_EQ(owner_count[n], 1) << "leaf " << n;
    }
}

TEST_P(Blocks, BoxesContainEverySphereTheBlockCanDraw) {
  const auto h = small_hierarchy(GetParam().kind, GetParam().points);
  const HlodBlocks b = build(GetParam());
  for (BlockId i = 0; i < b.block_count(); ++i) {
    // The representation and everything below it.
    for (NodeId r : b.representation(i)) {
      std::vector<NodeId> all;
      subtree(*h, r, all);
      for (NodeId n : all)
        ASSERT_TRUE(b.box(i).contains_sphere(h->center(n), h->radius(n)))
            << "block " << i << " node " << n;
    }
  }
}

TEST_P(Blocks, SizesAndTheTreeOfBlocks) {
  const auto h = small_hierarchy(GetParam().kind, GetParam().points);
  const std::uint32_t bs = GetParam().block_size;
  const unsigned fan_out = GetParam().fan_out;
  const HlodBlocks b = build(GetParam());
  EXPECT_EQ(b.fan_out(), fan_out);
  const auto& a = h->arrays();
  std::uint64_t leaf_sum = 0;
  std::uint32_t leaf_blocks = 0;
  std::uint32_t smallest = std::numeric_limits<std::uint32_t>::max();
  ASSERT_EQ(b.roots(0).size(), 1u);
  EXPECT_EQ(b.roots(0)[0], h->root());
  for (BlockId i = 0; i < b.block_count(); ++i) {
    const NodeId r = b.root(i);
    const auto roots = b.roots(i);
    ASSERT_FALSE(roots.empty());
    EXPECT_TRUE(std::is_sorted(roots.begin(), roots.end()));
    std::uint64_t leaves = 0;
    for (const NodeId x : roots) {
      leaves += a.point_count[x];
      EXPECT_TRUE(under(*h, x, r)) << "root() is a common ancestor of block " << i;
    }
    if (roots.size() == 1) {
      EXPECT_EQ(r, roots[0]);
    }
    EXPECT_EQ(b.leaf_count(i), leaves);
    const BlockId top = b.block_of_root(r);
    ASSERT_NE(top, kNoBlock);
    EXPECT_LE(top, i) << "the highest block of root " << r;
    EXPECT_EQ(b.root(top), r);
    if (i > 0) {
      EXPECT_LT(b.parent(i), i) << "breadth-first ids";
    }
    if (b.is_leaf(i)) {
      ++leaf_blocks;
      leaf_sum += b.leaf_count(i);
      smallest = std::min(smallest, b.leaf_count(i));
      EXPECT_GE(b.leaf_count(i), 1u);
      EXPECT_LE(b.leaf_count(i), bs);
      EXPECT_EQ(b.representation(i).size(), b.leaf_count(i)) << "full detail";
    } else {
      EXPECT_GT(b.leaf_count(i), bs);
      if (fan_out == 2) {
        EXPECT_EQ(b.child_count(i), 2u) << "binary";
      } else {
        ASSERT_EQ(roots.size(), 1u);
        EXPECT_EQ(b.child_count(i), h->child_count(r));
      }
      // The children split the block's subtrees: their subtrees lie in the
      // block's and hold its leaves (disjointly: the test above).
      std::uint64_t child_leaves = 0;
      std::uint64_t child_rep = 0;
      for (unsigned c = 0; c < b.child_count(i); ++c) {
        const BlockId child = b.first_child(i) + c;
        EXPECT_EQ(b.parent(child), i);
        if (fan_out == 4) {
          EXPECT_EQ(b.root(child), h->first_child(r) + c);
        }
        for (const NodeId x : b.roots(child)) EXPECT_TRUE(under_any(*h, x, roots));
        child_leaves += b.leaf_count(child);
        child_rep += b.representation(child).size();
        // Coarser than the child: every node the child draws lies under a
        // node the block draws.
        for (const NodeId n : b.representation(child))
          ASSERT_TRUE(under_any(*h, n, b.representation(i)))
              << "block " << i << " is finer than its child " << child << " at node " << n;
      }
      EXPECT_EQ(child_leaves, b.leaf_count(i));
      EXPECT_LE(b.representation(i).size(), child_rep)
          << "an interior block draws no more splats than its children together";
      EXPECT_LE(b.representation(i).size(), std::max<std::size_t>(bs, roots.size()));
      // The roots are refined once whenever their children fit.
      std::size_t children = 0;
      for (const NodeId x : roots) children += std::max(1u, h->child_count(x));
      EXPECT_GE(b.representation(i).size(), children <= bs ? children : roots.size());
    }
    // The representation is a cut of the block's subtrees.
    std::uint64_t covered = 0;
    for (NodeId n : b.representation(i)) {
      EXPECT_TRUE(under_any(*h, n, roots)) << "node " << n << " is not in block " << i;
      covered += a.point_count[n];
    }
    EXPECT_EQ(covered, b.leaf_count(i)) << "block " << i;
  }
  EXPECT_EQ(b.parent(0), kNoBlock);
  EXPECT_EQ(leaf_blocks, b.leaf_block_count());
  EXPECT_EQ(leaf_sum, h->leaf_count());
  const double mean = static_cast<double>(leaf_sum) / leaf_blocks;
  std::printf(
      "fan-out %u, block size %u: %u blocks, %u leaf blocks, leaves per leaf block: "
      "smallest %u, mean %.1f\n",
      fan_out, bs, b.block_count(), leaf_blocks, smallest, mean);
  if (h->leaf_count() > 4 * bs) {
    if (fan_out == 2) {
      // Balanced: every leaf block holds at least a quarter of the block
      // size, on average 0.6 of it (measured on these models: the smallest
      // 0.47 to 0.94 of it, the mean 0.7 to 0.94; fan-out 4 leaves slivers
      // of 0.3 to 0.47).
      EXPECT_GE(mean, 0.6 * bs);
      EXPECT_GE(smallest, bs / 4);
    } else {
      // The hierarchy's fan-out: slivers beside big siblings (the measured
      // mean is about half the block size).
      EXPECT_GE(mean, 0.1 * bs);
    }
  }
}

TEST_P(Blocks, BlockCutsMapToValidTreeCuts) {
  const auto h = small_hierarchy(GetParam().kind, GetParam().points);
  const HlodBlocks b = build(GetParam());

  // The root block alone and the full refinement.
  const auto root_nodes = b.nodes_of_cut(b.root_block_cut());
  EXPECT_EQ(TreeCut::validate(*h, root_nodes), "");
  auto leaf_nodes = b.nodes_of_cut(b.leaf_block_cut());
  EXPECT_EQ(TreeCut::validate(*h, leaf_nodes), "");
  const TreeCut full = TreeCut::leaf_cut(*h);
  std::vector<NodeId> expected(full.nodes().begin(), full.nodes().end());
  std::sort(leaf_nodes.begin(), leaf_nodes.end());
  std::sort(expected.begin(), expected.end());
  EXPECT_EQ(leaf_nodes, expected) << "the full refinement is the leaf cut";

  // Random cuts: refine blocks of the cut at random, a hundred steps.
  std::mt19937 rng(42);
  std::vector<BlockId> cut = b.root_block_cut();
  for (int step = 0; step < 100; ++step) {
    std::vector<std::size_t> interior;
    for (std::size_t k = 0; k < cut.size(); ++k)
      if (!b.is_leaf(cut[k])) interior.push_back(k);
    if (interior.empty()) break;
    const std::size_t k = interior[rng() % interior.size()];
    const BlockId parent = cut[k];
    cut.erase(cut.begin() + static_cast<std::ptrdiff_t>(k));
    for (unsigned c = 0; c < b.child_count(parent); ++c) cut.push_back(b.first_child(parent) + c);
    ASSERT_EQ(b.validate_cut(cut), "");
    const auto nodes = b.nodes_of_cut(cut);
    ASSERT_EQ(TreeCut::validate(*h, nodes), "") << "step " << step;
    EXPECT_NO_THROW(TreeCut::from_nodes(*h, nodes));
  }
}

INSTANTIATE_TEST_SUITE_P(
    Models, Blocks,
    ::testing::Values(Case{ModelKind::Terrain, 30000, 1000}, Case{ModelKind::City, 30000, 1000},
                      Case{ModelKind::Sphere, 20000, 64}, Case{ModelKind::City, 20000, 1},
                      Case{ModelKind::Terrain, 500, 1000}, Case{ModelKind::Plant, 30000, 1000},
                      Case{ModelKind::City, 30000, 300}, Case{ModelKind::Terrain, 30000, 1000, 4},
                      Case{ModelKind::City, 30000, 1000, 4}, Case{ModelKind::Sphere, 20000, 64, 4},
                      Case{ModelKind::City, 20000, 1, 4}));

TEST(BlocksCut, InvalidCutsAreNamed) {
  const auto h = small_hierarchy(ModelKind::Terrain, 30000);
  const HlodBlocks b = HlodBlocks::build(*h, 1000);
  ASSERT_GT(b.block_count(), 1u);
  EXPECT_NE(b.validate_cut({}).find("not covered"), std::string::npos);
  const std::vector<BlockId> twice{0, 0};
  EXPECT_NE(b.validate_cut(twice).find("twice"), std::string::npos);
  const std::vector<BlockId> nested{0, b.first_child(0)};
  EXPECT_NE(b.validate_cut(nested).find("under another block"), std::string::npos);
  const std::vector<BlockId> out{b.block_count()};
  EXPECT_NE(b.validate_cut(out).find("out of range"), std::string::npos);
  EXPECT_THROW((void)b.nodes_of_cut(nested), std::invalid_argument);
  EXPECT_THROW((void)HlodBlocks::build(*h, 0), std::invalid_argument);
  EXPECT_THROW((void)HlodBlocks::build(*h, 1000, 3), std::invalid_argument);
}

TEST(BlocksCut, OneBlockWhenTheModelIsSmallerThanABlock) {
  const auto h = small_hierarchy(ModelKind::Terrain, 500);
  const HlodBlocks b = HlodBlocks::build(*h, 1000);
  EXPECT_EQ(b.block_count(), 1u);
  EXPECT_TRUE(b.is_leaf(0));
  EXPECT_EQ(b.representation(0).size(), h->leaf_count());
}

// The blocks hoq makes as its traversal reaches them (resident_blocks.hpp)
// are, on a model held whole, those HlodBlocks::build gives with fan-out 4:
// the same representation, box and kind, block for block.
TEST(ResidentBlocks, OnAModelHeldWholeTheyAreTheBlocksBuiltAtOnce) {
  const auto h = small_hierarchy(ModelKind::City, 20000);
  for (const std::uint32_t size : {1u, 200u, 1000u}) {
    SCOPED_TRACE(size);
    const HlodBlocks built = HlodBlocks::build(*h, size, treecut::culling::kHierarchyFanOut);
    treecut::culling::ResidentBlocks made;
    made.reset(*h, size);
    // Breadth-first ids: a parent block before its children, as a traversal asks.
    for (BlockId b = 0; b < built.block_count(); ++b) {
      const NodeId n = built.root(b);
      const auto& m = made.at(*h, n);
      const auto rep = built.representation(b);
      ASSERT_EQ(m.rep, std::vector<NodeId>(rep.begin(), rep.end())) << "block " << b;
      EXPECT_EQ(m.box.lo, built.box(b).lo) << "block " << b;
      EXPECT_EQ(m.box.hi, built.box(b).hi) << "block " << b;
      EXPECT_EQ(made.is_leaf(*h, n), built.is_leaf(b)) << "block " << b;
      EXPECT_TRUE(m.hidden.empty());
    }
    EXPECT_EQ(made.size(), built.block_count());
  }
}

}  // namespace
