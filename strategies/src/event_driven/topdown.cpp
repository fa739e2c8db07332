// Top-down strategy (Zach & Karner 2003, figure 3); see topdown.hpp.
#include "treecut/strategies/topdown.hpp"

#include "top_down.hpp"
#include "treecut/strategies/refinement_criterion.hpp"

namespace treecut::strategies {

namespace detail {

bool topdown_pass(const Hierarchy& h, TreeCut& cut, IterationResult& r, const IterationInput& input,
                  const CriterionConstants& cam, std::vector<NodeId>* wanted) {
  const auto& cr = h.arrays().center_radius;
  auto decided = [](NodeId, bool) {};
  auto drop = [](NodeId) {};
  auto run = [&](auto& test) {
    TopDown walk(h, cut, r, input, test, decided, drop);
    walk.want_into(wanted);
    return walk.run(h.root());
  };
  if (cam.perspective) {
    auto test = [&](NodeId n) { return unfold_test(cam, cr[n]); };
    return run(test);
  }
  auto test = [&](NodeId n) { return unfold_test(cam, input.view, cr[n]); };
  return run(test);
}

}  // namespace detail

TopDownStrategy::TopDownStrategy()
    : Strategy({
          {"theta", "pixels: a node unfolds when its projected radius reaches theta", 1.5, 0.05,
           1e6, false},
      }) {}

void TopDownStrategy::reset(const Hierarchy& /*hierarchy*/) {}

void TopDownStrategy::iterate(const IterationInput& input, IterationOutput& output) {
  const CriterionConstants cam = CriterionConstants::from_view(input.view, param_at(kTheta));
  detail::topdown_pass(input.hierarchy, *output.cut, output.result, input, cam, output.wanted);
  // The cut is a function of the view alone: a second pass would change nothing.
  output.result.converged = !output.result.cancelled;
}

}  // namespace treecut::strategies
