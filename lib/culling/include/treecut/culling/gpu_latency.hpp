// A GPU-latency model for the query paths. On llvmpipe the rasterizer runs on
// the render thread's own cores and an occlusion query's answer is ready
// almost at once; on a GPU it comes a frame or more later (issue 16: CHC made
// 337 blocking reads a frame on an H200, 7.5 on llvmpipe). The model makes
// the delay explicit and deterministic, so the traversals' behaviour under a
// GPU's latency is tested and measured on any machine:
//   - GpuLatency: the delay, in frames (deterministic: counted by the
//     device's frames) and/or microseconds of wall time since the issue.
//   - LatentOcclusionDevice: an OcclusionDeviceRenderThread that wraps
//     another (the GL device, a test's CPU device) and says an answer is
//     available only once the delay has passed. A read before that is a
//     blocking read, counted as the GL device counts one. Answers complete
//     in issue order, as a GPU's do: once a read has waited for a query,
//     every query issued before it is available too.
//   - The query executor of the stage strategies takes GpuLatency::frames as
//     its minimum answer age (QueryExecutorOptions::min_answer_frames).
// Used by `treecut bench occlusion --latency` and the occlusion tests, which
// run at 0, 1 and 2 frames and assert counts (docs/occlusion.md, "GPU
// latency").
//
// Render thread only, as the device it wraps.
#pragma once

#include <chrono>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "treecut/culling/occlusion_device.hpp"

namespace treecut::culling {

struct GpuLatency {
  /// An answer is available no earlier than this many frames after the
  /// frame it was issued in (0: within the frame, as the wrapped device says).
  std::uint32_t frames = 0;
  /// ... and no earlier than this many microseconds after its issue.
  double microseconds = 0.0;

  [[nodiscard]] bool none() const { return frames == 0 && microseconds <= 0.0; }
};

/// "0", "2f", "1frame", "3frames", "300us": the --latency syntax. Throws
/// std::invalid_argument naming the text for anything else (negative, a
/// unit missing after a non-zero number, more than 1000 frames or 1 s).
[[nodiscard]] GpuLatency parse_gpu_latency(std::string_view text);
/// "none", "2 frames", "300 us" (the reports' wording).
[[nodiscard]] std::string describe(const GpuLatency& latency);

class LatentOcclusionDevice final : public OcclusionDeviceRenderThread {
 public:
  /// `inner` must outlive this device; its handles are this device's.
  LatentOcclusionDevice(OcclusionDeviceRenderThread& inner, GpuLatency latency);

  void begin_frame_render_thread() override;
  QueryHandle query_box_render_thread(BlockId b) override;
  QueryHandle query_draw_render_thread(BlockId b) override;
  /// The model's delay has passed and the wrapped device has the answer.
  bool result_available_render_thread(QueryHandle q) override;
  /// A read the model says is early counts as blocking (once, whether or
  /// not the wrapped device waits too); a microsecond delay is waited out
  /// (its time is wait_ms), a frame delay is not (nothing would end it: the
  /// read stands for the wait of a GPU finishing the frames before).
  std::uint64_t result_render_thread(QueryHandle q) override;
  void draw_render_thread(BlockId b) override;
  void end_frame_render_thread(bool finish) override;
  /// The wrapped device's counts, with the model's blocking reads and waits.
  [[nodiscard]] const DeviceFrameStats& frame_stats() const override;

  [[nodiscard]] const GpuLatency& latency() const { return latency_; }
  /// Frames begun so far.
  [[nodiscard]] std::uint64_t frame() const { return frame_; }

 private:
  using Clock = std::chrono::steady_clock;
  struct Issue {
    std::uint64_t frame = 0;
    std::uint64_t sequence = 0;  // issue order
    Clock::time_point time;
  };
  void record(QueryHandle q);
  [[nodiscard]] bool ready_in_model(QueryHandle q) const;

  OcclusionDeviceRenderThread* inner_;
  GpuLatency latency_;
  std::uint64_t frame_ = 0;
  std::uint64_t issued_ = 0;
  std::uint64_t completed_ = 0;  // queries up to this sequence number are done (in order)
  std::vector<Issue> issues_;    // per handle
  std::uint64_t blocking_ = 0;   // this frame's reads the model alone made blocking
  double wait_ms_ = 0.0;         // and the time waited out for microsecond delays
  mutable DeviceFrameStats stats_;
};

}  // namespace treecut::culling
