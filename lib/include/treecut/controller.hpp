// Controller (MVC, "Parallel TreeCut Manipulation", figure 1): turns user
// input into View changes and relays the Feedback Stage's cuts to the View.
// Render thread only; a thin layer over FeedbackStage that keeps the camera,
// the light and the frame number and versions the view.
#pragma once

#include <glm/mat4x4.hpp>
#include <glm/vec2.hpp>
#include <glm/vec3.hpp>
#include <memory>
#include <string_view>

#include "treecut/feedback_stage.hpp"
#include "treecut/model.hpp"
#include "treecut/strategy.hpp"
#include "treecut/view_snapshot.hpp"

namespace treecut {

class Controller {
 public:
  Controller(Model model, std::unique_ptr<Strategy> strategy, const ViewSnapshot& initial_view,
             StageOptions options = {});
  /// A scene (FeedbackStage's scene constructor): the view stays in world
  /// space; the stage folds each object's transform in.
  Controller(std::shared_ptr<const StageScene> scene, const StrategyFactory& factory,
             const ViewSnapshot& initial_view, StageOptions options = {});

  /// Camera input; bumps the view version only when something changed.
  void set_camera(const glm::mat4& view, const glm::mat4& projection, glm::ivec2 viewport);
  void set_light(glm::vec3 direction);
  void set_strategy(std::unique_ptr<Strategy> strategy) {
    stage_.set_strategy(std::move(strategy));
  }
  /// Both a model and a scene (per-object instances come from the factory).
  void set_strategy(StrategyFactory factory) { stage_.set_strategy(std::move(factory)); }
  void set_param(std::string_view name, double value) { stage_.set_param(name, value); }

  /// Call at the start of every frame: hands the view to the stage and polls
  /// it (exchange and request, never blocking), which advances the frame number.
  FrameLists begin_frame();

  [[nodiscard]] const ViewSnapshot& view() const { return view_; }
  /// The number of the frame begun by the last begin_frame(): the stage's
  /// frame counter (FeedbackStage::frame()), not a second count.
  [[nodiscard]] std::uint64_t frame() const { return stage_.frame(); }
  [[nodiscard]] FeedbackStage& stage() { return stage_; }
  [[nodiscard]] const FeedbackStage& stage() const { return stage_; }

 private:
  ViewSnapshot view_;
  bool view_dirty_ = true;
  FeedbackStage stage_;
};

}  // namespace treecut
