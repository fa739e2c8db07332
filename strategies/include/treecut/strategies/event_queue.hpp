// Event-driven refinement: Zach & Karner, "Fast Event-Driven Refinement of
// Dynamic Levels of Detail" (2003), section 3 and figure 7. Every node whose
// state can change carries how far the eye must move (in the translation
// unit, rho or more) or the view direction turn (in units of omega) before
// its fold/unfold test
// (refinement_criterion.hpp, the same test as `topdown`) can change; an
// iteration tests only the nodes whose time has come on either clock. The result equals `topdown`'s
// under the same view, node for node (tests/strategies/event_queue_gl_test.cpp).
//
// The queue is the paper's faster form: circular buffers of lists, one per
// fraction of a unit of each clock. Each list is an array of node ids and every node
// stores its list and index, so insert (append) and erase (the last entry
// moves into the gap) are O(1), and a due list is read front to back with its
// nodes' data prefetched ahead. (Measured on the dragon orbit of
// selection_bench: intrusive doubly-linked lists over node ids took 2x the
// time, a dependent cache miss per event; events carrying their node's
// sphere, 24 bytes, 1.4x, from the writes into the lists.) The children of
// an unfolded node are tested at once.
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
// the node's non-leaf children and a fold erases its subtree's events.
//
// Clocks: two real-valued clocks, one for the eye's translation (in a unit
// that is rho, or `follow` times the eye's recent pace where that is more:
// a fast eye's queue is converted to a larger unit, rounding every time
// down) and one for the view direction's rotation (units of omega), each
// with its own circular buffer of lists; an iteration advances each by
// what the camera really did since the strategy's last camera (moved /
// unit, turned / omega, fractions kept) and handles the lists the clocks
// passed. A node is
// due when either of its two times has come (criterion.cpp: a rotation time
// only where visibility is what keeps the node's change late), so a camera
// that only flies never makes a rotation event due and one that only turns
// never a translation event; a camera faster than rho and omega only makes
// more events due, never a wrong cut. A new lens is motion too (issue 31): a
// zoom by e^z advances the translation clock as a translation of z model
// diameters would, a new half-angle of the cone around the frustum (field
// of view, aspect) the rotation clock by that angle; the threshold times are
// scaled so that this stays a lower bound (criterion.cpp). The same view
// version, or the same camera, costs O(1). A rebuild (one top-down pass that
// schedules every node): the first iteration, a parameter change, reset(), a
// new projection kind, a cut that is not the one the strategy left, an
// iteration cancelled before (the cut then stays valid, the events are
// redone).
//
// The cheaper method each iteration (parameter `adaptive`, on by default):
// before handling the due events the strategy counts them (the sizes of the
// lists the clocks will pass) and compares their cost, kappa tests each
// (`event_cost`), with a plain top-down pass over the queue's nodes; a
// camera fast enough that a pass is cheaper gets the pass (the queue waits,
// out of date), and a jump of the camera (kSlots / 2 units or more) too.
// While passes run, every 128th test also computes its event time, and the
// events' cost for the current motion is predicted from those samples; once
// it is half a pass or less three iterations in a row, a rebuild returns to
// the events. Orthographic views: a top-down pass every iteration.
//
// The rotation lists are lazy: a node's rotation entry is only moved when
// its new time is earlier than the one it has (an early test is always
// correct), and a moved or dropped entry stays behind, recognized as stale
// because the node's state names another slot; the lists are compacted when
// stale entries outnumber live ones twice.
//
// A due list is handled in batches of 16: first every entry's decide() (the
// test and the next event time, pure functions of the camera and the node,
// so the long sqrt/division chains of consecutive entries overlap), then the
// queue and cut edits. Everything an event reads of a node is in one 32-byte
// record (a copy of the sphere, the children's range, the queue position) in
// huge-page memory: one cache line and no TLB miss per event instead of four
// arrays (docs/event-driven.md, "Speed").
//
// Memory: 32 bytes per resident node plus 4 bytes per queued event, and 4
// per rotation entry (live or stale, at most 3 per live one plus 65,536).
// The records lie in address space reserved for every node id, written
// only for the nodes the hierarchy holds: every node of a model held
// whole; of a paged model the resident ones, made as pages arrive
// (IterationInput::revealed) and given back with them (concealed), so the
// state follows the resident set, not the file (issue 45).
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <vector>

#include "treecut/reserved_array.hpp"
#include "treecut/strategies/refinement_criterion.hpp"
#include "treecut/strategy.hpp"

namespace treecut::strategies {

class EventQueueStrategy final : public Strategy {
 public:
  enum Param : std::size_t {
    kTheta,      ///< pixels: a node unfolds when its projected radius reaches theta
    kRho,        ///< maximal eye translation per frame, in model diameters (root sphere)
    kOmega,      ///< maximal rotation of the view direction per frame, radians
    kAdaptive,   ///< 1: each iteration takes the cheaper of the events and a top-down pass
    kEventCost,  ///< an event's cost in top-down tests, for that choice
    kFollow,     ///< the translation unit: at least rho, and this times the eye's peak motion
  };
  /// How the last iteration got its cut.
  enum class Method : std::uint8_t {
    kNone,     ///< nothing to do (same view, or the same camera)
    kEvents,   ///< the due events (figure 7)
    kRebuild,  ///< a top-down pass that also scheduled every node's event
    kTopDown,  ///< a plain top-down pass; the queue waits, out of date
  };
  /// Lists in the circular buffer of each clock, and lists per unit (the
  /// translation unit, omega); events farther than half a buffer are tested
  /// then (and rescheduled): after 511.75 units or 63.98 omega. A camera
  /// that moves or turns that much in one iteration is a jump.
  static constexpr std::uint32_t kTranslationSlots = 4096;
  static constexpr std::uint32_t kTranslationSlotsPerUnit = 4;
  static constexpr std::uint32_t kRotationSlots = 8192;
  static constexpr std::uint32_t kRotationSlotsPerUnit = 64;

  EventQueueStrategy();
  [[nodiscard]] std::string_view name() const override { return "event_queue"; }
  [[nodiscard]] Mode mode() const override { return Mode::Evolve; }
  void reset(const Hierarchy& hierarchy) override;
  /// A paged model's residency changed (IterationInput::revealed and
  /// concealed): the records of the nodes that gained their children and
  /// of those below them made again, and of those that lost them; with a
  /// valid queue, revealed cut nodes handled as boundary nodes under the
  /// last camera, else the next iteration rebuilds.
  void follow_residency(const IterationInput& input, TreeCut& cut, IterationResult& r);
  void iterate(const IterationInput& input, IterationOutput& output) override;

  /// Statistics of the last iteration, for tests and benchmarks.
  struct Stats {
    std::uint64_t frames_advanced = 0;  ///< ceil(max(moved, turned)); 0: nothing due
    double moved = 0.0;                 ///< translation clock advance, in its unit
    double turned = 0.0;                ///< rotation clock advance, units of omega
    double unit = 0.0;                  ///< the translation clock's unit, model diameters
    bool rescaled = false;              ///< the queue's translation times were converted to it
    Method method = Method::kNone;      ///< how the cut was made
    bool rebuilt = false;               ///< the queue was rebuilt (method kRebuild)
    std::size_t predicted = 0;          ///< events predicted due (method kEvents or kTopDown)
    std::size_t queued = 0;             ///< events in the translation lists afterwards
    std::size_t rotation_queued = 0;    ///< nodes with a live rotation entry afterwards
    std::uint64_t rotation_events = 0;  ///< events handled from the rotation lists
    std::uint64_t descended = 0;        ///< children of unfolds tested at once
    std::uint64_t changed = 0;          ///< tests that changed the cut (unfolds and folds)
    std::uint64_t unfolded = 0;         ///< of those, unfolds (the rest folded a subtree)
  };
  [[nodiscard]] const Stats& stats() const { return stats_; }
  /// Bytes of the event state: the records of the nodes made (every
  /// resident node), and the lists' storage.
  [[nodiscard]] std::size_t state_bytes() const {
    std::size_t bytes =
        made_ * sizeof(NodeState) + (work_.capacity() + wwork_.capacity()) * sizeof(NodeId);
    for (const auto& s : slots_) bytes += s.capacity() * sizeof(NodeId);
    for (const auto& s : wslots_) bytes += s.capacity() * sizeof(NodeId);
    return bytes;
  }
  /// Records made: the resident nodes' (every node of a model held whole).
  [[nodiscard]] std::size_t records() const { return made_; }
  /// Bytes per resident node of the records, and per queued event.
  static constexpr std::size_t kBytesPerNode = 32;
  static constexpr std::size_t kBytesPerEvent = 4;
  /// Every kTrimEvery iterations a list past four times what it holds, and
  /// past kTrimFloor entries, gives its storage back (trim_lists).
  static constexpr std::uint64_t kTrimEvery = 64;
  static constexpr std::size_t kTrimFloor = 1024;

 private:
  // Per node, all that an event reads and writes, in one aligned 32-byte
  // record (half a cache line): a copy of the node's sphere and of its
  // children's range, which translation list holds its event and where, and
  // which rotation list holds its live rotation entry (with the boundary flag
  // of that entry in the top bit). An event used to touch four arrays in
  // random order (the sphere, the children, the child count, this state):
  // four cache lines and four pages. The sphere is a bit-for-bit copy, so the
  // test is still unfold_test on the very same floats as topdown's.
  //
  // A record of zero bytes (memory never written, or given back) is one not
  // made and not queued: the slots are stored XOR their "none".
  struct alignas(32) NodeState {
    glm::vec4 sphere{0.0f};
    NodeId first_child = 0;
    std::uint8_t child_count = 0;
    std::uint8_t made = 0;  // 1: copied from the hierarchy (a resident node)
    std::uint32_t index = 0;
    std::uint16_t slot_bits = 0;
    std::uint16_t wslot_bits = 0;
    [[nodiscard]] std::uint16_t slot() const { return slot_bits ^ kNone; }
    [[nodiscard]] std::uint16_t wslot() const { return wslot_bits ^ kNoneW; }
    void set_slot(std::uint16_t s) { slot_bits = s ^ kNone; }
    void set_wslot(std::uint16_t s) { wslot_bits = s ^ kNoneW; }
  };
  static_assert(sizeof(NodeState) == 32);
  // NODE's record made from the hierarchy (its sphere and children; not
  // queued); made_ is the caller's to count.
  void make_record(const HierarchyArrays& a, NodeId n);
  // Makes the records of the nodes in runs_ and below them, none made
  // before, down through the hierarchy's children (runs_ is left empty).
  void make_records(const HierarchyArrays& a);
  // Gives back the records of the nodes in runs_ and below them, down
  // through their records' children: the hierarchy no longer has them.
  void give_back_records();
  static constexpr std::uint16_t kNone = 0xffff;   // not queued
  static constexpr std::uint16_t kNoneW = 0x7fff;  // no rotation entry (slots are 13 bits)
  static constexpr std::uint16_t kWBoundary = 0x8000;
  // A list entry is a node id with this bit set for a boundary node (in the
  // cut; else active), so a due event reads only its node's sphere.
  static constexpr NodeId kBoundary = 0x80000000u;
  static constexpr NodeId kErased = 0xffffffffu;  // an erased or read entry of work_

  // Queues n (just tested under this camera and decided: boundary or active)
  // with its event time.
  void schedule(NodeId n, const EventTime& t, bool boundary);
  void erase(NodeId n);          // the translation entry
  void drop_rotation(NodeId n);  // the rotation entry becomes stale
  void clear_queue();
  void compact_rotation_lists();
  void rebuild(const IterationInput& input, TreeCut& cut, IterationResult& r);
  // A plain top-down pass on the hierarchy's arrays; the queue is left as it is.
  bool pass(const IterationInput& input, TreeCut& cut, IterationResult& r);
  // The events in the lists an advance by (dm, dw) would handle (rotation
  // entries counted as live in the proportion the lists hold).
  [[nodiscard]] double due_events(double dm, double dw) const;
  // Which method this iteration takes, from the motion (units of the clocks).
  [[nodiscard]] Method choose(double dm, double dw);
  // The method from the camera's motion since the queue's camera (KNOWN:
  // the cut is topdown's for it; FAR: a jump), and carrying it out (false
  // when cancelled).
  [[nodiscard]] Method pick(bool known, bool far, double dm, double dw, bool adaptive);
  bool carry_out(Method method, const IterationInput& input, TreeCut& cut, IterationResult& r,
                 double dm, double dw);
  // While passes run: the events a valid queue would have made due for a
  // motion (dm, dw), from the event times sampled in the last pass, scaled
  // to its tests.
  [[nodiscard]] double predicted_from_samples(double dm, double dw) const;
  bool advance(const IterationInput& input, TreeCut& cut, IterationResult& r, double dm, double dw);
  // Acts on a due node's decision (its test and next event time; its entries
  // already taken).
  void handle(NodeId n, bool boundary, const Decision& dec, const IterationInput& input,
              TreeCut& cut, IterationResult& r);
  // Folds the active node n: its subtree collapses into it, its nodes'
  // events go.
  void fold(NodeId n, TreeCut& cut, IterationResult& r);
  // Moves a translation list into work_ for run().
  void take(std::uint32_t slot);
  // Handles the events of work_ (a translation list) or wwork_ (the rotation
  // list of `slot`); false when cancelled.
  bool run(const IterationInput& input, TreeCut& cut, IterationResult& r);
  bool run_rotation(std::uint32_t slot, const IterationInput& input, TreeCut& cut,
                    IterationResult& r);

  // The records, by node id: address space for every node, written for
  // the resident ones (state_ is records_->data()).
  std::unique_ptr<ReservedArray<NodeState>> records_;
  NodeState* state_ = nullptr;
  std::size_t node_count_ = 0;               // the hierarchy's
  std::size_t made_ = 0;                     // records made
  std::vector<NodeRange> runs_, next_runs_;  // a level of a walk over records
  const glm::vec4* spheres_ = nullptr;       // the hierarchy state_ was copied from
  std::vector<std::vector<NodeId>> slots_;   // translation clock: kSlots lists
  std::vector<std::vector<NodeId>> wslots_;  // rotation clock: kSlots lists
  std::vector<NodeId> work_;                 // a list taken out of its slot for processing
  std::vector<NodeId> wwork_;                // the same for a rotation list
  std::uint16_t processing_ = kNone;         // the slot work_ was taken from, while it is read
  // The clocks: the current slot's number and the fraction within it.
  std::uint64_t mbase_ = 0, wbase_ = 0;
  double mfrac_ = 0.0, wfrac_ = 0.0;
  std::size_t queued_ = 0;
  std::size_t wlive_ = 0;     // nodes with a live rotation entry
  std::size_t wentries_ = 0;  // entries in the rotation lists, live or stale
  // The camera's recent pace (moving average per iteration) in either unit:
  // their ratio sets how a visibility gap is split between the clocks.
  double pace_m_ = 1.0, pace_w_ = 1.0;
  bool valid_ = false;    // the queue describes the cut and last_camera_
  bool current_ = false;  // the cut is topdown's for last_camera_
  // A paged model: where this iteration reports the hidden nodes it wants
  // (IterationOutput::wanted), and the hidden cut leaves the last pass met.
  std::vector<NodeId>* wanted_ = nullptr;
  std::vector<NodeId> hidden_;
  void want_hidden(const Hierarchy& h, const TreeCut& cut);
  // The choice of method (choose()): iterations in a row in which the
  // events were predicted dearer than a pass (over_), or, while passes run,
  // much cheaper (calm_); the tests an event brings (itself and the
  // children of unfolds), measured on event iterations; the tests of the
  // last pass, and the event times of every kSampleEvery-th node it tested
  // (the time decide() gives, as a rebuild would schedule it).
  int over_ = 0, calm_ = 0;
  // Calm iterations needed before a rebuild: doubled (up to 64) when the
  // events after the last one lasted under kShortRun iterations, so a
  // camera at the crossing of the costs does not rebuild again and again.
  int calm_needed_ = 3;
  int events_run_ = 0;  // event iterations since the last rebuild
  static constexpr int kShortRun = 8;
  double tests_per_event_ = 1.0;
  double pass_tests_ = 0.0;
  static constexpr std::uint32_t kSampleEvery = 512;
  std::vector<EventTime> samples_;
  std::vector<NodeId> level_, next_level_;  // a pass's frontier
  CriterionConstants camera_;               // the camera of this iteration
  CriterionConstants last_camera_;          // the camera the queue's events are relative to
  EventRates rates_{CriterionConstants{}, 1.0, 1.0, 1.0, 1.0};
  std::uint64_t last_version_ = 0;
  std::uint64_t last_params_ = 0;
  std::size_t last_cut_size_ = 0;
  // The translation clock's unit (model units): rho, or more for a fast
  // eye (follow_unit()); fixed while the queue is valid unless converted
  // (rescale()). The rotation clock's unit is omega.
  double unit_ = 0.0;
  double omega_ = 0.0;
  // The eye's recent peak motion an iteration (model units): a maximum that
  // decays by kPeakDecay an iteration.
  double peak_ = 0.0;
  double last_moved_ = 0.0;  // the eye's motion in the last iteration
  static constexpr double kPeakDecay = 0.9;
  // The unit the eye's pace asks for: rho at least.
  [[nodiscard]] double follow_unit(double rho) const;
  // Tracks the eye's pace (peak_) and converts a valid queue to the unit it
  // asks for when that is 2 times off.
  void follow_pace(double moved, bool far, bool known, double rho);
  struct Motion {
    double moved = 0.0;   // model units, a zoom included
    double turned = 0.0;  // units of omega, a new cone included
  };
  [[nodiscard]] Motion motion_since_last(double diameter) const;
  // Converts the queued translation times to a new unit (each rounded
  // down: an earlier test is always correct); the lists are swapped with
  // spare_, so no list is allocated.
  void rescale(double unit);
  std::vector<std::vector<NodeId>> spare_;
  void trim_lists();
  std::uint64_t iterations_ = 0;
  std::size_t list_bytes_ = 0;  // the lists' storage at the last trim
  Stats stats_;
};

}  // namespace treecut::strategies
