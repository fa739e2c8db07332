// treecut view: the interactive window (GLFW + Dear ImGui HUD). The class is
// split by job over these files:
//   viewer.cpp          set-up, the main loop, switching to a loaded model
//   viewer_input.cpp    camera controls (mouse, keys, drag and drop)
//   viewer_playback.cpp view scripts, camera path recording and replay
//   viewer_hud.cpp      the HUD
//   viewer_output.cpp   screenshots
//   viewer_loader.cpp   opening another model on a background thread
//
// Controls: left drag orbits (fly mode: looks around), right or middle drag
// pans, wheel zooms, Tab toggles orbit/fly, WASD/QE fly (Shift = faster),
// F fits the model, U turns another axis up (x -> y -> z), L toggles the
// headlight, H hides the HUD, F12 or P saves a screenshot, R starts/stops
// recording a camera path, Space replays the last recorded (or --path) path,
// O opens the next model named on the command line, a PLY or .tch dropped on
// the window opens it, Esc quits.
#pragma once

#include <array>
#include <chrono>
#include <cstdint>
#include <deque>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#define GLFW_INCLUDE_NONE
#include <GLFW/glfw3.h>

#include "hud_summary.hpp"
#include "treecut/controller.hpp"
#include "treecut/registry.hpp"
#include "treecut/splat/camera.hpp"
#include "treecut/splat/camera_path.hpp"
#include "treecut/splat/context.hpp"
#include "treecut/splat/frame.hpp"
#include "treecut/splat/frame_rate.hpp"
#include "treecut/splat/image.hpp"
#include "treecut/splat/query_executor.hpp"
#include "treecut/splat/renderer.hpp"
#include "view_script.hpp"
#include "viewer.hpp"
#include "viewer_loader.hpp"

namespace treecut::cli {

/// What the GLFW callbacks leave for the next frame (the window's user pointer).
struct ViewerInput {
  double scroll = 0.0;
  std::vector<std::string> dropped;  ///< paths dropped on the window, in order
};

class Viewer {
 public:
  explicit Viewer(const ViewArgs& args);
  ~Viewer();
  Viewer(const Viewer&) = delete;
  Viewer& operator=(const Viewer&) = delete;

  int run();
  void set_target_fps(double fps) {
    target_fps_ = fps;
    if (fps > 0.0) chosen_fps_ = fps;
  }

 private:
  struct ParamState {
    ParamSpec spec;
    double value;
  };

  // viewer.cpp: strategies and models.
  void read_params(const Strategy& s);
  void set_param_value(const std::string& name, double v);
  void switch_strategy(const std::string& name);
  /// Starts loading `file` ("" = the generated default model) in the background.
  void open_model(const std::string& file);
  /// Each frame: hands a finished load to the stage (set_model), or reports
  /// its failure (HUD + stderr; a script's failure ends the run).
  void poll_loader();
  /// After the frame that first drew the new model: the scene is its.
  void adopt_scene();
  /// A new stage for `loaded`: a scene file (its own stage, strategy
  /// instances per object) or a model after a scene. Blocks this frame.
  void replace_stage(Scene loaded);
  /// Instances of strategy `name` with the command line's parameters (a
  /// scene's stage calls it per object, on its thread; it reads only what
  /// never changes after construction).
  [[nodiscard]] StrategyFactory strategy_factory(const std::string& name, bool with_params) const;

  // viewer_input.cpp: camera controls.
  void fit();
  /// The first view of a model: from its sensor where the file says (Scene::sensor_view), else
  /// fit().
  void open_view();
  void orbit(float dx, float dy);
  /// A frame's input: a dropped file, then the mouse and the keys unless
  /// the HUD has them or a path or script owns the camera, then fly moves.
  void handle_input(double dt);
  void open_dropped();
  /// Orbit, fly-look, pan, zoom; Ctrl+click picks (CLICKED: the left
  /// button pressed this frame). CURSOR in window pixels.
  void handle_mouse(glm::dvec2 cursor, glm::vec2 delta, bool clicked);
  void handle_keys();
  void fly(double dt);

  // viewer_playback.cpp: scripts and camera paths.
  std::string next_name(const char* ext);
  void toggle_recording();
  void record_key();
  void start_playback();
  void advance_playback(double dt);
  void step_script();

  // viewer_bookmarks.cpp: camera bookmarks, kept beside the model.
  [[nodiscard]] std::filesystem::path bookmarks_file() const;
  void load_bookmarks();
  void save_bookmark(int slot);
  void go_to_bookmark(int slot);
  void bookmarks_panel();

  // viewer_measure.cpp: picking and measuring.
  void pick_at(glm::ivec2 pixel);
  void measure_panel();

  // viewer_output.cpp: screenshots.
  void save_screenshot(const std::string& file, glm::ivec2 size);
  /// The scene of the current lists drawn at `size` off the window, read back.
  splat::Image draw_at(glm::ivec2 size);

  // viewer_hud.cpp.
  void hud(const splat::FrameStats& stats);
  /// TEXT on the HUD's status line, from now for StatusLine::kSeconds.
  void say(std::string text) { status_.say(std::move(text), glfwGetTime()); }
  void details_panel();  ///< reads last_stats_
  void strategy_panel();
  void load_progress();
  void rendering_panel();
  void clip_panel();
  void models_panel();
  void color_panel();
  /// Applies color_by_ to the scene's models (after an open, the up axis
  /// or the HUD changed it). A source the model lacks falls back to rgb,
  /// named in the status line, unless STRICT (the command line: exit 2).
  void recolor(bool strict = false);

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
  splat::ColorBy color_by_;  // --color, --classes and the HUD's colour panel
  /// --color auto, not changed in the HUD since: a model opened later is
  /// resolved again (its own RGB, intensity or elevation).
  bool color_auto_ = false;
  splat::Legend legend_;  // what the colours mean now
  std::unique_ptr<Controller> controller_;
  std::unique_ptr<splat::QueryExecutor> queries_;
  std::unique_ptr<splat::RenderThreadFrame> frame_loop_;  // after what it refers to

  // Models: those named on the command line (O cycles), the load running in
  // the background, and a loaded one handed to the stage but not yet drawn.
  std::vector<std::string> models_;
  std::size_t model_index_ = 0;
  ModelLoader loader_;
  std::optional<Scene> incoming_;
  std::string load_error_;        // the last failed load's line (HUD)
  std::uint64_t open_frame_ = 0;  // frame_ when the last open started
  char open_field_[512] = {};     // the HUD's "open" field

  splat::Camera camera_;
  ViewerInput input_;
  glm::vec2 last_mouse_{0.0f};
  bool have_mouse_ = false;
  bool keys_down_[GLFW_KEY_LAST + 1] = {};
  bool fly_ = false;
  bool show_hud_ = true;
  glm::ivec2 hud_size_{0};        ///< the HUD window's size in the last frame it showed
  bool hud_open_ = false;         ///< its sections' header is open (it may widen)
  splat::FrameStats last_stats_;  ///< the frame the HUD shows (details_panel)
  /// A pick: where (the world's and the file's coordinates) and, for a
  /// single model, the nearest point with its attributes.
  struct Pick {
    glm::dvec3 file{0.0};
    std::string text;
  };
  std::vector<Pick> picks_;                                ///< the last two
  std::array<std::optional<splat::Camera>, 9> bookmarks_;  ///< slots 1..9
  std::string current_file_;                ///< the file of the model shown ("" = generated)
  std::string opening_file_;                ///< the file of the load in progress
  std::optional<glm::ivec2> pending_pick_;  ///< a pixel to pick after the frame
  bool left_down_ = false;                  ///< the left button, last frame
  bool quit_ = false;
  std::deque<float> frame_times_;
  double frame_ms_ = 0.0;
  std::size_t last_splats_ = 0;
  double draw_ms_ = 0.0;
  std::uint64_t frame_ = 0;
  std::string pending_screenshot_;
  /// The pending screenshot is the window with the HUD (Shift+F12, a
  /// script's `screenshot NAME hud`), not the scene alone (F12, P).
  bool screenshot_hud_ = false;
  /// The scene alone drawn at this size (a script's `screenshot NAME WxH`);
  /// 0: the window's.
  glm::ivec2 screenshot_size_{0};
  int screenshot_scale_index_ = 0;  ///< the HUD's selector: 1x, 2x, 4x (1 << index)
  StatusLine status_;               ///< the HUD's last message, shown while fresh (say())
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
  bool script_opening_ = false;  // an `open` waits for its model to be drawn
};

}  // namespace treecut::cli
