// HOQ-coherent HLOD refinement: J. P. Charalambos, J. Bittner, M. Wimmer,
// E. Romero, "Optimized HLOD Refinement Driven by Hardware Occlusion
// Queries", ISVC 2007 (../shared/papers/hoq-driven-hlod-refinement.txt):
// the pure functions of section 3.2 and figure 3, and the `hoq` strategy,
// the Feedback Stage form of the paper's traversal (hoq.hpp; how the
// asynchronous answers map onto delay and RARN: docs/occlusion.md, "## HOQ").
#include "treecut/strategies/hoq.hpp"

#include <algorithm>
#include <cmath>
#include <glm/geometric.hpp>
#include <glm/vec4.hpp>

#include "treecut/query_proxy.hpp"

namespace treecut::strategies {

namespace hoq {

float sigmoid_bias(float mu, float s, float t) {
  mu = std::clamp(mu, 0.0f, 1.0f);
  s = std::clamp(s, 0.0f, 1.0f);
  t = std::clamp(t, 0.0f, 1.0f);
  float sig = 0.0f;
  if (mu <= t) {
    sig = t > 0.0f ? mu * mu / t : 0.0f;
  } else {
    const float u = 1.0f - mu;
    sig = 1.0f - u * u / (1.0f - t);  // t < mu <= 1, so 1 - t > 0
  }
  // mu = 1 gives exactly 1 whatever the rounding of the mix.
  if (mu >= 1.0f) return 1.0f;
  return (1.0f - s) * mu + s * sig;
}

float distance_to_box(glm::vec3 eye, const Box& box) {
  return box.distance_to(eye);
}

float block_sse(const ViewSnapshot& view, const Box& box, float error_radius) {
  if (error_radius <= 0.0f) return 0.0f;
  if (!view.derived.perspective) return error_radius * view.derived.pixel_scale;
  constexpr float kMinDistance = 1e-6f;  // as projected_radius_px: the eye inside is "huge"
  const float dist = std::max(distance_to_box(view.derived.eye, box), kMinDistance);
  return error_radius * view.derived.pixel_scale / dist;
}

double proxy_pixels(const QueryCamera& camera, glm::vec3 center, float radius) {
  // The rectangle the executor rasterizes (treecut/query_proxy.hpp); not
  // wholly in front of the eye: the executor's quad path or host answer.
  if (!is_perspective_frustum(camera.projection)) return -1.0;
  const float w = float(camera.viewport.x), h = float(camera.viewport.y);
  SphereWindowRect rect;
  if (!sphere_window_rect(camera.view, camera.projection, glm::vec2(w, h),
                          glm::vec4(center, radius), rect)) {
    return -1.0;
  }
  const float x0 = rect.x0, x1 = rect.x1, y0 = rect.y0, y1 = rect.y1;
  const float cx0 = std::max(x0, 0.0f), cx1 = std::min(x1, w);
  const float cy0 = std::max(y0, 0.0f), cy1 = std::min(y1, h);
  if (cx0 >= cx1 || cy0 >= cy1) return 0.0;
  // The sprite: the square of the clipped rectangle's longer side, centred
  // on it, and what of it lies in the viewport.
  const double side = std::max(cx1 - cx0, cy1 - cy0);
  const double mx = 0.5 * (double(cx0) + cx1), my = 0.5 * (double(cy0) + cy1);
  const double sw = std::min(mx + 0.5 * side, double(w)) - std::max(mx - 0.5 * side, 0.0);
  const double sh = std::min(my + 0.5 * side, double(h)) - std::max(my - 0.5 * side, 0.0);
  return std::max(sw, 0.0) * std::max(sh, 0.0);
}

float relative_visibility(std::uint32_t samples_passed, double projected_pixels) {
  if (samples_passed == 0) return 0.0f;
  if (!(projected_pixels > 0.0)) return 1.0f;
  return static_cast<float>(std::min(1.0, double(samples_passed) / projected_pixels));
}

float average_bias(std::span<const ChildState> children) {
  if (children.empty()) return 1.0f;
  float sum = 0.0f;
  for (const ChildState& c : children) sum += c.bias;
  return sum / float(children.size());
}

Prediction predict_refinement(const NodeState& node, float sse,
                              std::span<const ChildState> children, float tau) {
  if (!node.visited_last_frame || !node.visible) return Prediction::Delay;
  if (!node.stop_refinement) {
    bool candidate_to_shift_up = true;
    for (const ChildState& child : children) {
      if (!child.stop_refinement || !(vmsse(child.bias, child.sse) <= tau)) {
        candidate_to_shift_up = false;
      }
    }
    if (candidate_to_shift_up) {
      if (vmsse(average_bias(children), sse) <= tau) return Prediction::Delay;
    }
  } else if (vmsse(node.bias, sse) <= tau) {
    return Prediction::Stop;
  }
  return Prediction::Refine;
}

}  // namespace hoq

void HoqCounters::add(const HoqCounters& o) {
  blocks += o.blocks;
  drawn += o.drawn;
  culled += o.culled;
  delayed += o.delayed;
  delayed_shift_up += o.delayed_shift_up;
  rarn += o.rarn;
  rarn_frames += o.rarn_frames;
  late_refined += o.late_refined;
  late_frames += o.late_frames;
  refined += o.refined;
  coarsened += o.coarsened;
  queries += o.queries;
  answers += o.answers;
  answer_age_frames += o.answer_age_frames;
  answer_gpu_frames += o.answer_gpu_frames;
}

HoqStrategy::HoqStrategy()
    : Strategy({
          {"theta", "tau, pixels of error: a block stops refining when its VMSSE is <= theta", 1.0,
           0.0, 1e6, false},
          {"s", "smoothness of the bias B_{s,t}(mu): 0 = mu, 1 = the full sigmoid", 0.5, 0.0, 1.0,
           false},
          {"t", "turn-over of the bias: the closer to 0, the weaker the modulation", 0.5, 0.0, 1.0,
           false},
          {"block_size", "leaves per HLOD leaf block (the unit of one occlusion query)",
           double(kDefaultBlockSize), 1.0, 1e8, true},
          {"assume_visible",
           "1: a block new in the traversal is refined by its SSE alone (as if visible) until its "
           "first answer; 0: it keeps its level until then",
           1.0, 0.0, 1.0, true},
          {"bias",
           "1: VMSSE = B_{s,t}(mu) * SSE; 0: Bool, SSE alone with the answers as visible or not "
           "(the paper's image reference)",
           1.0, 0.0, 1.0, true},
      }) {}

void HoqStrategy::build_blocks(const Hierarchy& h) {
  built_block_size_ = static_cast<std::uint32_t>(param_at(kBlockSize));
  blocks_ = HlodBlocks::build(h, built_block_size_);
  hierarchy_ = &h;
  const auto& a = h.arrays();
  const BlockId n = blocks_.block_count();
  error_radius_.assign(n, 0.0f);
  for (BlockId b = 0; b < n; ++b) {
    // A leaf block draws its leaves: full detail, no error left to refine.
    if (blocks_.is_leaf(b)) continue;
    float r = 0.0f;
    for (const NodeId node : blocks_.representation(b)) r = std::max(r, a.center_radius[node].w);
    error_radius_[b] = r;
  }
  state_.assign(n, BlockState{});
  cut_.clear();
  previous_cut_.clear();
  iteration_ = 0;
  settled_ = 0;
  camera_count_ = 0;
  last_ = {};
  totals_ = {};
}

void HoqStrategy::reset(const Hierarchy& hierarchy) {
  build_blocks(hierarchy);
}

const hoq::QueryCamera* HoqStrategy::camera_of(std::uint64_t frame) const {
  const FrameCamera* best = nullptr;
  for (std::size_t i = 0; i < std::min(camera_count_, kCameras); ++i) {
    const FrameCamera& c = cameras_[i];
    if (c.frame <= frame && (best == nullptr || c.frame > best->frame)) best = &c;
  }
  return best != nullptr ? &best->camera : nullptr;
}

void HoqStrategy::take_answers(const IterationInput& input) {
  const ViewSnapshot& view = input.view;
  const auto& a = input.hierarchy.arrays();
  const hoq::QueryCamera current{view.view, view.projection, view.viewport};
  const float s = static_cast<float>(param_at(kS));
  const float t = static_cast<float>(param_at(kT));
  for (const VisibilityResult& r : view.visibility) {
    // Only answers to this strategy's requests about these blocks (a list
    // asked before a reset or a block-size change names other blocks).
    if (r.object != input.object || r.tag >= blocks_.block_count() ||
        blocks_.root(r.tag) != r.node) {
      continue;
    }
    ++last_.answers;
    last_.answer_age_frames += frame_ >= r.frame_issued ? frame_ - r.frame_issued : 0;
    last_.answer_gpu_frames += r.frame_read >= r.frame_issued ? r.frame_read - r.frame_issued : 0;
    BlockState& st = state_[r.tag];
    if (r.frame_issued < st.answer_frame) continue;  // an older answer than the one taken
    const hoq::QueryCamera* cam = camera_of(r.frame_issued);
    const glm::vec4 sphere = a.center_radius[r.node];
    const double pixels =
        hoq::proxy_pixels(cam != nullptr ? *cam : current, glm::vec3(sphere), sphere.w);
    const float mu = hoq::relative_visibility(r.samples_passed, pixels);
    // Bool (the paper's image reference): the answer only as visible or not.
    st.bias = param_at(kBias) != 0.0 ? hoq::sigmoid_bias(mu, s, t) : (mu > 0.0f ? 1.0f : 0.0f);
    st.visible = r.samples_passed > 0;
    st.answer_frame = r.frame_issued;
  }
}

void HoqStrategy::terminal(BlockId b, bool known_invisible) {
  state_[b].stop = true;
  state_[b].culled = known_invisible;
  cut_.push_back(b);
  ++last_.blocks;
  if (known_invisible) {
    ++last_.culled;
  } else {
    ++last_.drawn;
  }
}

void HoqStrategy::query(BlockId b, const IterationInput& input, IterationOutput& output) {
  // The proxy: the bounding sphere of the block's root node, which contains
  // every node of the block's subtree, drawn by the executor at the sphere's
  // nearest depth (a point sprite over its window rectangle).
  output.queries->push_back({input.object, blocks_.root(b), b, QueryKind::Samples});
  ++last_.queries;
}

void HoqStrategy::children_states(BlockId b, const ViewSnapshot& view) {
  children_.clear();
  const BlockId first = blocks_.first_child(b);
  for (BlockId c = first; c < first + blocks_.child_count(b); ++c) {
    const BlockState& cs = state_[c];
    children_.push_back({cs.stop, cs.bias, hoq::block_sse(view, blocks_.box(c), error_radius_[c])});
  }
}

void HoqStrategy::visit(BlockId b, const IterationInput& input, IterationOutput& output) {
  const ViewSnapshot& view = input.view;
  const float tau = static_cast<float>(param_at(kTheta));
  BlockState& s = state_[b];
  // A block the frustum culled has no occlusion answer to go by: back in
  // view it is new to the traversal, as the paper's not-visited node.
  const bool was_visited = s.visited != 0 && s.visited + 1 == iteration_ && !s.outside;
  const bool was_refined = was_visited && !s.stop;
  const bool was_terminal = was_visited && s.stop;
  if (!was_visited) {
    // Entering the traversal (or back after a while): nothing cached holds
    // for this frame. Assume visible, unmodulated, until its answer.
    s.bias = 1.0f;
    s.stop_bias = 1.0f;
    s.visible = true;
    s.stop = true;
    s.delay = Delay::None;
  }
  s.visited = iteration_;
  ++output.result.visited;

  auto refine = [&] {
    if (!was_refined) ++last_.refined;
    s.stop = false;
    const BlockId first = blocks_.first_child(b);
    bool any = false;
    for (BlockId c = first; c < first + blocks_.child_count(b); ++c) {
      visit(c, input, output);
      any = any || state_[c].visible;
    }
    // Pulled up: a refined block is visible when one of its children is.
    state_[b].visible = any;
  };
  const glm::vec4 sphere = input.hierarchy.arrays().center_radius[blocks_.root(b)];
  if (view.outside_frustum(glm::vec3(sphere), sphere.w)) {
    // Culled without a query, at the highest block found outside: its
    // subtree draws nothing the camera sees, so it is as coarse as it can be.
    if (was_refined) ++last_.coarsened;
    s.visible = false;
    s.bias = 0.0f;
    s.delay = Delay::None;
    s.outside = true;
    terminal(b, true);
    return;
  }
  s.outside = false;
  if (blocks_.is_leaf(b)) {
    // Full detail: the refinement stops here whatever the answer; the query
    // still gives its parent the bias the shift-up test reads.
    s.delay = Delay::None;
    s.stop_bias = s.bias;
    terminal(b, !s.visible);
    query(b, input, output);
    return;
  }
  const float sse = hoq::block_sse(view, blocks_.box(b), error_radius_[b]);

  if (s.delay != Delay::None) {
    if (s.answer_frame > s.delay_after) {
      // The answer the decision waited for (the paper's query queue): cull
      // an invisible block, stop where VMSSE <= tau, else refine.
      const Delay kind = s.delay;
      s.delay = Delay::None;
      const bool stop_here = !s.visible || hoq::vmsse(s.bias, sse) <= tau;
      if (stop_here) {
        if (kind == Delay::ShiftUp) ++last_.coarsened;
        s.stop_bias = s.bias;
        terminal(b, !s.visible);
        query(b, input, output);
        return;
      }
      if (kind != Delay::ShiftUp) {
        // Kept at its level while it waited: drawn too coarse since it
        // entered, or since the answer that found it visible was issued.
        ++last_.late_refined;
        last_.late_frames +=
            frame_ + 1 - (kind == Delay::Front ? s.delay_frame : std::min(s.answer_frame, frame_));
      }
      refine();
      return;
    }
    if (s.delay == Delay::ShiftUp) {
      // Still waiting; a child that now needs refinement ends the candidacy.
      children_states(b, view);
      const hoq::NodeState ns{true, true, false, s.bias};
      if (hoq::predict_refinement(ns, sse, children_, tau) == hoq::Prediction::Refine) {
        s.delay = Delay::None;
      } else {
        ++last_.delayed;
        ++last_.delayed_shift_up;
        query(b, input, output);
      }
      refine();
      return;
    }
    // A delayed termination block keeps its state (its level) until its answer.
    if (s.visible) ++last_.delayed;
    terminal(b, !s.visible);
    query(b, input, output);
    return;
  }

  hoq::NodeState ns{was_visited, s.visible, was_terminal, s.bias};
  if (was_refined) children_states(b, view);
  const hoq::Prediction p =
      hoq::predict_refinement(ns, sse,
                              was_refined ? std::span<const hoq::ChildState>(children_)
                                          : std::span<const hoq::ChildState>(),
                              tau);
  switch (p) {
    case hoq::Prediction::Stop:
      s.stop_bias = s.bias;
      terminal(b, false);
      query(b, input, output);
      return;
    case hoq::Prediction::Refine:
      if (was_terminal && s.culled) {
        // Culled (hidden) at its last visit, visible in the newer answer and
        // needing refinement: a disocclusion, drawn too coarse since that
        // answer was issued (the same as a Hidden delay resolved to refine).
        ++last_.late_refined;
        last_.late_frames += frame_ + 1 - std::min(s.answer_frame, frame_);
      } else if (was_terminal && hoq::vmsse(s.stop_bias, sse) <= tau) {
        // Drawn (Stop) and refined because a newer answer raised the bias
        // (the old one would still stop): the paper's RARN, drawn too coarse
        // from the frame the answer was issued in to the frame its
        // refinement can be drawn.
        ++last_.rarn;
        last_.rarn_frames += frame_ + 1 - std::min(s.answer_frame, frame_);
      }
      refine();
      return;
    case hoq::Prediction::Delay:
      s.delay_frame = frame_;
      if (was_refined) {
        // A candidate to shift up: its children stay drawn while its own
        // answer is on its way.
        s.delay = Delay::ShiftUp;
        s.delay_after = frame_;
        ++last_.delayed;
        ++last_.delayed_shift_up;
        query(b, input, output);
        refine();
        return;
      }
      if (!was_visited) {
        // New in the traversal: any answer issued from now on will do. With
        // assume_visible it is drawn as if visible and unmodulated (bias 1,
        // VMSSE = SSE: never too coarse) while it waits, so a block whose
        // SSE exceeds tau is refined now instead of a round trip per level.
        if (param_at(kAssumeVisible) != 0.0 && sse > tau) {
          refine();
          return;
        }
        s.delay = Delay::Front;
        s.delay_after = frame_;
        ++last_.delayed;
        terminal(b, false);
        query(b, input, output);
        return;
      }
      // Invisible last frame: the next answer will do; culled until then.
      s.delay = Delay::Hidden;
      s.delay_after = s.answer_frame;
      terminal(b, true);
      query(b, input, output);
      return;
  }
}

void HoqStrategy::iterate(const IterationInput& input, IterationOutput& output) {
  const Hierarchy& h = input.hierarchy;
  if (hierarchy_ != &h || blocks_.hierarchy_nodes() != h.node_count() ||
      built_block_size_ != static_cast<std::uint32_t>(param_at(kBlockSize))) {
    build_blocks(h);
  }
  IterationResult& r = output.result;
  if (input.cancelled()) {
    // Nothing decided yet: the last block cut (or the root block) stays.
    blocks_.append_nodes(cut_.empty() ? std::span<const BlockId>(blocks_.root_block_cut())
                                      : std::span<const BlockId>(cut_),
                         *output.nodes);
    r.cancelled = true;
    return;
  }
  ++iteration_;
  frame_ = input.view.frame;
  FrameCamera& slot = cameras_[camera_count_ % kCameras];
  slot = {frame_, {input.view.view, input.view.projection, input.view.viewport}};
  ++camera_count_;

  last_ = {};
  take_answers(input);
  previous_cut_.swap(cut_);
  cut_.clear();
  visit(0, input, output);
  blocks_.append_nodes(cut_, *output.nodes);

  r.refined = last_.refined;
  r.coarsened = last_.coarsened;
  r.culled = last_.culled;
  r.blocked = last_.delayed;
  const bool same_view =
      input.view.version == last_version_ && input.params_version == last_params_;
  last_version_ = input.view.version;
  last_params_ = input.params_version;
  settled_ = same_view && cut_ == previous_cut_ ? settled_ + 1 : 0;
  // Answers to the current list take a few frames: the cut is final once it
  // held for longer than that under the same view. Answers that arrive later
  // still run an iteration (the stage asks for one while visibility results
  // are pending), so a delayed block is decided even after convergence.
  constexpr std::uint32_t kSettle = 4;
  r.converged = settled_ >= kSettle;
  totals_.add(last_);
}

}  // namespace treecut::strategies
