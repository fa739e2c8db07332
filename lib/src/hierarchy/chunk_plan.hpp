// Where the chunked build cuts a model (issue 44, item 2; PotreeConverter
// 2's counting pass: Schütz, Ohrhallinger and Wimmer 2020, "Fast Out-of-Core
// Octree Generation for Massive Point Clouds", section 4.1): the points
// counted on a grid of cubic cells over the model's box, then an octree
// over the grid whose nodes of at most a chunk's points (or single cells)
// are the chunks. A point belongs to the chunk of its cell, and lies in
// the halo of every other chunk whose box is within `halo` of it: with the
// neighbour search's reach as the halo (NeighbourReach, attributes.hpp), a
// chunk holds every neighbour its points have in the whole model.
// Private to the library.
#pragma once

#include <cstdint>
#include <glm/vec3.hpp>
#include <span>
#include <vector>

namespace treecut::detail {

class ChunkPlan {
 public:
  /// A grid of 2^LEVELS cells an axis over the cube around [LO, HI].
  ChunkPlan(glm::vec3 lo, glm::vec3 hi, int levels);

  /// Counts POINTS into the grid (a point outside the box counts in the
  /// nearest cell).
  void count(std::span<const glm::vec3> points);

  /// Cuts the grid into chunks of at most MAX_POINTS (a single cell may hold
  /// more: it is one chunk), with halos HALO wide.
  void plan(std::uint64_t max_points, float halo);

  struct Chunk {
    glm::ivec3 lo, hi;  ///< its cells, [lo, hi)
    std::uint64_t points = 0;
  };
  [[nodiscard]] const std::vector<Chunk>& chunks() const { return chunks_; }
  [[nodiscard]] float halo() const { return halo_; }

  /// P's chunk.
  [[nodiscard]] std::uint32_t chunk_of(glm::vec3 p) const;
  /// The chunks other than OWN whose boxes lie within the halo of P, into
  /// OUT (cleared first).
  void halo_chunks(glm::vec3 p, std::uint32_t own, std::vector<std::uint32_t>& out) const;

 private:
  [[nodiscard]] glm::ivec3 cell_of(glm::vec3 p) const;
  [[nodiscard]] std::size_t index(glm::ivec3 c) const {
    return (std::size_t(c.z) * std::size_t(dims_) + std::size_t(c.y)) * std::size_t(dims_) +
           std::size_t(c.x);
  }
  void split(glm::ivec3 lo, int size, std::uint64_t max_points);

  glm::vec3 lo_;
  float cell_;
  int dims_;
  std::vector<std::uint32_t> counts_;  // per cell; then, planned, each cell's chunk
  std::vector<Chunk> chunks_;
  float halo_ = 0.0f;
};

}  // namespace treecut::detail
