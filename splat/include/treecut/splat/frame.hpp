// The frame layer: one object that runs a frame of the View on the render
// thread (camera and light in, poll the Feedback Stage through the
// Controller, upload the index list on an exchange, draw, execute the
// strategy's GPU queries, post their answers). `treecut view`, `treecut
// render` and the benchmarks run their frames through it; presenting to a
// window or reading the image back stays with the caller (present(),
// read_back_rgba()).
//
// Thread affinity: everything here runs on the render thread, with the GL
// context current (members end in _render_thread or say so). The only thing
// that crosses to the Feedback Stage thread is what Controller/FeedbackStage
// hand over themselves (the ViewSnapshot as one value, the query results).
#pragma once

#include <cstdint>
#include <glm/mat4x4.hpp>
#include <glm/vec2.hpp>
#include <glm/vec3.hpp>
#include <memory>
#include <span>
#include <vector>

#include "treecut/controller.hpp"
#include "treecut/splat/camera.hpp"
#include "treecut/splat/gl.hpp"
#include "treecut/splat/node_pool.hpp"
#include "treecut/splat/query_executor.hpp"
#include "treecut/splat/renderer.hpp"
#include "treecut/splat/scene_draw.hpp"
#include "treecut/view_snapshot.hpp"

namespace treecut::splat {

/// The unit direction towards the light in world (model) space that the
/// renderer lights with for a camera with this view matrix: the one place of
/// that maths (the renderer and the ViewSnapshot handed to strategies both use it).
[[nodiscard]] glm::vec3 world_light_dir(const Light& light, const glm::mat4& view);

/// The ViewSnapshot of a camera drawing into a `size` framebuffer, lit by
/// `light`, finalized (the initial view of a Controller).
[[nodiscard]] ViewSnapshot view_snapshot(const Camera& camera, glm::ivec2 size, const Light& light);

/// Reads `size` pixels of framebuffer `fbo` (0: the window, from `read_buffer`,
/// e.g. GL_BACK; ignored for another framebuffer) as tightly packed RGBA8, top
/// row first (image order). Render thread only. The one read-back of the
/// project: Renderer::read_pixels and the viewer's screenshot use it.
[[nodiscard]] std::vector<std::uint8_t> read_back_rgba(GLuint fbo, GLenum read_buffer,
                                                       glm::ivec2 size);

/// What one frame did.
struct FrameResult {
  FrameStats stats;                ///< the renderer's
  std::uint64_t frame = 0;         ///< the frame's number (the stage's counter)
  std::uint64_t generation = 0;    ///< of the list drawn
  bool exchanged = false;          ///< a new list became current this frame
  bool requested = false;          ///< an iteration was requested this frame
  std::size_t results_posted = 0;  ///< query answers handed to the stage this frame
  /// The list drawn this frame is the first of another hierarchy: its
  /// vertices were uploaded (Renderer::set_hierarchy) before it.
  bool model_switched = false;
  /// A scene's list (FrontList::scene): its objects; 0 for a single model.
  std::size_t objects = 0;
};

/// Runs frames of one Controller with one Renderer (render thread only).
/// Neither is owned; both must outlive the frame object. With an executor,
/// the strategy's queries run inside every draw and their answers go to the
/// stage after it (see QueryExecutor); without one, requests are ignored.
///
/// Models that change (Controller::set_model): the renderer follows the
/// hierarchy of the list it draws. The frame that receives the first list of
/// another hierarchy uploads that hierarchy's vertex buffer before drawing
/// it, drops the old model's list (no fade across the switch) and the
/// executor drops the old model's queries; frames before it draw the old
/// model, whose hierarchy the stage keeps alive while its list is current
/// (ListBuffer holds a shared_ptr). The renderer keeps no pointer into a
/// hierarchy: it copies the vertices and remembers the address as an identity.
class RenderThreadFrame {
 public:
  RenderThreadFrame(Controller& controller, Renderer& renderer, QueryExecutor* executor = nullptr);
  ~RenderThreadFrame();
  RenderThreadFrame(const RenderThreadFrame&) = delete;
  RenderThreadFrame& operator=(const RenderThreadFrame&) = delete;

  /// Render thread. Camera and light in, poll (exchange/request), upload the
  /// list if it changed: what a frame does before it draws.
  FrameResult begin_render_thread(const Camera& camera, const Light& light);
  /// Render thread. Draws the current list (queries inside the draw when an
  /// executor is set) and posts the query answers read this frame to the
  /// stage. With `finish`, waits for the GPU (FrameStats::cpu_ms is the frame).
  FrameResult draw_render_thread(const Camera& camera, const RenderSettings& settings,
                                 bool finish = false);
  /// Render thread. begin_render_thread + draw_render_thread.
  FrameResult run_render_thread(const Camera& camera, const RenderSettings& settings,
                                bool finish = false);

  /// A paged model (Model::paged): its lists are drawn from a pool of
  /// vertices within GPU's budget (GpuNodePool), the pages each list
  /// needs copied up before it is drawn; null: none.
  void follow_pages(PagedHierarchy* paged, const GpuPoolOptions& gpu = {});
  /// The paged model's pool while its lists are drawn (null otherwise).
  [[nodiscard]] const GpuNodePool* gpu_pool() const { return pool_.get(); }

  [[nodiscard]] const CutBuffer& cut() const { return cut_; }
  /// A scene's lists on the GPU (empty before a scene's first frame).
  [[nodiscard]] const SceneCutBuffer& scene_cut() const { return scene_cut_; }
  /// Whether the current list is a scene's.
  [[nodiscard]] bool drawing_scene() const { return scene_ != nullptr; }
  [[nodiscard]] Controller& controller() { return *controller_; }
  [[nodiscard]] Renderer& renderer() { return *renderer_; }
  [[nodiscard]] QueryExecutor* executor() { return executor_; }
  /// Query answers dropped because they were issued for a replaced model.
  [[nodiscard]] std::uint64_t stale_results() const { return stale_results_; }

 private:
  FrameResult begin_scene(const FrameLists& lists);
  void hold(const Hierarchy& h);

  Controller* controller_;
  Renderer* renderer_;
  QueryExecutor* executor_;
  CutBuffer cut_;
  SceneCutBuffer scene_cut_;
  const StageScene* scene_ = nullptr;                  // the scene set up for (identity only)
  std::uint64_t scene_generation_ = 0;                 // of the lists in scene_cut_
  std::vector<const Hierarchy*> models_;               // the scene's models, for upload()
  std::vector<std::span<const NodeId>> object_lists_;  // reused
  FrameResult current_;
  std::uint64_t model_frame_ = 0;  // the frame that first drew the current model (0: the first)
  std::uint64_t stale_results_ = 0;
  std::vector<VisibilityResult> kept_;  // reused by the filter of stale answers
  PagedHierarchy* paged_ = nullptr;
  GpuPoolOptions gpu_;
  std::unique_ptr<GpuNodePool> pool_;
};

}  // namespace treecut::splat
