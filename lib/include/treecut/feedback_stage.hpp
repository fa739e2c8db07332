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
// the renderer no longer draws is free for the stage at once: the renderer
// copies a list into a GPU buffer in the frame it is exchanged
// (splat::CutBuffer::follow), so no GPU read outlives the exchange and no
// fence is needed (a manual release mode for renderers that read the lists
// in place was removed: nothing used it). While blending the fading list is
// kept until the fade ends. No update is requested while no buffer is free;
// see docs/threading.md.
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
#include <functional>
#include <glm/mat4x4.hpp>
#include <memory>
#include <optional>
#include <span>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "treecut/model.hpp"
#include "treecut/strategy.hpp"
#include "treecut/view_snapshot.hpp"

namespace treecut {

struct Scene;

/// The stage's view of a loaded scene (treecut/scene.hpp): its models'
/// hierarchies (shared, not copied) and its objects' transforms.
std::shared_ptr<const StageScene> stage_scene(const Scene& scene);

/// Makes a strategy instance. A stage on a scene calls it once per object for
/// a per-object strategy (on the thread that constructs the stage, or on the
/// stage thread after set_strategy): it must stay callable until the stage
/// is destroyed or given another factory.
using StrategyFactory = std::function<std::unique_ptr<Strategy>()>;

/// Why `strategy` cannot run on `scene`, or empty: one that asks for GPU
/// queries (Strategy::asks_queries; a scene answers none), or a per-object
/// strategy (one that is not a SceneStrategy) past kMaxPerObjectNodes nodes
/// in all.
/// One line, naming the scene's size and the way out; the stage throws it
/// as an InputError, a program may check it before any work.
[[nodiscard]] std::string per_object_limit_problem(const StageScene& scene,
                                                   const Strategy& strategy);

/// Why `strategy` cannot run on any scene, or empty: it asks for GPU queries
/// (Strategy::asks_queries), which scenes do not answer. Needs no loaded
/// scene: a program checks it as soon as it knows the file is one.
[[nodiscard]] std::string scene_strategy_problem(const Strategy& strategy);

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

/// Whether the stage checks every cut a strategy hands back with
/// TreeCut::validate (every leaf covered exactly once; O(hierarchy) per
/// iteration): true in Debug and sanitizer builds of the library, false in
/// Release. A cheaper check (ids in range, the cut's point count equals the
/// leaf count: O(cut)) always runs. See docs/plugin-guide.md, "Checked cuts".
[[nodiscard]] bool validate_cuts_by_default();

/// A strategy failed: it threw (anything, not only a std::exception) or
/// handed back a cut that does not cover every leaf exactly once. what() is
/// one line: "strategy 'NAME' (plugin PATH): PROBLEM" ("(built-in)" for the
/// library's own). The front list stays what it was; the stage goes on.
class StrategyError : public std::runtime_error {
 public:
  StrategyError(std::string strategy, std::string origin, const std::string& problem);
  [[nodiscard]] const std::string& strategy() const { return strategy_; }
  [[nodiscard]] const std::string& origin() const { return origin_; }

 private:
  std::string strategy_;
  std::string origin_;
};

/// "strategy 'NAME' (plugin PATH)", "strategy 'NAME' (built-in)" or
/// "strategy 'NAME'" for an empty origin.
[[nodiscard]] std::string describe_strategy(std::string_view name, std::string_view origin);

struct StageOptions {
  unsigned list_buffers = 3;  ///< >= 2 (front + back); a third lets the stage work while blending
  StagePriority priority = StagePriority::Normal;
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
  /// Low or Idle priority must not become starvation: when a request has
  /// waited this long for its result, poll() raises the stage thread to the
  /// creator's priority until that iteration is done (a few system calls,
  /// only for a late request). Where the process may not raise a thread's priority again
  /// (unprivileged, RLIMIT_NICE 0), Idle becomes nice +19 instead of
  /// SCHED_IDLE, which the scheduler never starves entirely. 0: never raise
  /// (the counters still record the waits). docs/threading.md, "Thread priority".
  std::chrono::milliseconds starvation_bound{100};
  /// Check every cut a strategy returns with TreeCut::validate (see above).
  bool validate = validate_cuts_by_default();
  /// The destructor cancels a running iteration and waits for it. A strategy
  /// that is still running after `cancel_timeout` is reported through
  /// `on_slow_cancel` (one line naming strategy and plugin; default: stderr);
  /// the destructor then goes on waiting, since the iteration holds references
  /// into the stage's lists, cut and hierarchy. A program about to exit may
  /// end the process in the callback (treecut does).
  std::chrono::milliseconds cancel_timeout{2000};
  std::function<void(const std::string&)> on_slow_cancel;
};

/// A list the renderer may draw. `nodes` and `hierarchy` stay valid until the
/// next exchange (a fading `previous` list until its fade ends): copy them
/// within the frame (splat::CutBuffer::follow does).
struct FrontList {
  /// Ascending node ids: the stage sorts every list it publishes.
  std::span<const NodeId> nodes;
  std::uint64_t generation = 0;  ///< increases with every exchange; 1 for the initial cut
  const Hierarchy* hierarchy = nullptr;
  /// GPU queries the strategy asked for with this list; execute and answer
  /// them with FeedbackStage::post_visibility().
  std::span<const QueryRequest> queries;
  /// A scene's list (the stage was made on a StageScene; `hierarchy` is then
  /// null): the objects' lists back to back, object i's ids, ascending, of
  /// scene->models[scene->objects[i].model], at nodes[object_offsets[i] ..
  /// object_offsets[i + 1]) (objects + 1 offsets, the first 0). Empty and
  /// null for a single model. Published in the same back buffer as the
  /// nodes: the exchange stays one swap of indices.
  std::span<const std::uint32_t> object_offsets;
  const StageScene* scene = nullptr;
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
  /// Wait from a request to the start of its iteration: the last, the worst.
  std::uint64_t wait_ns_last = 0;
  std::uint64_t wait_ns_max = 0;
  /// Requests whose result took longer than StageOptions::starvation_bound.
  std::uint64_t starved = 0;
  /// Times poll() raised the stage's priority for a starved request.
  std::uint64_t boosts = 0;
  /// Iterations that failed (StrategyError), of them with an invalid cut.
  std::uint64_t errors = 0;
  std::uint64_t invalid_cuts = 0;
  std::string last_error;  ///< what() of the last StrategyError
  /// A scene: objects whose strategy ran in the last iteration (all of them
  /// unless cancelled; 0 for a single model).
  std::uint64_t objects_last = 0;
  bool converged = false;
  IterationResult last;  ///< counters of the last completed iteration
};

class FeedbackStage {
 public:
  /// Starts in Wait with `model.cut` as the front list (generation 1). Throws
  /// std::invalid_argument for a null hierarchy or strategy, an invalid cut or
  /// fewer than 2 buffers.
  FeedbackStage(Model model, std::unique_ptr<Strategy> strategy, StageOptions options = {});
  /// A stage on a scene: every object starts at its model's root cut. For a
  /// scene-level strategy (one that derives from SceneStrategy) `factory` is
  /// called once; otherwise once per object, here. Throws InputError when a
  /// per-object strategy would exceed kMaxPerObjectNodes, naming the scene
  /// size and the way out; std::invalid_argument for an empty scene, a model
  /// index out of range or no factory.
  FeedbackStage(std::shared_ptr<const StageScene> scene, const StrategyFactory& factory,
                StageOptions options = {});
  /// Cancels a running iteration, waits for it and joins the thread.
  ~FeedbackStage();
  FeedbackStage(const FeedbackStage&) = delete;
  FeedbackStage& operator=(const FeedbackStage&) = delete;

  /// Once per frame, render thread; never blocks. Exchanges and requests as
  /// described above. Throws StrategyError when the last iteration failed
  /// (the strategy threw, or its cut was invalid): the counters record it,
  /// the front list stays, and the next poll() requests again.
  FrameLists poll();

  /// The view of the next request, taken whole (every field, so a field added
  /// to ViewSnapshot travels without a change here), except: `frame` is set
  /// by the stage at the request, and the visibility results in it are
  /// appended to the pending ones. Its `version` decides whether the view
  /// changed.
  void set_view(const ViewSnapshot& view);
  /// Query results for the next request (render thread, any time).
  void post_visibility(std::span<const VisibilityResult> results);
  /// Replaces the strategy at the next request; a running iteration is asked
  /// to stop early. The old strategy is destroyed on the stage's thread.
  void set_strategy(std::unique_ptr<Strategy> strategy);
  /// A scene's strategy switch (a stage on a model takes one instance from
  /// `factory`). Checks the limit as the constructor does (InputError); the
  /// instances are made on the stage thread at the next request.
  void set_strategy(StrategyFactory factory);
  /// The scene the stage runs on (null for a single model).
  [[nodiscard]] const std::shared_ptr<const StageScene>& scene() const;
  /// Changes a parameter of the current (or pending) strategy at the next
  /// request. Throws InputError at once for an unknown name or bad value.
  void set_param(std::string_view name, double value);
  /// Replaces hierarchy and cut at the next request (the strategy is reset).
  /// Not on a scene (std::logic_error): a stage keeps what it was made on.
  /// Query answers posted from now until the new model's first list is
  /// exchanged are dropped: they answer queries about the old model.
  void set_model(Model model);
  /// Frames over which the next exchanges fade (StageOptions::blend_frames;
  /// the viewer's HUD switch). 0 ends a running fade at the next poll().
  void set_blend_frames(unsigned frames);
  [[nodiscard]] unsigned blend_frames() const;

  [[nodiscard]] const StageCounters& counters() const;
  /// The frame counter of the render thread: the number of the frame begun by
  /// the last poll() (1 for the first). The Controller, the request's
  /// ViewSnapshot::frame and the query executor all count frames with it.
  [[nodiscard]] std::uint64_t frame() const;
  [[nodiscard]] const FrontList& front() const;
  /// The name of the strategy the next iteration will run.
  [[nodiscard]] const std::string& strategy_name() const;
  [[nodiscard]] bool processing() const;

  /// Launch::Manual only, from the thread acting as the stage: runs one
  /// iteration if one was requested. Returns whether it ran.
  bool step();

  /// Whether poll() can raise a starved Low/Idle stage thread (known once the
  /// thread has started; false for Normal, Launch::Manual and elsewhere).
  [[nodiscard]] bool can_boost() const;

 private:
  // Everything else (the buffers, the inbox and outbox of the exchange, the
  // render thread's and the stage thread's state) is the implementation's:
  // lib/src/stage/feedback_stage_impl.hpp.
  class Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace treecut
