// The ids of a hierarchy built in chunks (chunked_build.cpp, issue 44) as a
// hierarchy built at once has them (breadth-first): what each page's runs
// say in the cache (format 10, issue 45), computed from the chunks' levels
// and the levels over them without holding a node of either. A level's ids
// are the top's nodes of that depth and each chunk's, in the order their
// parents have; a chunk's nodes of one depth are consecutive there, in its
// own order. Private to the library.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "cache_layout.hpp"
#include "subtree_roots.hpp"

namespace treecut::detail {

class WholeIds {
 public:
  /// TOP: the levels over the chunks' roots (null for a single chunk);
  /// CHUNK_LEVELS: each chunk's own level_begin (its node count last);
  /// CHUNK_DEPTH: the depth of each chunk's root in the whole.
  WholeIds(const TopLevels* top, std::span<const std::vector<std::uint64_t>> chunk_levels,
           std::span<const std::uint32_t> chunk_depth);

  /// The whole's levels' first ids, and its node count last.
  [[nodiscard]] const std::vector<std::uint64_t>& level_begin() const { return level_begin_; }
  /// RUNS of chunk C's page (in the chunk's ids and depths) in the whole's.
  [[nodiscard]] std::vector<cache_layout::PageRun> chunk_runs(
      std::size_t c, std::span<const cache_layout::PageRun> runs) const;
  /// RUNS of a page of the top (in its ids) in the whole's: the chunks'
  /// nodes lie between the top's of a level, so a run may part.
  [[nodiscard]] std::vector<cache_layout::PageRun> top_runs(
      std::span<const cache_layout::PageRun> runs) const;

 private:
  std::span<const std::vector<std::uint64_t>> chunk_levels_;
  std::span<const std::uint32_t> chunk_depth_;
  std::vector<std::uint64_t> level_begin_;
  std::vector<NodeId> top_id_;                          // each top node's id in the whole
  std::vector<std::vector<std::uint64_t>> chunk_base_;  // where each chunk's levels start
};

}  // namespace treecut::detail
