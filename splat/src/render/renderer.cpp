// Botsch, Hornung, Zwicker, Kobbelt: High-Quality Surface Splatting on Today's
// GPUs (Eurographics Symposium on Point-Based Graphics 2005) for the
// high-quality mode; QSplat's round splats for coarse nodes.
#include "treecut/splat/renderer.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <chrono>
#include <cstdint>
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
#include "treecut/splat/frame.hpp"
#include "treecut/splat/scene_draw.hpp"
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

void CutBuffer::write(std::span<const NodeId> ids) {
  // Write the buffer the last draws did not read: a driver with frames in
  // flight need not wait for them (or copy the buffer) before the write.
  const std::size_t next = buffers_[current_] ? 1 - current_ : current_;
  gl::Buffer& target = buffers_[next];
  const std::size_t bytes = ids.size_bytes();
  if (!target || target.size() < bytes) {
    const std::size_t capacity = std::bit_ceil(std::max<std::size_t>(bytes, 4096));
    target = gl::Buffer::create(capacity, nullptr, GL_DYNAMIC_STORAGE_BIT);
  }
  target.sub_data(0, std::as_bytes(ids));
  current_ = next;
}

void CutBuffer::upload(const Hierarchy& h, std::span<const NodeId> nodes) {
  // Draw in node-id order. Ids are breadth-first over a spatial tree, so this
  // order is spatially coherent; llvmpipe's rasterizer threads read each
  // triangle's setup data in submission order, and a strategy's cut order
  // (scattered by refines and coarsens) made them miss the cache on almost
  // every splat (docs/rendering.md, "Submission order"). The CPU copy is kept
  // so a caller of draw_ranges() knows which node sits at which position.
  sorted_.assign(nodes.begin(), nodes.end());
  if (!std::is_sorted(sorted_.begin(), sorted_.end())) {
    sort_node_ids(sorted_, h.node_count(), scratch_);
  }
  // Counted in id order: ascending addresses, which the prefetcher follows.
  std::uint64_t points = 0;
  const auto counts = h.arrays().point_count;
  for (const NodeId n : sorted_) points += counts[n];
  write(sorted_);
  count_ = nodes.size();
  entering_ = 0;
  leaving_ = 0;
  fade_ = 1.0f;
  points_ = points;
  hierarchy_ = &h;
  max_id_ = sorted_.empty() ? 0 : sorted_.back();
}

void CutBuffer::upload(const Hierarchy& h, std::span<const NodeId> nodes,
                       std::span<const NodeId> previous) {
  if (previous.empty()) {
    upload(h, nodes);
    return;
  }
  // The stage publishes sorted lists, so these are only checks.
  auto sorted_view = [&](std::span<const NodeId> in, std::vector<NodeId>& copy) {
    if (std::is_sorted(in.begin(), in.end())) return in;
    copy.assign(in.begin(), in.end());
    sort_node_ids(copy, h.node_count(), scratch_);
    return std::span<const NodeId>(copy);
  };
  const std::span<const NodeId> cur = sorted_view(nodes, current_sorted_);
  const std::span<const NodeId> prev = sorted_view(previous, previous_sorted_);
  // One merge: each run stays ascending (the coherent submission order).
  sorted_.clear();
  entering_ids_.clear();
  leaving_ids_.clear();
  std::size_t i = 0;
  std::size_t j = 0;
  while (i < cur.size() && j < prev.size()) {
    if (cur[i] == prev[j]) {
      sorted_.push_back(cur[i]);
      ++i;
      ++j;
    } else if (cur[i] < prev[j]) {
      entering_ids_.push_back(cur[i++]);
    } else {
      leaving_ids_.push_back(prev[j++]);
    }
  }
  entering_ids_.insert(entering_ids_.end(), cur.begin() + static_cast<std::ptrdiff_t>(i),
                       cur.end());
  leaving_ids_.insert(leaving_ids_.end(), prev.begin() + static_cast<std::ptrdiff_t>(j),
                      prev.end());
  sorted_.insert(sorted_.end(), entering_ids_.begin(), entering_ids_.end());
  sorted_.insert(sorted_.end(), leaving_ids_.begin(), leaving_ids_.end());
  std::uint64_t points = 0;
  const auto counts = h.arrays().point_count;
  for (const NodeId n : cur) points += counts[n];
  write(sorted_);
  count_ = cur.size();
  entering_ = entering_ids_.size();
  leaving_ = leaving_ids_.size();
  fade_ = 0.0f;
  points_ = points;
  hierarchy_ = &h;
  max_id_ = std::max(cur.empty() ? NodeId{0} : cur.back(), prev.back());
}

bool CutBuffer::follow(const FrameLists& lists) {
  const FrontList& cur = lists.current;
  bool uploaded = false;
  if (cur.hierarchy != nullptr && cur.generation != generation_) {
    const bool fades = !lists.previous.nodes.empty() && lists.previous.hierarchy == cur.hierarchy;
    if (fades) {
      upload(*cur.hierarchy, cur.nodes, lists.previous.nodes);
    } else {
      upload(*cur.hierarchy, cur.nodes);
    }
    generation_ = cur.generation;
    uploaded = true;
  }
  // The stage ends a blend by handing no previous list: the new one alone.
  set_fade(lists.previous.nodes.empty() ? 1.0f : lists.blend);
  return uploaded;
}

namespace {

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

void clear_color(const gl::Framebuffer& fbo, GLint buffer, glm::vec4 value) {
  gl::ClearNamedFramebufferfv(fbo.id(), GL_COLOR, buffer, &value.x);
}

void clear_depth(const gl::Framebuffer& fbo) {
  const float one = 1.0f;
  gl::ClearNamedFramebufferfv(fbo.id(), GL_DEPTH, 0, &one);
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
  return u;
}

Renderer::Renderer(const Hierarchy& h, glm::ivec2 size) {
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
  set_hierarchy(h);
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
  const std::size_t cr_bytes = n * sizeof(glm::vec4);
  const std::size_t nc_bytes = n * sizeof(glm::i16vec4);
  const std::size_t co_bytes = n * sizeof(glm::u8vec4);
  // One static buffer holding the three node arrays back to back, each the
  // models' arrays one after the other (a model's nodes start at its base).
  nodes_ = gl::Buffer::create(cr_bytes + nc_bytes + co_bytes, nullptr, GL_DYNAMIC_STORAGE_BIT);
  model_base_.clear();
  model_nodes_.clear();
  model_ids_.clear();
  std::size_t base = 0;
  for (const Hierarchy* h : models) {
    const HierarchyArrays& a = h->arrays();
    nodes_.sub_data(base * sizeof(glm::vec4), std::as_bytes(a.center_radius));
    nodes_.sub_data(cr_bytes + base * sizeof(glm::i16vec4), std::as_bytes(a.normal_cone));
    nodes_.sub_data(cr_bytes + nc_bytes + base * sizeof(glm::u8vec4), std::as_bytes(a.color));
    model_base_.push_back(static_cast<std::uint32_t>(base));
    model_nodes_.push_back(static_cast<std::uint32_t>(h->node_count()));
    model_ids_.push_back(h);
    base += h->node_count();
  }

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
  node_count_ = model_nodes_.front();
  hierarchy_ = models.front();
  ++hierarchy_uploads_;
  gl::check("Renderer vertex buffer");
}

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
  if (cut.max_id() >= node_count_) {
    throw std::logic_error("Renderer: the cut names node " + std::to_string(cut.max_id()) +
                           ", the vertex buffer holds " + std::to_string(node_count_));
  }
  last_max_id_ = cut.max_id();
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

void Renderer::plan_runs(const CutBuffer& cut, std::span<const CutRange> ranges, bool sorted) {
  runs_.clear();
  run_hook_.clear();
  const auto count = static_cast<std::uint32_t>(cut.size());
  const bool fading = cut.fading();
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
                         RangeHook* hook, const FrameView& frame, GLuint fbo, bool depth_writes) {
  // The exchange point: the cut is just the element buffer of the node VAO.
  gl::VertexArrayElementBuffer(vao_.id(), elements);
  gl::BindVertexArray(vao_.id());
  gl::UseProgram(program.id());
  int fade = 0;
  gl::ProgramUniform1i(program.id(), u.fade_mode, 0);
  for (std::size_t r = 0; r < runs_.size(); ++r) {
    const Run& run = runs_[r];
    if (run.indirect) {
      // A scene: every object's run, one command each, in one call.
      gl::BindBuffer(GL_DRAW_INDIRECT_BUFFER, indirect_);
      gl::MultiDrawElementsIndirect(GL_POINTS, GL_UNSIGNED_INT, nullptr,
                                    static_cast<GLsizei>(run.count), 0);
      gl::BindBuffer(GL_DRAW_INDIRECT_BUFFER, 0);
      ++draw_calls_;
    } else if (run.count > 0) {
      if (run.fade != fade) {
        fade = run.fade;
        gl::ProgramUniform1i(program.id(), u.fade_mode, fade);
      }
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
  return render(&cut, nullptr, ranges, false, camera, settings, hook, finish);
}

void Renderer::set_common_uniforms(const gl::Program& program, const Uniforms& u,
                                   const FrameView& frame, const RenderSettings& settings,
                                   float fade) const {
  const Light& light = settings.light;
  // The same direction the strategies are handed (frame.hpp): one function.
  const glm::vec3 light_dir = world_light_dir(light, frame.view);
  // Locations were looked up at link time (lookup_uniforms).
  const GLuint p = program.id();
  gl::ProgramUniformMatrix4fv(p, u.view, 1, GL_FALSE, glm::value_ptr(frame.view));
  gl::ProgramUniformMatrix4fv(p, u.proj, 1, GL_FALSE, glm::value_ptr(frame.projection));
  gl::ProgramUniform3f(p, u.eye, frame.eye.x, frame.eye.y, frame.eye.z);
  gl::ProgramUniform1f(p, u.radius_scale, settings.radius_scale);
  gl::ProgramUniform1i(p, u.cull, settings.backface_culling ? 1 : 0);
  gl::ProgramUniform1f(p, u.min_radius_px, 0.75f);
  gl::ProgramUniform1f(p, u.viewport_h, static_cast<float>(size_.y));
  gl::ProgramUniform3f(p, u.light_dir, light_dir.x, light_dir.y, light_dir.z);
  gl::ProgramUniform4f(p, u.light, light.ambient, light.diffuse, light.specular, light.shininess);
  gl::ProgramUniform1f(p, u.fade, fade);
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
    if (scene->commands() > 0) {
      runs_.push_back(Run{0, static_cast<std::uint32_t>(scene->commands()), 0, true});
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
  const float aspect = static_cast<float>(size_.x) / static_cast<float>(size_.y);
  FrameView frame;
  frame.view = camera.view_matrix();
  frame.projection = camera.projection_matrix(aspect);
  frame.eye = camera.eye;
  frame.size = size_;

  auto set_common = [&](const gl::Program& program, const Uniforms& u) {
    set_common_uniforms(program, u, frame, settings, fade_weight);
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
      set_common(fast_, fast_u_);
      gl::ProgramUniform1f(fast_.id(), fast_u_.depth_offset, 0.0f);
      draw_runs(elements, fast_, fast_u_, hook, frame, scene_fbo_.id(), true);
      run_hook(scene_fbo_.id());
      break;
    }
    case SplatMode::HighQuality: {
      // Pass 1: visibility, pushed back by depth_offset radii; the ranges in
      // their order, with the hook between them.
      clear_depth(visibility_fbo_);
      gl::BindFramebuffer(GL_FRAMEBUFFER, visibility_fbo_.id());
      gl::DepthFunc(GL_LESS);
      set_common(hq_visibility_, hq_visibility_u_);
      gl::ProgramUniform1f(hq_visibility_.id(), hq_visibility_u_.depth_offset,
                           settings.depth_offset);
      draw_runs(elements, hq_visibility_, hq_visibility_u_, hook, frame, visibility_fbo_.id(),
                true);
      run_hook(visibility_fbo_.id());

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
      set_common(hq_attributes_, hq_attributes_u_);
      gl::ProgramUniform1f(hq_attributes_.id(), hq_attributes_u_.depth_offset, 0.0f);
      draw_runs(elements, hq_attributes_, hq_attributes_u_, nullptr, frame, accum_fbo_.id(), false);
      gl::Disable(GL_BLEND);
      gl::DepthMask(GL_TRUE);

      // Pass 3: normalization and per-pixel lighting.
      clear_color(scene_fbo_, 0, background);
      gl::BindFramebuffer(GL_FRAMEBUFFER, scene_fbo_.id());
      gl::Disable(GL_DEPTH_TEST);
      set_common(hq_normalize_, hq_normalize_u_);
      const glm::mat4 inv_view_proj = glm::inverse(frame.projection * frame.view);
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
      break;
    }
    case SplatMode::ObjectId: {
      // White = no object: an index would need 2^24 - 1 objects to mean it.
      clear_color(scene_fbo_, 0, glm::vec4(1.0f));
      clear_depth(scene_fbo_);
      gl::BindFramebuffer(GL_FRAMEBUFFER, scene_fbo_.id());
      gl::DepthFunc(GL_LESS);
      set_common(object_id_, object_id_u_);
      gl::ProgramUniform1f(object_id_.id(), object_id_u_.depth_offset, 0.0f);
      draw_runs(elements, object_id_, object_id_u_, hook, frame, scene_fbo_.id(), true);
      run_hook(scene_fbo_.id());
      break;
    }
    case SplatMode::FixedSize: {
      clear_color(scene_fbo_, 0, background);
      clear_depth(scene_fbo_);
      gl::BindFramebuffer(GL_FRAMEBUFFER, scene_fbo_.id());
      gl::DepthFunc(GL_LESS);
      gl::Enable(GL_PROGRAM_POINT_SIZE);
      set_common(fixed_, fixed_u_);
      gl::ProgramUniform1f(fixed_.id(), fixed_u_.point_size,
                           std::max(settings.point_size_px, 1.0f));
      draw_runs(elements, fixed_, fixed_u_, hook, frame, scene_fbo_.id(), true);
      gl::Disable(GL_PROGRAM_POINT_SIZE);
      run_hook(scene_fbo_.id());
      break;
    }
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

void Renderer::begin_frame_ranges(const gl::Buffer& elements, NodeId max_id, const Camera& camera,
                                  const RenderSettings& settings) {
  if (settings.mode == SplatMode::HighQuality) {
    throw std::invalid_argument(
        "Renderer: in-frame ranges need a one-pass mode (fast, fixed or id)");
  }
  if (max_id >= node_count_) {
    throw std::logic_error("Renderer: the ranges name node " + std::to_string(max_id) +
                           ", the vertex buffer holds " + std::to_string(node_count_));
  }
  in_frame_start_ = std::chrono::steady_clock::now();
  const float aspect = static_cast<float>(size_.x) / static_cast<float>(size_.y);
  in_frame_view_.view = camera.view_matrix();
  in_frame_view_.projection = camera.projection_matrix(aspect);
  in_frame_view_.eye = camera.eye;
  in_frame_view_.size = size_;
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

void Renderer::present(glm::ivec2 window_size) const {
  gl::BlitNamedFramebuffer(scene_fbo_.id(), 0, 0, 0, size_.x, size_.y, 0, 0, window_size.x,
                           window_size.y, GL_COLOR_BUFFER_BIT, GL_NEAREST);
}

std::vector<std::uint8_t> Renderer::read_pixels() const {
  return read_back_rgba(scene_fbo_.id(), GL_COLOR_ATTACHMENT0, size_);
}

}  // namespace treecut::splat
