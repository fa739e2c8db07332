// Renderer set-up: the splat modes' names, the programs (compiled from
// shaders.hpp) and their uniforms (looked up once; the per-frame ones every
// program reads), and the static vertex buffer of the models (set_models).
// The draws are in renderer_draw.cpp and frame_ranges.cpp, the render targets
// in render_targets.cpp, CutBuffer in cut_buffer.cpp.
//
// Botsch, Hornung, Zwicker, Kobbelt: High-Quality Surface Splatting on Today's
// GPUs (Eurographics Symposium on Point-Based Graphics 2005) for the
// high-quality mode; QSplat's round splats for coarse nodes.
#include "treecut/splat/renderer.hpp"

#include <array>
#include <bit>
#include <cstdint>
#include <glm/gtc/type_ptr.hpp>
#include <initializer_list>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "shaders.hpp"
#include "treecut/error.hpp"
#include "treecut/splat/frame.hpp"
#include "treecut/splat/scene_draw.hpp"

namespace treecut::splat {

std::string_view splat_mode_name(SplatMode mode) {
  switch (mode) {
    case SplatMode::Fast:
      return "fast";
    case SplatMode::HighQuality:
      return "hq";
    case SplatMode::FixedSize:
      return "fixed";
    case SplatMode::ObjectId:
      return "id";
  }
  return "?";
}

SplatMode parse_splat_mode(std::string_view name) {
  if (name == "fast") return SplatMode::Fast;
  if (name == "hq" || name == "high-quality") return SplatMode::HighQuality;
  if (name == "fixed") return SplatMode::FixedSize;
  if (name == "id") return SplatMode::ObjectId;
  throw InputError("unknown splat mode '" + std::string(name) +
                   "' (expected fast, hq, fixed or id)");
}

namespace {

// The vertex buffer of N vertices: four regions back to back (centers and
// bounds, normal cones, colours, drawn radii), each indexed by vertex.
struct VertexRegions {
  explicit VertexRegions(std::size_t vertices) : n(vertices) {}
  std::size_t n;
  [[nodiscard]] std::size_t center_radius(std::size_t v) const { return v * sizeof(glm::vec4); }
  [[nodiscard]] std::size_t normal_cone(std::size_t v) const {
    return n * sizeof(glm::vec4) + v * sizeof(glm::i16vec4);
  }
  [[nodiscard]] std::size_t color(std::size_t v) const {
    return n * (sizeof(glm::vec4) + sizeof(glm::i16vec4)) + v * sizeof(glm::u8vec4);
  }
  [[nodiscard]] std::size_t splat_radius(std::size_t v) const {
    return n * (sizeof(glm::vec4) + sizeof(glm::i16vec4) + sizeof(glm::u8vec4)) + v * sizeof(float);
  }
  [[nodiscard]] std::size_t bytes() const { return splat_radius(n); }
};

// `defines` ("#define NAME 1\n" lines) go between kCommon and each body.
gl::Program make_program(std::initializer_list<std::pair<GLenum, const char*>> stages,
                         std::string_view label, std::string_view defines = {}) {
  std::vector<gl::Shader> shaders;
  shaders.reserve(stages.size());
  for (const auto& [stage, body] : stages) {
    // Fragment stages also get the fade's dither (it reads gl_FragCoord),
    // vertex stages the object's transform (a stage that does not use it
    // leaves the attributes unused).
    const char* prefix = stage == GL_FRAGMENT_SHADER ? shaders::kFragmentCommon
                         : stage == GL_VERTEX_SHADER ? shaders::kObjectVertex
                                                     : "";
    shaders.push_back(gl::Shader::compile(
        stage, std::string(shaders::kCommon) + std::string(defines) + prefix + body, label));
  }
  std::vector<const gl::Shader*> pointers;
  for (const auto& s : shaders) pointers.push_back(&s);
  return gl::Program::link(pointers, label);
}

}  // namespace

Renderer::Uniforms Renderer::lookup_uniforms(const gl::Program& p) {
  auto at = [&](const char* name) { return gl::GetUniformLocation(p.id(), name); };
  Uniforms u;
  u.view = at("u_view");
  u.proj = at("u_proj");
  u.eye = at("u_eye");
  u.radius_scale = at("u_radius_scale");
  u.cull = at("u_cull");
  u.min_radius_px = at("u_min_radius_px");
  u.viewport_h = at("u_viewport_h");
  u.light_dir = at("u_light_dir");
  u.light = at("u_light");
  u.depth_offset = at("u_depth_offset");
  u.point_size = at("u_point_size");
  u.inv_view_proj = at("u_inv_view_proj");
  u.fade_mode = at("u_fade_mode");
  u.fade = at("u_fade");
  u.clip = at("u_clip");
  u.clip_min = at("u_clip_min");
  u.clip_max = at("u_clip_max");
  return u;
}

void Renderer::set_common_uniforms(const gl::Program& program, const Uniforms& u,
                                   const ViewSnapshot& frame, const RenderSettings& settings,
                                   float fade) const {
  const Light& light = settings.light;
  // The same direction the strategies are handed (frame.hpp): one function.
  const glm::vec3 light_dir = world_light_dir(light, frame.view);
  // Locations were looked up at link time (lookup_uniforms).
  const GLuint p = program.id();
  // Relative to the eye (shaders.hpp): the view's rotation; the eye is
  // subtracted from each point in the vertex stage.
  const glm::mat4 rotation = frame.eye_relative_view();
  gl::ProgramUniformMatrix4fv(p, u.view, 1, GL_FALSE, glm::value_ptr(rotation));
  gl::ProgramUniformMatrix4fv(p, u.proj, 1, GL_FALSE, glm::value_ptr(frame.projection));
  gl::ProgramUniform3f(p, u.eye, frame.derived.eye.x, frame.derived.eye.y, frame.derived.eye.z);
  gl::ProgramUniform1f(p, u.radius_scale, settings.radius_scale);
  gl::ProgramUniform1i(p, u.cull, settings.backface_culling ? 1 : 0);
  gl::ProgramUniform1f(p, u.min_radius_px, 0.75f);
  gl::ProgramUniform1f(p, u.viewport_h, static_cast<float>(size_.y));
  gl::ProgramUniform3f(p, u.light_dir, light_dir.x, light_dir.y, light_dir.z);
  if (light.unlit) {
    gl::ProgramUniform4f(p, u.light, 1.0f, 0.0f, 0.0f, light.shininess);
  } else {
    gl::ProgramUniform4f(p, u.light, light.ambient, light.diffuse, light.specular, light.shininess);
  }
  gl::ProgramUniform1f(p, u.fade, fade);
  // The clip box relative to the eye, as the positions are (shaders.hpp).
  gl::ProgramUniform1i(p, u.clip, settings.clip ? 1 : 0);
  const glm::vec3 lo = settings.clip_min - frame.derived.eye;
  const glm::vec3 hi = settings.clip_max - frame.derived.eye;
  gl::ProgramUniform3f(p, u.clip_min, lo.x, lo.y, lo.z);
  gl::ProgramUniform3f(p, u.clip_max, hi.x, hi.y, hi.z);
}

Renderer::Renderer(const Hierarchy& h, glm::ivec2 size, std::uint32_t pool_vertices) {
  if (!gl::loaded()) throw gl::GlError("Renderer: no GL context is current");
  vao_ = gl::VertexArray::create();
  // The object attributes (kObjectVertex) of a single model: one identity
  // record for instance 0 (draw_scene binds its objects' records instead).
  const ObjectRecord identity = object_record(glm::mat4(1.0f));
  identity_object_ = gl::Buffer::create(sizeof identity, &identity, 0);
  for (GLuint i = 0; i < 4; ++i) {
    gl::VertexArrayAttribFormat(vao_.id(), 3 + i, 4, GL_FLOAT, GL_FALSE,
                                static_cast<GLuint>(i * sizeof(glm::vec4)));
    gl::VertexArrayAttribBinding(vao_.id(), 3 + i, kObjectBinding);
    gl::EnableVertexArrayAttrib(vao_.id(), 3 + i);
  }
  gl::VertexArrayBindingDivisor(vao_.id(), kObjectBinding, 1);
  bind_objects(identity_object_);
  set_vertex_format();
  if (pool_vertices > 0) {
    set_pool(h, pool_vertices);
  } else {
    set_hierarchy(h);
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
  object_id_ = make_program({{GL_VERTEX_SHADER, shaders::kSplatVertex},
                             {GL_GEOMETRY_SHADER, shaders::kSplatGeometry},
                             {GL_FRAGMENT_SHADER, shaders::kObjectIdFragment}},
                            "splat object id", "#define SPLAT_LIT 1\n#define SPLAT_ID 1\n");
  eye_dome_ = make_program({{GL_VERTEX_SHADER, shaders::kFullscreenVertex},
                            {GL_FRAGMENT_SHADER, shaders::kEyeDomeFragment}},
                           "eye-dome lighting");
  eye_dome_near_ = gl::GetUniformLocation(eye_dome_.id(), "u_near");
  eye_dome_far_ = gl::GetUniformLocation(eye_dome_.id(), "u_far");
  eye_dome_perspective_ = gl::GetUniformLocation(eye_dome_.id(), "u_perspective");
  eye_dome_strength_ = gl::GetUniformLocation(eye_dome_.id(), "u_strength");
  eye_dome_radius_ = gl::GetUniformLocation(eye_dome_.id(), "u_radius");
  fast_u_ = lookup_uniforms(fast_);
  object_id_u_ = lookup_uniforms(object_id_);
  hq_visibility_u_ = lookup_uniforms(hq_visibility_);
  hq_attributes_u_ = lookup_uniforms(hq_attributes_);
  hq_normalize_u_ = lookup_uniforms(hq_normalize_);
  fixed_u_ = lookup_uniforms(fixed_);
  resize(size);
  gl::check("Renderer setup");
}

void Renderer::set_hierarchy(const Hierarchy& h) {
  const Hierarchy* one = &h;
  set_models(std::span<const Hierarchy* const>(&one, 1));
}

void Renderer::set_models(std::span<const Hierarchy* const> models) {
  if (models.empty()) throw std::invalid_argument("Renderer: no model");
  std::size_t n = 0;
  for (const Hierarchy* h : models) {
    if (h == nullptr || h->empty()) throw std::invalid_argument("Renderer: empty hierarchy");
    n += h->node_count();
  }
  // baseVertex of an indirect command is a GLint.
  if (n > std::size_t{0x7fffffff}) {
    throw std::invalid_argument("Renderer: the models hold " + std::to_string(n) +
                                " nodes, more than one vertex buffer can address");
  }
  // One static buffer holding the four node arrays back to back, each the
  // models' arrays one after the other (a model's nodes start at its base).
  segments_.clear();
  segment_vertices_.clear();
  add_segment(static_cast<std::uint32_t>(n));
  bind_segment(0);
  gl::Buffer& nodes = segments_.front();
  const VertexRegions at(n);
  model_base_.clear();
  model_nodes_.clear();
  model_ids_.clear();
  std::size_t base = 0;
  for (const Hierarchy* h : models) {
    const HierarchyArrays& a = h->arrays();
    nodes.sub_data(at.center_radius(base), std::as_bytes(a.center_radius));
    nodes.sub_data(at.normal_cone(base), std::as_bytes(a.normal_cone));
    nodes.sub_data(at.color(base), std::as_bytes(colors_of(*h)));
    nodes.sub_data(at.splat_radius(base), std::as_bytes(a.splat_radius));
    model_base_.push_back(static_cast<std::uint32_t>(base));
    model_nodes_.push_back(static_cast<std::uint32_t>(h->node_count()));
    model_ids_.push_back(h);
    base += h->node_count();
  }
  node_count_ = model_nodes_.front();
  hierarchy_ = models.front();
  pooled_ = false;
  ++hierarchy_uploads_;
  gl::check("Renderer vertex buffer");
}

void Renderer::set_pool(const Hierarchy& h, std::uint32_t vertices) {
  const Hierarchy* one = &h;
  set_pool(std::span<const Hierarchy* const>(&one, 1), vertices);
}

void Renderer::set_pool(std::span<const Hierarchy* const> models, std::uint32_t vertices) {
  if (models.empty()) throw std::invalid_argument("Renderer: no model");
  if (pooled_ && std::equal(models.begin(), models.end(), model_ids_.begin(), model_ids_.end()) &&
      segment_vertices_.front() == vertices) {
    // The first segment kept (made for this pool: Renderer's constructor),
    // the others dropped: a new pool adds its own.
    segments_.resize(1);
    segment_vertices_.resize(1);
    bind_segment(0);
    node_count_ = vertices;
    model_nodes_.assign(models.size(), vertices);
    return;
  }
  if (vertices == 0 || vertices > 0x7fffffffu)
    throw std::invalid_argument("Renderer: a pool of " + std::to_string(vertices) + " vertices");
  segments_.clear();
  segment_vertices_.clear();
  add_segment(vertices);
  bind_segment(0);
  pool_shift_ = static_cast<std::uint32_t>(std::countr_zero(std::bit_ceil(vertices)));
  node_count_ = vertices;
  // Vertex 0 zeros (alpha 0: drawn as nothing), the rest undefined until
  // written: the pool writes what it maps to. Every model's vertices are
  // where the pool's map puts them: its base is 0.
  write_null_vertex();
  model_base_.assign(models.size(), 0);
  model_nodes_.assign(models.size(), vertices);
  model_ids_.assign(models.begin(), models.end());
  hierarchy_ = models.front();
  pooled_ = true;
  ++hierarchy_uploads_;
  gl::check("Renderer vertex pool");
}

void Renderer::write_null_vertex() {
  const VertexRegions at(segment_vertices_.front());
  const std::array<std::byte, sizeof(glm::vec4)> zero{};
  gl::Buffer& nodes = segments_.front();
  nodes.sub_data(at.center_radius(0), zero);
  nodes.sub_data(at.normal_cone(0), std::span(zero).first(sizeof(glm::i16vec4)));
  nodes.sub_data(at.color(0), std::span(zero).first(sizeof(glm::u8vec4)));
  nodes.sub_data(at.splat_radius(0), std::span(zero).first(sizeof(float)));
}

void Renderer::add_pool_segment(std::uint32_t vertices) {
  const std::uint64_t extent = (std::uint64_t{segments_.size()} << pool_shift_) + vertices;
  if (!pooled_ || vertices == 0 || vertices > segment_vertices_.front() || extent > 0x7fffffffu) {
    throw std::invalid_argument("Renderer: a pool segment of " + std::to_string(vertices) +
                                " vertices after " + std::to_string(segments_.size()) + " of " +
                                std::to_string(segment_vertices_.front()));
  }
  add_segment(vertices);
  node_count_ = static_cast<std::uint32_t>(extent);
  model_nodes_.assign(model_ids_.size(), node_count_);
  gl::check("Renderer pool segment");
}

void Renderer::write_vertices(std::uint32_t first, const Hierarchy& h, NodeRange nodes) {
  const std::uint32_t s = first >> pool_shift_;
  const std::uint32_t v = first & ((std::uint32_t{1} << pool_shift_) - 1);
  if (s >= segments_.size() || std::uint64_t{v} + nodes.count > segment_vertices_[s]) {
    throw std::invalid_argument("Renderer::write_vertices: vertices " + std::to_string(first) +
                                " + " + std::to_string(nodes.count) + " past a segment");
  }
  const VertexRegions at(segment_vertices_[s]);
  const HierarchyArrays& a = h.arrays();
  gl::Buffer& b = segments_[s];
  b.sub_data(at.center_radius(v), std::as_bytes(a.center_radius.subspan(nodes.first, nodes.count)));
  b.sub_data(at.normal_cone(v), std::as_bytes(a.normal_cone.subspan(nodes.first, nodes.count)));
  if (const NodeColoring* rule = coloring_of(h)) {
    colors_scratch_.resize(nodes.count);
    for (std::uint32_t i = 0; i < nodes.count; ++i) colors_scratch_[i] = (*rule)(nodes.first + i);
    b.sub_data(at.color(v), std::as_bytes(std::span<const glm::u8vec4>(colors_scratch_)));
  } else {
    b.sub_data(at.color(v), std::as_bytes(a.color.subspan(nodes.first, nodes.count)));
  }
  b.sub_data(at.splat_radius(v), std::as_bytes(a.splat_radius.subspan(nodes.first, nodes.count)));
}

void Renderer::set_node_coloring(const Hierarchy& h, std::shared_ptr<const NodeColoring> rule) {
  std::erase_if(colorings_, [&](const auto& c) { return c.first == &h; });
  if (rule) colorings_.emplace_back(&h, std::move(rule));
  ++coloring_version_;
}

const NodeColoring* Renderer::coloring_of(const Hierarchy& h) const {
  for (const auto& [model, rule] : colorings_)
    if (model == &h) return rule.get();
  return nullptr;
}

void Renderer::set_vertex_format() {
  const GLuint vao = vao_.id();
  gl::VertexArrayAttribFormat(vao, 0, 3, GL_FLOAT, GL_FALSE, 0);  // the center; .w is the bound
  gl::VertexArrayAttribFormat(vao, 1, 4, GL_SHORT, GL_TRUE, 0);
  gl::VertexArrayAttribFormat(vao, 2, 4, GL_UNSIGNED_BYTE, GL_TRUE, 0);
  gl::VertexArrayAttribFormat(vao, kSplatRadiusLocation, 1, GL_FLOAT, GL_FALSE, 0);
  for (GLuint i = 0; i < 3; ++i) {
    gl::VertexArrayAttribBinding(vao, i, i);
    gl::EnableVertexArrayAttrib(vao, i);
  }
  gl::VertexArrayAttribBinding(vao, kSplatRadiusLocation, kSplatRadiusBinding);
  gl::EnableVertexArrayAttrib(vao, kSplatRadiusLocation);
}

void Renderer::add_segment(std::uint32_t n) {
  segments_.push_back(
      gl::Buffer::create(VertexRegions(n).bytes(), nullptr, GL_DYNAMIC_STORAGE_BIT));
  segment_vertices_.push_back(n);
}

void Renderer::bind_segment(std::uint32_t s) {
  const VertexRegions at(segment_vertices_[s]);
  const GLuint vao = vao_.id();
  const GLuint id = segments_[s].id();
  gl::VertexArrayVertexBuffer(vao, 0, id, 0, sizeof(glm::vec4));
  gl::VertexArrayVertexBuffer(vao, 1, id, static_cast<GLintptr>(at.normal_cone(0)),
                              sizeof(glm::i16vec4));
  gl::VertexArrayVertexBuffer(vao, 2, id, static_cast<GLintptr>(at.color(0)), sizeof(glm::u8vec4));
  gl::VertexArrayVertexBuffer(vao, kSplatRadiusBinding, id,
                              static_cast<GLintptr>(at.splat_radius(0)), sizeof(float));
  bound_segment_ = s;
}

std::span<const glm::u8vec4> Renderer::colors_of(const Hierarchy& h) const {
  for (const NodeColors& c : node_colors_) {
    if (c.model == &h && c.nodes == h.node_count()) return c.colors;
  }
  return h.arrays().color;
}

void Renderer::set_node_colors(const Hierarchy& h, std::vector<glm::u8vec4> colors) {
  if (!colors.empty() && colors.size() != h.node_count()) {
    throw std::invalid_argument("Renderer::set_node_colors: " + std::to_string(colors.size()) +
                                " colours for " + std::to_string(h.node_count()) + " nodes");
  }
  if (pooled_ && std::find(model_ids_.begin(), model_ids_.end(), &h) != model_ids_.end() &&
      !colors.empty())
    throw std::invalid_argument("Renderer::set_node_colors: a pool's vertices are the file's");
  std::erase_if(node_colors_, [&](const NodeColors& c) { return c.model == &h; });
  if (!colors.empty()) node_colors_.push_back({&h, h.node_count(), std::move(colors)});
  // The model held now: its colour array in place (the others on upload).
  if (pooled_) return;
  const VertexRegions at(model_base_.empty() ? 0 : model_base_.back() + model_nodes_.back());
  for (std::size_t m = 0; m < model_ids_.size(); ++m) {
    if (model_ids_[m] != &h) continue;
    segments_.front().sub_data(at.color(model_base_[m]), std::as_bytes(colors_of(h)));
  }
  gl::check("Renderer node colours");
}

Renderer::~Renderer() = default;

}  // namespace treecut::splat
