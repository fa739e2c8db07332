// treecut view: the HUD's summary, the few lines shown while its sections
// are closed, and the status line under them. Apart from the Viewer so that
// a test can draw them in a headless Dear ImGui frame and time the status
// line with its own clock.
#pragma once

#include <string>
#include <utility>

namespace treecut::cli {

/// The HUD's width in pixels while its sections are closed: the summary's
/// lines wrap within it rather than being cut at its edge.
inline constexpr float kHudWidth = 300.0f;

/// A message for the user ("saved first_hud.png", "view 3 saved in ..."):
/// shown for kSeconds after it was said, then gone, so that an old message
/// is never taken for news. Said again, even in the same words, it shows again.
class StatusLine {
 public:
  static constexpr double kSeconds = 6.0;

  /// TEXT said at NOW (seconds on any clock that only goes forward).
  void say(std::string text, double now) {
    text_ = std::move(text);
    since_ = now;
  }
  void clear() { text_.clear(); }
  /// What to show at NOW: the text while it is fresh, else "".
  [[nodiscard]] const std::string& shown(double now) const {
    static const std::string kNone;
    return now - since_ < kSeconds ? text_ : kNone;
  }

 private:
  std::string text_;
  double since_ = 0.0;
};

/// What the summary says, taken from the viewer in one frame.
struct HudSummary {
  std::string label;  ///< the model or scene
  double frame_ms = 0.0;
  double splats = 0.0;  ///< drawn this frame
  double points = 0.0;  ///< the points those splats stand for
  double total = 0.0;   ///< the model's (or the scene's instanced) points
  bool converged = false;
  double iteration_ms = 0.0;  ///< the strategy's last iteration, while refining
  double holding_fps = 0.0;   ///< the frame-rate control's target; 0: off
  double budget = 0.0;        ///< the budget it holds that rate with
  std::string budget_param;   ///< the parameter that budget is
};

/// Begins the HUD's window at the top left, kHudWidth wide while its
/// sections are closed (OPEN: as wide as they need). End it with ImGui::End.
void begin_hud_window(bool open);

/// Draws the summary's lines in the current window, each wrapped at its width.
void draw_hud_summary(const HudSummary& s);

}  // namespace treecut::cli
