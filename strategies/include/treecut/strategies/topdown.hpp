// Top-down strategy: the baseline of Zach & Karner, "Fast Event-Driven
// Refinement of Dynamic Levels of Detail" (2003), figure 3 (VDSlib's
// adjustTreeTopDown): every iteration walks the active nodes from the root and
// tests each active and boundary node with the fold/unfold criterion of
// figure 4 (refinement_criterion.hpp); a boundary node that passes is
// unfolded, an active node that fails is folded with its subtree. O(active +
// boundary nodes) per iteration, about 4/3 of the cut. The cut it leaves
// depends on the view only, not on the cut before.
#pragma once

#include <vector>

#include "treecut/strategy.hpp"

namespace treecut::strategies {

class TopDownStrategy final : public Strategy {
 public:
  enum Param : std::size_t {
    kTheta,  ///< pixels: a node unfolds when its projected radius reaches theta
  };

  TopDownStrategy();
  [[nodiscard]] std::string_view name() const override { return "topdown"; }
  [[nodiscard]] Mode mode() const override { return Mode::Evolve; }
  void reset(const Hierarchy& hierarchy) override;
  void iterate(const IterationInput& input, IterationOutput& output) override;
};

}  // namespace treecut::strategies
