// Event-driven refinement (Zach & Karner 2003, section 3, figure 7); see
// event_queue.hpp for what is queued and why, criterion.cpp for the event
// times.
#include "treecut/strategies/event_queue.hpp"

#include <algorithm>
#include <bit>
#include <cmath>
#include <memory>

#include "event_time.hpp"
#include "top_down.hpp"

namespace treecut::strategies {
namespace {

// Either clock's circular buffer: kSlots lists, a list per 1 / kPerUnit of
// a unit (rho, omega). A slot's list is handled whenever the clock advances
// within it, however little, so a slot is a fraction of a unit: a camera
// that turns by float noise only (a flythrough's lookAt) makes only the
// rotation events due within 1/64 omega handled again.
constexpr std::uint32_t kMSlots = EventQueueStrategy::kTranslationSlots;
constexpr std::uint32_t kWSlots = EventQueueStrategy::kRotationSlots;
constexpr std::uint32_t kMMask = kMSlots - 1;
constexpr std::uint32_t kWMask = kWSlots - 1;
static_assert((kMSlots & kMMask) == 0 && (kWSlots & kWMask) == 0, "powers of two");
constexpr double kMPerUnit = EventQueueStrategy::kTranslationSlotsPerUnit;
constexpr double kWPerUnit = EventQueueStrategy::kRotationSlotsPerUnit;
// The farthest event, in units of each clock: beyond half the buffer, slots
// not yet processed in a multi-slot advance would be reused (see advance()).
constexpr double kMCap = double(kMSlots / 2 - 1) / kMPerUnit;
constexpr double kWCap = double(kWSlots / 2 - 1) / kWPerUnit;
// What a rotation event costs against a translation event: run_rotation()
// handles its entries one by one, run() in batches whose tests overlap
// (measured on selection_bench's turn and sweep paths over the dragon: 47-54
// and 32-39 ns an event).
constexpr double kRotationWeight = 1.5;
// Entries handled between two looks at the cancellation flag.
constexpr std::uint64_t kCancelEvery = 4096;

}  // namespace

EventQueueStrategy::EventQueueStrategy()
    : Strategy({
          {"theta", "pixels: a node unfolds when its projected radius reaches theta", 1.5, 0.05,
           1e6, false},
          {"rho", "maximal eye translation per frame, in diameters of the model", 0.002, 1e-7, 10.0,
           false},
          {"omega", "maximal rotation of the view direction per frame, radians", 0.02, 1e-6, 3.1416,
           false},
          {"adaptive",
           "1: each iteration takes the cheaper of the due events and a top-down pass; 0: the "
           "events always",
           1.0, 0.0, 1.0, true},
          {"event_cost", "an event's cost in top-down tests, for that choice", 3.5, 0.5, 100.0,
           false},
          {"follow",
           "the translation clock's unit: at least rho, and this many times the eye's recent "
           "peak motion an iteration (0: rho)",
           2.0, 0.0, 100.0, false},
      }) {}

// Written whole, never read first: a read of a record not yet written
// maps the zero page, and the write after it then copies and shoots the
// mapping down on every core (on the 500 M-point survey a paged flight's
// iterations spent a tenth of their time in those interrupts).
void EventQueueStrategy::make_record(const HierarchyArrays& a, NodeId n) {
  NodeState st{};
  st.sphere = a.center_radius[n];
  st.child_count = a.child_count[n];
  st.first_child = st.child_count != 0 ? a.first_child[n] : 0;
  st.made = 1;
  state_[n] = st;
}

static NodeRange children_of(const HierarchyArrays& a, NodeId n) {
  return NodeRange{a.first_child[n], a.child_count[n]};
}

// VISIT(run) for the runs in RUNS and every run of nodes below them, level
// by level, CHILDREN(n) read before n's run is visited. A level's children
// are runs of consecutive ids, and adjacent runs merge (breadth-first ids
// put the children of consecutive nodes side by side), so a model held
// whole is one run a level, written front to back, and a paged model's
// levels a run per stretch of resident pages.
template <class Children, class Visit>
static void walk_levels(std::vector<NodeRange>& runs, std::vector<NodeRange>& next,
                        Children&& children, Visit&& visit) {
  while (!runs.empty()) {
    next.clear();
    for (const NodeRange r : runs) {
      for (NodeId n = r.first; n < r.first + r.count; ++n) {
        const NodeRange c = children(n);
        if (c.count == 0) continue;
        if (!next.empty() && next.back().first + next.back().count == c.first) {
          next.back().count += c.count;
        } else {
          next.push_back(c);
        }
      }
      visit(r);
    }
    runs.swap(next);
  }
}

void EventQueueStrategy::make_records(const HierarchyArrays& a) {
  walk_levels(
      runs_, next_runs_, [&](NodeId n) { return children_of(a, n); },
      [&](NodeRange r) {
        records_->advise_huge(r.first, r.count);
        records_->use(r.first, r.count);
        for (NodeId n = r.first; n < r.first + r.count; ++n) make_record(a, n);
        made_ += r.count;
      });
}

void EventQueueStrategy::give_back_records() {
  walk_levels(
      runs_, next_runs_,
      [&](NodeId n) {
        const NodeState& st = state_[n];
        return NodeRange{st.first_child, st.made != 0 ? st.child_count : std::uint32_t{0}};
      },
      [&](NodeRange r) {
        // The made records only, in runs: the memory pages count what was
        // made (make_records), and a record not made counted nothing.
        NodeId from = r.first;
        for (NodeId n = r.first; n <= r.first + r.count; ++n) {
          if (n < r.first + r.count && state_[n].made != 0) continue;
          if (from < n) records_->release(from, n - from);
          made_ -= n - from;
          from = n + 1;
        }
      });
}

void EventQueueStrategy::reset(const Hierarchy& hierarchy) {
  node_count_ = hierarchy.node_count();
  // Counted: the records given back with a group of pages share memory
  // pages with others at their runs' ends, given back with the last.
  records_ = std::make_unique<ReservedArray<NodeState>>(node_count_, PageSharing::counted);
  state_ = records_->data();
  made_ = 0;
  const HierarchyArrays& a = hierarchy.arrays();
  // A model held whole gets huge pages under all its records, the levels'
  // edges included (the events read them in random order: docs/
  // event-driven.md, "Speed"); a paged model's runs of resident nodes under
  // their insides only (make_records()), so that no huge page holds mostly
  // records of nodes not resident. Whole: every node reachable through
  // children.
  std::size_t resident = 0;
  runs_.assign(1, NodeRange{hierarchy.root(), 1});
  walk_levels(
      runs_, next_runs_, [&](NodeId n) { return children_of(a, n); },
      [&](NodeRange r) { resident += r.count; });
  if (resident == node_count_) records_->advise_huge(0, node_count_);
  runs_.assign(1, NodeRange{hierarchy.root(), 1});
  make_records(a);
  spheres_ = a.center_radius.data();
  // A pass's frontier (the active nodes of a level) grows as passes need
  // it and keeps its room: about the cut's size, not half the model's.
  level_.clear();
  next_level_.clear();
  slots_.assign(kMSlots, {});
  spare_.assign(kMSlots, {});
  wslots_.assign(kWSlots, {});
  work_.clear();
  wwork_.clear();
  processing_ = kNone;
  mbase_ = wbase_ = 0;
  mfrac_ = wfrac_ = 0.0;
  queued_ = wlive_ = wentries_ = 0;
  pace_m_ = pace_w_ = 1.0;
  unit_ = peak_ = last_moved_ = 0.0;
  valid_ = false;
  stats_ = {};
  iterations_ = 0;
  list_bytes_ = 0;
}

// Inlined into its callers, the batch loop of run() above all: as a call it
// cost 5 ns of an event's 78 on the terrain flythrough and 4 to 8 of 37 to
// 45 on the dragon's and the lion's paths (selection_bench, alternating
// runs; docs/event-driven.md, "Speed").
[[gnu::always_inline]] inline void EventQueueStrategy::schedule(NodeId n, const EventTime& t,
                                                                bool boundary) {
  NodeState& st = state_[n];
  // Translation: the list of the slot the clock is in after t.m units (t.m
  // <= kMCap, so at most kCapSlots ahead). That may be the current slot: its
  // list is handled again at the next advance of the clock, however small.
  const std::uint64_t ms = mbase_ + static_cast<std::uint64_t>(mfrac_ + t.m * kMPerUnit);
  const auto slot = static_cast<std::uint16_t>(ms & kMMask);
  std::vector<NodeId>& list = slots_[slot];
  st.index = static_cast<std::uint32_t>(list.size());
  st.set_slot(slot);
  list.push_back(boundary ? n | kBoundary : n);
  ++queued_;
  // Rotation: none when rotation alone cannot change the test.
  if (!(t.w <= kWCap)) {
    if (st.wslot() != kNoneW) {
      st.set_wslot(kNoneW);
      --wlive_;
    }
    return;
  }
  // Slots ahead, and the slot used when a new entry is needed: rounded down
  // to 3 significant bits (at most 25 % early), so a node whose time keeps
  // shrinking while the clock stands still (a camera that flies without
  // turning) needs a new entry only every quarter of its time or so.
  const auto ahead = static_cast<std::uint64_t>(wfrac_ + t.w * kWPerUnit);
  const std::uint16_t flag = boundary ? kWBoundary : 0;
  if (st.wslot() != kNoneW) {
    // The entry the node has is kept when it comes no later and is for the
    // same state: an earlier test is always correct.
    if ((st.wslot() & kWBoundary) == flag &&
        ((std::uint64_t(st.wslot() & kWMask) - wbase_) & kWMask) <= ahead) {
      return;
    }
  } else {
    ++wlive_;
  }
  const int drop = std::max(0, int(std::bit_width(ahead)) - 3);
  const std::uint64_t ws = wbase_ + ((ahead >> drop) << drop);
  st.set_wslot(static_cast<std::uint16_t>((ws & kWMask) | flag));
  wslots_[ws & kWMask].push_back(n);
  ++wentries_;
}

void EventQueueStrategy::erase(NodeId n) {
  NodeState& e = state_[n];
  if (e.slot() == kNone) return;
  if (e.slot() == processing_ && e.index < work_.size() && (work_[e.index] & ~kBoundary) == n) {
    // Still to come in the list being processed: marked, not moved, so the
    // reader's position stays right. (Entries already read are kErased, so
    // an equal id here is the node's current entry.)
    work_[e.index] = kErased;
  } else {
    std::vector<NodeId>& list = slots_[e.slot()];
    const NodeId last = list.back();
    list[e.index] = last;
    state_[last & ~kBoundary].index = e.index;
    list.pop_back();
  }
  e.set_slot(kNone);
  --queued_;
}

void EventQueueStrategy::drop_rotation(NodeId n) {
  NodeState& e = state_[n];
  if (e.wslot() == kNoneW) return;
  e.set_wslot(kNoneW);  // its entry is stale now
  --wlive_;
}

// The lists only: the records of the nodes they held keep their old slots
// and indices. Every node is queued again through rebuild() or as a child of
// an unfold, and both reset its record first; no other code reads the
// record of a node that is not queued (a fold erases only queued nodes and
// leaves, which are never queued). So a rebuild costs no random access per
// old event.
void EventQueueStrategy::clear_queue() {
  for (std::vector<NodeId>& list : slots_) list.clear();
  for (std::vector<NodeId>& list : wslots_) list.clear();
  work_.clear();
  wwork_.clear();
  processing_ = kNone;
  queued_ = wlive_ = wentries_ = 0;
}

void EventQueueStrategy::compact_rotation_lists() {
  std::size_t kept = 0;
  for (std::uint32_t s = 0; s < kWSlots; ++s) {
    std::vector<NodeId>& list = wslots_[s];
    std::size_t out = 0;
    const std::size_t count = list.size();
    for (std::size_t i = 0; i < count; ++i) {
      // The records are read in random order: ahead of time.
      if (i + 16 < count) __builtin_prefetch(&state_[list[i + 16]]);
      const NodeId n = list[i];
      const std::uint16_t w = state_[n].wslot();
      if (w != kNoneW && (w & kWMask) == s) list[out++] = n;
    }
    list.resize(out);
    kept += out;
  }
  wentries_ = kept;
}

// topdown's pass (the same test on the same floats, the same edits), level
// by level with the nodes ahead prefetched (detail::level_pass): after event
// iterations the hierarchy's arrays are cold, and the recursion of figure 3
// waited for memory at every node (a pass at a teleport took 1.3-1.4 times
// topdown's; level by level 0.99-1.14, docs/benchmarks.md). On the
// hierarchy's arrays rather than the records: fewer bytes a node (on the
// records a pass at a teleport took 1.26-1.30 times topdown's, on the arrays
// 1.08-1.10 in the same runs).
bool EventQueueStrategy::pass(const IterationInput& input, TreeCut& cut, IterationResult& r) {
  const auto& cr = input.hierarchy.arrays().center_radius;
  // Every kSampleEvery-th test is decide(): the same test, and the event
  // time a rebuild would give the node, for predicting what the events
  // would cost (choose()); 1/512 of the tests (1/128 cost a teleport's pass
  // 2-4 % more; 200 to 300 samples still predict the events of the dragon).
  samples_.clear();
  std::uint32_t k = 0;
  auto test = [&](NodeId n) {
    if (++k % kSampleEvery != 0) return unfold_test(camera_, cr[n]);
    const Decision d = event_time::decide(camera_, cr[n], rates_);
    samples_.push_back(d.t);
    return d.pass;
  };
  auto decided = [](NodeId, bool) {};
  auto drop = [](NodeId) {};
  hidden_.clear();
  return detail::level_pass(input.hierarchy, cut, r, input, test, decided, drop, level_,
                            next_level_, wanted_, &hidden_);
}

// A jump: one top-down pass (figure 3, the code `topdown` runs) decides every
// active and boundary node under the current camera and schedules its next
// event. Each was just tested, so no event is due before the next slot. It
// walks the hierarchy's arrays like pass(), not the records it writes: the
// next pass (a teleport) then finds them warm (a teleport after a rebuild
// from the records took 1.08-1.11 times topdown's, from the arrays
// 1.00-1.04 in the same runs, and the rebuild itself no longer).
void EventQueueStrategy::rebuild(const IterationInput& input, TreeCut& cut, IterationResult& r) {
  clear_queue();
  const auto& cr = input.hierarchy.arrays().center_radius;
  // The pass tells decided(n) right after test(n), with no other test
  // between, so the test's decision (the test and the event of its result,
  // one look() at the node instead of two) is kept for it: the node is
  // active exactly when its test passed. Its record may hold an old queue
  // position (clear_queue()): reset before it is queued.
  Decision last{};
  auto test = [&](NodeId n) {
    last = event_time::decide(camera_, cr[n], rates_);
    return last.pass;
  };
  auto decided = [&](NodeId n, bool active) {
    state_[n].set_slot(kNone);
    state_[n].set_wslot(kNoneW);
    schedule(n, last.t, !active);
  };
  // A folded subtree is below the nodes this pass has queued: nothing to erase.
  auto drop = [](NodeId) {};
  hidden_.clear();
  valid_ = detail::level_pass(input.hierarchy, cut, r, input, test, decided, drop, level_,
                              next_level_, wanted_, &hidden_);
  stats_.rebuilt = true;
}

// Figure 7 for both clocks: every list of a slot the clock was in since the
// last iteration (from the one it was in then, whose entries may have a time
// in its rest, to the one it is in now) is handled once, testing its nodes
// against the current camera (the only one there is; the events were
// computed so that nothing else can have changed). Insertions are relative to
// the clocks' new values, at most kCapSlots ahead, so they never land in a
// list of this advance still to be processed (an advance is below half the
// buffer);
// the current lists are taken out first, so what is inserted into them waits
// for the next advance.
bool EventQueueStrategy::advance(const IterationInput& input, TreeCut& cut, IterationResult& r,
                                 double dm, double dw) {
  const std::uint64_t mfrom = mbase_, wfrom = wbase_;
  const double mt = mfrac_ + dm * kMPerUnit, wt = wfrac_ + dw * kWPerUnit;
  mbase_ += static_cast<std::uint64_t>(mt);
  mfrac_ = mt - std::floor(mt);
  wbase_ += static_cast<std::uint64_t>(wt);
  wfrac_ = wt - std::floor(wt);
  const auto mslot = [](std::uint64_t s) { return static_cast<std::uint32_t>(s & kMMask); };
  const auto wslot = [](std::uint64_t s) { return static_cast<std::uint32_t>(s & kWMask); };
  const bool moved = dm > 0.0, turned = dw > 0.0;
  if (moved) take(mslot(mbase_));
  if (turned) wwork_.swap(wslots_[wslot(wbase_)]);
  if (moved && !run(input, cut, r)) return false;
  if (turned && !run_rotation(wslot(wbase_), input, cut, r)) return false;
  for (std::uint64_t s = mfrom; moved && s < mbase_; ++s) {
    take(mslot(s));
    if (!run(input, cut, r)) return false;
  }
  for (std::uint64_t s = wfrom; turned && s < wbase_; ++s) {
    wwork_.swap(wslots_[wslot(s)]);
    if (!run_rotation(wslot(s), input, cut, r)) return false;
  }
  return true;
}

void EventQueueStrategy::handle(NodeId n, bool boundary, const Decision& dec,
                                const IterationInput& input, TreeCut& cut, IterationResult& r) {
  // dec.t is the event of the state the node is in afterwards: its fold
  // event when it passes (active), its unfold event when not (boundary).
  if (boundary) {
    if (!dec.pass) {
      schedule(n, dec.t, true);
      return;
    }
    // Unfold: the node is active now (its fold event), and its non-leaf
    // children become boundary nodes, tested right away (they may unfold
    // too: the descent of figure 3 below n).
    // From the node's record: n is a boundary node (in the cut, not a leaf).
    cut.refine_known(n, state_[n].first_child, state_[n].child_count);
    ++r.refined;
    ++stats_.changed;
    ++stats_.unfolded;
    schedule(n, dec.t, false);
    const NodeId first = state_[n].first_child;
    const NodeId end = first + state_[n].child_count;
    for (NodeId ch = first; ch < end; ++ch) {
      if (state_[ch].child_count == 0) continue;
      // Not queued until now; its record may hold an old position (clear_queue()).
      state_[ch].set_slot(kNone);
      state_[ch].set_wslot(kNoneW);
      ++r.visited;
      ++stats_.descended;
      handle(ch, true, decide(camera_, state_[ch].sphere, rates_), input, cut, r);
    }
  } else if (dec.pass) {
    schedule(n, dec.t, false);
  } else {
    // Fold: the subtree collapses into n and its events go; n becomes a
    // boundary node waiting to unfold.
    fold(n, cut, r);
    ++stats_.changed;
    schedule(n, dec.t, true);
  }
}

// detail::fold_subtree (the same edits in the same order) on the node
// records: the children's records are in cache already (run() prefetched
// them), and a leaf child is known from its record without reading the
// cut's slot of it (on the terrain flythrough, 6,000 folds an iteration,
// that read took the iteration from 4.1 to 4.7 ms).
void EventQueueStrategy::fold(NodeId n, TreeCut& cut, IterationResult& r) {
  const NodeId first = state_[n].first_child;
  const unsigned count = state_[n].child_count;
  for (NodeId c = first; c < first + count; ++c) {
    if (state_[c].child_count != 0 && !cut.contains(c)) fold(c, cut, r);
    erase(c);
    drop_rotation(c);
  }
  cut.coarsen_known(n, first, count);
  ++r.coarsened;
}

void EventQueueStrategy::take(std::uint32_t slot) {
  // The slot gets work_'s empty buffer, so a fold that erases an entry still
  // to come marks it instead of moving it.
  work_.swap(slots_[slot]);
  processing_ = static_cast<std::uint16_t>(slot);
}

bool EventQueueStrategy::run(const IterationInput& input, TreeCut& cut, IterationResult& r) {
  constexpr std::size_t kAhead = 32;  // entries prefetched ahead, enough to cover a DRAM miss
  const std::size_t count = work_.size();
  // Batches: first every entry's test and, where it does not change (nine
  // events in ten on the flythrough), its next event time; then the queue and
  // cut edits. The first half only reads (the test and the times are pure
  // functions of the camera and the node), so the long sqrt/division chains
  // of consecutive entries overlap instead of waiting behind each entry's
  // list writes; a decision stays right whatever the second half did before
  // it: a fold earlier in the batch can only erase an entry (checked again),
  // never change the node's state or sphere.
  constexpr std::size_t kBatch = 16;
  Decision d[kBatch];
  for (std::size_t b0 = 0; b0 < count; b0 += kBatch) {
    const std::size_t b1 = std::min(count, b0 + kBatch);
    for (std::size_t i = b0; i < b1; ++i) {
      if (i + kAhead < count && work_[i + kAhead] != kErased) {
        __builtin_prefetch(&state_[work_[i + kAhead] & ~kBoundary], 1);
      }
      const NodeId entry = work_[i];
      if (entry == kErased) continue;
      const NodeId n = entry & ~kBoundary;
      const bool boundary = (entry & kBoundary) != 0;
      d[i - b0] = event_time::decide(camera_, state_[n].sphere, rates_);
      if (d[i - b0].pass == boundary) {
        // A change: an unfold reads the node's and its children's entries of
        // the cut and the children's records (contiguous) next, a fold the
        // children's.
        const NodeState& st = state_[n];
        __builtin_prefetch(&state_[st.first_child], 1);
        __builtin_prefetch(&state_[st.first_child + st.child_count - 1], 1);
        cut.prefetch(st.first_child);
        if (boundary) cut.prefetch(n);
      }
    }
    // The changes' list positions in the cut, now that their slot entries
    // (prefetched above) have arrived: refine writes the node's, coarsen
    // the children's.
    for (std::size_t i = b0; i < b1; ++i) {
      const NodeId entry = work_[i];
      if (entry == kErased || d[i - b0].pass != ((entry & kBoundary) != 0)) continue;
      const NodeId n = entry & ~kBoundary;
      if ((entry & kBoundary) != 0) {
        cut.prefetch_position(n);
      } else {
        const NodeState& st = state_[n];
        for (NodeId c = st.first_child; c < st.first_child + st.child_count; ++c) {
          cut.prefetch_position(c);
        }
      }
    }
    for (std::size_t i = b0; i < b1; ++i) {
      const NodeId entry = work_[i];
      if (entry == kErased) continue;
      if ((++r.visited % kCancelEvery) == 0 && input.cancelled()) {
        // The rest of work_ stays for clear_queue (the next iteration rebuilds).
        processing_ = kNone;
        return false;
      }
      work_[i] = kErased;
      --queued_;
      const NodeId n = entry & ~kBoundary;
      const bool boundary = (entry & kBoundary) != 0;
      // No state_[n].set_slot(kNone) here: n is queued again either way.
      // The test changed (a boundary node passes, an active one fails): the
      // cut changes; else the node waits for its next time.
      if (d[i - b0].pass == boundary) {
        handle(n, boundary, d[i - b0], input, cut, r);
      } else {
        schedule(n, d[i - b0].t, boundary);
      }
    }
  }
  work_.clear();
  processing_ = kNone;
  return true;
}

bool EventQueueStrategy::run_rotation(std::uint32_t slot, const IterationInput& input, TreeCut& cut,
                                      IterationResult& r) {
  constexpr std::size_t kAhead = 16;
  const std::size_t count = wwork_.size();
  for (std::size_t i = 0; i < count; ++i) {
    if (i + kAhead < count) {
      __builtin_prefetch(&state_[wwork_[i + kAhead]], 1);
    }
    const NodeId n = wwork_[i];
    NodeState& st = state_[n];
    // A stale entry: the node's live one is elsewhere, or it has none.
    if (st.wslot() == kNoneW || (st.wslot() & kWMask) != slot) {
      wwork_[i] = kErased;
      --wentries_;
      continue;
    }
    if ((++r.visited % kCancelEvery) == 0 && input.cancelled()) return false;
    wwork_[i] = kErased;
    --wentries_;
    const bool boundary = (st.wslot() & kWBoundary) != 0;
    st.set_wslot(kNoneW);
    --wlive_;
    erase(n);  // its translation entry: handle() queues n again
    ++stats_.rotation_events;
    handle(n, boundary, decide(camera_, state_[n].sphere, rates_), input, cut, r);
  }
  wwork_.clear();
  return true;
}

// The events an advance by (dm, dw) would handle: the sizes of the lists it
// would take (advance() takes the current slot's and every one the clock
// passes), the rotation lists' counted at the share of their entries that
// are live. Reads only the lists' sizes: at most 2,049 and 4,097.
double EventQueueStrategy::due_events(double dm, double dw) const {
  double due = 0.0;
  if (dm > 0.0) {
    const std::uint64_t last = mbase_ + static_cast<std::uint64_t>(mfrac_ + dm * kMPerUnit);
    std::size_t n = 0;
    for (std::uint64_t s = mbase_; s <= last; ++s) n += slots_[s & kMMask].size();
    due += double(n);
  }
  if (dw > 0.0 && wentries_ > 0) {
    const std::uint64_t last = wbase_ + static_cast<std::uint64_t>(wfrac_ + dw * kWPerUnit);
    std::size_t n = 0;
    for (std::uint64_t s = wbase_; s <= last; ++s) n += wslots_[s & kWMask].size();
    due += kRotationWeight * double(n) * double(wlive_) / double(wentries_);
  }
  return due;
}

// While the events run, a node with the time t on a clock that advances x
// an iteration is due about every t / x iterations (its next time is about
// as far as this one, the node being about as far from its change): the
// events an iteration is the sum of x / t over the nodes (at most 1 each; a
// slot's list is handled whenever the clock moves within the slot, so x is
// the motion plus a slot), estimated from the sampled times. (The share of
// times below x alone, the events of the first iteration after a rebuild,
// was a quarter of what the following iterations then handled on the fast
// test paths, and the strategy came back to the events too early.)
double EventQueueStrategy::predicted_from_samples(double dm, double dw) const {
  if (samples_.empty()) return 0.0;
  const double m = dm > 0.0 ? dm + 1.0 / kMPerUnit : 0.0;
  const double w = dw > 0.0 ? dw + 1.0 / kWPerUnit : 0.0;
  double due = 0.0;
  for (const EventTime& t : samples_) {
    const double rm = m <= 0.0 ? 0.0 : t.m > m ? m / t.m : 1.0;
    const double rw = w <= 0.0 ? 0.0 : t.w > w ? w / t.w : 1.0;  // 0 for t.w infinite
    due += std::min(kRotationWeight, rm + kRotationWeight * rw);
  }
  return due * pass_tests_ / double(samples_.size());
}

// The cheaper method for this iteration (docs/event-driven.md, "The cheaper
// method each iteration"). An event costs kappa top-down tests (kEventCost:
// it reads its node's record in random order, computes the next event time
// and edits the lists; a test of the pass reads in order) and brings
// tests_per_event_ tests (itself and the children of unfolds); a pass
// costs the tests of the queue's nodes (queued_: the active and boundary
// ones, what the pass visits), or of the last pass. Both are counts, so the
// choice is the same on every machine and in every test run. While the
// queue is valid the due events are counted exactly (due_events()): the
// events, unless they are predicted dearer than a pass twice in a row, or
// twice as dear once. A pass leaves the queue out of date and going back
// costs a rebuild (about four passes, docs/benchmarks.md): so while passes
// run, the rebuild comes after three moving iterations in a row whose events,
// predicted from the event times sampled in the last pass, cost half a pass
// or less (more after a return that did not last: calm_needed_).
EventQueueStrategy::Method EventQueueStrategy::choose(double dm, double dw) {
  const double kappa = param_at(kEventCost);
  if (valid_) {
    const double due = due_events(dm, dw);
    stats_.predicted = static_cast<std::size_t>(due);
    const double events = kappa * tests_per_event_ * due;
    const double pass = double(queued_);
    over_ = events > pass ? over_ + 1 : 0;
    if (events > 2.0 * pass || over_ >= 2) {
      // A sudden jump in the cost (a jump of the camera) says nothing of the
      // last return; a cost that crept over a pass soon after it, that it
      // came too early.
      const bool crept = events <= 2.0 * pass;
      calm_needed_ = !crept                    ? calm_needed_
                     : events_run_ < kShortRun ? std::min(64, 2 * calm_needed_)
                                               : 3;
      over_ = 0;
      calm_ = 0;
      return Method::kTopDown;
    }
    ++events_run_;
    return Method::kEvents;
  }
  const double due = predicted_from_samples(dm, dw);
  stats_.predicted = static_cast<std::size_t>(due);
  calm_ = kappa * tests_per_event_ * due <= 0.5 * pass_tests_ ? calm_ + 1 : 0;
  if (calm_ >= calm_needed_) {
    calm_ = 0;
    events_run_ = 0;
    return Method::kRebuild;
  }
  return Method::kTopDown;
}

// The translation unit a pace asks for (docs/event-driven.md, "Units that
// follow the eye"): `follow` times the eye's recent peak motion an
// iteration, rho at least. With the unit near the motion, an iteration
// advances the clock a few slots and the horizon (kMCap units) grows with
// the speed; with rho fixed a sweep at 6 rho an iteration ran at 0.46-0.49
// of topdown, at its own pace 0.38-0.40. The rotation clock keeps omega: a
// turn's unit at its pace was as often dearer as cheaper (0.58 and 0.62
// against 0.51 and 0.66 on the dragon's and the lion's middle turn).
double EventQueueStrategy::follow_unit(double rho) const {
  return std::max(rho, param_at(kFollow) * peak_);
}

// Each list of a slot o ahead of the clock holds events whose time is at
// least o - mfrac_ slots of the old unit away: at least (o - mfrac_) u / u'
// slots of the new one, rounded down (and at most the horizon). The clock's
// fraction starts again at 0. One read of each entry and one write of its
// record: about a pass's memory traffic, so only at a factor of 2.
void EventQueueStrategy::rescale(double unit) {
  const double ratio = unit_ / unit;
  slots_.swap(spare_);  // slots_ gets spare_'s empty lists
  constexpr std::uint64_t kHorizon = kMSlots / 2 - 1;
  for (std::uint64_t o = 0; o <= kHorizon; ++o) {
    std::vector<NodeId>& old = spare_[(mbase_ + o) & kMMask];
    if (old.empty()) continue;
    const double ahead = std::clamp((double(o) - mfrac_) * ratio, 0.0, double(kHorizon));
    const auto to =
        static_cast<std::uint16_t>((mbase_ + static_cast<std::uint64_t>(ahead)) & kMMask);
    std::vector<NodeId>& list = slots_[to];
    for (const NodeId entry : old) {
      NodeState& st = state_[entry & ~kBoundary];
      st.set_slot(to);
      st.index = static_cast<std::uint32_t>(list.size());
      list.push_back(entry);
    }
    old.clear();
  }
  mfrac_ = 0.0;
  pace_m_ *= ratio;
  unit_ = unit;
  stats_.rescaled = true;
}

// How far the camera moved (model units) and turned (units of omega) since
// last_camera_; the angle between unit vectors from their chord. A new lens
// counts as motion (criterion.cpp): its cone's half-angle as a turn, its
// zoom by e^z as a translation of z diameters.
EventQueueStrategy::Motion EventQueueStrategy::motion_since_last(double diameter) const {
  const double mx = camera_.ex - last_camera_.ex;
  const double my = camera_.ey - last_camera_.ey;
  const double mz = camera_.ez - last_camera_.ez;
  const double wx = camera_.ux - last_camera_.ux;
  const double wy = camera_.uy - last_camera_.uy;
  const double wz = camera_.uz - last_camera_.uz;
  Motion m;
  m.moved = std::sqrt(mx * mx + my * my + mz * mz);
  m.turned = 2.0 * std::asin(std::min(1.0, 0.5 * std::sqrt(wx * wx + wy * wy + wz * wz))) / omega_;
  if (camera_.pixel_scale != last_camera_.pixel_scale) {
    m.moved += std::abs(std::log(camera_.pixel_scale / last_camera_.pixel_scale)) * diameter;
  }
  if (camera_.beta != last_camera_.beta)
    m.turned += std::abs(camera_.beta - last_camera_.beta) / omega_;
  return m;
}

// The eye's pace: what it moved in two iterations in a row, the smaller (a
// single step, a short jump or a wheel notch, is not a pace), as a maximum
// that decays; a far jump does not count. A valid queue far from the unit
// that pace asks for is converted, at a factor of 2 (a pace that wavers
// does not convert it again and again).
void EventQueueStrategy::follow_pace(double moved, bool far, bool known, double rho) {
  if (!known || far) {
    if (!known) peak_ = 0.0;
    last_moved_ = 0.0;
    return;
  }
  peak_ = std::max(std::min(moved, last_moved_), peak_ * kPeakDecay);
  last_moved_ = moved;
  const double want = follow_unit(rho);
  if (valid_ && (want > 2.0 * unit_ || want < 0.5 * unit_)) rescale(want);
}

// The iteration's method (issue 31: the cheaper of the due events and a
// pass), from what the camera did since the queue's camera.
EventQueueStrategy::Method EventQueueStrategy::pick(bool known, bool far, double dm, double dw,
                                                    bool adaptive) {
  if (!camera_.perspective) return Method::kTopDown;  // no distance, no event times
  if (!known)
    return Method::kRebuild;  // the first iteration, new parameters, a cut changed, a cancel
  if (far) return adaptive ? Method::kTopDown : Method::kRebuild;
  if (dm == 0.0 && dw == 0.0) return Method::kNone;  // the same camera: the same cut
  return adaptive ? choose(dm, dw) : Method::kEvents;
}

// Carries the method out; false when cancelled.
bool EventQueueStrategy::carry_out(Method method, const IterationInput& input, TreeCut& cut,
                                   IterationResult& r, double dm, double dw) {
  switch (method) {
    case Method::kNone:
      return true;
    case Method::kRebuild:
      rebuild(input, cut, r);
      stats_.frames_advanced = 1;
      return valid_;
    case Method::kTopDown: {
      const bool done = camera_.perspective ? pass(input, cut, r)
                                            : detail::topdown_pass(input.hierarchy, cut, r, input,
                                                                   camera_, wanted_);
      valid_ = false;
      pass_tests_ = double(r.visited);
      return done;
    }
    case Method::kEvents: {
      const bool done = advance(input, cut, r, dm, dw);
      // The cancelled cut is valid (every change was one refine or coarsen);
      // the events are not complete any more: the next iteration rebuilds.
      valid_ = done;
      const double due = double(stats_.predicted);
      if (done && due > 0.0) {
        tests_per_event_ += (std::max(1.0, double(r.visited) / due) - tests_per_event_) * 0.25;
      }
      stats_.frames_advanced = static_cast<std::uint64_t>(std::ceil(std::max(dm, dw)));
      stats_.moved = dm;
      stats_.turned = dw;
      return done;
    }
  }
  return true;
}

void EventQueueStrategy::follow_residency(const IterationInput& input, TreeCut& cut,
                                          IterationResult& r) {
  const HierarchyArrays& a = input.hierarchy.arrays();
  // With a queue that holds every active and boundary node's event for the
  // last camera, the changes are taken in as events would take them: a
  // rebuild at every arriving page cost event_queue's 99th percentile 2.9
  // times the model held whole (paging_bench). Otherwise the next
  // iteration rebuilds (current_ false).
  const bool keep = current_ && valid_;
  // A record made again leaves the queue. Only a boundary node's position
  // is sure to be its entry's (a rebuild clears the lists and resets the
  // positions of the nodes it visits only): it is erased; any other's is
  // forgotten (a stale one would make a later fold erase another node's
  // entry).
  // A node that lost its children is a cut node (a boundary node no more:
  // its unfold event goes; it is hidden now) or lies below the cut; the
  // records below it are given back (none is queued: the cut lies above
  // them). One below another given back in the same iteration is gone
  // already.
  for (const NodeId n : input.concealed) {
    if (state_[n].made == 0) continue;
    const bool in_cut = cut.contains(n);
    if (keep && in_cut) {
      erase(n);
      drop_rotation(n);
    }
    runs_.assign(1, NodeRange{state_[n].first_child, state_[n].child_count});
    give_back_records();
    make_record(a, n);
    if (in_cut) hidden_.push_back(n);
  }
  // A node that gained its children, and those below it, made: none queued.
  // (A hidden node's record has no children: one that has them now was
  // made by a revealed ancestor's walk; one not made lies below a node
  // concealed above.)
  for (const NodeId n : input.revealed) {
    if (state_[n].made == 0 || state_[n].child_count != 0) continue;
    make_record(a, n);
    runs_.assign(1, children_of(a, n));
    make_records(a);
  }
  std::vector<NodeId>& below = level_;  // (scratch: no pass runs meanwhile)
  if (!keep) {
    current_ = false;
    return;
  }
  // A revealed cut node is a boundary node now: tested under the last
  // camera, as the rebuild would have (an unfold descends at once), and
  // the hidden nodes its unfold reaches are tested by want_hidden().
  for (const NodeId n : input.revealed) {
    if (!cut.contains(n)) continue;  // the cut lies above it
    handle(n, true, event_time::decide(camera_, state_[n].sphere, rates_), input, cut, r);
    below.assign(1, n);
    while (!below.empty()) {
      const NodeId m = below.back();
      below.pop_back();
      if (cut.contains(m)) {
        if (input.hierarchy.is_hidden(m)) hidden_.push_back(m);
        continue;
      }
      for (NodeId c = a.first_child[m]; c < a.first_child[m] + a.child_count[m]; ++c)
        below.push_back(c);
    }
  }
  last_cut_size_ = cut.size();
}

// Events only visit nodes with children: a paged model's hidden cut leaves
// the last pass met are tested again here for what the iteration wants.
void EventQueueStrategy::want_hidden(const Hierarchy& h, const TreeCut& cut) {
  if (!wanted_) return;
  const auto& cr = h.arrays().center_radius;
  // (Those no longer hidden cut nodes go: the list stays the cut's hidden
  // leaves, whatever arrives between passes.)
  std::erase_if(hidden_, [&](NodeId n) { return !cut.contains(n) || !h.is_hidden(n); });
  for (const NodeId n : hidden_)
    if (unfold_test(camera_, cr[n])) wanted_->push_back(n);
}

void EventQueueStrategy::iterate(const IterationInput& input, IterationOutput& output) {
  const Hierarchy& h = input.hierarchy;
  TreeCut& cut = *output.cut;
  IterationResult& r = output.result;
  wanted_ = output.wanted;
  if (!records_ || node_count_ != h.node_count() || spheres_ != h.arrays().center_radius.data())
    reset(h);
  if (!input.revealed.empty() || !input.concealed.empty()) follow_residency(input, cut, r);
  stats_ = {};
  camera_ = CriterionConstants::from_view(input.view, param_at(kTheta));
  const double diameter = 2.0 * double(h.radius(h.root()));
  const double rho = param_at(kRho) * diameter;
  omega_ = param_at(kOmega);

  // The cut is topdown's for the last camera, under the same parameters and
  // projection kind: what the camera did since decides what is needed.
  const bool known = current_ && input.params_version == last_params_ &&
                     cut.size() == last_cut_size_ && camera_.perspective &&
                     last_camera_.perspective && camera_.theta == last_camera_.theta;
  if (known && input.view.version == last_version_) {
    r.converged = r.refined == 0 && r.coarsened == 0;  // nothing due: O(1) (pages may have come)
    stats_.queued = queued_;
    stats_.rotation_queued = wlive_;
    want_hidden(h, cut);
    return;
  }
  const Motion motion = known ? motion_since_last(diameter) : Motion{};
  const double moved = motion.moved, dw = motion.turned;
  if (unit_ == 0.0) unit_ = rho;
  // A far jump (or NaN): the events would all be due. Judged in the queue's
  // unit for the pace (a jump is not a pace), then in the unit follow_pace()
  // leaves for the method (converted down, a fast step may be one).
  const auto beyond = [&](double unit) { return !(moved / unit < kMCap && dw < kWCap); };
  follow_pace(moved, beyond(unit_), known, rho);
  const double dm = moved / unit_;
  const bool far = beyond(unit_);
  const Method method = pick(known, far, dm, dw, param_at(kAdaptive) != 0.0);
  if (method == Method::kEvents && (dm > 0.0 || dw > 0.0)) {
    pace_m_ += (dm - pace_m_) * 0.125;
    pace_w_ += (dw - pace_w_) * 0.125;
  }
  // Without a queue left valid the unit is free: the pace's (a pass's
  // sampled times are then in the unit the next choice measures in).
  if (method == Method::kRebuild || method == Method::kTopDown) {
    const double want = follow_unit(rho);
    pace_m_ *= unit_ / want;
    unit_ = want;
  }
  rates_ =
      EventRates(camera_, unit_, omega_, kMCap, kWCap, pace_w_ / std::max(pace_m_, 1e-9), diameter);
  stats_.unit = unit_ / diameter;
  stats_.method = method;
  const bool done = carry_out(method, input, cut, r, dm, dw);
  if (method == Method::kEvents) want_hidden(h, cut);
  current_ = done && camera_.perspective;
  r.cancelled = !done;
  if (valid_ && wentries_ > 3 * wlive_ + 65536) compact_rotation_lists();
  last_camera_ = camera_;
  last_version_ = input.view.version;
  last_params_ = input.params_version;
  last_cut_size_ = cut.size();
  stats_.queued = queued_;
  stats_.rotation_queued = wlive_;
  r.converged = !r.cancelled;
  if (++iterations_ % kTrimEvery == 0) trim_lists();
  r.counters.set("event_queue_records_mib", double(made_ * sizeof(NodeState)) / (1 << 20), "MiB");
  r.counters.set("event_queue_lists_mib", double(list_bytes_) / (1 << 20), "MiB");
}

// A list keeps the storage of its busiest moment, and the clocks carry the
// busy moments from slot to slot: along a flight over the 20 M terrain the
// lists' storage grew to 77 MiB for 0.3-3 MiB of queued events. A list past
// four times what it holds (and kTrimFloor entries) gives its storage back,
// its entries in the same places (their records keep their indices). Every
// kTrimEvery iterations: a trim of the 16,384 lists took 104-303 us on
// that flight (its iterations 1.4-17 ms).
void EventQueueStrategy::trim_lists() {
  std::size_t entries = 0;
  const auto trim = [&](std::vector<NodeId>& list) {
    if (list.capacity() > kTrimFloor && list.capacity() > 4 * list.size()) {
      std::vector<NodeId> smaller(list.begin(), list.end());
      list.swap(smaller);
    }
    entries += list.capacity();
  };
  for (std::vector<NodeId>& list : slots_) trim(list);
  for (std::vector<NodeId>& list : wslots_) trim(list);
  for (std::vector<NodeId>& list : spare_) trim(list);
  list_bytes_ = entries * sizeof(NodeId);
}

}  // namespace treecut::strategies
