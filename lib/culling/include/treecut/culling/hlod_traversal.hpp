// HOQ-coherent HLOD refinement in-frame on the render thread: the traversal
// of J. P. Charalambos, J. Bittner, M. Wimmer, E. Romero, "Optimized HLOD
// Refinement Driven by Hardware Occlusion Queries", ISVC 2007
// (../shared/papers/hoq-driven-hlod-refinement.txt, section 4, figures 2
// and 3), over HLOD blocks on the occlusion device CHC uses
// (occlusion_device.hpp), with the paper's four scenarios as modes of one
// loop (its table compares them on one code path):
//   - Bool: SSE refinement (a block stops where SSE <= tau or at a leaf
//     block) with CHC's boolean occlusion: opened blocks pass without a
//     query, last frame's visible termination blocks are drawn at once with
//     their query, the others wait for theirs. The paper's image reference.
//   - SwB: hierarchical stop-and-wait with VMSSE: every block in the frustum
//     is queried and waited for, then culled (no sample), stopped
//     (VMSSE <= tau or a leaf block: drawn) or refined. The ideal node count.
//   - SimpB: the simpler prediction by processing order (Charalambos' earlier
//     method, the paper's reference [12], not in ../shared/papers: this is our
//     reading of the paper's description of it): a block visible last frame
//     is decided at once with the bias last cached for it (1 if it never had
//     an answer): Stop (drawn, queried) when bias * SSE <= tau, else Refine
//     (its children traversed; queried too, so its bias stays current and the
//     front can move up). No delay and no check of the children: a Stop whose
//     answer then says refine is a RARN. Blocks invisible or new last frame
//     wait for their answer (as CHC's).
//   - CohB: the paper's method: hoq::predict_refinement (figure 3) with last
//     frame's cached visibility, stop flags and bias; Refine traverses the
//     children without a query, Stop draws the block and queries it (an
//     answer with VMSSE > tau refines it: a RARN), Delay queries it and
//     decides when the answer is there (cull, stop and draw, or refine).
// The query queue is polled (result_available_render_thread) before every
// block taken from the traversal queue; an answer is read before it is
// available only when the traversal queue is empty (or in SwB, which waits
// for every answer by definition).
// HlodOptions::carry_answers makes Bool, Simp(B) and Coh(B) tolerate a GPU's
// latency (issue 28; gpu_latency.hpp): when the traversal queue runs dry,
// the answers no decision of this frame needs (drawn blocks' and refined
// blocks') and that are not there are carried to a later frame instead of
// waited for: a drawn block counts as visible until its answer, which then
// updates its visibility and bias (a RARN becomes a refinement one frame
// later: late_refined). The answers this frame needs (Delay) are drained with
// one wait, for the newest of them (a GPU answers in issue order). mu = the box's unoccluded pixels (the
// device's box query) / the box's projected pixels (box_projected_pixels,
// analytic); B and VMSSE from hoq.hpp. A block whose box the eye is in (or
// nearer than ViewSnapshot::derived.near_radius) is visible with mu = 1, no query.
//
// Render thread only (the device is); not thread-safe. The hierarchy and the
// blocks must outlive the traversal.
#pragma once

#include <cstdint>
#include <glm/mat4x4.hpp>
#include <glm/vec2.hpp>
#include <string_view>
#include <vector>

#include "treecut/culling/chc.hpp"
#include "treecut/culling/hlod_blocks.hpp"
#include "treecut/culling/hoq_refinement.hpp"
#include "treecut/culling/occlusion_device.hpp"
#include "treecut/hierarchy.hpp"
#include "treecut/view_snapshot.hpp"

namespace treecut::culling {

enum class HlodMode { Bool, SwB, SimpB, CohB };

/// "Bool", "SW(B)", "Simp(B)", "Coh(B)" (the paper's names).
std::string_view hlod_mode_name(HlodMode mode);

struct HlodOptions {
  HlodMode mode = HlodMode::CohB;
  float tau = 1.0f;  ///< pixels of error (the paper's tests: 1)
  float s = 0.5f;    ///< smoothness of the bias (hoq::sigmoid_bias)
  float t = 0.5f;    ///< turn-over of the bias
  /// Latency-tolerant (see above); not SwB, which waits for every answer.
  bool carry_answers = false;
  /// Coh(B): a block new to the traversal (not visited last frame, or
  /// outside its frustum) is predicted as visible with bias 1 (SSE alone:
  /// Stop, drawn and queried, or Refine) instead of Delay, as the `hoq`
  /// strategy's assume_visible: figure 3 delays it for an answer a GPU gives
  /// a frame late, and a walk brings new blocks every frame.
  bool assume_new_visible = false;
};

/// The pixels the box proxy of `box` covers (the convex hull of its projected
/// corners, clipped to the viewport): mu's denominator for a box query.
/// Negative (no analytic count) when a corner is not in front of the eye.
[[nodiscard]] double box_projected_pixels(const ViewSnapshot& view, const Box& box);

/// What one frame did (means of these are the paper's table).
struct HlodFrameStats {
  std::uint64_t drawn = 0;   ///< DN: HLOD blocks drawn (leaf or interior representations)
  std::uint64_t splats = 0;  ///< their splats
  /// RARN: blocks drawn this frame (Stop) whose answer, read in the same
  /// frame, said VMSSE > tau, so their children were traversed and drawn too.
  std::uint64_t rarn = 0;
  std::uint64_t delayed = 0;  ///< CohB's Delay predictions (hidden blocks re-asked included)
  /// D, the paper's "nodes delayed for rendering": of those, the blocks the
  /// answer then drew (a stop found only after waiting for its answer).
  std::uint64_t delayed_drawn = 0;
  std::uint64_t delayed_shift_up = 0;  ///< of them, refined blocks (candidates to shift up)
  /// D by what delayed the block: a shift-up candidate drawn at its own level
  /// (the front moved up), a block new to the traversal (not visited last
  /// frame: the front moved down, or it entered the frustum), a block hidden
  /// last frame (a disocclusion). The three add up to delayed_drawn.
  std::uint64_t delayed_drawn_shift_up = 0;
  std::uint64_t delayed_drawn_new = 0;
  std::uint64_t delayed_drawn_hidden = 0;
  /// Stop predictions (drawn before their answer) whose answer found no
  /// sample: drawn although hidden this frame, where SW(B) culls them.
  std::uint64_t stopped_hidden = 0;
  std::uint64_t culled = 0;          ///< blocks an answer found invisible
  std::uint64_t frustum_culled = 0;  ///< blocks outside the frustum
  std::uint64_t queries = 0;
  std::uint64_t blocking_reads = 0;
  /// carry_answers: answers of earlier frames read this frame, the drawn
  /// blocks among them whose answer said refine (a RARN one frame late: the
  /// block refines in this frame's traversal), queries carried past this
  /// frame's end, and the waits (one read of the newest answer needed).
  std::uint64_t carried_answers = 0;
  std::uint64_t late_refined = 0;
  std::uint64_t carried_pending = 0;
  std::uint64_t drains = 0;
  double wait_ms = 0.0;   ///< CPU time blocked in query reads (the device's)
  double frame_ms = 0.0;  ///< wall time from begin to end of frame (GPU finished if asked)
};

class HlodTraversal {
 public:
  HlodTraversal(const Hierarchy& hierarchy, const HlodBlocks& blocks, HlodOptions options = {});

  /// One frame: begins the device's frame, traverses, ends it. `view`: the
  /// frame's camera over the hierarchy's model space, finalized (its order,
  /// frustum, near radius and the SSE of hoq::block_sse).
  HlodFrameStats frame_render_thread(OcclusionDeviceRenderThread& device, const ViewSnapshot& view,
                                     bool finish = true);
  /// Forgets every cached state (the next frame starts as the first).
  /// Queries still in flight are read and ignored by the next frames.
  void reset();
  /// Reads every answer still in flight (carry_answers), waiting for them,
  /// and gives their handles back to `device`. Render thread.
  void release_render_thread(OcclusionDeviceRenderThread& device);

  [[nodiscard]] const HlodOptions& options() const { return options_; }
  /// The blocks drawn in the last frame, in draw order.
  [[nodiscard]] const std::vector<BlockId>& drawn() const { return drawn_; }
  /// Blocks waiting in the traversal queue now (a read that blocks while this
  /// is not 0 breaks the rule, except in SwB).
  [[nodiscard]] std::size_t queued() const { return heap_.size(); }
  /// The largest splat radius of block `b`'s representation (0 for a leaf block).
  [[nodiscard]] float error_radius(BlockId b) const { return error_radius_[b]; }
  /// The cached state of block `b` after the last frame (tests).
  [[nodiscard]] bool visited(BlockId b) const { return frame_ > 0 && last_visited_[b] == frame_; }
  /// Visited in the last frame and outside its frustum.
  [[nodiscard]] bool outside(BlockId b) const { return visited(b) && outside_[b] != 0; }
  [[nodiscard]] bool visible(BlockId b) const { return visible_[b] != 0; }
  [[nodiscard]] bool stopped(BlockId b) const { return stop_[b] != 0; }
  [[nodiscard]] float bias(BlockId b) const { return bias_[b]; }

 private:
  enum class Kind : std::uint8_t { Drawn, Delayed, Refined };
  // Why a Delayed block waits (the D breakdown of HlodFrameStats).
  enum class Why : std::uint8_t { None, ShiftUp, New, Hidden };
  struct Entry {
    float distance;
    BlockId block;
  };
  struct Pending {
    BlockId block;
    QueryHandle query;
    Kind kind;
    float sse;
    Why why;
    double pixels;             // mu's denominator, for the camera it was issued with
    std::uint64_t frame = 0;   // issued in (carried: 0 after a reset, ignored)
    bool read = false;         // read ahead of the queue (the drain's newest)
    std::uint64_t samples = 0;
  };

  void push(BlockId b);
  void push_children(BlockId b);
  void draw(BlockId b);
  void pull_up(BlockId b);
  void answer(const Pending& p, std::uint64_t samples);
  void take_bias(const Pending& p, std::uint64_t samples);
  Entry pop_nearest();
  void read_available(bool wait_for_each);
  bool carry_or_drain();
  void take_carried_answers();
  void visit(const Entry& e);
  void visit_coh_b(BlockId b, float block_sse, bool visited_last, bool was_visible,
                   bool was_stopped, bool was_outside);
  void query(BlockId b, Kind kind, float sse, Why why = Why::None);
  [[nodiscard]] float sse(BlockId b) const;

  const Hierarchy* hierarchy_;
  const HlodBlocks* blocks_;
  HlodOptions options_;
  std::vector<float> error_radius_;
  std::uint64_t frame_ = 0;
  std::vector<std::uint64_t> last_visited_;  // frame of the last visit (0: never)
  std::vector<std::uint8_t> visible_;
  std::vector<std::uint8_t> outside_;
  std::vector<std::uint8_t> stop_;  // a termination block at its last visit
  std::vector<float> bias_;
  std::vector<std::uint64_t> drawn_frame_;
  std::vector<Entry> heap_;
  std::vector<Pending> pending_;
  std::size_t pending_head_ = 0;
  std::vector<BlockId> drawn_;
  std::vector<hoq::ChildState> children_;
  std::vector<Pending> carried_;              // carry_answers: earlier frames' queries
  std::vector<std::uint64_t> answer_frame_;   // frame of the query of the last answer taken
  // During a frame.
  OcclusionDeviceRenderThread* device_ = nullptr;
  const ViewSnapshot* view_ = nullptr;
  HlodFrameStats stats_;
};

}  // namespace treecut::culling
