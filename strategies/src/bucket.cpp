// Bucket-based strategy: Marton, Schiffner et al., "Parallel TreeCut
// Manipulation", section 4, figure 4 (and the stippling of figure 7a).
#include "treecut/strategies/bucket.hpp"

#include <algorithm>
#include <cmath>

namespace treecut::strategies {
namespace {

constexpr std::size_t kPrefetch = 64;  // nodes ahead, enough to cover a DRAM miss

}  // namespace

BucketStrategy::BucketStrategy(BucketFunction function)
    : Strategy({
          {"threshold", "minimal negative delta (levels beyond 0) that forces a coarse", 0.0, 0.0,
           255.0, true},
          {"min_depth", "target depth of fully lit nodes, as a fraction of the deepest level", 0.35,
           0.0, 1.0, false},
          {"max_depth", "target depth of unlit nodes, as a fraction of the deepest level", 1.0, 0.0,
           1.0, false},
          {"ambient", "light every node receives", 0.1, 0.0, 1.0, false},
          {"cull", "1: nodes outside the view frustum target the lit depth", 0.0, 0.0, 1.0, true},
      }),
      function_(std::move(function)) {}

void BucketStrategy::reset(const Hierarchy& hierarchy) {
  refine_.clear();
  coarsen_.clear();
  refine_.reserve(hierarchy.node_count() < 4096 ? hierarchy.node_count() : 4096);
}

namespace {

// The default bucket function with its parameters resolved once per iteration.
struct Illumination {
  float lit_depth;
  float depth_range;  // dark depth - lit depth
  float ambient;
  bool cull;

  // The darker the node, the deeper its target: more, smaller splats where
  // the surface is in shadow (the paper's stippling, figure 7a).
  [[gnu::always_inline]] int operator()(const HierarchyArrays& a, const ViewSnapshot& view,
                                        NodeId n) const {
    if (cull) {
      const glm::vec4 cr = a.center_radius[n];
      if (view.outside_frustum(glm::vec3(cr), cr.w)) return static_cast<int>(lit_depth);
    }
    const glm::vec3 normal = glm::vec3(a.normal_cone[n]) * (1.0f / 32767.0f);
    const float diffuse = std::max(0.0f, glm::dot(normal, view.light_dir));
    const float light = std::min(1.0f, ambient + (1.0f - ambient) * diffuse);
    return static_cast<int>(lit_depth + (1.0f - light) * depth_range);
  }
};

}  // namespace

int BucketStrategy::illumination_bucket(const Hierarchy& h, const ViewSnapshot& view,
                                        NodeId n) const {
  const float deepest = static_cast<float>(h.level_count() - 1);
  const float lit = static_cast<float>(param_at(kMinDepth)) * deepest;
  const float dark = static_cast<float>(param_at(kMaxDepth)) * deepest;
  const Illumination light{lit, dark - lit, static_cast<float>(param_at(kAmbient)),
                           param_at(kCull) != 0.0};
  return light(h.arrays(), view, n);
}

void BucketStrategy::iterate(const IterationInput& input, IterationOutput& output) {
  const Hierarchy& h = input.hierarchy;
  const ViewSnapshot& view = input.view;
  TreeCut& cut = *output.cut;
  IterationResult& r = output.result;
  const HierarchyArrays& a = h.arrays();
  const int threshold = static_cast<int>(param_at(kThreshold));
  std::vector<NodeId>* const wanted = output.wanted;

  // Evaluate every cut node against its bucket; collect the operations first
  // so the whole pass sees one consistent cut. The pass is instantiated for
  // the default function (inlined) and for a custom one.
  refine_.clear();
  coarsen_.clear();
  cut.keep_sorted(sort_scratch_);  // the pass then reads the arrays in address order
  const std::span<const NodeId> nodes = cut.nodes();
  const bool cull = function_ || param_at(kCull) != 0.0;
  const auto pass = [&](const auto& bucket) {
    for (std::size_t i = 0; i < nodes.size(); ++i) {
      if ((i & 4095) == 0 && input.cancelled()) {
        r.cancelled = true;
        break;
      }
      const NodeId n = nodes[i];
      // Sorted or not, neighbouring cut nodes can be far apart: fetch ahead.
      if (i + kPrefetch < nodes.size()) {
        const NodeId ahead = nodes[i + kPrefetch];
        if (cull) __builtin_prefetch(&a.center_radius[ahead]);
        __builtin_prefetch(&a.normal_cone[ahead]);
        __builtin_prefetch(&a.depth[ahead]);
        __builtin_prefetch(&a.child_count[ahead]);
        __builtin_prefetch(&a.parent[ahead]);
      }
      const int depth = a.depth[n];
      const int delta = bucket(n) - depth;
      if (delta > 0 && a.child_count[n] != 0) refine_.push_back(n);  // '+' in figure 4
      // A paged model's hidden node asking for '+': refined once its pages are read.
      if (delta > 0 && wanted && h.is_hidden(n)) wanted->push_back(n);

      // A sibling group is judged once, at its first child: every sibling
      // must ask for a coarse ('-'), and the parent's own delta must not be
      // positive ('?' in figure 4), else the parent would be refined again.
      if (delta + threshold >= 0) continue;  // this node does not ask for a coarse
      if (!h.is_first_child(n)) continue;
      const NodeId parent = a.parent[n];
      if (!cut.can_coarsen(h, parent)) continue;
      bool all_negative = true;
      for (NodeId c = n + 1; c < n + a.child_count[parent]; ++c) {
        if (bucket(c) - depth + threshold >= 0) {
          all_negative = false;
          break;
        }
      }
      if (!all_negative) continue;
      if (bucket(parent) - (depth - 1) > 0) {
        ++r.blocked;
        continue;
      }
      coarsen_.push_back(parent);
    }
  };
  if (function_) {
    pass([&](NodeId n) { return static_cast<int>(std::floor(function_(h, view, n))); });
  } else {
    const float deepest = static_cast<float>(h.level_count() - 1);
    const float lit = static_cast<float>(param_at(kMinDepth)) * deepest;
    const float dark = static_cast<float>(param_at(kMaxDepth)) * deepest;
    const Illumination light{lit, dark - lit, static_cast<float>(param_at(kAmbient)),
                             param_at(kCull) != 0.0};
    pass([&](NodeId n) { return light(a, view, n); });
  }
  r.visited = nodes.size();

  // Apply. Refines and coarsens never touch the same node: a group with a
  // refinable member is not coarsened.
  for (const NodeId n : refine_) r.refined += cut.refine(h, n) ? 1u : 0u;
  for (const NodeId p : coarsen_) r.coarsened += cut.coarsen(h, p) ? 1u : 0u;
  r.cut_size = cut.size();
  r.converged = !r.cancelled && r.refined == 0 && r.coarsened == 0;
}

}  // namespace treecut::strategies
