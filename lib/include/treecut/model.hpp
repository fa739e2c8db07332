// Model (MVC, "Parallel TreeCut Manipulation", figure 1): the hierarchy and
// the tree cut that currently represents it.
#pragma once

#include <memory>

#include "treecut/hierarchy.hpp"
#include "treecut/tree_cut.hpp"

namespace treecut {

struct Model {
  /// Shared and immutable: lists handed to the renderer keep it alive.
  std::shared_ptr<const Hierarchy> hierarchy;
  TreeCut cut;  ///< valid for *hierarchy
};

/// A model whose cut is the root only (where every strategy can start).
Model make_model(Hierarchy hierarchy);

/// A cut of at least `nodes` nodes (or all leaves), refined breadth-first:
/// a deterministic starting cut of a given size for tests and benchmarks.
TreeCut breadth_first_cut(const Hierarchy& hierarchy, std::size_t nodes);

}  // namespace treecut
