// treecut view: the HUD (Dear ImGui): frame times, the stage's counters, the
// strategy and its parameters, rendering settings, models and loading.
#include <imgui.h>

#include <algorithm>
#include <cfloat>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <string>
#include <utility>
#include <vector>

#include "hud_summary.hpp"
#include "ticks.hpp"
#include "viewer_app.hpp"

namespace treecut::cli {

// The summary (hud_summary.cpp), the load's progress, the status line and
// the sections, every one closed until opened; H (or a script's `hud off`)
// hides it, and screenshots leave it out unless asked (Shift+F12).
void Viewer::hud(const splat::FrameStats& stats) {
  begin_hud_window(hud_open_);
  const StageCounters& c = controller_->stage().counters();
  HudSummary summary;
  summary.label = scene_.label;
  summary.frame_ms = frame_ms_;
  summary.splats = double(stats.splats);
  summary.points = double(stats.points);
  summary.total = scene_.world       ? double(scene_.instanced_points)
                  : scene_.hierarchy ? double(scene_.hierarchy->leaf_count())
                                     : 0.0;
  summary.converged = c.converged;
  summary.iteration_ms = c.iteration_ns_last * 1e-6;
  if (governor_ && target_fps_ > 0.0) {
    summary.holding_fps = target_fps_;
    summary.budget = governor_->value();
    summary.budget_param = governor_->param();
  }
  draw_hud_summary(summary);
  load_progress();
  if (const std::string& said = status_.shown(glfwGetTime()); !said.empty())
    ImGui::TextWrapped("%s", said.c_str());
  // One closed header over the sections, each closed too.
  hud_open_ = ImGui::CollapsingHeader("more");
  if (hud_open_) {
    // Each section a closed tree node; details_panel also takes the frame's stats.
    last_stats_ = stats;
    using Panel = void (Viewer::*)();
    static constexpr std::pair<const char*, Panel> kSections[] = {
        {"details", &Viewer::details_panel},     {"model", &Viewer::models_panel},
        {"strategy", &Viewer::strategy_panel},   {"colour", &Viewer::color_panel},
        {"rendering", &Viewer::rendering_panel}, {"bookmarks", &Viewer::bookmarks_panel},
        {"measure", &Viewer::measure_panel},     {"clip box", &Viewer::clip_panel}};
    for (const auto& [name, panel] : kSections) {
      if (!ImGui::TreeNode(name)) continue;
      (this->*panel)();
      ImGui::TreePop();
    }
  }
  const ImVec2 size = ImGui::GetWindowSize();
  hud_size_ = glm::ivec2(static_cast<int>(size.x), static_cast<int>(size.y));
  ImGui::End();
}

// Frame times with their scale, the stage's and the strategy's counters.
void Viewer::details_panel() {
  const splat::FrameStats& stats = last_stats_;
  const StageCounters& c = controller_->stage().counters();
  if (scene_.world) {
    ImGui::Text("scene: %zu objects of %zu models, %zu draw calls", scene_.world->objects.size(),
                scene_.world->models.size(), stats.draw_calls);
  }
  if (scene_.hierarchy && !scene_.world) {
    // The coordinate system (and what a reprojection made of it) and origin.
    const CoordinateFrame& f = scene_.hierarchy->frame();
    if (!f.crs.empty()) ImGui::TextWrapped("crs %s", f.crs.c_str());
    if (f.origin != glm::dvec3(0.0))
      ImGui::Text("origin %.3f %.3f %.3f", f.origin.x, f.origin.y, f.origin.z);
  }
  if (scene_.up_axis.reason.empty()) {
    ImGui::Text("up %s  (U: next axis)", scene_.up_axis.name().c_str());
  } else {
    ImGui::Text("up %s (auto: %s)  (U: next axis)", scene_.up_axis.name().c_str(),
                scene_.up_axis.reason.c_str());
  }
  // The graph's top is the 1-2-5 step above the slowest frame shown, named
  // beside it, with the 60 and 30 fps lines where they fall inside.
  std::vector<float> times(frame_times_.begin(), frame_times_.end());
  const float slowest = times.empty() ? 1.0f : *std::max_element(times.begin(), times.end());
  const auto top = static_cast<float>(nice_ceiling(slowest));
  const ImVec2 at = ImGui::GetCursorScreenPos();
  constexpr float kGraphW = 200.0f, kGraphH = 48.0f;
  ImGui::PlotLines("##frametimes", times.data(), static_cast<int>(times.size()), 0, nullptr, 0.0f,
                   top, ImVec2(kGraphW, kGraphH));
  ImDrawList* draw = ImGui::GetWindowDrawList();
  for (const float fps_line : {60.0f, 30.0f}) {
    const float ms = 1000.0f / fps_line;
    if (ms >= top) continue;
    const float y = at.y + kGraphH * (1.0f - ms / top);
    draw->AddLine(ImVec2(at.x, y), ImVec2(at.x + kGraphW, y), IM_COL32(255, 255, 255, 60));
  }
  ImGui::SameLine();
  ImGui::BeginGroup();
  ImGui::Text("%g ms", double(top));
  ImGui::Dummy(ImVec2(1.0f, kGraphH - 2.0f * ImGui::GetTextLineHeightWithSpacing()));
  ImGui::TextUnformatted("0");
  ImGui::EndGroup();
  ImGui::TextDisabled("frame time, last %zu frames (lines: 60, 30 fps)", times.size());
  ImGui::Text("draw %.2f ms", draw_ms_);
  ImGui::Text("iteration %.2f ms, %llu iterations, %llu exchanges", c.iteration_ns_last * 1e-6,
              static_cast<unsigned long long>(c.iterations),
              static_cast<unsigned long long>(c.exchanges));
  // Whatever else the strategy measured in its last iteration, by name
  // (treecut/counters.hpp): the HUD needs to know no strategy.
  for (const Counter& counter : c.last.counters.items()) {
    ImGui::Text("%.*s %.6g %.*s", static_cast<int>(counter.name().size()), counter.name().data(),
                counter.value, static_cast<int>(counter.unit().size()), counter.unit().data());
  }
  if (const splat::GpuNodePool* pool = frame_loop_->gpu_pool()) {
    // A paged model's pages on the GPU (the RAM's are the stage's pages_*).
    const splat::GpuPoolStats g = pool->stats();
    ImGui::Text("GPU pages: %llu, %.1f of %.1f MiB; %.0f KiB up this frame",
                static_cast<unsigned long long>(g.resident_pages),
                double(g.resident_bytes) / (1 << 20), double(g.capacity_bytes) / (1 << 20),
                double(g.uploaded_bytes) / 1024.0);
    if (g.waiting_pages > 0)
      ImGui::Text("GPU: %llu pages on their way, %llu nodes drawn as an ancestor",
                  static_cast<unsigned long long>(g.waiting_pages),
                  static_cast<unsigned long long>(g.stand_ins));
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
}

// The strategy, its parameters and the frame-rate control.
void Viewer::strategy_panel() {
  if (ImGui::BeginCombo("##strategy", strategy_.c_str())) {
    for (const std::string& n : strategy_names_) {
      if (ImGui::Selectable(n.c_str(), n == strategy_) && n != strategy_) switch_strategy(n);
    }
    ImGui::EndCombo();
  }
  for (auto& p : params_) {
    double v = p.value;
    bool changed = false;
    ImGui::SetNextItemWidth(140.0f);
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
      ImGui::SetNextItemWidth(140.0f);
      if (ImGui::SliderFloat("target fps", &f, 1.0f, 120.0f)) target_fps_ = chosen_fps_ = f;
      ImGui::Text("adapting %s = %.4g (smoothed %.1f ms)", governor_->param().c_str(),
                  governor_->value(), governor_->smoothed_ms());
      ImGui::Text("model %.2f ms + %.3g us/splat: %.0f splats", governor_->fixed_ms(),
                  governor_->per_splat_ms() * 1e3, governor_->wanted_splats());
    }
  } else {
    ImGui::TextDisabled("hold frame rate: strategy has no budget/threshold");
  }
}

// A load in progress or the last failure: shown with the summary, not in a
// section, so it is seen while a model builds.
void Viewer::load_progress() {
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
}

// Another model: the "open" field, and the next one named on the command line.
void Viewer::models_panel() {
  ImGui::SetNextItemWidth(200.0f);
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
  std::vector<std::string> sources = {"rgb", "elevation"};
  if (scene_.hierarchy) {
    for (const NodeAttribute& a : scene_.hierarchy->attributes()) sources.push_back(a.name);
  }
  if (ImGui::BeginCombo("colour by", color_by_.source.c_str())) {
    for (const std::string& s : sources) {
      if (ImGui::Selectable(s.c_str(), s == color_by_.source) && s != color_by_.source) {
        color_by_.source = s;
        color_auto_ = false;
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
    constexpr float kWidth = 200.0f, kHeight = 14.0f;
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
      // (A model drawn from its pages counts none: NaN.)
      const std::string label =
          std::isnan(e.share)
              ? e.label
              : e.label + "  " + std::to_string(int(std::lround(100 * e.share))) + " %";
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
      if (std::isnan(e.share)) {
        ImGui::TextUnformatted(e.label.c_str());
      } else {
        ImGui::Text("%s  %.0f %%", e.label.c_str(), 100.0 * e.share);
      }
    }
  }
}

// The clip box: what lies outside is not drawn (RenderSettings::clip), in
// the model's coordinates, each axis a range within its bounds.
void Viewer::clip_panel() {
  if (ImGui::Checkbox("draw only inside", &settings_.clip) && settings_.clip &&
      settings_.clip_min == settings_.clip_max) {
    settings_.clip_min = scene_.bounds_min;
    settings_.clip_max = scene_.bounds_max;
  }
  if (!settings_.clip) return;
  const char* axes[3] = {"x", "y", "z"};
  for (int a = 0; a < 3; ++a) {
    const float lo = scene_.bounds_min[a], hi = scene_.bounds_max[a];
    ImGui::SetNextItemWidth(200.0f);
    ImGui::DragFloatRange2(axes[a], &settings_.clip_min[a], &settings_.clip_max[a],
                           std::max(hi - lo, 1e-6f) / 200.0f, lo, hi, "%.3f", "%.3f",
                           ImGuiSliderFlags_AlwaysClamp);
  }
}

void Viewer::rendering_panel() {
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
  ImGui::Checkbox("unlit: the scan's colours (L)", &settings_.light.unlit);
  if (!settings_.light.unlit)
    ImGui::Checkbox("light follows camera", &settings_.light.follow_camera);
  // Eye-dome lighting: on by default for models without normals of their own.
  bool edl = settings_.eye_dome > 0.0f;
  if (ImGui::Checkbox("eye-dome lighting", &edl)) {
    settings_.eye_dome = edl ? std::max(args_.scene.edl_strength, 0.01f) : 0.0f;
  }
  if (edl) {
    ImGui::SetNextItemWidth(140.0f);
    ImGui::SliderFloat("strength", &settings_.eye_dome, 0.05f, 5.0f, "%.2f",
                       ImGuiSliderFlags_Logarithmic);
  }
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
  ImGui::SetNextItemWidth(60.0f);
  ImGui::Combo("size", &screenshot_scale_index_,
               "1x\0"
               "2x\0"
               "4x\0");
  ImGui::SameLine();
  if (ImGui::Button(recording_ ? "stop recording (R)" : "record path (R)")) toggle_recording();
  ImGui::SameLine();
  if (!path_.empty() && ImGui::Button("play (Space)")) start_playback();
}

}  // namespace treecut::cli
