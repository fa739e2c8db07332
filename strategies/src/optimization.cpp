// Optimization strategy: Marton, Schiffner et al., "Parallel TreeCut
// Manipulation", section 4, figure 3. Partial sorting of the cut after
// Carr et al. [Car11]; priorities from curvature and projected splat size
// (Schiffner & Kroemker [Sch10]).
#include "treecut/strategies/optimization.hpp"

#include <algorithm>
#include <bit>
#include <cassert>
#include <cmath>
#include <functional>

namespace treecut::strategies {
namespace {

constexpr std::uint32_t kRefinedBit = 1;
constexpr std::uint32_t kMaxIteration = 0x7fffffffu;
constexpr std::size_t kPrefetch = 32;  // nodes ahead, enough to cover a DRAM miss

// A candidate packs (priority, node) into one integer; see the header.
using Candidate = std::uint64_t;

[[gnu::always_inline]] inline Candidate candidate(float priority, NodeId n) {
  // + 0.0f turns a -0.0f (whose sign bit would rank it highest) into +0.0f.
  return std::uint64_t{std::bit_cast<std::uint32_t>(priority + 0.0f)} << 32 | n;
}
inline float priority_of(Candidate c) {
  return std::bit_cast<float>(static_cast<std::uint32_t>(c >> 32));
}
inline NodeId node_of(Candidate c) {
  return static_cast<NodeId>(c);
}

// Keeps the k best candidates of a stream (Carr et al. keep a partial sort of
// size k): candidates better than the current bound are appended; when 2k
// have gathered, nth_element keeps the best k and tightens the bound. O(1)
// amortized per candidate, O(n) per pass; the caller may test admits() first
// to skip computing a candidate at all. The buffer ends with the best k among
// at most 2k candidates, unordered.
template <typename Better>
class Selection {
 public:
  Selection(std::vector<Candidate>& buffer, std::size_t k, Better better)
      : buf_(buffer), k_(k), better_(better) {
    buf_.clear();
  }
  /// True when `c` could still be among the best k.
  [[nodiscard]] bool admits(const Candidate& c) const { return !bounded_ || better_(c, bound_); }
  void add(const Candidate& c) {
    if (!admits(c)) return;
    buf_.push_back(c);
    if (buf_.size() >= 2 * k_) shrink();
  }

 private:
  void shrink() {
    const auto kth = buf_.begin() + static_cast<std::ptrdiff_t>(k_ - 1);
    std::nth_element(buf_.begin(), kth, buf_.end(), better_);
    bound_ = *kth;
    bounded_ = true;
    buf_.resize(k_);
  }
  std::vector<Candidate>& buf_;
  std::size_t k_;
  Better better_;
  Candidate bound_{};
  bool bounded_ = false;
};

// The body of OptimizationStrategy::priority, inlined into the hot loop.
[[gnu::always_inline]] inline float view_priority(const HierarchyArrays& a,
                                                  const ViewSnapshot& view, NodeId n,
                                                  float curvature_weight, float& size) {
  const glm::vec4 cr = a.center_radius[n];
  const glm::vec3 c(cr);
  if (view.outside_frustum(c, cr.w)) {
    size = 0.0f;
    return 0.0f;
  }
  size = view.projected_radius_px(c, cr.w);
  return size * ((1.0f - curvature_weight) + curvature_weight * a.priority[n]);
}

// One iteration's settings and the hysteresis marks it reads and writes
// (OptimizationStrategy::last_op_: iteration << 1 | refined, per node).
struct Pass {
  std::size_t max_nodes;
  std::size_t k;
  float threshold;
  float weight;
  float min_size;
  SparseNodeArray<std::uint32_t>& last_op;
  std::uint32_t view_start;  // first iteration of the current view
  std::uint32_t iteration;
  // A paged model's: the hidden nodes a refine chose (IterationOutput::
  // wanted), null for a model held whole.
  std::vector<NodeId>* wanted;
  bool memory_short;  // IterationInput::memory_short

  // A node coarsened under the current view is not refined again under it.
  [[nodiscard]] bool refine_blocked(NodeId n) const {
    const std::uint32_t op = last_op[n];
    return (op & kRefinedBit) == 0 && (op >> 1) >= view_start;
  }
  // A node refined in the previous iteration is not coarsened.
  [[nodiscard]] bool coarsen_blocked(NodeId n) const {
    return last_op[n] == ((iteration - 1) << 1 | kRefinedBit);
  }
};

// Evaluate: one pass over the cut, keeping the k highest refinable nodes
// (in `high`) and the k lowest coarsenable parents (in `low`; a parent is
// seen once, at its first child). The hot loop of the strategy: inlined
// into iterate(), as it was before this was a function of its own.
[[gnu::always_inline]] inline void evaluate_cut(const Hierarchy& h, const ViewSnapshot& view,
                                                const TreeCut& cut, const IterationInput& input,
                                                const Pass& pass, std::vector<Candidate>& high,
                                                std::vector<Candidate>& low, IterationResult& r) {
  const HierarchyArrays& a = h.arrays();
  high.clear();
  low.clear();
  Selection highs(high, pass.k, std::greater<Candidate>{});  // keeps the highest
  Selection lows(low, pass.k, std::less<Candidate>{});       // keeps the lowest
  const std::span<const NodeId> nodes = cut.nodes();
  for (std::size_t i = 0; i < nodes.size(); ++i) {
    const NodeId n = nodes[i];
    if ((i & 4095) == 0 && input.cancelled()) {
      r.cancelled = true;
      break;
    }
    // The cut is unordered, so every node is a cache miss: fetch ahead.
    if (i + kPrefetch < nodes.size()) {
      const NodeId ahead = nodes[i + kPrefetch];
      __builtin_prefetch(&a.center_radius[ahead]);
      __builtin_prefetch(&a.priority[ahead]);
      __builtin_prefetch(&a.parent[ahead]);
      __builtin_prefetch(&a.child_count[ahead]);
    }
    float size = 0.0f;
    const float p = view_priority(a, view, n, pass.weight, size);
    const Candidate self = candidate(p, n);
    const bool refinable = a.child_count[n] != 0 || (pass.wanted && a.point_count[n] > 1);
    if (refinable && size >= pass.min_size && highs.admits(self)) {
      if (pass.refine_blocked(n)) {
        ++r.blocked;
      } else {
        highs.add(self);
      }
    }
    // Parents are ranked at their first child. p(parent) >= p(n) (monotone
    // priorities), so a node above the k-th lowest rejects its parent unseen.
    if (!lows.admits(candidate(p, 0))) continue;
    if (!h.is_first_child(n)) continue;
    const NodeId parent = a.parent[n];
    // Rank before the coarsenability test, which touches the cut's slot map.
    float parent_size = 0.0f;
    const Candidate c = candidate(view_priority(a, view, parent, pass.weight, parent_size), parent);
    if (!lows.admits(c) || !cut.can_coarsen(h, parent)) continue;
    if (pass.coarsen_blocked(parent)) {
      ++r.blocked;
    } else {
      lows.add(c);
    }
  }
  r.visited = nodes.size();
}

// Apply: refine in descending priority while there is room; make room by
// coarsening the lowest parents, but only for a gain above the threshold.
// Inlined into iterate() like the evaluation.
[[gnu::always_inline]] inline void apply_candidates(const Hierarchy& h, const ViewSnapshot& view,
                                                    TreeCut& cut, const Pass& pass,
                                                    std::vector<Candidate>& high,
                                                    std::vector<Candidate>& low,
                                                    IterationResult& r) {
  const HierarchyArrays& a = h.arrays();
  const std::uint32_t refined_mark = pass.iteration << 1 | kRefinedBit;
  const std::uint32_t coarsened_mark = pass.iteration << 1;
  // Heaps over the selection buffers (O(k)), popped lazily and at most k
  // times: an iteration that stops early pays O(log k) per candidate used,
  // not a sort of k.
  const auto higher = std::less<Candidate>{};    // max-heap order: highest on top
  const auto lower = std::greater<Candidate>{};  // min-heap order: lowest on top
  std::make_heap(high.begin(), high.end(), higher);
  std::make_heap(low.begin(), low.end(), lower);
  std::size_t high_left = pass.k;
  std::size_t low_left = pass.k;
  const auto pop = [](std::vector<Candidate>& heap, auto order) {
    std::pop_heap(heap.begin(), heap.end(), order);
    heap.pop_back();
  };
  const auto coarsen_next = [&](float must_beat, bool forced) {
    while (!low.empty() && low_left > 0) {
      const float p = priority_of(low.front());
      const NodeId parent = node_of(low.front());
      if (!cut.can_coarsen(h, parent)) {  // a child was refined meanwhile
        pop(low, lower);
        --low_left;
        continue;
      }
      if (!forced && !(p + pass.threshold < must_beat)) return false;
      pop(low, lower);
      --low_left;
      cut.coarsen(h, parent);
      pass.last_op.set(parent, coarsened_mark);
      ++r.coarsened;
      return true;
    }
    return false;
  };
  // A lowered budget: shrink first, whatever the gain.
  while (cut.size() > pass.max_nodes && coarsen_next(0.0f, true)) {
  }
  while (!high.empty() && high_left > 0) {
    const float p = priority_of(high.front());
    const NodeId n = node_of(high.front());
    pop(high, higher);
    --high_left;
    if (!cut.contains(n)) continue;  // its parent was coarsened above
    if (a.child_count[n] == 0) {     // hidden: refined once its pages are read
      pass.wanted->push_back(n);
      continue;
    }
    const std::size_t grow = a.child_count[n] - 1u;
    bool room = true;
    while (cut.size() + grow > pass.max_nodes) {
      if (!coarsen_next(p, false)) {
        room = false;
        break;
      }
    }
    if (!room) break;  // every later candidate has a lower priority
    if (!cut.contains(n)) continue;
    cut.refine(h, n);
    pass.last_op.set(n, refined_mark);
    ++r.refined;
  }
  // A paged model short of memory (IterationInput::memory_short): the
  // cut's room is the budget's too. A parent the view does not see
  // (outside the frustum: priority 0, the lowest) is coarsened whatever
  // room the cut has left, so that the pages below it can go back for the
  // nodes that are seen (issue 45). Otherwise it stays until its room is
  // needed, as in figure 3: detail for a camera that turns back.
  if (!pass.memory_short) return;
  while (!low.empty() && low_left > 0 && priority_of(low.front()) == 0.0f) {
    const NodeId parent = node_of(low.front());
    const glm::vec4 cr = a.center_radius[parent];
    if (!view.outside_frustum(glm::vec3(cr), cr.w)) break;  // seen, of priority 0
    if (!cut.can_coarsen(h, parent)) {                      // a child was refined meanwhile
      pop(low, lower);
      --low_left;
      continue;
    }
    coarsen_next(0.0f, true);  // (this one: it can be)
  }
}

}  // namespace

OptimizationStrategy::OptimizationStrategy()
    : Strategy({
          {"max_nodes", "maximal number of cut nodes", 100000, 1, 4e9, true},
          {"k", "partial sort size: refine/coarsen candidates per iteration", 8192, 1, 1 << 24,
           true},
          {"threshold", "minimal priority gain that allows a coarse", 0.0, 0.0, 1e12, false},
          {"curvature_weight", "weight of the curvature in the priority (0 = size only)", 0.5, 0.0,
           1.0, false},
          {"min_size", "pixels: nodes with a smaller projected radius are not refined", 0.5, 0.0,
           1e6, false},
      }) {}

void OptimizationStrategy::reset(const Hierarchy& hierarchy) {
  last_op_.assign(hierarchy.node_count(), 0);
  view_forgotten_ = 0;
  iteration_ = 0;
  view_start_ = 0;
  last_version_ = ~std::uint64_t{0};
  last_params_ = ~std::uint64_t{0};
}

float OptimizationStrategy::priority(const Hierarchy& h, const ViewSnapshot& view, NodeId n,
                                     float curvature_weight, float* size_px) {
  float size = 0.0f;
  const float p = view_priority(h.arrays(), view, n, curvature_weight, size);
  if (size_px != nullptr) *size_px = size;
  return p;
}

void OptimizationStrategy::iterate(const IterationInput& input, IterationOutput& output) {
  const Hierarchy& h = input.hierarchy;
  const ViewSnapshot& view = input.view;
  TreeCut& cut = *output.cut;
  IterationResult& r = output.result;
  assert(last_op_.size() == h.node_count() && "reset() was not called for this hierarchy");

  const auto max_nodes = static_cast<std::size_t>(param_at(kMaxNodes));
  const auto k = static_cast<std::size_t>(param_at(kK));
  const auto threshold = static_cast<float>(param_at(kThreshold));
  const auto weight = static_cast<float>(param_at(kCurvatureWeight));
  const auto min_size = static_cast<float>(param_at(kMinSize));
  if (iteration_ == kMaxIteration) {  // after 2^31 iterations: forget every mark
    last_op_.assign(h.node_count(), 0u);
    view_forgotten_ = 0;
    iteration_ = 0;
    last_version_ = ~std::uint64_t{0};
    last_params_ = ~std::uint64_t{0};
  }
  ++iteration_;
  if (view.version != last_version_ || input.params_version != last_params_) {
    // A new view or new parameters (strategy.hpp, "Events"): earlier
    // coarsens may be undone.
    last_version_ = view.version;
    last_params_ = input.params_version;
    view_start_ = iteration_;
  }
  const Pass pass{max_nodes, k,           threshold,  weight,        min_size,
                  last_op_,  view_start_, iteration_, output.wanted, input.memory_short};

  // The pass reads the node arrays at every cut node: in id order they are
  // read with ascending addresses instead of at random.
  cut.keep_sorted(sort_scratch_);
  evaluate_cut(h, view, cut, input, pass, high_, low_, r);
  apply_candidates(h, view, cut, pass, high_, low_, r);
  r.cut_size = cut.size();
  r.converged = !r.cancelled && r.refined == 0 && r.coarsened == 0;
  forget_old_marks(cut.size());
}

void OptimizationStrategy::forget_old_marks(std::size_t cut_size) {
  // Marks gather wherever the cut has been. Scanning them costs about what
  // an evaluation pass over a cut of their size does, so they are scanned
  // once they hold four times the cut's ids (a floor for small cuts), and
  // once a view: under the view of the last scan, a scan forgets nothing.
  constexpr std::size_t kBlock = SparseNodeArray<std::uint32_t>::kBlock;
  if (last_op_.blocks_held() <= 4 * cut_size / kBlock + 16 || view_start_ == view_forgotten_)
    return;
  // The next iteration reads the coarsen marks of the current view (from
  // view_start_ on) and the refine marks of this iteration (later still).
  const std::uint32_t oldest = view_start_;
  last_op_.rewrite_held([oldest](std::uint32_t op) { return (op >> 1) >= oldest ? op : 0u; });
  view_forgotten_ = view_start_;
}

}  // namespace treecut::strategies
