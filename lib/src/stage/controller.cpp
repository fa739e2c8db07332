#include "treecut/controller.hpp"

namespace treecut {

Controller::Controller(Model model, std::unique_ptr<Strategy> strategy,
                       const ViewSnapshot& initial_view, StageOptions options)
    : view_(initial_view), stage_(std::move(model), std::move(strategy), options) {
  view_.visibility.clear();
  view_.finalize();
}

Controller::Controller(std::shared_ptr<const StageScene> scene, const StrategyFactory& factory,
                       const ViewSnapshot& initial_view, StageOptions options)
    : view_(initial_view), stage_(std::move(scene), factory, options) {
  view_.visibility.clear();
  view_.finalize();
}

void Controller::set_camera(const glm::mat4& view, const glm::mat4& projection,
                            glm::ivec2 viewport) {
  if (view == view_.view && projection == view_.projection && viewport == view_.viewport) return;
  view_.view = view;
  view_.projection = projection;
  view_.viewport = viewport;
  view_.finalize();
  ++view_.version;
  view_dirty_ = true;
}

void Controller::set_light(glm::vec3 direction) {
  if (direction == view_.light_dir) return;
  view_.light_dir = direction;
  ++view_.version;
  view_dirty_ = true;
}

FrameLists Controller::begin_frame() {
  if (view_dirty_) {
    stage_.set_view(view_);
    view_dirty_ = false;
  }
  FrameLists lists = stage_.poll();
  // One frame counter: the stage's (it numbers the requests and so every
  // VisibilityResult); the controller only mirrors it.
  view_.frame = stage_.frame();
  return lists;
}

}  // namespace treecut
