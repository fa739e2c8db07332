// k-nearest-neighbour queries over a uniform grid sized for surfaces: the cell
// edge is chosen so that occupied cells hold a few points each, whatever the
// bounding volume. Read-only after construction, so queries run in parallel.
#pragma once

#include <algorithm>
#include <cstdint>
#include <glm/common.hpp>
#include <glm/vec3.hpp>
#include <span>
#include <vector>

#include "treecut/parallel.hpp"

namespace treecut::detail {

class KnnGrid {
 public:
  explicit KnnGrid(std::span<const glm::vec3> points, float points_per_cell = 5.0f);

  /// The (up to) k nearest points to points[self], self excluded, nearest
  /// first. Writes indices and squared distances; returns how many were found.
  /// Cells holding hundreds of coincident points are scanned partially, which
  /// bounds the cost on degenerate input (all points at one place).
  int query(std::uint32_t self, int k, std::uint32_t* index, float* dist2) const;

  /// Calls fn(i, found, index, dist2) once for every point i with its (up to)
  /// k nearest neighbours, nearest first, from several threads. Points of one
  /// cell share one gathered candidate list (the 27 surrounding cells), which
  /// answers most queries from contiguous memory; the rest fall back to query().
  /// Only points below QUERIED are asked for (the others are neighbours
  /// only: a chunk's halo).
  template <class Fn>
  void for_each_knn(int k, Fn&& fn, std::uint32_t queried = 0xffffffffu) const;

 private:
  struct Cell {
    std::uint64_t key;
    std::uint32_t begin, end;
  };
  std::uint64_t key_of(glm::ivec3 c) const;
  glm::ivec3 cell_of(glm::vec3 p) const;
  const Cell* find(std::uint64_t key) const;
  void bucket(float cell_size);

  // Candidates gathered from the 27 cells around one cell, structure of
  // arrays so that the distance loop vectorizes.
  struct Candidates {
    std::vector<float> x, y, z, d2;
    std::vector<std::uint32_t> index;
  };
  // Exact top-k over gathered candidates; returns how many were found.
  static int top_k(glm::vec3 q, std::uint32_t self, int k, Candidates& c, std::uint32_t* index,
                   float* dist2);
  // Distance from p to the outside of the cube of cells within `r` of its cell.
  float reach(glm::vec3 p, glm::ivec3 cell, int r) const;
  void gather(glm::ivec3 cell, Candidates& c) const;

  std::span<const glm::vec3> points_;
  glm::vec3 origin_{0.0f};
  float cell_ = 1.0f;
  glm::ivec3 dims_{1};
  std::vector<std::uint32_t> order_;
  std::vector<glm::vec3> sorted_;  // points_ in order_ order
  std::vector<Cell> table_;        // open addressing, capacity a power of two
  std::vector<Cell> runs_;         // the occupied cells in key order
  std::uint64_t mask_ = 0;
  std::size_t occupied_ = 0;
};

template <class Fn>
void KnnGrid::for_each_knn(int k, Fn&& fn, std::uint32_t queried) const {
  const auto kk = static_cast<std::size_t>(std::max(k, 1));
  parallel_for(
      runs_.size(),
      [&](std::size_t b, std::size_t e) {
        Candidates cand;
        std::vector<std::uint32_t> index(kk);
        std::vector<float> dist2(kk);
        for (std::size_t c = b; c < e; ++c) {
          const Cell& run = runs_[c];
          const glm::ivec3 cell = cell_of(points_[order_[run.begin]]);
          gather(cell, cand);
          for (std::uint32_t j = run.begin; j < run.end; ++j) {
            const std::uint32_t i = order_[j];
            if (i >= queried) continue;
            int found = top_k(points_[i], i, k, cand, index.data(), dist2.data());
            const float r = reach(points_[i], cell, 1);
            if (found < k || dist2[kk - 1] > r * r) found = query(i, k, index.data(), dist2.data());
            fn(i, found, static_cast<const std::uint32_t*>(index.data()),
               static_cast<const float*>(dist2.data()));
          }
        }
      },
      0, 64);
}

}  // namespace treecut::detail
