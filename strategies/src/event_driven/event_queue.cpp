// Event-driven refinement (Zach & Karner 2003, section 3, figure 7); see
// event_queue.hpp for what is queued and why, criterion.cpp for the event
// times.
#include "treecut/strategies/event_queue.hpp"

#include <algorithm>
#include <cmath>

#include "top_down.hpp"

namespace treecut::strategies {
namespace {

constexpr std::uint32_t kMask = EventQueueStrategy::kSlots - 1;
// The farthest event: beyond it, slots not yet processed in a multi-frame
// advance would be reused (see advance()).
constexpr std::uint32_t kCap = EventQueueStrategy::kSlots / 2 - 1;
static_assert((EventQueueStrategy::kSlots & kMask) == 0, "kSlots is a power of two");

}  // namespace

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
  slots_.assign(kSlots, {});
  work_.clear();
  queued_ = 0;
  frame_ = 0;
  valid_ = false;
  stats_ = {};
}

void EventQueueStrategy::insert(NodeId n, std::uint32_t t, bool boundary) {
  const auto slot = static_cast<std::uint16_t>((frame_ + t) & kMask);
  std::vector<NodeId>& list = slots_[slot];
  state_[n] = {static_cast<std::uint32_t>(list.size()), slot};
  list.push_back(boundary ? n | kBoundary : n);
  ++queued_;
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

void EventQueueStrategy::clear_queue() {
  // Through the lists rather than the node array: O(events), not O(nodes).
  for (std::vector<NodeId>& list : slots_) {
    for (const NodeId n : list) state_[n & ~kBoundary].slot = kNone;
    list.clear();
  }
  queued_ = 0;
}

// A jump: one top-down pass (figure 3, the code `topdown` runs) decides every
// active and boundary node under the current camera and schedules its next
// event. Each was just tested, so no event is due before the next frame.
void EventQueueStrategy::rebuild(const IterationInput& input, TreeCut& cut, IterationResult& r) {
  const Hierarchy& h = input.hierarchy;
  const auto& cr = h.arrays().center_radius;
  clear_queue();
  ++frame_;
  const EventRates rates(camera_, rho_, omega_, kCap);
  auto test = [&](NodeId n) { return unfold_test(camera_, cr[n]); };
  auto decided = [&](NodeId n, bool active) {
    const std::uint32_t t = active ? potential_fold_time(camera_, cr[n], rates)
                                   : potential_unfold_time(camera_, cr[n], rates);
    insert(n, std::max<std::uint32_t>(1, t), !active);
  };
  auto drop = [&](NodeId n) { erase(n); };
  detail::TopDown pass(h, cut, r, input, test, decided, drop);
  valid_ = pass.run(h.root());
  stats_.rebuilt = true;
}

// Figure 7 for every frame from the last one up to the current: the nodes
// whose events are due are tested against the current camera (the only one
// there is; the events were computed so that nothing else can have changed).
// Insertions are relative to the current frame, at most kCap ahead, so they
// never land in a slot of this advance that is still to be processed
// (steps + kCap < kSlots); t = 0 lands in the current frame's slot, which is
// processed last, until no insertion is left in it.
void EventQueueStrategy::advance(const IterationInput& input, TreeCut& cut, IterationResult& r,
                                 std::uint64_t steps) {
  const std::uint64_t from = frame_ + 1;
  frame_ += steps;
  for (std::uint64_t f = from; f <= frame_; ++f) {
    const auto slot = static_cast<std::uint32_t>(f & kMask);
    do {
      if (!process(slot, input, cut, r)) {
        // The cut is valid (every change was one refine or coarsen); the
        // events are not complete any more: the next iteration rebuilds.
        r.cancelled = true;
        valid_ = false;
        return;
      }
    } while (f == frame_ && !slots_[slot].empty());
  }
}

bool EventQueueStrategy::process(std::uint32_t slot, const IterationInput& input, TreeCut& cut,
                                 IterationResult& r) {
  constexpr std::size_t kAhead = 16;  // entries prefetched ahead, enough to cover a DRAM miss
  const Hierarchy& h = input.hierarchy;
  const HierarchyArrays& a = h.arrays();
  // Take the list out of its slot (the slot gets work_'s empty buffer), so a
  // fold that erases an entry still to come marks it instead of moving it.
  work_.swap(slots_[slot]);
  processing_ = static_cast<std::uint16_t>(slot);
  auto drop = [&](NodeId n) { erase(n); };
  const EventRates rates(camera_, rho_, omega_, kCap);
  const std::size_t count = work_.size();
  for (std::size_t i = 0; i < count; ++i) {
    if (i + kAhead < count && work_[i + kAhead] != kErased) {
      __builtin_prefetch(&a.center_radius[work_[i + kAhead] & ~kBoundary]);
      __builtin_prefetch(&state_[work_[i + kAhead] & ~kBoundary], 1);
    }
    const NodeId entry = work_[i];
    if (entry == kErased) continue;
    work_[i] = kErased;
    --queued_;
    const NodeId n = entry & ~kBoundary;
    const bool boundary = (entry & kBoundary) != 0;
    if ((++r.visited & 4095) == 0 && input.cancelled()) {
      for (std::size_t j = i + 1; j < count; ++j) {
        if (work_[j] != kErased) state_[work_[j] & ~kBoundary].slot = kNone;
      }
      state_[n].slot = kNone;
      work_.clear();
      processing_ = kNone;
      return false;
    }
    // No state_[n].slot = kNone here: every branch below queues n again.
    const glm::vec4 c = a.center_radius[n];
    const bool pass = unfold_test(camera_, c);
    if (boundary) {
      if (!pass) {
        insert(n, std::max<std::uint32_t>(1, potential_unfold_time(camera_, c, rates)), true);
        continue;
      }
      // Unfold: the node is active now (its fold event), and its non-leaf
      // children become boundary nodes with their own unfold events, maybe
      // due in this very frame.
      cut.refine(h, n);
      ++r.refined;
      insert(n, std::max<std::uint32_t>(1, potential_fold_time(camera_, c, rates)), false);
      const NodeId first = a.first_child[n];
      const NodeId end = first + a.child_count[n];
      for (NodeId ch = first; ch < end; ++ch) {
        if (a.child_count[ch] == 0) continue;
        insert(ch, potential_unfold_time(camera_, a.center_radius[ch], rates), true);
      }
    } else if (pass) {
      insert(n, std::max<std::uint32_t>(1, potential_fold_time(camera_, c, rates)), false);
    } else {
      // Fold: the subtree collapses into n and its events go; n becomes a
      // boundary node waiting to unfold.
      detail::fold_subtree(h, cut, n, r, drop);
      insert(n, std::max<std::uint32_t>(1, potential_unfold_time(camera_, c, rates)), true);
    }
  }
  work_.clear();
  processing_ = kNone;
  return true;
}

void EventQueueStrategy::iterate(const IterationInput& input, IterationOutput& output) {
  const Hierarchy& h = input.hierarchy;
  TreeCut& cut = *output.cut;
  IterationResult& r = output.result;
  if (state_.size() != h.node_count()) reset(h);
  stats_ = {};
  camera_ = CriterionCamera::from_view(input.view, param_at(kTheta));
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
    return;
  }
  double steps = 0.0;
  if (!jump) {
    // How many frames of rho and omega the camera's change since the last
    // iteration takes; the angle between unit vectors from their chord.
    const double mx = camera_.ex - last_camera_.ex;
    const double my = camera_.ey - last_camera_.ey;
    const double mz = camera_.ez - last_camera_.ez;
    const double wx = camera_.ux - last_camera_.ux;
    const double wy = camera_.uy - last_camera_.uy;
    const double wz = camera_.uz - last_camera_.uz;
    const double moved = std::sqrt(mx * mx + my * my + mz * mz);
    const double turned =
        2.0 * std::asin(std::min(1.0, 0.5 * std::sqrt(wx * wx + wy * wy + wz * wz)));
    steps = std::max(std::ceil(moved / rho_), std::ceil(turned / omega_));
    // Far jumps (and NaN) rebuild: the events would all be due anyway.
    if (!(steps < double(kSlots / 2))) jump = true;
  }
  if (jump) {
    rebuild(input, cut, r);
    stats_.frames_advanced = 1;
  } else if (steps > 0.0) {
    advance(input, cut, r, static_cast<std::uint64_t>(steps));
    stats_.frames_advanced = static_cast<std::uint64_t>(steps);
  }
  last_camera_ = camera_;
  last_version_ = input.view.version;
  last_params_ = input.params_version;
  last_cut_size_ = cut.size();
  stats_.queued = queued_;
  r.converged = !r.cancelled;
}

}  // namespace treecut::strategies
