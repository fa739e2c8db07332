// Recursive strategy (Marton, Schiffner et al., "Parallel TreeCut
// Manipulation", section 4, after QSplat, Rusinkiewicz & Levoy 2000): a new
// cut from a traversal from the root that stops at nodes outside the frustum,
// nodes whose normal cone faces away, nodes projecting below a size, and
// leaves. O(visited nodes), logarithmic on average for large models. The
// traversal runs level by level rather than depth first: the same cut, but
// each level is read in ascending id order (ascending addresses, prefetched
// ahead) and the cut comes out sorted.
#pragma once

#include <cstdint>
#include <vector>

#include "treecut/strategy.hpp"

namespace treecut::strategies {

class RecursiveStrategy final : public Strategy {
 public:
  enum Param : std::size_t {
    kMinSize,   ///< pixels: projected radius below which the recursion stops
    kBackface,  ///< 1: stop at back-facing normal cones, 0: do not test
  };

  RecursiveStrategy();
  [[nodiscard]] std::string_view name() const override { return "recursive"; }
  [[nodiscard]] Mode mode() const override { return Mode::Rebuild; }
  void reset(const Hierarchy& hierarchy) override;
  void iterate(const IterationInput& input, IterationOutput& output) override;

 private:
  struct Pending {
    NodeId node;
    std::uint32_t planes;  // frustum planes the node's ancestors did not clear
  };
  std::vector<Pending> level_;  // the nodes of one depth still to decide (scratch)
  std::vector<Pending> next_;   // their children (scratch)
  std::uint64_t last_hash_ = 0;
  std::size_t last_size_ = 0;
};

}  // namespace treecut::strategies
