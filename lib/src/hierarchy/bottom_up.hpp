// The builder's bottom-up pass over a hierarchy's interior nodes: level by
// level from the deepest, so a node's children are final when it is filled,
// the nodes of one level in parallel (hierarchy.cpp's spheres, cones and
// colours; node_attributes.cpp's summaries). Private to the builder.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>

#include "treecut/hierarchy.hpp"
#include "treecut/parallel.hpp"

namespace treecut::detail {

/// Calls FILL(i) for every node i with children, deepest level first, then
/// AFTER_LEVEL() once a level is done.
template <class Fill, class AfterLevel>
void for_each_interior_bottom_up(std::span<const NodeId> level_begin,
                                 std::span<const std::uint8_t> child_count, unsigned threads,
                                 Fill&& fill, AfterLevel&& after_level) {
  const int levels = static_cast<int>(level_begin.size()) - 1;
  for (int d = levels - 1; d >= 0; --d) {
    const std::size_t lb = level_begin[static_cast<std::size_t>(d)];
    const std::size_t le = level_begin[static_cast<std::size_t>(d) + 1];
    parallel_for(
        le - lb,
        [&](std::size_t b, std::size_t e) {
          for (std::size_t i = lb + b; i < lb + e; ++i) {
            if (child_count[i] != 0) fill(i);
          }
        },
        threads, 256);
    after_level();
  }
}

}  // namespace treecut::detail
