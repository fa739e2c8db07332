// The Process step of "Parallel TreeCut Manipulation" (Marton, Schiffner et
// al.), section 3, figure 2, on the stage thread (or the caller of step()):
// Extract the inputs from the inbox, Iterate the strategy into the back
// list, check and Publish it sorted, hand the outbox over and return to
// Wait; for a model and for a scene (the objects one after the other, with
// their offsets), a failure of either becoming one StrategyError. See
// feedback_stage.hpp and docs/threading.md for the ownership rules this file
// relies on. Model-checked: tests/model/exchange.pml is this protocol in
// Promela, with the same names (process with Extract, Iterate, Publish);
// change both.
#include <cxxabi.h>

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
#include <typeinfo>
#include <utility>

#include "feedback_stage_impl.hpp"
#include "treecut/feedback_stage.hpp"

namespace treecut {
namespace {

// The name of the type of the exception being handled ("int", "std::string").
std::string current_exception_type() {
  const std::type_info* t = abi::__cxa_current_exception_type();
  if (t == nullptr) return "unknown";
  int status = 0;
  char* demangled = abi::__cxa_demangle(t->name(), nullptr, nullptr, &status);
  std::string name = status == 0 && demangled != nullptr ? demangled : t->name();
  std::free(demangled);
  return name;
}

std::uint64_t ns_between(std::chrono::steady_clock::time_point a,
                         std::chrono::steady_clock::time_point b) {
  return static_cast<std::uint64_t>(
      std::chrono::duration_cast<std::chrono::nanoseconds>(b - a).count());
}

// Object i's list in a buffer of n objects' lists back to back (empty when
// the buffer does not hold n lists).
std::span<const NodeId> object_list(const std::vector<NodeId>& nodes,
                                    const std::vector<std::uint32_t>& offsets, std::size_t n,
                                    std::size_t i) {
  return offsets.size() == n + 1
             ? std::span<const NodeId>(nodes).subspan(offsets[i], offsets[i + 1] - offsets[i])
             : std::span<const NodeId>();
}

void refuse_scene_queries(const std::vector<QueryRequest>& queries) {
  // The query executor places a node of the one model it draws; on a
  // scene it would test the wrong place. Refused, not answered wrongly.
  if (!queries.empty()) {
    throw std::runtime_error("asked for " + std::to_string(queries.size()) +
                             " GPU queries on a scene: queries are answered for single models "
                             "only (docs/architecture.md, \"Scenes through the stage\")");
  }
}

[[noreturn]] void refuse_object_cut(bool& invalid_cut, std::size_t i, const std::string& why) {
  invalid_cut = true;
  throw std::runtime_error("object " + std::to_string(i) + ": returned an invalid cut: " + why);
}

// The object's model space: the view with its world matrix folded in, so an
// unchanged strategy sees what it sees on a model.
void fold_object_view(ViewSnapshot& v, const ViewSnapshot& view, const SceneObject& o) {
  v.view = view.view * o.world;
  v.projection = view.projection;
  v.viewport = view.viewport;
  // The light into model space (a direction: the inverse's linear part),
  // renormalized only where that changed its length (a rotation or the
  // identity leaves it bit for bit as the model would see it).
  const glm::vec3 light = glm::mat3(o.world_inverse) * view.light_dir;
  const float len = glm::length(light);
  v.light_dir = !(len > 0.0f) ? view.light_dir : std::abs(len - 1.0f) > 1e-6f ? light / len : light;
  v.frame = view.frame;
  v.version = view.version;
  v.visibility.clear();  // no queries on a scene (see refuse_scene_queries)
  v.finalize();
}

void add_object_result(IterationResult& total, const IterationResult& r) {
  total.visited += r.visited;
  total.refined += r.refined;
  total.coarsened += r.coarsened;
  total.culled += r.culled;
  total.backfacing += r.backfacing;
  total.too_small += r.too_small;
  total.blocked += r.blocked;
  total.counters.add_all(r.counters);
  total.converged = total.converged && r.converged;
  total.cancelled = total.cancelled || r.cancelled;
}

}  // namespace

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
    // Extract (figure 2): take the inputs the render thread handed over.
    bool reset = false;
    if (inbox_.strategy) {
      strategy_ = std::move(inbox_.strategy);  // the old one dies on this thread
      reset = true;
    }
    if (inbox_.model) {
      hierarchy_ = std::move(inbox_.model->hierarchy);
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
    const Clock::time_point t1 = Clock::now();

    ListBuffer& back = buffers_[inbox_.back];
    back.nodes.clear();
    back.queries.clear();
    const IterationInput input{*hierarchy_, view_, 0, &cancel_, strategy_->params_version()};
    IterationOutput output;
    output.cut = &cut_;
    output.nodes = &back.nodes;
    output.queries = &back.queries;
    strategy_->iterate(input, output);
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
    const Clock::time_point t3 = Clock::now();

    out.ready = true;
    out.result = output.result;
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

// Stage thread, Process, on a scene: Extract as for a model, then the
// objects one after the other into the back list, each list sorted, with
// the object offsets beside them in the same buffer.
void FeedbackStage::Impl::process_scene(Outbox& out) {
  using Clock = std::chrono::steady_clock;
  const Clock::time_point t0 = out.started;
  const bool evolve = extract_scene();
  const Clock::time_point t1 = Clock::now();

  ListBuffer& back = buffers_[inbox_.back];
  back.nodes.clear();
  back.offsets.clear();
  back.queries.clear();
  SceneTotals totals;
  if (scene_strategy_ != nullptr) {
    iterate_scene_strategy(out, totals);
  } else {
    iterate_object_strategies(evolve, out, totals);
    if (!evolve) cut_stale_ = true;
  }
  const IterationResult& total = totals.result;
  back.generation = inbox_.generation;
  const Clock::time_point t3 = Clock::now();
  out.ready = true;
  out.result = total;
  out.result.converged = total.converged && !total.cancelled;
  out.result.cut_size = back.nodes.size();
  out.objects = totals.objects;
  out.extract_ns = ns_between(t0, t1);
  const std::uint64_t all = ns_between(t1, t3);
  out.iteration_ns = all > totals.publish_ns ? all - totals.publish_ns : 0;
  out.publish_ns = totals.publish_ns;
}

// Extract on a scene: the inbox's strategy, parameters and view taken over.
// Returns whether the objects' strategies evolve their cuts; if so, stale
// object cuts are rebuilt from the front lists.
bool FeedbackStage::Impl::extract_scene() {
  const std::size_t n = scene_->objects.size();
  // Taken out of the inbox first: a failure below leaves nothing behind
  // for the next request to find.
  std::unique_ptr<Strategy> incoming = std::move(inbox_.strategy);
  const StrategyFactory factory = std::move(inbox_.factory);
  inbox_.factory = nullptr;
  std::vector<std::pair<std::string, double>> params;
  params.swap(inbox_.params);
  if (incoming) {
    make_object_strategies(std::move(incoming), factory);
    cut_stale_ = true;
  }
  for (const auto& [name, value] : params) {
    for (const auto& s : object_strategies_) s->set_param(name, value);
  }
  std::swap(view_, inbox_.view);
  const bool evolve =
      scene_strategy_ == nullptr && object_strategies_[0]->mode() == Strategy::Mode::Evolve;
  if (evolve && (cut_stale_ || object_cuts_.size() != n)) {
    // As for a model: the front lists are the cuts to evolve (an object
    // whose list is empty, drawn by a scene-level strategy, starts at its root).
    const ListBuffer& front = buffers_[inbox_.front];
    object_cuts_.resize(n);
    for (std::size_t i = 0; i < n; ++i) {
      const std::span<const NodeId> list = object_list(front.nodes, front.offsets, n, i);
      object_cuts_[i] = list.empty() ? TreeCut::root_cut(scene_->hierarchy(i))
                                     : TreeCut::from_nodes(scene_->hierarchy(i), list);
    }
    cut_stale_ = false;
  }
  return evolve;
}

// Iterate and Publish with a scene-level strategy: one call for every
// object, its list checked and each object's part sorted.
void FeedbackStage::Impl::iterate_scene_strategy(Outbox& out, SceneTotals& totals) {
  using Clock = std::chrono::steady_clock;
  const std::size_t n = scene_->objects.size();
  const ListBuffer& front = buffers_[inbox_.front];
  ListBuffer& back = buffers_[inbox_.back];
  const SceneIterationInput input{*scene_, view_,
                                  &cancel_,      object_strategies_[0]->params_version(),
                                  front.nodes,   front.offsets};
  SceneIterationOutput output;
  output.nodes = &back.nodes;
  output.offsets = &back.offsets;
  output.queries = &back.queries;
  scene_strategy_->iterate_scene(input, output);
  const Clock::time_point t2 = Clock::now();
  refuse_scene_queries(back.queries);
  std::vector<std::uint32_t>& off = back.offsets;
  if (off.size() != n + 1 || off.front() != 0 || off.back() != back.nodes.size() ||
      !std::is_sorted(off.begin(), off.end())) {
    out.invalid_cut = true;
    throw std::runtime_error("returned an invalid scene list: " + std::to_string(off.size()) +
                             " offsets for " + std::to_string(n) + " objects and " +
                             std::to_string(back.nodes.size()) + " nodes");
  }
  for (std::size_t i = 0; i < n; ++i) {
    const auto first = back.nodes.begin() + off[i], last = back.nodes.begin() + off[i + 1];
    if (first == last) continue;  // not drawn
    if (std::string why = check_cut(scene_->hierarchy(i), {first, last}); !why.empty()) {
      refuse_object_cut(out.invalid_cut, i, why);
    }
    if (!std::is_sorted(first, last)) std::sort(first, last);
  }
  totals.result = output.result;
  totals.objects = n;
  cut_stale_ = true;
  totals.publish_ns = ns_between(t2, Clock::now());
}

// Iterate and Publish with a strategy per object, one object after the
// other; once cancelled, the objects not reached keep the lists they have.
void FeedbackStage::Impl::iterate_object_strategies(bool evolve, Outbox& out, SceneTotals& totals) {
  const std::size_t n = scene_->objects.size();
  const ListBuffer& front = buffers_[inbox_.front];
  ListBuffer& back = buffers_[inbox_.back];
  IterationResult& total = totals.result;
  back.offsets.reserve(n + 1);
  back.offsets.push_back(0);
  total.converged = true;
  for (std::size_t i = 0; i < n; ++i) {
    if (!total.cancelled && !cancel_.load(std::memory_order_relaxed)) {
      iterate_object(i, evolve, out, totals);
    } else {
      total.cancelled = true;
      if (evolve) {
        const TreeCut& cut = object_cuts_[i];
        back.nodes.insert(back.nodes.end(), cut.nodes().begin(), cut.nodes().end());
      } else if (const std::span<const NodeId> list = object_list(front.nodes, front.offsets, n, i);
                 !list.empty()) {
        back.nodes.insert(back.nodes.end(), list.begin(), list.end());
      } else {
        back.nodes.push_back(scene_->hierarchy(i).root());
      }
    }
    if (back.nodes.size() >= std::numeric_limits<std::uint32_t>::max()) {
      throw std::runtime_error("the scene's cut has more than 2^32 - 1 nodes");
    }
    back.offsets.push_back(static_cast<std::uint32_t>(back.nodes.size()));
  }
}

// Object i's strategy in the object's model space, its cut checked, sorted
// and appended to the back list.
void FeedbackStage::Impl::iterate_object(std::size_t i, bool evolve, Outbox& out,
                                         SceneTotals& totals) {
  using Clock = std::chrono::steady_clock;
  const SceneObject& o = scene_->objects[i];
  const Hierarchy& h = scene_->hierarchy(i);
  ListBuffer& back = buffers_[inbox_.back];
  ViewSnapshot& v = object_view_;
  fold_object_view(v, view_, o);
  v.derived.pixel_scale *= object_size_factor_[v.derived.perspective ? 1 : 0][i];
  Strategy& s = *object_strategies_[i];
  object_nodes_.clear();
  const IterationInput input{h, v, static_cast<std::uint32_t>(i), &cancel_, s.params_version()};
  IterationOutput output;
  output.cut = evolve ? &object_cuts_[i] : &cut_;  // a Rebuild strategy ignores it
  output.nodes = &object_nodes_;
  output.queries = &back.queries;
  s.iterate(input, output);
  refuse_scene_queries(back.queries);
  const Clock::time_point p0 = Clock::now();
  if (evolve) {
    TreeCut& cut = object_cuts_[i];
    if (std::string why = check_cut(h, cut.nodes()); !why.empty()) {
      refuse_object_cut(out.invalid_cut, i, why);
    }
    if (cut.disorder() > 0) cut.sort(sort_scratch_);
    back.nodes.insert(back.nodes.end(), cut.nodes().begin(), cut.nodes().end());
  } else {
    if (std::string why = check_cut(h, object_nodes_); !why.empty()) {
      refuse_object_cut(out.invalid_cut, i, why);
    }
    if (!std::is_sorted(object_nodes_.begin(), object_nodes_.end())) {
      sort_node_ids(object_nodes_, h.node_count(), sort_scratch_);
    }
    back.nodes.insert(back.nodes.end(), object_nodes_.begin(), object_nodes_.end());
  }
  totals.publish_ns += ns_between(p0, Clock::now());
  add_object_result(totals.result, output.result);
  ++totals.objects;
}

// Stage thread, inside a catch handler: whatever the strategy threw (also
// `throw 42`) becomes one StrategyError naming it and its plugin; nothing
// escapes this thread (no terminate).
void FeedbackStage::Impl::fail(Outbox& out) {
  std::string problem;
  try {
    throw;
  } catch (const std::exception& e) {
    problem = out.invalid_cut ? e.what() : "threw " + current_exception_type() + ": " + e.what();
  } catch (...) {
    problem = "threw an exception of type " + current_exception_type();
  }
  const Strategy* s = scene_ ? (object_strategies_.empty() ? nullptr : object_strategies_[0].get())
                             : strategy_.get();
  const std::string_view name = s != nullptr ? s->name() : std::string_view("?");
  const std::string origin = s != nullptr ? s->origin() : std::string();
  try {
    out.error = std::make_exception_ptr(StrategyError(std::string(name), origin, problem));
  } catch (...) {
    out.error = std::current_exception();  // bad_alloc while describing it
  }
  out.ready = false;
  // An Evolve strategy may have left its cut half-changed: the next
  // iteration starts again from the front list.
  cut_stale_ = true;
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
