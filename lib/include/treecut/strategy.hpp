// The Strategy API: one interface for every LOD strategy (Marton, Schiffner et
// al., "Parallel TreeCut Manipulation", section 4: "LOD-strategies that are
// based solely on the current cut" plus strategies that rebuild the cut from
// the root).
//
// Contract
// - An iteration is `iterate(input, output)`: a function of explicit inputs
//   (the hierarchy, the view snapshot, the cut, the parameters and the
//   strategy's own per-node state) that writes the new cut and fills
//   `output.result` with counters. It must leave a valid cut (every leaf under
//   exactly one cut node) even when it stops early on cancellation.
// - Evolve strategies modify `*output.cut` in place with TreeCut::refine and
//   TreeCut::coarsen (and may reorder it, TreeCut::sort); on entry it is the
//   cut of the previous iteration (what the render thread draws), in
//   ascending id order when the stage calls. Rebuild strategies ignore the cut and fill
//   `*output.nodes` (empty on entry, capacity kept) with a new cut. The first
//   cut is the model's (the root in treecut render/view).
// - Checked: the stage rejects a cut that does not cover every leaf once
//   (always: empty, ids out of range, wrong point total; in checked builds or
//   with StageOptions::validate: TreeCut::validate) and turns anything the
//   strategy throws, of any type, into a StrategyError naming it and its
//   origin; the previous list stays on screen. The stage fills
//   `result.cut_size` itself.
// - What may be read: only `input` and the strategy's members. The references
//   in `input` and `output` are valid for the duration of the call only; the
//   hierarchy stays the same until reset() is called with another.
// - Threads: a Strategy is used by one thread at a time. Once it is handed to a
//   FeedbackStage, only the Feedback Stage thread calls it (iterate, reset,
//   set_param); parameter changes from the render thread travel through
//   FeedbackStage::set_param. name(), mode() and param_specs() are immutable
//   after construction and may be read from any thread.
// - GPU queries: a strategy appends QueryRequests to `*output.queries`
//   (query_about(): the node's sphere travels with the request;
//   QueryKind::AnySamples when "visible or not" is enough); the render
//   thread executes them once, in the frames after it exchanges that list
//   (a per-frame cap may spread them over several frames; a few requests
//   wait up to max_defer_frames for a batch of min_batch; requests of a list
//   replaced after they were due but before they were issued are dropped),
//   and reports the answers in
//   `input.view.visibility` of a later iteration. Each VisibilityResult
//   carries frame_issued and frame_read on the one frame counter that
//   `input.view.frame` also counts (FeedbackStage::frame()). A strategy that
//   wants a result in the same frame, or in the iteration that asked, is
//   impossible by design: the list must be drawn before its queries can be
//   issued, and an answer is read only once the GPU says it is available,
//   never by waiting for it (treecut/splat/query_executor.hpp).
// - State: a strategy may keep per-node state across iterations (hysteresis,
//   event queues); reset() drops it when the hierarchy changes.
// - Events: `input.view.version` changes when the view changed and
//   `input.params_version` when a parameter value changed (set_param with a
//   new value) since an earlier iteration. Both are events: state keyed on
//   the view (a hysteresis that blocks undoing an operation under the same
//   view, a converged flag) must also be dropped on a parameter change, or a
//   raised budget under a static camera never gets the work it asks for. Scratch
//   buffers live in the strategy and are reused: no allocation per iteration
//   once the buffers have grown.
#pragma once

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <glm/mat4x4.hpp>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "treecut/counters.hpp"
#include "treecut/hierarchy.hpp"
#include "treecut/scene_object.hpp"
#include "treecut/tree_cut.hpp"
#include "treecut/view_snapshot.hpp"

namespace treecut {

/// One numeric parameter of a strategy. Values are doubles; `integer`
/// parameters must hold whole numbers.
struct ParamSpec {
  std::string name;
  std::string description;
  double default_value = 0.0;
  double min_value = 0.0;
  double max_value = 0.0;
  bool integer = false;
};

/// Counters of one iteration; they feed the stage statistics and the tests.
struct IterationResult {
  std::uint64_t visited = 0;     ///< nodes evaluated (cut nodes, or traversed nodes)
  std::uint64_t refined = 0;     ///< refine operations applied
  std::uint64_t coarsened = 0;   ///< coarsen operations applied
  std::uint64_t culled = 0;      ///< recursion stopped by the view frustum
  std::uint64_t backfacing = 0;  ///< recursion stopped by the normal cone
  std::uint64_t too_small = 0;   ///< recursion stopped by the projected size
  std::uint64_t blocked = 0;     ///< operations refused by a threshold or hysteresis rule
  std::size_t cut_size = 0;      ///< nodes in the resulting cut
  bool converged = false;        ///< another iteration under the same view changes nothing
  bool cancelled = false;        ///< stopped early on request; the cut is still valid
  /// What else the strategy measured, by name (treecut/counters.hpp): shown
  /// by the HUD, stats.csv, summary.json and the benchmarks as they are. On
  /// a scene of per-object strategies, the sums over the objects.
  Counters counters;
};

/// What an iteration may read. Valid for the duration of iterate() only.
struct IterationInput {
  const Hierarchy& hierarchy;
  const ViewSnapshot& view;
  /// Which hierarchy of a scene this is (0 for a single model); copied into QueryRequests.
  std::uint32_t object = 0;
  /// Set by the owner to ask a long iteration to end early (strategy switch,
  /// shutdown). May be null. Strategies test it every few thousand nodes.
  const std::atomic<bool>* cancel = nullptr;
  /// Strategy::params_version() when the iteration started: compare it with the
  /// value seen last to notice a parameter change (see "Events" above).
  std::uint64_t params_version = 0;
  /// A paged model (treecut/paged_hierarchy.hpp): the nodes that gained
  /// their children since the previous iteration (their pages arrived),
  /// and those that lost them (their pages were given back; never a node
  /// the cut holds, nor one above a cut node). Residency is an input like
  /// the view: a strategy that keeps copies of the hierarchy's links or
  /// values (the event queue's records) refreshes them at these nodes and
  /// below; one that reads the hierarchy as it goes needs nothing. Empty
  /// for a model held whole.
  std::span<const NodeId> revealed{};
  std::span<const NodeId> concealed{};
  /// A paged model whose pages asked for last do not fit its memory budget
  /// with what the lists hold (PagingStats::memory_short): a strategy that
  /// keeps nodes the view does not need (detail outside the frustum, kept
  /// for when the camera turns back) lets them go, so that their pages can
  /// be given back. Always false for a model held whole.
  bool memory_short = false;

  [[nodiscard]] bool cancelled() const {
    return cancel != nullptr && cancel->load(std::memory_order_relaxed);
  }
};

/// A query about NODE of the iteration's hierarchy, its sphere read now
/// (the View tests the request's sphere, never the hierarchy).
[[nodiscard]] inline QueryRequest query_about(const IterationInput& input, NodeId node,
                                              std::uint32_t tag,
                                              QueryKind kind = QueryKind::Samples) {
  return {input.object, node, tag, kind, input.hierarchy.arrays().center_radius[node]};
}

/// Where an iteration writes. Pointers are never null when the stage calls.
struct IterationOutput {
  TreeCut* cut = nullptr;                        ///< Evolve: modify in place
  std::vector<NodeId>* nodes = nullptr;          ///< Rebuild: fill (empty on entry)
  std::vector<QueryRequest>* queries = nullptr;  ///< append GPU query requests (empty on entry)
  /// A paged model: the hidden nodes (Hierarchy::is_hidden) this iteration
  /// would have refined by its own criterion had their children been
  /// resident; their pages are read next (PagedHierarchy::request). May be
  /// null (a model held whole has none); empty on entry otherwise.
  std::vector<NodeId>* wanted = nullptr;
  IterationResult result;
};

class Strategy {
 public:
  enum class Mode {
    Evolve,   ///< refine/coarsen the current cut (optimization, bucket, event queue)
    Rebuild,  ///< produce a new cut from the root (recursive, occlusion-driven)
  };

  virtual ~Strategy() = default;
  Strategy(const Strategy&) = delete;
  Strategy& operator=(const Strategy&) = delete;

  [[nodiscard]] virtual std::string_view name() const = 0;
  [[nodiscard]] virtual Mode mode() const = 0;

  /// Runs one iteration (see the contract at the top of this file).
  virtual void iterate(const IterationInput& input, IterationOutput& output) = 0;

  /// Drops per-node state and sizes it for `hierarchy`. Called by the stage
  /// before the first iteration and whenever the model changes.
  virtual void reset(const Hierarchy& hierarchy) = 0;

  /// Whether iterations may append GPU query requests (IterationOutput::
  /// queries). Scenes answer none: a strategy that asks is refused for a
  /// scene before any work (per_object_limit_problem, feedback_stage.hpp).
  [[nodiscard]] virtual bool asks_queries() const { return false; }

  [[nodiscard]] const std::vector<ParamSpec>& param_specs() const { return specs_; }
  /// Throws InputError naming the parameter for an unknown name.
  [[nodiscard]] double param(std::string_view name) const;
  /// Checks range and integrality; throws InputError ("NAME: PARAM = V is out
  /// of range [a, b]") and changes nothing on a bad value.
  void set_param(std::string_view name, double value);
  /// Increases whenever set_param() changes a value (setting the value a
  /// parameter already has is no event). The stage passes it in
  /// IterationInput::params_version.
  [[nodiscard]] std::uint64_t params_version() const { return params_version_; }

  /// Where the strategy's code comes from: "built-in", a plugin's path, or
  /// empty for an instance made directly. StrategyRegistry::create sets it;
  /// the stage names it in every error of the strategy.
  [[nodiscard]] const std::string& origin() const { return origin_; }
  void set_origin(std::string origin) { origin_ = std::move(origin); }

 protected:
  explicit Strategy(std::vector<ParamSpec> specs);
  /// The value of param_specs()[index]; the hot path reads parameters this way.
  [[nodiscard]] double param_at(std::size_t index) const { return values_[index]; }

 private:
  std::vector<ParamSpec> specs_;
  std::vector<double> values_;
  std::uint64_t params_version_ = 0;
  std::string origin_;
};

// ---------------------------------------------------------------------------
// Scenes (many objects; docs/architecture.md, "Scenes through the stage").
//
// A FeedbackStage on a scene runs an ordinary Strategy once per object: one
// instance and one TreeCut per object, iterated with IterationInput{the
// object's hierarchy, object = its index, view = the snapshot with the
// object's world matrix folded in (model space)}. Nothing changes in the
// strategy. That costs per-node state for every object (a TreeCut alone is 4
// bytes per node of the object's model), so the stage refuses it above
// kMaxPerObjectNodes nodes in all (FeedbackStage's constructor says so).
//
// A strategy that also derives from SceneStrategy is a scene-level strategy:
// the stage makes one instance and calls iterate_scene() once per iteration
// for all objects (the budget of Eq. 1 is one: a share per object from the
// whole view). It keeps what per-object state it wants; the stage keeps no
// TreeCut per object for it. Its iterate() is what runs on a single model.

/// What one scene iteration may read; valid for the duration of the call.
struct SceneIterationInput {
  /// The stage's scene: its objects (model, transforms, world bounds) and
  /// their models' hierarchies (scene.hierarchy(i)).
  const StageScene& scene;
  const ViewSnapshot& view;  ///< world space (the camera's view, no model matrix folded in)
  const std::atomic<bool>* cancel = nullptr;
  std::uint64_t params_version = 0;
  /// Every object's list of the previous iteration, back to back: object i's
  /// ids are previous[previous_offsets[i] .. previous_offsets[i + 1]).
  std::span<const NodeId> previous;
  std::span<const std::uint32_t> previous_offsets;
  [[nodiscard]] bool cancelled() const {
    return cancel != nullptr && cancel->load(std::memory_order_relaxed);
  }
};

/// Where a scene iteration writes: every object's list, in object order,
/// back to back into `*nodes`, and `*offsets` (objects + 1 entries, the first
/// 0, ascending) where each starts. An object's list is either empty (the
/// object is not drawn: culled, below the PET) or a cut of its model (every
/// leaf under exactly one node: the stage checks it as any cut); the stage
/// sorts each list. Both vectors are empty on entry (capacity kept).
/// A node of an object's model (SceneIterationOutput::wanted).
struct ObjectNode {
  std::uint32_t object = 0;
  NodeId node = 0;
};

struct SceneIterationOutput {
  std::vector<NodeId>* nodes = nullptr;
  std::vector<std::uint32_t>* offsets = nullptr;
  std::vector<QueryRequest>* queries = nullptr;  ///< refused on a scene for now (see FrontList)
  /// A scene with models drawn from their pages (StageScene::paged): as
  /// IterationOutput::wanted, the hidden nodes each object would have
  /// refined, by object; their pages are read next, the largest on screen
  /// first. Null when every model is held whole; empty on entry otherwise.
  std::vector<ObjectNode>* wanted = nullptr;
  IterationResult result;
};

/// The hook for scene-level strategies (see above). Implemented by a class
/// that also derives from Strategy; the stage finds it by dynamic_cast.
class SceneStrategy {
 public:
  virtual ~SceneStrategy() = default;
  /// Drops per-object state and sizes it for this scene's objects. Called
  /// before the first scene iteration and whenever the scene changes.
  virtual void reset_scene(const StageScene& scene) = 0;
  /// One iteration over all objects.
  virtual void iterate_scene(const SceneIterationInput& input, SceneIterationOutput& output) = 0;

 protected:
  SceneStrategy() = default;
  SceneStrategy(const SceneStrategy&) = default;
  SceneStrategy& operator=(const SceneStrategy&) = default;
};

/// Per-object strategies on a scene keep state for every node of every
/// object: at most this many nodes in all (the sum over objects of their
/// model's node count; 2^28: about 1 GiB in TreeCuts alone, as much again in
/// a strategy's own per-node arrays).
inline constexpr std::uint64_t kMaxPerObjectNodes = std::uint64_t{1} << 28;

/// Checks `value` against `spec`; returns an empty string or the problem.
std::string check_param(const ParamSpec& spec, double value);

}  // namespace treecut
