// k-nearest-neighbour queries over a uniform grid sized for surfaces: the cell
// edge is chosen so that occupied cells hold a few points each, whatever the
// bounding volume. Read-only after construction, so queries run in parallel.
#pragma once

#include <cstdint>
#include <glm/vec3.hpp>
#include <span>
#include <vector>

namespace treecut::detail {

class KnnGrid {
 public:
  explicit KnnGrid(std::span<const glm::vec3> points, float points_per_cell = 3.0f);

  /// The (up to) k nearest points to points[self], self excluded, nearest
  /// first. Writes indices and squared distances; returns how many were found.
  /// Cells holding hundreds of coincident points are scanned partially, which
  /// bounds the cost on degenerate input (all points at one place).
  int query(std::uint32_t self, int k, std::uint32_t* index, float* dist2) const;

  /// Points in grid order (cell by cell): iterate in this order for locality.
  [[nodiscard]] std::span<const std::uint32_t> order() const { return order_; }

 private:
  struct Cell {
    std::uint64_t key;
    std::uint32_t begin, end;
  };
  std::uint64_t key_of(glm::ivec3 c) const;
  glm::ivec3 cell_of(glm::vec3 p) const;
  const Cell* find(std::uint64_t key) const;
  void bucket(float cell_size);

  std::span<const glm::vec3> points_;
  glm::vec3 origin_{0.0f};
  float cell_ = 1.0f;
  glm::ivec3 dims_{1};
  std::vector<std::uint32_t> order_;
  std::vector<Cell> table_;  // open addressing, capacity a power of two
  std::uint64_t mask_ = 0;
  std::size_t occupied_ = 0;
};

}  // namespace treecut::detail
