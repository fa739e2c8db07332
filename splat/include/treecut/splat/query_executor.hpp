// QueryExecutor: runs the GPU visibility queries a strategy posts with a list
// (FrontList::queries) and hands the answers back as VisibilityResults.
//
// - Once per list generation: the requests of a generation are queued when
//   that generation becomes the drawn list, never again on a later poll that
//   returns the same list. Requests of an older generation not yet issued are
//   dropped when a newer list arrives (counted): they were asked about a cut
//   that is no longer drawn, and the strategy asks again with its next list.
// - A per-frame cap (max_issue_per_frame): the rest waits for later frames.
// - A pool of query objects, grown on demand and reused (no glGenQueries per
//   frame once the pool has grown).
// - The proxy of a node is a screen-aligned square in front of its bounding
//   sphere: in the plane normal to the eye-to-center axis at the sphere's
//   nearest distance, large enough to cover the cone of rays that touch the
//   sphere. Every ray that hits the sphere crosses the square no farther than
//   the sphere, so the proxy passes wherever the sphere would (conservative).
//   Drawn against the frame's depth with color and depth writes off and depth
//   clamping on (a proxy in front of the near plane passes instead of being
//   clipped away). An eye inside the sphere is answered visible at once.
// - GL_SAMPLES_PASSED, or GL_ANY_SAMPLES_PASSED_CONSERVATIVE for
//   QueryKind::AnySamples.
// - A result is read only after GL_QUERY_RESULT_AVAILABLE said it is there;
//   never a blocking read. Queries are polled in issue order and the poll of
//   a frame stops at the first one still pending (a GPU answers in order).
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
};

/// Counters of the executor (cesium-native's tilesOccluded /
/// tilesWaitingForOcclusionResults in spirit). Totals since construction.
struct QueryStats {
  std::uint64_t issued = 0;                ///< proxies drawn inside a query
  std::uint64_t answered = 0;              ///< results read (and those answered without the GPU)
  std::uint64_t occluded = 0;              ///< answers with 0 samples
  std::uint64_t dropped = 0;               ///< requests of a replaced generation never issued
  std::size_t pending = 0;                 ///< issued, answer not yet available
  std::size_t queued = 0;                  ///< requested, not yet issued (waiting for the cap)
  std::uint64_t latency_frames_total = 0;  ///< sum of frame_read - frame_issued
  std::uint64_t latency_frames_max = 0;
  std::uint64_t cpu_ns_total = 0;  ///< render-thread time in run() (issue + poll)
  std::uint64_t cpu_ns_last = 0;   ///< of the last run()
  std::uint64_t poll_ns_last = 0;  ///< of which polling earlier queries
  std::size_t issued_last = 0;     ///< issued by the last run()
  std::size_t answered_last = 0;   ///< read by the last run()
  std::size_t pool_size = 0;       ///< query objects created
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
  /// queues its requests; the same generation again changes nothing. Uploads
  /// the node spheres when the list's hierarchy is new.
  void begin_frame_render_thread(const FrontList& list, std::uint64_t frame);

  /// Render thread, called by the renderer inside draw() with the frame's
  /// depth complete: polls earlier queries, then issues queued ones (cap).
  void run(const FrameView& view) override;

  /// Answers read since the last clear_results(), in the order read.
  [[nodiscard]] std::span<const VisibilityResult> results() const { return results_; }
  void clear_results() { results_.clear(); }

  [[nodiscard]] const QueryStats& stats() const { return stats_; }
  [[nodiscard]] const QueryExecutorOptions& options() const { return options_; }
  void set_max_issue_per_frame(std::size_t n) { options_.max_issue_per_frame = n; }

 private:
  struct InFlight {
    QueryRequest request;
    std::uint32_t query = 0;  // index into the pool of its kind
    std::uint64_t frame_issued = 0;
  };
  void upload_spheres(const Hierarchy& h);
  void poll_render_thread();
  void issue_render_thread(const FrameView& view);
  std::uint32_t acquire(QueryKind kind);
  void answer(const QueryRequest& r, std::uint32_t samples, std::uint64_t issued);

  QueryExecutorOptions options_;
  QueryStats stats_;
  std::uint64_t frame_ = 0;
  std::uint64_t generation_ = 0;
  const Hierarchy* hierarchy_ = nullptr;
  std::vector<glm::vec4> spheres_;   // the hierarchy's center_radius, for the eye-inside test
  std::vector<QueryRequest> queue_;  // of the current generation
  std::size_t queue_next_ = 0;       // first not yet issued
  std::vector<InFlight> in_flight_;  // issue order; [in_flight_head_, end) pending
  std::size_t in_flight_head_ = 0;
  std::vector<VisibilityResult> results_;
  // Pools per kind (a query object keeps its target): all objects, the free ones.
  std::vector<gl::Query> samples_pool_, any_pool_;
  std::vector<std::uint32_t> samples_free_, any_free_;
  gl::Buffer sphere_buffer_;
  gl::VertexArray vao_;
  gl::Program proxy_;
  GLint u_view_ = -1, u_proj_ = -1;
};

}  // namespace treecut::splat
