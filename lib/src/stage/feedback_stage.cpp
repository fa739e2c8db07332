// The wait/process exchange of "Parallel TreeCut Manipulation" (Marton,
// Schiffner et al.), section 3, figure 2. See feedback_stage.hpp and
// docs/threading.md for the ownership rules this file relies on.
// Model-checked: tests/model/exchange.pml is this protocol in Promela, with the
// same names (states, buffer uses, poll/exchange/request/retire,
// run/process with Extract, Iterate, Publish, the destructor); change both.
#include "treecut/feedback_stage.hpp"

#include <cxxabi.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <stdexcept>
#include <typeinfo>
#include <utility>

#if defined(__linux__)
#include <pthread.h>
#include <sched.h>
#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>
#endif

#include <glm/geometric.hpp>
#include <glm/mat3x3.hpp>
#include <glm/matrix.hpp>

#include "treecut/error.hpp"
#include "treecut/scene.hpp"

namespace treecut {
namespace {

#if defined(__linux__)
// Lowers a stage thread (`self`: the calling thread, else by its handle and
// tid; Linux keeps a nice value per thread, so PRIO_PROCESS with a thread id
// changes that thread only). `idle` chooses SCHED_IDLE over nice +19 for
// Idle: only a process that may raise the thread again uses SCHED_IDLE,
// since an unprivileged thread can never leave it (sched(7), RLIMIT_NICE).
void apply_low_priority(pthread_t thread, int tid, int base_nice, StagePriority priority,
                        bool idle) {
  if (priority == StagePriority::Low) {
    (void)setpriority(PRIO_PROCESS, static_cast<id_t>(tid), std::min(base_nice + 10, 19));
  } else if (priority == StagePriority::Idle) {
    if (idle) {
      const sched_param param{};
      (void)pthread_setschedparam(thread, SCHED_IDLE, &param);
    } else {
      (void)setpriority(PRIO_PROCESS, static_cast<id_t>(tid), 19);
    }
  }
}
#endif

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

#if !defined(NDEBUG)
constexpr bool kCheckedBuild = true;
#elif defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
constexpr bool kCheckedBuild = true;
#elif defined(__has_feature)
#if __has_feature(address_sanitizer) || __has_feature(thread_sanitizer) || \
    __has_feature(undefined_behavior_sanitizer)
constexpr bool kCheckedBuild = true;
#else
constexpr bool kCheckedBuild = false;
#endif
#else
constexpr bool kCheckedBuild = false;
#endif

std::uint64_t ns_between(std::chrono::steady_clock::time_point a,
                         std::chrono::steady_clock::time_point b) {
  return static_cast<std::uint64_t>(
      std::chrono::duration_cast<std::chrono::nanoseconds>(b - a).count());
}

}  // namespace

std::uint64_t StageScene::object_nodes() const {
  std::uint64_t n = 0;
  for (const Object& o : objects) {
    if (o.model < models.size() && models[o.model]) n += models[o.model]->node_count();
  }
  return n;
}

std::shared_ptr<const StageScene> stage_scene(const Scene& scene) {
  auto s = std::make_shared<StageScene>();
  s->models.reserve(scene.models.size());
  for (const SceneModel& m : scene.models) s->models.push_back(m.hierarchy);
  s->objects.reserve(scene.objects.size());
  for (const SceneObject& o : scene.objects) {
    s->objects.push_back(StageScene::Object{o.model, o.world, o.world_inverse});
  }
  return s;
}

bool validate_cuts_by_default() {
  return kCheckedBuild;
}

std::string describe_strategy(std::string_view name, std::string_view origin) {
  std::string d = "strategy '" + std::string(name) + "'";
  if (origin == "built-in") {
    d += " (built-in)";
  } else if (!origin.empty()) {
    d += " (plugin " + std::string(origin) + ")";
  }
  return d;
}

StrategyError::StrategyError(std::string strategy, std::string origin, const std::string& problem)
    : std::runtime_error(describe_strategy(strategy, origin) + ": " + problem),
      strategy_(std::move(strategy)),
      origin_(std::move(origin)) {}

FeedbackStage::FeedbackStage(Model model, std::unique_ptr<Strategy> strategy, StageOptions options)
    : options_(options) {
  if (!model.hierarchy || model.hierarchy->empty()) {
    throw std::invalid_argument("FeedbackStage: the model has no hierarchy");
  }
  if (!strategy) throw std::invalid_argument("FeedbackStage: no strategy");
  if (options_.list_buffers < 2) throw std::invalid_argument("FeedbackStage: fewer than 2 buffers");
  if (std::string why = model.cut.validate(*model.hierarchy); !why.empty()) {
    throw std::invalid_argument("FeedbackStage: invalid initial cut: " + why);
  }
  buffers_.resize(options_.list_buffers);
  ListBuffer& first = buffers_[0];
  first.nodes.assign(model.cut.nodes().begin(), model.cut.nodes().end());
  std::sort(first.nodes.begin(), first.nodes.end());  // once; every list is ascending
  first.hierarchy = model.hierarchy;
  first.generation = 1;
  first.use = BufferUse::Front;
  front_ = 0;
  front_view_ = list_of(front_);

  strategy_name_ = std::string(strategy->name());
  pending_.specs = strategy->param_specs();
  hierarchy_ = std::move(model.hierarchy);
  cut_ = std::move(model.cut);
  strategy_ = std::move(strategy);
  running_ = strategy_.get();
  strategy_->reset(*hierarchy_);
  if (options_.launch == Launch::Thread) thread_ = std::thread([this] { run(); });
}

FeedbackStage::FeedbackStage(std::shared_ptr<const StageScene> scene,
                             const StrategyFactory& factory, StageOptions options)
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
  scene_inputs_.reserve(n);
  object_size_factor_[0].reserve(n);
  object_size_factor_[1].reserve(n);
  for (const StageScene::Object& o : scene_->objects) {
    if (o.model >= scene_->models.size()) {
      throw std::invalid_argument("FeedbackStage: an object's model index is out of range");
    }
    scene_inputs_.push_back(
        SceneObjectInput{scene_->models[o.model].get(), o.world, o.world_inverse, o.model});
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
    for (const SceneObjectInput& o : scene_inputs_) {
      object_cuts_.push_back(TreeCut::root_cut(*o.hierarchy));
    }
  } else {
    cut_stale_ = true;
  }
  running_ = object_strategies_[0].get();
  if (options_.launch == Launch::Thread) thread_ = std::thread([this] { run(); });
}

// Render thread (constructor, set_strategy): per-object instances are state
// for every node of every object; refused past the limit, before any is made.
void FeedbackStage::check_scene_strategy(const Strategy& probe) const {
  if (std::string why = per_object_limit_problem(*scene_, probe); !why.empty()) {
    throw InputError(why);
  }
}

std::string per_object_limit_problem(const StageScene& scene, const Strategy& probe) {
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
void FeedbackStage::make_object_strategies(std::unique_ptr<Strategy> first,
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
      scene_level->reset_scene(scene_inputs_);
    } else {
      const std::size_t n = scene_inputs_.size();
      made.reserve(n);
      for (std::size_t i = 1; i < n; ++i) {
        std::unique_ptr<Strategy> s = factory ? factory() : nullptr;
        if (!s) {
          throw std::runtime_error("the strategy factory made no instance for object " +
                                   std::to_string(i));
        }
        made.push_back(std::move(s));
      }
      for (std::size_t i = 0; i < n; ++i) made[i]->reset(*scene_inputs_[i].hierarchy);
    }
  } catch (...) {
    failed_first_ = std::move(made.front());
    throw;
  }
  object_strategies_.swap(made);
  scene_strategy_ = scene_level;
}

FeedbackStage::~FeedbackStage() {
  cancel_.store(true, std::memory_order_relaxed);
  if (!thread_.joinable()) return;
  // Shutdown while Process runs: let the (cancelled) iteration return to Wait,
  // then tell the thread to exit. Only this thread moves Wait -> anything, so
  // no request can slip in between. A starved low-priority stage would reach
  // the cancel check late: raise it first. The iteration reads the stage's
  // lists, cut and hierarchy, so there is no safe way to leave without it:
  // past cancel_timeout the wait is reported, then goes on.
  using Clock = std::chrono::steady_clock;
  if (state_.load(std::memory_order_acquire) == State::Process) {
    set_boost(true);
    const Clock::time_point since = Clock::now();
    while (state_.load(std::memory_order_acquire) == State::Process &&
           Clock::now() - since < options_.cancel_timeout) {
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
    if (state_.load(std::memory_order_acquire) == State::Process) {
      char seconds[32];
      std::snprintf(seconds, sizeof seconds, "%.1f",
                    std::chrono::duration<double>(Clock::now() - since).count());
      const std::string what = describe_strategy(running_->name(), running_->origin()) +
                               " ignored cancellation for " + seconds + " s";
      if (options_.on_slow_cancel) {
        options_.on_slow_cancel(what);
      } else {
        std::fprintf(stderr, "warning: %s; waiting for it to return\n", what.c_str());
      }
    }
    while (state_.load(std::memory_order_acquire) == State::Process) {
      state_.wait(State::Process, std::memory_order_acquire);
    }
  }
  state_.store(State::Exit, std::memory_order_release);
  state_.notify_all();
  thread_.join();
}

void FeedbackStage::run() {
#if defined(__linux__)
  if (options_.priority != StagePriority::Normal) {
    const int tid = static_cast<int>(syscall(SYS_gettid));
    errno = 0;
    const int nice = getpriority(PRIO_PROCESS, static_cast<id_t>(tid));
    // May this thread be raised back once lowered? Try it on a small step:
    // one nice level down, then back up (needs CAP_SYS_NICE or RLIMIT_NICE).
    bool raisable = false;
    if (errno == 0 && nice < 19 &&
        setpriority(PRIO_PROCESS, static_cast<id_t>(tid), nice + 1) == 0) {
      raisable = setpriority(PRIO_PROCESS, static_cast<id_t>(tid), nice) == 0;
    }
    stage_tid_ = tid;
    base_nice_ = errno == 0 ? nice : 0;
    apply_low_priority(pthread_self(), tid, base_nice_, options_.priority, raisable);
    boostable_.store(raisable, std::memory_order_release);
  }
#endif
  for (;;) {
    if (await_request() == State::Exit) return;
    process();
  }
}

// Stage thread, state == Wait: returns once the render thread has moved the
// state to Process or Exit. Spin, then poll, then park (StageOptions).
FeedbackStage::State FeedbackStage::await_request() {
  using Clock = std::chrono::steady_clock;
  const Clock::time_point idle_since = Clock::now();
  for (;;) {
    const State s = state_.load(std::memory_order_acquire);
    if (s != State::Wait) return s;
    const auto idle = Clock::now() - idle_since;
    if (idle < options_.idle_spin) {
      std::this_thread::yield();
    } else if (idle < options_.idle_park_after) {
      std::this_thread::sleep_for(options_.idle_poll_interval);
    } else {
      // Park. Dekker-style with request(): it stores Process, then reads
      // parked_; we store parked_, then read the state (in wait()). Both
      // sequentially consistent, so either it sees parked_ and notifies, or
      // wait() sees Process and returns: no lost wake-up.
      parked_.store(true, std::memory_order_seq_cst);
      state_.wait(State::Wait, std::memory_order_seq_cst);
      parked_.store(false, std::memory_order_relaxed);
    }
  }
}

bool FeedbackStage::step() {
  if (options_.launch != Launch::Manual) return false;
  if (state_.load(std::memory_order_acquire) != State::Process) return false;
  process();
  return true;
}

// Feedback Stage side, state == Process: everything in the inbox, the back
// buffer and the stage-only members is ours; the front list is read-only.
void FeedbackStage::process() {
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
void FeedbackStage::process_scene(Outbox& out) {
  using Clock = std::chrono::steady_clock;
  const Clock::time_point t0 = out.started;
  const std::size_t n = scene_inputs_.size();
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
  const ListBuffer& front = buffers_[inbox_.front];
  const bool whole_front = front.offsets.size() == n + 1;
  const auto front_list = [&](std::size_t i) {
    return whole_front ? std::span<const NodeId>(front.nodes)
                             .subspan(front.offsets[i], front.offsets[i + 1] - front.offsets[i])
                       : std::span<const NodeId>();
  };
  const bool evolve =
      scene_strategy_ == nullptr && object_strategies_[0]->mode() == Strategy::Mode::Evolve;
  if (evolve && (cut_stale_ || object_cuts_.size() != n)) {
    // As for a model: the front lists are the cuts to evolve (an object
    // whose list is empty, drawn by a scene-level strategy, starts at its root).
    object_cuts_.resize(n);
    for (std::size_t i = 0; i < n; ++i) {
      const std::span<const NodeId> list = front_list(i);
      object_cuts_[i] = list.empty() ? TreeCut::root_cut(*scene_inputs_[i].hierarchy)
                                     : TreeCut::from_nodes(*scene_inputs_[i].hierarchy, list);
    }
    cut_stale_ = false;
  }
  const Clock::time_point t1 = Clock::now();

  ListBuffer& back = buffers_[inbox_.back];
  back.nodes.clear();
  back.offsets.clear();
  back.queries.clear();
  const auto no_queries = [&] {
    // The query executor places a node of the one model it draws; on a
    // scene it would test the wrong place. Refused, not answered wrongly.
    if (!back.queries.empty()) {
      throw std::runtime_error("asked for " + std::to_string(back.queries.size()) +
                               " GPU queries on a scene: queries are answered for single models "
                               "only (docs/architecture.md, \"Scenes through the stage\")");
    }
  };
  const auto invalid = [&](std::size_t i, const std::string& why) {
    out.invalid_cut = true;
    throw std::runtime_error("object " + std::to_string(i) + ": returned an invalid cut: " + why);
  };
  std::uint64_t publish_ns = 0;
  std::uint64_t objects = 0;
  IterationResult total;
  if (scene_strategy_ != nullptr) {
    const SceneIterationInput input{scene_inputs_, view_,
                                    &cancel_,      object_strategies_[0]->params_version(),
                                    front.nodes,   front.offsets};
    SceneIterationOutput output;
    output.nodes = &back.nodes;
    output.offsets = &back.offsets;
    output.queries = &back.queries;
    scene_strategy_->iterate_scene(input, output);
    const Clock::time_point t2 = Clock::now();
    no_queries();
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
      if (std::string why = check_cut(*scene_inputs_[i].hierarchy, {first, last}); !why.empty()) {
        invalid(i, why);
      }
      if (!std::is_sorted(first, last)) std::sort(first, last);
    }
    total = output.result;
    objects = n;
    cut_stale_ = true;
    publish_ns = ns_between(t2, Clock::now());
  } else {
    back.offsets.reserve(n + 1);
    back.offsets.push_back(0);
    total.converged = true;
    for (std::size_t i = 0; i < n; ++i) {
      const SceneObjectInput& o = scene_inputs_[i];
      const Hierarchy& h = *o.hierarchy;
      if (!total.cancelled && !cancel_.load(std::memory_order_relaxed)) {
        // The object's model space: the view with its world matrix folded
        // in, so an unchanged strategy sees what it sees on a model.
        ViewSnapshot& v = object_view_;
        v.view = view_.view * o.world;
        v.projection = view_.projection;
        v.viewport = view_.viewport;
        // The light into model space (a direction: the inverse's linear
        // part), renormalized only where that changed its length (a rotation
        // or the identity leaves it bit for bit as the model would see it).
        const glm::vec3 light = glm::mat3(o.world_inverse) * view_.light_dir;
        const float len = glm::length(light);
        v.light_dir = !(len > 0.0f)                  ? view_.light_dir
                      : std::abs(len - 1.0f) > 1e-6f ? light / len
                                                     : light;
        v.frame = view_.frame;
        v.version = view_.version;
        v.visibility.clear();  // no queries on a scene (see no_queries)
        v.finalize();
        v.derived.pixel_scale *= object_size_factor_[v.derived.perspective ? 1 : 0][i];
        Strategy& s = *object_strategies_[i];
        object_nodes_.clear();
        const IterationInput input{h, v, static_cast<std::uint32_t>(i), &cancel_,
                                   s.params_version()};
        IterationOutput output;
        output.cut = evolve ? &object_cuts_[i] : &cut_;  // a Rebuild strategy ignores it
        output.nodes = &object_nodes_;
        output.queries = &back.queries;
        s.iterate(input, output);
        no_queries();
        const Clock::time_point p0 = Clock::now();
        if (evolve) {
          TreeCut& cut = object_cuts_[i];
          if (std::string why = check_cut(h, cut.nodes()); !why.empty()) invalid(i, why);
          if (cut.disorder() > 0) cut.sort(sort_scratch_);
          back.nodes.insert(back.nodes.end(), cut.nodes().begin(), cut.nodes().end());
        } else {
          if (std::string why = check_cut(h, object_nodes_); !why.empty()) invalid(i, why);
          if (!std::is_sorted(object_nodes_.begin(), object_nodes_.end())) {
            sort_node_ids(object_nodes_, h.node_count(), sort_scratch_);
          }
          back.nodes.insert(back.nodes.end(), object_nodes_.begin(), object_nodes_.end());
        }
        publish_ns += ns_between(p0, Clock::now());
        const IterationResult& r = output.result;
        total.visited += r.visited;
        total.refined += r.refined;
        total.coarsened += r.coarsened;
        total.culled += r.culled;
        total.backfacing += r.backfacing;
        total.too_small += r.too_small;
        total.blocked += r.blocked;
        total.converged = total.converged && r.converged;
        total.cancelled = total.cancelled || r.cancelled;
        ++objects;
      } else {
        // Cancelled: the objects not reached keep the lists they have.
        total.cancelled = true;
        if (evolve) {
          const TreeCut& cut = object_cuts_[i];
          back.nodes.insert(back.nodes.end(), cut.nodes().begin(), cut.nodes().end());
        } else if (const std::span<const NodeId> list = front_list(i); !list.empty()) {
          back.nodes.insert(back.nodes.end(), list.begin(), list.end());
        } else {
          back.nodes.push_back(h.root());
        }
      }
      if (back.nodes.size() >= std::numeric_limits<std::uint32_t>::max()) {
        throw std::runtime_error("the scene's cut has more than 2^32 - 1 nodes");
      }
      back.offsets.push_back(static_cast<std::uint32_t>(back.nodes.size()));
    }
    if (!evolve) cut_stale_ = true;
  }
  back.generation = inbox_.generation;
  const Clock::time_point t3 = Clock::now();
  out.ready = true;
  out.result = total;
  out.result.converged = total.converged && !total.cancelled;
  out.result.cut_size = back.nodes.size();
  out.objects = objects;
  out.extract_ns = ns_between(t0, t1);
  const std::uint64_t all = ns_between(t1, t3);
  out.iteration_ns = all > publish_ns ? all - publish_ns : 0;
  out.publish_ns = publish_ns;
}

// Stage thread, inside a catch handler: whatever the strategy threw (also
// `throw 42`) becomes one StrategyError naming it and its plugin; nothing
// escapes this thread (no terminate).
void FeedbackStage::fail(Outbox& out) {
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
std::string FeedbackStage::check_cut(std::span<const NodeId> nodes) const {
  return check_cut(*hierarchy_, nodes);
}

std::string FeedbackStage::check_cut(const Hierarchy& h, std::span<const NodeId> nodes) const {
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

// Render thread: raises the stage thread to the priority it started with
// (starved request, shutdown), or lowers it again.
void FeedbackStage::set_boost(bool on) {
#if defined(__linux__)
  if (on == boosted_ || !boostable_.load(std::memory_order_acquire)) return;
  boosted_ = on;
  if (on) {
    ++counters_.boosts;
    const sched_param param{};
    (void)pthread_setschedparam(thread_.native_handle(), SCHED_OTHER, &param);
    (void)setpriority(PRIO_PROCESS, static_cast<id_t>(stage_tid_), base_nice_);
  } else {
    apply_low_priority(thread_.native_handle(), stage_tid_, base_nice_, options_.priority, true);
  }
#else
  (void)on;
#endif
}

FrontList FeedbackStage::list_of(std::uint32_t index) const {
  const ListBuffer& b = buffers_[index];
  return FrontList{b.nodes, b.generation, b.hierarchy.get(), b.queries, b.offsets, scene_.get()};
}

std::optional<std::uint32_t> FeedbackStage::free_buffer() const {
  for (std::uint32_t i = 0; i < buffers_.size(); ++i) {
    if (buffers_[i].use == BufferUse::Free) return i;
  }
  return std::nullopt;
}

// A list the renderer no longer draws: it was copied in the frame of its
// exchange (CutBuffer::follow), so the stage may write it again at once.
void FeedbackStage::retire(std::uint32_t index) {
  buffers_[index].use = BufferUse::Free;
}

// The Exchange: O(1), swaps which buffer is the front; no list is copied.
void FeedbackStage::exchange() {
  const std::uint32_t old = front_;
  front_ = back_;
  buffers_[front_].use = BufferUse::Front;
  if (options_.blend_frames > 0) {
    if (blending_) retire(*blending_);
    blending_ = old;
    buffers_[old].use = BufferUse::Blending;
    blend_frame_ = 0;
  } else {
    retire(old);
  }
  front_view_ = list_of(front_);
  ++counters_.exchanges;
  if (front_view_.hierarchy == switching_to_) switching_to_ = nullptr;
}

bool FeedbackStage::request() {
  const std::optional<std::uint32_t> free = free_buffer();
  if (!free) {
    ++counters_.no_free_buffer;
    return false;
  }
  back_ = *free;
  buffers_[back_].use = BufferUse::Back;
  inbox_.view = pending_.view;
  inbox_.view.frame = counters_.frames;
  pending_.view.visibility.clear();
  pending_.view_changed = false;
  if (pending_.strategy) running_ = pending_.strategy.get();
  inbox_.strategy = std::move(pending_.strategy);
  inbox_.factory = std::move(pending_.factory);
  pending_.factory = nullptr;
  inbox_.params.swap(pending_.params);
  if (pending_.model) {
    inbox_.model = std::move(pending_.model);
    pending_.model.reset();
  }
  inbox_.back = back_;
  inbox_.front = front_;
  inbox_.generation = next_generation_++;
  frames_at_request_ = counters_.frames;
  requested_at_ = std::chrono::steady_clock::now();
  starved_ = false;
  in_flight_ = true;
  ++counters_.requests;
  // A cancel stored before this point was for an earlier iteration. Cleared
  // here, not by the stage: set_strategy(), set_model() or the destructor may
  // cancel this iteration before the stage thread has even woken up.
  cancel_.store(false, std::memory_order_relaxed);
  // seq_cst, paired with await_request(): a stage that is not parked sees the
  // new state by itself, so the wake-up (a system call) is only paid after a
  // long idle period.
  state_.store(State::Process, std::memory_order_seq_cst);
  if (parked_.load(std::memory_order_seq_cst)) state_.notify_one();
  return true;
}

FrameLists FeedbackStage::poll() {
  ++counters_.frames;
  FrameLists f;
  if (blending_ && ++blend_frame_ >= options_.blend_frames) {
    retire(*blending_);
    blending_.reset();
  }
  // The lock-free query of figure 2.
  const State state = state_.load(std::memory_order_acquire);
  if (state == State::Process && in_flight_ && !starved_ && options_.starvation_bound.count() > 0 &&
      std::chrono::steady_clock::now() - requested_at_ >= options_.starvation_bound) {
    // Bounded wait: a Low/Idle stage that has not delivered within the bound
    // runs at the creator's priority until this iteration is done.
    starved_ = true;
    ++counters_.starved;
    set_boost(true);
  }
  // A fade runs to its end before the next exchange: an exchange in the
  // middle of one would snap the pixels still fading (and with an iteration
  // per frame no fade would ever get past its first step). The finished list
  // waits in the back buffer meanwhile; an error is reported at once.
  const bool hold = blending_ && in_flight_ && state == State::Wait && outbox_.ready;
  if (state == State::Wait && !hold) {
    if (in_flight_) {
      in_flight_ = false;
      set_boost(false);
      counters_.frames_last_iteration = counters_.frames - frames_at_request_;
      const auto wait = outbox_.started - requested_at_;
      counters_.wait_ns_last =
          wait.count() > 0 ? static_cast<std::uint64_t>(
                                 std::chrono::duration_cast<std::chrono::nanoseconds>(wait).count())
                           : 0;
      counters_.wait_ns_max = std::max(counters_.wait_ns_max, counters_.wait_ns_last);
      if (outbox_.error) {
        buffers_[back_].use = BufferUse::Free;
        ++counters_.errors;
        if (outbox_.invalid_cut) ++counters_.invalid_cuts;
        try {
          std::rethrow_exception(outbox_.error);
        } catch (const std::exception& e) {
          counters_.last_error = e.what();
        }
        std::rethrow_exception(std::exchange(outbox_.error, nullptr));
      }
      ++counters_.iterations;
      counters_.iteration_ns_last = outbox_.iteration_ns;
      counters_.iteration_ns_total += outbox_.iteration_ns;
      counters_.extract_ns_last = outbox_.extract_ns;
      counters_.extract_ns_total += outbox_.extract_ns;
      counters_.publish_ns_last = outbox_.publish_ns;
      counters_.objects_last = outbox_.objects;
      counters_.last = outbox_.result;
      converged_ = outbox_.result.converged && !outbox_.result.cancelled;
      counters_.converged = converged_;
      if (outbox_.ready) {
        outbox_.ready = false;
        exchange();
        f.exchanged = true;
      }
    }
    const bool due = !converged_ || pending_.view_changed || pending_.strategy ||
                     !pending_.params.empty() || pending_.model ||
                     !pending_.view.visibility.empty();
    if (due) f.requested = request();
  }
  f.current = front_view_;
  if (blending_) {
    f.previous = list_of(*blending_);
    f.blend = static_cast<float>(blend_frame_ + 1) / static_cast<float>(options_.blend_frames + 1);
  }
  return f;
}

void FeedbackStage::set_view(const ViewSnapshot& view) {
  ViewSnapshot& p = pending_.view;
  if (view.version != p.version) pending_.view_changed = true;
  // One assignment of the whole value (a field added later is never dropped);
  // the pending results survive it in the scratch vector, and both vectors
  // keep their capacity, so this allocates only while they grow.
  std::vector<VisibilityResult>& kept = pending_.visibility_scratch;
  kept.swap(p.visibility);
  p = view;
  kept.insert(kept.end(), p.visibility.begin(), p.visibility.end());
  kept.swap(p.visibility);
  kept.clear();
}

void FeedbackStage::post_visibility(std::span<const VisibilityResult> results) {
  // Until the new model's first list is drawn, every answer is about the old one.
  if (switching_to_ != nullptr) return;
  pending_.view.visibility.insert(pending_.view.visibility.end(), results.begin(), results.end());
}

void FeedbackStage::set_strategy(std::unique_ptr<Strategy> strategy) {
  if (!strategy) throw std::invalid_argument("FeedbackStage: no strategy");
  if (scene_ && dynamic_cast<const SceneStrategy*>(strategy.get()) == nullptr) {
    throw std::invalid_argument(
        "FeedbackStage: a per-object strategy on a scene needs a StrategyFactory");
  }
  pending_.factory = nullptr;
  strategy_name_ = std::string(strategy->name());
  pending_.specs = strategy->param_specs();
  pending_.strategy = std::move(strategy);
  pending_.params.clear();  // they were meant for the strategy being replaced
  converged_ = false;
  if (state_.load(std::memory_order_relaxed) == State::Process) {
    cancel_.store(true, std::memory_order_relaxed);
  }
}

void FeedbackStage::set_strategy(StrategyFactory factory) {
  if (!factory) throw std::invalid_argument("FeedbackStage: no strategy factory");
  std::unique_ptr<Strategy> first = factory();
  if (!first) throw std::invalid_argument("FeedbackStage: the factory made no strategy");
  if (!scene_) {
    set_strategy(std::move(first));
    return;
  }
  check_scene_strategy(*first);
  strategy_name_ = std::string(first->name());
  pending_.specs = first->param_specs();
  pending_.strategy = std::move(first);
  pending_.factory = std::move(factory);
  pending_.params.clear();
  converged_ = false;
  if (state_.load(std::memory_order_relaxed) == State::Process) {
    cancel_.store(true, std::memory_order_relaxed);
  }
}

void FeedbackStage::set_param(std::string_view name, double value) {
  for (const ParamSpec& spec : pending_.specs) {
    if (spec.name != name) continue;
    if (std::string why = check_param(spec, value); !why.empty()) {
      throw InputError(strategy_name_ + ": " + why);
    }
    pending_.params.emplace_back(std::string(name), value);
    converged_ = false;
    return;
  }
  throw InputError(strategy_name_ + ": unknown parameter '" + std::string(name) + "'");
}

void FeedbackStage::set_model(Model model) {
  if (scene_) throw std::logic_error("FeedbackStage: set_model on a stage made on a scene");
  if (!model.hierarchy || model.hierarchy->empty()) {
    throw std::invalid_argument("FeedbackStage: the model has no hierarchy");
  }
  if (std::string why = model.cut.validate(*model.hierarchy); !why.empty()) {
    throw std::invalid_argument("FeedbackStage: invalid cut: " + why);
  }
  // Answers not yet handed over name nodes of the model being replaced.
  pending_.view.visibility.clear();
  switching_to_ = model.hierarchy.get();
  pending_.model = std::move(model);
  converged_ = false;
  if (state_.load(std::memory_order_relaxed) == State::Process) {
    cancel_.store(true, std::memory_order_relaxed);
  }
}

}  // namespace treecut
