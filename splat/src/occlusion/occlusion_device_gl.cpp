// GL occlusion device of the in-frame traversals (CHC: Bittner et al. 2004,
// ../shared/papers/coherent-hierarchical-culling.tex.txt): the paper's
// hardware occlusion queries of bounding boxes, polled for availability.
#include "treecut/splat/occlusion_device_gl.hpp"

#include <array>
#include <chrono>
#include <cmath>
#include <glm/gtc/type_ptr.hpp>
#include <stdexcept>
#include <string>

namespace treecut::splat {

namespace {

// The unit cube's six faces as 12 triangles, counter-clockwise seen from
// outside: with back faces culled, a box the eye is outside of covers each
// pixel of its projection once, so its samples are its unoccluded pixels (the
// paper's n_vp counts pixels) and it costs one fill, not two.
constexpr const char* kProxyVertex = R"(#version 450 core
uniform mat4 u_view_proj;
uniform vec3 u_lo;
uniform vec3 u_hi;
const vec3 k_quads[24] = vec3[](
    vec3(1, 0, 0), vec3(1, 1, 0), vec3(1, 1, 1), vec3(1, 0, 1),   // +x
    vec3(0, 0, 0), vec3(0, 0, 1), vec3(0, 1, 1), vec3(0, 1, 0),   // -x
    vec3(0, 1, 0), vec3(0, 1, 1), vec3(1, 1, 1), vec3(1, 1, 0),   // +y
    vec3(0, 0, 0), vec3(1, 0, 0), vec3(1, 0, 1), vec3(0, 0, 1),   // -y
    vec3(0, 0, 1), vec3(1, 0, 1), vec3(1, 1, 1), vec3(0, 1, 1),   // +z
    vec3(0, 0, 0), vec3(0, 1, 0), vec3(1, 1, 0), vec3(1, 0, 0));  // -z
const int k_corner[6] = int[](0, 1, 2, 0, 2, 3);
void main() {
  const vec3 k = k_quads[4 * (gl_VertexID / 6) + k_corner[gl_VertexID % 6]];
  gl_Position = u_view_proj * vec4(mix(u_lo, u_hi, k), 1.0);
}
)";

constexpr const char* kProxyFragment = R"(#version 450 core
layout(early_fragment_tests) in;
void main() {}
)";

}  // namespace

GlOcclusionDevice::GlOcclusionDevice(Renderer& renderer, const culling::HlodBlocks& blocks,
                                     std::size_t initial_queries)
    : renderer_(&renderer), blocks_(&blocks) {
  if (blocks.hierarchy_nodes() != renderer.node_count() || blocks.block_count() == 0) {
    throw std::invalid_argument("GlOcclusionDevice: the blocks are of another hierarchy");
  }
  // The representations are one array in HlodBlocks (rep_): one upload.
  const std::uint32_t n = blocks.block_count();
  const auto all_first = blocks.representation(0).data();
  const auto last = blocks.representation(n - 1);
  const std::size_t total = static_cast<std::size_t>(last.data() + last.size() - all_first);
  first_.resize(n);
  for (std::uint32_t b = 0; b < n; ++b) {
    first_[b] = static_cast<std::uint32_t>(blocks.representation(b).data() - all_first);
  }
  for (std::size_t i = 0; i < total; ++i) max_id_ = std::max(max_id_, all_first[i]);
  elements_ = gl::Buffer::create(std::max<std::size_t>(total, 1) * sizeof(NodeId), all_first, 0);

  const gl::Shader vs = gl::Shader::compile(GL_VERTEX_SHADER, kProxyVertex, "box proxy");
  const gl::Shader fs = gl::Shader::compile(GL_FRAGMENT_SHADER, kProxyFragment, "box proxy");
  const std::array<const gl::Shader*, 2> shaders{&vs, &fs};
  proxy_ = gl::Program::link(shaders, "box proxy");
  u_view_proj_ = gl::GetUniformLocation(proxy_.id(), "u_view_proj");
  u_lo_ = gl::GetUniformLocation(proxy_.id(), "u_lo");
  u_hi_ = gl::GetUniformLocation(proxy_.id(), "u_hi");
  proxy_vao_ = gl::VertexArray::create();
  pool_.reserve(initial_queries);
  for (std::size_t i = 0; i < initial_queries; ++i) {
    pool_.push_back(gl::Query::create(GL_SAMPLES_PASSED));
  }
  seen_available_.assign(pool_.size(), 0);
  free_.reserve(pool_.size());
  for (std::size_t i = pool_.size(); i-- > 0;)
    free_.push_back(static_cast<culling::QueryHandle>(i));
  gl::check("GlOcclusionDevice setup");
}

GlOcclusionDevice::~GlOcclusionDevice() = default;

void GlOcclusionDevice::set_view_render_thread(const Camera& camera,
                                               const RenderSettings& settings) {
  camera_ = camera;
  settings_ = settings;
}

culling::QueryHandle GlOcclusionDevice::acquire() {
  if (free_.empty()) {
    // More queries in flight than ever before: grow once (doubling), not per frame.
    const std::size_t old = pool_.size();
    const std::size_t grown = std::max<std::size_t>(2 * old, 64);
    for (std::size_t i = old; i < grown; ++i) pool_.push_back(gl::Query::create(GL_SAMPLES_PASSED));
    seen_available_.resize(grown, 0);
    for (std::size_t i = grown; i-- > old;) free_.push_back(static_cast<culling::QueryHandle>(i));
    ++pool_growths_;
  }
  const culling::QueryHandle q = free_.back();
  free_.pop_back();
  seen_available_[q] = 0;
  return q;
}

void GlOcclusionDevice::enter_proxy_state() {
  if (proxy_state_) return;
  gl::ColorMask(GL_FALSE, GL_FALSE, GL_FALSE, GL_FALSE);
  gl::DepthMask(GL_FALSE);
  gl::DepthFunc(GL_LEQUAL);
  gl::Enable(GL_DEPTH_CLAMP);
  gl::Enable(
      GL_CULL_FACE);  // GL's defaults: back faces culled, CCW front (nothing here changes them)
  gl::BindVertexArray(proxy_vao_.id());
  gl::UseProgram(proxy_.id());
  proxy_state_ = true;
}

void GlOcclusionDevice::leave_proxy_state() {
  if (!proxy_state_) return;
  // Masks, depth function, program and vertex array: draw_frame_range sets its own.
  gl::Disable(GL_DEPTH_CLAMP);
  gl::Disable(GL_CULL_FACE);
  proxy_state_ = false;
}

void GlOcclusionDevice::begin_frame_render_thread() {
  if (in_frame_) throw std::logic_error("GlOcclusionDevice: frame already open");
  stats_ = {};
  renderer_->begin_frame_ranges(elements_, max_id_, camera_, settings_);
  const ViewSnapshot& f = renderer_->frame_view();
  // Relative to the eye, as the splats are drawn (shaders.hpp): the boxes'
  // corners less the eye, then the rotation and the projection.
  const glm::mat4 view_proj = f.projection * f.eye_relative_view();
  gl::ProgramUniformMatrix4fv(proxy_.id(), u_view_proj_, 1, GL_FALSE, glm::value_ptr(view_proj));
  eye_ = f.derived.eye;
  proxy_state_ = false;
  in_frame_ = true;
}

culling::QueryHandle GlOcclusionDevice::query_box_render_thread(culling::BlockId b) {
  const culling::Box& box = blocks_->box(b);
  enter_proxy_state();
  const glm::vec3 lo = box.lo - eye_, hi = box.hi - eye_;
  gl::ProgramUniform3f(proxy_.id(), u_lo_, lo.x, lo.y, lo.z);
  gl::ProgramUniform3f(proxy_.id(), u_hi_, hi.x, hi.y, hi.z);
  const culling::QueryHandle q = acquire();
  pool_[q].begin();
  gl::DrawArrays(GL_TRIANGLES, 0, 36);
  pool_[q].end();
  ++stats_.queries;
  return q;
}

culling::QueryHandle GlOcclusionDevice::query_draw_render_thread(culling::BlockId b) {
  const culling::QueryHandle q = acquire();
  pool_[q].begin();
  draw_render_thread(b);
  pool_[q].end();
  ++stats_.queries;
  return q;
}

bool GlOcclusionDevice::result_available_render_thread(culling::QueryHandle q) {
  if (seen_available_[q] != 0) return true;
  GLuint available = GL_FALSE;
  gl::GetQueryObjectuiv(pool_[q].id(), GL_QUERY_RESULT_AVAILABLE, &available);
  seen_available_[q] = available != GL_FALSE ? 1 : 0;
  return seen_available_[q] != 0;
}

std::uint64_t GlOcclusionDevice::result_render_thread(culling::QueryHandle q) {
  GLuint64 samples = 0;
  if (result_available_render_thread(q)) {
    gl::GetQueryObjectui64v(pool_[q].id(), GL_QUERY_RESULT, &samples);
  } else {
    // The caller has nothing else to do: wait in the driver, and count it.
    const auto t0 = std::chrono::steady_clock::now();
    gl::GetQueryObjectui64v(pool_[q].id(), GL_QUERY_RESULT, &samples);
    stats_.wait_ms +=
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    ++stats_.blocking_reads;
  }
  free_.push_back(q);
  return samples;
}

void GlOcclusionDevice::draw_render_thread(culling::BlockId b) {
  leave_proxy_state();
  const auto count = static_cast<std::uint32_t>(blocks_->representation(b).size());
  renderer_->draw_frame_range(first_[b], count);
  if (flush_after_draw_) gl::Flush();
  ++stats_.blocks_drawn;
  stats_.splats_drawn += count;
}

void GlOcclusionDevice::end_frame_render_thread(bool finish) {
  if (!in_frame_) throw std::logic_error("GlOcclusionDevice: no frame open");
  leave_proxy_state();
  last_frame_ = renderer_->end_frame_ranges(finish);
  in_frame_ = false;
}

}  // namespace treecut::splat
