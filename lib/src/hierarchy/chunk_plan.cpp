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
  total_ += points.size();
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

void ChunkPlan::plan(std::uint64_t max_points, int neighbours) {
  // The typical spacing: in the median occupied cell (by points), a surface
  // through it holds its points at about cell / sqrt(count) apart.
  std::vector<std::uint32_t> occupied;
  for (const std::uint32_t c : counts_)
    if (c) occupied.push_back(c);
  float spacing = cell_;
  if (!occupied.empty()) {
    std::sort(occupied.begin(), occupied.end());
    std::uint64_t seen = 0;
    for (const std::uint32_t c : occupied) {
      seen += c;
      if (2 * seen >= total_) {
        spacing = cell_ / std::sqrt(float(c));
        break;
      }
    }
  }
  // k neighbours on a surface lie within about sqrt(k / pi) spacings; four
  // times that covers the points of places 16 times sparser than the median.
  halo_ = std::min(cell_, 4.0f * std::sqrt(float(std::max(neighbours, 1)) / 3.14159265f) * spacing);
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

int ChunkPlan::halo_chunks(glm::vec3 p, std::uint32_t own, std::uint32_t out[26]) const {
  const glm::ivec3 c = cell_of(p);
  const glm::vec3 in = p - (lo_ + glm::vec3(c) * cell_);  // within the cell
  int step[3][3], steps[3];
  for (int a = 0; a < 3; ++a) {
    steps[a] = 0;
    step[a][steps[a]++] = 0;
    if (in[a] < halo_ && c[a] > 0) step[a][steps[a]++] = -1;
    if (cell_ - in[a] < halo_ && c[a] + 1 < dims_) step[a][steps[a]++] = 1;
  }
  int found = 0;
  for (int i = 0; i < steps[0]; ++i)
    for (int j = 0; j < steps[1]; ++j)
      for (int k = 0; k < steps[2]; ++k) {
        if (i == 0 && j == 0 && k == 0) continue;
        const glm::ivec3 d(step[0][i], step[1][j], step[2][k]);
        // The neighbour cell's nearest point must be within the halo.
        float d2 = 0.0f;
        for (int a = 0; a < 3; ++a) {
          const float gap = d[a] < 0 ? in[a] : d[a] > 0 ? cell_ - in[a] : 0.0f;
          d2 += gap * gap;
        }
        if (d2 > halo_ * halo_) continue;
        const std::uint32_t chunk = counts_[index(c + d)];
        if (chunk == kNoChunk || chunk == own) continue;
        if (std::find(out, out + found, chunk) == out + found) out[found++] = chunk;
      }
  return found;
}

bool ChunkPlan::covers(std::uint32_t c, glm::vec3 p, float r) const {
  const Chunk& k = chunks_[c];
  const glm::vec3 lo = lo_ + glm::vec3(k.lo) * cell_ - halo_;
  const glm::vec3 hi = lo_ + glm::vec3(k.hi) * cell_ + halo_;
  // The grid's outer faces hold nothing beyond them (a point outside the
  // box counts in the nearest cell): no neighbour can lie past them.
  for (int a = 0; a < 3; ++a) {
    if (k.lo[a] > 0 && p[a] - r < lo[a]) return false;
    if (k.hi[a] < dims_ && p[a] + r > hi[a]) return false;
  }
  return true;
}

}  // namespace treecut::detail
