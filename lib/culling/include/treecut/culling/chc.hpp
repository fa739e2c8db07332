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

enum class OcclusionMode { Vfc, StopAndWait, Chc, Ideal };

/// "vfc", "sw", "chc", "ideal".
std::string_view occlusion_mode_name(OcclusionMode mode);

struct ChcOptions {
  OcclusionMode mode = OcclusionMode::Chc;
  /// t_av: frames a leaf found visible by a query is assumed visible without
  /// a new query (0: query every frame). Chc only.
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
  /// Forgets all visibility (the next frame starts as the first).
  void reset();

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
  };

  void push(BlockId b, const ViewSnapshot& view);
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
  double wait_at_push_ = 0.0;        // the device's wait_ms when the last block was queued
  const OcclusionDeviceRenderThread* device_ = nullptr;  // during a frame
};

}  // namespace treecut::culling
