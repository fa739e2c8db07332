// The GL side of the in-frame occlusion traversals (strategies/chc.hpp,
// strategies/occlusion_device.hpp): GL occlusion queries of block boxes
// against the depth the frame has drawn so far, polled with
// GL_QUERY_RESULT_AVAILABLE, and the blocks' representations drawn through
// the renderer's in-frame ranges (Renderer::begin_frame_ranges).
//
// - One element buffer holds every block's representation (the HlodBlocks'
//   concatenated ranges), uploaded once: drawing a block is one
//   glDrawElements of its range, no per-frame upload.
// - Box proxies: one empty vertex array and the unit cube's 12 triangles made
//   in the vertex shader (gl_VertexID), scaled to the box by two uniforms;
//   back faces culled (the eye is outside every queried box: boxes at the
//   near plane never get here, the traversal takes them as visible), so the
//   samples are the box's unoccluded pixels; color and depth writes off,
//   GL_LEQUAL, depth clamping on (a box crossing the far plane still counts
//   its pixels).
// - A pool of GL_SAMPLES_PASSED query objects made once (grown only if a
//   frame has more queries in flight than ever before): no GL object is
//   created per frame in a steady state.
// - result_render_thread reads GL_QUERY_RESULT only after
//   GL_QUERY_RESULT_AVAILABLE said true for that query, except when the
//   traversal asks for an answer that is not there (stop-and-wait's every
//   query; CHC's with an empty traversal queue): that read blocks in the
//   driver, and its time is the frame's wait_ms and counts as a blocking
//   read (tests/culling/chc_gl_test.cpp checks both with interposed entry points).
//
// Render thread only, with the renderer's context current. The renderer and
// the blocks must outlive the device; the blocks must be of the renderer's
// hierarchy (checked by node count).
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "treecut/culling/chc.hpp"
#include "treecut/culling/hlod_blocks.hpp"
#include "treecut/culling/occlusion_device.hpp"
#include "treecut/splat/camera.hpp"
#include "treecut/splat/gl_objects.hpp"
#include "treecut/splat/renderer.hpp"

namespace treecut::splat {

class GlOcclusionDevice final : public culling::OcclusionDeviceRenderThread {
 public:
  /// Uploads the representations, makes `initial_queries` query objects and
  /// the proxy program. Throws std::invalid_argument when the blocks were
  /// built for another hierarchy than the renderer's.
  GlOcclusionDevice(Renderer& renderer, const culling::HlodBlocks& blocks,
                    std::size_t initial_queries = 1024);
  GlOcclusionDevice(const GlOcclusionDevice&) = delete;
  GlOcclusionDevice& operator=(const GlOcclusionDevice&) = delete;
  ~GlOcclusionDevice() override;

  /// The camera and settings of the next frames (fast or fixed mode).
  void set_view_render_thread(const Camera& camera, const RenderSettings& settings);

  void begin_frame_render_thread() override;
  culling::QueryHandle query_box_render_thread(culling::BlockId b) override;
  culling::QueryHandle query_draw_render_thread(culling::BlockId b) override;
  bool result_available_render_thread(culling::QueryHandle q) override;
  std::uint64_t result_render_thread(culling::QueryHandle q) override;
  void draw_render_thread(culling::BlockId b) override;
  void end_frame_render_thread(bool finish) override;
  [[nodiscard]] const culling::DeviceFrameStats& frame_stats() const override { return stats_; }

  /// Diagnostics: a glFlush after every block draw. On llvmpipe the first
  /// availability poll of a query flushes the batched work (Mesa starts
  /// rasterizing at a flush), so CHC's polling cuts a frame into many small
  /// batches; this gives a query-free mode (Ideal) the same cuts, to measure
  /// what they cost (`treecut bench occlusion`, docs/occlusion.md).
  void set_flush_after_draw(bool flush) { flush_after_draw_ = flush; }

  /// The renderer's stats of the last frame.
  [[nodiscard]] const FrameStats& last_frame() const { return last_frame_; }
  /// Query objects made so far (the pool).
  [[nodiscard]] std::size_t query_objects() const { return pool_.size(); }
  /// Times the pool had to grow after construction.
  [[nodiscard]] std::uint64_t pool_growths() const { return pool_growths_; }
  /// The GL name of a handle's query object (tests).
  [[nodiscard]] GLuint query_name(culling::QueryHandle q) const { return pool_[q].id(); }

 private:
  culling::QueryHandle acquire();
  void enter_proxy_state();
  void leave_proxy_state();

  Renderer* renderer_;
  const culling::HlodBlocks* blocks_;
  Camera camera_;
  RenderSettings settings_;
  gl::Buffer elements_;               // every representation, back to back
  std::vector<std::uint32_t> first_;  // per block: its first position in elements_
  NodeId max_id_ = 0;
  gl::Program proxy_;
  GLint u_view_proj_ = -1, u_lo_ = -1, u_hi_ = -1;
  glm::vec3 eye_{0.0f};  ///< the frame's eye: proxies are drawn relative to it
  gl::VertexArray proxy_vao_;
  std::vector<gl::Query> pool_;
  std::vector<culling::QueryHandle> free_;
  std::vector<std::uint8_t> seen_available_;  // per handle, since its issue
  std::uint64_t pool_growths_ = 0;
  bool proxy_state_ = false;
  bool flush_after_draw_ = false;
  bool in_frame_ = false;
  culling::DeviceFrameStats stats_;
  FrameStats last_frame_;
};

}  // namespace treecut::splat
