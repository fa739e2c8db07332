// The chunks of a chunked build (chunk_plan.hpp).
#include "chunk_plan.hpp"

#include <algorithm>
#include <cmath>
#include <glm/common.hpp>

namespace treecut::detail {

namespace {
constexpr std::uint32_t kNoChunk = 0xffffffffu;
}

ChunkPlan::ChunkPlan(glm::vec3 lo, glm::vec3 hi, int levels) : lo_(lo), dims_(1 << levels) {
  const glm::vec3 extent = glm::max(hi - lo, glm::vec3(0.0f));
  // A little wider than the box, so that its far faces fall inside the grid.
  const float side = std::max({extent.x, extent.y, extent.z, 1e-6f}) * (1.0f + 1e-5f);
  cell_ = side / float(dims_);
  counts_.assign(std::size_t(dims_) * std::size_t(dims_) * std::size_t(dims_), 0);
}

glm::ivec3 ChunkPlan::cell_of(glm::vec3 p) const {
  const glm::vec3 c = glm::floor((p - lo_) / cell_);
  return glm::ivec3(glm::clamp(c, glm::vec3(0.0f), glm::vec3(float(dims_ - 1))));
}

void ChunkPlan::count(std::span<const glm::vec3> points) {
  for (const glm::vec3& p : points) ++counts_[index(cell_of(p))];
}

void ChunkPlan::split(glm::ivec3 lo, int size, std::uint64_t max_points) {
  std::uint64_t sum = 0;
  for (int z = lo.z; z < lo.z + size; ++z)
    for (int y = lo.y; y < lo.y + size; ++y)
      for (int x = lo.x; x < lo.x + size; ++x) sum += counts_[index({x, y, z})];
  if (sum == 0) return;
  if (sum > max_points && size > 1) {
    const int half = size / 2;
    for (int k = 0; k < 8; ++k)
      split(lo + glm::ivec3(k & 1, (k >> 1) & 1, k >> 2) * half, half, max_points);
    return;
  }
  chunks_.push_back({lo, lo + size, sum});
}

void ChunkPlan::plan(std::uint64_t max_points, float halo) {
  halo_ = halo;
  chunks_.clear();
  split(glm::ivec3(0), dims_, std::max<std::uint64_t>(max_points, 1));
  // From counts to chunk ids (empty cells too: a chunk's box is whole).
  std::fill(counts_.begin(), counts_.end(), kNoChunk);
  for (std::uint32_t k = 0; k < chunks_.size(); ++k) {
    const Chunk& c = chunks_[k];
    for (int z = c.lo.z; z < c.hi.z; ++z)
      for (int y = c.lo.y; y < c.hi.y; ++y)
        for (int x = c.lo.x; x < c.hi.x; ++x) counts_[index({x, y, z})] = k;
  }
}

std::uint32_t ChunkPlan::chunk_of(glm::vec3 p) const {
  return counts_[index(cell_of(p))];
}

void ChunkPlan::halo_chunks(glm::vec3 p, std::uint32_t own, std::vector<std::uint32_t>& out) const {
  out.clear();
  const glm::ivec3 c = cell_of(p);
  const glm::vec3 in = p - (lo_ + glm::vec3(c) * cell_);  // within the cell
  // The cells within the halo: the neighbours on the sides it reaches
  // (usually one; more where the halo is wider than a cell).
  const int r = static_cast<int>(std::ceil(halo_ / cell_));
  glm::ivec3 lo, hi;
  for (int a = 0; a < 3; ++a) {
    lo[a] = std::max(0, c[a] - (in[a] < halo_ ? r : 0));
    hi[a] = std::min(dims_ - 1, c[a] + (cell_ - in[a] < halo_ ? r : 0));
  }
  for (int z = lo.z; z <= hi.z; ++z)
    for (int y = lo.y; y <= hi.y; ++y)
      for (int x = lo.x; x <= hi.x; ++x) {
        const glm::ivec3 n(x, y, z);
        if (n == c) continue;
        // The cell's nearest point must lie within the halo.
        float d2 = 0.0f;
        for (int a = 0; a < 3; ++a) {
          const float cell_lo = lo_[a] + float(n[a]) * cell_, cell_hi = cell_lo + cell_;
          const float gap = p[a] < cell_lo   ? cell_lo - p[a]
                            : p[a] > cell_hi ? p[a] - cell_hi
                                             : 0.0f;
          d2 += gap * gap;
        }
        if (d2 > halo_ * halo_) continue;
        const std::uint32_t chunk = counts_[index(n)];
        if (chunk == kNoChunk || chunk == own) continue;
        if (std::find(out.begin(), out.end(), chunk) == out.end()) out.push_back(chunk);
      }
}

}  // namespace treecut::detail
