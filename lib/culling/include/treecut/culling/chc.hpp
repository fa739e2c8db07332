// Coherent hierarchical culling over HLOD blocks, in-frame on the render thread:
//   J. Bittner, M. Wimmer, H. Piringer, W. Purgathofer, "Coherent Hierarchical
//   Culling: Hardware Occlusion Queries Made Useful", Eurographics 2004
//   (../shared/papers/coherent-hierarchical-culling.tex.txt).
//
// One traversal, four modes (the paper's table compares them on one code path):
//   - Vfc: view-frustum culling only; every leaf block whose box meets the
//     frustum is drawn.
//   - StopAndWait: hierarchical stop-and-wait: every block in the frustum is
//     queried and its answer waited for before the traversal goes on; a
//     visible interior block opens its children, a visible leaf is drawn.
//   - Chc: the paper's algorithm. Blocks are taken front to back (a priority
//     queue on the distance from the eye to the box). Interior blocks visible
//     last frame (the opened nodes) are passed through without a query;
//     queries go to last frame's termination nodes; a leaf visible last frame
//     is drawn at once, its query issued before it and its answer not waited
//     for. Issued queries wait in a query queue whose oldest entry is polled
//     (OcclusionDeviceRenderThread::result_available_render_thread) before
//     every node taken from the traversal queue; a read that may block
//     happens only when the traversal queue is empty. A visible answer pulls
//     visibility up (every ancestor becomes visible) and opens the block
//     (pull-down: its children are traversed); a block not found visible this
//     frame stays invisible (pull-up of invisibility: an opened block with no
//     visible child is a termination node next frame).
//   - Ideal: draws exactly the leaf blocks given by set_ideal_leaves (the set
//     StopAndWait found visible for the same camera), with no query: the
//     traversal runs with the set as an oracle, so the draw order is the
//     same front-to-back order. `treecut bench occlusion` records the set of
//     each frame in its StopAndWait pass over the path and replays it.
//   - ChcPlusPlus: CHC made for a GPU's latency, after CHC++ (O. Mattausch,
//     J. Bittner, M. Wimmer, "CHC++: Coherent Hierarchical Culling
//     Revisited", Eurographics 2008; not in ../shared/papers, our reading in
//     chc_plus_plus.cpp): answers are read only when available while other
//     work exists, previously invisible nodes are queried in batches (the
//     i-queue), a previously visible leaf is drawn at once and queried at the
//     end of the frame against the complete depth (the v-queue) with its
//     answer taken in a later frame (carried: never waited for), t_av is
//     randomized per node, and the answers the frame needs are drained with
//     one wait for the newest (a GPU answers in order). Without waiting
//     (ChcOptions::wait_for_invisible false) those are carried too, their
//     nodes culled until an answer says visible (delayed blocks).
//     docs/gpu-latency.md.
// Options (the paper's section 5): assume_visible_frames (t_av: a leaf found
// visible by a query is assumed visible for the next t_av frames, no query)
// and min_visible_samples (n_vp: an answer below n_vp samples counts as
// occluded; 0 and 1 both mean "any sample").
//
// A block whose box the eye is in (or nearer than ViewSnapshot::derived.near_radius)
// is visible without a query: its proxy would be clipped by the near plane.
//
// Render thread only (the device is); not thread-safe. The blocks must outlive
// the traversal.
#pragma once

#include <cstdint>
#include <glm/mat4x4.hpp>
#include <glm/vec3.hpp>
#include <span>
#include <string_view>
#include <vector>

#include "treecut/culling/hlod_blocks.hpp"
#include "treecut/culling/occlusion_device.hpp"
#include "treecut/view_snapshot.hpp"

namespace treecut::culling {

enum class OcclusionMode { Vfc, StopAndWait, Chc, Ideal, ChcPlusPlus };

/// "vfc", "sw", "chc", "ideal", "chc++".
std::string_view occlusion_mode_name(OcclusionMode mode);

struct ChcOptions {
  OcclusionMode mode = OcclusionMode::Chc;
  /// t_av: frames a leaf found visible by a query is assumed visible without
  /// a new query (0: query every frame). Chc: t_av frames; ChcPlusPlus: a
  /// number of frames drawn per node and answer from [1, t_av] (CHC++'s
  /// randomization: the queries of a region that became visible at once do
  /// not all fall due in the same frame again).
  std::uint32_t assume_visible_frames = 0;
  /// n_vp: answers below this many samples count as occluded (0 or 1: exact).
  std::uint64_t min_visible_samples = 0;
  /// Chc: blocks taken from the traversal queue between two polls of a
  /// pending answer (1: before every block, the paper's basic form). The
  /// paper's section 3.6: where the check is costly, ask later. On llvmpipe
  /// the first poll of a query flushes the batched draws (docs/occlusion.md).
  std::uint32_t poll_interval = 1;
  /// Ideal only, a diagnostic: a box query before every leaf block it draws,
  /// answers read as CHC reads them and ignored. Ideal's draws with CHC's
  /// query traffic: the difference to Ideal is the queries' own cost.
  bool ideal_probe_queries = false;
  /// ChcPlusPlus: queries of previously invisible nodes are issued when this
  /// many are queued (or when the traversal queue runs dry): the i-queue.
  std::uint32_t batch_size = 32;
  /// ChcPlusPlus: false: never wait. Answers of previously invisible nodes
  /// that are not there when the frame has nothing else to do are carried
  /// to a later frame, their nodes culled meanwhile; one that then says
  /// visible is a delayed block (drawn from that frame on, a frame or more
  /// late). True: the drain waits for them (the image is exact).
  bool wait_for_invisible = true;
};

/// What one frame did.
struct ChcFrameStats {
  std::uint64_t queries = 0;         ///< occlusion queries issued
  std::uint64_t blocking_reads = 0;  ///< answers read before they were available
  double wait_ms = 0.0;              ///< CPU time blocked in those reads (the device's)
  /// The part of wait_ms after the traversal queue got its last block of the
  /// frame: the drain of the last answers, which waits for the frame's GPU
  /// work (what the final glFinish would wait for otherwise).
  double drain_wait_ms = 0.0;
  std::uint64_t blocks_drawn = 0;    ///< leaf blocks drawn
  std::uint64_t splats_drawn = 0;    ///< their splats
  std::uint64_t leaves_visible = 0;  ///< leaf blocks classified visible at the end of the frame
  std::uint64_t frustum_culled = 0;  ///< blocks taken from the traversal queue outside the frustum
  /// ChcPlusPlus: answers read this frame of queries issued in an earlier
  /// frame (the v-queue's, taken when available, never waited for).
  std::uint64_t carried_answers = 0;
  /// ChcPlusPlus: queries still in flight when the frame ended (carried).
  std::uint64_t carried_pending = 0;
  /// ChcPlusPlus: the times the frame had to wait (one blocking read of the
  /// newest answer needed, after which the older ones are there).
  std::uint64_t drains = 0;
  std::uint64_t batches = 0;  ///< ChcPlusPlus: i-queue batches issued
  /// ChcPlusPlus without waiting: carried answers of previously invisible
  /// nodes read this frame that said visible (culled in the frame they were
  /// asked in, although visible: drawn late).
  std::uint64_t delayed_blocks = 0;
  double frame_ms = 0.0;  ///< wall time from begin to end of frame (GPU finished if asked)
};

class ChcTraversal {
 public:
  explicit ChcTraversal(const HlodBlocks& blocks, ChcOptions options = {});

  /// One frame: begins the device's frame, traverses, ends it (finish: waits
  /// for the GPU, so frame_ms is the whole frame).
  /// `view`: the frame's camera over the blocks' model space, finalized.
  ChcFrameStats frame_render_thread(OcclusionDeviceRenderThread& device, const ViewSnapshot& view,
                                    bool finish = true);

  /// Ideal mode: the leaf blocks to draw in the next frame (the StopAndWait
  /// set of the same camera). Ids that are not leaf blocks are ignored.
  void set_ideal_leaves(std::span<const BlockId> leaves);
  /// Forgets all visibility (the next frame starts as the first). Queries
  /// still in flight from earlier frames (ChcPlusPlus) are read and ignored
  /// by the next frames.
  void reset();
  /// ChcPlusPlus: reads every answer still in flight (waiting for them) and
  /// gives their handles back to `device`; call before the device or the
  /// traversal goes away, or between runs on one device. Render thread.
  void release_render_thread(OcclusionDeviceRenderThread& device);

  [[nodiscard]] const ChcOptions& options() const { return options_; }
  [[nodiscard]] const HlodBlocks& blocks() const { return *blocks_; }
  /// The leaf blocks drawn in the last frame, in draw order.
  [[nodiscard]] const std::vector<BlockId>& drawn() const { return drawn_; }
  /// The leaf blocks classified visible at the end of the last frame, in
  /// classification order (StopAndWait: the same set as drawn()).
  [[nodiscard]] std::vector<BlockId> visible_leaves() const;
  /// Whether block `b` is visible by the last frame's classification.
  [[nodiscard]] bool visible(BlockId b) const;
  /// Blocks waiting in the traversal queue now (a device may ask while the
  /// frame runs: a read that blocks while this is not 0 breaks CHC's rule).
  [[nodiscard]] std::size_t queued() const { return heap_.size(); }
  /// Frames run since construction or reset().
  [[nodiscard]] std::uint64_t frame() const { return frame_; }

 private:
  struct Entry {
    float distance;
    BlockId block;
  };
  struct Pending {
    BlockId block;
    QueryHandle query;
    bool drawn;  // drawn when queried (a previously visible leaf)
    bool read = false;  // ChcPlusPlus's drain: its answer was read first (samples)
    std::uint64_t samples = 0;
  };

  // A query of an earlier frame whose answer is taken when it is there.
  struct Carried {
    BlockId block;
    QueryHandle query;
    std::uint64_t frame;  // issued in (0: issued before a reset, ignored)
    bool hidden = false;  // a previously invisible node's (not waited for): culled meanwhile
  };

  void push(BlockId b, const ViewSnapshot& view);
  Entry pop_nearest();
  // ChcPlusPlus (chc_plus_plus.cpp).
  void traverse_chc_plus_plus(const ViewSnapshot& view, OcclusionDeviceRenderThread& device,
                              ChcFrameStats& stats);
  void visit_chc_plus_plus(const Entry& e, const ViewSnapshot& view,
                           OcclusionDeviceRenderThread& device, ChcFrameStats& stats);
  void take_carried_answers(OcclusionDeviceRenderThread& device, ChcFrameStats& stats);
  void issue_invisible_batch(OcclusionDeviceRenderThread& device, ChcFrameStats& stats);
  void read_needed_answers(const ViewSnapshot& view, OcclusionDeviceRenderThread& device,
                           bool drain, ChcFrameStats& stats);
  void apply_answer(const Pending& p, std::uint64_t samples, const ViewSnapshot& view,
                    OcclusionDeviceRenderThread& device);
  [[nodiscard]] bool assumed_visible(BlockId b) const;
  void traverse(BlockId b, const ViewSnapshot& view, OcclusionDeviceRenderThread& device);
  void read_answers(const ViewSnapshot& view, OcclusionDeviceRenderThread& device,
                    std::uint32_t interval, std::uint32_t& since_poll);
  void visit(const Entry& e, const ViewSnapshot& view, OcclusionDeviceRenderThread& device,
             ChcFrameStats& stats);
  void draw(BlockId b, OcclusionDeviceRenderThread& device);
  void pull_up(BlockId b);
  [[nodiscard]] bool answer_visible(std::uint64_t samples) const;

  const HlodBlocks* blocks_;
  ChcOptions options_;
  std::uint64_t frame_ = 0;
  std::vector<std::uint8_t> visible_;
  std::vector<std::uint64_t> last_visited_;   // frame of the last visit (0: never)
  std::vector<std::uint64_t> visible_query_;  // frame of the last query that found it visible
  std::vector<std::uint64_t> drawn_frame_;    // frame it was last drawn in
  std::vector<std::uint8_t> ideal_;           // Ideal: in the set or above a block in it
  std::vector<Entry> heap_;                   // traversal queue (min-heap on distance)
  std::vector<Pending> pending_;              // query queue (FIFO from pending_head_)
  std::size_t pending_head_ = 0;
  std::vector<BlockId> drawn_;
  std::vector<BlockId> classified_;  // leaves visited this frame
  std::vector<BlockId> i_queue_;     // ChcPlusPlus: invisible nodes waiting for a batch
  std::vector<BlockId> v_queue_;     // ChcPlusPlus: visible leaves to query at the frame's end
  std::vector<Carried> carried_;     // ChcPlusPlus: queries of earlier frames (in issue order)
  std::vector<std::uint8_t> in_flight_;  // ChcPlusPlus: per block, a carried query pending
  double wait_at_push_ = 0.0;        // the device's wait_ms when the last block was queued
  const OcclusionDeviceRenderThread* device_ = nullptr;  // during a frame
};

}  // namespace treecut::culling
