#include "treecut/splat/frame_rate.hpp"

#include <algorithm>
#include <cmath>

namespace treecut::splat {
namespace {

// Forgetting factor of the fit: about the last 10 frames count, so a change
// of the machine's load or of the view is learnt within a fraction of a second.
constexpr double kForget = 0.9;
// The slope is fitted over a longer window (about 20 frames): the cost per
// splat is the renderer's, it changes slowly, and noise averages out.
constexpr double kForgetSlope = 0.95;
// The fixed cost is taken to be at most this share of the recent frame time.
constexpr double kMaxFixedShare = 0.75;
// The splat counts must spread by 5 % (standard deviation over the mean)
// before a slope is fitted; below that the last fitted line is kept (scaled).
constexpr double kMinSpread = 0.05;
// A frame slower than 1.5 times the model's prediction counts as 1.5 times:
// one hiccup (a page fault, another process) moves the model by a bounded
// amount, a lasting slowdown still shows within a few frames.
constexpr double kMaxResidual = 1.5;
// Anti-windup: a budget is at most the drawn cut times kGrowth, or the cut
// plus a sixteenth of the hierarchy (so a small cut can grow quickly), and at
// most the node count.
constexpr double kGrowth = 1.25;
constexpr double kGrowthNodes = 1.0 / 16.0;
// Slow frames set a budget of at least this fraction of the drawn cut.
constexpr double kMaxDrop = 0.5;
// Changes below 3 % are not sent: frame-time noise must not keep the stage busy.
constexpr double kDeadband = 0.03;
// A threshold moves by at most this factor per change (the 1/size^2 law is
// only a rough guide; 1.4 took 50 frames at 200 ms from the recursive
// strategy's default on the dragon).
constexpr double kMaxThresholdStep = 2.0;
// A threshold moves again the same way without an answer from the cut after
// kPatience frames (or twice the frames the cut took to answer before), at
// most kMaxBlind times in a row (2^8: a factor 256, enough to cross from a
// default to where a close view's cut responds; a reversal undoes blind steps
// at once, so they cost no wind-up).
constexpr int kPatience = 6;
constexpr int kMaxBlind = 8;
// A threshold of 0 could never grow multiplicatively: keep it off zero.
constexpr double kMinThreshold = 1e-3;

}  // namespace

std::optional<FrameRateGovernor> FrameRateGovernor::for_params(std::span<const ParamSpec> specs,
                                                               double current_value,
                                                               std::size_t node_count,
                                                               double floor_splats) {
  for (const auto& [name, knob] :
       {std::pair{"max_nodes", Knob::Budget}, std::pair{"min_size", Knob::Threshold}}) {
    for (const ParamSpec& s : specs) {
      if (s.name == name) {
        return FrameRateGovernor(s.name, knob, current_value, s.min_value, s.max_value, node_count,
                                 floor_splats);
      }
    }
  }
  return std::nullopt;
}

std::optional<FrameRateGovernor> FrameRateGovernor::for_strategy(const Strategy& strategy,
                                                                 std::size_t node_count,
                                                                 double floor_splats) {
  auto g = for_params(strategy.param_specs(), 0.0, node_count, floor_splats);
  if (g) g->value_ = g->sent_ = g->anchor_ = strategy.param(g->param_);
  return g;
}

FrameRateGovernor::FrameRateGovernor(std::string param, Knob knob, double value, double min_value,
                                     double max_value, std::size_t node_count, double floor_splats)
    : param_(std::move(param)),
      knob_(knob),
      value_(value),
      min_value_(min_value),
      max_value_(max_value),
      node_count_(std::max<double>(1.0, static_cast<double>(node_count))),
      floor_(std::clamp(floor_splats, 1.0, node_count_)),
      sent_(value),
      anchor_(value) {}

void FrameRateGovernor::Moments::add(double x, double y, double forget) {
  // Weighted incremental means and co-moments (West 1979) with exponential
  // forgetting: the old weights shrink by `forget`, the new sample weighs 1.
  weight = forget * weight + 1.0;
  const double dx = x - mean_x;
  mean_x += dx / weight;
  mean_y += (y - mean_y) / weight;
  cxx = forget * cxx + dx * (x - mean_x);
  cxy = forget * cxy + dx * (y - mean_y);
}

void FrameRateGovernor::fit(double frame_ms, double splats) {
  if (slope_fitted_) {
    frame_ms = std::min(frame_ms, kMaxResidual * (fixed_ms_ + per_splat_ms_ * splats));
  }
  recent_.add(splats, frame_ms, kForget);
  slope_window_.add(splats, frame_ms, kForgetSlope);
  // The line through the origin (QSplat's ratio rule) as a reference.
  const double ratio = recent_.mean_y / recent_.mean_x;
  const double spread = kMinSpread * slope_window_.mean_x;
  bool fitted_now = false;
  if (slope_window_.weight > 2.0 && slope_window_.cxx / slope_window_.weight > spread * spread) {
    const double slope = slope_window_.cxy / slope_window_.cxx;
    // slope <= 0 (the frame time rose while the cut shrank: the load changed,
    // not the cost per splat): keep the last line, scaled below.
    if (slope > 0.0) {
      per_splat_ms_ = slope;
      slope_fitted_ = fitted_now = true;
    }
  }
  if (!slope_fitted_) {  // no spread yet: the ratio rule
    per_splat_ms_ = ratio;
    fixed_ms_ = 0.0;
    return;
  }
  if (!fitted_now) {
    // No new slope: the last line, scaled through the recent mean, so a change
    // of speed shows at once. Scaled, not shifted: a loaded machine is slower
    // at everything, and a fixed cost shifted up by a slow burst could pass
    // the target and ask for the coarsest cut (measured on the dragon at a
    // load average of 8).
    const double predicted = fixed_ms_ + per_splat_ms_ * recent_.mean_x;
    if (predicted > 0.0) per_splat_ms_ *= recent_.mean_y / predicted;
  }
  // The fixed cost between 0 and kMaxFixedShare of the recent frame time: a
  // slope fitted from noise (0.045 us/splat against 0.3 measured alone, at a
  // load average of 7) would otherwise promise a splat count far off.
  per_splat_ms_ = std::clamp(per_splat_ms_, (1.0 - kMaxFixedShare) * ratio, ratio);
  // The line passes through the recent mean.
  fixed_ms_ = recent_.mean_y - per_splat_ms_ * recent_.mean_x;
}

std::optional<double> FrameRateGovernor::update(double frame_ms, std::size_t splats,
                                                double target_fps) {
  if (!(frame_ms > 0.0) || !std::isfinite(frame_ms)) return std::nullopt;
  const double x = std::max<double>(1.0, static_cast<double>(splats));
  // The first frame compiles shaders and uploads buffers: it says nothing
  // about the cost of the next ones (275 ms for one splat on llvmpipe).
  const bool learnt = frames_++ > 0;
  if (learnt) {
    smoothed_ms_ = smoothed_ms_ > 0.0 ? 0.8 * smoothed_ms_ + 0.2 * frame_ms : frame_ms;
    fit(frame_ms, x);
  }
  if (!(target_fps > 0.0) || !std::isfinite(target_fps)) {
    wanted_ = 0.0;
    return std::nullopt;
  }
  const double target_ms = 1000.0 / target_fps;
  // The budget never exceeds what the strategy can use: the cut it drew,
  // grown, and at most the node count (also before the model knows anything).
  const double cap = std::min(node_count_, std::max(x * kGrowth, x + kGrowthNodes * node_count_));
  double v = value_;
  if (!learnt) {
    if (knob_ == Knob::Threshold) return std::nullopt;
    v = std::min(v, cap);
  } else {
    // The model's answer; a fixed cost alone above the target asks for the
    // floor.
    wanted_ = target_ms > fixed_ms_ ? (target_ms - fixed_ms_) / per_splat_ms_ : 1.0;
    const bool fast = wanted_ > x;  // before the clamp: at full detail fast frames stay fast
    wanted_ = std::clamp(wanted_, floor_, node_count_);
    // Detail is taken away once a slope was fitted, or by the ratio rule from
    // a cut of a sixteenth of the hierarchy up. A slow frame of a smaller cut
    // says nothing about the cost of a splat: the viewer's first frames draw
    // 16 splats in 30 ms, and the ratio rule set the budget to 1.
    const bool may_coarsen = (slope_fitted_ || x >= kGrowthNodes * node_count_) && x > floor_;
    if (knob_ == Knob::Budget) {
      // Fast frames never lower the budget and slow ones never raise it (a
      // budget the cut has not reached yet is not taken away while frames are
      // fast), within the cap. Slow frames take at most half of the drawn cut
      // away per answer of the stage: a burst of load passes without a
      // collapse to the root.
      const double slow = may_coarsen ? std::min(value_, std::max(wanted_, kMaxDrop * x)) : value_;
      v = std::min(fast ? std::max(wanted_, value_) : slow, cap);
    } else if (fast || may_coarsen) {
      v = threshold_for(x);
    }
  }
  if (knob_ == Knob::Budget) {
    v = std::round(std::clamp(std::max(v, floor_), std::max(min_value_, 1.0), max_value_));
  }
  if (std::abs(v - sent_) <= kDeadband * std::max(std::abs(sent_), 1e-9)) return std::nullopt;
  if (knob_ == Knob::Threshold) {
    const int move = v > sent_ ? 1 : -1;
    blind_ = move == last_move_ && !answered_ ? blind_ + 1 : 0;
    last_move_ = move;
    answered_ = false;
    splats_at_move_ = x;
    frames_since_move_ = 0;
  }
  value_ = sent_ = v;
  return v;
}

double FrameRateGovernor::threshold_for(double x) {
  ++frames_since_move_;
  // Did the cut answer the last move (by 2 % the expected way)? Then the value
  // in effect is one the strategy responds to: the anchor of anti-windup.
  if (last_move_ != 0 && !answered_ &&
      (last_move_ > 0 ? x <= 0.98 * splats_at_move_ : x >= 1.02 * splats_at_move_)) {
    answered_ = true;
    anchor_ = value_;
    // How long the stage takes to answer: blind steps wait twice as long.
    lag_ = std::max(0.9 * lag_, static_cast<double>(frames_since_move_));
  }
  // splats ~ 1 / threshold^2: the factor that turns x into wanted_.
  const double ratio =
      std::clamp(std::sqrt(x / wanted_), 1.0 / kMaxThresholdStep, kMaxThresholdStep);
  const int move = ratio > 1.0 ? 1 : (ratio < 1.0 ? -1 : 0);
  double from = std::max(value_, kMinThreshold);
  if (move != 0 && move == last_move_ && !answered_) {
    // The cut follows a threshold frames later: a second move the same way
    // waits for the answer to the first. Without one for kPatience frames the
    // knob is in a range that changes nothing (full detail, the coarsest
    // cut) or the stage is slow; a few more blind steps find out, no more.
    const double patience = std::max<double>(kPatience, 2.0 * lag_);
    if (frames_since_move_ < patience || blind_ >= kMaxBlind) return value_;
  } else if (move != 0 && move == -last_move_ && blind_ > 0) {
    // Reversing after blind steps: they changed nothing, so start from the
    // last value the cut answered to (back-calculation: no wound-up distance
    // to travel back first).
    from = std::max(anchor_, kMinThreshold);
  }
  return std::clamp(from * ratio, std::max(min_value_, kMinThreshold), max_value_);
}

}  // namespace treecut::splat
