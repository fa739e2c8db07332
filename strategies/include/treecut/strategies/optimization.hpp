// Optimization strategy (Marton, Schiffner et al., "Parallel TreeCut
// Manipulation", section 4 and figure 3; partial sorting after Carr et al.
// [Car11]). Evolves the cut under a maximal node count: the k cut nodes of
// highest priority are refined, the k coarsenable parents of lowest priority
// are coarsened to make room. The partial sort of size k is a bounded
// selection (nth_element over at most 2k candidates at a time) plus lazily
// popped heaps: O(n + m log k) for a cut of n nodes and m operations, within
// the paper's O(n log k).
#pragma once

#include <cstdint>
#include <vector>

#include "treecut/sparse_node_array.hpp"
#include "treecut/strategy.hpp"

namespace treecut::strategies {

class OptimizationStrategy final : public Strategy {
 public:
  /// Parameter indices (param_specs() order).
  enum Param : std::size_t {
    kMaxNodes,         ///< maximal cut size (the budget)
    kK,                ///< partial sort size: candidates kept per side
    kThreshold,        ///< minimal priority gain that allows a coarse
    kCurvatureWeight,  ///< 0: projected size only, 1: size x curvature
    kMinSize,          ///< pixels: nodes projecting smaller are not refined
  };

  OptimizationStrategy();
  [[nodiscard]] std::string_view name() const override { return "optimization"; }
  [[nodiscard]] Mode mode() const override { return Mode::Evolve; }
  void reset(const Hierarchy& hierarchy) override;
  void iterate(const IterationInput& input, IterationOutput& output) override;
  /// Bytes of per-node state held (the hysteresis marks): about the cut's
  /// size, not the hierarchy's.
  [[nodiscard]] std::size_t state_bytes() const { return last_op_.memory_bytes(); }

  /// The view-dependent priority of a node: projected radius in pixels times
  /// ((1 - w) + w * curvature), 0 outside the frustum. Monotone: a parent's
  /// priority is >= each child's, because the child's sphere lies inside the
  /// parent's and the hierarchy's curvature priority is monotone.
  [[nodiscard]] static float priority(const Hierarchy& h, const ViewSnapshot& view, NodeId n,
                                      float curvature_weight, float* size_px = nullptr);

 private:
  // (priority bits << 32 | node): priorities are >= 0, so their IEEE bits
  // order like the values, and one integer compare ranks by priority, then id.
  using Candidate = std::uint64_t;

  // Clears the marks no later iteration reads (refine_blocked reads those
  // of the current view, coarsen_blocked the last iteration's) once they
  // hold many more blocks than the cut needs.
  void forget_old_marks(std::size_t cut_size);

  // Per-node hysteresis against "a node refined in an iteration while it is
  // coarsened in the next" (the paper's threshold discussion): the iteration
  // and kind of each node's last operation. A node coarsened under the current
  // view is not refined again under it; a node refined in the previous
  // iteration is not coarsened. Each node changes at most twice per view (and
  // parameter set), so a static view converges. Sparse, and marks no
  // iteration reads again are forgotten now and then (forget_old_marks), so
  // the marks follow the cut, not the hierarchy (issue 45).
  SparseNodeArray<std::uint32_t> last_op_;  // iteration << 1 | refined
  std::uint32_t view_forgotten_ = 0;        // view_start_ at the last forget_old_marks
  std::uint32_t iteration_ = 0;             // iterations since reset(), from 1
  std::uint32_t view_start_ = 0;            // first iteration of the current view
  std::uint64_t last_version_ = ~std::uint64_t{0};
  // A parameter change opens a new hysteresis period like a new view: a raised
  // max_nodes may refine what a lower one coarsened under the same view.
  std::uint64_t last_params_ = ~std::uint64_t{0};
  std::vector<Candidate> high_;       // selection buffer, then a max-heap
  std::vector<Candidate> low_;        // selection buffer, then a min-heap
  std::vector<NodeId> sort_scratch_;  // TreeCut::keep_sorted
};

}  // namespace treecut::strategies
