// Top-down strategy (Zach & Karner 2003, figure 3); see topdown.hpp.
#include "treecut/strategies/topdown.hpp"

#include "top_down.hpp"
#include "treecut/strategies/refinement_criterion.hpp"

namespace treecut::strategies {

TopDownStrategy::TopDownStrategy()
    : Strategy({
          {"theta", "pixels: a node unfolds when its projected radius reaches theta", 1.5, 0.05,
           1e6, false},
      }) {}

void TopDownStrategy::reset(const Hierarchy& /*hierarchy*/) {}

void TopDownStrategy::iterate(const IterationInput& input, IterationOutput& output) {
  const Hierarchy& h = input.hierarchy;
  IterationResult& r = output.result;
  const CriterionConstants cam = CriterionConstants::from_view(input.view, param_at(kTheta));
  const auto& cr = h.arrays().center_radius;
  auto decided = [](NodeId, bool) {};
  auto drop = [](NodeId) {};
  if (cam.perspective) {
    auto test = [&](NodeId n) { return unfold_test(cam, cr[n]); };
    detail::TopDown pass(h, *output.cut, r, input, test, decided, drop);
    pass.run(h.root());
  } else {
    auto test = [&](NodeId n) { return unfold_test(cam, input.view, cr[n]); };
    detail::TopDown pass(h, *output.cut, r, input, test, decided, drop);
    pass.run(h.root());
  }
  // The cut is a function of the view alone: a second pass would change nothing.
  r.converged = !r.cancelled;
}

}  // namespace treecut::strategies
