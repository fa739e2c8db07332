// Fixtures shared by the strategy, feedback-stage and stress tests: small
// generated hierarchies, cameras, and a recorder of refine/coarsen operations
// derived from consecutive cuts (independent of how a strategy works).
#pragma once

#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <cstdint>
#include <map>
#include <memory>
#include <random>
#include <span>
#include <thread>
#include <vector>

#include "treecut/attributes.hpp"
#include "treecut/hierarchy.hpp"
#include "treecut/strategy.hpp"
#include "treecut/tools/generate.hpp"
#include "treecut/tree_cut.hpp"
#include "treecut/view_snapshot.hpp"

namespace treecut::test {

/// A hierarchy over a generated model, built once per (kind, points) and shared.
inline std::shared_ptr<const Hierarchy> small_hierarchy(tools::ModelKind kind, std::size_t points) {
  static std::map<std::pair<int, std::size_t>, std::shared_ptr<const Hierarchy>> cache;
  auto& slot = cache[{static_cast<int>(kind), points}];
  if (!slot) {
    PointSet model = tools::generate_model(kind, points, 7);
    complete_attributes(model);
    slot = std::make_shared<const Hierarchy>(build_hierarchy(std::move(model)));
  }
  return slot;
}

/// A camera on a circle around the model's bounds, looking at their center.
inline ViewSnapshot orbit_view(const Hierarchy& h, float angle, float distance_factor = 2.0f,
                               glm::ivec2 viewport = {800, 600}) {
  const glm::vec3 center = 0.5f * (h.bounds_min() + h.bounds_max());
  const float extent = glm::length(h.bounds_max() - h.bounds_min());
  const glm::vec3 eye =
      center + distance_factor * extent * glm::vec3(std::cos(angle), 0.35f, std::sin(angle));
  return ViewSnapshot::look_at(eye, center, viewport, 0.8f, 0.001f * extent, 10.0f * extent);
}

/// A walk through a generated city at a low height, looking along the
/// street; t = 0 .. 1 crosses 40 % of the model.
inline ViewSnapshot street_view(const Hierarchy& h, float t) {
  const glm::vec3 lo = h.bounds_min(), hi = h.bounds_max();
  const glm::vec3 c = 0.5f * (lo + hi);
  const float ext = glm::length(hi - lo);
  const glm::vec3 eye = c + ext * glm::vec3(-0.3f + 0.4f * t, -0.02f, 0.03f);
  const glm::vec3 target = eye + glm::vec3(std::cos(0.6f * t), std::sin(0.6f * t), -0.05f);
  return ViewSnapshot::look_at(eye, target, {640, 360}, 0.9f, 0.0005f * ext, 4.0f * ext);
}

/// One iteration of S on CUT as the Feedback Stage runs it: frame 0, the
/// strategy's current parameter version, fresh node and query lists.
inline IterationResult iterate_once(Strategy& s, const Hierarchy& h, TreeCut& cut,
                                    const ViewSnapshot& view,
                                    const std::atomic<bool>* cancel = nullptr) {
  std::vector<NodeId> nodes;
  std::vector<QueryRequest> queries;
  IterationInput in{h, view, 0, cancel, s.params_version()};
  IterationOutput out;
  out.cut = &cut;
  out.nodes = &nodes;
  out.queries = &queries;
  s.iterate(in, out);
  return out.result;
}

/// Watches refine and coarsen operations between consecutive cuts under a
/// static view and counts the oscillations the paper's thresholds must prevent
/// (section 4): a node coarsened and later refined again, a node refined in
/// one iteration and coarsened in the next, a node refined or coarsened twice.
/// A node that leaves the cut while nodes below it enter was refined; a node
/// that enters while nodes below it leave was coarsened (what an ancestor's
/// operation does to it is not counted against it).
class OperationRecorder {
 public:
  explicit OperationRecorder(const Hierarchy& h)
      : h_(h), refined_at_(h.node_count(), -1), coarsened_at_(h.node_count(), -1) {}

  void record(std::span<const NodeId> before, std::span<const NodeId> after) {
    ++iteration_;
    const TreeCut a = TreeCut::from_nodes(h_, before);
    const TreeCut b = TreeCut::from_nodes(h_, after);
    for (const NodeId n : before) {
      if (b.contains(n) || has_ancestor_in(b, n)) continue;
      if (coarsened_at_[n] >= 0 || refined_at_[n] >= 0) ++flip_flops_;
      refined_at_[n] = iteration_;
    }
    for (const NodeId n : after) {
      if (a.contains(n) || has_ancestor_in(a, n)) continue;
      if (coarsened_at_[n] >= 0 || refined_at_[n] == iteration_ - 1) ++flip_flops_;
      coarsened_at_[n] = iteration_;
    }
  }
  [[nodiscard]] std::size_t flip_flops() const { return flip_flops_; }

 private:
  [[nodiscard]] bool has_ancestor_in(const TreeCut& cut, NodeId n) const {
    for (NodeId p = h_.parent(n); p != kNoNode; p = h_.parent(p)) {
      if (cut.contains(p)) return true;
    }
    return false;
  }
  const Hierarchy& h_;
  std::vector<int> refined_at_;
  std::vector<int> coarsened_at_;
  int iteration_ = 0;
  std::size_t flip_flops_ = 0;
};

/// A test strategy that never converges: every iteration applies `ops`
/// random refines/coarsens and, with `spin` > 0, busy-waits a random number of
/// loop turns (up to `spin`), yielding now and then: the Feedback Stage side
/// of the stress tests' randomized delays.
class RandomWalkStrategy final : public Strategy {
 public:
  explicit RandomWalkStrategy(std::uint64_t seed = 1)
      : Strategy({{"ops", "operations per iteration", 8, 0, 1e6, true},
                  {"spin", "maximal busy-wait turns per iteration", 0, 0, 1e9, true}}),
        rng_(seed) {}
  [[nodiscard]] std::string_view name() const override { return "random_walk"; }
  [[nodiscard]] Mode mode() const override { return Mode::Evolve; }
  void reset(const Hierarchy&) override {}
  void iterate(const IterationInput& in, IterationOutput& out) override {
    TreeCut& cut = *out.cut;
    const auto ops = static_cast<int>(param_at(0));
    for (int i = 0; i < ops && !in.cancelled(); ++i) {
      const NodeId n = cut.nodes()[rng_() % cut.size()];
      ++out.result.visited;
      if (rng_() % 2 == 0) {
        out.result.refined += cut.refine(in.hierarchy, n) ? 1u : 0u;
      } else if (const NodeId p = in.hierarchy.parent(n); p != kNoNode) {
        out.result.coarsened += cut.coarsen(in.hierarchy, p) ? 1u : 0u;
      }
    }
    if (const auto spin = static_cast<std::uint64_t>(param_at(1)); spin > 0) {
      const std::uint64_t turns = rng_() % spin;
      for (std::uint64_t t = 0; t < turns; ++t) sink_ = sink_ + t;
      if (rng_() % 64 == 0) std::this_thread::yield();
    }
    out.result.converged = false;
  }

 private:
  std::mt19937_64 rng_;
  volatile std::uint64_t sink_ = 0;
};

}  // namespace treecut::test
