// The strategies that ship with treecut, for a StrategyRegistry.
#pragma once

#include "treecut/registry.hpp"

namespace treecut::strategies {

/// Adds "optimization", "bucket", "recursive", "topdown", "event_queue" and "hoq".
void register_builtin(StrategyRegistry& registry);

/// A registry holding the built-in strategies.
StrategyRegistry builtin_registry();

}  // namespace treecut::strategies
