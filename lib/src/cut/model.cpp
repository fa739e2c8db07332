#include "treecut/model.hpp"

namespace treecut {

Model make_model(Hierarchy hierarchy) {
  auto h = std::make_shared<const Hierarchy>(std::move(hierarchy));
  TreeCut cut = TreeCut::root_cut(*h);
  return Model{std::move(h), std::move(cut), nullptr};
}

Model make_paged_model(std::shared_ptr<PagedHierarchy> paged) {
  std::shared_ptr<const Hierarchy> h(paged, &paged->hierarchy());
  TreeCut cut = TreeCut::root_cut(*h);
  return Model{std::move(h), std::move(cut), std::move(paged)};
}

TreeCut breadth_first_cut(const Hierarchy& hierarchy, std::size_t nodes) {
  TreeCut cut = TreeCut::root_cut(hierarchy);
  // Ids are breadth-first, so when node `id` is reached every inner node with
  // a smaller id has been refined and `id` itself is in the cut.
  for (NodeId id = 0; id < hierarchy.node_count() && cut.size() < nodes; ++id) {
    if (!hierarchy.is_leaf(id)) cut.refine(hierarchy, id);
  }
  return cut;
}

}  // namespace treecut
