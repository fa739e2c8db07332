// Model (MVC, "Parallel TreeCut Manipulation", figure 1): the hierarchy and
// the tree cut that currently represents it.
#pragma once

#include <memory>

#include "treecut/hierarchy.hpp"
#include "treecut/paged_hierarchy.hpp"
#include "treecut/tree_cut.hpp"

namespace treecut {

struct Model {
  /// Shared and immutable: lists handed to the renderer keep it alive.
  std::shared_ptr<const Hierarchy> hierarchy;
  TreeCut cut;  ///< valid for *hierarchy
  /// A model drawn from its cache's pages (paged_hierarchy.hpp): HIERARCHY
  /// is its hierarchy(), and the stage reads its pages as the strategy asks
  /// for them and gives back what no list holds, between iterations. Null
  /// for a model held whole.
  std::shared_ptr<PagedHierarchy> paged{};
};

/// A model of PAGED (its root cut), HIERARCHY sharing its ownership.
Model make_paged_model(std::shared_ptr<PagedHierarchy> paged);

/// A model whose cut is the root only (where every strategy can start).
Model make_model(Hierarchy hierarchy);

/// A cut of at least `nodes` nodes (or all leaves), refined breadth-first:
/// a deterministic starting cut of a given size for tests and benchmarks.
TreeCut breadth_first_cut(const Hierarchy& hierarchy, std::size_t nodes);

}  // namespace treecut
