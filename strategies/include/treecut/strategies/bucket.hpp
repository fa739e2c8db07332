// Bucket-based strategy (Marton, Schiffner et al., "Parallel TreeCut
// Manipulation", section 4 and figure 4). Every cut node gets a target bucket
// (a target depth); a positive delta refines the node, a negative delta of all
// siblings coarsens their parent unless the parent's own bucket would refine it
// again. O(n) for a cut of n nodes.
#pragma once

#include <cstdint>
#include <functional>
#include <vector>

#include "treecut/strategy.hpp"

namespace treecut::strategies {

/// The target bucket (a depth; fractions are floored) of node `n`. Called for
/// every cut node on the Feedback Stage thread; must be a pure function of its
/// arguments so the strategy converges under a static view.
using BucketFunction = std::function<float(const Hierarchy&, const ViewSnapshot&, NodeId)>;

class BucketStrategy final : public Strategy {
 public:
  enum Param : std::size_t {
    kThreshold,  ///< minimal negative delta (in levels, beyond 0) that forces a coarse
    kMinDepth,   ///< fraction of the depth range used for fully lit nodes
    kMaxDepth,   ///< fraction of the depth range used for unlit nodes
    kAmbient,    ///< light every node receives, [0, 1]
    kCull,       ///< 1: nodes outside the view frustum target kMinDepth
  };

  /// Without a function: the stippling look of the paper's figure 7a, the
  /// target depth interpolates from kMinDepth (lit) to kMaxDepth (dark) by the
  /// node's diffuse illumination (with kCull, nodes outside the frustum
  /// target kMinDepth).
  explicit BucketStrategy(BucketFunction function = {});
  [[nodiscard]] std::string_view name() const override { return "bucket"; }
  [[nodiscard]] Mode mode() const override { return Mode::Evolve; }
  void reset(const Hierarchy& hierarchy) override;
  void iterate(const IterationInput& input, IterationOutput& output) override;

  /// The default bucket of `n` with this strategy's parameters.
  [[nodiscard]] int illumination_bucket(const Hierarchy& h, const ViewSnapshot& view,
                                        NodeId n) const;

 private:
  BucketFunction function_;
  std::vector<NodeId> refine_;        // scratch
  std::vector<NodeId> coarsen_;       // scratch
  std::vector<NodeId> sort_scratch_;  // TreeCut::keep_sorted
};

}  // namespace treecut::strategies
