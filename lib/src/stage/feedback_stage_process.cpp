// The Process step of "Parallel TreeCut Manipulation" (Marton, Schiffner et
// al.), section 3, figure 2, on the stage thread (or the caller of step()):
// Extract the inputs from the inbox, Iterate the strategy into the back
// list, check and Publish it sorted, hand the outbox over and return to
// Wait. A scene's Process is in feedback_stage_scene.cpp, the StrategyError
// a failure becomes in feedback_stage_errors.cpp. See
// feedback_stage.hpp and docs/threading.md for the ownership rules this file
// relies on. Model-checked: tests/model/exchange.pml is this protocol in
// Promela, with the same names (process with Extract, Iterate, Publish);
// change both.

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <glm/geometric.hpp>
#include <glm/mat3x3.hpp>
#include <glm/matrix.hpp>
#include <limits>
#include <stdexcept>
#include <string>
#include <utility>

#include "feedback_stage_impl.hpp"
#include "treecut/feedback_stage.hpp"

namespace treecut {

using detail::ns_between;

// Extract (figure 2), stage thread in Process: take the inputs the render
// thread handed over (a strategy, a model, parameters, the view) and, for
// an Evolve strategy after a Rebuild or a failure, the cut to evolve.
void FeedbackStage::Impl::extract() {
  bool reset = false;
  if (inbox_.strategy) {
    strategy_ = std::move(inbox_.strategy);  // the old one dies on this thread
    reset = true;
  }
  if (inbox_.model) {
    hierarchy_ = std::move(inbox_.model->hierarchy);
    paged_ = std::move(inbox_.model->paged);
    revealed_.clear(), concealed_.clear();
    cut_ = std::move(inbox_.model->cut);
    cut_stale_ = false;
    inbox_.model.reset();
    reset = true;
  }
  if (reset) strategy_->reset(*hierarchy_);
  for (const auto& [name, value] : inbox_.params) strategy_->set_param(name, value);
  inbox_.params.clear();
  std::swap(view_, inbox_.view);
  if (strategy_->mode() == Strategy::Mode::Evolve && cut_stale_) {
    // The last iteration rebuilt the cut as a plain list, or failed: the
    // front list (the render thread only reads it) is the cut to evolve,
    // unless it belongs to the hierarchy a failed model switch replaced.
    const ListBuffer& front = buffers_[inbox_.front];
    cut_ = front.hierarchy == hierarchy_ ? TreeCut::from_nodes(*hierarchy_, front.nodes)
                                         : TreeCut::root_cut(*hierarchy_);
    cut_stale_ = false;
  }
}

// Feedback Stage side, state == Process: everything in the inbox, the back
// buffer and the stage-only members is ours; the front list is read-only.
void FeedbackStage::Impl::process() {
  using Clock = std::chrono::steady_clock;
  Outbox out;
  out.started = Clock::now();
  if (scene_) {
    try {
      process_scene(out);
    } catch (...) {
      fail(out);
    }
    outbox_ = std::move(out);
    state_.store(State::Wait, std::memory_order_release);
    state_.notify_all();
    return;
  }
  try {
    const Clock::time_point t0 = out.started;
    extract();
    const Clock::time_point t1 = Clock::now();

    ListBuffer& back = buffers_[inbox_.back];
    back.nodes.clear();
    back.queries.clear();
    // A paged model: the pages read since the last iteration join the
    // hierarchy now, between iterations (paged_hierarchy.hpp).
    if (paged_) paged_->publish(&revealed_);
    const IterationInput input{*hierarchy_,
                               view_,
                               0,
                               &cancel_,
                               strategy_->params_version(),
                               revealed_,
                               concealed_,
                               paged_ && paged_->stats().memory_short};
    IterationOutput output;
    output.cut = &cut_;
    output.nodes = &back.nodes;
    output.queries = &back.queries;
    wanted_.clear();
    if (paged_) output.wanted = &wanted_;
    strategy_->iterate(input, output);
    revealed_.clear(), concealed_.clear();
    const Clock::time_point t2 = Clock::now();

    // The host checks what the strategy hands back before anybody draws it.
    const bool evolve = strategy_->mode() == Strategy::Mode::Evolve;
    if (std::string why = check_cut(evolve ? cut_.nodes() : std::span<const NodeId>(back.nodes));
        !why.empty()) {
      out.invalid_cut = true;
      throw std::runtime_error("returned an invalid cut: " + why);
    }

    // Publish in ascending id order, sorted here rather than on the render
    // thread (a renderer draws in id order, see CutBuffer::upload). The
    // evolving cut is nearly sorted, so its sort is a merge of the few moved
    // nodes; it also enters the next iteration sorted (TreeCut::sort).
    if (strategy_->mode() == Strategy::Mode::Evolve) {
      if (cut_.disorder() > 0) cut_.sort(sort_scratch_);
      back.nodes.assign(cut_.nodes().begin(), cut_.nodes().end());
    } else {
      if (!std::is_sorted(back.nodes.begin(), back.nodes.end())) {
        sort_node_ids(back.nodes, hierarchy_->node_count(), sort_scratch_);
      }
      cut_stale_ = true;
    }
    if (back.hierarchy != hierarchy_) back.hierarchy = hierarchy_;
    back.generation = inbox_.generation;
    out.result = output.result;
    if (paged_) follow_pages(back.nodes, out);
    const Clock::time_point t3 = Clock::now();

    out.ready = true;
    out.result.cut_size = back.nodes.size();
    out.extract_ns = ns_between(t0, t1);
    out.iteration_ns = ns_between(t1, t2);
    out.publish_ns = ns_between(t2, t3);
  } catch (...) {
    fail(out);
  }
  outbox_ = std::move(out);
  // Back to Wait with release: the render thread that sees Wait sees the
  // back list and the outbox complete.
  state_.store(State::Wait, std::memory_order_release);
  state_.notify_all();
}

// Stage thread, after an iteration on a paged model whose list is LIST
// (sorted): asks for the pages the strategy wanted, most wanted first, and
// gives back what neither LIST nor the front list (the render thread's)
// holds, so that no list anyone reads loses a node. The pages' counters
// join the iteration's.
void FeedbackStage::Impl::follow_pages(std::span<const NodeId> list, Outbox& out) {
  paged_->request(paged_->rank(wanted_, view_));
  // The back list and the front list (the one drawn while this runs; the
  // render thread exchanges lists only in Wait), each on its own.
  const ListBuffer& front = buffers_[inbox_.front];
  auto holds = [](std::span<const NodeId> nodes) {
    return [nodes](NodeId n) { return std::binary_search(nodes.begin(), nodes.end(), n); };
  };
  std::vector<PagedHierarchy::ListHolds> lists{holds(list)};
  if (front.hierarchy == hierarchy_) lists.push_back(holds(front.nodes));
  paged_->evict(lists, &concealed_);
  const PagingStats s = paged_->stats();
  // Not converged while pages it wants are on their way: the iterations
  // that follow take them in.
  if (!wanted_.empty() || s.in_flight > 0) out.result.converged = false;
  detail::report_pages(s, wanted_.size(), out.result.counters);
}

void detail::report_pages(const PagingStats& s, std::size_t wanted, Counters& c) {
  c.set("pages_resident", double(s.resident_pages), "pages");
  c.set("pages_resident_mib", double(s.resident_bytes) / double(1 << 20), "MiB");
  c.set("pages_requested", double(s.requested), "pages");
  c.set("pages_in_flight", double(s.in_flight), "groups");
  c.set("pages_wanted", double(wanted), "nodes");
  c.set("pages_loaded", double(s.loaded), "groups");
  c.set("pages_evicted", double(s.evicted), "groups");
  c.set("pages_failed", double(s.failed), "groups");
  c.set("pages_memory_short", s.memory_short ? 1.0 : 0.0, "flag");
}

// Stage thread. Always: ids in range and the cut's points add up to the
// leaf count (O(cut): catches an empty cut and a missing node). With
// options_.validate: every leaf exactly once (TreeCut::validate).
std::string FeedbackStage::Impl::check_cut(std::span<const NodeId> nodes) const {
  return check_cut(*hierarchy_, nodes);
}

std::string FeedbackStage::Impl::check_cut(const Hierarchy& h,
                                           std::span<const NodeId> nodes) const {
  if (nodes.empty()) return "the cut is empty";
  const std::uint32_t m = h.node_count();
  const auto counts = h.arrays().point_count;
  std::uint64_t points = 0;
  for (const NodeId n : nodes) {
    if (n >= m) return "node id " + std::to_string(n) + " out of range";
    points += counts[n];
  }
  if (points != h.leaf_count()) {
    return "its nodes hold " + std::to_string(points) + " points, the model has " +
           std::to_string(h.leaf_count());
  }
  if (options_.validate) return TreeCut::validate(h, nodes);
  return {};
}

}  // namespace treecut
