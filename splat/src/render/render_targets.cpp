// The renderer's render targets (the frame's color and depth, hq's
// accumulation buffers and the three framebuffers over them) and what reads
// the frame back: present() to a window, read_pixels() to memory, pick()
// one pixel's position.
#include <array>
#include <cstdint>
#include <glm/ext/matrix_double4x4.hpp>
#include <glm/matrix.hpp>
#include <optional>
#include <stdexcept>
#include <vector>

#include "treecut/splat/frame.hpp"
#include "treecut/splat/renderer.hpp"

namespace treecut::splat {

void Renderer::resize(glm::ivec2 size) {
  if (size.x <= 0 || size.y <= 0) throw std::invalid_argument("Renderer: size must be positive");
  if (size == size_ && color_) return;
  size_ = size;
  create_targets();
}

void Renderer::create_targets() {
  color_ = gl::Texture::create_2d(GL_RGBA8, size_.x, size_.y);
  depth_ = gl::Texture::create_2d(GL_DEPTH_COMPONENT24, size_.x, size_.y);
  accum_color_ = gl::Texture::create_2d(GL_RGBA16F, size_.x, size_.y);
  accum_normal_ = gl::Texture::create_2d(GL_RGBA16F, size_.x, size_.y);

  scene_fbo_ = gl::Framebuffer::create();
  scene_fbo_.attach(GL_COLOR_ATTACHMENT0, color_);
  scene_fbo_.attach(GL_DEPTH_ATTACHMENT, depth_);
  const std::array<GLenum, 1> one{GL_COLOR_ATTACHMENT0};
  scene_fbo_.set_draw_buffers(one, "scene framebuffer");

  visibility_fbo_ = gl::Framebuffer::create();
  visibility_fbo_.attach(GL_DEPTH_ATTACHMENT, depth_);
  visibility_fbo_.set_draw_buffers({}, "visibility framebuffer");

  color_fbo_ = gl::Framebuffer::create();
  color_fbo_.attach(GL_COLOR_ATTACHMENT0, color_);
  color_fbo_.set_draw_buffers(one, "colour framebuffer");

  accum_fbo_ = gl::Framebuffer::create();
  accum_fbo_.attach(GL_COLOR_ATTACHMENT0, accum_color_);
  accum_fbo_.attach(GL_COLOR_ATTACHMENT1, accum_normal_);
  accum_fbo_.attach(GL_DEPTH_ATTACHMENT, depth_);
  const std::array<GLenum, 2> two{GL_COLOR_ATTACHMENT0, GL_COLOR_ATTACHMENT1};
  accum_fbo_.set_draw_buffers(two, "accumulation framebuffer");
}

void Renderer::present(glm::ivec2 window_size) const {
  gl::BlitNamedFramebuffer(scene_fbo_.id(), 0, 0, 0, size_.x, size_.y, 0, 0, window_size.x,
                           window_size.y, GL_COLOR_BUFFER_BIT, GL_NEAREST);
}

std::vector<std::uint8_t> Renderer::read_pixels() const {
  return read_back_rgba(scene_fbo_.id(), GL_COLOR_ATTACHMENT0, size_);
}

std::optional<glm::vec3> Renderer::pick(glm::ivec2 pixel, const Camera& camera) const {
  if (pixel.x < 0 || pixel.y < 0 || pixel.x >= size_.x || pixel.y >= size_.y) return std::nullopt;
  const int row = size_.y - 1 - pixel.y;  // GL's rows run bottom-up
  float depth = 1.0f;
  gl::BindFramebuffer(GL_READ_FRAMEBUFFER, scene_fbo_.id());
  gl::PixelStorei(GL_PACK_ALIGNMENT, 1);
  gl::ReadPixels(pixel.x, row, 1, 1, GL_DEPTH_COMPONENT, GL_FLOAT, &depth);
  gl::BindFramebuffer(GL_READ_FRAMEBUFFER, 0);
  gl::check("pick");
  if (!(depth < 1.0f)) return std::nullopt;
  // The frame was drawn relative to the eye (shaders.hpp): unproject there.
  const ViewSnapshot v = camera.view(size_);
  const glm::dvec4 ndc(2.0 * (pixel.x + 0.5) / size_.x - 1.0, 2.0 * (row + 0.5) / size_.y - 1.0,
                       2.0 * depth - 1.0, 1.0);
  const glm::dvec4 p =
      glm::inverse(glm::dmat4(v.projection) * glm::dmat4(v.eye_relative_view())) * ndc;
  return v.derived.eye + glm::vec3(glm::dvec3(p) / p.w);
}

}  // namespace treecut::splat
