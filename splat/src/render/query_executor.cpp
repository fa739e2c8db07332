#include "treecut/splat/query_executor.hpp"

#include <algorithm>
#include <chrono>
#include <glm/gtc/type_ptr.hpp>
#include <string>

namespace treecut::splat {

namespace {

// The proxy of one node: instance attribute 0 is its bounding sphere (the
// hierarchy's center_radius, selected by the draw's base instance); the four
// vertices of a strip make the square described in query_executor.hpp.
constexpr const char* kProxyVertex = R"(#version 450 core
layout(location = 0) in vec4 a_sphere;
uniform mat4 u_view;
uniform mat4 u_proj;
void main() {
  vec3 c = (u_view * vec4(a_sphere.xyz, 1.0)).xyz;
  float r = a_sphere.w;
  float d = length(c);
  // The host answers an eye inside the sphere; guard the square root anyway.
  float front = max(d - r, 0.0);
  float half_size = front * r / sqrt(max(d * d - r * r, 1e-30));
  vec3 axis = c / max(d, 1e-30);
  vec3 helper = abs(axis.y) < 0.9 ? vec3(0.0, 1.0, 0.0) : vec3(1.0, 0.0, 0.0);
  vec3 u = normalize(cross(helper, axis));
  vec3 v = cross(axis, u);
  vec2 corner = vec2(float(gl_VertexID & 1), float(gl_VertexID >> 1)) * 2.0 - 1.0;
  // A hair larger than the cone: rasterization rounding must not make it
  // smaller than the sphere's silhouette.
  vec3 p = axis * front + (corner.x * u + corner.y * v) * half_size * 1.001;
  gl_Position = u_proj * vec4(p, 1.0);
}
)";

constexpr const char* kProxyFragment = R"(#version 450 core
void main() {}
)";

}  // namespace

QueryExecutor::QueryExecutor(QueryExecutorOptions options) : options_(options) {
  if (!gl::loaded()) throw gl::GlError("QueryExecutor: no GL context is current");
  const gl::Shader vs = gl::Shader::compile(GL_VERTEX_SHADER, kProxyVertex, "query proxy");
  const gl::Shader fs = gl::Shader::compile(GL_FRAGMENT_SHADER, kProxyFragment, "query proxy");
  const gl::Shader* stages[] = {&vs, &fs};
  proxy_ = gl::Program::link(stages, "query proxy");
  // Looked up once: run() sets them every frame.
  u_view_ = gl::GetUniformLocation(proxy_.id(), "u_view");
  u_proj_ = gl::GetUniformLocation(proxy_.id(), "u_proj");
  vao_ = gl::VertexArray::create();
  gl::VertexArrayAttribFormat(vao_.id(), 0, 4, GL_FLOAT, GL_FALSE, 0);
  gl::VertexArrayAttribBinding(vao_.id(), 0, 0);
  gl::VertexArrayBindingDivisor(vao_.id(), 0, 1);
  gl::EnableVertexArrayAttrib(vao_.id(), 0);
  gl::check("QueryExecutor setup");
}

QueryExecutor::~QueryExecutor() = default;

void QueryExecutor::upload_spheres(const Hierarchy& h) {
  const auto cr = h.arrays().center_radius;
  spheres_.assign(cr.begin(), cr.end());
  sphere_buffer_ = gl::Buffer::create(std::max<std::size_t>(cr.size_bytes(), 16), nullptr,
                                      GL_DYNAMIC_STORAGE_BIT);
  if (!cr.empty()) sphere_buffer_.sub_data(0, std::as_bytes(cr));
  gl::VertexArrayVertexBuffer(vao_.id(), 0, sphere_buffer_.id(), 0, sizeof(glm::vec4));
  hierarchy_ = &h;
}

void QueryExecutor::begin_frame_render_thread(const FrontList& list, std::uint64_t frame) {
  frame_ = frame;
  if (list.hierarchy == nullptr || list.generation == generation_) return;
  generation_ = list.generation;
  if (list.hierarchy != hierarchy_) {
    // Another model: queries in flight name nodes of the old one. Their
    // answers are still read (in order) but describe the old hierarchy; the
    // stage drops results of a model it replaced along with its state.
    upload_spheres(*list.hierarchy);
  }
  stats_.dropped += queue_.size() - queue_next_;
  queue_.assign(list.queries.begin(), list.queries.end());
  queue_next_ = 0;
  stats_.queued = queue_.size();
}

std::uint32_t QueryExecutor::acquire(QueryKind kind) {
  const bool any = kind == QueryKind::AnySamples;
  std::vector<std::uint32_t>& free = any ? any_free_ : samples_free_;
  std::vector<gl::Query>& pool = any ? any_pool_ : samples_pool_;
  if (!free.empty()) {
    const std::uint32_t q = free.back();
    free.pop_back();
    return q;
  }
  pool.push_back(gl::Query::create(any ? GL_ANY_SAMPLES_PASSED_CONSERVATIVE : GL_SAMPLES_PASSED));
  ++stats_.pool_size;
  return static_cast<std::uint32_t>(pool.size() - 1);
}

void QueryExecutor::answer(const QueryRequest& r, std::uint32_t samples, std::uint64_t issued) {
  VisibilityResult v;
  v.object = r.object;
  v.node = r.node;
  v.tag = r.tag;
  v.kind = r.kind;
  v.samples_passed = samples;
  v.frame_issued = issued;
  v.frame_read = frame_;
  results_.push_back(v);
  ++stats_.answered;
  ++stats_.answered_last;
  if (samples == 0) ++stats_.occluded;
  const std::uint64_t latency = frame_ - issued;
  stats_.latency_frames_total += latency;
  stats_.latency_frames_max = std::max(stats_.latency_frames_max, latency);
}

void QueryExecutor::poll_render_thread() {
  while (in_flight_head_ < in_flight_.size()) {
    const InFlight& f = in_flight_[in_flight_head_];
    const bool any = f.request.kind == QueryKind::AnySamples;
    const gl::Query& q = (any ? any_pool_ : samples_pool_)[f.query];
    GLuint available = GL_FALSE;
    gl::GetQueryObjectuiv(q.id(), GL_QUERY_RESULT_AVAILABLE, &available);
    if (available == GL_FALSE) break;  // later ones are later still: next frame
    GLuint64 samples = 0;
    gl::GetQueryObjectui64v(q.id(), GL_QUERY_RESULT, &samples);
    answer(f.request, static_cast<std::uint32_t>(std::min<GLuint64>(samples, 0xffffffffu)),
           f.frame_issued);
    (any ? any_free_ : samples_free_).push_back(f.query);
    ++in_flight_head_;
  }
  if (in_flight_head_ == in_flight_.size()) {
    in_flight_.clear();
    in_flight_head_ = 0;
  } else if (in_flight_head_ > 1024 && in_flight_head_ * 2 > in_flight_.size()) {
    // Keep the pending ones at the front; amortized O(1) per query.
    in_flight_.erase(in_flight_.begin(),
                     in_flight_.begin() + static_cast<std::ptrdiff_t>(in_flight_head_));
    in_flight_head_ = 0;
  }
}

void QueryExecutor::issue_render_thread(const FrameView& view) {
  const std::size_t end = std::min(queue_.size(), queue_next_ + options_.max_issue_per_frame);
  if (queue_next_ >= end || hierarchy_ == nullptr) return;
  GLint depth_func = GL_LESS;
  gl::GetIntegerv(GL_DEPTH_FUNC, &depth_func);
  // LEQUAL: a proxy exactly on an occluder's depth counts as visible.
  gl::DepthFunc(GL_LEQUAL);
  gl::Enable(GL_DEPTH_CLAMP);
  gl::UseProgram(proxy_.id());
  gl::ProgramUniformMatrix4fv(proxy_.id(), u_view_, 1, GL_FALSE, glm::value_ptr(view.view));
  gl::ProgramUniformMatrix4fv(proxy_.id(), u_proj_, 1, GL_FALSE, glm::value_ptr(view.projection));
  gl::BindVertexArray(vao_.id());
  const auto node_count = static_cast<NodeId>(spheres_.size());
  for (std::size_t i = queue_next_; i < end; ++i) {
    const QueryRequest& r = queue_[i];
    if (r.node >= node_count) {  // not a node of this hierarchy: nothing to see
      answer(r, 0, frame_);
      continue;
    }
    const glm::vec4 s = spheres_[r.node];
    const glm::vec3 d = glm::vec3(s) - view.eye;
    if (d.x * d.x + d.y * d.y + d.z * d.z <= s.w * s.w) {
      // The eye inside the sphere: it covers the whole view.
      answer(r, r.kind == QueryKind::AnySamples ? 1u : std::uint32_t(view.size.x * view.size.y),
             frame_);
      continue;
    }
    const std::uint32_t q = acquire(r.kind);
    const gl::Query& query = (r.kind == QueryKind::AnySamples ? any_pool_ : samples_pool_)[q];
    query.begin();
    gl::DrawArraysInstancedBaseInstance(GL_TRIANGLE_STRIP, 0, 4, 1, r.node);
    query.end();
    in_flight_.push_back({r, q, frame_});
    ++stats_.issued;
    ++stats_.issued_last;
  }
  queue_next_ = end;
  gl::BindVertexArray(0);
  gl::UseProgram(0);
  gl::Disable(GL_DEPTH_CLAMP);
  gl::DepthFunc(static_cast<GLenum>(depth_func));
}

void QueryExecutor::run(const FrameView& view) {
  const auto start = std::chrono::steady_clock::now();
  stats_.issued_last = 0;
  stats_.answered_last = 0;
  // Poll first: a query issued in this frame is never read in this frame.
  poll_render_thread();
  stats_.poll_ns_last = static_cast<std::uint64_t>(
      std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now() - start)
          .count());
  issue_render_thread(view);
  stats_.pending = in_flight_.size() - in_flight_head_;
  stats_.queued = queue_.size() - queue_next_;
  const auto ns =
      std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now() - start)
          .count();
  stats_.cpu_ns_last = static_cast<std::uint64_t>(ns);
  stats_.cpu_ns_total += stats_.cpu_ns_last;
}

}  // namespace treecut::splat
