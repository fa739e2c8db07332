// Target-frame-rate control (QSplat's "desired frame rate" loop, Rusinkiewicz
// & Levoy 2000, section 4.2): after each frame the LOD knob of the strategy is
// scaled by the ratio of the target to the measured frame time, so the viewer
// settles on the detail it can draw at the chosen rate. A budget knob (more =
// slower, e.g. optimization's max_nodes) is multiplied by target/measured, a
// threshold knob (more = faster, e.g. recursive's min_size) by its inverse.
// The step is clamped and the frame time smoothed, so one slow frame does not
// halve the detail. Plain logic, no GL; render thread.
#pragma once

#include <optional>
#include <span>
#include <string>

#include "treecut/strategy.hpp"

namespace treecut::splat {

class FrameRateGovernor {
 public:
  enum class Knob { Budget, Threshold };

  /// Picks the strategy's knob from its parameters: "max_nodes" (budget) or
  /// "min_size" (threshold). nullopt when the strategy has neither.
  static std::optional<FrameRateGovernor> for_params(std::span<const ParamSpec> specs,
                                                     double current_value);

  FrameRateGovernor(std::string param, Knob knob, double value, double min_value, double max_value);

  /// Feeds one measured frame time (ms) and returns the new knob value when it
  /// changed by more than 2 % (the caller forwards it with set_param).
  /// target_fps <= 0 disables the control.
  std::optional<double> update(double frame_ms, double target_fps);

  [[nodiscard]] const std::string& param() const { return param_; }
  [[nodiscard]] Knob knob() const { return knob_; }
  [[nodiscard]] double value() const { return value_; }
  [[nodiscard]] double smoothed_ms() const { return smoothed_ms_; }

 private:
  std::string param_;
  Knob knob_;
  double value_;
  double min_value_;
  double max_value_;
  double smoothed_ms_ = 0.0;
  double sent_ = 0.0;
};

}  // namespace treecut::splat
