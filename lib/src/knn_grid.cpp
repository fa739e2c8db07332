#include "knn_grid.hpp"

#include <algorithm>
#include <cmath>
#include <glm/common.hpp>
#include <numeric>

#include "treecut/parallel.hpp"

namespace treecut::detail {

namespace {

constexpr int kAxisBits = 21;
constexpr int kMaxDim = (1 << kAxisBits) - 2;
constexpr std::uint32_t kMaxScanPerCell = 512;
// Shells searched at most: with a few points per occupied cell the k nearest
// are found within 2-3 shells; an isolated outlier stops here with fewer.
constexpr int kMaxShell = 8;

std::uint64_t mix(std::uint64_t x) {  // splitmix64 finalizer
  x ^= x >> 30;
  x *= 0xbf58476d1ce4e5b9ull;
  x ^= x >> 27;
  x *= 0x94d049bb133111ebull;
  return x ^ (x >> 31);
}

}  // namespace

KnnGrid::KnnGrid(std::span<const glm::vec3> points, float points_per_cell) : points_(points) {
  const std::size_t n = points.size();
  glm::vec3 lo(INFINITY), hi(-INFINITY);
  for (const auto& p : points) lo = glm::min(lo, p), hi = glm::max(hi, p);
  if (n == 0) lo = hi = glm::vec3(0.0f);
  origin_ = lo;
  const glm::vec3 ext = hi - lo;
  const float longest = std::max({ext.x, ext.y, ext.z});
  if (!(longest > 0.0f)) {  // every point at one place: one cell
    bucket(1.0f);
    return;
  }
  // First guess as if the points filled the box, then correct for points on a
  // surface, where occupied cells scale with the square of the cell size.
  const glm::vec3 e = glm::max(ext, glm::vec3(longest * 1e-3f));
  float cell = std::cbrt(e.x * e.y * e.z * points_per_cell / static_cast<float>(n));
  const float min_cell = longest / static_cast<float>(kMaxDim);
  cell = std::max(cell, min_cell);
  bucket(cell);
  const float per_cell = static_cast<float>(n) / static_cast<float>(std::max<std::size_t>(occupied_, 1));
  if (per_cell > 2.0f * points_per_cell) bucket(std::max(min_cell, cell * std::sqrt(points_per_cell / per_cell)));
}

glm::ivec3 KnnGrid::cell_of(glm::vec3 p) const {
  const glm::vec3 f = (p - origin_) / cell_;
  return glm::clamp(glm::ivec3(glm::floor(f)), glm::ivec3(0), dims_ - 1);
}

std::uint64_t KnnGrid::key_of(glm::ivec3 c) const {
  return (static_cast<std::uint64_t>(c.x) << (2 * kAxisBits)) |
         (static_cast<std::uint64_t>(c.y) << kAxisBits) | static_cast<std::uint64_t>(c.z);
}

void KnnGrid::bucket(float cell_size) {
  const std::size_t n = points_.size();
  cell_ = cell_size;
  glm::vec3 hi(-INFINITY);
  for (const auto& p : points_) hi = glm::max(hi, p);
  if (n == 0) hi = origin_;
  dims_ = glm::clamp(glm::ivec3(glm::floor((hi - origin_) / cell_)) + 1, glm::ivec3(1), glm::ivec3(kMaxDim));

  std::vector<std::uint64_t> keys(n);
  parallel_for(n, [&](std::size_t b, std::size_t e) {
    for (std::size_t i = b; i < e; ++i) keys[i] = key_of(cell_of(points_[i]));
  });
  order_.resize(n);
  std::iota(order_.begin(), order_.end(), 0u);
  std::sort(order_.begin(), order_.end(), [&](std::uint32_t a, std::uint32_t b) {
    return keys[a] < keys[b] || (keys[a] == keys[b] && a < b);
  });

  occupied_ = 0;
  for (std::size_t i = 0; i < n; ++i)
    if (i == 0 || keys[order_[i]] != keys[order_[i - 1]]) ++occupied_;
  std::size_t cap = 16;
  while (cap < 2 * occupied_) cap <<= 1;
  table_.assign(cap, Cell{~0ull, 0, 0});
  mask_ = cap - 1;
  for (std::size_t i = 0; i < n;) {
    const std::uint64_t k = keys[order_[i]];
    std::size_t j = i + 1;
    while (j < n && keys[order_[j]] == k) ++j;
    std::uint64_t h = mix(k) & mask_;
    while (table_[h].key != ~0ull) h = (h + 1) & mask_;
    table_[h] = Cell{k, static_cast<std::uint32_t>(i), static_cast<std::uint32_t>(j)};
    i = j;
  }
}

const KnnGrid::Cell* KnnGrid::find(std::uint64_t key) const {
  for (std::uint64_t h = mix(key) & mask_;; h = (h + 1) & mask_) {
    const Cell& c = table_[h];
    if (c.key == key) return &c;
    if (c.key == ~0ull) return nullptr;
  }
}

int KnnGrid::query(std::uint32_t self, int k, std::uint32_t* index, float* dist2) const {
  if (k <= 0) return 0;
  const glm::vec3 q = points_[self];
  const glm::ivec3 c = cell_of(q);
  int found = 0;
  auto consider = [&](std::uint32_t i) {
    if (i == self) return;
    const glm::vec3 d = points_[i] - q;
    const float d2 = d.x * d.x + d.y * d.y + d.z * d.z;
    if (found == k && d2 >= dist2[k - 1]) return;
    int pos = found < k ? found++ : k - 1;
    while (pos > 0 && dist2[pos - 1] > d2) {
      dist2[pos] = dist2[pos - 1];
      index[pos] = index[pos - 1];
      --pos;
    }
    dist2[pos] = d2;
    index[pos] = i;
  };
  auto scan = [&](glm::ivec3 cc) {
    if (glm::any(glm::lessThan(cc, glm::ivec3(0))) || glm::any(glm::greaterThanEqual(cc, dims_))) return;
    const Cell* cell = find(key_of(cc));
    if (!cell) return;
    const std::uint32_t end = std::min(cell->end, cell->begin + kMaxScanPerCell);
    for (std::uint32_t j = cell->begin; j < end; ++j) consider(order_[j]);
  };
  const int max_r = std::min(kMaxShell, std::max({dims_.x, dims_.y, dims_.z}));
  for (int r = 0; r <= max_r; ++r) {
    for (int dz = -r; dz <= r; ++dz)
      for (int dy = -r; dy <= r; ++dy) {
        const bool face = std::abs(dz) == r || std::abs(dy) == r;
        if (face) {
          for (int dx = -r; dx <= r; ++dx) scan(c + glm::ivec3(dx, dy, dz));
        } else {  // interior rows of the shell: only its two ends
          scan(c + glm::ivec3(-r, dy, dz));
          if (r) scan(c + glm::ivec3(r, dy, dz));
        }
      }
    // Every point outside shells 0..r is at least r cells away.
    const float reach = static_cast<float>(r) * cell_;
    if (found == k && dist2[k - 1] <= reach * reach) break;
  }
  return found;
}

}  // namespace treecut::detail
