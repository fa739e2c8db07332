// Private to splat/src/render/: what the renderer's files share (the set-up
// in renderer.cpp, the draw passes in renderer_draw.cpp, the in-frame ranges
// in frame_ranges.cpp). Render thread only, like the renderer.
#pragma once

#include <glm/vec4.hpp>

#include "treecut/splat/gl.hpp"
#include "treecut/splat/gl_objects.hpp"

namespace treecut::splat::render_detail {

inline void clear_color(const gl::Framebuffer& fbo, GLint buffer, glm::vec4 value) {
  gl::ClearNamedFramebufferfv(fbo.id(), GL_COLOR, buffer, &value.x);
}

inline void clear_depth(const gl::Framebuffer& fbo) {
  const float one = 1.0f;
  gl::ClearNamedFramebufferfv(fbo.id(), GL_DEPTH, 0, &one);
}

}  // namespace treecut::splat::render_detail
