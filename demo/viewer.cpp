// treecut view: the interactive window (GLFW + Dear ImGui HUD).
//
// Controls: left drag orbits (fly mode: looks around), right or middle drag
// pans, wheel zooms, Tab toggles orbit/fly, WASD/QE fly (Shift = faster),
// F fits the model, U turns another axis up (x -> y -> z), L toggles the
// headlight, H hides the HUD, F12 or P saves a screenshot, R starts/stops
// recording a camera path, Space replays the last recorded (or --path) path,
// Esc quits.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <deque>
#include <filesystem>
#include <fstream>
#include <glm/geometric.hpp>
#include <glm/gtc/matrix_transform.hpp>
#include <optional>
#include <sstream>

#define GLFW_INCLUDE_NONE
#include <GLFW/glfw3.h>
#include <backends/imgui_impl_glfw.h>
#include <backends/imgui_impl_opengl3.h>
#include <imgui.h>

#include "treecut/error.hpp"
#include "treecut/file_io.hpp"
#include "treecut/model.hpp"
#include "treecut/splat/camera_path.hpp"
#include "treecut/splat/context.hpp"
#include "treecut/splat/frame.hpp"
#include "treecut/splat/frame_rate.hpp"
#include "treecut/splat/gl.hpp"
#include "treecut/splat/image.hpp"
#include "view_script.hpp"
#include "viewer.hpp"

namespace treecut::cli {

namespace {

// ---------------------------------------------------------------------------
struct Input {
  double scroll = 0.0;
};

void on_scroll(GLFWwindow* w, double, double dy) {
  if (ImGui::GetCurrentContext() != nullptr && ImGui::GetIO().WantCaptureMouse) return;
  static_cast<Input*>(glfwGetWindowUserPointer(w))->scroll += dy;
}

class Viewer {
 public:
  explicit Viewer(const ViewArgs& args)
      : args_(args),
        registry_(make_registry(args.scene)),
        settings_(render_settings(args.scene)),
        window_(splat::WindowOptions{args.width, args.height, "treecut", false}) {
    if (!args.script.empty()) script_ = load_view_script(args.script);
    if (!args.path.empty()) path_ = splat::load_camera_path(args.path);
    scene_ = load_scene(args.scene);
    glfwSetWindowTitle(window_.handle(), ("treecut - " + scene_.label).c_str());
    strategy_names_ = registry_.names();
    strategy_ = args.scene.strategies.empty() ? "optimization" : args.scene.strategies.front();
    check_params(registry_, {strategy_}, args.scene.params);
    renderer_ = std::make_unique<splat::Renderer>(*scene_.hierarchy, window_.framebuffer_size());
    fit();
    auto strategy = make_strategy(registry_, strategy_, args.scene.params);
    read_params(*strategy);
    StageOptions stage_options;
    // The stage takes the cycles the render thread and the GL driver leave.
    stage_options.priority = StagePriority::Idle;
    configure_stage(stage_options, args.scene);
    controller_ = std::make_unique<Controller>(
        make_model(*scene_.hierarchy), std::move(strategy),
        splat::view_snapshot(camera_, window_.framebuffer_size(), settings_.light), stage_options);
    queries_ = std::make_unique<splat::QueryExecutor>();
    frame_loop_ =
        std::make_unique<splat::RenderThreadFrame>(*controller_, *renderer_, queries_.get());

    glfwSetWindowUserPointer(window_.handle(), &input_);
    glfwSetScrollCallback(window_.handle(), &on_scroll);  // before ImGui, which chains it
    IMGUI_CHECKVERSION();
    ImGui::CreateContext();
    ImGui::GetIO().IniFilename = nullptr;
    ImGui::StyleColorsDark();
    ImGui_ImplGlfw_InitForOpenGL(window_.handle(), true);
    ImGui_ImplOpenGL3_Init("#version 450 core");
    if (!path_.empty() && script_.empty()) start_playback();
  }

  ~Viewer() {
    ImGui_ImplOpenGL3_Shutdown();
    ImGui_ImplGlfw_Shutdown();
    ImGui::DestroyContext();
  }

  int run() {
    auto last = std::chrono::steady_clock::now();
    while (!window_.should_close() && !quit_) {
      splat::GlfwWindow::poll_events();
      const auto now = std::chrono::steady_clock::now();
      const double dt = std::chrono::duration<double>(now - last).count();
      last = now;
      frame_ms_ = dt * 1000.0;
      frame_times_.push_back(static_cast<float>(frame_ms_));
      if (frame_times_.size() > 240) frame_times_.pop_front();

      const glm::ivec2 size = window_.framebuffer_size();
      if (size.x <= 0 || size.y <= 0) continue;  // minimized
      renderer_->resize(size);
      handle_input(dt);
      step_script();
      advance_playback(dt);
      record_key();
      splat::fit_clip_planes(camera_, scene_.center, scene_.radius);

      const splat::FrameStats stats = frame_loop_->run_render_thread(camera_, settings_).stats;
      draw_ms_ = stats.cpu_ms;
      // frame_ms_ is the time of the previous frame: it pairs with the splats
      // that frame drew. The model keeps learning while the control is off.
      if (governor_) {
        if (auto v = governor_->update(frame_ms_, last_splats_, target_fps_)) {
          controller_->set_param(governor_->param(), *v);
          set_param_value(governor_->param(), *v);
        }
      }
      last_splats_ = stats.splats;

      treecut::gl::BindFramebuffer(GL_FRAMEBUFFER, 0);
      treecut::gl::Viewport(0, 0, size.x, size.y);
      renderer_->present(size);
      ImGui_ImplOpenGL3_NewFrame();
      ImGui_ImplGlfw_NewFrame();
      ImGui::NewFrame();
      if (show_hud_) hud(stats);
      ImGui::Render();
      ImGui_ImplOpenGL3_RenderDrawData(ImGui::GetDrawData());
      if (!pending_screenshot_.empty()) {
        save_screenshot(pending_screenshot_, size);
        pending_screenshot_.clear();
      }
      window_.swap_buffers();
      ++frame_;
    }
    // Where the frame-rate control ended (scripted runs measure it).
    if (governor_ && target_fps_ > 0.0) {
      std::printf("governor  %s = %.6g after %llu frames, %zu splats, %.1f ms/frame (smoothed)\n",
                  governor_->param().c_str(), governor_->value(),
                  static_cast<unsigned long long>(frame_), last_splats_, governor_->smoothed_ms());
    }
    return 0;
  }

 private:
  void fit() {
    const glm::ivec2 size = window_.framebuffer_size();
    camera_ = splat::default_camera(scene_.hierarchy->bounds_min(), scene_.hierarchy->bounds_max(),
                                    float(size.x) / float(std::max(size.y, 1)), scene_.up);
  }

  void read_params(const Strategy& s) {
    params_.clear();
    for (const ParamSpec& spec : s.param_specs()) params_.push_back({spec, s.param(spec.name)});
    governor_ = splat::FrameRateGovernor::for_strategy(s, scene_.hierarchy->node_count());
  }

  void set_param_value(const std::string& name, double v) {
    for (auto& p : params_) {
      if (p.spec.name == name) p.value = v;
    }
  }

  void switch_strategy(const std::string& name) {
    auto s = make_strategy(registry_, name, {});
    read_params(*s);
    strategy_ = name;
    controller_->set_strategy(std::move(s));
  }

  // -- camera ---------------------------------------------------------------
  // Turns the eye about the model's up axis (dx) and raises it towards the
  // pole (dy), stopping short of it. Radians.
  void orbit(float dx, float dy) {
    const glm::vec3 up = scene_.up;
    glm::vec3 offset = camera_.eye - camera_.target;
    offset = glm::vec3(glm::rotate(glm::mat4(1.0f), -dx, up) * glm::vec4(offset, 0.0f));
    const float dist = glm::length(offset);
    const glm::vec3 side = glm::cross(up, offset);
    if (dist > 0.0f && glm::length(side) > 1e-6f * dist) {
      const float now = std::asin(std::clamp(glm::dot(offset, up) / dist, -1.0f, 1.0f));
      const float next = std::clamp(now + dy, -1.55f, 1.55f);
      offset = glm::vec3(glm::rotate(glm::mat4(1.0f), -(next - now), glm::normalize(side)) *
                         glm::vec4(offset, 0.0f));
    }
    camera_.eye = camera_.target + offset;
    camera_.up = up;
  }

  void handle_input(double dt) {
    GLFWwindow* w = window_.handle();
    double x = 0.0, y = 0.0;
    glfwGetCursorPos(w, &x, &y);
    const glm::vec2 mouse(static_cast<float>(x), static_cast<float>(y));
    const glm::vec2 delta = have_mouse_ ? mouse - last_mouse_ : glm::vec2(0.0f);
    last_mouse_ = mouse;
    have_mouse_ = true;
    const ImGuiIO& io = ImGui::GetIO();
    if (playing_ || !script_.empty()) return;  // the path or the script owns the camera
    const float scale = scene_.radius;
    if (!io.WantCaptureMouse) {
      if (glfwGetMouseButton(w, GLFW_MOUSE_BUTTON_LEFT) == GLFW_PRESS) {
        if (fly_) {
          const glm::vec3 f = camera_.forward();
          glm::mat4 rot = glm::rotate(glm::mat4(1.0f), -delta.x * 0.005f, scene_.up);
          const glm::vec3 right = glm::normalize(glm::cross(f, camera_.up));
          rot = glm::rotate(rot, -delta.y * 0.005f, right);
          const glm::vec3 nf = glm::vec3(rot * glm::vec4(f, 0.0f));
          camera_.target = camera_.eye + nf * glm::length(camera_.target - camera_.eye);
        } else {
          orbit(delta.x * 0.008f, delta.y * 0.008f);
        }
      }
      if (glfwGetMouseButton(w, GLFW_MOUSE_BUTTON_RIGHT) == GLFW_PRESS ||
          glfwGetMouseButton(w, GLFW_MOUSE_BUTTON_MIDDLE) == GLFW_PRESS) {
        const glm::vec3 f = camera_.forward();
        const glm::vec3 right = glm::normalize(glm::cross(f, camera_.up));
        const glm::vec3 up = glm::cross(right, f);
        const float k = glm::length(camera_.eye - camera_.target) * 0.0015f;
        const glm::vec3 move = (-delta.x * right + delta.y * up) * k;
        camera_.eye += move;
        camera_.target += move;
      }
      if (input_.scroll != 0.0) {
        const glm::vec3 offset = camera_.eye - camera_.target;
        camera_.eye = camera_.target + offset * static_cast<float>(std::pow(0.88, input_.scroll));
      }
    }
    input_.scroll = 0.0;
    if (io.WantCaptureKeyboard) return;
    auto pressed_once = [&](int key) {
      const bool down = glfwGetKey(w, key) == GLFW_PRESS;
      const bool was = keys_down_[key];
      keys_down_[key] = down;
      return down && !was;
    };
    if (pressed_once(GLFW_KEY_ESCAPE)) quit_ = true;
    if (pressed_once(GLFW_KEY_TAB)) fly_ = !fly_;
    if (pressed_once(GLFW_KEY_F)) fit();
    if (pressed_once(GLFW_KEY_U)) {
      // When --up auto guessed wrong: the next axis, and the view fitted to it.
      scene_.up_axis = next_up_axis(scene_.up_axis);
      scene_.up = scene_.up_axis.vector();
      fit();
    }
    if (pressed_once(GLFW_KEY_L)) settings_.light.follow_camera = !settings_.light.follow_camera;
    if (pressed_once(GLFW_KEY_H)) show_hud_ = !show_hud_;
    if (pressed_once(GLFW_KEY_F12) || pressed_once(GLFW_KEY_P))
      pending_screenshot_ = next_name("png");
    if (pressed_once(GLFW_KEY_R)) toggle_recording();
    if (pressed_once(GLFW_KEY_SPACE)) start_playback();
    if (fly_) {
      const float speed = scale * (glfwGetKey(w, GLFW_KEY_LEFT_SHIFT) == GLFW_PRESS ? 1.5f : 0.4f) *
                          static_cast<float>(dt);
      const glm::vec3 f = camera_.forward();
      const glm::vec3 right = glm::normalize(glm::cross(f, camera_.up));
      glm::vec3 move(0.0f);
      if (glfwGetKey(w, GLFW_KEY_W) == GLFW_PRESS) move += f;
      if (glfwGetKey(w, GLFW_KEY_S) == GLFW_PRESS) move -= f;
      if (glfwGetKey(w, GLFW_KEY_D) == GLFW_PRESS) move += right;
      if (glfwGetKey(w, GLFW_KEY_A) == GLFW_PRESS) move -= right;
      if (glfwGetKey(w, GLFW_KEY_E) == GLFW_PRESS) move += camera_.up;
      if (glfwGetKey(w, GLFW_KEY_Q) == GLFW_PRESS) move -= camera_.up;
      camera_.eye += move * speed;
      camera_.target += move * speed;
    }
  }

  // -- camera paths ----------------------------------------------------------
  std::string next_name(const char* ext) {
    for (int i = 0;; ++i) {
      char name[64];
      std::snprintf(name, sizeof name, "treecut_%03d.%s", i, ext);
      const auto p = std::filesystem::path(args_.screenshot_dir) / name;
      if (!std::filesystem::exists(p)) return p.string();
    }
  }

  void toggle_recording() {
    if (!recording_) {
      recorded_ = {};
      recording_ = true;
      record_start_ = std::chrono::steady_clock::now();
      return;
    }
    recording_ = false;
    if (recorded_.keys.size() >= 2) {
      const std::string file = next_name("campath");
      splat::save_camera_path(file, recorded_);
      path_ = recorded_;
      status_ = "saved " + file;
    }
  }

  void record_key() {
    if (!recording_) return;
    const double t =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - record_start_).count();
    // At most 30 keys per second; the player interpolates between them.
    if (!recorded_.keys.empty() && t - recorded_.keys.back().time < 1.0 / 30.0) return;
    recorded_.keys.push_back({t, camera_});
  }

  void start_playback() {
    if (path_.empty()) return;
    playing_ = true;
    play_time_ = 0.0;
    camera_ = path_.at(0.0);
  }

  void advance_playback(double dt) {
    if (!playing_) return;
    play_time_ += dt;
    camera_ = path_.at(play_time_);
    if (play_time_ >= path_.duration()) playing_ = false;
  }

  // -- scripts ---------------------------------------------------------------
  // Frame-based (not wall-clock) so a run is the same on any machine: "play"
  // advances the path by 1/30 s per frame.
  void step_script() {
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
      } else if (c.verb == "screenshot") {
        pending_screenshot_ = (std::filesystem::path(args_.screenshot_dir) / c.arg).string();
      } else if (c.verb == "strategy") {
        switch_strategy(c.arg);
      } else if (c.verb == "param") {
        controller_->set_param(c.arg, c.number);
        set_param_value(c.arg, c.number);
      } else if (c.verb == "mode") {
        settings_.mode = splat::parse_splat_mode(c.arg);
      } else if (c.verb == "fit") {
        fit();
      } else if (c.verb == "orbit") {
        orbit(static_cast<float>(c.number * 3.14159265358979 / 180.0), 0.0f);
      } else if (c.verb == "exit") {
        quit_ = true;
      }
      script_counter_ = -1;
      ++script_pos_;
      if (quit_ || !pending_screenshot_.empty()) return;
    }
  }

  // -- output ----------------------------------------------------------------
  // The screenshot function: what the window shows (scene and HUD), read from
  // the back buffer after the HUD is drawn and before the swap.
  void save_screenshot(const std::string& file, glm::ivec2 size) {
    splat::Image img{size.x, size.y, splat::read_back_rgba(0, GL_BACK, size)};
    for (std::size_t i = 3; i < img.rgba.size(); i += 4) img.rgba[i] = 255;
    // Never over a file the viewer did not write this session: the next free name.
    const std::filesystem::path p = free_screenshot_name(file);
    try {
      if (p.has_parent_path()) {
        std::error_code ec;
        std::filesystem::create_directories(p.parent_path(), ec);
        if (ec) throw std::runtime_error(system_error_text(p.parent_path(), ec.value()));
      }
      splat::write_png(p, img);  // atomic and checked: a failure leaves no partial PNG
    } catch (const std::exception& e) {
      status_ = std::string("screenshot failed: ") + e.what();
      // A scripted run is automation: its failure is the run's (exit code 1,
      // one line); an interactive one reports on the HUD and stderr and goes on.
      if (!script_.empty()) throw std::runtime_error(e.what());
      std::fprintf(stderr, "treecut: error: screenshot %s\n", e.what());
      return;
    }
    written_screenshots_.push_back(p);
    status_ = "saved " + p.string();
    std::printf("screenshot %s\n", p.string().c_str());
  }

  std::filesystem::path free_screenshot_name(const std::filesystem::path& wanted) const {
    auto ours = [&](const std::filesystem::path& p) {
      return std::find(written_screenshots_.begin(), written_screenshots_.end(), p) !=
             written_screenshots_.end();
    };
    if (file_kind(wanted) == FileKind::Missing || ours(wanted)) return wanted;
    for (int i = 1;; ++i) {
      std::filesystem::path p = wanted;
      p.replace_filename(wanted.stem().string() + "-" + std::to_string(i) +
                         wanted.extension().string());
      if (file_kind(p) == FileKind::Missing || ours(p)) return p;
    }
  }

  void hud(const splat::FrameStats& stats) {
    ImGui::SetNextWindowPos(ImVec2(10, 10), ImGuiCond_FirstUseEver);
    ImGui::SetNextWindowBgAlpha(0.8f);
    ImGui::Begin("treecut", nullptr, ImGuiWindowFlags_AlwaysAutoResize);
    const StageCounters& c = controller_->stage().counters();
    ImGui::Text("%s", scene_.label.c_str());
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
        changed =
            ImGui::DragInt(p.spec.name.c_str(), &iv, std::max(1.0f, float(std::abs(v)) * 0.01f),
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

  void rendering_panel() {
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

  struct ParamState {
    ParamSpec spec;
    double value;
  };

  const ViewArgs& args_;
  StrategyRegistry registry_;
  splat::RenderSettings settings_;
  splat::GlfwWindow window_;
  Scene scene_;
  std::vector<std::string> strategy_names_;
  std::string strategy_;
  std::vector<ParamState> params_;
  std::optional<splat::FrameRateGovernor> governor_;
  double target_fps_ = 0.0;
  double chosen_fps_ = 30.0;
  std::unique_ptr<splat::Renderer> renderer_;
  std::unique_ptr<Controller> controller_;
  std::unique_ptr<splat::QueryExecutor> queries_;
  std::unique_ptr<splat::RenderThreadFrame> frame_loop_;  // after what it refers to
  splat::Camera camera_;
  Input input_;
  glm::vec2 last_mouse_{0.0f};
  bool have_mouse_ = false;
  bool keys_down_[GLFW_KEY_LAST + 1] = {};
  bool fly_ = false;
  bool show_hud_ = true;
  bool quit_ = false;
  std::deque<float> frame_times_;
  double frame_ms_ = 0.0;
  std::size_t last_splats_ = 0;
  double draw_ms_ = 0.0;
  std::uint64_t frame_ = 0;
  std::string pending_screenshot_;
  std::vector<std::filesystem::path> written_screenshots_;  // may be replaced by a script
  std::string status_;
  bool recording_ = false;
  splat::CameraPath recorded_;
  std::chrono::steady_clock::time_point record_start_;
  splat::CameraPath path_;
  bool playing_ = false;
  double play_time_ = 0.0;
  std::vector<ScriptCommand> script_;
  std::size_t script_pos_ = 0;
  int script_counter_ = -1;
  bool script_playing_ = false;

 public:
  void set_target_fps(double fps) {
    target_fps_ = fps;
    if (fps > 0.0) chosen_fps_ = fps;
  }
};

}  // namespace

int run_viewer(const ViewArgs& args) {
  Viewer viewer(args);
  viewer.set_target_fps(args.target_fps);
  return viewer.run();
}

}  // namespace treecut::cli
