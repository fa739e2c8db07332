#include "knn_grid.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <glm/common.hpp>
#include <numeric>

#include "support/radix_sort.hpp"
#include "treecut/mix64.hpp"
#include "treecut/parallel.hpp"

namespace treecut::detail {

namespace {

constexpr int kAxisBits = 21;
constexpr int kMaxDim = (1 << kAxisBits) - 2;
constexpr std::uint32_t kMaxScanPerCell = 512;
// Shells searched at most: with a few points per occupied cell the k nearest
// are found within 2-3 shells, and a reach of a few spacings is a few cells;
// only a reach past 64 cells (a dense spot in a sparse model) stops here.
constexpr int kMaxShell = 64;

template <class T>
void release_keys(std::vector<T>& v) {
  std::vector<T>().swap(v);
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
  // Every point at one place, or so close (denormal extents) that the
  // smallest cell size underflows to 0: one cell.
  if (!(longest / static_cast<float>(kMaxDim) > 0.0f)) {
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
  const float per_cell =
      static_cast<float>(n) / static_cast<float>(std::max<std::size_t>(occupied_, 1));
  if (per_cell > 2.0f * points_per_cell)
    bucket(std::max(min_cell, cell * std::sqrt(points_per_cell / per_cell)));
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
  dims_ = glm::clamp(glm::ivec3(glm::floor((hi - origin_) / cell_)) + 1, glm::ivec3(1),
                     glm::ivec3(kMaxDim));

  // Points sorted by cell, x then y then z, ties by index (a stable radix
  // sort over (cell, index) pairs): the order is deterministic. The cell's
  // number in the box, not its key, so the sort takes a few 11-bit digits.
  const std::uint64_t cells =
      std::uint64_t(dims_.x) * std::uint64_t(dims_.y) * std::uint64_t(dims_.z);
  const auto linear = [&](glm::ivec3 c) {
    return (std::uint64_t(c.x) * std::uint64_t(dims_.y) + std::uint64_t(c.y)) *
               std::uint64_t(dims_.z) +
           std::uint64_t(c.z);
  };
  std::vector<std::pair<std::uint64_t, std::uint32_t>> keyed;
  std::vector<std::uint64_t> packed;  // cell << 32 | index, while cells fit 32 bits
  if (cells <= 0xffffffffull) {
    packed.resize(n);
    parallel_for(n, [&](std::size_t b, std::size_t e) {
      for (std::size_t i = b; i < e; ++i) packed[i] = linear(cell_of(points_[i])) << 32 | i;
    });
    std::vector<std::uint64_t> scratch;
    radix_sort(packed, 32, static_cast<unsigned>(std::bit_width(cells - 1)), scratch);
  } else {  // a huge sparse box: a comparison sort
    keyed.resize(n);
    parallel_for(n, [&](std::size_t b, std::size_t e) {
      for (std::size_t i = b; i < e; ++i)
        keyed[i] = {linear(cell_of(points_[i])), static_cast<std::uint32_t>(i)};
    });
    std::sort(keyed.begin(), keyed.end());
  }
  const auto entry = [&](std::size_t i) {
    return packed.empty() ? keyed[i] : std::pair{packed[i] >> 32, std::uint32_t(packed[i])};
  };
  order_.resize(n);
  runs_.clear();
  std::uint64_t previous = ~0ull;
  for (std::size_t i = 0; i < n; ++i) {
    const auto [cell, index] = entry(i);
    order_[i] = index;
    if (i == 0 || cell != previous)
      runs_.push_back(Cell{key_of(cell_of(points_[index])), static_cast<std::uint32_t>(i), 0});
    runs_.back().end = static_cast<std::uint32_t>(i + 1);
    previous = cell;
  }
  occupied_ = runs_.size();
  release_keys(keyed);
  release_keys(packed);
  // Positions in grid order: a cell's points are contiguous in memory, so
  // gathering a neighbourhood does not miss the cache once per point.
  sorted_.resize(n);
  parallel_for(n, [&](std::size_t b, std::size_t e) {
    for (std::size_t i = b; i < e; ++i) sorted_[i] = points_[order_[i]];
  });
  std::size_t cap = 16;
  while (cap < 2 * occupied_) cap <<= 1;
  table_.assign(cap, Cell{~0ull, 0, 0});
  mask_ = cap - 1;
  for (const Cell& run : runs_) {
    std::uint64_t h = mix64(run.key) & mask_;
    while (table_[h].key != ~0ull) h = (h + 1) & mask_;
    table_[h] = run;
  }
}

const KnnGrid::Cell* KnnGrid::find(std::uint64_t key) const {
  for (std::uint64_t h = mix64(key) & mask_;; h = (h + 1) & mask_) {
    const Cell& c = table_[h];
    if (c.key == key) return &c;
    if (c.key == ~0ull) return nullptr;
  }
}

// The 27 offsets of a cell's neighbourhood, nearest first: the cell, its 6
// faces, 12 edges and 8 corners.
constexpr std::array<std::array<int, 3>, 27> kNeighbourhood = [] {
  std::array<std::array<int, 3>, 27> out{};
  int n = 0;
  for (int ring = 0; ring <= 3; ++ring)
    for (int dz = -1; dz <= 1; ++dz)
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx)
          if ((dx != 0) + (dy != 0) + (dz != 0) == ring)
            out[static_cast<std::size_t>(n++)] = {dx, dy, dz};
  return out;
}();

void KnnGrid::gather(glm::ivec3 c, Candidates& out) const {
  out.x.clear(), out.y.clear(), out.z.clear(), out.index.clear();
  for (const auto& o : kNeighbourhood) {
    const glm::ivec3 cc = c + glm::ivec3(o[0], o[1], o[2]);
    if (glm::any(glm::lessThan(cc, glm::ivec3(0))) || glm::any(glm::greaterThanEqual(cc, dims_)))
      continue;
    const Cell* cell = find(key_of(cc));
    if (!cell) continue;
    const std::uint32_t end = std::min(cell->end, cell->begin + kMaxScanPerCell);
    for (std::uint32_t j = cell->begin; j < end; ++j) {
      const glm::vec3 p = sorted_[j];
      out.x.push_back(p.x), out.y.push_back(p.y), out.z.push_back(p.z);
      out.index.push_back(order_[j]);
    }
  }
  out.d2.resize(out.x.size());
  out.keys.resize(out.x.size());
}

float KnnGrid::reach(glm::vec3 p, glm::ivec3 c, int r) const {
  const glm::vec3 lo = origin_ + glm::vec3(c - r) * cell_;
  const glm::vec3 hi = origin_ + glm::vec3(c + r + 1) * cell_;
  // Sides of the cube at the grid border have nothing beyond them.
  glm::vec3 below = p - lo, above = hi - p;
  for (int a = 0; a < 3; ++a) {
    if (c[a] - r <= 0) below[a] = INFINITY;
    if (c[a] + r >= dims_[a] - 1) above[a] = INFINITY;
  }
  const glm::vec3 m = glm::min(below, above);
  return std::min({m.x, m.y, m.z});
}

int KnnGrid::top_k(glm::vec3 q, std::uint32_t self, int k, float reach2, float& guess2,
                   Candidates& c, float* dist2, glm::vec3* near) {
  const std::size_t n = c.x.size();
  const float* __restrict x = c.x.data();
  const float* __restrict y = c.y.data();
  const float* __restrict z = c.z.data();
  float* __restrict d2 = c.d2.data();
  for (std::size_t j = 0; j < n; ++j) {  // vectorized
    const float dx = x[j] - q.x, dy = y[j] - q.y, dz = z[j] - q.z;
    d2[j] = dx * dx + dy * dy + dz * dz;
  }
  // The candidates within a bound, as (distance bits, candidate) keys: a
  // non-negative float's bits order as the float does. The bound is a guess
  // from the previous query (a neighbour's k-th distance, widened); when it
  // holds at least k, everything outside it comes after the k-th, so the
  // answer is exact; else it widens. A branchless pass and a sort of a few
  // more than k keys: inserting every candidate that beat the k-th so far
  // into a sorted list made the stage 1.3x slower at k = 12, 1.5x at 24
  // (attributes_bench).
  const std::uint32_t* __restrict ids = c.index.data();
  std::uint64_t* __restrict keys = c.keys.data();
  const auto uk = static_cast<std::size_t>(k);
  float bound = guess2 > 0.0f ? std::min(guess2, reach2) : reach2;
  std::size_t m = 0;
  for (;;) {
    m = 0;
    for (std::size_t j = 0; j < n; ++j) {
      keys[m] = std::uint64_t(std::bit_cast<std::uint32_t>(d2[j])) << 32 | j;
      m += static_cast<std::size_t>((d2[j] <= bound) & (ids[j] != self));
    }
    if (m >= uk || !(bound < reach2)) break;
    bound = std::min(bound * 2.0f, reach2);
  }
  std::sort(keys, keys + m);
  const std::size_t found = std::min(m, uk);
  // As near: by position (`before`), a run of equal distances at a time.
  const auto at = [&](std::uint64_t key) {
    const auto j = static_cast<std::uint32_t>(key);
    return glm::vec3(x[j], y[j], z[j]);
  };
  for (std::size_t a = 0, e = 0; a < found; a = e) {
    for (e = a + 1; e < m && keys[e] >> 32 == keys[a] >> 32;) ++e;
    if (e - a > 1)
      std::sort(keys + a, keys + e,
                [&](std::uint64_t u, std::uint64_t v) { return before(0.0f, at(u), 0.0f, at(v)); });
  }
  for (std::size_t i = 0; i < found; ++i) {
    const auto j = static_cast<std::uint32_t>(keys[i]);
    dist2[i] = d2[j];
    near[i] = glm::vec3(x[j], y[j], z[j]);
  }
  // The next query (a point of the same cell, or the next cell's) expects
  // about this point's spacing: its k-th squared distance and a fifth (the
  // bound doubles where that holds fewer than k; 1.44 sorted more keys).
  guess2 = found == uk ? dist2[uk - 1] * 1.2f : 0.0f;
  return static_cast<int>(found);
}

int KnnGrid::query(std::uint32_t self, int k, std::uint32_t* index, float* dist2,
                   float reach_limit) const {
  if (k <= 0) return 0;
  const glm::vec3 q = points_[self];
  const glm::ivec3 c = cell_of(q);
  const float limit2 = reach_limit * reach_limit;
  int found = 0;
  auto consider = [&](std::uint32_t i) {
    if (i == self) return;
    const glm::vec3 p = points_[i];
    const glm::vec3 d = p - q;
    const float d2 = d.x * d.x + d.y * d.y + d.z * d.z;
    if (d2 > limit2) return;
    if (found == k && !before(d2, p, dist2[k - 1], points_[index[k - 1]])) return;
    int pos = found < k ? found++ : k - 1;
    while (pos > 0 && before(d2, p, dist2[pos - 1], points_[index[pos - 1]])) {
      dist2[pos] = dist2[pos - 1];
      index[pos] = index[pos - 1];
      --pos;
    }
    dist2[pos] = d2;
    index[pos] = i;
  };
  auto scan = [&](glm::ivec3 cc) {
    if (glm::any(glm::lessThan(cc, glm::ivec3(0))) || glm::any(glm::greaterThanEqual(cc, dims_)))
      return;
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
    if ((found == k && dist2[k - 1] <= reach * reach) || reach >= reach_limit) break;
  }
  return found;
}

}  // namespace treecut::detail
