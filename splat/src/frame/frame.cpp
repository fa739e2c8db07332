#include "treecut/splat/frame.hpp"

#include <cstring>
#include <glm/geometric.hpp>
#include <glm/mat3x3.hpp>
#include <glm/matrix.hpp>
#include <stdexcept>

namespace treecut::splat {

glm::vec3 world_light_dir(const Light& light, const glm::mat4& view) {
  glm::vec3 d = light.direction;
  // A headlight is given in view space: the inverse view's rotation turns it
  // into the world.
  if (light.follow_camera) d = glm::mat3(glm::inverse(view)) * d;
  const float len = glm::length(d);
  return len > 0.0f ? d / len : glm::vec3(0.0f, 0.0f, 1.0f);
}

ViewSnapshot view_snapshot(const Camera& camera, glm::ivec2 size, const Light& light) {
  ViewSnapshot v = camera.view(size);
  v.light_dir = world_light_dir(light, v.view);
  return v;
}

std::vector<std::uint8_t> read_back_rgba(GLuint fbo, GLenum read_buffer, glm::ivec2 size) {
  const auto w = static_cast<std::size_t>(size.x);
  const auto h = static_cast<std::size_t>(size.y);
  std::vector<std::uint8_t> bottom_up(w * h * 4);
  gl::BindFramebuffer(GL_READ_FRAMEBUFFER, fbo);
  if (fbo == 0) gl::NamedFramebufferReadBuffer(0, read_buffer);
  gl::PixelStorei(GL_PACK_ALIGNMENT, 1);
  gl::ReadPixels(0, 0, size.x, size.y, GL_RGBA, GL_UNSIGNED_BYTE, bottom_up.data());
  gl::BindFramebuffer(GL_READ_FRAMEBUFFER, 0);
  gl::check("read back");
  // GL's rows run bottom-up; images top-down.
  std::vector<std::uint8_t> top_down(bottom_up.size());
  for (std::size_t y = 0; y < h; ++y) {
    std::memcpy(&top_down[y * w * 4], &bottom_up[(h - 1 - y) * w * 4], w * 4);
  }
  return top_down;
}

RenderThreadFrame::RenderThreadFrame(Controller& controller, Renderer& renderer,
                                     QueryExecutor* executor)
    : controller_(&controller), renderer_(&renderer), executor_(executor) {}

RenderThreadFrame::~RenderThreadFrame() {
  // The renderer may outlive this object: never leave it a dangling hook.
  if (executor_ != nullptr) renderer_->set_query_hook(nullptr);
}

FrameResult RenderThreadFrame::begin_render_thread(const Camera& camera, const Light& light) {
  const glm::ivec2 size = renderer_->size();
  const glm::mat4 view = camera.view_matrix();
  controller_->set_camera(
      view, camera.projection_matrix(static_cast<float>(size.x) / static_cast<float>(size.y)),
      size);
  controller_->set_light(world_light_dir(light, view));
  const FrameLists lists = controller_->begin_frame();
  if (lists.current.scene != nullptr) return begin_scene(lists);
  scene_ = nullptr;
  // Another model: its vertices first (hold), the old model's list dropped.
  const bool switched =
      lists.current.hierarchy != nullptr && lists.current.hierarchy != renderer_->hierarchy();
  if (switched) hold(*lists.current.hierarchy);
  // A paged model: the pages the list needs go up (within the frame's
  // budget) before it is drawn; the rest is drawn as ancestors meanwhile.
  if (pool_) pool_->begin_frame();
  // A new generation is copied into the GPU index buffer now (so the stage
  // may reuse the list after the next exchange), fading from the previous
  // list while the stage blends.
  cut_.follow(lists);
  if (pool_) pool_->prepare(cut_);
  current_ = FrameResult{};
  current_.model_switched = switched;
  if (switched) model_frame_ = controller_->frame();
  current_.frame = controller_->frame();
  current_.generation = lists.current.generation;
  current_.exchanged = lists.exchanged;
  current_.requested = lists.requested;
  // Queued once per generation (the executor ignores a generation it has seen).
  if (executor_ != nullptr) executor_->begin_frame_render_thread(lists.current, current_.frame);
  return current_;
}

void RenderThreadFrame::follow_pages(PagedHierarchy* paged, const GpuPoolOptions& gpu) {
  paged_ = paged;
  gpu_ = gpu;
  pool_.reset();
  cut_.set_vertex_map(nullptr);
  // The renderer made for this model (its pool): drawn through a pool now.
  if (paged_ != nullptr && renderer_->hierarchy() == &paged_->hierarchy())
    hold(*renderer_->hierarchy());
}

// Another model (FeedbackStage::set_model): its vertices go up before its
// first list, so no id of one hierarchy is drawn against the other's
// vertices (follow() then uploads that list plainly: a fade never mixes two
// hierarchies). A paged model's are its pool's.
void RenderThreadFrame::hold(const Hierarchy& h) {
  cut_.set_vertex_map(nullptr);
  pool_.reset();
  if (paged_ != nullptr && &h == &paged_->hierarchy()) {
    pool_ = std::make_unique<GpuNodePool>(*renderer_, *paged_, gpu_);
    cut_.set_vertex_map(pool_.get());
  } else {
    renderer_->set_hierarchy(h);
  }
}

FrameResult RenderThreadFrame::begin_scene(const FrameLists& lists) {
  const StageScene& scene = *lists.current.scene;
  bool switched = false;
  if (&scene != scene_) {
    // Once per scene: the distinct models into the one vertex buffer (unless
    // the renderer holds exactly these already), the objects' records.
    models_.clear();
    for (const auto& m : scene.models) models_.push_back(m.get());
    scene_cut_.set_vertex_map(nullptr);
    pool_.reset();
    if (!scene.paged.empty()) {
      // Models drawn from their pages: one pool of every model's pages
      // (those held whole are up for good), within the GPU budget.
      std::vector<PoolModel> pool_models;
      for (std::size_t m = 0; m < models_.size(); ++m)
        pool_models.push_back({models_[m], scene.paged_model(m)});
      pool_ = std::make_unique<GpuNodePool>(*renderer_, pool_models, gpu_);
      scene_cut_.set_vertex_map(pool_.get());
    } else {
      bool held = renderer_->model_count() == models_.size();
      for (std::size_t i = 0; held && i < models_.size(); ++i) {
        held = renderer_->model_identity(i) == models_[i];
      }
      if (!held) renderer_->set_models(models_);
    }
    scene_cut_.set_objects(*renderer_, scene.objects);
    scene_ = &scene;
    switched = true;
  }
  if (pool_) pool_->begin_frame();
  if (switched || lists.current.generation != scene_generation_) {
    // A new generation: the objects' lists, copied into the GPU buffers now
    // (the stage may reuse the list after the next exchange).
    const std::span<const std::uint32_t> off = lists.current.object_offsets;
    const std::size_t n = scene.objects.size();
    if (off.size() != n + 1) {
      throw std::logic_error("a scene list without the layout of its objects");
    }
    object_lists_.resize(n);
    for (std::size_t i = 0; i < n; ++i) {
      object_lists_[i] = lists.current.nodes.subspan(off[i], off[i + 1] - off[i]);
    }
    scene_cut_.upload(models_, object_lists_);
    scene_generation_ = lists.current.generation;
  }
  // The pages the lists need go up (within the frame's budget) before
  // they are drawn; the rest is drawn as ancestors meanwhile.
  if (pool_) pool_->prepare(scene_cut_);
  current_ = FrameResult{};
  current_.model_switched = switched;
  if (switched) model_frame_ = controller_->frame();
  current_.frame = controller_->frame();
  current_.generation = lists.current.generation;
  current_.exchanged = lists.exchanged;
  current_.requested = lists.requested;
  current_.objects = scene.objects.size();
  return current_;
}

FrameResult RenderThreadFrame::draw_render_thread(const Camera& camera,
                                                  const RenderSettings& settings, bool finish) {
  if (scene_ != nullptr) {
    current_.stats = renderer_->draw_scene(scene_cut_, camera, settings, finish);
    return current_;
  }
  if (executor_ != nullptr) renderer_->set_query_hook(executor_);
  current_.stats = renderer_->draw(cut_, camera, settings, finish);
  if (executor_ != nullptr) {
    std::span<const VisibilityResult> results = executor_->results();
    if (model_frame_ > 0 && !results.empty() && results.front().frame_issued < model_frame_) {
      // Answers to queries issued before the model switch name nodes of the
      // old hierarchy: dropped (the executor queued the new model's requests
      // in the switch frame, so everything issued from then on is the new
      // model's). The executor answers in issue order: a prefix.
      kept_.clear();
      for (const VisibilityResult& r : results) {
        if (r.frame_issued >= model_frame_) kept_.push_back(r);
      }
      stale_results_ += results.size() - kept_.size();
      results = kept_;
    }
    // The stage hands them to the strategy with the next request: frames
    // after they were issued, never in the frame that asked.
    if (!results.empty()) controller_->stage().post_visibility(results);
    current_.results_posted = results.size();
    executor_->clear_results();
  }
  return current_;
}

FrameResult RenderThreadFrame::run_render_thread(const Camera& camera,
                                                 const RenderSettings& settings, bool finish) {
  begin_render_thread(camera, settings.light);
  return draw_render_thread(camera, settings, finish);
}

}  // namespace treecut::splat
