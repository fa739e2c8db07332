// A FeedbackStage on a scene: the StageScene of a loaded Scene, the
// construction (every object at its model's root, one list with object
// offsets), the size factors of stretched objects, and the strategies a scene
// runs: one SceneStrategy for all objects, or one instance of a per-object
// strategy per object, refused past kMaxPerObjectNodes; and the scene's
// Process step (Extract, then one scene-level iteration or the objects one
// after the other, each object's list checked and sorted); docs/architecture.md, "Scenes
// through the stage".
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <glm/geometric.hpp>
#include <glm/mat3x3.hpp>
#include <glm/matrix.hpp>
#include <limits>
#include <span>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "feedback_stage_impl.hpp"
#include "treecut/error.hpp"
#include "treecut/feedback_stage.hpp"
#include "treecut/paged_hierarchy.hpp"
#include "treecut/scene.hpp"

namespace treecut {

using detail::fold_object_view;
using detail::ns_between;
using detail::object_list;

namespace {

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

std::span<const NodeId> detail::object_list(const std::vector<NodeId>& nodes,
                                            const std::vector<std::uint32_t>& offsets,
                                            std::size_t n, std::size_t i) {
  return offsets.size() == n + 1
             ? std::span<const NodeId>(nodes).subspan(offsets[i], offsets[i + 1] - offsets[i])
             : std::span<const NodeId>();
}

// The object's model space: the view with its world matrix folded in, so an
// unchanged strategy sees what it sees on a model.
void detail::fold_object_view(ViewSnapshot& v, const ViewSnapshot& view, const SceneObject& o) {
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

std::uint64_t StageScene::object_nodes() const {
  std::uint64_t n = 0;
  for (const SceneObject& o : objects) {
    if (o.model >= models.size() || !models[o.model]) continue;
    std::uint64_t nodes = models[o.model]->node_count();
    // A model drawn from its pages holds no more than its budget's nodes,
    // and a strategy's state follows what is resident.
    if (const PagedHierarchy* p = paged_model(o.model); p && p->memory_budget() != 0)
      nodes = std::min(nodes, p->memory_budget() / p->bytes_per_node());
    n += nodes;
  }
  return n;
}

std::shared_ptr<const StageScene> stage_scene(const Scene& scene) {
  auto s = std::make_shared<StageScene>();
  s->models.reserve(scene.models.size());
  for (const SceneModel& m : scene.models) s->models.push_back(m.hierarchy);
  // Pages per model, only when one model at least is drawn from them.
  if (std::any_of(scene.models.begin(), scene.models.end(),
                  [](const SceneModel& m) { return m.paged != nullptr; }))
    for (const SceneModel& m : scene.models) s->paged.push_back(m.paged);
  s->objects.reserve(scene.objects.size());
  s->objects = scene.objects;
  return s;
}

FeedbackStage::Impl::Impl(std::shared_ptr<const StageScene> scene, const StrategyFactory& factory,
                          StageOptions options)
    : options_(options), scene_(std::move(scene)) {
  if (!scene_ || scene_->objects.empty()) {
    throw std::invalid_argument("FeedbackStage: the scene has no objects");
  }
  if (!factory) throw std::invalid_argument("FeedbackStage: no strategy factory");
  if (options_.list_buffers < 2) throw std::invalid_argument("FeedbackStage: fewer than 2 buffers");
  for (const auto& m : scene_->models) {
    if (!m || m->empty()) throw std::invalid_argument("FeedbackStage: a model has no hierarchy");
  }
  const std::size_t n = scene_->objects.size();
  if (n >= std::numeric_limits<std::uint32_t>::max()) {
    throw std::invalid_argument("FeedbackStage: too many objects");
  }
  object_size_factor_[0].reserve(n);
  object_size_factor_[1].reserve(n);
  for (const SceneObject& o : scene_->objects) {
    if (o.model >= scene_->models.size()) {
      throw std::invalid_argument("FeedbackStage: an object's model index is out of range");
    }
    // A strategy sizes a node by its model-space radius over its model-space
    // distance. Under a stretch that ratio is no bound of the world's: the
    // radius grows by up to sigma_max, the distance shrinks by down to
    // sigma_min. The pixel scale takes their ratio (perspective) or sigma_max
    // (orthographic), so the projected radius stays an upper bound; a
    // similarity's ratio is exactly 1 (the identity changes nothing).
    const std::array<double, 3> sv = singular_values(o.world);
    const double hi = sv[0], lo = sv[2];
    object_size_factor_[0].push_back(static_cast<float>(hi));
    object_size_factor_[1].push_back(lo > 0.0 ? static_cast<float>(hi / lo) : 1.0f);
  }
  std::unique_ptr<Strategy> first = factory();
  if (!first) throw std::invalid_argument("FeedbackStage: the factory made no strategy");
  check_scene_strategy(*first);

  buffers_.resize(options_.list_buffers);
  ListBuffer& list = buffers_[0];
  list.nodes.reserve(n);
  list.offsets.reserve(n + 1);
  list.offsets.push_back(0);
  for (std::size_t i = 0; i < n; ++i) {
    list.nodes.push_back(scene_->models[scene_->objects[i].model]->root());
    list.offsets.push_back(static_cast<std::uint32_t>(i + 1));
  }
  list.generation = 1;
  list.use = BufferUse::Front;
  front_ = 0;
  front_view_ = list_of(front_);

  strategy_name_ = std::string(first->name());
  pending_.specs = first->param_specs();
  make_object_strategies(std::move(first), factory);
  if (!scene_strategy_ && object_strategies_[0]->mode() == Strategy::Mode::Evolve) {
    object_cuts_.reserve(n);
    for (std::size_t i = 0; i < n; ++i)
      object_cuts_.push_back(TreeCut::root_cut(scene_->hierarchy(i)));
  } else {
    cut_stale_ = true;
  }
  running_ = object_strategies_[0].get();
  if (options_.launch == Launch::Thread) thread_ = std::thread([this] { run(); });
}

// Render thread (constructor, set_strategy): per-object instances are state
// for every node of every object; refused past the limit, before any is made.
void FeedbackStage::Impl::check_scene_strategy(const Strategy& probe) const {
  if (std::string why = per_object_limit_problem(*scene_, probe); !why.empty()) {
    throw InputError(why);
  }
}

std::string scene_strategy_problem(const Strategy& probe) {
  if (!probe.asks_queries()) return {};
  return describe_strategy(probe.name(), probe.origin()) +
         " asks for GPU occlusion queries, which are answered for single models only "
         "(docs/architecture.md, \"Scenes through the stage\"); use a strategy without "
         "queries for a scene";
}

std::string per_object_limit_problem(const StageScene& scene, const Strategy& probe) {
  if (std::string why = scene_strategy_problem(probe); !why.empty()) return why;
  if (dynamic_cast<const SceneStrategy*>(&probe) != nullptr) return {};
  const std::uint64_t nodes = scene.object_nodes();
  if (nodes <= kMaxPerObjectNodes) return {};
  return ("a scene of " + std::to_string(scene.objects.size()) + " objects and " +
          std::to_string(nodes) +
          " nodes in all: " + describe_strategy(probe.name(), probe.origin()) +
          " runs once per object, at most " + std::to_string(kMaxPerObjectNodes) +
          " nodes in all; use a scene-level strategy (SceneStrategy, e.g. 'budget') "
          "or models of fewer points");
}

// The instances a scene runs: `first` and, for a per-object strategy, one
// more from `factory` per further object, each reset for its model.
void FeedbackStage::Impl::make_object_strategies(std::unique_ptr<Strategy> first,
                                                 const StrategyFactory& factory) {
  // Made aside and swapped in whole: a factory or reset that throws leaves
  // the instances of the strategy before (the iteration fails, the next
  // one runs them). The first instance outlives such a failure: the render
  // thread names it if the destructor waits for an iteration (running_).
  std::vector<std::unique_ptr<Strategy>> made;
  SceneStrategy* scene_level = dynamic_cast<SceneStrategy*>(first.get());
  made.push_back(std::move(first));
  try {
    if (scene_level != nullptr) {
      scene_level->reset_scene(*scene_);
    } else {
      const std::size_t n = scene_->objects.size();
      made.reserve(n);
      for (std::size_t i = 1; i < n; ++i) {
        std::unique_ptr<Strategy> s = factory ? factory() : nullptr;
        if (!s) {
          throw std::runtime_error("the strategy factory made no instance for object " +
                                   std::to_string(i));
        }
        made.push_back(std::move(s));
      }
      for (std::size_t i = 0; i < n; ++i) made[i]->reset(scene_->hierarchy(i));
    }
  } catch (...) {
    failed_first_ = std::move(made.front());
    throw;
  }
  object_strategies_.swap(made);
  scene_strategy_ = scene_level;
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
  // Models drawn from their pages: what was read joins them now, between
  // iterations (paged_hierarchy.hpp).
  if (scene_paged()) publish_scene_pages();
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
  if (scene_paged()) {
    follow_scene_pages(out);
    out.publish_ns += ns_between(t3, Clock::now());
  }
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
  const SceneIterationInput input{*scene_,     view_,
                                  &cancel_,    object_strategies_[0]->params_version(),
                                  front.nodes, front.offsets};
  SceneIterationOutput output;
  output.nodes = &back.nodes;
  output.offsets = &back.offsets;
  output.queries = &back.queries;
  if (scene_paged()) output.wanted = &scene_wanted_;
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
  // A model drawn from its pages: what its pages did is every instance's input.
  const PagedHierarchy* paged = scene_->paged_model(o.model);
  const std::span<const NodeId> revealed =
      paged ? std::span<const NodeId>(model_revealed_[o.model]) : std::span<const NodeId>();
  const std::span<const NodeId> concealed =
      paged ? std::span<const NodeId>(model_concealed_[o.model]) : std::span<const NodeId>();
  const IterationInput input{
      h,        v,         static_cast<std::uint32_t>(i),       &cancel_, s.params_version(),
      revealed, concealed, paged && paged->stats().memory_short};
  IterationOutput output;
  output.cut = evolve ? &object_cuts_[i] : &cut_;  // a Rebuild strategy ignores it
  output.nodes = &object_nodes_;
  output.queries = &back.queries;
  object_wanted_.clear();
  if (paged) output.wanted = &object_wanted_;
  s.iterate(input, output);
  for (const NodeId w : object_wanted_) scene_wanted_.push_back({static_cast<std::uint32_t>(i), w});
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

}  // namespace treecut
