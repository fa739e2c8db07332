// Event-driven refinement: Zach & Karner, "Fast Event-Driven Refinement of
// Dynamic Levels of Detail" (2003), section 3 and figure 7. Every node whose
// state can change carries the earliest frame in which its fold/unfold test
// (refinement_criterion.hpp, the same test as `topdown`) can change, computed
// from the maximal translation rho and rotation omega per frame; an iteration
// tests only the nodes whose frame has come. The result equals `topdown`'s
// under the same view, node for node (tests/event_queue_test.cpp).
//
// The queue is the paper's faster form: a circular buffer of per-frame lists
// (kSlots frames ahead). Each list is an array of node ids and every node
// stores its list and index, so insert (append) and erase (the last entry
// moves into the gap) are O(1), and a due list is read front to back with its
// nodes' data prefetched ahead. (Measured on the dragon orbit of
// selection_bench: intrusive doubly-linked lists over node ids took 2x the
// time, a dependent cache miss per event; events carrying their node's
// sphere, 24 bytes, 1.4x, from the writes into the lists.) An insertion for
// the current frame (t = 0) is handled within the same iteration.
//
// Which nodes are queued: every boundary node (a cut node that is not a leaf:
// its unfold event) and every active node (its fold event). The paper queues
// only active nodes whose children are all boundary, which is exact only for
// a criterion that is monotone (a child passing implies its parent passes);
// with nested spheres it is in exact arithmetic, but rounding and spheres
// that contain their children only up to float precision break that, and
// figure 3 then folds a whole subtree the paper's queue would not see. So an
// unfolded node keeps its fold event (its own test is farther from the
// threshold than its children's, so its events are rare), an unfold queues
// the node's non-leaf children (t may be 0) and a fold erases its subtree's
// events.
//
// Frames: one iteration advances the strategy's own frame counter by
// ceil(max(moved / rho, turned / omega)) since its last camera (at least 1
// when the camera changed at all, 0 and O(1) when it did not), so a camera
// faster than rho and omega only makes more events due, never a wrong cut. A
// jump rebuilds the queue with one top-down pass: the first iteration, a
// camera that moved kSlots / 2 frames' worth or more, a new projection or
// viewport, a parameter change, reset(), a cut that is not the one the
// strategy left, an iteration cancelled before (the cut then stays valid,
// the events are redone). Orthographic views: a top-down pass every
// iteration.
//
// Memory: 8 bytes per hierarchy node plus 4 bytes per queued event.
#pragma once

#include <cstdint>
#include <vector>

#include "treecut/strategies/refinement_criterion.hpp"
#include "treecut/strategy.hpp"

namespace treecut::strategies {

class EventQueueStrategy final : public Strategy {
 public:
  enum Param : std::size_t {
    kTheta,  ///< pixels: a node unfolds when its projected radius reaches theta
    kRho,    ///< maximal eye translation per frame, in model diameters (root sphere)
    kOmega,  ///< maximal rotation of the view direction per frame, radians
  };
  /// Frames the circular buffer holds; events farther away are tested after
  /// kSlots / 2 - 1 frames (and rescheduled).
  static constexpr std::uint32_t kSlots = 1024;

  EventQueueStrategy();
  [[nodiscard]] std::string_view name() const override { return "event_queue"; }
  [[nodiscard]] Mode mode() const override { return Mode::Evolve; }
  void reset(const Hierarchy& hierarchy) override;
  void iterate(const IterationInput& input, IterationOutput& output) override;

  /// Statistics of the last iteration, for tests and benchmarks.
  struct Stats {
    std::uint64_t frames_advanced = 0;  ///< frames the counter moved (0: nothing due)
    bool rebuilt = false;               ///< the queue was rebuilt (a jump)
    std::size_t queued = 0;             ///< events in the queue afterwards
  };
  [[nodiscard]] const Stats& stats() const { return stats_; }
  /// Bytes of the event state: per node, and the lists' storage.
  [[nodiscard]] std::size_t state_bytes() const {
    std::size_t bytes = state_.capacity() * sizeof(NodeState) + work_.capacity() * sizeof(NodeId);
    for (const auto& s : slots_) bytes += s.capacity() * sizeof(NodeId);
    return bytes;
  }
  /// Bytes per node of the state array, and per queued event.
  static constexpr std::size_t kBytesPerNode = 8;
  static constexpr std::size_t kBytesPerEvent = 4;

 private:
  // Per node: which frame's list holds its event and where. 8 bytes.
  struct NodeState {
    std::uint32_t index = 0;
    std::uint16_t slot = kNone;
  };
  static constexpr std::uint16_t kNone = 0xffff;  // not queued
  // A list entry is a node id with this bit set for a boundary node (in the
  // cut; else active), so a due event reads only its node's sphere.
  static constexpr NodeId kBoundary = 0x80000000u;
  static constexpr NodeId kErased = 0xffffffffu;  // an erased or read entry of work_

  void insert(NodeId n, std::uint32_t t, bool boundary);
  void erase(NodeId n);
  void clear_queue();
  void rebuild(const IterationInput& input, TreeCut& cut, IterationResult& r);
  void advance(const IterationInput& input, TreeCut& cut, IterationResult& r, std::uint64_t steps);
  // Processes the events of one frame's list; false when cancelled.
  bool process(std::uint32_t slot, const IterationInput& input, TreeCut& cut, IterationResult& r);

  std::vector<NodeState> state_;            // per hierarchy node
  std::vector<std::vector<NodeId>> slots_;  // the circular buffer: kSlots frames' lists
  std::vector<NodeId> work_;                // a list taken out of its slot for processing
  std::uint16_t processing_ = kNone;        // the slot work_ was taken from, while it is read
  std::uint64_t frame_ = 0;                 // the strategy's frame counter
  std::size_t queued_ = 0;
  bool valid_ = false;           // the queue describes the cut and last_camera_
  CriterionCamera camera_;       // the camera of this iteration
  CriterionCamera last_camera_;  // the camera the queue's events are relative to
  std::uint64_t last_version_ = 0;
  std::uint64_t last_params_ = 0;
  std::size_t last_cut_size_ = 0;
  double rho_ = 0.0;  // model units per frame
  double omega_ = 0.0;
  Stats stats_;
};

}  // namespace treecut::strategies
