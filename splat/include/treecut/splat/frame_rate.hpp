// Target-frame-rate control (QSplat's "desired frame rate" loop, Rusinkiewicz
// & Levoy 2000, section 4.2), with a model of the loop instead of QSplat's
// bare ratio rule. The frame time is modelled as
//
//     frame_ms ~ fixed_ms + per_splat_ms * splats
//
// fitted online from the (splats drawn, frame time) pairs of the last frames
// (least squares with exponential forgetting). The splat count that meets the
// target follows from the model, and the knob is set to deliver it: a budget
// knob (more = slower, e.g. optimization's max_nodes) to that count, a
// threshold knob (more = faster, e.g. recursive's min_size) through
// splats ~ 1 / threshold^2 (the nodes of a surface above a projected size).
//
// Why a model and not "scale the knob by target/measured every frame": the
// cut follows the knob only after the stage ran (frames later), so a ratio
// applied every frame integrates the same error again and again (wind-up: the
// budget grew to 22 times the node count while the cut could not follow). A
// set point from the model does not integrate. Anti-windup on top: a budget is
// never set past what the strategy showed it can use (the drawn cut times a
// growth factor, plus a step, and at most the node count), a threshold moves
// again in the same direction only after the cut answered the last move, fast
// frames never take detail away and slow frames never add it.
//
// Plain logic, no GL; render thread.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string>

#include "treecut/strategy.hpp"

namespace treecut::splat {

class FrameRateGovernor {
 public:
  enum class Knob { Budget, Threshold };

  /// By default detail is never taken below this many splats (or the
  /// hierarchy's node count, if fewer): a cut that small is already a rough
  /// picture, and what still makes the frame slow is not the splats but the
  /// fixed cost (the passes, eye-dome lighting; llvmpipe at 1280x720: 37 ms
  /// for 100 splats). Without it a target out of reach ran the cut down to
  /// the root. The viewer opens at a cut of this size too.
  static constexpr double kFloorSplats = 20000.0;

  /// Picks the strategy's knob from its parameters: "max_nodes" (budget) or
  /// "min_size" (threshold). nullopt when the strategy has neither.
  /// `node_count` is the hierarchy's: no budget is ever set above it.
  static std::optional<FrameRateGovernor> for_params(std::span<const ParamSpec> specs,
                                                     double current_value, std::size_t node_count,
                                                     double floor_splats = kFloorSplats);

  /// The same for a strategy, from its current knob value (call it before the
  /// strategy is handed to a stage). The viewer and `treecut render` use this.
  static std::optional<FrameRateGovernor> for_strategy(const Strategy& strategy,
                                                       std::size_t node_count,
                                                       double floor_splats = kFloorSplats);

  FrameRateGovernor(std::string param, Knob knob, double value, double min_value, double max_value,
                    std::size_t node_count, double floor_splats = kFloorSplats);

  /// Feeds one frame: its time (ms) and the splats it drew (the cut size).
  /// Returns the new knob value when it changed by more than 3 % (the caller
  /// forwards it with set_param). target_fps <= 0 disables the control (the
  /// model keeps learning). Non-finite or non-positive times are ignored, and
  /// so is the first frame (shader compilation, uploads).
  std::optional<double> update(double frame_ms, std::size_t splats, double target_fps);

  [[nodiscard]] const std::string& param() const { return param_; }
  [[nodiscard]] Knob knob() const { return knob_; }
  [[nodiscard]] double value() const { return value_; }
  /// Exponential average of the frame times (for the HUD).
  [[nodiscard]] double smoothed_ms() const { return smoothed_ms_; }
  /// The model's fixed cost and cost per splat (0 before the first frame).
  [[nodiscard]] double fixed_ms() const { return fixed_ms_; }
  [[nodiscard]] double per_splat_ms() const { return per_splat_ms_; }
  /// The splat count the model predicts for the target (0 before a target).
  [[nodiscard]] double wanted_splats() const { return wanted_; }

 private:
  void fit(double frame_ms, double splats);
  double threshold_for(double splats);

  std::string param_;
  Knob knob_;
  double value_;
  double min_value_;
  double max_value_;
  double node_count_;
  double floor_;  // min(floor_splats, node count): no coarser than this
  double sent_;
  double anchor_;
  double smoothed_ms_ = 0.0;
  std::uint64_t frames_ = 0;
  // Exponentially weighted means and co-moments of (splats, frame time).
  struct Moments {
    double weight = 0.0;
    double mean_x = 0.0;
    double mean_y = 0.0;
    double cxx = 0.0;
    double cxy = 0.0;
    void add(double x, double y, double forget);
  };
  Moments recent_;             // about 10 frames: where the line passes
  Moments slope_window_;       // about 20 frames: its slope
  bool slope_fitted_ = false;  // per_splat_ms_ comes from a fit, not the ratio guess
  double fixed_ms_ = 0.0;
  double per_splat_ms_ = 0.0;
  double wanted_ = 0.0;
  // Threshold knob: the last move's direction, the cut size when it was made,
  // whether the cut answered it, frames since, consecutive moves the same way
  // without an answer; anchor_ is the value of the last answered move.
  int last_move_ = 0;
  double splats_at_move_ = 0.0;
  bool answered_ = false;
  int frames_since_move_ = 0;
  int blind_ = 0;
  double lag_ = 0.0;  // frames the cut took to answer a move (decaying maximum)
};

}  // namespace treecut::splat
