// The GPU-latency model of the query paths (gpu_latency.hpp): answers that
// arrive frames or microseconds after their issue, in issue order, as on a
// GPU (issue 28; the measured H200 behaviour in docs/occlusion.md).
#include "treecut/culling/gpu_latency.hpp"

#include <charconv>
#include <cmath>
#include <stdexcept>
#include <thread>

namespace treecut::culling {

namespace {

[[noreturn]] void bad_latency(std::string_view text, const char* why) {
  throw std::invalid_argument("latency '" + std::string(text) + "': " + why +
                              " (examples: 0, 1f, 2frames, 300us)");
}

}  // namespace

GpuLatency parse_gpu_latency(std::string_view text) {
  double value = 0.0;
  const char* first = text.data();
  const char* last = text.data() + text.size();
  const auto [end, ec] = std::from_chars(first, last, value);
  if (ec != std::errc() || end == first || !std::isfinite(value)) bad_latency(text, "no number");
  if (value < 0.0) bad_latency(text, "negative");
  const std::string_view unit(end, static_cast<std::size_t>(last - end));
  GpuLatency l;
  if (unit == "f" || unit == "frame" || unit == "frames") {
    if (value != std::floor(value)) bad_latency(text, "frames are whole");
    if (value > 1000.0) bad_latency(text, "more than 1000 frames");
    l.frames = static_cast<std::uint32_t>(value);
  } else if (unit == "us") {
    if (value > 1e6) bad_latency(text, "more than 1 s");
    l.microseconds = value;
  } else if (unit.empty() && value == 0.0) {
    // "0": none.
  } else {
    bad_latency(text, "the unit is f (frames) or us (microseconds)");
  }
  return l;
}

std::string describe(const GpuLatency& latency) {
  if (latency.none()) return "none";
  std::string out;
  if (latency.frames > 0) {
    out = std::to_string(latency.frames) + (latency.frames == 1 ? " frame" : " frames");
  }
  if (latency.microseconds > 0.0) {
    char us[32];
    std::snprintf(us, sizeof us, "%g us", latency.microseconds);
    out += (out.empty() ? "" : " and ") + std::string(us);
  }
  return out;
}

LatentOcclusionDevice::LatentOcclusionDevice(OcclusionDeviceRenderThread& inner,
                                             GpuLatency latency)
    : inner_(&inner), latency_(latency) {}

void LatentOcclusionDevice::begin_frame_render_thread() {
  ++frame_;
  blocking_ = 0;
  wait_ms_ = 0.0;
  inner_->begin_frame_render_thread();
}

void LatentOcclusionDevice::record(QueryHandle q) {
  if (q >= issues_.size()) issues_.resize(std::max<std::size_t>(q + 1, 2 * issues_.size()));
  issues_[q] = {frame_, ++issued_, Clock::now()};
}

QueryHandle LatentOcclusionDevice::query_box_render_thread(BlockId b) {
  const QueryHandle q = inner_->query_box_render_thread(b);
  record(q);
  return q;
}

QueryHandle LatentOcclusionDevice::query_draw_render_thread(BlockId b) {
  const QueryHandle q = inner_->query_draw_render_thread(b);
  record(q);
  return q;
}

bool LatentOcclusionDevice::ready_in_model(QueryHandle q) const {
  const Issue& i = issues_.at(q);
  if (i.sequence <= completed_) return true;  // a later query was waited for: done, in order
  if (frame_ - i.frame < latency_.frames) return false;
  if (latency_.microseconds <= 0.0) return true;
  const double age_us =
      std::chrono::duration<double, std::micro>(Clock::now() - i.time).count();
  return age_us >= latency_.microseconds;
}

bool LatentOcclusionDevice::result_available_render_thread(QueryHandle q) {
  return ready_in_model(q) && inner_->result_available_render_thread(q);
}

std::uint64_t LatentOcclusionDevice::result_render_thread(QueryHandle q) {
  if (!ready_in_model(q)) {
    const Issue& i = issues_.at(q);
    // The wrapped device's own wait, if it has one, counts there: count
    // here only the reads the model alone makes blocking.
    if (inner_->result_available_render_thread(q)) ++blocking_;
    if (latency_.microseconds > 0.0 && frame_ - i.frame >= latency_.frames) {
      const auto due = i.time + std::chrono::duration_cast<Clock::duration>(
                                    std::chrono::duration<double, std::micro>(latency_.microseconds));
      const auto t0 = Clock::now();
      std::this_thread::sleep_until(due);
      wait_ms_ += std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
    }
    completed_ = std::max(completed_, i.sequence);
  }
  return inner_->result_render_thread(q);
}

void LatentOcclusionDevice::draw_render_thread(BlockId b) {
  inner_->draw_render_thread(b);
}

void LatentOcclusionDevice::end_frame_render_thread(bool finish) {
  inner_->end_frame_render_thread(finish);
}

const DeviceFrameStats& LatentOcclusionDevice::frame_stats() const {
  stats_ = inner_->frame_stats();
  stats_.blocking_reads += blocking_;
  stats_.wait_ms += wait_ms_;
  return stats_;
}

}  // namespace treecut::culling
