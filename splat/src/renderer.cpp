// Botsch, Hornung, Zwicker, Kobbelt: High-Quality Surface Splatting on Today's
// GPUs (Eurographics Symposium on Point-Based Graphics 2005) for the
// high-quality mode; QSplat's round splats for coarse nodes.
#include "treecut/splat/renderer.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <chrono>
#include <cstring>
#include <glm/geometric.hpp>
#include <glm/gtc/matrix_inverse.hpp>
#include <glm/gtc/type_ptr.hpp>
#include <glm/mat3x3.hpp>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "shaders.hpp"
#include "treecut/error.hpp"
#include "treecut/tree_cut.hpp"

namespace treecut::splat {

std::string_view splat_mode_name(SplatMode mode) {
  switch (mode) {
    case SplatMode::Fast:
      return "fast";
    case SplatMode::HighQuality:
      return "hq";
    case SplatMode::FixedSize:
      return "fixed";
  }
  return "?";
}

SplatMode parse_splat_mode(std::string_view name) {
  if (name == "fast") return SplatMode::Fast;
  if (name == "hq" || name == "high-quality") return SplatMode::HighQuality;
  if (name == "fixed") return SplatMode::FixedSize;
  throw InputError("unknown splat mode '" + std::string(name) + "' (expected fast, hq or fixed)");
}

void CutBuffer::upload(const Hierarchy& h, std::span<const NodeId> nodes) {
  // Draw in node-id order. Ids are breadth-first over a spatial tree, so this
  // order is spatially coherent; llvmpipe's rasterizer threads read each
  // triangle's setup data in submission order, and a strategy's cut order
  // (scattered by refines and coarsens) made them miss the cache on almost
  // every splat (docs/rendering.md, "Submission order").
  std::span<const NodeId> ordered = nodes;
  if (!std::is_sorted(nodes.begin(), nodes.end())) {
    sorted_.assign(nodes.begin(), nodes.end());
    sort_node_ids(sorted_, h.node_count(), scratch_);
    ordered = sorted_;
  }
  // Counted in id order: ascending addresses, which the prefetcher follows.
  std::uint64_t points = 0;
  const auto counts = h.arrays().point_count;
  for (const NodeId n : ordered) points += counts[n];
  // Write the buffer the last draws did not read: a driver with frames in
  // flight need not wait for them (or copy the buffer) before the write.
  const std::size_t next = buffers_[current_] ? 1 - current_ : current_;
  gl::Buffer& target = buffers_[next];
  const std::size_t bytes = ordered.size_bytes();
  if (!target || target.size() < bytes) {
    const std::size_t capacity = std::bit_ceil(std::max<std::size_t>(bytes, 4096));
    target = gl::Buffer::create(capacity, nullptr, GL_DYNAMIC_STORAGE_BIT);
  }
  target.sub_data(0, std::as_bytes(ordered));
  current_ = next;
  count_ = nodes.size();
  points_ = points;
}

namespace {

// `defines` ("#define NAME 1\n" lines) go between kCommon and each body.
gl::Program make_program(std::initializer_list<std::pair<GLenum, const char*>> stages,
                         std::string_view label, std::string_view defines = {}) {
  std::vector<gl::Shader> shaders;
  shaders.reserve(stages.size());
  for (const auto& [stage, body] : stages) {
    shaders.push_back(gl::Shader::compile(
        stage, std::string(shaders::kCommon) + std::string(defines) + body, label));
  }
  std::vector<const gl::Shader*> pointers;
  for (const auto& s : shaders) pointers.push_back(&s);
  return gl::Program::link(pointers, label);
}

void clear_color(const gl::Framebuffer& fbo, GLint buffer, glm::vec4 value) {
  gl::ClearNamedFramebufferfv(fbo.id(), GL_COLOR, buffer, &value.x);
}

void clear_depth(const gl::Framebuffer& fbo) {
  const float one = 1.0f;
  gl::ClearNamedFramebufferfv(fbo.id(), GL_DEPTH, 0, &one);
}

}  // namespace

Renderer::Renderer(const Hierarchy& h, glm::ivec2 size) : node_count_(h.node_count()) {
  if (h.empty()) throw std::invalid_argument("Renderer: empty hierarchy");
  if (!gl::loaded()) throw gl::GlError("Renderer: no GL context is current");
  const HierarchyArrays& a = h.arrays();
  const std::size_t n = h.node_count();
  const std::size_t cr_bytes = n * sizeof(glm::vec4);
  const std::size_t nc_bytes = n * sizeof(glm::i16vec4);
  const std::size_t co_bytes = n * sizeof(glm::u8vec4);
  // One static buffer holding the three node arrays back to back.
  nodes_ = gl::Buffer::create(cr_bytes + nc_bytes + co_bytes, nullptr, GL_DYNAMIC_STORAGE_BIT);
  nodes_.sub_data(0, std::as_bytes(a.center_radius));
  nodes_.sub_data(cr_bytes, std::as_bytes(a.normal_cone));
  nodes_.sub_data(cr_bytes + nc_bytes, std::as_bytes(a.color));

  vao_ = gl::VertexArray::create();
  const GLuint vao = vao_.id();
  gl::VertexArrayVertexBuffer(vao, 0, nodes_.id(), 0, sizeof(glm::vec4));
  gl::VertexArrayVertexBuffer(vao, 1, nodes_.id(), static_cast<GLintptr>(cr_bytes),
                              sizeof(glm::i16vec4));
  gl::VertexArrayVertexBuffer(vao, 2, nodes_.id(), static_cast<GLintptr>(cr_bytes + nc_bytes),
                              sizeof(glm::u8vec4));
  gl::VertexArrayAttribFormat(vao, 0, 4, GL_FLOAT, GL_FALSE, 0);
  gl::VertexArrayAttribFormat(vao, 1, 4, GL_SHORT, GL_TRUE, 0);
  gl::VertexArrayAttribFormat(vao, 2, 4, GL_UNSIGNED_BYTE, GL_TRUE, 0);
  for (GLuint i = 0; i < 3; ++i) {
    gl::VertexArrayAttribBinding(vao, i, i);
    gl::EnableVertexArrayAttrib(vao, i);
  }
  empty_vao_ = gl::VertexArray::create();

  fast_ = make_program({{GL_VERTEX_SHADER, shaders::kSplatVertex},
                        {GL_GEOMETRY_SHADER, shaders::kSplatGeometry},
                        {GL_FRAGMENT_SHADER, shaders::kFastFragment}},
                       "splat fast", "#define SPLAT_LIT 1\n");
  hq_visibility_ = make_program({{GL_VERTEX_SHADER, shaders::kSplatVertex},
                                 {GL_GEOMETRY_SHADER, shaders::kSplatGeometry},
                                 {GL_FRAGMENT_SHADER, shaders::kVisibilityFragment}},
                                "splat hq visibility");
  hq_attributes_ = make_program({{GL_VERTEX_SHADER, shaders::kSplatVertex},
                                 {GL_GEOMETRY_SHADER, shaders::kSplatGeometry},
                                 {GL_FRAGMENT_SHADER, shaders::kAttributeFragment}},
                                "splat hq attributes");
  hq_normalize_ = make_program({{GL_VERTEX_SHADER, shaders::kFullscreenVertex},
                                {GL_FRAGMENT_SHADER, shaders::kNormalizeFragment}},
                               "splat hq normalize");
  fixed_ = make_program(
      {{GL_VERTEX_SHADER, shaders::kFixedVertex}, {GL_FRAGMENT_SHADER, shaders::kFixedFragment}},
      "splat fixed");
  resize(size);
  gl::check("Renderer setup");
}

Renderer::~Renderer() = default;

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

  accum_fbo_ = gl::Framebuffer::create();
  accum_fbo_.attach(GL_COLOR_ATTACHMENT0, accum_color_);
  accum_fbo_.attach(GL_COLOR_ATTACHMENT1, accum_normal_);
  accum_fbo_.attach(GL_DEPTH_ATTACHMENT, depth_);
  const std::array<GLenum, 2> two{GL_COLOR_ATTACHMENT0, GL_COLOR_ATTACHMENT1};
  accum_fbo_.set_draw_buffers(two, "accumulation framebuffer");
}

void Renderer::draw_splats(const CutBuffer& cut) const {
  if (cut.size() == 0) return;
  // The exchange point: the cut is just the element buffer of the node VAO.
  gl::VertexArrayElementBuffer(vao_.id(), cut.buffer().id());
  gl::BindVertexArray(vao_.id());
  gl::DrawElements(GL_POINTS, static_cast<GLsizei>(cut.size()), GL_UNSIGNED_INT, nullptr);
}

FrameStats Renderer::draw(const CutBuffer& cut, const Camera& camera,
                          const RenderSettings& settings, bool finish) {
  const auto start = std::chrono::steady_clock::now();
  const float aspect = static_cast<float>(size_.x) / static_cast<float>(size_.y);
  FrameView frame;
  frame.view = camera.view_matrix();
  frame.projection = camera.projection_matrix(aspect);
  frame.eye = camera.eye;
  frame.size = size_;

  const Light& light = settings.light;
  glm::vec3 light_dir = light.direction;
  if (light.follow_camera) light_dir = glm::mat3(glm::inverse(frame.view)) * light_dir;
  const float light_len = glm::length(light_dir);
  light_dir = light_len > 0.0f ? light_dir / light_len : glm::vec3(0.0f, 0.0f, 1.0f);

  auto set_common = [&](const gl::Program& p) {
    p.set_mat4("u_view", glm::value_ptr(frame.view));
    p.set_mat4("u_proj", glm::value_ptr(frame.projection));
    p.set("u_eye", frame.eye.x, frame.eye.y, frame.eye.z);
    p.set("u_radius_scale", settings.radius_scale);
    p.set("u_cull", settings.backface_culling ? 1 : 0);
    p.set("u_min_radius_px", 0.75f);
    p.set("u_viewport_h", static_cast<float>(size_.y));
    p.set("u_light_dir", light_dir.x, light_dir.y, light_dir.z);
    p.set("u_light", light.ambient, light.diffuse, light.specular, light.shininess);
  };

  gl::Viewport(0, 0, size_.x, size_.y);
  gl::Disable(GL_BLEND);
  gl::Enable(GL_DEPTH_TEST);
  gl::DepthMask(GL_TRUE);
  gl::ColorMask(GL_TRUE, GL_TRUE, GL_TRUE, GL_TRUE);
  const glm::vec4 background(settings.background, 1.0f);

  auto run_hook = [&](GLuint fbo) {
    if (query_hook_ == nullptr) return;
    gl::BindFramebuffer(GL_FRAMEBUFFER, fbo);
    gl::ColorMask(GL_FALSE, GL_FALSE, GL_FALSE, GL_FALSE);
    gl::DepthMask(GL_FALSE);
    query_hook_->run(frame);
    gl::ColorMask(GL_TRUE, GL_TRUE, GL_TRUE, GL_TRUE);
    gl::DepthMask(GL_TRUE);
  };

  switch (settings.mode) {
    case SplatMode::Fast: {
      clear_color(scene_fbo_, 0, background);
      clear_depth(scene_fbo_);
      gl::BindFramebuffer(GL_FRAMEBUFFER, scene_fbo_.id());
      gl::DepthFunc(GL_LESS);
      set_common(fast_);
      fast_.set("u_depth_offset", 0.0f);
      gl::UseProgram(fast_.id());
      draw_splats(cut);
      run_hook(scene_fbo_.id());
      break;
    }
    case SplatMode::HighQuality: {
      // Pass 1: visibility, pushed back by depth_offset radii.
      clear_depth(visibility_fbo_);
      gl::BindFramebuffer(GL_FRAMEBUFFER, visibility_fbo_.id());
      gl::DepthFunc(GL_LESS);
      set_common(hq_visibility_);
      hq_visibility_.set("u_depth_offset", settings.depth_offset);
      gl::UseProgram(hq_visibility_.id());
      draw_splats(cut);
      run_hook(visibility_fbo_.id());

      // Pass 2: attributes of every splat in front of the offset surface.
      clear_color(accum_fbo_, 0, glm::vec4(0.0f));
      clear_color(accum_fbo_, 1, glm::vec4(0.0f));
      gl::BindFramebuffer(GL_FRAMEBUFFER, accum_fbo_.id());
      gl::DepthFunc(GL_LEQUAL);
      gl::DepthMask(GL_FALSE);
      gl::Enable(GL_BLEND);
      gl::BlendEquation(GL_FUNC_ADD);
      gl::BlendFunc(GL_ONE, GL_ONE);
      set_common(hq_attributes_);
      hq_attributes_.set("u_depth_offset", 0.0f);
      gl::UseProgram(hq_attributes_.id());
      draw_splats(cut);
      gl::Disable(GL_BLEND);
      gl::DepthMask(GL_TRUE);

      // Pass 3: normalization and per-pixel lighting.
      clear_color(scene_fbo_, 0, background);
      gl::BindFramebuffer(GL_FRAMEBUFFER, scene_fbo_.id());
      gl::Disable(GL_DEPTH_TEST);
      set_common(hq_normalize_);
      const glm::mat4 inv_view_proj = glm::inverse(frame.projection * frame.view);
      hq_normalize_.set_mat4("u_inv_view_proj", glm::value_ptr(inv_view_proj));
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
      break;
    }
    case SplatMode::FixedSize: {
      clear_color(scene_fbo_, 0, background);
      clear_depth(scene_fbo_);
      gl::BindFramebuffer(GL_FRAMEBUFFER, scene_fbo_.id());
      gl::DepthFunc(GL_LESS);
      gl::Enable(GL_PROGRAM_POINT_SIZE);
      set_common(fixed_);
      fixed_.set("u_point_size", std::max(settings.point_size_px, 1.0f));
      gl::UseProgram(fixed_.id());
      draw_splats(cut);
      gl::Disable(GL_PROGRAM_POINT_SIZE);
      run_hook(scene_fbo_.id());
      break;
    }
  }
  gl::BindVertexArray(0);
  gl::UseProgram(0);
  gl::BindFramebuffer(GL_FRAMEBUFFER, 0);
  if (finish) gl::Finish();

  FrameStats stats;
  stats.splats = cut.size();
  stats.points = cut.points();
  stats.finished = finish;
  stats.cpu_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  return stats;
}

void Renderer::present(glm::ivec2 window_size) const {
  gl::BlitNamedFramebuffer(scene_fbo_.id(), 0, 0, 0, size_.x, size_.y, 0, 0, window_size.x,
                           window_size.y, GL_COLOR_BUFFER_BIT, GL_NEAREST);
}

std::vector<std::uint8_t> Renderer::read_pixels() const {
  const auto w = static_cast<std::size_t>(size_.x);
  const auto h = static_cast<std::size_t>(size_.y);
  std::vector<std::uint8_t> bottom_up(w * h * 4);
  gl::BindFramebuffer(GL_READ_FRAMEBUFFER, scene_fbo_.id());
  gl::PixelStorei(GL_PACK_ALIGNMENT, 1);
  gl::ReadPixels(0, 0, size_.x, size_.y, GL_RGBA, GL_UNSIGNED_BYTE, bottom_up.data());
  gl::BindFramebuffer(GL_READ_FRAMEBUFFER, 0);
  gl::check("Renderer::read_pixels");
  std::vector<std::uint8_t> top_down(bottom_up.size());
  for (std::size_t y = 0; y < h; ++y) {
    std::memcpy(&top_down[y * w * 4], &bottom_up[(h - 1 - y) * w * 4], w * 4);
  }
  return top_down;
}

}  // namespace treecut::splat
