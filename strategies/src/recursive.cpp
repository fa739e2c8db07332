// Recursive strategy: Marton, Schiffner et al., "Parallel TreeCut
// Manipulation", section 4, after the QSplat traversal (Rusinkiewicz & Levoy,
// "QSplat: A Multiresolution Point Rendering System for Large Meshes", 2000).
#include "treecut/strategies/recursive.hpp"

#include <algorithm>
#include <cmath>
#include <glm/geometric.hpp>

namespace treecut::strategies {
namespace {

// FNV-1a over the emitted ids: an equal list under an equal view means the
// strategy has converged.
constexpr std::uint64_t kFnvOffset = 0xcbf29ce484222325ull;
constexpr std::uint64_t kFnvPrime = 0x100000001b3ull;
constexpr std::size_t kPrefetch = 64;  // nodes ahead, enough to cover a DRAM miss

// ViewSnapshot::backfacing with the distance to the eye already known: the
// cone (axis, half-angle a) faces away from the whole sphere, seen under the
// half-angle b, iff the angle to the eye exceeds 90 degrees + a + b (QSplat).
[[gnu::always_inline]] inline bool backfacing(glm::i16vec4 cone, glm::vec3 to_eye, float dist,
                                              float radius) {
  const float cone_cos = static_cast<float>(cone.w) * (1.0f / 32767.0f);
  if (cone_cos <= 0.0f || dist <= radius) return false;
  const float sin_b = radius / dist;
  const float cos_b = std::sqrt(1.0f - sin_b * sin_b);
  const float sin_a = std::sqrt(std::max(0.0f, 1.0f - cone_cos * cone_cos));
  if (cone_cos * cos_b - sin_a * sin_b <= 0.0f) return false;  // a + b >= 90 degrees
  const float sin_ab = sin_a * cos_b + cone_cos * sin_b;
  const glm::vec3 axis = glm::vec3(cone) * (1.0f / 32767.0f);
  return glm::dot(axis, to_eye) < -sin_ab * dist;
}

}  // namespace

RecursiveStrategy::RecursiveStrategy()
    : Strategy({
          {"min_size", "pixels: the recursion stops below this projected radius", 1.0, 0.0, 1e6,
           false},
          {"backface", "1: stop at normal cones facing away from the eye", 1.0, 0.0, 1.0, true},
      }) {}

void RecursiveStrategy::reset(const Hierarchy& hierarchy) {
  level_.clear();
  next_.clear();
  level_.reserve(hierarchy.node_count() < 4096 ? hierarchy.node_count() : 4096);
  next_.reserve(level_.capacity());
  last_hash_ = 0;
  last_size_ = 0;
}

namespace {

// Whether the sphere CR lies outside one of the frustum planes still in
// PLANES (a bit a plane); the planes it lies wholly inside are taken out
// of PLANES (its descendants lie inside them too).
[[gnu::always_inline]] inline bool outside_planes(const ViewSnapshot& view, const glm::vec4& cr,
                                                  std::uint32_t& planes) {
  for (std::uint32_t p = 0; p < 6 && planes != 0; ++p) {
    if ((planes & (1u << p)) == 0) continue;
    const Plane& pl = view.derived.frustum[p];
    const float d = pl.x * cr.x + pl.y * cr.y + pl.z * cr.z + pl.w;
    if (d < -cr.w) return true;
    if (d > cr.w) planes &= ~(1u << p);
  }
  return false;
}

}  // namespace

void RecursiveStrategy::iterate(const IterationInput& input, IterationOutput& output) {
  const Hierarchy& h = input.hierarchy;
  const ViewSnapshot& view = input.view;
  const HierarchyArrays& a = h.arrays();
  std::vector<NodeId>& out = *output.nodes;
  IterationResult& r = output.result;
  const auto min_size = static_cast<float>(param_at(kMinSize));
  const bool backface = param_at(kBackface) != 0.0;

  std::uint64_t hash = kFnvOffset;
  const auto emit = [&](NodeId n) {
    out.push_back(n);
    hash = (hash ^ n) * kFnvPrime;
  };
  // Hierarchical frustum culling: a sphere completely inside a plane's half
  // space keeps its descendants inside it too, so the plane is not tested
  // again below it.
  constexpr std::uint32_t kAllPlanes = 0x3f;
  const float pixel_scale = view.derived.pixel_scale;
  const glm::vec3 eye = view.derived.eye;
  // Level by level: children of ascending parents are ascending ranges, so
  // every level is visited in ascending id order and the emitted cut is sorted
  // (what TreeCut::sort and the renderer's upload prefer).
  level_.clear();
  level_.push_back({h.root(), kAllPlanes});
  while (!level_.empty() && !r.cancelled) {
    next_.clear();
    const std::size_t count = level_.size();
    for (std::size_t i = 0; i < count; ++i) {
      const auto [n, planes_in] = level_[i];
      ++r.visited;
      if ((r.visited & 4095) == 0 && input.cancelled()) {
        // Every node not yet decided roots an untraversed subtree: emitting
        // them all keeps the cut complete (and sorted).
        r.cancelled = true;
        for (std::size_t j = i; j < count; ++j) emit(level_[j].node);
        for (const Pending& p : next_) emit(p.node);
        break;
      }
      if (i + kPrefetch < count) {
        const NodeId ahead = level_[i + kPrefetch].node;
        __builtin_prefetch(&a.center_radius[ahead]);
        __builtin_prefetch(&a.normal_cone[ahead]);
        __builtin_prefetch(&a.first_child[ahead]);
        __builtin_prefetch(&a.child_count[ahead]);
      }
      const glm::vec4 cr = a.center_radius[n];
      const glm::vec3 c(cr);
      std::uint32_t planes = planes_in;
      if (outside_planes(view, cr, planes)) {
        ++r.culled;
        emit(n);
        continue;
      }
      const unsigned children = a.child_count[n];
      if (children == 0 && a.point_count[n] <= 1) {  // a leaf (not a hidden one)
        emit(n);
        continue;
      }
      // Projected radius as in ViewSnapshot::projected_radius_px, with the
      // division turned into a multiplication; the distance serves the cone
      // test too.
      const glm::vec3 to_eye = eye - c;
      const float dist = std::sqrt(glm::dot(to_eye, to_eye));
      const bool small = view.derived.perspective ? cr.w * pixel_scale < min_size * (dist - cr.w)
                                                  : cr.w * pixel_scale < min_size;
      if (small) {
        ++r.too_small;
        emit(n);
        continue;
      }
      if (backface && view.derived.perspective &&
          backfacing(a.normal_cone[n], to_eye, dist, cr.w)) {
        ++r.backfacing;
        emit(n);
        continue;
      }
      if (children == 0) {  // hidden: refined once its pages are read
        if (output.wanted) output.wanted->push_back(n);
        emit(n);
        continue;
      }
      const NodeId first = a.first_child[n];
      for (unsigned j = 0; j < children; ++j) next_.push_back({first + j, planes});
    }
    level_.swap(next_);
  }
  r.cut_size = out.size();
  r.converged = !r.cancelled && hash == last_hash_ && out.size() == last_size_;
  last_hash_ = r.cancelled ? 0 : hash;
  last_size_ = out.size();
}

}  // namespace treecut::strategies
