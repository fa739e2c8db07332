// Coherent hierarchical culling: J. Bittner, M. Wimmer, H. Piringer,
// W. Purgathofer, "Coherent Hierarchical Culling: Hardware Occlusion Queries
// Made Useful", Eurographics 2004
// (../shared/papers/coherent-hierarchical-culling.tex.txt, figure "Pseudo-code
// of coherent hierarchical culling"), over HLOD blocks, with the paper's
// baselines (VFC, stop-and-wait, Ideal) in the same loop.
#include "treecut/culling/chc.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <glm/geometric.hpp>
#include <glm/vec4.hpp>

namespace treecut::culling {

std::string_view occlusion_mode_name(OcclusionMode mode) {
  switch (mode) {
    case OcclusionMode::Vfc:
      return "vfc";
    case OcclusionMode::StopAndWait:
      return "sw";
    case OcclusionMode::Chc:
      return "chc";
    case OcclusionMode::Ideal:
      return "ideal";
    case OcclusionMode::ChcPlusPlus:
      return "chc++";
  }
  return "?";
}

namespace {

// std heaps are max-heaps: the nearest block must compare greatest.
constexpr auto heap_less = [](const auto& a, const auto& b) {
  return a.distance > b.distance || (a.distance == b.distance && a.block > b.block);
};

}  // namespace

ChcTraversal::ChcTraversal(const HlodBlocks& blocks, ChcOptions options)
    : blocks_(&blocks), options_(options) {
  reset();
}

void ChcTraversal::reset() {
  const std::size_t n = blocks_->block_count();
  frame_ = 0;
  visible_.assign(n, 0);
  last_visited_.assign(n, 0);
  visible_query_.assign(n, 0);
  drawn_frame_.assign(n, 0);
  in_flight_.assign(n, 0);
  drawn_.clear();
  classified_.clear();
  // Queries still in flight name blocks whose state is gone: their answers
  // are read (the handles go back to the device) and ignored.
  for (Carried& c : carried_) c.frame = 0;
}

void ChcTraversal::set_ideal_leaves(std::span<const BlockId> leaves) {
  ideal_.assign(blocks_->block_count(), 0);
  for (const BlockId leaf : leaves) {
    if (leaf >= blocks_->block_count() || !blocks_->is_leaf(leaf)) continue;
    // Mark the leaf and its ancestors: the oracle's "visible" for every block.
    for (BlockId b = leaf; b != kNoBlock && ideal_[b] == 0; b = blocks_->parent(b)) ideal_[b] = 1;
  }
}

bool ChcTraversal::answer_visible(std::uint64_t samples) const {
  return samples > 0 && samples >= options_.min_visible_samples;
}

void ChcTraversal::push(BlockId b, const ViewSnapshot& view) {
  wait_at_push_ = device_->frame_stats().wait_ms;
  heap_.push_back({blocks_->box(b).distance_to(view.derived.eye), b});
  std::push_heap(heap_.begin(), heap_.end(), heap_less);
}

ChcTraversal::Entry ChcTraversal::pop_nearest() {
  std::pop_heap(heap_.begin(), heap_.end(), heap_less);
  const Entry e = heap_.back();
  heap_.pop_back();
  return e;
}

void ChcTraversal::draw(BlockId b, OcclusionDeviceRenderThread& device) {
  if (drawn_frame_[b] == frame_) return;  // a previously visible leaf, drawn when queried
  drawn_frame_[b] = frame_;
  device.draw_render_thread(b);
  drawn_.push_back(b);
}

// The paper's TraverseNode: a leaf is drawn, an interior block's children go
// to the traversal queue.
void ChcTraversal::traverse(BlockId b, const ViewSnapshot& view,
                            OcclusionDeviceRenderThread& device) {
  if (blocks_->is_leaf(b)) {
    draw(b, device);
    return;
  }
  const BlockId first = blocks_->first_child(b);
  for (unsigned i = 0; i < blocks_->child_count(b); ++i) push(first + i, view);
}

// The paper's PullUpVisibility: every block of this frame starts invisible,
// so a visible answer marks its ancestors up to the first already visible.
void ChcTraversal::pull_up(BlockId b) {
  for (; b != kNoBlock && visible_[b] == 0; b = blocks_->parent(b)) visible_[b] = 1;
}

ChcFrameStats ChcTraversal::frame_render_thread(OcclusionDeviceRenderThread& device,
                                                const ViewSnapshot& view, bool finish) {
  const auto start = std::chrono::steady_clock::now();
  ++frame_;
  heap_.clear();
  pending_.clear();
  pending_head_ = 0;
  drawn_.clear();
  classified_.clear();
  if (options_.mode == OcclusionMode::Ideal && ideal_.size() != blocks_->block_count()) {
    ideal_.assign(blocks_->block_count(), 0);
  }
  ChcFrameStats stats;
  const std::uint32_t interval = std::max<std::uint32_t>(options_.poll_interval, 1);
  std::uint32_t since_poll = interval;
  device.begin_frame_render_thread();
  device_ = &device;
  if (options_.mode == OcclusionMode::ChcPlusPlus) {
    traverse_chc_plus_plus(view, device, stats);
  } else {
    push(0, view);
    while (!heap_.empty() || pending_head_ < pending_.size()) {
      read_answers(view, device, interval, since_poll);
      // Part 2: the hierarchical traversal, front to back.
      if (heap_.empty()) continue;
      ++since_poll;
      visit(pop_nearest(), view, device, stats);
    }
  }
  device.end_frame_render_thread(finish);

  const DeviceFrameStats& d = device.frame_stats();
  stats.blocking_reads = d.blocking_reads;
  stats.wait_ms = d.wait_ms;
  stats.drain_wait_ms = d.wait_ms - wait_at_push_;
  device_ = nullptr;
  stats.blocks_drawn = drawn_.size();
  stats.splats_drawn = d.splats_drawn;
  for (const BlockId b : classified_) stats.leaves_visible += visible_[b];
  stats.frame_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  return stats;
}

// Part 1: answers. Stop-and-wait always waits; CHC reads an answer only when
// it is available, or when there is nothing else to do.
void ChcTraversal::read_answers(const ViewSnapshot& view, OcclusionDeviceRenderThread& device,
                                std::uint32_t interval, std::uint32_t& since_poll) {
  while (pending_head_ < pending_.size()) {
    bool read = options_.mode == OcclusionMode::StopAndWait || heap_.empty();
    if (!read && since_poll >= interval) {
      read = device.result_available_render_thread(pending_[pending_head_].query);
      if (!read) since_poll = 0;  // not there: the next poll after `interval` blocks
    }
    if (!read) break;
    const Pending p = pending_[pending_head_++];
    const std::uint64_t samples = device.result_render_thread(p.query);
    if (options_.mode == OcclusionMode::Ideal) continue;  // a probe: ignored
    apply_answer(p, samples, view, device);
  }
}

// An answer read in the frame it was issued in: a visible block is pulled up
// and opened (pull-down: a leaf drawn when queried is not redrawn).
void ChcTraversal::apply_answer(const Pending& p, std::uint64_t samples, const ViewSnapshot& view,
                                OcclusionDeviceRenderThread& device) {
  if (!answer_visible(samples)) return;
  pull_up(p.block);
  visible_query_[p.block] = frame_;
  traverse(p.block, view, device);
}

// One block taken from the traversal queue: culled, opened, queried or drawn
// as the mode says.
void ChcTraversal::visit(const Entry& e, const ViewSnapshot& view,
                         OcclusionDeviceRenderThread& device, ChcFrameStats& stats) {
  const BlockId b = e.block;
  if (!may_be_in_frustum(view, blocks_->box(b))) {
    ++stats.frustum_culled;
    return;
  }
  const std::uint64_t frame = frame_;
  const bool leaf = blocks_->is_leaf(b);
  if (leaf) classified_.push_back(b);
  const bool was_visible = visible_[b] != 0 && last_visited_[b] + 1 == frame;
  visible_[b] = 0;
  last_visited_[b] = frame;
  // A box the eye is in (or at the near plane) cannot be queried: its
  // proxy would be clipped. It is visible.
  const bool near = e.distance <= view.derived.near_radius;
  switch (options_.mode) {
    case OcclusionMode::Vfc:
      pull_up(b);
      traverse(b, view, device);
      break;
    case OcclusionMode::Ideal:
      if (ideal_[b] != 0) {
        if (leaf && options_.ideal_probe_queries) {
          pending_.push_back({b, device.query_box_render_thread(b), true});
          ++stats.queries;
        }
        pull_up(b);
        traverse(b, view, device);
      }
      break;
    case OcclusionMode::StopAndWait:
      if (near) {
        pull_up(b);
        traverse(b, view, device);
      } else {
        pending_.push_back({b, device.query_box_render_thread(b), false});
        ++stats.queries;
      }
      break;
    case OcclusionMode::ChcPlusPlus:
      break;  // visit_chc_plus_plus
    case OcclusionMode::Chc: {
      const bool opened = was_visible && !leaf;
      if (opened || near) {
        // An opened node: no query, its children decide (pull-up).
        if (near) pull_up(b);
        traverse(b, view, device);
      } else if (was_visible && options_.assume_visible_frames > 0 &&
                 frame - visible_query_[b] <= options_.assume_visible_frames) {
        // Conservative visibility testing: assumed visible, no query.
        pull_up(b);
        traverse(b, view, device);
      } else {
        pending_.push_back({b, device.query_box_render_thread(b), was_visible});
        ++stats.queries;
        if (was_visible) traverse(b, view, device);  // a previously visible leaf: draw at once
      }
      break;
    }
  }
}

std::vector<BlockId> ChcTraversal::visible_leaves() const {
  std::vector<BlockId> out;
  for (const BlockId b : classified_) {
    if (visible_[b] != 0) out.push_back(b);
  }
  return out;
}

bool ChcTraversal::visible(BlockId b) const {
  return b < visible_.size() && visible_[b] != 0 && last_visited_[b] == frame_;
}

}  // namespace treecut::culling
