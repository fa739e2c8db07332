// The top-down adjustment of Zach & Karner 2003, figure 3, over a TreeCut:
// shared by the `topdown` strategy and by event_queue's rebuild, so both take
// the same decisions in the same order. A node is "active" (unfolded) when it
// is an ancestor of cut nodes, "boundary" when it is a cut node that is not a
// leaf. The result is the cut below every node whose test and whose
// ancestors' tests are all true, whatever the cut was before.
#pragma once

#include <atomic>
#include <cstdint>
#include <vector>

#include "treecut/hierarchy.hpp"
#include "treecut/strategies/refinement_criterion.hpp"
#include "treecut/strategy.hpp"
#include "treecut/tree_cut.hpp"

namespace treecut::strategies::detail {

/// What a pass reads of node n in the hierarchy's arrays, asked for ahead.
/// (The passes walk these arrays: on event_queue's node records, a copy of
/// the spheres and the children in one cache line per two nodes, they were
/// slower; docs/event-driven.md.)
inline void prefetch_node(const Hierarchy& h, NodeId n) {
  __builtin_prefetch(h.arrays().center_radius.data() + n);
  __builtin_prefetch(h.arrays().first_child.data() + n);
  __builtin_prefetch(h.arrays().child_count.data() + n);
}

/// Folds the active node `n`: its subtree collapses into it (bottom up, each
/// coarsen a valid cut). `drop(m)` is told every node below n that was active
/// or a cut node (the event queue erases their events).
template <class Drop>
void fold_subtree(const Hierarchy& h, TreeCut& cut, NodeId n, IterationResult& r, Drop&& drop) {
  const NodeId first = h.first_child(n);
  const unsigned count = h.child_count(n);
  for (NodeId c = first; c < first + count; ++c) {
    if (!cut.contains(c)) fold_subtree(h, cut, c, r, drop);
    drop(c);
  }
  cut.coarsen_known(n, first, count);
  ++r.coarsened;
}

/// Figure 3's step at the non-leaf node n, reached with every ancestor
/// active: tests it, unfolds or folds it, tells decided(n, active). Returns
/// true when n is active now (its children are to be visited).
template <class Test, class Decided, class Drop>
bool figure3_step(const Hierarchy& h, TreeCut& cut, IterationResult& r, NodeId n, Test& test,
                  Decided& decided, Drop& drop) {
  const bool pass = test(n);
  if (cut.contains(n)) {
    // Inactive: unfold when the test passes, else the subtree stays folded.
    if (!pass) {
      decided(n, false);
      return false;
    }
    cut.refine_known(n, h.first_child(n), h.child_count(n));
    ++r.refined;
  } else if (!pass) {
    // Active, and no longer meets the criterion: fold it and its subtree.
    fold_subtree(h, cut, n, r, drop);
    decided(n, false);
    return false;
  }
  decided(n, true);
  return true;
}

/// Figure 3 from `n` down. `test(n)` is the unfold test; `decided(n, active)`
/// is told each non-leaf node's state once it is final, right after its test
/// (the event queue schedules its next event). Returns false when cancelled
/// (the cut is valid: every step is one refine or coarsen).
template <class Test, class Decided, class Drop>
class TopDown {
 public:
  TopDown(const Hierarchy& h, TreeCut& cut, IterationResult& r, const IterationInput& input,
          Test& test, Decided& decided, Drop& drop)
      : h_(h), cut_(cut), r_(r), input_(input), test_(test), decided_(decided), drop_(drop) {}
  /// A paged model's hidden leaves whose test passes go to WANTED
  /// (IterationOutput::wanted).
  void want_into(std::vector<NodeId>* wanted) { wanted_ = wanted; }

  bool run(NodeId n) {
    if (h_.is_leaf(n)) {
      leaf(n);
      return true;
    }
    return run_inner(n);
  }

 private:
  void leaf(NodeId n) {
    if (wanted_ && h_.is_hidden(n) && test_(n)) wanted_->push_back(n);
  }
  // N is no leaf. Leaf children are met here, not by a call: most children
  // are leaves, and the walk ran 10-25 % slower where the compiler did not
  // inline the recursion once by itself (selection_bench).
  bool run_inner(NodeId n) {
    if ((++r_.visited & 4095) == 0 && input_.cancelled()) {
      r_.cancelled = true;
      return false;
    }
    if (!figure3_step(h_, cut_, r_, n, test_, decided_, drop_)) return true;
    const NodeId first = h_.first_child(n);
    const unsigned count = h_.child_count(n);
    for (NodeId c = first; c < first + count; ++c) {
      if (h_.is_leaf(c)) {
        leaf(c);
      } else if (!run_inner(c)) {
        return false;
      }
    }
    return true;
  }

  const Hierarchy& h_;
  TreeCut& cut_;
  IterationResult& r_;
  const IterationInput& input_;
  Test& test_;
  Decided& decided_;
  Drop& drop_;
  std::vector<NodeId>* wanted_ = nullptr;
};

/// Figure 3 level by level: the same tests, edits and decided() calls as
/// TopDown, in breadth-first order. Node ids are breadth-first, so each
/// level's nodes are read in ascending order and the ones ahead are known:
/// the 48th ahead is prefetched (16 ahead left a pass at a teleport 1.0 to
/// 1.1 times topdown's, 48 0.8 to 1.0 in the same runs), and a pass over
/// cold memory (after event iterations) waits for it far less. `a` and `b`
/// are scratch. A paged model's hidden leaves met go to HIDDEN, those whose
/// test passes to WANTED (IterationOutput::wanted), each when given.
template <class Test, class Decided, class Drop>
bool level_pass(const Hierarchy& h, TreeCut& cut, IterationResult& r, const IterationInput& input,
                Test& test, Decided& decided, Drop& drop, std::vector<NodeId>& a,
                std::vector<NodeId>& b, std::vector<NodeId>* wanted,
                std::vector<NodeId>* hidden = nullptr) {
  constexpr std::size_t kAhead = 48;
  auto leaf = [&](NodeId c) {
    if (!h.is_hidden(c)) return;
    if (hidden) hidden->push_back(c);
    if (wanted && test(c)) wanted->push_back(c);
  };
  a.clear();
  if (!h.is_leaf(h.root()))
    a.push_back(h.root());
  else
    leaf(h.root());
  while (!a.empty()) {
    b.clear();
    const std::size_t count = a.size();
    for (std::size_t i = 0; i < count; ++i) {
      if (i + kAhead < count) {
        prefetch_node(h, a[i + kAhead]);
        cut.prefetch(a[i + kAhead]);
      }
      const NodeId n = a[i];
      if ((++r.visited & 4095) == 0 && input.cancelled()) {
        r.cancelled = true;
        return false;
      }
      if (!figure3_step(h, cut, r, n, test, decided, drop)) continue;
      const NodeId first = h.first_child(n);
      const unsigned children = h.child_count(n);
      for (NodeId c = first; c < first + children; ++c) {
        if (!h.is_leaf(c))
          b.push_back(c);
        else
          leaf(c);
      }
    }
    a.swap(b);
  }
  return true;
}

/// The `topdown` strategy's pass: figure 3 from the root under `cam`.
/// Returns false when cancelled. Defined once, in topdown.cpp: as an inline
/// function each file that called it compiled its own copy of the walk,
/// and the linker kept one of them, inlined more or less as that file's
/// size allowed (topdown ran 10-25 % slower in selection_bench after
/// event_queue.cpp grew).
bool topdown_pass(const Hierarchy& h, TreeCut& cut, IterationResult& r, const IterationInput& input,
                  const CriterionConstants& cam, std::vector<NodeId>* wanted);

}  // namespace treecut::strategies::detail
