// Event-driven refinement (Zach & Karner 2003, section 3, figure 7); see
// event_queue.hpp for what is queued and why, criterion.cpp for the event
// times.
#include "treecut/strategies/event_queue.hpp"

#include <sys/mman.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdlib>
#include <memory>
#include <new>

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
// Entries handled between two looks at the cancellation flag.
constexpr std::uint64_t kCancelEvery = 4096;

}  // namespace

namespace detail {

template <class T>
void HugeArray<T>::assign(std::size_t n, const T& value) {
  release();
  if (n == 0) return;
  // Whole huge pages, aligned to one, so that madvise covers all of it; the
  // pages are not touched before the advice (the first touch allocates).
  constexpr std::size_t kHuge = std::size_t{2} << 20;
  const std::size_t bytes = (n * sizeof(T) + kHuge - 1) / kHuge * kHuge;
  void* p = std::aligned_alloc(kHuge, bytes);
  if (p == nullptr) throw std::bad_alloc();
  ::madvise(p, bytes, MADV_HUGEPAGE);  // a hint: without it the array still works
  data_ = static_cast<T*>(p);
  size_ = n;
  bytes_ = bytes;
  std::uninitialized_fill_n(data_, n, value);
}

template <class T>
void HugeArray<T>::release() {
  std::free(data_);
  data_ = nullptr;
  size_ = bytes_ = 0;
}

template class HugeArray<EventQueueStrategy::NodeState>;

}  // namespace detail

EventQueueStrategy::EventQueueStrategy()
    : Strategy({
          {"theta", "pixels: a node unfolds when its projected radius reaches theta", 1.5, 0.05,
           1e6, false},
          {"rho", "maximal eye translation per frame, in diameters of the model", 0.002, 1e-7, 10.0,
           false},
          {"omega", "maximal rotation of the view direction per frame, radians", 0.02, 1e-6, 3.1416,
           false},
      }) {}

void EventQueueStrategy::reset(const Hierarchy& hierarchy) {
  state_.assign(hierarchy.node_count(), NodeState{});
  const HierarchyArrays& a = hierarchy.arrays();
  for (NodeId n = 0; n < hierarchy.node_count(); ++n) {
    NodeState& st = state_[n];
    st.sphere = a.center_radius[n];
    st.child_count = a.child_count[n];
    st.first_child = st.child_count != 0 ? a.first_child[n] : 0;
  }
  spheres_ = a.center_radius.data();
  slots_.assign(kMSlots, {});
  wslots_.assign(kWSlots, {});
  work_.clear();
  wwork_.clear();
  processing_ = kNone;
  mbase_ = wbase_ = 0;
  mfrac_ = wfrac_ = 0.0;
  queued_ = wlive_ = wentries_ = 0;
  pace_m_ = pace_w_ = 1.0;
  valid_ = false;
  stats_ = {};
}

void EventQueueStrategy::schedule(NodeId n, const EventTime& t, bool boundary) {
  NodeState& st = state_[n];
  // Translation: the list of the slot the clock is in after t.m units (t.m
  // <= kMCap, so at most kCapSlots ahead). That may be the current slot: its
  // list is handled again at the next advance of the clock, however small.
  const std::uint64_t ms = mbase_ + static_cast<std::uint64_t>(mfrac_ + t.m * kMPerUnit);
  const auto slot = static_cast<std::uint16_t>(ms & kMMask);
  std::vector<NodeId>& list = slots_[slot];
  st.index = static_cast<std::uint32_t>(list.size());
  st.slot = slot;
  list.push_back(boundary ? n | kBoundary : n);
  ++queued_;
  // Rotation: none when rotation alone cannot change the test.
  if (!(t.w <= kWCap)) {
    if (st.wslot != kNoneW) {
      st.wslot = kNoneW;
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
  if (st.wslot != kNoneW) {
    // The entry the node has is kept when it comes no later and is for the
    // same state: an earlier test is always correct.
    if ((st.wslot & kWBoundary) == flag &&
        ((std::uint64_t(st.wslot & kWMask) - wbase_) & kWMask) <= ahead) {
      return;
    }
  } else {
    ++wlive_;
  }
  const int drop = std::max(0, int(std::bit_width(ahead)) - 3);
  const std::uint64_t ws = wbase_ + ((ahead >> drop) << drop);
  st.wslot = static_cast<std::uint16_t>((ws & kWMask) | flag);
  wslots_[ws & kWMask].push_back(n);
  ++wentries_;
}

void EventQueueStrategy::erase(NodeId n) {
  NodeState& e = state_[n];
  if (e.slot == kNone) return;
  if (e.slot == processing_ && e.index < work_.size() && (work_[e.index] & ~kBoundary) == n) {
    // Still to come in the list being processed: marked, not moved, so the
    // reader's position stays right. (Entries already read are kErased, so
    // an equal id here is the node's current entry.)
    work_[e.index] = kErased;
  } else {
    std::vector<NodeId>& list = slots_[e.slot];
    const NodeId last = list.back();
    list[e.index] = last;
    state_[last & ~kBoundary].index = e.index;
    list.pop_back();
  }
  e.slot = kNone;
  --queued_;
}

void EventQueueStrategy::drop_rotation(NodeId n) {
  NodeState& e = state_[n];
  if (e.wslot == kNoneW) return;
  e.wslot = kNoneW;  // its entry is stale now
  --wlive_;
}

void EventQueueStrategy::clear_queue() {
  // Through the lists rather than the node array: O(events), not O(nodes).
  // The work lists too: a cancelled iteration leaves the rest of one there.
  auto clear = [&](std::vector<NodeId>& list) {
    for (const NodeId e : list) {
      if (e == kErased) continue;
      NodeState& st = state_[e & ~kBoundary];
      st.slot = kNone;
      st.wslot = kNoneW;
    }
    list.clear();
  };
  for (std::vector<NodeId>& list : slots_) clear(list);
  for (std::vector<NodeId>& list : wslots_) clear(list);
  clear(work_);
  clear(wwork_);
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
      const std::uint16_t w = state_[n].wslot;
      if (w != kNoneW && (w & kWMask) == s) list[out++] = n;
    }
    list.resize(out);
    kept += out;
  }
  wentries_ = kept;
}

// A jump: one top-down pass (figure 3, the code `topdown` runs) decides every
// active and boundary node under the current camera and schedules its next
// event. Each was just tested, so no event is due before the next slot.
void EventQueueStrategy::rebuild(const IterationInput& input, TreeCut& cut, IterationResult& r) {
  const Hierarchy& h = input.hierarchy;
  clear_queue();
  // The spheres from the node records (the same floats): schedule() writes
  // those records anyway.
  auto test = [&](NodeId n) { return unfold_test(camera_, state_[n].sphere); };
  auto decided = [&](NodeId n, bool active) {
    const glm::vec4 c = state_[n].sphere;
    schedule(n,
             active ? potential_fold_event(camera_, c, rates_)
                    : potential_unfold_event(camera_, c, rates_),
             !active);
  };
  auto drop = [&](NodeId n) {
    erase(n);
    drop_rotation(n);
  };
  detail::TopDown pass(h, cut, r, input, test, decided, drop);
  valid_ = pass.run(h.root());
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
// records instead of the hierarchy's arrays, which the records copy: the
// children's records are in cache already (run() prefetched them).
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
      // No state_[n].slot = kNone here: n is queued again either way.
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
    if (st.wslot == kNoneW || (st.wslot & kWMask) != slot) {
      wwork_[i] = kErased;
      --wentries_;
      continue;
    }
    if ((++r.visited % kCancelEvery) == 0 && input.cancelled()) return false;
    wwork_[i] = kErased;
    --wentries_;
    const bool boundary = (st.wslot & kWBoundary) != 0;
    st.wslot = kNoneW;
    --wlive_;
    erase(n);  // its translation entry: handle() queues n again
    ++stats_.rotation_events;
    handle(n, boundary, decide(camera_, state_[n].sphere, rates_), input, cut, r);
  }
  wwork_.clear();
  return true;
}

void EventQueueStrategy::iterate(const IterationInput& input, IterationOutput& output) {
  const Hierarchy& h = input.hierarchy;
  TreeCut& cut = *output.cut;
  IterationResult& r = output.result;
  if (state_.size() != h.node_count() || spheres_ != h.arrays().center_radius.data()) reset(h);
  stats_ = {};
  camera_ = CriterionConstants::from_view(input.view, param_at(kTheta));
  rho_ = param_at(kRho) * 2.0 * double(h.radius(h.root()));
  omega_ = param_at(kOmega);

  if (!camera_.perspective) {
    // No distance, no event times: the plain top-down pass.
    const auto& cr = h.arrays().center_radius;
    auto test = [&](NodeId n) { return unfold_test(camera_, input.view, cr[n]); };
    auto decided = [](NodeId, bool) {};
    auto drop = [](NodeId) {};
    detail::TopDown pass(h, cut, r, input, test, decided, drop);
    pass.run(h.root());
    valid_ = false;
    r.converged = !r.cancelled;
    return;
  }

  bool jump = !valid_ || input.params_version != last_params_ || !camera_.same_lens(last_camera_) ||
              cut.size() != last_cut_size_;
  if (!jump && input.view.version == last_version_) {
    r.converged = true;  // nothing due: O(1)
    stats_.queued = queued_;
    stats_.rotation_queued = wlive_;
    return;
  }
  double dm = 0.0, dw = 0.0;
  if (!jump) {
    // How far the camera moved and turned since the last iteration, in units
    // of rho and omega; the angle between unit vectors from their chord.
    const double mx = camera_.ex - last_camera_.ex;
    const double my = camera_.ey - last_camera_.ey;
    const double mz = camera_.ez - last_camera_.ez;
    const double wx = camera_.ux - last_camera_.ux;
    const double wy = camera_.uy - last_camera_.uy;
    const double wz = camera_.uz - last_camera_.uz;
    dm = std::sqrt(mx * mx + my * my + mz * mz) / rho_;
    dw = 2.0 * std::asin(std::min(1.0, 0.5 * std::sqrt(wx * wx + wy * wy + wz * wz))) / omega_;
    // Far jumps (and NaN) rebuild: the events would all be due anyway.
    if (!(dm < kMCap && dw < kWCap)) jump = true;
  }
  if (!jump && (dm > 0.0 || dw > 0.0)) {
    pace_m_ += (dm - pace_m_) * 0.125;
    pace_w_ += (dw - pace_w_) * 0.125;
  }
  rates_ = EventRates(camera_, rho_, omega_, kMCap, kWCap, pace_w_ / std::max(pace_m_, 1e-9));
  if (jump) {
    rebuild(input, cut, r);
    stats_.frames_advanced = 1;
  } else if (dm > 0.0 || dw > 0.0) {
    if (!advance(input, cut, r, dm, dw)) {
      // The cut is valid (every change was one refine or coarsen); the
      // events are not complete any more: the next iteration rebuilds.
      r.cancelled = true;
      valid_ = false;
    }
    stats_.frames_advanced = static_cast<std::uint64_t>(std::ceil(std::max(dm, dw)));
    stats_.moved = dm;
    stats_.turned = dw;
  }
  if (wentries_ > 3 * wlive_ + 65536) compact_rotation_lists();
  last_camera_ = camera_;
  last_version_ = input.view.version;
  last_params_ = input.params_version;
  last_cut_size_ = cut.size();
  stats_.queued = queued_;
  stats_.rotation_queued = wlive_;
  r.converged = !r.cancelled;
}

}  // namespace treecut::strategies
