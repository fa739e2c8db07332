// Budgeted LOD selection (Eq. 1 and PET): Peng & Cao, "Integrating Occlusion
// Culling and Parallel LOD for Rendering Complex 3D Environments on GPU",
// I3D 2013 (../shared/papers/occlusion-culling-with-parallel-lod.txt),
// section 5. What the paper says and what is added: budget.hpp.
#include "treecut/strategies/budget.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>

#include "treecut/strategies/optimization.hpp"

namespace treecut::strategies::many {
namespace {

constexpr std::size_t kGrain = 4096;
constexpr double kMinDepth = 1e-6;
// After this many water-filling rounds the rest is settled by one sort
// (rounds are parallel and nearly always few; the sort bounds the worst case).
constexpr std::size_t kMaxRounds = 32;

// An object with a term t_i > 0: its index, P_i and t_i.
struct Active {
  std::uint32_t index;
  std::uint32_t points;
  double term;
};

// Pass 1 over all objects: the terms t_i = w_i^(1/alpha), keeping the
// objects with t_i > 0 (most of a large scene is culled or below PET); the
// rest works on that list. Per-chunk lists and sums are joined in chunk
// order, so nothing depends on the schedule. The objects below PET are
// counted into stats.below_pet.
std::vector<Active> active_objects(std::span<const BudgetItem> items, const BudgetParams& params,
                                   WorkerPool* pool, BudgetStats& stats) {
  const std::size_t m = items.size();
  const std::size_t chunks = WorkerPool::chunk_count(m, kGrain);
  std::vector<std::vector<Active>> found(chunks);
  std::vector<std::size_t> chunk_pet(chunks);
  for_chunks(pool, m, kGrain, [&](std::size_t b, std::size_t e, std::size_t c) {
    std::size_t pet = 0;
    // eq1_term() with log(P_i) kept while P_i repeats (instances of one
    // model: a few distinct values among 48 k visible objects), the same
    // operations otherwise, so the same bits.
    const double beta = params.alpha - 1.0;
    std::uint32_t last_points = 0;
    double log_points = 0.0;
    for (std::size_t i = b; i < e; ++i) {
      const BudgetItem& it = items[i];
      if (!(it.area > 0.0f)) continue;
      if (it.area < params.pet) {
        ++pet;
        continue;
      }
      if (it.points == 0) continue;
      if (it.points != last_points) {
        last_points = it.points;
        log_points = std::log(static_cast<double>(it.points));
      }
      const double depth = std::max(static_cast<double>(it.depth), kMinDepth);
      const double t = std::exp((std::log(it.area / depth) + beta * log_points) / params.alpha);
      if (t > 0.0) found[c].push_back({static_cast<std::uint32_t>(i), it.points, t});
    }
    chunk_pet[c] = pet;
  });
  std::vector<Active> act;
  for (std::size_t c = 0; c < chunks; ++c) {
    act.insert(act.end(), found[c].begin(), found[c].end());
    stats.below_pet += chunk_pet[c];
  }
  return act;
}

// Water filling: an object is capped when lambda * t_i >= P_i; the capped
// points leave the budget and their terms the sum. Every round caps all
// objects above the current lambda, which only grows, so the capped set
// only grows and the rounds end. Marks `capped`, counts the rounds and the
// capped objects into stats; returns the final lambda.
// Inlined, as are the shares below: allocate_budget is benchmarked, and
// this keeps its code one function's, as before it was split.
[[gnu::always_inline]] inline double water_fill(const std::vector<Active>& act,
                                                const BudgetParams& params,
                                                std::vector<std::uint8_t>& capped,
                                                BudgetStats& stats) {
  const std::size_t a = act.size();
  double sum = 0.0;
  for (const Active& x : act) sum += x.term;
  double remaining = static_cast<double>(params.total);
  std::uint64_t capped_points = 0;
  double lambda = remaining / sum;
  bool settled = false;
  for (stats.rounds = 1; stats.rounds <= kMaxRounds; ++stats.rounds) {
    std::size_t newly = 0;
    for (std::size_t k = 0; k < a; ++k) {
      if (capped[k] || lambda * act[k].term < static_cast<double>(act[k].points)) continue;
      capped[k] = 1;
      sum -= act[k].term;
      capped_points += act[k].points;
      ++newly;
    }
    stats.capped += newly;
    remaining = static_cast<double>(params.total) - static_cast<double>(capped_points);
    if (newly == 0 || !(sum > 1e-300) || remaining <= 0.0) {
      settled = true;
      break;
    }
    lambda = remaining / sum;
  }
  if (!settled) {
    // The worst case: uncapped objects in ascending P_i / t_i are capped in
    // that order while lambda * t_i >= P_i.
    std::vector<std::size_t> order;
    for (std::size_t k = 0; k < a; ++k)
      if (!capped[k]) order.push_back(k);
    std::sort(order.begin(), order.end(), [&](std::size_t x, std::size_t y) {
      return static_cast<double>(act[x].points) / act[x].term <
             static_cast<double>(act[y].points) / act[y].term;
    });
    for (const std::size_t k : order) {
      lambda = remaining / sum;
      if (lambda * act[k].term < static_cast<double>(act[k].points)) break;
      capped[k] = 1;
      ++stats.capped;
      sum -= act[k].term;
      capped_points += act[k].points;
      remaining = static_cast<double>(params.total) - static_cast<double>(capped_points);
      if (!(sum > 1e-300)) break;
    }
  }
  return sum > 1e-300 && remaining > 0.0 ? remaining / sum : 0.0;
}

// Integer shares: floors, then the points left to the largest fractions,
// then (float rounding of lambda) any overshoot of N taken back. Returns
// the sum of the shares.
[[gnu::always_inline]] inline std::uint64_t integer_shares(const std::vector<Active>& act,
                                                           const std::vector<std::uint8_t>& capped,
                                                           double lambda,
                                                           const BudgetParams& params,
                                                           std::vector<std::uint32_t>& share) {
  const std::size_t a = act.size();
  std::vector<float> fraction(a, -1.0f);  // -1: full (capped or at P_i)
  std::uint64_t total = 0, room = 0;
  for (std::size_t k = 0; k < a; ++k) {
    if (capped[k]) {
      share[k] = act[k].points;
    } else {
      const double x = std::min(lambda * act[k].term, static_cast<double>(act[k].points));
      const double f = std::floor(x);
      share[k] = static_cast<std::uint32_t>(f);
      if (share[k] < act[k].points) {
        fraction[k] = static_cast<float>(x - f);
        room += act[k].points - share[k];
      }
    }
    total += share[k];
  }
  // The target: N, or every point when the objects have fewer.
  const std::uint64_t target = std::min<std::uint64_t>(params.total, total + room);
  if (total < target) {
    std::vector<std::size_t> open;
    for (std::size_t k = 0; k < a; ++k)
      if (fraction[k] >= 0.0f) open.push_back(k);
    const auto larger = [&](std::size_t x, std::size_t y) {
      return fraction[x] != fraction[y] ? fraction[x] > fraction[y] : x < y;
    };
    // Rounding leaves fewer points than there are uncapped objects (the
    // fractions sum to less than their count), but float rounding of lambda
    // may leave a few more: then go round again, by index.
    while (total < target && !open.empty()) {
      const std::size_t give =
          static_cast<std::size_t>(std::min<std::uint64_t>(target - total, open.size()));
      std::nth_element(open.begin(), open.begin() + static_cast<std::ptrdiff_t>(give - 1),
                       open.end(), larger);
      for (std::size_t k = 0; k < give; ++k) ++share[open[k]];
      total += give;
      std::erase_if(open, [&](std::size_t k) { return share[k] >= act[k].points; });
      for (const std::size_t k : open) fraction[k] = 0.0f;
    }
  }
  while (total > params.total) {
    // lambda's float rounding overshot: take back from the smallest
    // fractional parts (kept for the guarantee).
    std::size_t worst = a;
    for (std::size_t k = 0; k < a; ++k) {
      if (share[k] == 0 || capped[k]) continue;
      if (worst == a || fraction[k] < fraction[worst]) worst = k;
    }
    if (worst == a) break;
    --share[worst];
    fraction[worst] = 2.0f;
    --total;
  }
  return total;
}

}  // namespace

double eq1_term(const BudgetItem& item, const BudgetParams& params) {
  if (item.points == 0 || !(item.area > 0.0f) || item.area < params.pet) return 0.0;
  const double beta = params.alpha - 1.0;
  const double depth = std::max(static_cast<double>(item.depth), kMinDepth);
  // w^(1/alpha) = (A / D)^(1/alpha) * P^(beta/alpha), in logarithms so that a
  // large P^beta cannot overflow.
  const double log_w =
      std::log(item.area / depth) + beta * std::log(static_cast<double>(item.points));
  return std::exp(log_w / params.alpha);
}

std::vector<double> eq1_shares(std::span<const BudgetItem> items, const BudgetParams& params) {
  std::vector<double> t(items.size());
  double sum = 0.0;
  for (std::size_t i = 0; i < items.size(); ++i) sum += t[i] = eq1_term(items[i], params);
  for (double& x : t) x = sum > 0.0 ? static_cast<double>(params.total) * x / sum : 0.0;
  return t;
}

void budget_items(std::span<const culling::ObjectBounds> objects,
                  std::span<const culling::ScreenRect> rects, std::span<const std::uint8_t> visible,
                  std::vector<BudgetItem>& items, WorkerPool* pool) {
  // The objects' point counts as the dense array the strategy keeps.
  std::vector<std::uint32_t> points(objects.size());
  for (std::size_t i = 0; i < objects.size(); ++i) points[i] = objects[i].points;
  budget_items(points, rects, visible, items, pool);
}

void budget_items(std::span<const std::uint32_t> points, std::span<const culling::ScreenRect> rects,
                  std::span<const std::uint8_t> visible, std::vector<BudgetItem>& items,
                  WorkerPool* pool) {
  items.resize(points.size());
  for_chunks(pool, points.size(), kGrain, [&](std::size_t b, std::size_t e, std::size_t) {
    for (std::size_t i = b; i < e; ++i) {
      const bool v = (visible.empty() || visible[i] != 0) && rects[i].in_frustum;
      items[i] = {v ? rects[i].area() : 0.0f, rects[i].depth, v ? points[i] : 0u};
    }
  });
}

BudgetStats allocate_budget(std::span<const BudgetItem> items, const BudgetParams& params,
                            std::vector<std::uint32_t>& shares, WorkerPool* pool) {
  const std::size_t m = items.size();
  BudgetStats stats;
  shares.assign(m, 0);
  if (m == 0 || params.total == 0) return stats;

  const std::vector<Active> act = active_objects(items, params, pool, stats);
  const std::size_t a = act.size();
  if (a == 0) return stats;
  std::vector<std::uint8_t> capped(a, 0);
  const double lambda = water_fill(act, params, capped, stats);
  stats.lambda = lambda;
  std::vector<std::uint32_t> share(a);
  const std::uint64_t total = integer_shares(act, capped, lambda, params, share);
  for (std::size_t k = 0; k < a; ++k) {
    shares[act[k].index] = share[k];
    stats.receiving += share[k] > 0;
  }
  stats.total = total;
  return stats;
}

std::vector<NodeId> best_cut(const Hierarchy& h, const ViewSnapshot& view, std::size_t n,
                             const CutParams& params) {
  std::vector<NodeId> cut;
  best_cut(h, view, n, cut, params);
  return cut;
}

void best_cut(const Hierarchy& h, const ViewSnapshot& view, std::size_t n, std::vector<NodeId>& cut,
              const CutParams& params, std::vector<NodeId>* wanted) {
  cut.clear();
  if (n == 0 || h.empty()) return;
  // Max-heap of (priority, node) over the refinable cut nodes; the rest of the
  // cut (leaves, too small, no room) goes straight to the result. The heap's
  // storage is the thread's, kept from object to object (push_heap and
  // pop_heap with operator<, what std::priority_queue does: the same order).
  struct Entry {
    float priority;
    NodeId node;
    bool operator<(const Entry& o) const {
      return priority != o.priority ? priority < o.priority : node > o.node;
    }
  };
  thread_local std::vector<Entry> heap;
  heap.clear();
  std::size_t size = 1;
  const auto offer = [&](NodeId node) {
    float px = 0.0f;
    const float p = OptimizationStrategy::priority(h, view, node, params.curvature_weight, &px);
    if (h.is_leaf(node) || !(px >= params.min_size) || !(p > 0.0f)) {
      // A paged model's node whose children are not resident, which this
      // rule would refine: its pages are asked for (they may not fit the
      // share when they come; the next iteration decides).
      if (wanted != nullptr && h.is_hidden(node) && px >= params.min_size && p > 0.0f)
        wanted->push_back(node);
      cut.push_back(node);
    } else {
      heap.push_back({p, node});
      std::push_heap(heap.begin(), heap.end());
    }
  };
  offer(h.root());
  while (!heap.empty()) {
    std::pop_heap(heap.begin(), heap.end());
    const Entry top = heap.back();
    heap.pop_back();
    const std::size_t children = h.child_count(top.node);
    if (size + children - 1 > n) {
      cut.push_back(top.node);  // its children do not fit; a later node's may
      continue;
    }
    size += children - 1;
    const NodeId first = h.first_child(top.node);
    for (NodeId c = first; c < first + children; ++c) offer(c);
  }
}

}  // namespace treecut::strategies::many
