// In-frame drawing (renderer.hpp, begin_frame_ranges): a frame of ranges a
// traversal chooses while it draws (CHC, splat/occlusion_device_gl.hpp),
// one draw call per range into the scene framebuffer, one-pass modes only.
#include <algorithm>
#include <chrono>
#include <cstdint>
#include <glm/vec4.hpp>
#include <stdexcept>
#include <string>

#include "renderer_internal.hpp"
#include "treecut/splat/renderer.hpp"

namespace treecut::splat {

using render_detail::clear_color;
using render_detail::clear_depth;

void Renderer::begin_frame_ranges(const gl::Buffer& elements, NodeId max_id, const Camera& camera,
                                  const RenderSettings& settings) {
  if (settings.mode == SplatMode::HighQuality) {
    throw std::invalid_argument(
        "Renderer: in-frame ranges need a one-pass mode (fast, fixed or id)");
  }
  if (pooled_)
    throw std::logic_error("Renderer: in-frame ranges name nodes, a pool's vertices not");
  if (max_id >= node_count_) {
    throw std::logic_error("Renderer: the ranges name node " + std::to_string(max_id) +
                           ", the vertex buffer holds " + std::to_string(node_count_));
  }
  in_frame_start_ = std::chrono::steady_clock::now();
  in_frame_view_ = camera.view(size_);
  in_frame_splats_ = 0;
  draw_calls_ = 0;
  const bool fixed = settings.mode == SplatMode::FixedSize;
  const bool ids = settings.mode == SplatMode::ObjectId;
  in_frame_program_ = fixed ? &fixed_ : ids ? &object_id_ : &fast_;
  const Uniforms& u = fixed ? fixed_u_ : ids ? object_id_u_ : fast_u_;
  set_common_uniforms(*in_frame_program_, u, in_frame_view_, settings, 1.0f);
  gl::ProgramUniform1i(in_frame_program_->id(), u.fade_mode, 0);
  if (fixed) {
    gl::ProgramUniform1f(fixed_.id(), u.point_size, std::max(settings.point_size_px, 1.0f));
    gl::Enable(GL_PROGRAM_POINT_SIZE);
  } else {
    gl::ProgramUniform1f(in_frame_program_->id(), u.depth_offset, 0.0f);
  }
  gl::VertexArrayElementBuffer(vao_.id(), elements.id());
  gl::Viewport(0, 0, size_.x, size_.y);
  gl::Disable(GL_BLEND);
  gl::Enable(GL_DEPTH_TEST);
  gl::DepthFunc(GL_LESS);
  clear_color(scene_fbo_, 0, ids ? glm::vec4(1.0f) : glm::vec4(settings.background, 1.0f));
  clear_depth(scene_fbo_);
  gl::BindFramebuffer(GL_FRAMEBUFFER, scene_fbo_.id());
  last_max_id_ = max_id;
}

void Renderer::draw_frame_range(std::uint32_t first, std::uint32_t count) {
  if (in_frame_program_ == nullptr) throw std::logic_error("Renderer: no frame of ranges is open");
  if (count == 0) return;
  // The caller's queries may have changed these since the last range.
  gl::ColorMask(GL_TRUE, GL_TRUE, GL_TRUE, GL_TRUE);
  gl::DepthMask(GL_TRUE);
  gl::DepthFunc(GL_LESS);
  gl::BindVertexArray(vao_.id());
  gl::UseProgram(in_frame_program_->id());
  gl::DrawElements(GL_POINTS, static_cast<GLsizei>(count), GL_UNSIGNED_INT,
                   reinterpret_cast<const void*>(std::uintptr_t{first} * sizeof(NodeId)));
  in_frame_splats_ += count;
  ++draw_calls_;
}

FrameStats Renderer::end_frame_ranges(bool finish) {
  if (in_frame_program_ == nullptr) throw std::logic_error("Renderer: no frame of ranges is open");
  if (in_frame_program_ == &fixed_) gl::Disable(GL_PROGRAM_POINT_SIZE);
  in_frame_program_ = nullptr;
  gl::ColorMask(GL_TRUE, GL_TRUE, GL_TRUE, GL_TRUE);
  gl::DepthMask(GL_TRUE);
  gl::BindVertexArray(0);
  gl::UseProgram(0);
  gl::BindFramebuffer(GL_FRAMEBUFFER, 0);
  if (finish) gl::Finish();
  FrameStats stats;
  stats.splats = in_frame_splats_;
  stats.draw_calls = draw_calls_;
  stats.finished = finish;
  stats.cpu_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - in_frame_start_)
          .count();
  return stats;
}

}  // namespace treecut::splat
