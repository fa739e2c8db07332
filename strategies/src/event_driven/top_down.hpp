// The top-down adjustment of Zach & Karner 2003, figure 3, over a TreeCut:
// shared by the `topdown` strategy and by event_queue's rebuild, so both take
// the same decisions in the same order. A node is "active" (unfolded) when it
// is an ancestor of cut nodes, "boundary" when it is a cut node that is not a
// leaf. The result is the cut below every node whose test and whose
// ancestors' tests are all true, whatever the cut was before.
#pragma once

#include <atomic>
#include <cstdint>

#include "treecut/hierarchy.hpp"
#include "treecut/strategy.hpp"
#include "treecut/tree_cut.hpp"

namespace treecut::strategies::detail {

/// Folds the active node `n`: its subtree collapses into n (bottom up, each
/// coarsen a valid cut). `drop(m)` is told every node below n that was active
/// or a cut node (the event queue erases their events).
template <class Drop>
void fold_subtree(const Hierarchy& h, TreeCut& cut, NodeId n, IterationResult& r, Drop&& drop) {
  const NodeId first = h.first_child(n);
  const NodeId end = first + h.child_count(n);
  for (NodeId c = first; c < end; ++c) {
    if (!cut.contains(c)) fold_subtree(h, cut, c, r, drop);
    drop(c);
  }
  cut.coarsen(h, n);
  ++r.coarsened;
}

/// Figure 3 from `n` down. `test(n)` is the unfold test; `decided(n, active)`
/// is told each non-leaf node's state once it is final (the event queue
/// schedules its next event). Returns false when cancelled (the cut is valid:
/// every step is one refine or coarsen).
template <class Test, class Decided, class Drop>
class TopDown {
 public:
  TopDown(const Hierarchy& h, TreeCut& cut, IterationResult& r, const IterationInput& input,
          Test& test, Decided& decided, Drop& drop)
      : h_(h), cut_(cut), r_(r), input_(input), test_(test), decided_(decided), drop_(drop) {}

  bool run(NodeId n) {
    if (h_.is_leaf(n)) return true;
    if ((++r_.visited & 4095) == 0 && input_.cancelled()) {
      r_.cancelled = true;
      return false;
    }
    const bool pass = test_(n);
    if (cut_.contains(n)) {
      // Inactive: unfold when the test passes, else the subtree stays folded.
      if (!pass) {
        decided_(n, false);
        return true;
      }
      cut_.refine(h_, n);
      ++r_.refined;
    } else if (!pass) {
      // Active, and no longer meets the criterion: fold it and its subtree.
      fold_subtree(h_, cut_, n, r_, drop_);
      decided_(n, false);
      return true;
    }
    decided_(n, true);
    const NodeId first = h_.first_child(n);
    const NodeId end = first + h_.child_count(n);
    for (NodeId c = first; c < end; ++c) {
      if (!run(c)) return false;
    }
    return true;
  }

 private:
  const Hierarchy& h_;
  TreeCut& cut_;
  IterationResult& r_;
  const IterationInput& input_;
  Test& test_;
  Decided& decided_;
  Drop& drop_;
};

}  // namespace treecut::strategies::detail
