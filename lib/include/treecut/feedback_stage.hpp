// FeedbackStage: runs one LOD strategy beside the render thread and hands its
// cuts over with the wait/process protocol of "Parallel TreeCut Manipulation"
// (Marton, Schiffner et al.), section 3 and figure 2.
//
// One atomic state, Wait or Process, initially Wait. The render thread calls
// poll() once per frame; poll() reads the state without a lock and, only in
// Wait, (1) exchanges the front list with the back list when a new cut is
// ready and (2) requests an update when the view changed, the strategy has
// not converged or an input (strategy, parameter, model) is pending: it hands
// the inputs over, sets Process and wakes the stage. In Process the stage
// (thread or the caller of step()) extracts its read-only inputs, runs one
// iteration into the back list, flags ready/converged and returns to Wait with
// release semantics. In Wait the render thread owns every shared field, in
// Process the stage does; the state's acquire/release orders the hand-over.
//
// The exchange is O(1): it swaps buffer indices, never copies a list. A list
// the renderer no longer draws is "retired"; the stage writes into it again
// only after it is released: at once (ReleaseMode::OnExchange, for renderers
// that copy the list into a GPU buffer during the frame) or when the render
// thread calls release(generation) after the GPU finished reading it
// (ReleaseMode::Manual, e.g. after a fence). No update is requested while no
// buffer is free; see docs/threading.md.
//
// Threads: every public member except step() is for the render thread (the
// thread that constructed the stage). step() is for the thread that acts as
// the Feedback Stage when launched with Launch::Manual (tests).
//
// tests/model/exchange.pml models this protocol (State, BufferUse and the
// steps by their names here) and spin checks it: keep the two in step.
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <exception>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <thread>
#include <vector>

#include "treecut/model.hpp"
#include "treecut/strategy.hpp"
#include "treecut/view_snapshot.hpp"

namespace treecut {

enum class ReleaseMode {
  OnExchange,  ///< a retired list is free at once (the renderer copied it)
  Manual,      ///< a retired list is free after release(generation)
};

enum class Launch {
  Thread,  ///< the stage runs its own thread
  Manual,  ///< no thread: the owner calls step() (synchronous tests)
};

/// Scheduling of the stage thread (Launch::Thread). The stage only prepares
/// the next cut, so it should give way to the render thread and the GL
/// driver's threads (llvmpipe rasterizes on one thread per core). Linux only,
/// best effort (elsewhere, or if the call fails, the thread keeps the
/// priority it inherited). See docs/threading.md, "Thread priority".
enum class StagePriority {
  Normal,  ///< the priority of the thread that created the stage
  Low,     ///< nice +10 for the stage thread only
  Idle,    ///< SCHED_IDLE: runs only on a core no other thread wants
};

struct StageOptions {
  unsigned list_buffers = 3;  ///< >= 2 (front + back); more absorb late releases and blending
  StagePriority priority = StagePriority::Normal;
  ReleaseMode release = ReleaseMode::OnExchange;
  /// Frames over which an exchanged list fades in over the previous one; 0 = swap at once.
  unsigned blend_frames = 0;
  Launch launch = Launch::Thread;
  /// How an idle stage thread (Launch::Thread) notices the next request.
  /// Waking a sleeping thread is a system call on the render thread (about
  /// 10 us on a virtual machine), so after an iteration the stage first spins
  /// (yielding its core), then checks every `idle_poll_interval`, and goes to
  /// sleep until woken only after `idle_park_after` without a request: a
  /// viewer that renders continuously never pays for a wake-up, an idle one
  /// costs nothing. docs/threading.md, "Waking the stage".
  std::chrono::microseconds idle_spin{50};
  std::chrono::microseconds idle_poll_interval{200};
  std::chrono::microseconds idle_park_after{100'000};
};

/// A list the renderer may draw. `nodes` and `hierarchy` stay valid until the
/// list is released (at the next exchange with ReleaseMode::OnExchange,
/// otherwise until release(generation)).
struct FrontList {
  /// Ascending node ids: the stage sorts every list it publishes.
  std::span<const NodeId> nodes;
  std::uint64_t generation = 0;  ///< increases with every exchange; 1 for the initial cut
  const Hierarchy* hierarchy = nullptr;
  /// GPU queries the strategy asked for with this list; execute and answer
  /// them with FeedbackStage::post_visibility().
  std::span<const QueryRequest> queries;
};

/// What poll() tells the renderer for this frame.
struct FrameLists {
  FrontList current;
  FrontList previous;      ///< while blending: the list fading out (else empty)
  float blend = 1.0f;      ///< weight of `current` in [0, 1]
  bool exchanged = false;  ///< a new list became current this frame
  bool requested = false;  ///< an iteration was requested this frame
};

/// Counters, as of the last poll() that saw the stage in Wait.
struct StageCounters {
  std::uint64_t frames = 0;             ///< poll() calls
  std::uint64_t requests = 0;           ///< iterations requested
  std::uint64_t iterations = 0;         ///< iterations completed
  std::uint64_t exchanges = 0;          ///< lists exchanged
  std::uint64_t no_free_buffer = 0;     ///< frames an update was due but no buffer was free
  std::uint64_t iteration_ns_last = 0;  ///< strategy time of the last iteration
  std::uint64_t iteration_ns_total = 0;
  std::uint64_t extract_ns_last = 0;  ///< input extraction (+ cut rebuild after a model switch)
  std::uint64_t extract_ns_total = 0;
  std::uint64_t publish_ns_last = 0;        ///< copying the cut into the back list
  std::uint64_t frames_last_iteration = 0;  ///< frames rendered while the last iteration ran
  bool converged = false;
  IterationResult last;  ///< counters of the last completed iteration
};

class FeedbackStage {
 public:
  /// Starts in Wait with `model.cut` as the front list (generation 1). Throws
  /// std::invalid_argument for a null hierarchy or strategy, an invalid cut or
  /// fewer than 2 buffers.
  FeedbackStage(Model model, std::unique_ptr<Strategy> strategy, StageOptions options = {});
  /// Cancels a running iteration, waits for it and joins the thread.
  ~FeedbackStage();
  FeedbackStage(const FeedbackStage&) = delete;
  FeedbackStage& operator=(const FeedbackStage&) = delete;

  /// Once per frame, render thread; never blocks. Exchanges and requests as
  /// described above. Rethrows an exception that escaped the strategy.
  FrameLists poll();

  /// The view of the next request. Its `version` decides whether the view
  /// changed. The visibility results in it are appended to the pending ones.
  void set_view(const ViewSnapshot& view);
  /// Query results for the next request (render thread, any time).
  void post_visibility(std::span<const VisibilityResult> results);
  /// Replaces the strategy at the next request; a running iteration is asked
  /// to stop early. The old strategy is destroyed on the stage's thread.
  void set_strategy(std::unique_ptr<Strategy> strategy);
  /// Changes a parameter of the current (or pending) strategy at the next
  /// request. Throws InputError at once for an unknown name or bad value.
  void set_param(std::string_view name, double value);
  /// Replaces hierarchy and cut at the next request (the strategy is reset).
  void set_model(Model model);
  /// The render thread no longer needs list `generation` (ReleaseMode::Manual).
  /// Unknown or already free generations are ignored.
  void release(std::uint64_t generation);

  [[nodiscard]] const StageCounters& counters() const { return counters_; }
  [[nodiscard]] const FrontList& front() const { return front_view_; }
  /// The name of the strategy the next iteration will run.
  [[nodiscard]] const std::string& strategy_name() const { return strategy_name_; }
  [[nodiscard]] bool processing() const {
    return state_.load(std::memory_order_acquire) == State::Process;
  }

  /// Launch::Manual only, from the thread acting as the stage: runs one
  /// iteration if one was requested. Returns whether it ran.
  bool step();

 private:
  enum class State : std::uint32_t { Wait, Process, Exit };
  enum class BufferUse : std::uint8_t { Free, Back, Front, Blending, Retired };

  struct ListBuffer {
    std::vector<NodeId> nodes;
    std::vector<QueryRequest> queries;
    std::shared_ptr<const Hierarchy> hierarchy;
    std::uint64_t generation = 0;
    BufferUse use = BufferUse::Free;  // render thread only
  };
  // Written by the render thread in Wait, read by the stage in Process.
  struct Inbox {
    ViewSnapshot view;
    std::unique_ptr<Strategy> strategy;
    std::vector<std::pair<std::string, double>> params;
    std::optional<Model> model;
    std::uint32_t back = 0;
    std::uint32_t front = 0;
    std::uint64_t generation = 0;
  };
  // Written by the stage in Process, read by the render thread in Wait.
  struct Outbox {
    bool ready = false;
    IterationResult result;
    std::uint64_t iteration_ns = 0;
    std::uint64_t extract_ns = 0;
    std::uint64_t publish_ns = 0;
    std::exception_ptr error;
  };
  // Render-thread inputs not yet handed over.
  struct Pending {
    ViewSnapshot view;
    bool view_changed = true;
    std::unique_ptr<Strategy> strategy;
    std::vector<std::pair<std::string, double>> params;
    std::optional<Model> model;
    std::vector<ParamSpec> specs;  // of the strategy the next iteration runs
  };

  void run();
  [[nodiscard]] State await_request();
  void process();
  void exchange();
  void retire(std::uint32_t index);
  bool request();
  [[nodiscard]] std::optional<std::uint32_t> free_buffer() const;
  [[nodiscard]] FrontList list_of(std::uint32_t index) const;

  StageOptions options_;
  std::atomic<State> state_{State::Wait};
  std::atomic<bool> cancel_{false};
  // The stage thread sleeps in state_.wait(): a request must notify it. While
  // false the stage checks the state by itself and request() skips the
  // notification (a system call).
  std::atomic<bool> parked_{false};
  std::vector<ListBuffer> buffers_;
  Inbox inbox_;
  Outbox outbox_;

  // Render thread only.
  Pending pending_;
  StageCounters counters_;
  FrontList front_view_;
  std::string strategy_name_;
  std::uint32_t front_ = 0;
  std::uint32_t back_ = 0;
  bool in_flight_ = false;  // requested, completion not yet seen
  std::optional<std::uint32_t> blending_;
  unsigned blend_frame_ = 0;
  std::uint64_t next_generation_ = 2;
  std::uint64_t frames_at_request_ = 0;
  bool converged_ = false;

  // Stage thread only (in Process).
  std::shared_ptr<const Hierarchy> hierarchy_;
  TreeCut cut_;
  bool cut_stale_ = false;
  std::vector<NodeId> sort_scratch_;
  std::unique_ptr<Strategy> strategy_;
  ViewSnapshot view_;

  std::thread thread_;  // last: started after everything above exists
};

}  // namespace treecut
