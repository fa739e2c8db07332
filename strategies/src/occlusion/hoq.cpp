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
           double(culling::kDefaultBlockSize), 1.0, 1e8, true},
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
  // The blocks are made as the traversal reaches them (resident_blocks.hpp).
  blocks_.reset(h, static_cast<std::uint32_t>(param_at(kBlockSize)));
  hierarchy_ = &h;
  hierarchy_nodes_ = h.node_count();
  state_.clear();
  cut_.clear();
  cut_slots_.clear();
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

// A paged model's pages changed: the blocks over them are made again, and
// the state of those dropped with a concealed node's pages goes with them.
void HoqStrategy::follow_residency(const IterationInput& input) {
  if (input.revealed.empty() && input.concealed.empty()) return;
  dropped_.clear();
  blocks_.residency_changed(input.hierarchy, input.revealed, input.concealed, dropped_);
  for (const std::uint32_t slot : dropped_)
    if (slot < state_.size()) state_[slot] = BlockState{};
}

HoqStrategy::BlockState& HoqStrategy::state(std::uint32_t slot) {
  // A deque grows without moving the states the traversal holds
  // references to.
  if (slot >= state_.size()) state_.resize(std::size_t{slot} + 1);
  return state_[slot];
}

void HoqStrategy::append_representations(std::vector<NodeId>& out, bool memory_short) const {
  out.clear();
  for (const std::uint32_t slot : cut_slots_) {
    // A block outside the frustum is drawn at its representation: nothing
    // of it is seen, but a camera that turns finds it there before the
    // next list (drawn at its root node instead, the city walk's frames
    // that differ from full detail lose 9 dB of luma PSNR). On a paged
    // model short of memory the representation would hold pages below
    // the block that the view needs: its root node stands for it.
    if (memory_short && state_[slot].outside) {
      out.push_back(blocks_.block(slot).node);
      continue;
    }
    const auto& rep = blocks_.block(slot).rep;
    out.insert(out.end(), rep.begin(), rep.end());
  }
}

const ViewSnapshot* HoqStrategy::camera_of(std::uint64_t frame) const {
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
  const float s = static_cast<float>(param_at(kS));
  const float t = static_cast<float>(param_at(kT));
  for (const VisibilityResult& r : view.visibility) {
    // Only answers to this strategy's requests (tag: the block's slot)
    // about blocks it still holds (not dropped with their pages since, nor
    // the slot given to another block).
    if (r.object != input.object || r.tag >= state_.size() || state_[r.tag].node != r.node)
      continue;
    const std::uint32_t slot = r.tag;
    ++last_.answers;
    last_.answer_age_frames += frame_ >= r.frame_issued ? frame_ - r.frame_issued : 0;
    last_.answer_gpu_frames += r.frame_read >= r.frame_issued ? r.frame_read - r.frame_issued : 0;
    BlockState& st = state_[slot];
    if (r.frame_issued < st.answer_frame) continue;  // an older answer than the one taken
    const ViewSnapshot* cam = camera_of(r.frame_issued);
    const glm::vec4 sphere = a.center_radius[r.node];
    const double pixels =
        culling::hoq::proxy_pixels(cam != nullptr ? *cam : view, glm::vec3(sphere), sphere.w);
    const float mu = culling::hoq::relative_visibility(r.samples_passed, pixels);
    // Bool (the paper's image reference): the answer only as visible or not.
    st.bias =
        param_at(kBias) != 0.0 ? culling::hoq::sigmoid_bias(mu, s, t) : (mu > 0.0f ? 1.0f : 0.0f);
    st.visible = r.samples_passed > 0;
    st.answer_frame = r.frame_issued;
  }
}

void HoqStrategy::terminal(std::uint32_t slot, bool known_invisible, IterationOutput& output) {
  BlockState& s = state_[slot];
  const NodeId b = s.node;
  s.stop = true;
  s.culled = known_invisible;
  cut_.push_back(b);
  cut_slots_.push_back(slot);
  ++last_.blocks;
  if (known_invisible) {
    ++last_.culled;
    return;
  }
  ++last_.drawn;
  // A paged model: the block draws nodes it would refine past were their
  // children resident; their pages are what it asks for (a block known
  // invisible, out of the view or occluded, is drawn as it is).
  if (output.wanted != nullptr) {
    const auto& hidden = blocks_.block(slot).hidden;
    output.wanted->insert(output.wanted->end(), hidden.begin(), hidden.end());
  }
}

void HoqStrategy::query(std::uint32_t slot, const IterationInput& input, IterationOutput& output) {
  // The proxy: the bounding sphere of the block's root node, which contains
  // every node of the block's subtree, drawn by the executor at the sphere's
  // nearest depth (a point sprite over its window rectangle).
  output.queries->push_back(query_about(input, state_[slot].node, slot));
  ++last_.queries;
}

void HoqStrategy::children_states(NodeId b, const IterationInput& input) {
  children_.clear();
  const auto& a = input.hierarchy.arrays();
  for (NodeId c = a.first_child[b]; c < a.first_child[b] + a.child_count[b]; ++c) {
    const culling::ResidentBlocks::Block& block = blocks_.at(input.hierarchy, c);
    const BlockState& cs = state(block.slot);
    children_.push_back(
        {cs.stop, cs.bias, culling::hoq::block_sse(input.view, block.box, block.error_radius)});
  }
}

// The paper's Refine: the children are traversed now, no query nor drawing
// for the block itself. A refined block is visible when one of its children
// is (pulled up).
[[gnu::always_inline]] inline void HoqStrategy::refine(const Visit& v, const IterationInput& input,
                                                       IterationOutput& output) {
  if (!v.was_refined) ++last_.refined;
  state_[v.slot].stop = false;
  const auto& a = input.hierarchy.arrays();
  const NodeId first = a.first_child[v.block];
  bool any = false;
  for (NodeId c = first; c < first + a.child_count[v.block]; ++c) {
    any = visit(c, input, output) || any;
  }
  state_[v.slot].visible = any;
}

// A delayed block (the paper's case 3, its node in the query queue): decided
// once the answer it waits for is in, else kept as the delay began.
[[gnu::always_inline]] inline void HoqStrategy::decide_delayed(const Visit& v,
                                                               const IterationInput& input,
                                                               IterationOutput& output) {
  const std::uint32_t slot = v.slot;
  BlockState& s = state_[slot];
  if (s.answer_frame > s.delay_after) {
    // The answer the decision waited for (the paper's query queue): cull
    // an invisible block, stop where VMSSE <= tau, else refine.
    const Delay kind = s.delay;
    s.delay = Delay::None;
    const bool stop_here = !s.visible || culling::hoq::vmsse(s.bias, v.sse) <= v.tau;
    if (stop_here) {
      if (kind == Delay::ShiftUp) ++last_.coarsened;
      s.stop_bias = s.bias;
      terminal(slot, !s.visible, output);
      query(slot, input, output);
      return;
    }
    if (kind != Delay::ShiftUp) {
      // Kept at its level while it waited: drawn too coarse since it
      // entered, or since the answer that found it visible was issued.
      ++last_.late_refined;
      last_.late_frames +=
          frame_ + 1 - (kind == Delay::Front ? s.delay_frame : std::min(s.answer_frame, frame_));
    }
    refine(v, input, output);
    return;
  }
  if (s.delay == Delay::ShiftUp) {
    // Still waiting; a child that now needs refinement ends the candidacy.
    children_states(v.block, input);
    const culling::hoq::NodeState ns{true, true, false, s.bias};
    if (culling::hoq::predict_refinement(ns, v.sse, children_, v.tau) ==
        culling::hoq::Prediction::Refine) {
      s.delay = Delay::None;
    } else {
      ++last_.delayed;
      ++last_.delayed_shift_up;
      query(slot, input, output);
    }
    refine(v, input, output);
    return;
  }
  // A delayed termination block keeps its state (its level) until its answer.
  if (s.visible) ++last_.delayed;
  terminal(slot, !s.visible, output);
  query(slot, input, output);
}

// The paper's Refine as predicted, with the too-coarse drawings it reveals:
// a disocclusion, or RARN.
[[gnu::always_inline]] inline void HoqStrategy::refine_predicted(const Visit& v,
                                                                 const IterationInput& input,
                                                                 IterationOutput& output) {
  const BlockState& s = state_[v.slot];
  if (v.was_terminal && s.culled) {
    // Culled (hidden) at its last visit, visible in the newer answer and
    // needing refinement: a disocclusion, drawn too coarse since that
    // answer was issued (the same as a Hidden delay resolved to refine).
    ++last_.late_refined;
    last_.late_frames += frame_ + 1 - std::min(s.answer_frame, frame_);
  } else if (v.was_terminal && culling::hoq::vmsse(s.stop_bias, v.sse) <= v.tau) {
    // Drawn (Stop) and refined because a newer answer raised the bias
    // (the old one would still stop): the paper's RARN, drawn too coarse
    // from the frame the answer was issued in to the frame its
    // refinement can be drawn.
    ++last_.rarn;
    last_.rarn_frames += frame_ + 1 - std::min(s.answer_frame, frame_);
  }
  refine(v, input, output);
}

// The paper's Delay as predicted: the decision waits for the block's answer.
[[gnu::always_inline]] inline void HoqStrategy::delay_decision(const Visit& v,
                                                               const IterationInput& input,
                                                               IterationOutput& output) {
  const std::uint32_t slot = v.slot;
  BlockState& s = state_[slot];
  s.delay_frame = frame_;
  if (v.was_refined) {
    // A candidate to shift up: its children stay drawn while its own
    // answer is on its way.
    s.delay = Delay::ShiftUp;
    s.delay_after = frame_;
    ++last_.delayed;
    ++last_.delayed_shift_up;
    query(slot, input, output);
    refine(v, input, output);
    return;
  }
  if (!v.was_visited) {
    // New in the traversal: any answer issued from now on will do. With
    // assume_visible it is drawn as if visible and unmodulated (bias 1,
    // VMSSE = SSE: never too coarse) while it waits, so a block whose
    // SSE exceeds tau is refined now instead of a round trip per level.
    if (param_at(kAssumeVisible) != 0.0 && v.sse > v.tau) {
      refine(v, input, output);
      return;
    }
    s.delay = Delay::Front;
    s.delay_after = frame_;
    ++last_.delayed;
    terminal(slot, false, output);
    query(slot, input, output);
    return;
  }
  // Invisible last frame: the next answer will do; culled until then.
  s.delay = Delay::Hidden;
  s.delay_after = s.answer_frame;
  terminal(slot, true, output);
  query(slot, input, output);
}

// PredictRefinement (the paper's figure 3) from the last iteration's state,
// and its action: Stop (query and draw), Refine, or Delay.
[[gnu::always_inline]] inline void HoqStrategy::follow_prediction(const Visit& v,
                                                                  const IterationInput& input,
                                                                  IterationOutput& output) {
  BlockState& s = state_[v.slot];
  culling::hoq::NodeState ns{v.was_visited, s.visible, v.was_terminal, s.bias};
  if (v.was_refined) children_states(v.block, input);
  const culling::hoq::Prediction p = culling::hoq::predict_refinement(
      ns, v.sse,
      v.was_refined ? std::span<const culling::hoq::ChildState>(children_)
                    : std::span<const culling::hoq::ChildState>(),
      v.tau);
  switch (p) {
    case culling::hoq::Prediction::Stop:
      s.stop_bias = s.bias;
      terminal(v.slot, false, output);
      query(v.slot, input, output);
      return;
    case culling::hoq::Prediction::Refine:
      refine_predicted(v, input, output);
      return;
    case culling::hoq::Prediction::Delay:
      delay_decision(v, input, output);
      return;
  }
}

bool HoqStrategy::visit(NodeId b, const IterationInput& input, IterationOutput& output) {
  const ViewSnapshot& view = input.view;
  const float tau = static_cast<float>(param_at(kTheta));
  const culling::ResidentBlocks::Block& block = blocks_.at(input.hierarchy, b);
  const std::uint32_t slot = block.slot;
  BlockState& s = state(slot);
  s.node = b;
  // A block the frustum culled has no occlusion answer to go by: back in
  // view it is new to the traversal, as the paper's not-visited node.
  // One that was a leaf only for want of its children's pages enters anew
  // once they are in, as on the model held whole.
  const bool revealed = s.hidden && !input.hierarchy.is_hidden(b);
  const bool was_visited = s.visited != 0 && s.visited + 1 == iteration_ && !s.outside && !revealed;
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

  const glm::vec4 sphere = input.hierarchy.arrays().center_radius[b];
  if (view.outside_frustum(glm::vec3(sphere), sphere.w)) {
    // Culled without a query, at the highest block found outside: its
    // subtree draws nothing the camera sees, so it is as coarse as it can be.
    if (was_refined) ++last_.coarsened;
    s.visible = false;
    s.bias = 0.0f;
    s.delay = Delay::None;
    s.outside = true;
    terminal(slot, true, output);
    return s.visible;
  }
  s.outside = false;
  if (blocks_.is_leaf(input.hierarchy, b)) {
    // Full detail (or all of it that is resident): the refinement stops
    // here whatever the answer; the query still gives its parent the bias
    // the shift-up test reads.
    s.delay = Delay::None;
    s.stop_bias = s.bias;
    // A leaf only until its children's pages arrive: it enters anew then.
    s.hidden = input.hierarchy.is_hidden(b);
    terminal(slot, !s.visible, output);
    query(slot, input, output);
    return s.visible;
  }
  // A paged model: a representation not all resident yet gives a box and an
  // error at least the whole one's (a hidden node's sphere holds its
  // subtree, its radius its descendants'), so the SSE errs towards
  // refining, into children whose own blocks are smaller: what a block
  // asks for stays near the view. (Waiting for the whole representation
  // instead stalled the root block under a budget its subtree's pages
  // exceed.)
  const float sse = culling::hoq::block_sse(view, block.box, block.error_radius);
  const Visit v{b, slot, was_visited, was_refined, was_terminal, sse, tau};
  if (s.delay != Delay::None) {
    decide_delayed(v, input, output);
  } else {
    follow_prediction(v, input, output);
  }
  return state_[slot].visible;
}

void HoqStrategy::iterate(const IterationInput& input, IterationOutput& output) {
  const Hierarchy& h = input.hierarchy;
  if (hierarchy_ != &h || hierarchy_nodes_ != h.node_count() ||
      blocks_.block_size() != static_cast<std::uint32_t>(param_at(kBlockSize))) {
    build_blocks(h);
  } else {
    follow_residency(input);
  }
  IterationResult& r = output.result;
  if (input.cancelled()) {
    // Nothing decided yet: the last block cut (or the root block) stays.
    if (cut_.empty()) cut_.push_back(h.root());
    // (Made again where their pages changed since.)
    cut_slots_.clear();
    for (const NodeId b : cut_) cut_slots_.push_back(blocks_.at(h, b).slot);
    append_representations(*output.nodes, input.memory_short);
    r.cancelled = true;
    return;
  }
  ++iteration_;
  frame_ = input.view.frame;
  FrameCamera& slot = cameras_[camera_count_ % kCameras];
  // The camera only: the view's visibility list stays with the snapshot.
  slot.frame = frame_;
  slot.camera.view = input.view.view;
  slot.camera.projection = input.view.projection;
  slot.camera.viewport = input.view.viewport;
  slot.camera.derived = input.view.derived;
  ++camera_count_;

  last_ = {};
  take_answers(input);
  previous_cut_.swap(cut_);
  cut_.clear();
  cut_slots_.clear();
  visit(h.root(), input, output);
  append_representations(*output.nodes, input.memory_short);

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
  publish(last_, r.counters);
}

void HoqStrategy::publish(const HoqCounters& c, Counters& out) {
  // The paper's quantities per iteration (docs/occlusion.md, "## HOQ"): the
  // block cut, DN, the culled blocks, D (of it the refined candidates to
  // shift up), RARN and the late refinements with the frames they waited.
  out.set("hoq_blocks", double(c.blocks), "blocks");
  out.set("hoq_dn", double(c.drawn), "blocks");
  out.set("hoq_culled", double(c.culled), "blocks");
  out.set("hoq_delayed", double(c.delayed), "blocks");
  out.set("hoq_shift_up", double(c.delayed_shift_up), "blocks");
  out.set("hoq_rarn", double(c.rarn), "blocks");
  out.set("hoq_rarn_frames", double(c.rarn_frames), "frames");
  out.set("hoq_late", double(c.late_refined), "blocks");
  out.set("hoq_late_frames", double(c.late_frames), "frames");
}

}  // namespace treecut::strategies
