// k-nearest-neighbour queries over a uniform grid sized for surfaces: the cell
// edge is chosen so that occupied cells hold a few points each, whatever the
// bounding volume. Read-only after construction, so queries run in parallel.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <glm/common.hpp>
#include <glm/vec3.hpp>
#include <span>
#include <vector>

#include "treecut/parallel.hpp"

namespace treecut::detail {

class KnnGrid {
 public:
  /// About POINTS_PER_CELL in an occupied cell: as many as the neighbours
  /// asked for by default (12), so that the k-th nearest usually lies within
  /// the 27 cells gathered (with 5, one query in 22 of a survey tile was
  /// searched again cell by cell).
  explicit KnnGrid(std::span<const glm::vec3> points, float points_per_cell = 12.0f);

  /// The (up to) k nearest points to points[self] within REACH, self
  /// excluded, nearest first (as near: by position, `before`). Writes
  /// indices and squared distances; returns how many were found. Exact
  /// within the reach, whatever the grid (so the same in any set holding
  /// the point's surroundings within it), but for two guards against
  /// degenerate input: cells holding hundreds of coincident points are
  /// scanned partially, and no search goes past 64 cells.
  int query(std::uint32_t self, int k, std::uint32_t* index, float* dist2,
            float reach = INFINITY) const;

  /// Calls fn(i, p, found, near, dist2) once for every point i (at p) with
  /// the positions of its (up to) k nearest neighbours, nearest first, from
  /// several threads. Points of one cell share one gathered candidate list
  /// (the 27 surrounding cells), which answers most queries from contiguous
  /// memory; the rest fall back to query(). Only points below QUERIED are
  /// asked for (the others are neighbours only: a chunk's halo); neighbours
  /// within REACH, as query() finds them.
  template <class Fn>
  void for_each_knn(int k, Fn&& fn, std::uint32_t queried = 0xffffffffu,
                    float reach = INFINITY) const;

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
    std::vector<std::uint64_t> keys;  // top_k's (distance, candidate) pairs
  };
  // Whether a neighbour at squared distance D and position P comes before
  // one at E and Q: nearer, or as near and lower in x, then y, then z. Ties
  // go by position, not by index, so that a point's neighbours and their
  // order are the same in any set that holds them (a chunk and its halo,
  // or the whole model: chunked_build.hpp).
  static bool before(float d, glm::vec3 p, float e, glm::vec3 q) {
    if (d != e) return d < e;
    if (p.x != q.x) return p.x < q.x;
    if (p.y != q.y) return p.y < q.y;
    return p.z < q.z;
  }
  // Exact top-k over gathered candidates within the reach: their squared
  // distances and positions; returns how many were found. GUESS2 (0: none)
  // is where the k-th is expected; it is set for the next query.
  static int top_k(glm::vec3 q, std::uint32_t self, int k, float reach2, float& guess2,
                   Candidates& c, float* dist2, glm::vec3* near);
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
void KnnGrid::for_each_knn(int k, Fn&& fn, std::uint32_t queried, float reach) const {
  const auto kk = static_cast<std::size_t>(std::max(k, 1));
  parallel_for(
      runs_.size(),
      [&](std::size_t b, std::size_t e) {
        Candidates cand;
        std::vector<std::uint32_t> index(kk);
        std::vector<float> dist2(kk);
        std::vector<glm::vec3> near(kk);
        float guess2 = 0.0f;
        for (std::size_t c = b; c < e; ++c) {
          const Cell& run = runs_[c];
          const glm::ivec3 cell = cell_of(sorted_[run.begin]);
          gather(cell, cand);
          for (std::uint32_t j = run.begin; j < run.end; ++j) {
            const std::uint32_t i = order_[j];
            if (i >= queried) continue;
            const glm::vec3 p = sorted_[j];
            int found = top_k(p, i, k, reach * reach, guess2, cand, dist2.data(), near.data());
            // Exact when the k-th lies within the gathered cells, or when
            // they hold everything within the reach.
            const float r = this->reach(p, cell, 1);
            if (found < k ? r < reach : dist2[kk - 1] > r * r) {
              found = query(i, k, index.data(), dist2.data(), reach);
              for (int f = 0; f < found; ++f) near[std::size_t(f)] = points_[index[std::size_t(f)]];
            }
            fn(i, p, found, static_cast<const glm::vec3*>(near.data()),
               static_cast<const float*>(dist2.data()));
          }
        }
      },
      0, 64);
}

}  // namespace treecut::detail
