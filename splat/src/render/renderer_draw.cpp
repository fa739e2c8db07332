// The renderer's draw passes: draw, draw_scene and draw_ranges (one
// render() for all three: a mode's passes over the planned runs, the query
// and range hooks between them), and the checks that a cut matches the
// vertex buffer. The in-frame ranges of CHC are in frame_ranges.cpp.
//
// Botsch, Hornung, Zwicker, Kobbelt: High-Quality Surface Splatting on Today's
// GPUs (Eurographics Symposium on Point-Based Graphics 2005) for the
// high-quality mode; QSplat's round splats for coarse nodes.
#include <algorithm>
#include <chrono>
#include <cstdint>
#include <glm/gtc/matrix_inverse.hpp>
#include <glm/gtc/type_ptr.hpp>
#include <span>
#include <stdexcept>
#include <string>

#include "renderer_internal.hpp"
#include "treecut/splat/renderer.hpp"
#include "treecut/splat/scene_draw.hpp"

namespace treecut::splat {

using render_detail::clear_color;
using render_detail::clear_depth;

void Renderer::check_cut(const CutBuffer& cut) {
  // An empty buffer draws nothing, whatever it was uploaded for.
  if (cut.size() + cut.leaving() == 0) {
    last_max_id_ = 0;
    return;
  }
  if (cut.hierarchy() != hierarchy_) {
    throw std::logic_error(
        "Renderer: the cut belongs to another hierarchy than the vertex buffer "
        "(set_hierarchy first)");
  }
  if (cut.max_vertex() >= node_count_) {
    throw std::logic_error("Renderer: the cut names vertex " + std::to_string(cut.max_vertex()) +
                           ", the vertex buffer holds " + std::to_string(node_count_));
  }
  last_max_id_ = cut.max_id();
}

void Renderer::plan_runs(const CutBuffer& cut, std::span<const CutRange> ranges, bool sorted) {
  runs_.clear();
  run_hook_.clear();
  const auto count = static_cast<std::uint32_t>(cut.size());
  const bool fading = cut.fading();
  if (!cut.segment_runs().empty()) {
    // A pool's segments (only whole lists: draw_ranges refuses them): a
    // draw call a group, each reading its segment.
    for (const CutBuffer::SegmentRun& g : cut.segment_runs()) {
      if (g.part == 2 && !fading) continue;
      const int fade = g.part == 2 ? 2 : g.part == 1 && fading ? 1 : 0;
      runs_.push_back(Run{g.first, g.count, fade, false, g.segment});
      run_hook_.push_back(SIZE_MAX);
    }
    return;
  }
  const auto stable = static_cast<std::uint32_t>(cut.stable());
  std::span<const CutRange> order = ranges;
  if (sorted) {
    sorted_ranges_.assign(ranges.begin(), ranges.end());
    std::sort(sorted_ranges_.begin(), sorted_ranges_.end(),
              [](const CutRange& x, const CutRange& y) { return x.first < y.first; });
    order = sorted_ranges_;
  }
  auto add = [&](std::uint32_t first, std::uint32_t n, int fade) {
    if (n == 0) return;
    // Adjacent runs of one kind are one draw call (the buffer-order pass of
    // a partition becomes the one-call draw again).
    if (sorted && !runs_.empty() && run_hook_.back() == SIZE_MAX && runs_.back().fade == fade &&
        runs_.back().first + runs_.back().count == first) {
      runs_.back().count += n;
      return;
    }
    runs_.push_back(Run{first, n, fade});
    run_hook_.push_back(SIZE_MAX);
  };
  for (std::size_t i = 0; i < order.size(); ++i) {
    const std::uint32_t first = std::min(order[i].first, count);
    const std::uint32_t end = first + std::min(order[i].count, count - first);
    if (fading && first < stable && end > stable) {
      add(first, stable - first, 0);
      add(stable, end - stable, 1);
    } else {
      add(first, end - first, fading && first >= stable ? 1 : 0);
    }
    if (!sorted) {
      // The hook runs after this range even when it drew nothing.
      if (runs_.empty() || run_hook_.back() != SIZE_MAX) runs_.push_back(Run{first, 0, 0});
      if (run_hook_.size() < runs_.size()) run_hook_.push_back(SIZE_MAX);
      run_hook_.back() = i;
    }
  }
  if (fading) add(count, static_cast<std::uint32_t>(cut.leaving()), 2);
}

void Renderer::draw_runs(GLuint elements, const gl::Program& program, const Uniforms& u,
                         RangeHook* hook, const ViewSnapshot& frame, GLuint fbo,
                         bool depth_writes) {
  // The exchange point: the cut is just the element buffer of the node VAO.
  gl::VertexArrayElementBuffer(vao_.id(), elements);
  gl::BindVertexArray(vao_.id());
  gl::UseProgram(program.id());
  int fade = 0;
  gl::ProgramUniform1i(program.id(), u.fade_mode, 0);
  for (std::size_t r = 0; r < runs_.size(); ++r) {
    const Run& run = runs_[r];
    if (run.indirect) {
      // A scene: every object's run in a segment, one command each, in one call.
      if (run.segment != bound_segment_) bind_segment(run.segment);
      gl::BindBuffer(GL_DRAW_INDIRECT_BUFFER, indirect_);
      gl::MultiDrawElementsIndirect(
          GL_POINTS, GL_UNSIGNED_INT,
          reinterpret_cast<const void*>(std::uintptr_t{run.first} * 5 * sizeof(std::uint32_t)),
          static_cast<GLsizei>(run.count), 0);
      gl::BindBuffer(GL_DRAW_INDIRECT_BUFFER, 0);
      ++draw_calls_;
    } else if (run.count > 0) {
      if (run.fade != fade) {
        fade = run.fade;
        gl::ProgramUniform1i(program.id(), u.fade_mode, fade);
      }
      if (run.segment != bound_segment_) bind_segment(run.segment);
      gl::DrawElements(GL_POINTS, static_cast<GLsizei>(run.count), GL_UNSIGNED_INT,
                       reinterpret_cast<const void*>(std::uintptr_t{run.first} * sizeof(NodeId)));
      ++draw_calls_;
    }
    if (hook != nullptr && run_hook_[r] != SIZE_MAX) {
      gl::ColorMask(GL_FALSE, GL_FALSE, GL_FALSE, GL_FALSE);
      gl::DepthMask(GL_FALSE);
      hook->after_range(run_hook_[r], frame);
      gl::ColorMask(GL_TRUE, GL_TRUE, GL_TRUE, GL_TRUE);
      gl::DepthMask(depth_writes ? GL_TRUE : GL_FALSE);
      gl::BindFramebuffer(GL_FRAMEBUFFER, fbo);
      gl::BindVertexArray(vao_.id());
      gl::UseProgram(program.id());
    }
  }
}

FrameStats Renderer::draw(const CutBuffer& cut, const Camera& camera,
                          const RenderSettings& settings, bool finish) {
  const CutRange all{0, static_cast<std::uint32_t>(cut.size())};
  return render(&cut, nullptr, std::span<const CutRange>(&all, 1), true, camera, settings, nullptr,
                finish);
}

FrameStats Renderer::draw_scene(const SceneCutBuffer& scene, const Camera& camera,
                                const RenderSettings& settings, bool finish) {
  return render(nullptr, &scene, {}, true, camera, settings, nullptr, finish);
}

FrameStats Renderer::draw_ranges(const CutBuffer& cut, std::span<const CutRange> ranges,
                                 const Camera& camera, const RenderSettings& settings,
                                 RangeHook* hook, bool finish) {
  if (!cut.segment_runs().empty()) {
    throw std::logic_error(
        "Renderer::draw_ranges: the list lies in several segments of a pool (draw it whole)");
  }
  return render(&cut, nullptr, ranges, false, camera, settings, hook, finish);
}

FrameStats Renderer::render(const CutBuffer* cut, const SceneCutBuffer* scene,
                            std::span<const CutRange> ranges, bool whole, const Camera& camera,
                            const RenderSettings& settings, RangeHook* hook, bool finish) {
  const auto start = std::chrono::steady_clock::now();
  // What is drawn: a model's cut (its runs: one, or three while it fades;
  // ranges for draw_ranges) or a scene's objects (one indirect run).
  GLuint elements = 0;
  float fade_weight = 1.0f;
  std::size_t splats = 0;
  std::uint64_t points = 0;
  if (scene != nullptr) {
    check_scene(*scene);
    runs_.clear();
    run_hook_.clear();
    // A run of commands a segment (one without a pool).
    for (const SceneCutBuffer::SegmentRun& g : scene->segment_runs()) {
      runs_.push_back(Run{g.first, g.count, 0, true, g.segment});
      run_hook_.push_back(SIZE_MAX);
    }
    elements = scene->elements().id();
    indirect_ = scene->indirect().id();
    bind_objects(scene->objects());
    splats = scene->size();
    points = scene->points();
  } else {
    check_cut(*cut);
    plan_runs(*cut, ranges, whole);
    for (const Run& r : runs_) splats += r.fade == 2 ? 0 : r.count;
    elements = cut->buffer().id();
    fade_weight = cut->fade();
    points = whole ? cut->points() : 0;
  }
  draw_calls_ = 0;
  const ViewSnapshot frame = camera.view(size_);

  gl::Viewport(0, 0, size_.x, size_.y);
  gl::Disable(GL_BLEND);
  gl::Enable(GL_DEPTH_TEST);
  gl::DepthMask(GL_TRUE);
  gl::ColorMask(GL_TRUE, GL_TRUE, GL_TRUE, GL_TRUE);
  draw_passes(elements, frame, settings, fade_weight, hook, cut, ranges, whole);
  if (settings.eye_dome > 0.0f && settings.mode != SplatMode::ObjectId) {
    draw_eye_dome(frame, settings);
  }
  gl::BindVertexArray(0);
  gl::UseProgram(0);
  gl::BindFramebuffer(GL_FRAMEBUFFER, 0);
  // Instance 0 of every other draw is the identity again.
  if (scene != nullptr) bind_objects(identity_object_);
  if (finish) gl::Finish();

  FrameStats stats;
  stats.splats = splats;
  stats.points = points;
  stats.draw_calls = draw_calls_;
  stats.finished = finish;
  stats.cpu_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  return stats;
}

// The query hook of the frame (if any), after the frame's draws into `fbo`,
// with color and depth writes off.
void Renderer::run_query_hook(GLuint fbo, const ViewSnapshot& frame) {
  if (query_hook_ == nullptr) return;
  gl::BindFramebuffer(GL_FRAMEBUFFER, fbo);
  gl::ColorMask(GL_FALSE, GL_FALSE, GL_FALSE, GL_FALSE);
  gl::DepthMask(GL_FALSE);
  query_hook_->run(frame);
  gl::ColorMask(GL_TRUE, GL_TRUE, GL_TRUE, GL_TRUE);
  gl::DepthMask(GL_TRUE);
}

// The passes of settings.mode over the planned runs of `elements`.
void Renderer::draw_passes(GLuint elements, const ViewSnapshot& frame,
                           const RenderSettings& settings, float fade_weight, RangeHook* hook,
                           const CutBuffer* cut, std::span<const CutRange> ranges, bool whole) {
  const glm::vec4 background(settings.background, 1.0f);
  switch (settings.mode) {
    case SplatMode::Fast: {
      clear_color(scene_fbo_, 0, background);
      clear_depth(scene_fbo_);
      gl::BindFramebuffer(GL_FRAMEBUFFER, scene_fbo_.id());
      gl::DepthFunc(GL_LESS);
      set_common_uniforms(fast_, fast_u_, frame, settings, fade_weight);
      gl::ProgramUniform1f(fast_.id(), fast_u_.depth_offset, 0.0f);
      draw_runs(elements, fast_, fast_u_, hook, frame, scene_fbo_.id(), true);
      run_query_hook(scene_fbo_.id(), frame);
      break;
    }
    case SplatMode::HighQuality:
      draw_high_quality(elements, frame, settings, fade_weight, hook, cut, ranges, whole);
      break;
    case SplatMode::ObjectId: {
      // White = no object: an index would need 2^24 - 1 objects to mean it.
      clear_color(scene_fbo_, 0, glm::vec4(1.0f));
      clear_depth(scene_fbo_);
      gl::BindFramebuffer(GL_FRAMEBUFFER, scene_fbo_.id());
      gl::DepthFunc(GL_LESS);
      set_common_uniforms(object_id_, object_id_u_, frame, settings, fade_weight);
      gl::ProgramUniform1f(object_id_.id(), object_id_u_.depth_offset, 0.0f);
      draw_runs(elements, object_id_, object_id_u_, hook, frame, scene_fbo_.id(), true);
      run_query_hook(scene_fbo_.id(), frame);
      break;
    }
    case SplatMode::FixedSize: {
      clear_color(scene_fbo_, 0, background);
      clear_depth(scene_fbo_);
      gl::BindFramebuffer(GL_FRAMEBUFFER, scene_fbo_.id());
      gl::DepthFunc(GL_LESS);
      gl::Enable(GL_PROGRAM_POINT_SIZE);
      set_common_uniforms(fixed_, fixed_u_, frame, settings, fade_weight);
      gl::ProgramUniform1f(fixed_.id(), fixed_u_.point_size,
                           std::max(settings.point_size_px, 1.0f));
      draw_runs(elements, fixed_, fixed_u_, hook, frame, scene_fbo_.id(), true);
      gl::Disable(GL_PROGRAM_POINT_SIZE);
      run_query_hook(scene_fbo_.id(), frame);
      break;
    }
  }
}

// Eye-dome lighting (shaders.hpp): the frame's colour times a shade from
// its depth, one full-screen triangle.
void Renderer::draw_eye_dome(const ViewSnapshot& frame, const RenderSettings& settings) {
  gl::BindFramebuffer(GL_FRAMEBUFFER, color_fbo_.id());
  gl::Disable(GL_DEPTH_TEST);
  gl::Enable(GL_BLEND);
  gl::BlendEquation(GL_FUNC_ADD);
  gl::BlendFunc(GL_ZERO, GL_SRC_COLOR);
  const GLuint p = eye_dome_.id();
  gl::ProgramUniform1f(p, eye_dome_near_, frame.derived.near_plane);
  gl::ProgramUniform1f(p, eye_dome_far_, frame.derived.far_plane);
  gl::ProgramUniform1i(p, eye_dome_perspective_, frame.derived.perspective ? 1 : 0);
  gl::ProgramUniform1f(p, eye_dome_strength_, settings.eye_dome);
  gl::ProgramUniform1f(p, eye_dome_radius_, std::max(settings.eye_dome_radius, 1.0f));
  gl::UseProgram(p);
  gl::BindTextureUnit(0, depth_.id());
  gl::BindVertexArray(empty_vao_.id());
  gl::DrawArrays(GL_TRIANGLES, 0, 3);
  gl::BindTextureUnit(0, 0);
  gl::Disable(GL_BLEND);
  gl::Enable(GL_DEPTH_TEST);
}

// High quality (Botsch et al.): visibility, attributes, normalization.
void Renderer::draw_high_quality(GLuint elements, const ViewSnapshot& frame,
                                 const RenderSettings& settings, float fade_weight, RangeHook* hook,
                                 const CutBuffer* cut, std::span<const CutRange> ranges,
                                 bool whole) {
  // Pass 1: visibility, pushed back by depth_offset radii; the ranges in
  // their order, with the hook between them.
  clear_depth(visibility_fbo_);
  gl::BindFramebuffer(GL_FRAMEBUFFER, visibility_fbo_.id());
  gl::DepthFunc(GL_LESS);
  set_common_uniforms(hq_visibility_, hq_visibility_u_, frame, settings, fade_weight);
  gl::ProgramUniform1f(hq_visibility_.id(), hq_visibility_u_.depth_offset, settings.depth_offset);
  draw_runs(elements, hq_visibility_, hq_visibility_u_, hook, frame, visibility_fbo_.id(), true);
  run_query_hook(visibility_fbo_.id(), frame);

  // Pass 2: attributes of every splat in front of the offset surface.
  // Additive blending in half floats depends on the order, so the ranges
  // go in buffer order: the primitive order of the one-call draw.
  if (!whole) plan_runs(*cut, ranges, true);
  clear_color(accum_fbo_, 0, glm::vec4(0.0f));
  clear_color(accum_fbo_, 1, glm::vec4(0.0f));
  gl::BindFramebuffer(GL_FRAMEBUFFER, accum_fbo_.id());
  gl::DepthFunc(GL_LEQUAL);
  gl::DepthMask(GL_FALSE);
  gl::Enable(GL_BLEND);
  gl::BlendEquation(GL_FUNC_ADD);
  gl::BlendFunc(GL_ONE, GL_ONE);
  set_common_uniforms(hq_attributes_, hq_attributes_u_, frame, settings, fade_weight);
  gl::ProgramUniform1f(hq_attributes_.id(), hq_attributes_u_.depth_offset, 0.0f);
  draw_runs(elements, hq_attributes_, hq_attributes_u_, nullptr, frame, accum_fbo_.id(), false);
  gl::Disable(GL_BLEND);
  gl::DepthMask(GL_TRUE);

  // Pass 3: normalization and per-pixel lighting.
  const glm::vec4 background(settings.background, 1.0f);
  clear_color(scene_fbo_, 0, background);
  gl::BindFramebuffer(GL_FRAMEBUFFER, scene_fbo_.id());
  gl::Disable(GL_DEPTH_TEST);
  set_common_uniforms(hq_normalize_, hq_normalize_u_, frame, settings, fade_weight);
  // Positions relative to the eye, as the passes before drew them.
  const glm::mat4 inv_view_proj = glm::inverse(frame.projection * frame.eye_relative_view());
  gl::ProgramUniformMatrix4fv(hq_normalize_.id(), hq_normalize_u_.inv_view_proj, 1, GL_FALSE,
                              glm::value_ptr(inv_view_proj));
  gl::UseProgram(hq_normalize_.id());
  gl::BindTextureUnit(0, accum_color_.id());
  gl::BindTextureUnit(1, accum_normal_.id());
  gl::BindTextureUnit(2, depth_.id());
  gl::BindVertexArray(empty_vao_.id());
  gl::DrawArrays(GL_TRIANGLES, 0, 3);
  gl::BindTextureUnit(0, 0);
  gl::BindTextureUnit(1, 0);
  gl::BindTextureUnit(2, 0);
  gl::Enable(GL_DEPTH_TEST);
}

}  // namespace treecut::splat
