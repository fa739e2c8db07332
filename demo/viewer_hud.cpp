// treecut view: the HUD (Dear ImGui): frame times, the stage's counters, the
// strategy and its parameters, rendering settings, models and loading.
#include <imgui.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <vector>

#include "viewer_app.hpp"

namespace treecut::cli {

void Viewer::hud(const splat::FrameStats& stats) {
  ImGui::SetNextWindowPos(ImVec2(10, 10), ImGuiCond_FirstUseEver);
  ImGui::SetNextWindowBgAlpha(0.8f);
  ImGui::Begin("treecut", nullptr, ImGuiWindowFlags_AlwaysAutoResize);
  const StageCounters& c = controller_->stage().counters();
  ImGui::Text("%s", scene_.label.c_str());
  if (scene_.world) {
    ImGui::Text("scene: %zu objects of %zu models, %zu draw calls", scene_.world->objects.size(),
                scene_.world->models.size(), stats.draw_calls);
  }
  models_panel();
  if (scene_.up_axis.reason.empty()) {
    ImGui::Text("up %s  (U: next axis)", scene_.up_axis.name().c_str());
  } else {
    ImGui::Text("up %s (auto: %s)  (U: next axis)", scene_.up_axis.name().c_str(),
                scene_.up_axis.reason.c_str());
  }
  ImGui::Text("%.1f fps  %.2f ms/frame  (draw %.2f ms)", frame_ms_ > 0 ? 1000.0 / frame_ms_ : 0.0,
              frame_ms_, draw_ms_);
  std::vector<float> times(frame_times_.begin(), frame_times_.end());
  ImGui::PlotLines("##frametimes", times.data(), static_cast<int>(times.size()), 0,
                   "frame time (ms)", 0.0f, 100.0f, ImVec2(300, 60));
  ImGui::Text("%zu splats drawn, %llu points represented", stats.splats,
              static_cast<unsigned long long>(stats.points));
  ImGui::Text("iteration %.2f ms, %llu iterations, %llu exchanges", c.iteration_ns_last * 1e-6,
              static_cast<unsigned long long>(c.iterations),
              static_cast<unsigned long long>(c.exchanges));
  ImGui::Text("converged: %s", c.converged ? "yes" : "no");
  // Whatever else the strategy measured in its last iteration, by name
  // (treecut/counters.hpp): the HUD needs to know no strategy.
  for (const Counter& counter : c.last.counters.items()) {
    ImGui::Text("%.*s %.6g %.*s", static_cast<int>(counter.name().size()), counter.name().data(),
                counter.value, static_cast<int>(counter.unit().size()), counter.unit().data());
  }
  if (const splat::QueryStats& q = queries_->stats(); q.issued > 0 || q.queued > 0) {
    // The strategy's GPU queries: what is waiting, and how late answers come.
    ImGui::Text("queries: %llu issued, %llu answered (%llu occluded), %zu pending, %zu queued",
                static_cast<unsigned long long>(q.issued),
                static_cast<unsigned long long>(q.answered),
                static_cast<unsigned long long>(q.occluded), q.pending, q.queued);
    ImGui::Text("query latency %.1f frames (max %llu), %.3f ms/frame", q.latency_frames_mean(),
                static_cast<unsigned long long>(q.latency_frames_max), q.cpu_ns_last * 1e-6);
  }
  if (!ImGui::CollapsingHeader("strategy", ImGuiTreeNodeFlags_DefaultOpen)) {
    rendering_panel();
    ImGui::End();
    return;
  }
  if (ImGui::BeginCombo("##strategy", strategy_.c_str())) {
    for (const std::string& n : strategy_names_) {
      if (ImGui::Selectable(n.c_str(), n == strategy_) && n != strategy_) switch_strategy(n);
    }
    ImGui::EndCombo();
  }
  for (auto& p : params_) {
    double v = p.value;
    bool changed = false;
    if (p.spec.integer) {
      int iv = static_cast<int>(std::clamp(v, -2e9, 2e9));
      changed = ImGui::DragInt(p.spec.name.c_str(), &iv, std::max(1.0f, float(std::abs(v)) * 0.01f),
                               static_cast<int>(std::max(p.spec.min_value, -2e9)),
                               static_cast<int>(std::min(p.spec.max_value, 2e9)));
      v = iv;
    } else {
      float fv = static_cast<float>(v);
      changed = ImGui::DragFloat(p.spec.name.c_str(), &fv, 0.01f, float(p.spec.min_value),
                                 float(p.spec.max_value));
      v = fv;
    }
    if (ImGui::IsItemHovered()) ImGui::SetTooltip("%s", p.spec.description.c_str());
    if (changed && check_param(p.spec, v).empty()) {
      p.value = v;
      controller_->set_param(p.spec.name, v);
    }
  }
  ImGui::Separator();
  bool target = target_fps_ > 0.0;
  if (governor_) {
    if (ImGui::Checkbox("hold frame rate", &target)) target_fps_ = target ? chosen_fps_ : 0.0;
    if (target) {
      float f = static_cast<float>(chosen_fps_);
      if (ImGui::SliderFloat("target fps", &f, 1.0f, 120.0f)) target_fps_ = chosen_fps_ = f;
      ImGui::Text("adapting %s = %.4g (smoothed %.1f ms)", governor_->param().c_str(),
                  governor_->value(), governor_->smoothed_ms());
      ImGui::Text("model %.2f ms + %.3g us/splat: %.0f splats", governor_->fixed_ms(),
                  governor_->per_splat_ms() * 1e3, governor_->wanted_splats());
    }
  } else {
    ImGui::TextDisabled("hold frame rate: strategy has no budget/threshold");
  }
  rendering_panel();
  ImGui::End();
}

// Another model: a load in progress, the last failure, the "open" field.
void Viewer::models_panel() {
  if (const std::optional<LoadProgress> p = loader_.progress()) {
    const std::string name =
        p->file.empty() ? "generated model" : std::filesystem::path(p->file).filename().string();
    if (p->total > 1) {
      ImGui::Text("loading %s: %s %3.0f %%", name.c_str(), p->stage.c_str(),
                  100.0 * double(p->done) / double(p->total));
    } else {
      ImGui::Text("loading %s: %s ...", name.c_str(), p->stage.empty() ? "open" : p->stage.c_str());
    }
  } else if (incoming_) {
    ImGui::Text("switching to %s ...", incoming_->label.c_str());
  }
  if (!load_error_.empty())
    ImGui::TextColored(ImVec4(1.0f, 0.45f, 0.4f, 1.0f), "%s", load_error_.c_str());
  ImGui::SetNextItemWidth(260.0f);
  if (ImGui::InputTextWithHint("##open", "PLY or .tch (or drop one on the window)", open_field_,
                               sizeof open_field_, ImGuiInputTextFlags_EnterReturnsTrue) &&
      open_field_[0] != '\0') {
    open_model(open_field_);
  }
  ImGui::SameLine();
  if (ImGui::Button("open") && open_field_[0] != '\0') open_model(open_field_);
  if (models_.size() > 1) {
    ImGui::SameLine();
    if (ImGui::Button("next (O)")) {
      model_index_ = (model_index_ + 1) % models_.size();
      open_model(models_[model_index_]);
    }
  }
}

// Colour by RGB, elevation or an attribute, with its legend: a gradient
// with its end values, or the categories with their share of the points
// (classification's with a box each to hide the class).
void Viewer::color_panel() {
  if (!ImGui::CollapsingHeader("colour")) return;
  std::vector<std::string> sources = {"rgb", "elevation"};
  if (scene_.hierarchy) {
    for (const NodeAttribute& a : scene_.hierarchy->attributes()) sources.push_back(a.name);
  }
  if (ImGui::BeginCombo("colour by", color_by_.source.c_str())) {
    for (const std::string& s : sources) {
      if (ImGui::Selectable(s.c_str(), s == color_by_.source) && s != color_by_.source) {
        color_by_.source = s;
        color_by_.low.reset();
        color_by_.high.reset();
        recolor();
      }
    }
    ImGui::EndCombo();
  }
  if (legend_.title == "rgb") return;
  ImDrawList* draw = ImGui::GetWindowDrawList();
  if (legend_.continuous) {
    const ImVec2 at = ImGui::GetCursorScreenPos();
    constexpr int kSteps = 32;
    constexpr float kWidth = 240.0f, kHeight = 14.0f;
    for (int i = 0; i < kSteps; ++i) {
      const glm::u8vec4 c = splat::map_color(legend_.map, (float(i) + 0.5f) / kSteps);
      draw->AddRectFilled(ImVec2(at.x + kWidth * float(i) / kSteps, at.y),
                          ImVec2(at.x + kWidth * float(i + 1) / kSteps, at.y + kHeight),
                          IM_COL32(c.x, c.y, c.z, 255));
    }
    ImGui::Dummy(ImVec2(kWidth, kHeight));
    ImGui::Text("%-12.6g %28.6g", legend_.low, legend_.high);
    return;
  }
  const bool classes = legend_.title == "classification";
  for (const splat::Legend::Entry& e : legend_.entries) {
    const ImVec2 at = ImGui::GetCursorScreenPos();
    draw->AddRectFilled(at, ImVec2(at.x + 12, at.y + 12),
                        IM_COL32(e.color.x, e.color.y, e.color.z, 255));
    ImGui::Dummy(ImVec2(14, 12));
    ImGui::SameLine();
    if (classes && !std::isnan(e.value)) {
      bool shown = !e.hidden;
      const std::string label =
          e.label + "  " + std::to_string(int(std::lround(100 * e.share))) + " %";
      if (ImGui::Checkbox(label.c_str(), &shown)) {
        // The HUD speaks in classes to hide.
        std::vector<int> hidden;
        for (const splat::Legend::Entry& o : legend_.entries) {
          const bool hide = &o == &e ? !shown : o.hidden;
          if (hide && !std::isnan(o.value)) hidden.push_back(static_cast<int>(o.value));
        }
        color_by_.show_classes.clear();
        color_by_.hide_classes = hidden;
        recolor();
        return;  // the legend was replaced
      }
    } else {
      ImGui::Text("%s  %.0f %%", e.label.c_str(), 100.0 * e.share);
    }
  }
}

void Viewer::rendering_panel() {
  color_panel();
  if (!ImGui::CollapsingHeader("rendering")) {
    if (!status_.empty()) ImGui::TextUnformatted(status_.c_str());
    return;
  }
  int mode = static_cast<int>(settings_.mode);
  ImGui::RadioButton("fast", &mode, 0);
  ImGui::SameLine();
  ImGui::RadioButton("high quality", &mode, 1);
  ImGui::SameLine();
  ImGui::RadioButton("fixed", &mode, 2);
  settings_.mode = static_cast<splat::SplatMode>(mode);
  ImGui::SliderFloat("radius scale", &settings_.radius_scale, 0.25f, 4.0f);
  if (settings_.mode == splat::SplatMode::FixedSize) {
    ImGui::SliderFloat("point size", &settings_.point_size_px, 1.0f, 16.0f);
  }
  ImGui::Checkbox("light follows camera", &settings_.light.follow_camera);
  // Fades of an exchange (--blend N): the stage holds the next list until one ends.
  int blend = static_cast<int>(controller_->stage().blend_frames());
  bool fades = blend > 0;
  if (ImGui::Checkbox("fade exchanges", &fades)) {
    controller_->stage().set_blend_frames(fades ? 8u : 0u);
  }
  if (fades && ImGui::SliderInt("fade frames", &blend, 1, 32)) {
    controller_->stage().set_blend_frames(static_cast<unsigned>(blend));
  }
  ImGui::Checkbox("fly camera (Tab)", &fly_);
  if (ImGui::Button("fit (F)")) fit();
  ImGui::SameLine();
  if (ImGui::Button("screenshot (F12)")) pending_screenshot_ = next_name("png");
  ImGui::SameLine();
  if (ImGui::Button(recording_ ? "stop recording (R)" : "record path (R)")) toggle_recording();
  ImGui::SameLine();
  if (!path_.empty() && ImGui::Button("play (Space)")) start_playback();
  if (!status_.empty()) ImGui::TextUnformatted(status_.c_str());
}

}  // namespace treecut::cli
