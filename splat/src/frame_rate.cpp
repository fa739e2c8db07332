#include "treecut/splat/frame_rate.hpp"

#include <algorithm>
#include <cmath>

namespace treecut::splat {

std::optional<FrameRateGovernor> FrameRateGovernor::for_params(std::span<const ParamSpec> specs,
                                                               double current_value) {
  for (const auto& [name, knob] :
       {std::pair{"max_nodes", Knob::Budget}, std::pair{"min_size", Knob::Threshold}}) {
    for (const ParamSpec& s : specs) {
      if (s.name == name) {
        return FrameRateGovernor(s.name, knob, current_value, s.min_value, s.max_value);
      }
    }
  }
  return std::nullopt;
}

FrameRateGovernor::FrameRateGovernor(std::string param, Knob knob, double value, double min_value,
                                     double max_value)
    : param_(std::move(param)),
      knob_(knob),
      value_(value),
      min_value_(min_value),
      max_value_(max_value),
      sent_(value) {}

std::optional<double> FrameRateGovernor::update(double frame_ms, double target_fps) {
  if (!(frame_ms > 0.0) || !std::isfinite(frame_ms)) return std::nullopt;
  smoothed_ms_ = smoothed_ms_ > 0.0 ? 0.8 * smoothed_ms_ + 0.2 * frame_ms : frame_ms;
  if (target_fps <= 0.0) return std::nullopt;
  const double target_ms = 1000.0 / target_fps;
  // Clamped so a single frame never moves the knob by more than 10 %.
  const double ratio = std::clamp(target_ms / smoothed_ms_, 0.9, 1.1);
  value_ *= knob_ == Knob::Budget ? ratio : 1.0 / ratio;
  // A threshold of 0 could never grow multiplicatively: keep it off zero.
  value_ =
      std::clamp(value_, std::max(min_value_, knob_ == Knob::Threshold ? 1e-3 : 1.0), max_value_);
  if (knob_ == Knob::Budget) value_ = std::round(value_);
  if (std::abs(value_ - sent_) <= 0.02 * std::max(std::abs(sent_), 1e-9)) return std::nullopt;
  sent_ = value_;
  return value_;
}

}  // namespace treecut::splat
