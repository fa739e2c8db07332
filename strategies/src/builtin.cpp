#include "treecut/strategies/builtin.hpp"

#include <memory>

#include "treecut/strategies/bucket.hpp"
#include "treecut/strategies/budget_strategy.hpp"
#include "treecut/strategies/event_queue.hpp"
#include "treecut/strategies/hoq.hpp"
#include "treecut/strategies/optimization.hpp"
#include "treecut/strategies/recursive.hpp"
#include "treecut/strategies/topdown.hpp"

namespace treecut::strategies {

void register_builtin(StrategyRegistry& registry) {
  registry.add("bucket",
               "target bucket per cut node (illumination -> depth, stippling); O(n) "
               "[Parallel TreeCut Manipulation, fig. 4]",
               [] { return std::make_unique<BucketStrategy>(); });
  registry.add("optimization",
               "refine the k highest, coarsen the k lowest priorities under a node budget; "
               "O(n log k) [Parallel TreeCut Manipulation, fig. 3]",
               [] { return std::make_unique<OptimizationStrategy>(); });
  registry.add("recursive",
               "QSplat traversal from the root: stops at culled, back-facing, small nodes and "
               "leaves; new cut every iteration",
               [] { return std::make_unique<RecursiveStrategy>(); });
  registry.add("topdown",
               "fold/unfold criterion (inside, or visible and projected radius >= theta) "
               "applied top-down to the active nodes every iteration [Zach & Karner 2003, fig. 3]",
               [] { return std::make_unique<TopDownStrategy>(); });
  registry.add("event_queue",
               "the same cut as topdown, testing only the nodes whose earliest possible change "
               "(from rho, omega) is due [Zach & Karner 2003, fig. 7]",
               [] { return std::make_unique<EventQueueStrategy>(); });
  registry.add("hoq",
               "HLOD blocks refined by VMSSE = B_{s,t}(mu) * SSE from occlusion queries, with "
               "refine/stop/delay predicted from cached bias [Charalambos et al. 2007, fig. 3]",
               [] { return std::make_unique<HoqStrategy>(); });
  registry.add("budget",
               "scene-level: Eq. 1 shares of N points over the objects left by frustum and "
               "hierarchical Z-map culling, each share the best cut of its object "
               "[Peng & Cao 2013, sections 5, 6]",
               [] { return std::make_unique<BudgetStrategy>(); });
}

StrategyRegistry builtin_registry() {
  StrategyRegistry registry;
  register_builtin(registry);
  return registry;
}

}  // namespace treecut::strategies
