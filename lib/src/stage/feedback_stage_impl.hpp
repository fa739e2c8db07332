// Private to the FeedbackStage sources (lib/src/stage/feedback_stage*.cpp):
// the implementation class and what more than one of them needs. Only the stage
// thread's start (feedback_stage_thread.cpp) and the render thread's boost
// (feedback_stage_exchange.cpp) change a thread's priority, with this one
// function.
#pragma once

#include "treecut/feedback_stage.hpp"

#if defined(__linux__)
#include <pthread.h>
#endif

#include <atomic>
#include <chrono>
#include <exception>
#include <optional>
#include <thread>

namespace treecut {

// The FeedbackStage itself (treecut/feedback_stage.hpp shows only its API,
// which forwards here: feedback_stage.cpp). Its sources, one job each:
// feedback_stage_exchange.cpp (the paper's exchange, render thread side),
// feedback_stage_thread.cpp (the stage thread and its scheduling),
// feedback_stage_process.cpp (an iteration and its error attribution),
// feedback_stage_scene.cpp (scene mode), feedback_stage_inputs.cpp (the
// render thread's inputs).
class FeedbackStage::Impl {
 public:
  Impl(Model model, std::unique_ptr<Strategy> strategy, StageOptions options = {});
  Impl(std::shared_ptr<const StageScene> scene, const StrategyFactory& factory,
       StageOptions options = {});
  ~Impl();
  Impl(const Impl&) = delete;
  Impl& operator=(const Impl&) = delete;
  FrameLists poll();
  void set_view(const ViewSnapshot& view);
  void post_visibility(std::span<const VisibilityResult> results);
  void set_strategy(std::unique_ptr<Strategy> strategy);
  void set_strategy(StrategyFactory factory);
  [[nodiscard]] const std::shared_ptr<const StageScene>& scene() const { return scene_; }
  void set_param(std::string_view name, double value);
  void set_model(Model model);
  void set_blend_frames(unsigned frames) { options_.blend_frames = frames; }
  [[nodiscard]] unsigned blend_frames() const { return options_.blend_frames; }
  [[nodiscard]] const StageCounters& counters() const { return counters_; }
  [[nodiscard]] std::uint64_t frame() const { return counters_.frames; }
  [[nodiscard]] const FrontList& front() const { return front_view_; }
  [[nodiscard]] const std::string& strategy_name() const { return strategy_name_; }
  [[nodiscard]] bool processing() const {
    return state_.load(std::memory_order_acquire) == State::Process;
  }
  bool step();
  [[nodiscard]] bool can_boost() const { return boostable_.load(std::memory_order_acquire); }

  enum class State : std::uint32_t { Wait, Process, Exit };
  enum class BufferUse : std::uint8_t { Free, Back, Front, Blending };

  struct ListBuffer {
    std::vector<NodeId> nodes;
    std::vector<std::uint32_t> offsets;  // a scene's object layout (else empty)
    std::vector<QueryRequest> queries;
    std::shared_ptr<const Hierarchy> hierarchy;
    std::uint64_t generation = 0;
    BufferUse use = BufferUse::Free;  // render thread only
  };
  // Written by the render thread in Wait, read by the stage in Process.
  struct Inbox {
    ViewSnapshot view;
    std::unique_ptr<Strategy> strategy;
    StrategyFactory factory;  // a scene's: the rest of the per-object instances
    std::vector<std::pair<std::string, double>> params;
    std::optional<Model> model;
    std::uint32_t back = 0;
    std::uint32_t front = 0;
    std::uint64_t generation = 0;
  };
  // Written by the stage in Process, read by the render thread in Wait.
  struct Outbox {
    bool ready = false;
    std::chrono::steady_clock::time_point started;  // the iteration's start
    bool invalid_cut = false;
    IterationResult result;
    std::uint64_t iteration_ns = 0;
    std::uint64_t extract_ns = 0;
    std::uint64_t publish_ns = 0;
    std::uint64_t objects = 0;  // a scene: objects iterated
    std::exception_ptr error;
  };
  // What a scene's iteration adds up (feedback_stage_process.cpp).
  struct SceneTotals {
    IterationResult result;
    std::uint64_t objects = 0;     // objects iterated
    std::uint64_t publish_ns = 0;  // of it, checking and sorting the lists
  };
  // Render-thread inputs not yet handed over.
  struct Pending {
    ViewSnapshot view;
    bool view_changed = true;
    std::unique_ptr<Strategy> strategy;
    StrategyFactory factory;
    std::vector<std::pair<std::string, double>> params;
    std::optional<Model> model;
    std::vector<ParamSpec> specs;                      // of the strategy the next iteration runs
    std::vector<VisibilityResult> visibility_scratch;  // set_view's swap space (keeps capacity)
  };

  void run();
  [[nodiscard]] State await_request();
  void process();
  void extract();
  void process_scene(Outbox& out);
  [[nodiscard]] bool extract_scene();
  void iterate_scene_strategy(Outbox& out, SceneTotals& totals);
  void iterate_object_strategies(bool evolve, Outbox& out, SceneTotals& totals);
  void iterate_object(std::size_t i, bool evolve, Outbox& out, SceneTotals& totals);
  void fail(Outbox& out);
  void make_object_strategies(std::unique_ptr<Strategy> first, const StrategyFactory& factory);
  void check_scene_strategy(const Strategy& probe) const;
  void exchange();
  void retire(std::uint32_t index);
  bool request();
  [[nodiscard]] std::optional<std::uint32_t> free_buffer() const;
  [[nodiscard]] FrontList list_of(std::uint32_t index) const;
  void set_boost(bool on);
  [[nodiscard]] std::string check_cut(std::span<const NodeId> nodes) const;
  [[nodiscard]] std::string check_cut(const Hierarchy& h, std::span<const NodeId> nodes) const;

  StageOptions options_;
  std::atomic<State> state_{State::Wait};
  std::atomic<bool> cancel_{false};
  // The stage thread sleeps in state_.wait(): a request must notify it. While
  // false the stage checks the state by itself and request() skips the
  // notification (a system call).
  std::atomic<bool> parked_{false};
  // Set by the stage thread once it has applied its priority: its thread id,
  // the nice value it started with, whether that can be restored later.
  std::atomic<bool> boostable_{false};
  int stage_tid_ = 0;
  int base_nice_ = 0;
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
  std::chrono::steady_clock::time_point requested_at_;
  bool boosted_ = false;
  bool starved_ = false;               // the in-flight request passed the bound
  const Strategy* running_ = nullptr;  // the strategy of the in-flight iteration
  // set_model's hierarchy until its first list is front: post_visibility
  // drops answers meanwhile (they are about the old model). Identity only.
  const Hierarchy* switching_to_ = nullptr;

  // Stage thread only (in Process).
  std::shared_ptr<const Hierarchy> hierarchy_;
  // A paged model's pages (Model::paged), and what they did between
  // iterations: the nodes that gained or lost their children (the next
  // iteration's inputs) and the hidden nodes the last one wanted.
  std::shared_ptr<PagedHierarchy> paged_;
  std::vector<NodeId> revealed_, concealed_, wanted_;
  void follow_pages(std::span<const NodeId> list, Outbox& out);
  // A scene's models drawn from their pages (StageScene::paged): per model
  // the nodes that gained or lost their children, and the hidden nodes the
  // objects wanted (feedback_stage_scene_pages.cpp).
  std::vector<std::vector<NodeId>> model_revealed_, model_concealed_;
  std::vector<ObjectNode> scene_wanted_;
  std::vector<NodeId> object_wanted_;  // one object's (per-object strategies)
  [[nodiscard]] bool scene_paged() const { return !scene_->paged.empty(); }
  void publish_scene_pages();
  void follow_scene_pages(Outbox& out);
  TreeCut cut_;
  bool cut_stale_ = false;
  std::vector<NodeId> sort_scratch_;
  std::unique_ptr<Strategy> strategy_;
  ViewSnapshot view_;
  // A scene (the pointer is set at construction and never changes, so both
  // threads may read it). Stage thread only: per object a strategy (all
  // null but the first for a scene-level strategy) and a cut, whether the
  // cuts must be rebuilt from the front list, the object's view scratch.
  std::shared_ptr<const StageScene> scene_;
  std::vector<std::unique_ptr<Strategy>> object_strategies_;
  SceneStrategy* scene_strategy_ = nullptr;
  std::unique_ptr<Strategy> failed_first_;  // see make_object_strategies
  std::vector<TreeCut> object_cuts_;
  std::vector<float> object_size_factor_[2];  // pixel_scale factors: [0] ortho, [1] perspective
  std::vector<NodeId> object_nodes_;
  ViewSnapshot object_view_;

  std::thread thread_;  // last: started after everything above exists
};

}  // namespace treecut

namespace treecut::detail {

/// Object I's list in a buffer of N objects' lists back to back (empty when
/// the buffer does not hold N lists).
std::span<const NodeId> object_list(const std::vector<NodeId>& nodes,
                                    const std::vector<std::uint32_t>& offsets, std::size_t n,
                                    std::size_t i);
/// V: VIEW in object O's model space (feedback_stage_scene.cpp).
void fold_object_view(ViewSnapshot& v, const ViewSnapshot& view, const SceneObject& o);
/// A paged model's counters (pages_*) of S, WANTED hidden nodes wanted.
void report_pages(const PagingStats& s, std::size_t wanted, Counters& c);

/// Nanoseconds from a to b (the stage's phase timings).
inline std::uint64_t ns_between(std::chrono::steady_clock::time_point a,
                                std::chrono::steady_clock::time_point b) {
  return static_cast<std::uint64_t>(
      std::chrono::duration_cast<std::chrono::nanoseconds>(b - a).count());
}

#if defined(__linux__)
// Lowers a stage thread (by its handle and tid; Linux keeps a nice value per thread, so
// PRIO_PROCESS with a thread id changes that thread only). `idle` chooses SCHED_IDLE over nice +19
// for Idle: only a process that may raise the thread again uses SCHED_IDLE, since an unprivileged
// thread can never leave it (sched(7), RLIMIT_NICE).
void apply_low_priority(pthread_t thread, int tid, int base_nice, StagePriority priority,
                        bool idle);
#endif

}  // namespace treecut::detail
