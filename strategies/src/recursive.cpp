// Recursive strategy: Marton, Schiffner et al., "Parallel TreeCut
// Manipulation", section 4, after the QSplat traversal (Rusinkiewicz & Levoy,
// "QSplat: A Multiresolution Point Rendering System for Large Meshes", 2000).
#include "treecut/strategies/recursive.hpp"

namespace treecut::strategies {
namespace {

// FNV-1a over the emitted ids: an equal list under an equal view means the
// strategy has converged.
constexpr std::uint64_t kFnvOffset = 0xcbf29ce484222325ull;
constexpr std::uint64_t kFnvPrime = 0x100000001b3ull;

}  // namespace

RecursiveStrategy::RecursiveStrategy()
    : Strategy({
          {"min_size", "pixels: the recursion stops below this projected radius", 1.0, 0.0, 1e6,
           false},
          {"backface", "1: stop at normal cones facing away from the eye", 1.0, 0.0, 1.0, true},
      }) {}

void RecursiveStrategy::reset(const Hierarchy& hierarchy) {
  stack_.clear();
  stack_.reserve(static_cast<std::size_t>(hierarchy.level_count()) * 4 + 4);
  last_hash_ = 0;
  last_size_ = 0;
}

void RecursiveStrategy::iterate(const IterationInput& input, IterationOutput& output) {
  const Hierarchy& h = input.hierarchy;
  const ViewSnapshot& view = input.view;
  const HierarchyArrays& a = h.arrays();
  std::vector<NodeId>& out = *output.nodes;
  IterationResult& r = output.result;
  const auto min_size = static_cast<float>(param_at(kMinSize));
  const bool backface = param_at(kBackface) != 0.0;

  std::uint64_t hash = kFnvOffset;
  const auto emit = [&](NodeId n) {
    out.push_back(n);
    hash = (hash ^ n) * kFnvPrime;
  };
  stack_.clear();
  stack_.push_back(h.root());
  while (!stack_.empty()) {
    const NodeId n = stack_.back();
    stack_.pop_back();
    ++r.visited;
    if ((r.visited & 4095) == 0 && input.cancelled()) {
      // Every node still on the stack roots an untraversed subtree: emitting
      // them all keeps the cut complete.
      r.cancelled = true;
      emit(n);
      for (const NodeId s : stack_) emit(s);
      break;
    }
    const glm::vec4 cr = a.center_radius[n];
    const glm::vec3 c(cr);
    if (view.outside_frustum(c, cr.w)) {
      ++r.culled;
      emit(n);
      continue;
    }
    if (backface && view.backfacing(c, cr.w, h.normal(n), h.cone_cos(n))) {
      ++r.backfacing;
      emit(n);
      continue;
    }
    const unsigned children = a.child_count[n];
    if (children == 0) {
      emit(n);
      continue;
    }
    if (view.projected_radius_px(c, cr.w) < min_size) {
      ++r.too_small;
      emit(n);
      continue;
    }
    // Reverse order so the first child is traversed first (deterministic order).
    const NodeId first = a.first_child[n];
    for (unsigned i = children; i-- > 0;) stack_.push_back(first + i);
  }
  r.cut_size = out.size();
  r.converged = !r.cancelled && hash == last_hash_ && out.size() == last_size_;
  last_hash_ = r.cancelled ? 0 : hash;
  last_size_ = out.size();
}

}  // namespace treecut::strategies
