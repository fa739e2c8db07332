// The whole's ids of a hierarchy built in chunks (whole_ids.hpp).
#include "whole_ids.hpp"

#include <utility>

namespace treecut::detail {

using cache_layout::PageRun;

WholeIds::WholeIds(const TopLevels* top, std::span<const std::vector<std::uint64_t>> chunk_levels,
                   std::span<const std::uint32_t> chunk_depth)
    : chunk_levels_(chunk_levels), chunk_depth_(chunk_depth), chunk_base_(chunk_levels.size()) {
  // Level by level, as the decoder of a whole hierarchy numbers it: each
  // item a node of the top, or one level of one chunk.
  struct Item {
    NodeId top;  // a node of the top, or kNoNode: LEVEL of CHUNK
    std::uint32_t chunk, level;
  };
  std::vector<Item> level{top ? Item{0, 0, 0} : Item{kNoNode, 0, 0}}, next;
  if (top) top_id_.assign(top->hierarchy.node_count(), kNoNode);
  std::uint64_t id = 0;
  while (!level.empty()) {
    level_begin_.push_back(id);
    next.clear();
    for (const Item& it : level) {
      if (it.top == kNoNode) {
        const std::vector<std::uint64_t>& lb = chunk_levels_[it.chunk];
        chunk_base_[it.chunk].push_back(id);
        id += lb[it.level + 1] - lb[it.level];
        if (it.level + 2 < lb.size()) next.push_back({kNoNode, it.chunk, it.level + 1});
        continue;
      }
      const Hierarchy& t = top->hierarchy;
      top_id_[it.top] = static_cast<NodeId>(id++);
      for (NodeId c = t.first_child(it.top); c < t.first_child(it.top) + t.child_count(it.top); ++c)
        next.push_back(t.is_leaf(c) ? Item{kNoNode, top->root_of[c], 0} : Item{c, 0, 0});
    }
    std::swap(level, next);
  }
  level_begin_.push_back(id);
}

std::vector<PageRun> WholeIds::chunk_runs(std::size_t c, std::span<const PageRun> runs) const {
  std::vector<PageRun> out(runs.begin(), runs.end());
  for (PageRun& r : out) {
    r.first = chunk_base_[c][r.depth] + (r.first - chunk_levels_[c][r.depth]);
    r.depth += chunk_depth_[c];
  }
  return out;
}

std::vector<PageRun> WholeIds::top_runs(std::span<const PageRun> runs) const {
  std::vector<PageRun> out;
  for (const PageRun& r : runs)
    for (std::uint64_t i = r.first; i < r.first + r.count; ++i) {
      const NodeId id = top_id_[i];
      if (!out.empty() && out.back().first + out.back().count == id && out.back().depth == r.depth)
        ++out.back().count;
      else
        out.push_back({id, 1, r.depth});
    }
  return out;
}

}  // namespace treecut::detail
