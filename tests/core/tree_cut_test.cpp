// TreeCut: refine/coarsen keep the cut valid under random sequences; the
// validator catches every kind of broken list.
#include "treecut/tree_cut.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <random>
#include <vector>

#include "treecut/model_io.hpp"
#include "treecut/tools/generate.hpp"

using namespace treecut;
using namespace treecut::tools;

namespace {
const Hierarchy& small_hierarchy() {
  static const Hierarchy h = build_from_points(generate_model(ModelKind::Sphere, 4000, 2));
  return h;
}
}  // namespace

TEST(TreeCut, RootAndLeafCutsAreValid) {
  const Hierarchy& h = small_hierarchy();
  const TreeCut root = TreeCut::root_cut(h);
  EXPECT_EQ(root.size(), 1u);
  EXPECT_EQ(root.validate(h), "");
  const TreeCut leaves = TreeCut::leaf_cut(h);
  EXPECT_EQ(leaves.size(), h.leaf_count());
  EXPECT_EQ(leaves.validate(h), "");
}

TEST(TreeCut, RefineReplacesANodeByItsChildren) {
  const Hierarchy& h = small_hierarchy();
  TreeCut cut = TreeCut::root_cut(h);
  ASSERT_TRUE(cut.refine(h, h.root()));
  EXPECT_EQ(cut.size(), h.child_count(h.root()));
  EXPECT_FALSE(cut.contains(h.root()));
  EXPECT_TRUE(cut.contains(h.first_child(h.root())));
  EXPECT_FALSE(cut.refine(h, h.root())) << "a node outside the cut cannot be refined";
  EXPECT_TRUE(cut.coarsen(h, h.root()));
  EXPECT_EQ(cut.size(), 1u);
  EXPECT_EQ(cut.refinements(), 1u);
  EXPECT_EQ(cut.coarsenings(), 1u);
}

TEST(TreeCut, CoarsenNeedsAllChildrenInTheCut) {
  const Hierarchy& h = small_hierarchy();
  TreeCut cut = TreeCut::root_cut(h);
  cut.refine(h, h.root());
  const NodeId c0 = h.first_child(h.root());
  ASSERT_TRUE(cut.refine(h, c0));
  EXPECT_FALSE(cut.can_coarsen(h, h.root()));
  EXPECT_FALSE(cut.coarsen(h, h.root()));
  EXPECT_EQ(cut.validate(h), "");
}

TEST(TreeCut, LeavesCannotBeRefined) {
  const Hierarchy& h = small_hierarchy();
  TreeCut cut = TreeCut::leaf_cut(h);
  EXPECT_FALSE(cut.refine(h, cut.nodes()[0]));
}

TEST(TreeCut, RandomRefineCoarsenSequencesStayValid) {
  const Hierarchy& h = small_hierarchy();
  std::mt19937 rng(1234);
  TreeCut cut = TreeCut::root_cut(h);
  for (int step = 0; step < 20000; ++step) {
    const NodeId n = cut.nodes()[rng() % cut.size()];
    if (rng() % 3 != 0) {
      cut.refine(h, n);
    } else if (h.parent(n) != kNoNode) {
      cut.coarsen(h, h.parent(n));
    }
    if (step % 997 == 0) {
      ASSERT_EQ(cut.validate(h), "") << "step " << step;
    }
  }
  EXPECT_EQ(cut.validate(h), "");
  EXPECT_GT(cut.refinements(), 0u);
  EXPECT_GT(cut.coarsenings(), 0u);
}

// sort() through both of its paths: few positions written since the last
// sort (pull out, sort, merge) and many (radix sort). Afterwards the list is
// ascending, holds the same nodes, and the slot map still drives refine and
// coarsen correctly.
TEST(TreeCut, SortOrdersTheListAndKeepsItUsable) {
  const Hierarchy& h = small_hierarchy();
  std::mt19937 rng(99);
  TreeCut cut = TreeCut::root_cut(h);
  std::vector<NodeId> scratch;
  int merges = 0;
  int full = 0;
  for (int round = 0; round < 400; ++round) {
    const int steps = static_cast<int>(rng() % (round % 2 == 0 ? 8 : 400)) + 1;
    for (int step = 0; step < steps; ++step) {
      const NodeId n = cut.nodes()[rng() % cut.size()];
      if (rng() % 5 < 3) {
        cut.refine(h, n);
      } else if (h.parent(n) != kNoNode) {
        cut.coarsen(h, h.parent(n));
      }
    }
    std::vector<NodeId> expected(cut.nodes().begin(), cut.nodes().end());
    std::sort(expected.begin(), expected.end());
    const bool merge_path = cut.disorder() * 4 <= cut.size();
    (merge_path ? merges : full) += 1;
    cut.sort(scratch);
    ASSERT_TRUE(
        std::equal(cut.nodes().begin(), cut.nodes().end(), expected.begin(), expected.end()))
        << "round " << round;
    ASSERT_EQ(cut.disorder(), 0u);
    for (const NodeId n : expected) ASSERT_TRUE(cut.contains(n));
    ASSERT_EQ(cut.validate(h), "") << "round " << round;
  }
  EXPECT_GT(merges, 20) << "the merge path was not exercised";
  EXPECT_GT(full, 20) << "the radix path was not exercised";
  EXPECT_GT(cut.size(), 100u);
}

// Many moved nodes in a large cut: the merge path sorts them with the radix sort.
TEST(TreeCut, SortMergesManyMovedNodes) {
  const Hierarchy h = build_from_points(generate_model(ModelKind::Terrain, 60000, 3));
  TreeCut cut = TreeCut::leaf_cut(h);
  std::mt19937 rng(3);
  std::vector<NodeId> scratch;
  for (int step = 0; step < 3000; ++step) {
    const NodeId n = cut.nodes()[rng() % cut.size()];
    if (h.parent(n) != kNoNode) cut.coarsen(h, h.parent(n));
  }
  ASSERT_GT(cut.disorder(), 4096u);
  ASSERT_LE(cut.disorder() * 4, cut.size()) << "meant for the merge path";
  std::vector<NodeId> expected(cut.nodes().begin(), cut.nodes().end());
  std::sort(expected.begin(), expected.end());
  cut.sort(scratch);
  EXPECT_TRUE(std::equal(cut.nodes().begin(), cut.nodes().end(), expected.begin(), expected.end()));
  EXPECT_EQ(cut.validate(h), "");
  for (int step = 0; step < 1000; ++step) cut.refine(h, cut.nodes()[rng() % cut.size()]);
  EXPECT_EQ(cut.validate(h), "") << "the slot map still drives refine";
}

TEST(TreeCut, DisorderCountsWrittenPositions) {
  const Hierarchy& h = small_hierarchy();
  EXPECT_EQ(TreeCut::root_cut(h).disorder(), 0u);
  EXPECT_EQ(TreeCut::leaf_cut(h).disorder(), 0u);
  TreeCut cut = TreeCut::root_cut(h);
  std::vector<NodeId> scratch;
  ASSERT_TRUE(cut.refine(h, h.root()));
  EXPECT_EQ(cut.disorder(), h.child_count(h.root()));
  EXPECT_TRUE(cut.keep_sorted(scratch));
  EXPECT_EQ(cut.disorder(), 0u);
  EXPECT_TRUE(std::is_sorted(cut.nodes().begin(), cut.nodes().end()));

  // A large sorted cut tolerates a few writes before keep_sorted() sorts.
  TreeCut leaves = TreeCut::leaf_cut(h);
  const NodeId parent = h.parent(leaves.nodes()[0]);
  ASSERT_TRUE(leaves.coarsen(h, parent));
  EXPECT_GT(leaves.disorder(), 0u);
  EXPECT_FALSE(leaves.keep_sorted(scratch));
  EXPECT_FALSE(std::is_sorted(leaves.nodes().begin(), leaves.nodes().end()));
  leaves.sort(scratch);
  EXPECT_TRUE(std::is_sorted(leaves.nodes().begin(), leaves.nodes().end()));
  EXPECT_EQ(leaves.validate(h), "");

  // A list given out of order counts as scattered.
  std::vector<NodeId> reversed(cut.nodes().rbegin(), cut.nodes().rend());
  EXPECT_EQ(TreeCut::from_nodes(h, reversed).disorder(), reversed.size());
}

TEST(TreeCut, SortNodeIdsMatchesStdSort) {
  std::mt19937 rng(5);
  std::vector<NodeId> scratch;
  for (const NodeId id_end : {1u, 2u, 2048u, 2049u, 1u << 22, 1u << 25, 0xffffffffu}) {
    for (const std::size_t count : {0u, 1u, 7u, 5000u}) {
      std::vector<NodeId> ids(count);
      for (NodeId& id : ids) id = static_cast<NodeId>(rng() % id_end);
      std::vector<NodeId> expected = ids;
      std::sort(expected.begin(), expected.end());
      sort_node_ids(ids, id_end, scratch);
      ASSERT_EQ(ids, expected) << "id_end " << id_end << ", " << count << " ids";
    }
  }
}

TEST(TreeCut, ValidateRejectsBrokenLists) {
  const Hierarchy& h = small_hierarchy();
  const NodeId r = h.root();
  const NodeId c0 = h.first_child(r);
  std::vector<NodeId> children;
  for (NodeId c = c0; c < c0 + h.child_count(r); ++c) children.push_back(c);

  EXPECT_EQ(TreeCut::validate(h, children), "");
  auto missing = children;
  missing.pop_back();
  EXPECT_NE(TreeCut::validate(h, missing), "") << "an uncovered subtree";
  auto dup = children;
  dup.push_back(children[0]);
  EXPECT_NE(TreeCut::validate(h, dup), "") << "a node listed twice";
  auto nested = children;
  nested.push_back(h.first_child(children[0]));
  EXPECT_NE(TreeCut::validate(h, nested), "") << "a node below another";
  EXPECT_NE(TreeCut::validate(h, std::vector<NodeId>{h.node_count()}), "") << "an id out of range";
  EXPECT_THROW(TreeCut::from_nodes(h, missing), std::invalid_argument);
  EXPECT_EQ(TreeCut::from_nodes(h, children).size(), children.size());
}

TEST(SparseNodeArray, HoldsOnlyTheBlocksWrittenTo) {
  SparseNodeArray<std::uint32_t> a(10'000'000, 7u);
  EXPECT_EQ(a.blocks_held(), 0u);
  EXPECT_EQ(a[0], 7u);
  EXPECT_EQ(a[9'999'999], 7u);
  a.set(5, 7u);  // the fill value: nothing to hold
  EXPECT_EQ(a.blocks_held(), 0u);
  a.set(5'000'000, 1u);
  a.set(5'000'001, 2u);
  EXPECT_EQ(a.blocks_held(), 1u);
  EXPECT_EQ(a[5'000'000], 1u);
  EXPECT_EQ(a[5'000'001], 2u);
  EXPECT_EQ(a[4'999'999], 7u);
  EXPECT_LT(a.memory_bytes(), 10'000'000u * 4 / 100) << "a directory and two blocks";

  SparseNodeArray<std::uint32_t> copy = a;  // deep: the Feedback Stage's copy of a cut
  copy.set(5'000'000, 3u);
  EXPECT_EQ(a[5'000'000], 1u);
  EXPECT_EQ(copy[5'000'000], 3u);
  EXPECT_EQ(copy[5'000'001], 2u);
  EXPECT_EQ(copy[17], 7u);

  a.set(5'000'000, 7u);
  a.release_unused();
  EXPECT_EQ(a.blocks_held(), 1u) << "one value still differs from the fill";
  a.set(5'000'001, 7u);
  a.release_unused();
  EXPECT_EQ(a.blocks_held(), 0u);
  EXPECT_EQ(a[5'000'001], 7u);
  a.set(5'000'001, 4u);  // a released block comes back on a write
  EXPECT_EQ(a[5'000'001], 4u);
  EXPECT_EQ(a[5'000'002], 7u);
}

// A cut's memory follows the cut, not the hierarchy (issue 45): the root
// cut of a large hierarchy holds a directory and one block; a view-sized cut
// a few bytes a node beyond its list; and a cut coarsened back gives its
// blocks back at the next full sort.
TEST(TreeCut, MemoryFollowsTheCutNotTheHierarchy) {
  static const Hierarchy h = build_from_points(generate_model(ModelKind::Sphere, 400'000, 3));
  const std::size_t per_node_map = std::size_t{h.node_count()} * sizeof(std::uint32_t);
  TreeCut cut = TreeCut::root_cut(h);
  EXPECT_LT(cut.memory_bytes(), per_node_map / 50) << h.node_count() << " nodes";

  // Refine the part of the model on one side of a plane down to its leaves'
  // parents: a cut over a spatially coherent part, as a view gives.
  std::vector<NodeId> scratch;
  const float plane = h.bounds_min().x + 0.8f * (h.bounds_max().x - h.bounds_min().x);
  for (bool again = true; again;) {
    again = false;
    const std::vector<NodeId> nodes(cut.nodes().begin(), cut.nodes().end());
    for (const NodeId n : nodes) {
      if (h.center(n).x + h.radius(n) > plane && !h.is_leaf(n) && !h.is_leaf(h.first_child(n)) &&
          cut.refine(h, n))
        again = true;
    }
  }
  cut.sort(scratch);
  ASSERT_EQ(cut.validate(h), "");
  ASSERT_GT(cut.size(), 5'000u);
  ASSERT_LT(cut.size() * 10, h.node_count());
  EXPECT_LT(cut.memory_bytes(), per_node_map / 3)
      << cut.size() << " nodes in the cut, " << h.node_count() << " in the hierarchy";
  EXPECT_LT(cut.memory_bytes(), 40 * cut.size()) << "bytes a cut node";
  const std::size_t refined = cut.memory_bytes();

  for (bool again = true; again;) {
    again = false;
    const std::vector<NodeId> nodes(cut.nodes().begin(), cut.nodes().end());
    for (const NodeId n : nodes)
      if (h.parent(n) != kNoNode && cut.coarsen(h, h.parent(n))) again = true;
  }
  ASSERT_EQ(cut.size(), 1u);
  cut.sort(scratch);
  EXPECT_EQ(cut.validate(h), "");
  EXPECT_LT(cut.memory_bytes(), refined / 4);
  EXPECT_TRUE(cut.refine(h, h.root())) << "the map still drives the edits";
  EXPECT_EQ(cut.validate(h), "");
}
