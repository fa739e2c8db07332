// The wait/process exchange of "Parallel TreeCut Manipulation" (Marton,
// Schiffner et al.), section 3, figure 2. See feedback_stage.hpp and
// docs/threading.md for the ownership rules this file relies on.
// Model-checked: tests/model/exchange.pml is this protocol in Promela, with the
// same names (states, buffer uses, poll/exchange/request/retire/release,
// run/process with Extract, Iterate, Publish, the destructor); change both.
#include "treecut/feedback_stage.hpp"

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <stdexcept>
#include <utility>

#if defined(__linux__)
#include <pthread.h>
#include <sched.h>
#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>
#endif

#include "treecut/error.hpp"

namespace treecut {
namespace {

// Called by the stage thread on itself. Best effort: on failure the thread
// keeps its inherited priority.
void lower_own_priority(StagePriority priority) {
#if defined(__linux__)
  if (priority == StagePriority::Low) {
    // Linux keeps a nice value per thread: PRIO_PROCESS with a thread id
    // changes this thread only.
    const auto tid = static_cast<id_t>(syscall(SYS_gettid));
    errno = 0;
    const int nice = getpriority(PRIO_PROCESS, tid);
    if (errno == 0) (void)setpriority(PRIO_PROCESS, tid, std::min(nice + 10, 19));
  } else if (priority == StagePriority::Idle) {
    const sched_param param{};
    (void)pthread_setschedparam(pthread_self(), SCHED_IDLE, &param);
  }
#else
  (void)priority;
#endif
}

std::uint64_t ns_between(std::chrono::steady_clock::time_point a,
                         std::chrono::steady_clock::time_point b) {
  return static_cast<std::uint64_t>(
      std::chrono::duration_cast<std::chrono::nanoseconds>(b - a).count());
}

}  // namespace

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
  strategy_->reset(*hierarchy_);
  if (options_.launch == Launch::Thread) thread_ = std::thread([this] { run(); });
}

FeedbackStage::~FeedbackStage() {
  cancel_.store(true, std::memory_order_relaxed);
  if (!thread_.joinable()) return;
  // Shutdown while Process runs: let the (cancelled) iteration return to Wait,
  // then tell the thread to exit. Only this thread moves Wait -> anything, so
  // no request can slip in between.
  while (state_.load(std::memory_order_acquire) == State::Process) {
    state_.wait(State::Process, std::memory_order_acquire);
  }
  state_.store(State::Exit, std::memory_order_release);
  state_.notify_all();
  thread_.join();
}

void FeedbackStage::run() {
  lower_own_priority(options_.priority);
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
  try {
    const Clock::time_point t0 = Clock::now();
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
      // The last iteration rebuilt the cut as a plain list: the front list
      // (the render thread only reads it) is the cut to evolve.
      cut_ = TreeCut::from_nodes(*hierarchy_, buffers_[inbox_.front].nodes);
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
    out.error = std::current_exception();
  }
  outbox_ = std::move(out);
  // Back to Wait with release: the render thread that sees Wait sees the
  // back list and the outbox complete.
  state_.store(State::Wait, std::memory_order_release);
  state_.notify_all();
}

FrontList FeedbackStage::list_of(std::uint32_t index) const {
  const ListBuffer& b = buffers_[index];
  return FrontList{b.nodes, b.generation, b.hierarchy.get(), b.queries};
}

std::optional<std::uint32_t> FeedbackStage::free_buffer() const {
  for (std::uint32_t i = 0; i < buffers_.size(); ++i) {
    if (buffers_[i].use == BufferUse::Free) return i;
  }
  return std::nullopt;
}

void FeedbackStage::retire(std::uint32_t index) {
  buffers_[index].use =
      options_.release == ReleaseMode::OnExchange ? BufferUse::Free : BufferUse::Retired;
}

void FeedbackStage::release(std::uint64_t generation) {
  for (ListBuffer& b : buffers_) {
    if (b.use == BufferUse::Retired && b.generation == generation) b.use = BufferUse::Free;
  }
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
  inbox_.strategy = std::move(pending_.strategy);
  inbox_.params.swap(pending_.params);
  if (pending_.model) {
    inbox_.model = std::move(pending_.model);
    pending_.model.reset();
  }
  inbox_.back = back_;
  inbox_.front = front_;
  inbox_.generation = next_generation_++;
  frames_at_request_ = counters_.frames;
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
  if (state_.load(std::memory_order_acquire) == State::Wait) {
    if (in_flight_) {
      in_flight_ = false;
      counters_.frames_last_iteration = counters_.frames - frames_at_request_;
      if (outbox_.error) {
        buffers_[back_].use = BufferUse::Free;
        std::rethrow_exception(std::exchange(outbox_.error, nullptr));
      }
      ++counters_.iterations;
      counters_.iteration_ns_last = outbox_.iteration_ns;
      counters_.iteration_ns_total += outbox_.iteration_ns;
      counters_.extract_ns_last = outbox_.extract_ns;
      counters_.extract_ns_total += outbox_.extract_ns;
      counters_.publish_ns_last = outbox_.publish_ns;
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
  p.view = view.view;
  p.projection = view.projection;
  p.viewport = view.viewport;
  p.light_dir = view.light_dir;
  p.frame = view.frame;
  p.version = view.version;
  p.derived = view.derived;
  p.visibility.insert(p.visibility.end(), view.visibility.begin(), view.visibility.end());
}

void FeedbackStage::post_visibility(std::span<const VisibilityResult> results) {
  pending_.view.visibility.insert(pending_.view.visibility.end(), results.begin(), results.end());
}

void FeedbackStage::set_strategy(std::unique_ptr<Strategy> strategy) {
  if (!strategy) throw std::invalid_argument("FeedbackStage: no strategy");
  strategy_name_ = std::string(strategy->name());
  pending_.specs = strategy->param_specs();
  pending_.strategy = std::move(strategy);
  pending_.params.clear();  // they were meant for the strategy being replaced
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
  if (!model.hierarchy || model.hierarchy->empty()) {
    throw std::invalid_argument("FeedbackStage: the model has no hierarchy");
  }
  if (std::string why = model.cut.validate(*model.hierarchy); !why.empty()) {
    throw std::invalid_argument("FeedbackStage: invalid cut: " + why);
  }
  pending_.model = std::move(model);
  converged_ = false;
  if (state_.load(std::memory_order_relaxed) == State::Process) {
    cancel_.store(true, std::memory_order_relaxed);
  }
}

}  // namespace treecut
