// treecut view: view scripts (--script, docs/camera-paths.md), camera path
// recording (R) and replay (Space, --path).
#include <algorithm>
#include <cstdio>
#include <filesystem>

#include "treecut/file_io.hpp"
#include "viewer_app.hpp"

namespace treecut::cli {

std::string Viewer::next_name(const char* ext) {
  for (int i = 0;; ++i) {
    char name[64];
    std::snprintf(name, sizeof name, "treecut_%03d.%s", i, ext);
    const auto p = std::filesystem::path(args_.screenshot_dir) / name;
    if (!std::filesystem::exists(p)) return p.string();
  }
}

void Viewer::toggle_recording() {
  if (!recording_) {
    recorded_ = {};
    recording_ = true;
    record_start_ = std::chrono::steady_clock::now();
    return;
  }
  recording_ = false;
  if (recorded_.keys.size() >= 2) {
    // The name is taken when the file is committed (another program may
    // have made treecut_NNN.campath since next_name looked).
    const std::string file =
        write_file_to_free_name(next_name("campath"), splat::format_camera_path(recorded_))
            .string();
    path_ = recorded_;
    say("saved " + file);
  }
}

void Viewer::record_key() {
  if (!recording_) return;
  const double t =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - record_start_).count();
  // At most 30 keys per second; the player interpolates between them.
  if (!recorded_.keys.empty() && t - recorded_.keys.back().time < 1.0 / 30.0) return;
  recorded_.keys.push_back({t, camera_});
}

void Viewer::start_playback() {
  if (path_.empty()) return;
  playing_ = true;
  play_time_ = 0.0;
  camera_ = path_.at(0.0);
}

void Viewer::advance_playback(double dt) {
  if (!playing_) return;
  play_time_ += dt;
  camera_ = path_.at(play_time_);
  if (play_time_ >= path_.duration()) playing_ = false;
}

// Frame-based (not wall-clock) so a run is the same on any machine: "play"
// advances the path by 1/30 s per frame.
void Viewer::step_script() {
  while (script_pos_ < script_.size()) {
    const ScriptCommand& c = script_[script_pos_];
    if (c.verb == "frames") {
      if (script_counter_ < 0) script_counter_ = static_cast<int>(c.number);
      if (script_counter_-- > 0) return;
    } else if (c.verb == "converge") {
      if (script_counter_ < 0) script_counter_ = static_cast<int>(c.number);
      if (!controller_->stage().counters().converged && script_counter_-- > 0) return;
    } else if (c.verb == "play") {
      if (!script_playing_) {
        path_ = splat::load_camera_path(c.arg);
        script_playing_ = true;
        play_time_ = 0.0;
      }
      camera_ = path_.at(play_time_);
      play_time_ += 1.0 / 30.0;
      if (play_time_ <= path_.duration() + 1.0 / 30.0) return;
      script_playing_ = false;
    } else if (c.verb == "open") {
      // Waits (frames go on drawing the old model) until the new model is
      // drawn; a failed load throws from poll_loader() and ends the run.
      if (script_counter_ < 0) {
        script_counter_ = 0;
        script_opening_ = true;
        open_model(c.arg);
      }
      if (script_opening_) return;
    } else if (c.verb == "screenshot") {
      pending_screenshot_ = (std::filesystem::path(args_.screenshot_dir) / c.arg).string();
      screenshot_hud_ = c.number != 0.0;
      screenshot_size_ = glm::ivec2(c.width, c.height);
    } else if (c.verb == "edl") {
      settings_.eye_dome = c.arg == "on" ? std::max(args_.scene.edl_strength, 0.01f) : 0.0f;
    } else if (c.verb == "clip") {
      apply_clip(settings_, c.box, scene_);  // the file's coordinates, as --clip
    } else if (c.verb == "bookmark") {
      // bookmark save N | bookmark N
      if (c.arg == "save") {
        save_bookmark(static_cast<int>(c.number));
      } else {
        go_to_bookmark(static_cast<int>(c.number));
      }
    } else if (c.verb == "pick") {
      pending_pick_ = glm::ivec2(static_cast<int>(c.number), static_cast<int>(c.second));
    } else if (c.verb == "hud") {
      show_hud_ = c.arg == "on";
    } else if (c.verb == "strategy") {
      switch_strategy(c.arg);
    } else if (c.verb == "param") {
      controller_->set_param(c.arg, c.number);
      set_param_value(c.arg, c.number);
    } else if (c.verb == "mode") {
      settings_.mode = splat::parse_splat_mode(c.arg);
    } else if (c.verb == "color") {
      color_by_.source = c.arg;
      color_by_.low.reset(), color_by_.high.reset();
      recolor(true);  // a source the model lacks ends the script: exit 2
    } else if (c.verb == "classes") {
      if (c.arg == "all") {
        color_by_.show_classes.clear(), color_by_.hide_classes.clear();
      } else {
        splat::parse_class_filter(c.arg, color_by_);
      }
      recolor(true);
    } else if (c.verb == "fit") {
      fit();
    } else if (c.verb == "orbit") {
      orbit(static_cast<float>(c.number * 3.14159265358979 / 180.0), 0.0f);
    } else if (c.verb == "exit") {
      quit_ = true;
    }
    script_counter_ = -1;
    ++script_pos_;
    if (quit_ || !pending_screenshot_.empty() || pending_pick_) return;  // one a frame
  }
}

}  // namespace treecut::cli
