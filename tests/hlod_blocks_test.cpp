// HLOD blocks (strategies/include/treecut/strategies/hlod_blocks.hpp): the
// partition of the leaves, conservative boxes, block sizes, the tree of blocks
// and the mapping of block cuts to valid TreeCuts.
#include "treecut/strategies/hlod_blocks.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <random>

#include "strategy_fixtures.hpp"
#include "treecut/tree_cut.hpp"

namespace {

using treecut::Hierarchy;
using treecut::ModelKind;
using treecut::NodeId;
using treecut::TreeCut;
using treecut::strategies::BlockId;
using treecut::strategies::HlodBlocks;
using treecut::strategies::kNoBlock;
using treecut::test::small_hierarchy;

// Leaves of the subtree of n, collected depth first.
void subtree(const Hierarchy& h, NodeId n, std::vector<NodeId>& all) {
  all.push_back(n);
  for (unsigned c = 0; c < h.child_count(n); ++c) subtree(h, h.first_child(n) + c, all);
}

struct Case {
  ModelKind kind;
  std::size_t points;
  std::uint32_t block_size;
};

class Blocks : public ::testing::TestWithParam<Case> {};

TEST_P(Blocks, EveryLeafIsInExactlyOneLeafBlock) {
  const auto h = small_hierarchy(GetParam().kind, GetParam().points);
  const HlodBlocks b = HlodBlocks::build(*h, GetParam().block_size);
  std::vector<int> owner_count(h->node_count(), 0);
  std::uint64_t leaves = 0;
  for (BlockId i = 0; i < b.block_count(); ++i) {
    if (!b.is_leaf(i)) continue;
    std::vector<NodeId> all;
    subtree(*h, b.root(i), all);
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
  const HlodBlocks b = HlodBlocks::build(*h, GetParam().block_size);
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
  const HlodBlocks b = HlodBlocks::build(*h, bs);
  const auto& a = h->arrays();
  std::uint64_t leaf_sum = 0;
  std::uint32_t leaf_blocks = 0;
  for (BlockId i = 0; i < b.block_count(); ++i) {
    const NodeId r = b.root(i);
    EXPECT_EQ(b.leaf_count(i), a.point_count[r]);
    EXPECT_EQ(b.block_of_root(r), i);
    if (i > 0) {
      EXPECT_GT(r, b.root(i - 1)) << "block ids follow the root ids";
    }
    if (b.is_leaf(i)) {
      ++leaf_blocks;
      leaf_sum += b.leaf_count(i);
      // Within [1, block_size] leaves; a leaf block is maximal: its parent's
      // subtree is too big (a block far smaller than block_size is a small
      // subtree beside big siblings: the hierarchy's shape, not a choice).
      EXPECT_GE(b.leaf_count(i), 1u);
      EXPECT_LE(b.leaf_count(i), bs);
      if (i != 0) {
        EXPECT_GT(a.point_count[h->parent(r)], bs);
      }
      EXPECT_EQ(b.representation(i).size(), b.leaf_count(i)) << "full detail";
    } else {
      EXPECT_GT(b.leaf_count(i), bs);
      EXPECT_EQ(b.child_count(i), h->child_count(r));
      for (unsigned c = 0; c < b.child_count(i); ++c) {
        const BlockId child = b.first_child(i) + c;
        EXPECT_EQ(b.parent(child), i);
        EXPECT_EQ(b.root(child), h->first_child(r) + c);
      }
      EXPECT_LE(b.representation(i).size(), bs);
      // The root is refined once whenever its children fit.
      EXPECT_GE(b.representation(i).size(), h->child_count(r) <= bs ? h->child_count(r) : 1u);
    }
    // The representation is a cut of the block's subtree.
    std::uint64_t covered = 0;
    for (NodeId n : b.representation(i)) {
      NodeId up = n;
      while (up != r && up != treecut::kNoNode) up = h->parent(up);
      EXPECT_EQ(up, r) << "node " << n << " is not under block " << i;
      covered += a.point_count[n];
    }
    EXPECT_EQ(covered, a.point_count[r]) << "block " << i;
  }
  EXPECT_EQ(b.parent(0), kNoBlock);
  EXPECT_EQ(leaf_blocks, b.leaf_block_count());
  EXPECT_EQ(leaf_sum, h->leaf_count());
  // On the generated models the blocks are not degenerate: on average at least
  // a tenth of the block size (the measured mean is about half).
  if (h->leaf_count() > 4 * bs) {
    EXPECT_GE(static_cast<double>(leaf_sum) / leaf_blocks, 0.1 * bs);
  }
}

TEST_P(Blocks, BlockCutsMapToValidTreeCuts) {
  const auto h = small_hierarchy(GetParam().kind, GetParam().points);
  const HlodBlocks b = HlodBlocks::build(*h, GetParam().block_size);

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

INSTANTIATE_TEST_SUITE_P(Models, Blocks,
                         ::testing::Values(Case{ModelKind::Terrain, 30000, 1000},
                                           Case{ModelKind::City, 30000, 1000},
                                           Case{ModelKind::Sphere, 20000, 64},
                                           Case{ModelKind::City, 20000, 1},
                                           Case{ModelKind::Terrain, 500, 1000}));

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
}

TEST(BlocksCut, OneBlockWhenTheModelIsSmallerThanABlock) {
  const auto h = small_hierarchy(ModelKind::Terrain, 500);
  const HlodBlocks b = HlodBlocks::build(*h, 1000);
  EXPECT_EQ(b.block_count(), 1u);
  EXPECT_TRUE(b.is_leaf(0));
  EXPECT_EQ(b.representation(0).size(), h->leaf_count());
}

}  // namespace
