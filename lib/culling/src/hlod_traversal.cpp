// HOQ-coherent HLOD refinement, in-frame: J. P. Charalambos, J. Bittner,
// M. Wimmer, E. Romero, "Optimized HLOD Refinement Driven by Hardware
// Occlusion Queries", ISVC 2007 (../shared/papers/hoq-driven-hlod-refinement.txt,
// figure 2: the traversal; figure 3: hoq::predict_refinement), with the
// paper's scenarios Bool, SW(B), Simp(B) and Coh(B) as modes of one loop.
#include "treecut/culling/hlod_traversal.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <glm/geometric.hpp>
#include <glm/vec4.hpp>

namespace treecut::culling {

std::string_view hlod_mode_name(HlodMode mode) {
  switch (mode) {
    case HlodMode::Bool:
      return "Bool";
    case HlodMode::SwB:
      return "SW(B)";
    case HlodMode::SimpB:
      return "Simp(B)";
    case HlodMode::CohB:
      return "Coh(B)";
  }
  return "?";
}

namespace {

struct P2 {
  double x, y;
};

double cross(P2 o, P2 a, P2 b) {
  return (a.x - o.x) * (b.y - o.y) - (a.y - o.y) * (b.x - o.x);
}

// Sutherland-Hodgman against one axis-aligned edge: keep the points with
// sign * (coord - bound) >= 0.
std::vector<P2> clip(const std::vector<P2>& in, bool use_x, double bound, double sign) {
  std::vector<P2> out;
  const std::size_t n = in.size();
  for (std::size_t i = 0; i < n; ++i) {
    const P2 a = in[i], b = in[(i + 1) % n];
    const double da = sign * ((use_x ? a.x : a.y) - bound);
    const double db = sign * ((use_x ? b.x : b.y) - bound);
    if (da >= 0) out.push_back(a);
    if ((da >= 0) != (db >= 0)) {
      const double f = da / (da - db);
      out.push_back({a.x + f * (b.x - a.x), a.y + f * (b.y - a.y)});
    }
  }
  return out;
}

bool heap_less(const auto& a, const auto& b) {
  return a.distance > b.distance || (a.distance == b.distance && a.block > b.block);
}

}  // namespace

double box_projected_pixels(const ViewSnapshot& view, const Box& box) {
  const glm::mat4& view_projection = view.derived.view_projection;
  const glm::ivec2 viewport = view.viewport;
  std::vector<P2> pts;
  for (int c = 0; c < 8; ++c) {
    const glm::vec4 p((c & 1) ? box.hi.x : box.lo.x, (c & 2) ? box.hi.y : box.lo.y,
                      (c & 4) ? box.hi.z : box.lo.z, 1.0f);
    const glm::vec4 q = view_projection * p;
    if (!(q.w > 1e-6f)) return -1.0;
    pts.push_back({(double(q.x) / q.w + 1.0) * 0.5 * viewport.x,
                   (double(q.y) / q.w + 1.0) * 0.5 * viewport.y});
  }
  // Monotone chain: the silhouette of a convex box is the hull of its corners
  // (with back faces culled and depth clamped, what the proxy rasterizes).
  std::sort(pts.begin(), pts.end(),
            [](P2 a, P2 b) { return a.x < b.x || (a.x == b.x && a.y < b.y); });
  std::vector<P2> hull(2 * pts.size());
  std::size_t k = 0;
  for (const P2& p : pts) {
    while (k >= 2 && cross(hull[k - 2], hull[k - 1], p) <= 0) --k;
    hull[k++] = p;
  }
  for (std::size_t i = pts.size() - 1, lower = k + 1; i-- > 0;) {
    while (k >= lower && cross(hull[k - 2], hull[k - 1], pts[i]) <= 0) --k;
    hull[k++] = pts[i];
  }
  hull.resize(k > 1 ? k - 1 : k);
  hull = clip(hull, true, 0.0, 1.0);
  hull = clip(hull, true, double(viewport.x), -1.0);
  hull = clip(hull, false, 0.0, 1.0);
  hull = clip(hull, false, double(viewport.y), -1.0);
  double area = 0.0;
  for (std::size_t i = 0; i < hull.size(); ++i) {
    const P2 a = hull[i], b = hull[(i + 1) % hull.size()];
    area += a.x * b.y - b.x * a.y;
  }
  return 0.5 * std::abs(area);
}

HlodTraversal::HlodTraversal(const Hierarchy& hierarchy, const HlodBlocks& blocks,
                             HlodOptions options)
    : hierarchy_(&hierarchy), blocks_(&blocks), options_(options) {
  const auto& a = hierarchy.arrays();
  error_radius_.assign(blocks.block_count(), 0.0f);
  for (BlockId b = 0; b < blocks.block_count(); ++b) {
    // As HoqStrategy: a leaf block is full detail, no error left to refine.
    if (blocks.is_leaf(b)) continue;
    float r = 0.0f;
    for (const NodeId n : blocks.representation(b)) r = std::max(r, a.center_radius[n].w);
    error_radius_[b] = r;
  }
  reset();
}

void HlodTraversal::reset() {
  const std::size_t n = blocks_->block_count();
  frame_ = 0;
  last_visited_.assign(n, 0);
  visible_.assign(n, 0);
  stop_.assign(n, 0);
  outside_.assign(n, 0);
  bias_.assign(n, 1.0f);
  drawn_frame_.assign(n, 0);
  answer_frame_.assign(n, 0);
  drawn_.clear();
  for (Pending& c : carried_) c.frame = 0;  // names state that is gone: read, ignored
}

float HlodTraversal::sse(BlockId b) const {
  return hoq::block_sse(*view_, blocks_->box(b), error_radius_[b]);
}

void HlodTraversal::push(BlockId b) {
  heap_.push_back({hoq::distance_to_box(view_->derived.eye, blocks_->box(b)), b});
  std::push_heap(heap_.begin(), heap_.end(),
                 [](const Entry& x, const Entry& y) { return heap_less(x, y); });
}

void HlodTraversal::push_children(BlockId b) {
  stop_[b] = 0;
  const BlockId first = blocks_->first_child(b);
  for (unsigned i = 0; i < blocks_->child_count(b); ++i) push(first + i);
}

void HlodTraversal::draw(BlockId b) {
  stop_[b] = 1;
  if (drawn_frame_[b] == frame_) return;
  drawn_frame_[b] = frame_;
  device_->draw_render_thread(b);
  drawn_.push_back(b);
}

// Every block visited this frame starts invisible; a visible answer (or a
// block the eye is at) marks it and its ancestors up to the first already
// visible, so a refined block is visible when one of its children is.
void HlodTraversal::pull_up(BlockId b) {
  for (; b != kNoBlock && visible_[b] == 0; b = blocks_->parent(b)) visible_[b] = 1;
}

void HlodTraversal::query(BlockId b, Kind kind, float block_sse, Why why) {
  const double pixels =
      options_.mode == HlodMode::Bool ? 0.0 : box_projected_pixels(*view_, blocks_->box(b));
  pending_.push_back({b, device_->query_box_render_thread(b), kind, block_sse, why, pixels, frame_});
  ++stats_.queries;
}

// The answer's bias (Bool: the answer only as visible or not), for the
// camera the query was issued with.
void HlodTraversal::take_bias(const Pending& p, std::uint64_t samples) {
  answer_frame_[p.block] = p.frame;
  if (options_.mode == HlodMode::Bool) {
    bias_[p.block] = samples > 0 ? 1.0f : 0.0f;
    return;
  }
  const float mu = hoq::relative_visibility(
      static_cast<std::uint32_t>(std::min<std::uint64_t>(samples, 0xffffffffu)), p.pixels);
  bias_[p.block] = hoq::sigmoid_bias(mu, options_.s, options_.t);
}

void HlodTraversal::answer(const Pending& p, std::uint64_t samples) {
  const BlockId b = p.block;
  const bool visible = samples > 0;
  take_bias(p, samples);
  if (visible) pull_up(b);
  const bool leaf = blocks_->is_leaf(b);
  const bool stops = leaf || hoq::vmsse(bias_[b], p.sse) <= options_.tau;
  switch (p.kind) {
    case Kind::Delayed:
      // The decision waited for this answer: cull, stop and draw, or refine.
      if (!visible) {
        stop_[b] = 1;
        ++stats_.culled;
      } else if (stops) {
        draw(b);
        if (options_.mode == HlodMode::CohB) {
          ++stats_.delayed_drawn;
          stats_.delayed_drawn_shift_up += p.why == Why::ShiftUp ? 1 : 0;
          stats_.delayed_drawn_new += p.why == Why::New ? 1 : 0;
          stats_.delayed_drawn_hidden += p.why == Why::Hidden ? 1 : 0;
        }
      } else {
        push_children(b);
      }
      break;
    case Kind::Drawn:
      // Drawn when predicted to stop; a visible answer that says refine
      // makes it a RARN: its children are drawn over it in this frame.
      if (visible && !stops) {
        ++stats_.rarn;
        push_children(b);
      }
      if (!visible) ++stats_.stopped_hidden;
      break;
    case Kind::Refined:
      break;  // its children are traversed already; the answer keeps its bias current
  }
}

// Coh(B): the paper's PredictRefinement (figure 3) from last frame's state,
// and its action: Refine, Stop (query and draw) or Delay (query, wait).
[[gnu::always_inline]] inline void HlodTraversal::visit_coh_b(BlockId b, float block_sse,
                                                              bool visited_last, bool was_visible,
                                                              bool was_stopped, bool was_outside) {
  if (options_.assume_new_visible && (!visited_last || was_outside)) {
    // New: no answer of last frame to go by; as if visible, with the bias
    // of its last answer (1, unmodulated, if it never had one).
    if (blocks_->is_leaf(b) || hoq::vmsse(bias_[b], block_sse) <= options_.tau) {
      query(b, Kind::Drawn, block_sse);
      draw(b);
    } else {
      push_children(b);
    }
    return;
  }
  children_.clear();
  if (visited_last && !was_stopped && !blocks_->is_leaf(b)) {
    const BlockId first = blocks_->first_child(b);
    for (BlockId c = first; c < first + blocks_->child_count(b); ++c) {
      children_.push_back({stop_[c] != 0, bias_[c], sse(c)});
    }
  }
  const hoq::NodeState ns{visited_last, was_visible, was_stopped, bias_[b]};
  switch (hoq::predict_refinement(ns, block_sse, children_, options_.tau)) {
    case hoq::Prediction::Refine:
      push_children(b);
      return;
    case hoq::Prediction::Stop:
      query(b, Kind::Drawn, block_sse);
      draw(b);
      return;
    case hoq::Prediction::Delay: {
      ++stats_.delayed;
      const Why why = !visited_last || was_outside ? Why::New
                      : !was_visible               ? Why::Hidden
                                                   : Why::ShiftUp;
      if (why == Why::ShiftUp) ++stats_.delayed_shift_up;
      query(b, Kind::Delayed, block_sse, why);
      return;
    }
  }
}

void HlodTraversal::visit(const Entry& e) {
  const BlockId b = e.block;
  const std::uint64_t frame = frame_;
  const bool visited_last = last_visited_[b] != 0 && last_visited_[b] + 1 == frame;
  const bool was_visible = visited_last && visible_[b] != 0;
  const bool was_stopped = stop_[b] != 0;
  const bool was_outside = visited_last && outside_[b] != 0;
  last_visited_[b] = frame;
  visible_[b] = 0;
  outside_[b] = 0;
  if (!may_be_in_frustum(*view_, blocks_->box(b))) {
    outside_[b] = 1;
    // Nothing to query against: next frame it is invisible last frame (Delay).
    // Its bias stays its last answer's (figure 3 caches biases from answers
    // only). Setting it to 0 (no pixel on screen) for its parent's shift-up
    // test was measured: no change on the city walk at 10 fps (Coh(B) DN
    // 160.9 vs 161.0, 0 to 20 s), so the literal reading stays.
    ++stats_.frustum_culled;
    stop_[b] = 1;
    return;
  }
  const bool leaf = blocks_->is_leaf(b);
  const float block_sse = sse(b);
  const float tau = options_.tau;
  if (e.distance <= view_->derived.near_radius) {
    // The eye is at the box: its proxy would be clipped. Visible, mu = 1.
    bias_[b] = 1.0f;
    pull_up(b);
    if (leaf || block_sse <= tau) {
      draw(b);
    } else {
      push_children(b);
    }
    return;
  }
  switch (options_.mode) {
    case HlodMode::SwB:
      query(b, Kind::Delayed, block_sse);
      return;
    case HlodMode::Bool: {
      const bool terminal = leaf || block_sse <= tau;
      if (was_visible && !was_stopped && !terminal) {
        push_children(b);  // an opened block: no query, its children decide
      } else if (was_visible) {
        // Last frame's visible termination block: traversed at once, its
        // answer not waited for.
        query(b, terminal ? Kind::Drawn : Kind::Refined, block_sse);
        if (terminal) {
          draw(b);
        } else {
          push_children(b);
        }
      } else {
        query(b, Kind::Delayed, block_sse);
      }
      return;
    }
    case HlodMode::SimpB: {
      if (!was_visible) {
        query(b, Kind::Delayed, block_sse);
      } else if (leaf || hoq::vmsse(bias_[b], block_sse) <= tau) {
        query(b, Kind::Drawn, block_sse);
        draw(b);
      } else {
        query(b, Kind::Refined, block_sse);
        push_children(b);
      }
      return;
    }
    case HlodMode::CohB:
      visit_coh_b(b, block_sse, visited_last, was_visible, was_stopped, was_outside);
      return;
  }
}

HlodTraversal::Entry HlodTraversal::pop_nearest() {
  std::pop_heap(heap_.begin(), heap_.end(),
                [](const Entry& x, const Entry& y) { return heap_less(x, y); });
  const Entry e = heap_.back();
  heap_.pop_back();
  return e;
}

// The query queue in issue order, as far as the answers are there (or read
// ahead by the drain); with `wait_for_each`, the next one even if it is not
// (waiting), stopping once the traversal queue has work again, except in
// SwB, which reads them all.
void HlodTraversal::read_available(bool wait_for_each) {
  while (pending_head_ < pending_.size()) {
    Pending& p = pending_[pending_head_];
    if (!p.read) {
      if (!wait_for_each && !device_->result_available_render_thread(p.query)) break;
      p.samples = device_->result_render_thread(p.query);
      p.read = true;
    }
    ++pending_head_;
    answer(p, p.samples);
    if (wait_for_each && options_.mode != HlodMode::SwB && !heap_.empty()) break;
  }
}

// carry_answers, the traversal queue empty: the answers no decision of this
// frame needs and that are not there go to a later frame (a drawn block
// stays visible until its answer); of those a decision needs (Delay), the
// newest is waited for, after which the older ones are there. False when
// nothing is left to wait for.
bool HlodTraversal::carry_or_drain() {
  std::size_t keep = pending_head_;
  std::size_t newest_needed = pending_.size();
  for (std::size_t i = pending_head_; i < pending_.size(); ++i) {
    Pending& p = pending_[i];
    const bool needed = p.kind == Kind::Delayed;
    if (needed || p.read || device_->result_available_render_thread(p.query)) {
      if (needed && !p.read) newest_needed = keep;
      pending_[keep++] = p;
      continue;
    }
    if (p.kind == Kind::Drawn) pull_up(p.block);  // visible until its answer says otherwise
    carried_.push_back(p);
  }
  pending_.resize(keep);
  if (newest_needed < pending_.size()) {
    Pending& p = pending_[newest_needed];
    p.samples = device_->result_render_thread(p.query);
    p.read = true;
    ++stats_.drains;
  }
  return pending_head_ < pending_.size();
}

// Earlier frames' answers that are there, in issue order: their bias and
// visibility for this frame's predictions (an answer older than the one
// taken is ignored). A drawn block whose answer says refine refines now, by
// figure 3's prediction (stopped, VMSSE > tau): a late RARN.
void HlodTraversal::take_carried_answers() {
  std::size_t keep = 0;
  bool waiting = false;
  for (const Pending& c : carried_) {
    if (waiting || !device_->result_available_render_thread(c.query)) {
      waiting = true;
      carried_[keep++] = c;
      continue;
    }
    const std::uint64_t samples = device_->result_render_thread(c.query);
    if (c.frame == 0 || c.frame < answer_frame_[c.block]) continue;
    ++stats_.carried_answers;
    take_bias(c, samples);
    const bool visible = samples > 0;
    if (!visible) visible_[c.block] = 0;
    if (c.kind != Kind::Drawn) continue;
    const bool stops = blocks_->is_leaf(c.block) || hoq::vmsse(bias_[c.block], c.sse) <= options_.tau;
    if (visible && !stops) ++stats_.late_refined;
    if (!visible) ++stats_.stopped_hidden;
  }
  carried_.resize(keep);
}

void HlodTraversal::release_render_thread(OcclusionDeviceRenderThread& device) {
  for (const Pending& c : carried_) (void)device.result_render_thread(c.query);
  carried_.clear();
}

HlodFrameStats HlodTraversal::frame_render_thread(OcclusionDeviceRenderThread& device,
                                                  const ViewSnapshot& view, bool finish) {
  const auto start = std::chrono::steady_clock::now();
  ++frame_;
  device_ = &device;
  view_ = &view;
  stats_ = {};
  heap_.clear();
  pending_.clear();
  pending_head_ = 0;
  drawn_.clear();
  device.begin_frame_render_thread();
  const bool carry = options_.carry_answers && options_.mode != HlodMode::SwB;
  if (carry) take_carried_answers();
  push(0);
  while (true) {
    read_available(options_.mode == HlodMode::SwB);  // SwB waits for every answer
    if (!heap_.empty()) {
      visit(pop_nearest());
    } else if (pending_head_ == pending_.size()) {
      break;
    } else if (!carry) {
      read_available(true);  // nothing else to do: wait (the paper's form)
    } else if (!carry_or_drain()) {
      break;
    }
  }
  stats_.carried_pending = carried_.size();
  device.end_frame_render_thread(finish);
  const DeviceFrameStats& d = device.frame_stats();
  stats_.drawn = drawn_.size();
  stats_.splats = d.splats_drawn;
  stats_.blocking_reads = d.blocking_reads;
  stats_.wait_ms = d.wait_ms;
  device_ = nullptr;
  view_ = nullptr;
  stats_.frame_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  return stats_;
}

}  // namespace treecut::culling
