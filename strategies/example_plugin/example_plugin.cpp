// An example out-of-tree strategy: "uniform_depth" drives every cut node to
// one depth (a fraction of the hierarchy's depth), refining what is above it
// and coarsening what is below. A minimal, complete Evolve strategy for the
// plugin guide (docs/plugin-guide.md).
#include <cmath>
#include <cstddef>
#include <memory>
#include <span>
#include <vector>

#include "treecut/plugin.hpp"
#include "treecut/strategy.hpp"

namespace {

class UniformDepthStrategy final : public treecut::Strategy {
 public:
  UniformDepthStrategy()
      : Strategy(
            {{"depth", "target depth as a fraction of the deepest level", 0.5, 0.0, 1.0, false}}) {}
  [[nodiscard]] std::string_view name() const override { return "uniform_depth"; }
  [[nodiscard]] Mode mode() const override { return Mode::Evolve; }
  void reset(const treecut::Hierarchy&) override { ops_.clear(); }

  void iterate(const treecut::IterationInput& in, treecut::IterationOutput& out) override {
    const treecut::Hierarchy& h = in.hierarchy;
    const auto& a = h.arrays();
    const int target =
        static_cast<int>(std::lround(param_at(0) * static_cast<double>(h.level_count() - 1)));
    treecut::TreeCut& cut = *out.cut;
    // Collect first, apply after: the pass sees one consistent cut.
    ops_.clear();
    const std::span<const treecut::NodeId> nodes = cut.nodes();
    for (std::size_t i = 0; i < nodes.size(); ++i) {
      // The guide's rule: test for cancellation every few thousand nodes and
      // return with a valid cut (nothing applied yet: the cut is unchanged).
      if ((i & 4095) == 0 && in.cancelled()) {
        out.result.cancelled = true;
        out.result.cut_size = cut.size();
        return;
      }
      const treecut::NodeId n = nodes[i];
      ++out.result.visited;
      if (a.depth[n] < target && a.child_count[n] != 0) {
        ops_.push_back(n);
      } else if (const treecut::NodeId p = a.parent[n];
                 a.depth[n] > target && a.first_child[p] == n && cut.can_coarsen(h, p)) {
        ops_.push_back(p);
      }
    }
    for (const treecut::NodeId n : ops_) {
      if (cut.contains(n)) {
        out.result.refined += cut.refine(h, n) ? 1u : 0u;
      } else {
        out.result.coarsened += cut.coarsen(h, n) ? 1u : 0u;
      }
    }
    out.result.cut_size = cut.size();
    out.result.converged = out.result.refined == 0 && out.result.coarsened == 0;
    // A named counter (treecut/counters.hpp): `treecut render` writes it as
    // a stats.csv column and into summary.json, the viewer's HUD shows it.
    out.result.counters.set("uniform_depth_target", target, "levels");
  }

 private:
  std::vector<treecut::NodeId> ops_;  // scratch, reused
};

}  // namespace

TREECUT_PLUGIN(registry) {
  registry.add("uniform_depth", "example plugin: every cut node at one depth",
               [] { return std::make_unique<UniformDepthStrategy>(); });
}
