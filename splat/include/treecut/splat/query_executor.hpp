// QueryExecutor: runs the GPU visibility queries a strategy posts with a list
// (FrontList::queries) and hands the answers back as VisibilityResults.
//
// - Once per list generation: the requests of a generation are queued when
//   that generation becomes the drawn list, never again on a later poll that
//   returns the same list. Requests of an older generation that were due
//   and not yet issued (the cap, a full ring) are dropped when a newer list
//   arrives (counted): they were asked about a cut that is no longer drawn,
//   and the strategy asks again with its next list.
// - A minimum batch (CHC++'s query batching, Mattausch, Bittner and Wimmer
//   2008: batches cut the state changes): every batch pays a fixed cost
//   (~100-150 us of render-thread CPU on llvmpipe, docs/rendering.md)
//   whatever it holds, so queued requests go out when at least min_batch
//   are queued or when the oldest has waited max_defer_frames frames
//   (defaults 256 and 1): a trickle of 100 requests per frame goes out every
//   other frame as one batch of 200, a large batch at once. Requests held
//   back only by this rule are kept when a newer generation arrives (they
//   join its batch: a strategy posting a new list every frame still gets
//   answers; a request the newer list repeats is then issued and answered
//   twice); those that were due and did not fit (cap, full ring) are
//   dropped as below. The contract for a strategy: a strategy asking for
//   few queries gets its answers up to max_defer_frames frames later than
//   without batching. frame_issued stays the frame the proxy was drawn in;
//   the latency stats count from the frame the request was queued in
//   (frame_read - frame requested), the deferral included.
// - A per-frame cap (max_issue_per_frame): the rest waits for later frames.
// - One batch per frame: the frame's issued requests are ONE draw of their
//   point proxies (and one instanced draw of the few quads, below), from a
//   buffer written once per batch, against the frame's depth, color and
//   depth writes off, depth clamping on (a proxy in front of the near plane
//   passes instead of being clipped away), GL_LEQUAL. The fragment shader
//   runs after the depth test (early_fragment_tests) and adds 1 per fragment
//   to one of its request's 16 counters in a shader storage buffer (one per
//   pixel of a 4 x 4 tile, so a large proxy's fragments do not all add to one
//   address; the host sums them): on a single-sampled target exactly what
//   GL_SAMPLES_PASSED counts. QueryKind::AnySamples
//   answers count > 0.
// - The sphere tested is the request's (QueryRequest::sphere, read by the
//   strategy on its own thread): the render thread reads no hierarchy for a
//   query and keeps no copy of one (it copied every node's sphere, 16 B a
//   node, before a paged model could ask queries).
// - The proxy of a node, usually ONE point (a point costs llvmpipe a small
//   fraction of a strip of two triangles): the host computes the window
//   rectangle that bounds the projection of the node's bounding sphere
//   (exact tangent planes of a perspective projection, half a pixel wider on
//   every side, clipped to the viewport) and draws a point sprite of side
//   max(width, height) + 1 pixels at its center, at the depth of the
//   sphere's nearest plane (z_eye = c.z + r). Every pixel whose center the
//   sphere covers lies strictly inside the sprite, and every point of the
//   sphere lies behind that depth, so the point passes wherever the sphere
//   would (conservative). A rectangle that misses the viewport is answered 0
//   on the host (the sphere covers no pixel).
// - The rest take the quad path: a sphere not entirely in front of the
//   eye's plane, a sprite wider than GL_POINT_SIZE_RANGE's max, or a
//   projection that is not a perspective frustum. Its proxy is a square in
//   front of the sphere: in the plane normal to the eye-to-center axis at the
//   sphere's nearest distance, large enough to cover the cone of rays that
//   touch the sphere. Every ray that hits the sphere crosses the square no
//   farther than the sphere (conservative). Points and quads are two draws
//   of one batch (the second only if there are quads).
//   An eye inside the sphere is answered visible at once, without the GPU.
// - A small ring of counter buffers (batches_in_flight), made once and reused
//   (no buffer per frame once the ring has grown), persistently mapped: the
//   batch is written into the mapping (no glBufferSubData), its counters read
//   from it. A batch gets its memory barrier and fence when the next frame
//   begins (begin_frame_render_thread); its counters are read only after
//   glClientWaitSync(fence, 0, 0) said signaled: never a blocking read.
//   Batches are polled in issue order and a poll stops at the first one
//   still pending (a GPU answers in order).
//
// Why not one GL query object per request: measured (query_bench, llvmpipe)
// the batch costs the same render-thread CPU as a single query object for
// one request and 6 to 10 times less from 10 requests on; see
// docs/rendering.md.
//
// All members: render thread only, with the GL context current. The executor
// is a QueryHook: the renderer calls run() inside draw(); RenderThreadFrame
// (frame.hpp) wires it up and posts the results to the stage.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "treecut/feedback_stage.hpp"
#include "treecut/hierarchy.hpp"
#include "treecut/splat/gl_objects.hpp"
#include "treecut/splat/renderer.hpp"
#include "treecut/view_snapshot.hpp"

namespace treecut::splat {

struct QueryExecutorOptions {
  /// Queries issued per frame at most; the rest are carried to later frames.
  std::size_t max_issue_per_frame = 4096;
  /// Batches in flight at most (the ring of counter buffers); a frame that
  /// finds every one still unsignaled issues nothing (its requests wait).
  std::size_t batches_in_flight = 4;
  /// Issue when at least this many requests are queued (see above); 0 or 1:
  /// every frame that has requests issues them (no batching).
  std::size_t min_batch = 256;
  /// ... or when the oldest queued request has waited this many frames.
  std::uint64_t max_defer_frames = 1;
  /// Point proxies where they fit (see above); false: every proxy a quad
  /// (for the tests and the benchmark's comparison).
  bool point_proxies = true;
  /// The GPU-latency model (culling/gpu_latency.hpp): a batch's answers are
  /// read no earlier than this many frames after the frame it was issued in
  /// (its fence signaled or not). 1, the least, is what a fence allows.
  std::uint64_t min_answer_frames = 1;
};

/// Counters of the executor (cesium-native's tilesOccluded /
/// tilesWaitingForOcclusionResults in spirit). Totals since construction.
struct QueryStats {
  std::uint64_t issued = 0;    ///< proxies drawn inside a query
  std::uint64_t answered = 0;  ///< results read (and those answered without the GPU)
  std::uint64_t occluded = 0;  ///< answers with 0 samples
  std::uint64_t dropped = 0;   ///< requests of a replaced generation never issued
  std::size_t pending = 0;     ///< issued, answer not yet available
  std::size_t queued = 0;      ///< requested, not yet issued (waiting for the cap)
  std::uint64_t latency_frames_total =
      0;  ///< sum of frame_read - frame requested (deferral included)
  std::uint64_t latency_frames_max = 0;
  std::uint64_t cpu_ns_total = 0;  ///< render-thread CPU time in run() (issue + poll)
  std::uint64_t cpu_ns_last = 0;   ///< of the last run()
  std::uint64_t poll_ns_last = 0;  ///< of which polling earlier batches (CPU time)
  std::uint64_t wall_ns_last = 0;  ///< wall time of the last run() (a wait would show here)
  std::size_t issued_last = 0;     ///< issued by the last run()
  std::size_t answered_last = 0;   ///< read by the last run()
  std::uint64_t latency_frames_max_last = 0;  ///< of the answers read by the last run()
  std::uint64_t batches = 0;                  ///< batches issued (one draw and one fence each)
  std::uint64_t ring_full = 0;      ///< runs that issued nothing: every counter buffer in flight
  std::size_t pool_size = 0;        ///< counter buffers made (ring slots in use so far)
  std::uint64_t point_proxies = 0;  ///< proxies drawn as one point
  std::uint64_t quad_proxies = 0;   ///< proxies drawn as a square of two triangles
  std::uint64_t offscreen = 0;  ///< answered 0 on the host: the sphere's rectangle misses the view
  std::uint64_t deferred_runs = 0;  ///< runs that held queued requests back (below min_batch)
  std::uint64_t deferral_frames_total = 0;  ///< sum of frame issued - frame requested
  [[nodiscard]] double latency_frames_mean() const {
    return answered == 0 ? 0.0 : double(latency_frames_total) / double(answered);
  }
};

class QueryExecutor final : public QueryHook {
 public:
  explicit QueryExecutor(QueryExecutorOptions options = {});
  ~QueryExecutor() override;
  QueryExecutor(const QueryExecutor&) = delete;
  QueryExecutor& operator=(const QueryExecutor&) = delete;

  /// Render thread, before draw(): the list drawn this frame and the frame's
  /// number (the stage's frame counter). A generation seen for the first time
  /// queues its requests; the same generation again changes nothing. Takes
  /// the node spheres when the list's hierarchy is new. Sets the barrier and
  /// fence of the last frame's batch (before this frame draws anything).
  void begin_frame_render_thread(const FrontList& list, std::uint64_t frame);

  /// Render thread, called by the renderer inside draw() with the frame's
  /// depth complete: polls earlier queries, then issues queued ones (cap).
  void run(const ViewSnapshot& view) override;

  /// Answers read since the last clear_results(), in the order read.
  [[nodiscard]] std::span<const VisibilityResult> results() const { return results_; }
  void clear_results() { results_.clear(); }

  [[nodiscard]] const QueryStats& stats() const { return stats_; }
  [[nodiscard]] const QueryExecutorOptions& options() const { return options_; }
  void set_max_issue_per_frame(std::size_t n) { options_.max_issue_per_frame = n; }

 private:
  // A queued request and the frame it was queued in (its latency counts
  // from there).
  struct Queued {
    QueryRequest request;
    std::uint64_t frame_requested = 0;
  };
  // One slot of the ring of batches: a batch's instance spheres and counters
  // stay untouched until its fence was seen signaled.
  struct Batch {
    // n counters (one uint per proxy), then at a 16-byte aligned offset
    // the points' vec4s (ndc x, y, depth, side in pixels), then the quads'
    // spheres (vec4 center, radius): points first, the same order as the
    // counters.
    gl::Buffer buffer;
    std::byte* mapped = nullptr;  // the whole buffer, mapped persistent and coherent
    std::size_t capacity = 0;
    GLsync fence = nullptr;
    std::vector<Queued> requests;  // instance i answers requests[i]
    std::uint64_t frame_issued = 0;
  };
  // Answers without the GPU (no sphere to test, or the eye inside it);
  // false if the request needs a proxy.
  bool answer_on_host(const Queued& q, const ViewSnapshot& view);
  // The point proxy of a sphere (ndc x, y, depth, side px); w < 0: it
  // misses the viewport; false: it needs the quad path.
  bool point_proxy(glm::vec4 sphere, const ViewSnapshot& view, glm::vec4& out) const;
  void fence_last_batch_render_thread();
  void poll_render_thread();
  void issue_render_thread(const ViewSnapshot& view, std::size_t end);
  // The steps of issue_render_thread(): the requests up to END answered on
  // the host or sorted into B's points and the quads (staging_*,
  // quad_requests_); B's buffer grown to N proxies; the counters zeroed and
  // the proxies written (returns the proxies' offset); the proxies drawn.
  void collect_proxies_render_thread(Batch& b, const ViewSnapshot& view, std::size_t end);
  void reserve_batch_buffer(Batch& b, std::size_t n);
  std::size_t write_batch(Batch& b, std::size_t n_points, std::size_t n_quads);
  void draw_batch_render_thread(const Batch& b, const ViewSnapshot& view, std::size_t data_at,
                                std::size_t n_points, std::size_t n_quads);
  void begin_proxy_state();
  void end_proxy_state();
  void answer(const Queued& q, std::uint32_t samples, std::uint64_t issued);

  QueryExecutorOptions options_;
  QueryStats stats_;
  std::uint64_t frame_ = 0;
  std::uint64_t generation_ = 0;
  const Hierarchy* hierarchy_ = nullptr;
  std::vector<Queued> queue_;   // the current generation's (and deferred older ones)
  std::size_t queue_next_ = 0;  // first not yet issued
  std::size_t due_end_ = 0;     // [queue_next_, due_end_): were due, did not fit
  // Batched: a ring of slots, [ring_head_, ring_head_ + ring_count_) in flight.
  std::vector<Batch> ring_;
  std::size_t ring_head_ = 0, ring_count_ = 0;
  std::vector<glm::vec4> staging_;        // the batch's points being filled
  std::vector<glm::vec4> staging_quads_;  // and its quads' spheres
  std::vector<Queued> quad_requests_;
  std::uint64_t fence_ns_ = 0;  // CPU time of the last fence, charged to the next run()
  gl::VertexArray vao_;         // quads: per-instance spheres
  gl::VertexArray point_vao_;   // points: per-vertex
  gl::Program proxy_;           // quads
  gl::Program point_proxy_;
  GLint u_view_ = -1, u_eye_ = -1, u_proj_ = -1, u_base_ = -1, u_count_ = -1, u_point_count_ = -1;
  GLint depth_func_ = GL_LESS;
  GLint program_point_size_ = 0;
  float max_point_size_ = 1.0f;  // GL_POINT_SIZE_RANGE's max
  std::vector<VisibilityResult> results_;
};

}  // namespace treecut::splat
