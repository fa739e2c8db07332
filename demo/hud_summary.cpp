#include "hud_summary.hpp"

#include <imgui.h>

#include <cfloat>
#include <cstdio>

namespace treecut::cli {

namespace {

// 1234 -> "1234", 56789 -> "56.8 k", 1.5e6 -> "1.50 M": the HUD's point counts.
std::string compact(double v) {
  char text[32];
  if (v >= 1e9) {
    std::snprintf(text, sizeof text, "%.2f G", v * 1e-9);
  } else if (v >= 1e6) {
    std::snprintf(text, sizeof text, "%.2f M", v * 1e-6);
  } else if (v >= 1e4) {
    std::snprintf(text, sizeof text, "%.1f k", v * 1e-3);
  } else {
    std::snprintf(text, sizeof text, "%.0f", v);
  }
  return text;
}

}  // namespace

// Out of the way (issue 30): the top-left corner, a summary of a few lines,
// and every section closed until opened.
void begin_hud_window(bool open) {
  ImGui::SetNextWindowPos(ImVec2(8, 8), ImGuiCond_FirstUseEver);
  ImGui::SetNextWindowBgAlpha(0.6f);
  // As narrow as the summary while the sections are closed (long lines wrap
  // rather than widen it); as wide as they need once opened.
  ImGui::SetNextWindowSizeConstraints(ImVec2(kHudWidth, 0.0f),
                                      ImVec2(open ? FLT_MAX : kHudWidth, FLT_MAX));
  ImGui::Begin("treecut", nullptr, ImGuiWindowFlags_AlwaysAutoResize);
}

void draw_hud_summary(const HudSummary& s) {
  // Every line wraps at the window's width rather than being cut at its
  // edge (issue 43, item 18: "20.0 k splats for 110.0 k of 110.0 k poin").
  ImGui::TextWrapped("%s", s.label.c_str());
  ImGui::Text("%.1f fps  %.1f ms", s.frame_ms > 0 ? 1000.0 / s.frame_ms : 0.0, s.frame_ms);
  ImGui::SameLine();
  ImGui::TextDisabled("(H hides this)");
  ImGui::TextWrapped("%s splats for %s of %s points", compact(s.splats).c_str(),
                     compact(s.points).c_str(), compact(s.total).c_str());
  if (s.converged) {
    ImGui::TextUnformatted("converged");
  } else {
    ImGui::Text("refining (iteration %.1f ms)", s.iteration_ms);
  }
  if (s.holding_fps > 0.0) {
    // The frame-rate control: what budget holds the rate on this machine.
    ImGui::PushStyleColor(ImGuiCol_Text, ImGui::GetStyle().Colors[ImGuiCol_TextDisabled]);
    ImGui::TextWrapped("holding %.0f fps: %s %s", s.holding_fps, compact(s.budget).c_str(),
                       s.budget_param.c_str());
    ImGui::PopStyleColor();
  }
}

}  // namespace treecut::cli
