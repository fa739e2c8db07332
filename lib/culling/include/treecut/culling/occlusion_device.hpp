// What an in-frame occlusion traversal needs from the render thread: issue a
// query of a block's box against the depth drawn so far, ask whether its
// answer is there (never blocks), read the answer (may block: the device
// measures that time, the "CPU wait time" of the CHC paper's table), draw a
// block's representation (optionally inside a query), begin and end a frame.
//
// Pure C++, no GL: the GL device (treecut/splat/occlusion_device_gl.hpp) does
// it with GL query objects and the renderer's in-frame range draws; the tests
// use a CPU device (tests/culling/chc_test.cpp). The CHC traversal
// (treecut/culling/chc.hpp) is the first user; the HOQ in-frame modes
// (Charalambos et al. 2007) need the same four operations (box queries, a
// block's representation drawn inside a query, polling, plain draws of
// interior blocks' representations), so nothing here is CHC-specific.
//
// Thread affinity: every member runs on the render thread, inside the frame
// it belongs to (between begin_frame_render_thread and
// end_frame_render_thread), with that thread's GL context current for the
// GL device. Handles are valid from their issue until their result is read
// (result_render_thread frees them), in a later frame too: a traversal may
// carry a query whose answer it does not need now (CHC++'s visible leaves,
// HLOD's drawn blocks under a GPU's latency) and read it frames later.
#pragma once

#include <cstdint>
#include <limits>

#include "treecut/culling/hlod_blocks.hpp"

namespace treecut::culling {

/// A query in flight; kNoQuery is no query.
using QueryHandle = std::uint32_t;
inline constexpr QueryHandle kNoQuery = std::numeric_limits<QueryHandle>::max();

/// What the device counted since begin_frame_render_thread.
struct DeviceFrameStats {
  std::uint64_t queries = 0;         ///< box and draw queries issued
  std::uint64_t blocking_reads = 0;  ///< results read before they were known available
  double wait_ms = 0.0;              ///< CPU time blocked in those reads
  std::uint64_t blocks_drawn = 0;    ///< representations drawn (plain or inside a query)
  std::uint64_t splats_drawn = 0;    ///< nodes of those representations
};

class OcclusionDeviceRenderThread {
 public:
  virtual ~OcclusionDeviceRenderThread() = default;

  /// Clears color and depth and opens a frame; resets frame_stats().
  virtual void begin_frame_render_thread() = 0;
  /// Issues a query of block `b`'s box against the depth drawn so far (no
  /// color or depth writes). Its answer: the samples of the box that pass.
  virtual QueryHandle query_box_render_thread(BlockId b) = 0;
  /// Draws block `b`'s representation inside a query (color and depth
  /// written): its answer is the samples of those splats that passed.
  virtual QueryHandle query_draw_render_thread(BlockId b) = 0;
  /// Whether the answer of `q` can be read without waiting. Never blocks.
  virtual bool result_available_render_thread(QueryHandle q) = 0;
  /// The answer of `q` (samples passed); waits for it if it is not available
  /// yet (counted in DeviceFrameStats::blocking_reads and wait_ms). Frees `q`.
  virtual std::uint64_t result_render_thread(QueryHandle q) = 0;
  /// Draws block `b`'s representation (color and depth written).
  virtual void draw_render_thread(BlockId b) = 0;
  /// Closes the frame; with `finish`, returns only when the GPU is done with it.
  virtual void end_frame_render_thread(bool finish) = 0;

  [[nodiscard]] virtual const DeviceFrameStats& frame_stats() const = 0;
};

}  // namespace treecut::culling
