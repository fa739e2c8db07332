// TreeCut: refine/coarsen keep the cut valid under random sequences; the
// validator catches every kind of broken list.
#include "treecut/tree_cut.hpp"

#include <gtest/gtest.h>

#include <random>

#include "treecut/generate.hpp"
#include "treecut/model_io.hpp"

using namespace treecut;

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
