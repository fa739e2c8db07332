#include "treecut/splat/query_executor.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <ctime>
#include <glm/gtc/type_ptr.hpp>
#include <string>

#include "treecut/query_proxy.hpp"

namespace treecut::splat {

namespace {

// The proxies of a batch: one instance per request, its node's sphere an
// instance attribute; the four vertices of a strip make the square described
// in query_executor.hpp. The fragment shader runs only
// for fragments that passed the depth test (early_fragment_tests: it has no
// outputs and writes no depth, so the test can run first) and counts them per
// instance: what GL_SAMPLES_PASSED counts on a single-sampled target.
constexpr const char* kBatchVertex = R"(#version 450 core
layout(location = 0) in vec4 a_sphere;
uniform mat4 u_view;  // rotation only: the sphere is taken relative to the eye first
uniform vec3 u_eye;
uniform mat4 u_proj;
uniform int u_base;
flat out uint v_slot;
void main() {
  // Relative to the eye, as the splats are drawn (shaders.hpp).
  precise vec3 rel = a_sphere.xyz - u_eye;
  vec3 c = mat3(u_view) * rel;
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
  // The quads follow the batch's points in the counters.
  v_slot = uint(gl_InstanceID + u_base);
}
)";

// The point proxies: the host computed each one's window position, depth
// and side (QueryExecutor::point_proxy); the counter is the vertex's.
constexpr const char* kPointVertex = R"(#version 450 core
layout(location = 0) in vec4 a_point;
flat out uint v_slot;
void main() {
  gl_Position = vec4(a_point.xyz, 1.0);
  gl_PointSize = a_point.w;
  v_slot = uint(gl_VertexID);
}
)";

// kCounterLanes counters per request, one per pixel of a 4 x 4 tile, summed
// on the host: a proxy covering much of the screen (a block near a
// street-level eye) adds to 16 addresses instead of one. On llvmpipe an
// atomic is cheap; on a GPU the additions to one address serialize, the
// first suspect of the 264 ms frames of `hoq` on an H200 (issue 28).
constexpr const char* kBatchFragment = R"(#version 450 core
layout(early_fragment_tests) in;
flat in uint v_slot;
uniform uint u_count;
layout(std430, binding = 0) buffer Counters { uint counts[]; };
void main() {
  uint lane = (uint(gl_FragCoord.x) & 3u) | ((uint(gl_FragCoord.y) & 3u) << 2);
  atomicAdd(counts[lane * u_count + v_slot], 1u);
}
)";
constexpr std::size_t kCounterLanes = 16;

// The counters' binding point (the renderer binds no storage buffers).
constexpr GLuint kCounterBinding = 0;

std::uint64_t thread_cpu_ns() {
  timespec t{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
  return std::uint64_t(t.tv_sec) * 1'000'000'000u + std::uint64_t(t.tv_nsec);
}

gl::Program link_program(const char* vertex, const char* fragment, const char* label) {
  const gl::Shader vs = gl::Shader::compile(GL_VERTEX_SHADER, vertex, label);
  const gl::Shader fs = gl::Shader::compile(GL_FRAGMENT_SHADER, fragment, label);
  const gl::Shader* stages[] = {&vs, &fs};
  return gl::Program::link(stages, label);
}

// A vertex array whose attribute 0 is a vec4 from binding 0, per instance
// (divisor 1) or per vertex (0).
gl::VertexArray vec4_attribute(GLuint divisor) {
  gl::VertexArray vao = gl::VertexArray::create();
  gl::VertexArrayAttribFormat(vao.id(), 0, 4, GL_FLOAT, GL_FALSE, 0);
  gl::VertexArrayAttribBinding(vao.id(), 0, 0);
  gl::VertexArrayBindingDivisor(vao.id(), 0, divisor);
  gl::EnableVertexArrayAttrib(vao.id(), 0);
  return vao;
}

}  // namespace

QueryExecutor::QueryExecutor(QueryExecutorOptions options) : options_(options) {
  if (!gl::loaded()) throw gl::GlError("QueryExecutor: no GL context is current");
  options_.batches_in_flight = std::max<std::size_t>(options_.batches_in_flight, 1);
  proxy_ = link_program(kBatchVertex, kBatchFragment, "query proxy");
  // Looked up once: run() sets them every frame that issues.
  u_view_ = gl::GetUniformLocation(proxy_.id(), "u_view");
  u_eye_ = gl::GetUniformLocation(proxy_.id(), "u_eye");
  u_proj_ = gl::GetUniformLocation(proxy_.id(), "u_proj");
  u_base_ = gl::GetUniformLocation(proxy_.id(), "u_base");
  u_count_ = gl::GetUniformLocation(proxy_.id(), "u_count");
  vao_ = vec4_attribute(1);
  point_proxy_ = link_program(kPointVertex, kBatchFragment, "query point proxy");
  u_point_count_ = gl::GetUniformLocation(point_proxy_.id(), "u_count");
  point_vao_ = vec4_attribute(0);
  GLfloat range[2] = {1.0f, 1.0f};
  gl::GetFloatv(GL_POINT_SIZE_RANGE, range);
  max_point_size_ = range[1];
  ring_.resize(options_.batches_in_flight);
  gl::check("QueryExecutor setup");
}

QueryExecutor::~QueryExecutor() {
  for (Batch& b : ring_) {
    if (b.fence != nullptr) gl::DeleteSync(b.fence);
  }
}

void QueryExecutor::begin_frame_render_thread(const FrontList& list, std::uint64_t frame) {
  frame_ = frame;
  fence_last_batch_render_thread();
  if (list.hierarchy == nullptr || list.generation == generation_) return;
  generation_ = list.generation;
  // What an older generation left unissued: requests that were due and did
  // not fit (cap, full ring) are dropped, they asked about a cut no longer
  // drawn; those held back only by the minimum batch are kept and join this
  // generation's batch (else a strategy that posts a few requests with every
  // list would never see one issued). Another model drops them all: they
  // name nodes of the old hierarchy.
  std::size_t keep = std::max(due_end_, queue_next_);
  if (list.hierarchy != hierarchy_) keep = queue_.size();
  stats_.dropped += keep - queue_next_;
  queue_.erase(queue_.begin(), queue_.begin() + static_cast<std::ptrdiff_t>(keep));
  queue_next_ = 0;
  due_end_ = 0;
  if (list.hierarchy != hierarchy_) {
    // Another model: queries in flight name nodes of the old one. Their
    // answers are still read (in order) but describe the old hierarchy; the
    // stage drops results of a model it replaced along with its state.
    hierarchy_ = list.hierarchy;
  }
  queue_.reserve(queue_.size() + list.queries.size());
  for (const QueryRequest& r : list.queries) queue_.push_back({r, frame});
  stats_.queued = queue_.size();
}

void QueryExecutor::answer(const Queued& q, std::uint32_t samples, std::uint64_t issued) {
  const QueryRequest& r = q.request;
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
  // From the request: a batch's deferral is part of what a strategy waits.
  const std::uint64_t latency = frame_ - q.frame_requested;
  stats_.latency_frames_total += latency;
  stats_.latency_frames_max = std::max(stats_.latency_frames_max, latency);
  stats_.latency_frames_max_last = std::max(stats_.latency_frames_max_last, latency);
}

bool QueryExecutor::answer_on_host(const Queued& q, const ViewSnapshot& view) {
  const QueryRequest& r = q.request;
  const glm::vec4 s = r.sphere;
  if (!(s.w > 0.0f && std::isfinite(s.w) && std::isfinite(s.x) && std::isfinite(s.y) &&
        std::isfinite(s.z))) {  // no sphere to test (QueryRequest::sphere)
    answer(q, 0, frame_);
    return true;
  }
  const glm::vec3 d = glm::vec3(s) - view.derived.eye;
  if (d.x * d.x + d.y * d.y + d.z * d.z <= s.w * s.w) {
    // The eye inside the sphere: it covers the whole view.
    answer(q,
           r.kind == QueryKind::AnySamples ? 1u : std::uint32_t(view.viewport.x * view.viewport.y),
           frame_);
    return true;
  }
  return false;
}

bool QueryExecutor::point_proxy(glm::vec4 sphere, const ViewSnapshot& view, glm::vec4& out) const {
  const glm::mat4& p = view.projection;
  const float w = float(view.viewport.x), h = float(view.viewport.y);
  // Not entirely in front of the eye's plane, or NaN: the quad path.
  SphereWindowRect rect;
  if (!sphere_window_rect(view.view, p, glm::vec2(w, h), sphere, rect)) return false;
  const glm::vec3 c = rect.eye_center;
  const float r = sphere.w;
  const float x0 = rect.x0, x1 = rect.x1, y0 = rect.y0, y1 = rect.y1;
  // Clipped to the viewport: a point whose center lies outside the clip
  // volume is discarded whole, so the sprite is centered on the visible part.
  const float cx0 = std::max(x0, 0.0f), cx1 = std::min(x1, w);
  const float cy0 = std::max(y0, 0.0f), cy1 = std::min(y1, h);
  if (cx0 >= cx1 || cy0 >= cy1) {
    out.w = -1.0f;  // no pixel center of the view inside: the sphere covers none
    return true;
  }
  // A sprite of side S covers the pixels whose centers lie in the S x S
  // square around its center (the rule of a polygon's rasterization too):
  // the square of the rectangle's longer side holds the whole rectangle.
  const float side = std::max(cx1 - cx0, cy1 - cy0);
  if (side > max_point_size_) return false;
  // The depth of the sphere's nearest plane: in front of all of the sphere.
  // In front of the near plane (or NaN): depth 0, which passes everywhere.
  const float zf = c.z + r;
  float ndc_z = (p[2][2] * zf + p[3][2]) / -zf;
  if (!(ndc_z >= -1.0f)) ndc_z = -1.0f;
  ndc_z = std::min(ndc_z, 1.0f);
  out = glm::vec4((cx0 + cx1) / w - 1.0f, (cy0 + cy1) / h - 1.0f, ndc_z, side);
  return true;
}

void QueryExecutor::begin_proxy_state() {
  gl::GetIntegerv(GL_DEPTH_FUNC, &depth_func_);
  // LEQUAL: a proxy exactly on an occluder's depth counts as visible.
  gl::DepthFunc(GL_LEQUAL);
  gl::Enable(GL_DEPTH_CLAMP);
}

void QueryExecutor::end_proxy_state() {
  gl::BindVertexArray(0);
  gl::UseProgram(0);
  gl::Disable(GL_DEPTH_CLAMP);
  gl::DepthFunc(static_cast<GLenum>(depth_func_));
}

void QueryExecutor::poll_render_thread() {
  while (ring_count_ > 0) {
    Batch& b = ring_[ring_head_];
    if (b.fence == nullptr) break;  // issued this frame: fenced when the next one begins
    if (frame_ < b.frame_issued + options_.min_answer_frames) break;  // the latency model
    // Timeout 0: a status check, never a wait.
    const GLenum status = gl::ClientWaitSync(b.fence, 0, 0);
    if (status == GL_WAIT_FAILED) throw gl::GlError("QueryExecutor: glClientWaitSync failed");
    if (status != GL_ALREADY_SIGNALED && status != GL_CONDITION_SATISFIED) break;  // in order
    gl::DeleteSync(b.fence);
    b.fence = nullptr;
    // Signaled: the counters in the mapping are final (the barrier before
    // the fence made the shader's atomics visible to the mapping).
    const std::size_t n = b.requests.size();
    for (std::size_t i = 0; i < n; ++i) {
      const Queued& q = b.requests[i];
      std::uint32_t c = 0;
      for (std::size_t lane = 0; lane < kCounterLanes; ++lane) {
        std::uint32_t part = 0;
        std::memcpy(&part, b.mapped + (lane * n + i) * sizeof(std::uint32_t), sizeof part);
        c += part;
      }
      answer(q, q.request.kind == QueryKind::AnySamples ? (c > 0 ? 1u : 0u) : c, b.frame_issued);
    }
    b.requests.clear();
    ring_head_ = (ring_head_ + 1) % ring_.size();
    --ring_count_;
  }
  stats_.pending = 0;
  for (std::size_t k = 0; k < ring_count_; ++k) {
    stats_.pending += ring_[(ring_head_ + k) % ring_.size()].requests.size();
  }
}

void QueryExecutor::collect_proxies_render_thread(Batch& b, const ViewSnapshot& view,
                                                  std::size_t end) {
  b.requests.clear();
  staging_.clear();
  staging_quads_.clear();
  quad_requests_.clear();
  const bool points = options_.point_proxies && is_perspective_frustum(view.projection);
  for (std::size_t i = queue_next_; i < end; ++i) {
    const Queued& q = queue_[i];
    stats_.deferral_frames_total += frame_ - q.frame_requested;
    if (answer_on_host(q, view)) continue;
    const glm::vec4 s = q.request.sphere;
    glm::vec4 pt;
    if (points && point_proxy(s, view, pt)) {
      if (pt.w < 0.0f) {
        ++stats_.offscreen;
        answer(q, 0, frame_);
        continue;
      }
      b.requests.push_back(q);
      staging_.push_back(pt);
    } else {
      quad_requests_.push_back(q);
      staging_quads_.push_back(s);
    }
  }
  queue_next_ = end;
}

void QueryExecutor::reserve_batch_buffer(Batch& b, std::size_t n) {
  if (b.capacity >= n) return;
  // Grown to a power of two: a few sizes over a run, then reused.
  std::size_t cap = 256;
  while (cap < n) cap *= 2;
  // Counters and proxies in one buffer, mapped once, persistent and
  // coherent: the batch is written straight into the mapping (a
  // glNamedBufferSubData may make the driver synchronize), and a read after
  // the fence needs only GL_CLIENT_MAPPED_BUFFER_BARRIER_BIT.
  constexpr GLbitfield kMap =
      GL_MAP_READ_BIT | GL_MAP_WRITE_BIT | GL_MAP_PERSISTENT_BIT | GL_MAP_COHERENT_BIT;
  const std::size_t bytes = cap * (kCounterLanes * sizeof(std::uint32_t) + sizeof(glm::vec4)) + 16;
  b.buffer = gl::Buffer::create(bytes, nullptr, kMap);
  b.mapped = static_cast<std::byte*>(
      gl::MapNamedBufferRange(b.buffer.id(), 0, static_cast<GLsizeiptr>(bytes), kMap));
  if (b.mapped == nullptr) throw gl::GlError("QueryExecutor: cannot map the sample counters");
  if (b.capacity == 0) ++stats_.pool_size;
  b.capacity = cap;
}

std::size_t QueryExecutor::write_batch(Batch& b, std::size_t n_points, std::size_t n_quads) {
  const std::size_t n = b.requests.size();
  // n zeroed counters, then (16-byte aligned) the points and the quads'
  // spheres. The slot's last batch was read after its fence: the GPU is
  // done with this memory.
  const std::size_t counters = kCounterLanes * n * sizeof(std::uint32_t);
  const std::size_t data_at = (counters + 15) / 16 * 16;
  std::memset(b.mapped, 0, counters);
  // (memcpy from an empty vector's data() may be from a null pointer: UB)
  if (n_points > 0) {
    std::memcpy(b.mapped + data_at, staging_.data(), n_points * sizeof(glm::vec4));
  }
  if (n_quads > 0) {
    std::memcpy(b.mapped + data_at + n_points * sizeof(glm::vec4), staging_quads_.data(),
                n_quads * sizeof(glm::vec4));
  }
  return data_at;
}

void QueryExecutor::draw_batch_render_thread(const Batch& b, const ViewSnapshot& view,
                                             std::size_t data_at, std::size_t n_points,
                                             std::size_t n_quads) {
  begin_proxy_state();
  gl::BindBufferBase(GL_SHADER_STORAGE_BUFFER, kCounterBinding, b.buffer.id());
  const auto n = static_cast<GLuint>(n_points + n_quads);
  gl::ProgramUniform1ui(point_proxy_.id(), u_point_count_, n);
  gl::ProgramUniform1ui(proxy_.id(), u_count_, n);
  if (n_points > 0) {
    gl::GetIntegerv(GL_PROGRAM_POINT_SIZE, &program_point_size_);
    if (program_point_size_ == 0) gl::Enable(GL_PROGRAM_POINT_SIZE);
    gl::UseProgram(point_proxy_.id());
    gl::VertexArrayVertexBuffer(point_vao_.id(), 0, b.buffer.id(), static_cast<GLintptr>(data_at),
                                sizeof(glm::vec4));
    gl::BindVertexArray(point_vao_.id());
    gl::DrawArrays(GL_POINTS, 0, static_cast<GLsizei>(n_points));
    if (program_point_size_ == 0) gl::Disable(GL_PROGRAM_POINT_SIZE);
  }
  if (n_quads > 0) {
    gl::UseProgram(proxy_.id());
    const glm::mat4 rotation = view.eye_relative_view();
    gl::ProgramUniformMatrix4fv(proxy_.id(), u_view_, 1, GL_FALSE, glm::value_ptr(rotation));
    gl::ProgramUniform3f(proxy_.id(), u_eye_, view.derived.eye.x, view.derived.eye.y,
                         view.derived.eye.z);
    gl::ProgramUniformMatrix4fv(proxy_.id(), u_proj_, 1, GL_FALSE, glm::value_ptr(view.projection));
    gl::ProgramUniform1i(proxy_.id(), u_base_, static_cast<GLint>(n_points));
    gl::VertexArrayVertexBuffer(vao_.id(), 0, b.buffer.id(),
                                static_cast<GLintptr>(data_at + n_points * sizeof(glm::vec4)),
                                sizeof(glm::vec4));
    gl::BindVertexArray(vao_.id());
    gl::DrawArraysInstancedBaseInstance(GL_TRIANGLE_STRIP, 0, 4, static_cast<GLsizei>(n_quads), 0);
  }
  gl::BindBufferBase(GL_SHADER_STORAGE_BUFFER, kCounterBinding, 0);
  // No barrier and fence here: fence_last_batch_render_thread() sets them
  // when the next frame begins (see there).
  end_proxy_state();
}

void QueryExecutor::issue_render_thread(const ViewSnapshot& view, std::size_t end) {
  if (ring_count_ > 0 && ring_[(ring_head_ + ring_count_ - 1) % ring_.size()].fence == nullptr) {
    return;  // run() twice in one frame: one batch per frame, the rest waits
  }
  if (ring_count_ == ring_.size()) {
    ++stats_.ring_full;  // every slot still on the GPU: the requests wait a frame
    return;
  }
  Batch& b = ring_[(ring_head_ + ring_count_) % ring_.size()];
  collect_proxies_render_thread(b, view, end);
  const std::size_t n_points = b.requests.size();
  const std::size_t n_quads = quad_requests_.size();
  // Points first: the same order as the counters.
  b.requests.insert(b.requests.end(), quad_requests_.begin(), quad_requests_.end());
  if (b.requests.empty()) return;
  const std::size_t n = b.requests.size();
  reserve_batch_buffer(b, n);
  const std::size_t data_at = write_batch(b, n_points, n_quads);
  draw_batch_render_thread(b, view, data_at, n_points, n_quads);
  b.frame_issued = frame_;
  ++ring_count_;
  ++stats_.batches;
  stats_.issued += n;
  stats_.issued_last += n;
  stats_.pending += n;
  stats_.point_proxies += n_points;
  stats_.quad_proxies += n_quads;
}

void QueryExecutor::fence_last_batch_render_thread() {
  if (ring_count_ == 0) return;
  Batch& b = ring_[(ring_head_ + ring_count_ - 1) % ring_.size()];
  if (b.fence != nullptr) return;
  const std::uint64_t cpu0 = thread_cpu_ns();
  // The barrier makes the shader's atomics visible to the mapping; the fence
  // after it says when. Both here, before the frame draws anything, and not
  // right after the batch's draw: a driver may implement the barrier as a
  // wait for everything drawn so far (llvmpipe does, a glFinish), and here
  // that is nothing, the last frame having ended with a swap, read-back or
  // glFinish. The flush sends the fence on its way (polls never flush: that
  // would be a wait on llvmpipe, in the middle of a frame).
  gl::MemoryBarrier(GL_CLIENT_MAPPED_BUFFER_BARRIER_BIT);
  b.fence = gl::FenceSync(GL_SYNC_GPU_COMMANDS_COMPLETE, 0);
  gl::Flush();
  fence_ns_ += thread_cpu_ns() - cpu0;
}

void QueryExecutor::run(const ViewSnapshot& view) {
  const auto wall0 = std::chrono::steady_clock::now();
  const std::uint64_t cpu0 = thread_cpu_ns();
  stats_.issued_last = 0;
  stats_.answered_last = 0;
  stats_.latency_frames_max_last = 0;
  // Poll first: a query issued in this frame is never read in this frame.
  poll_render_thread();
  stats_.poll_ns_last = thread_cpu_ns() - cpu0;
  if (queue_next_ < queue_.size() && hierarchy_ != nullptr) {
    // The minimum batch: issue when enough are queued, the oldest has waited
    // long enough, or some were already due and did not fit (cap, ring).
    const bool due = queue_next_ < due_end_ || queue_.size() - queue_next_ >= options_.min_batch ||
                     frame_ - queue_[queue_next_].frame_requested >= options_.max_defer_frames;
    if (due) {
      due_end_ = queue_.size();
      issue_render_thread(view,
                          std::min(queue_.size(), queue_next_ + options_.max_issue_per_frame));
    } else {
      ++stats_.deferred_runs;
    }
  }
  if (queue_next_ == queue_.size() && !queue_.empty()) {
    // All issued: the queue's memory is reused by the next generation.
    queue_.clear();
    queue_next_ = 0;
    due_end_ = 0;
  }
  stats_.queued = queue_.size() - queue_next_;
  // The fence set when this frame began is part of the executor's cost.
  stats_.cpu_ns_last = thread_cpu_ns() - cpu0 + fence_ns_;
  fence_ns_ = 0;
  stats_.cpu_ns_total += stats_.cpu_ns_last;
  stats_.wall_ns_last = static_cast<std::uint64_t>(
      std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::steady_clock::now() - wall0)
          .count());
}

}  // namespace treecut::splat
