// treecut view: set-up, the main loop, strategies, and switching to a model
// loaded in the background (viewer_app.hpp lists the other files).
#include <backends/imgui_impl_glfw.h>
#include <backends/imgui_impl_opengl3.h>
#include <imgui.h>

#include <cstdio>
#include <stdexcept>

#include "messages.hpp"
#include "treecut/error.hpp"
#include "treecut/model.hpp"
#include "treecut/splat/gl.hpp"
#include "viewer_app.hpp"

namespace treecut::cli {

namespace {

void on_scroll(GLFWwindow* w, double, double dy) {
  if (ImGui::GetCurrentContext() != nullptr && ImGui::GetIO().WantCaptureMouse) return;
  static_cast<ViewerInput*>(glfwGetWindowUserPointer(w))->scroll += dy;
}

void on_drop(GLFWwindow* w, int count, const char** paths) {
  auto* input = static_cast<ViewerInput*>(glfwGetWindowUserPointer(w));
  for (int i = 0; i < count; ++i) input->dropped.emplace_back(paths[i]);
}

}  // namespace

Viewer::Viewer(const ViewArgs& args)
    : args_(args),
      registry_(make_registry(args.scene)),
      settings_(render_settings(args.scene)),
      window_(splat::WindowOptions{args.width, args.height, "treecut", false}) {
  if (!args.script.empty()) script_ = load_view_script(args.script);
  if (!args.path.empty()) path_ = splat::load_camera_path(args.path);
  scene_ = load_scene(args.scene);
  apply_model_settings(settings_, args.scene, scene_);
  current_file_ = args.scene.model;
  load_bookmarks();
  models_.push_back(args.scene.model);
  models_.insert(models_.end(), args.more_models.begin(), args.more_models.end());
  glfwSetWindowTitle(window_.handle(), ("treecut - " + scene_.label).c_str());
  strategy_names_ = registry_.names();
  strategy_ = args.scene.strategies.empty() ? "optimization" : args.scene.strategies.front();
  check_params(registry_, {strategy_}, args.scene.params);
  renderer_ = std::make_unique<splat::Renderer>(*scene_.hierarchy, window_.framebuffer_size(),
                                                pool_vertices(scene_, args.scene));
  std::string color_note;
  color_auto_ = args.scene.color == "auto";
  color_by_ = resolve_color(scene_, args.scene, &color_note);
  if (!color_note.empty()) {
    std::printf("colour    %s\n", color_note.c_str());
    say(color_note);
  }
  recolor(true);
  open_view();
  auto strategy = make_strategy(registry_, strategy_, args.scene.params);
  read_params(*strategy);
  if (scene_.world) {
    if (const std::string why = per_object_limit_problem(*scene_.world, *strategy); !why.empty()) {
      throw InputError(args.scene.model + ": " + why);
    }
    strategy.reset();  // a scene makes its own from the factory
  }
  StageOptions stage_options;
  // The stage takes the cycles the render thread and the GL driver leave.
  stage_options.priority = StagePriority::Idle;
  configure_stage(stage_options, args.scene);
  // The stage shares the scene's hierarchy (no copy): the renderer sees the
  // same one in the lists and keeps its vertex buffer.
  const ViewSnapshot initial =
      splat::view_snapshot(camera_, window_.framebuffer_size(), settings_.light);
  if (scene_.world) {
    // A scene: the stage runs the strategy per object (or a scene-level one).
    controller_ = std::make_unique<Controller>(scene_.world, strategy_factory(strategy_, true),
                                               initial, stage_options);
  } else {
    controller_ = std::make_unique<Controller>(
        Model{scene_.hierarchy, opening_cut(*scene_.hierarchy), scene_.paged}, std::move(strategy),
        initial, stage_options);
  }
  queries_ = std::make_unique<splat::QueryExecutor>();
  frame_loop_ =
      std::make_unique<splat::RenderThreadFrame>(*controller_, *renderer_, queries_.get());
  frame_loop_->follow_pages(scene_.paged.get(), gpu_pool_options(args_.scene));

  glfwSetWindowUserPointer(window_.handle(), &input_);
  // Before ImGui, which chains them.
  glfwSetScrollCallback(window_.handle(), &on_scroll);
  glfwSetDropCallback(window_.handle(), &on_drop);
  IMGUI_CHECKVERSION();
  ImGui::CreateContext();
  ImGui::GetIO().IniFilename = nullptr;
  ImGui::StyleColorsDark();
  ImGui_ImplGlfw_InitForOpenGL(window_.handle(), true);
  ImGui_ImplOpenGL3_Init("#version 450 core");
  if (!path_.empty() && script_.empty()) start_playback();
}

Viewer::~Viewer() {
  ImGui_ImplOpenGL3_Shutdown();
  ImGui_ImplGlfw_Shutdown();
  ImGui::DestroyContext();
}

int Viewer::run() {
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
    poll_loader();
    step_script();
    advance_playback(dt);
    record_key();
    splat::fit_clip_planes(camera_, scene_.center, scene_.radius);

    const splat::FrameResult result = frame_loop_->run_render_thread(camera_, settings_);
    const splat::FrameStats& stats = result.stats;
    if (pending_pick_) {
      pick_at(*pending_pick_);  // what this frame drew, with its camera
      pending_pick_.reset();
    }
    // The first frame of a loaded model: from now on the camera and HUD are its.
    if (result.model_switched && incoming_ &&
        renderer_->hierarchy() == incoming_->hierarchy.get()) {
      adopt_scene();
    }
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
    // The scene alone: read before the HUD is drawn over it.
    if (!pending_screenshot_.empty() && !screenshot_hud_) {
      save_screenshot(pending_screenshot_, size);
      pending_screenshot_.clear();
    }
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
    screenshot_hud_ = false;
    screenshot_size_ = glm::ivec2(0);
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

void Viewer::read_params(const Strategy& s) {
  params_.clear();
  for (const ParamSpec& spec : s.param_specs()) params_.push_back({spec, s.param(spec.name)});
  governor_ = splat::FrameRateGovernor::for_strategy(
      s, scene_.world ? static_cast<std::size_t>(scene_.world->object_nodes())
                      : scene_.hierarchy->node_count());
}

StrategyFactory Viewer::strategy_factory(const std::string& name, bool with_params) const {
  const StrategyRegistry* registry = &registry_;
  std::vector<std::string> params = with_params ? args_.scene.params : std::vector<std::string>{};
  return [registry, name, params] { return make_strategy(*registry, name, params); };
}

void Viewer::set_param_value(const std::string& name, double v) {
  for (auto& p : params_) {
    if (p.spec.name == name) p.value = v;
  }
}

void Viewer::switch_strategy(const std::string& name) {
  auto s = make_strategy(registry_, name, {});
  read_params(*s);
  strategy_ = name;
  if (scene_.world) {
    controller_->set_strategy(strategy_factory(name, false));
  } else {
    controller_->set_strategy(std::move(s));
  }
}

void Viewer::open_model(const std::string& file) {
  opening_file_ = file;
  SceneArgs args = args_.scene;
  args.model = file;
  // A newer request replaces a load still running (it is asked to stop) and
  // a loaded model not yet drawn (the stage takes the latest set_model).
  loader_.start(args);
  open_frame_ = frame_;
  load_error_.clear();
  status_.clear();
}

void Viewer::poll_loader() {
  std::optional<LoadedModel> done = loader_.take();
  if (!done) return;
  if (done->scene && done->scene->hierarchy->empty()) {
    // The stage takes no empty model (set_model would throw): a bad file.
    done->error = done->file + ": no points to show";
    done->input_error = true;
    done->scene.reset();
  }
  if (!done->scene) {
    // The old model stays. One line, on the HUD and on stderr; in a script the
    // run's failure (exit 2 for a bad or missing file, as a bad script line).
    load_error_ = done->error;
    script_opening_ = false;
    if (!script_.empty()) {
      if (done->input_error) throw InputError(done->error);
      throw std::runtime_error(done->error);
    }
    // The program's own prefixes: "treecut: " for bad input, "treecut: error: " else.
    print_error(done->error, done->input_error);
    return;
  }
  if (done->scene->world) {
    // A scene too large for per-object instances of this strategy: a failed
    // open like any other (the old model or scene stays).
    if (std::string why =
            per_object_limit_problem(*done->scene->world, *make_strategy(registry_, strategy_, {}));
        !why.empty()) {
      done->error = quoted_name(done->file) + ": " + why;
      done->input_error = true;
      done->scene.reset();
      load_error_ = done->error;
      script_opening_ = false;
      if (!script_.empty()) throw InputError(done->error);
      print_error(done->error, true);
      return;
    }
  }
  if (done->scene->world || scene_.world) {
    replace_stage(std::move(*done->scene));
    return;
  }
  const std::shared_ptr<const Hierarchy> h = done->scene->hierarchy;
  // The stage switches at its next request; the window draws the old model
  // until the exchange (RenderThreadFrame uploads the new vertices then).
  controller_->stage().set_model(Model{h, opening_cut(*h), done->scene->paged});
  // (Its pages go up once its lists are drawn: RenderThreadFrame checks.)
  frame_loop_->follow_pages(done->scene->paged.get(), gpu_pool_options(args_.scene));
  incoming_ = std::move(done->scene);
}

void Viewer::adopt_scene() {
  scene_ = std::move(*incoming_);
  incoming_.reset();
  current_file_ = opening_file_;
  load_bookmarks();
  picks_.clear();
  glfwSetWindowTitle(window_.handle(), ("treecut - " + scene_.label).c_str());
  open_view();
  // The governor caps a budget at the hierarchy's node count and its cost
  // model belongs to the old model: it starts again from the current value.
  if (governor_) {
    std::vector<ParamSpec> specs;
    for (const ParamState& p : params_) specs.push_back(p.spec);
    governor_ = splat::FrameRateGovernor::for_params(specs, governor_->value(),
                                                     scene_.hierarchy->node_count());
  }
  say("opened " + scene_.label);
  apply_model_settings(settings_, args_.scene, scene_);
  if (color_auto_) {
    std::string note;
    color_by_ = resolve_color(scene_, args_.scene, &note);
    if (!note.empty()) std::printf("colour    %s\n", note.c_str());
  }
  recolor();
  // The frames the window drew meanwhile (the old model): a load never blocks it.
  std::printf("opened %s (%zu nodes) after %llu frames of the old model\n", scene_.label.c_str(),
              static_cast<std::size_t>(scene_.hierarchy->node_count()),
              static_cast<unsigned long long>(frame_ - open_frame_));
  script_opening_ = false;
}

void Viewer::replace_stage(Scene loaded) {
  // The stage is made on a model or on a scene for good (set_model refuses a
  // scene): a new one, and a new frame loop and executor with it. The old
  // one cancels its iteration and joins its thread here. The HUD's fade
  // setting carries over.
  const unsigned blend = controller_->stage().blend_frames();
  frame_loop_.reset();
  controller_.reset();
  queries_.reset();
  incoming_.reset();
  scene_ = std::move(loaded);
  fit();
  StageOptions stage_options;
  stage_options.priority = StagePriority::Idle;
  configure_stage(stage_options, args_.scene);
  const ViewSnapshot initial =
      splat::view_snapshot(camera_, window_.framebuffer_size(), settings_.light);
  if (scene_.world) {
    controller_ = std::make_unique<Controller>(scene_.world, strategy_factory(strategy_, false),
                                               initial, stage_options);
  } else {
    controller_ = std::make_unique<Controller>(
        Model{scene_.hierarchy, opening_cut(*scene_.hierarchy), scene_.paged},
        make_strategy(registry_, strategy_, {}), initial, stage_options);
  }
  controller_->stage().set_blend_frames(blend);
  queries_ = std::make_unique<splat::QueryExecutor>();
  frame_loop_ =
      std::make_unique<splat::RenderThreadFrame>(*controller_, *renderer_, queries_.get());
  frame_loop_->follow_pages(scene_.paged.get(), gpu_pool_options(args_.scene));
  read_params(*make_strategy(registry_, strategy_, {}));
  glfwSetWindowTitle(window_.handle(), ("treecut - " + scene_.label).c_str());
  say("opened " + scene_.label);
  apply_model_settings(settings_, args_.scene, scene_);
  recolor();
  if (scene_.world) {
    std::printf("opened %s (%zu objects)\n", scene_.label.c_str(), scene_.world->objects.size());
  } else {
    std::printf("opened %s (%zu nodes)\n", scene_.label.c_str(),
                static_cast<std::size_t>(scene_.hierarchy->node_count()));
  }
  script_opening_ = false;
}

void Viewer::recolor(bool strict) {
  try {
    legend_ = apply_coloring(scene_, color_by_, *renderer_);
  } catch (const InputError& e) {
    if (strict) throw;
    say(std::string(e.what()) + "; colours: rgb");
    color_by_.source = "rgb";
    color_by_.show_classes.clear();
    color_by_.hide_classes.clear();
    legend_ = apply_coloring(scene_, color_by_, *renderer_);
  }
}

int run_viewer(const ViewArgs& args) {
  Viewer viewer(args);
  viewer.set_target_fps(args.target_fps);
  return viewer.run();
}

}  // namespace treecut::cli
