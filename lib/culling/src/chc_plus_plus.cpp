// CHC for a GPU's latency, after O. Mattausch, J. Bittner, M. Wimmer,
// "CHC++: Coherent Hierarchical Culling Revisited", Eurographics 2008 (not in
// ../shared/papers: what follows is our reading of its published ideas, on
// top of CHC, ../shared/papers/coherent-hierarchical-culling.tex.txt):
//   - No wait while other work exists. Answers are polled; a read that may
//     block happens only when the traversal queue and the i-queue are empty,
//     and then once: the newest answer needed is read (waited for), after
//     which the older ones are there (a GPU answers in issue order). One
//     "drain" per round, not one blocking read per query as CHC on an H200
//     (337 a frame, issue 16).
//   - The i-queue: queries of previously invisible nodes are not issued one
//     by one between draws (each a switch of GPU state) but in batches of
//     ChcOptions::batch_size, or when the traversal runs dry. A batch issued
//     later is tested against more of the frame's depth.
//   - The v-queue: a previously visible leaf is drawn at once (it is the
//     likely occluder), and its query is issued at the end of the frame,
//     against the complete depth, and its answer read in a later frame when
//     it is there (carried). The answer only tells the next frames whether
//     to keep drawing the leaf, so nothing waits for it. Until it arrives the
//     leaf stays visible (drawn, no second query).
//   - Optionally no wait at all (ChcOptions::wait_for_invisible false): the
//     answers a frame would drain for are carried too, their nodes culled
//     until an answer says visible (a delayed block: disoccluded geometry
//     appears a frame or two late).
//   - Randomized assumed visibility: a leaf found visible is not queried
//     again for 1 to t_av frames, drawn per node and answer, so the queries
//     of a region that became visible together spread over frames.
// Multiqueries and tighter bounds of CHC++ are not done (issue 28).
#include <algorithm>

#include "treecut/culling/chc.hpp"
#include "treecut/mix64.hpp"

namespace treecut::culling {

bool ChcTraversal::assumed_visible(BlockId b) const {
  const std::uint32_t t_av = options_.assume_visible_frames;
  if (t_av == 0 || visible_query_[b] == 0) return false;
  const std::uint64_t span = 1 + mix64((std::uint64_t(b) << 32) ^ visible_query_[b]) % t_av;
  return frame_ - visible_query_[b] <= span;
}

// Answers of earlier frames' queries (the v-queue's), in issue order, as far
// as they are there: an invisible answer makes its leaf a previously
// invisible one for this frame (queried, not drawn, unless a newer answer
// found it visible).
void ChcTraversal::take_carried_answers(OcclusionDeviceRenderThread& device,
                                        ChcFrameStats& stats) {
  std::size_t keep = 0;
  bool waiting = false;  // the first one not there: the later ones are not either
  for (const Carried& c : carried_) {
    if (waiting || !device.result_available_render_thread(c.query)) {
      waiting = true;
      carried_[keep++] = c;
      continue;
    }
    const std::uint64_t samples = device.result_render_thread(c.query);
    if (c.frame == 0) continue;  // issued before a reset
    ++stats.carried_answers;
    if (c.hidden) {
      // A previously invisible node culled while its answer was on its way:
      // visible now, it is drawn (opened) from this frame on.
      if (answer_visible(samples) && c.frame >= visible_query_[c.block]) {
        visible_query_[c.block] = c.frame;
        if (last_visited_[c.block] + 1 == frame_) {
          pull_up(c.block);
          ++stats.delayed_blocks;
        }
      }
      continue;
    }
    in_flight_[c.block] = 0;
    if (answer_visible(samples)) {
      visible_query_[c.block] = std::max(visible_query_[c.block], c.frame);
    } else if (c.frame > visible_query_[c.block]) {
      visible_[c.block] = 0;
    }
  }
  carried_.resize(keep);
}

void ChcTraversal::issue_invisible_batch(OcclusionDeviceRenderThread& device,
                                         ChcFrameStats& stats) {
  for (const BlockId b : i_queue_) pending_.push_back({b, device.query_box_render_thread(b), false});
  stats.queries += i_queue_.size();
  ++stats.batches;
  i_queue_.clear();
}

// The answers this frame needs (the i-queue's), in issue order: those that
// are there; with `drain`, all of them, waiting once, for the newest.
void ChcTraversal::read_needed_answers(const ViewSnapshot& view,
                                       OcclusionDeviceRenderThread& device, bool drain,
                                       ChcFrameStats& stats) {
  if (drain && pending_head_ < pending_.size() && !pending_.back().read) {
    Pending& newest = pending_.back();
    newest.samples = device.result_render_thread(newest.query);
    newest.read = true;
    ++stats.drains;
  }
  while (pending_head_ < pending_.size()) {
    Pending& p = pending_[pending_head_];
    if (!p.read) {
      if (!drain && !device.result_available_render_thread(p.query)) break;
      p.samples = device.result_render_thread(p.query);
      p.read = true;
    }
    ++pending_head_;
    apply_answer(p, p.samples, view, device);
  }
}

void ChcTraversal::visit_chc_plus_plus(const Entry& e, const ViewSnapshot& view,
                                       OcclusionDeviceRenderThread& device,
                                       ChcFrameStats& stats) {
  const BlockId b = e.block;
  if (!may_be_in_frustum(view, blocks_->box(b))) {
    ++stats.frustum_culled;
    return;
  }
  const bool leaf = blocks_->is_leaf(b);
  if (leaf) classified_.push_back(b);
  // Not waiting, a node new to the traversal (no classification of the last
  // few frames to go by) is taken as visible: culled until its answer, a
  // subtree would open one level per round trip. One classified lately (not
  // visited last frame because its parent was culled) keeps that class, or
  // a parent found visible by its box would redraw its hidden children.
  constexpr std::uint64_t kRecentFrames = 8;
  const bool visited_last = last_visited_[b] != 0 && last_visited_[b] + 1 == frame_;
  const bool recent = last_visited_[b] != 0 && frame_ - last_visited_[b] <= kRecentFrames;
  bool was_visible = false;
  if (visited_last) {
    was_visible = visible_[b] != 0;
  } else if (!options_.wait_for_invisible) {
    was_visible = recent ? visible_[b] != 0 : true;
  }
  visible_[b] = 0;
  last_visited_[b] = frame_;
  const bool near = e.distance <= view.derived.near_radius;
  if (near || was_visible) {
    // An opened node (its children decide), a box at the eye, or a
    // previously visible leaf: drawn now and visible until an answer says
    // otherwise; its query (if due) waits for the end of the frame.
    if (near || leaf) pull_up(b);
    traverse(b, view, device);
    if (leaf && !near && in_flight_[b] == 0 && !assumed_visible(b)) v_queue_.push_back(b);
    return;
  }
  i_queue_.push_back(b);
  if (i_queue_.size() >= std::max<std::uint32_t>(options_.batch_size, 1)) {
    issue_invisible_batch(device, stats);
  }
}

void ChcTraversal::traverse_chc_plus_plus(const ViewSnapshot& view,
                                          OcclusionDeviceRenderThread& device,
                                          ChcFrameStats& stats) {
  i_queue_.clear();
  v_queue_.clear();
  take_carried_answers(device, stats);
  const std::uint32_t interval = std::max<std::uint32_t>(options_.poll_interval, 1);
  std::uint32_t since_poll = interval;
  push(0, view);
  while (true) {
    if (since_poll >= interval) {
      const std::size_t before = pending_head_;
      read_needed_answers(view, device, false, stats);
      if (pending_head_ == before && pending_head_ < pending_.size()) since_poll = 0;
    }
    if (!heap_.empty()) {
      ++since_poll;
      visit_chc_plus_plus(pop_nearest(), view, device, stats);
    } else if (!i_queue_.empty()) {
      issue_invisible_batch(device, stats);
      since_poll = interval;
    } else if (pending_head_ < pending_.size() && options_.wait_for_invisible) {
      read_needed_answers(view, device, true, stats);
      since_poll = interval;
    } else if (pending_head_ < pending_.size()) {
      // No wait: what is not there goes to a later frame, its node culled.
      for (; pending_head_ < pending_.size(); ++pending_head_) {
        const Pending& p = pending_[pending_head_];
        carried_.push_back({p.block, p.query, frame_, true});
      }
    } else {
      break;
    }
  }
  // The v-queue, against the frame's complete depth; read in later frames.
  for (const BlockId b : v_queue_) {
    carried_.push_back({b, device.query_box_render_thread(b), frame_});
    in_flight_[b] = 1;
  }
  stats.queries += v_queue_.size();
  stats.carried_pending = carried_.size();
}

void ChcTraversal::release_render_thread(OcclusionDeviceRenderThread& device) {
  for (const Carried& c : carried_) {
    (void)device.result_render_thread(c.query);
    if (c.block < in_flight_.size()) in_flight_[c.block] = 0;
  }
  carried_.clear();
}

}  // namespace treecut::culling
