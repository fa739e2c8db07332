// What a block draws at its level and the box around it: shared by the
// blocks built at once (hlod_blocks.cpp) and those made as a traversal
// reaches them (resident_blocks.cpp), so both draw the same nodes.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "treecut/culling/box.hpp"
#include "treecut/hierarchy.hpp"

namespace treecut::culling {

/// The representation of a block whose subtrees are rooted at ROOTS, into
/// OUT: for a leaf block (their leaves <= LIMIT) every leaf of them, else
/// the roots refined in id order (ids are breadth-first: the biggest splats
/// first) while the node count stays <= LIMIT. The first node that does not
/// fit ends the refinement, so the cut stays breadth-first instead of
/// refining small nodes deep in one corner. HIDDEN (may be null) receives
/// the nodes of OUT the walk would have gone on below had their children
/// been resident (Hierarchy::is_hidden). QUEUE is scratch.
void collect_representation(const Hierarchy& h, std::span<const NodeId> roots, std::uint32_t limit,
                            std::vector<NodeId>& queue, std::vector<NodeId>& out,
                            std::vector<NodeId>* hidden);

/// The box of a representation: its splats' spheres, widened for the
/// descendants that may reach past them.
Box representation_box(const HierarchyArrays& a, std::span<const NodeId> rep);

}  // namespace treecut::culling
