// The splat renderer: every node of a Hierarchy lives in one static vertex
// buffer; a cut is an index list of node ids in a CutBuffer, drawn with
// glDrawElements(GL_POINTS). Exchanging cuts only changes which index buffer
// is bound. Three splat modes:
//
//  - Fast: one pass. A geometry shader turns each node into a disc in its
//    tangent plane (a real quad, so depth is per fragment and intersecting
//    splats resolve correctly), lit per fragment with the node normal.
//  - HighQuality: deferred surface splatting after Botsch, Hornung, Zwicker,
//    Kobbelt, "High-Quality Surface Splatting on Today's GPUs" (PBG 2005):
//    a visibility pass pushed back by a depth offset, an attribute pass that
//    accumulates Gaussian-weighted color and normal of every splat within the
//    offset of the visible surface, and a normalization pass that divides by
//    the weight and shades per pixel (Phong).
//  - FixedSize: screen-space points of a fixed pixel size (the stippling look
//    of the bucket strategy).
//  - ObjectId: the discs of Fast, unlit, each pixel the index of the scene
//    object in front (r | g << 8 | b << 16; 0xffffff where nothing is; 0 for
//    a single model): the exact visibility reference of occlusion culling.
//
// All methods: render thread only, with the renderer's context current.
#pragma once

#include <array>
#include <chrono>
#include <cstddef>
#include <cstdint>
#include <glm/mat4x4.hpp>
#include <glm/vec2.hpp>
#include <glm/vec3.hpp>
#include <memory>
#include <optional>
#include <span>
#include <string_view>
#include <vector>

#include "treecut/feedback_stage.hpp"
#include "treecut/hierarchy.hpp"
#include "treecut/paged_hierarchy.hpp"
#include "treecut/splat/camera.hpp"
#include "treecut/splat/coloring.hpp"
#include "treecut/splat/gl_objects.hpp"

namespace treecut::splat {

enum class SplatMode { Fast, HighQuality, FixedSize, ObjectId };

/// "fast", "hq", "fixed", "id".
std::string_view splat_mode_name(SplatMode mode);
/// Inverse of splat_mode_name (also accepts "high-quality"); throws InputError.
SplatMode parse_splat_mode(std::string_view name);

struct Light {
  /// A headlight: the direction is given in view space and moves with the camera.
  bool follow_camera = true;
  /// Direction towards the light: view space if follow_camera, else world space.
  glm::vec3 direction{-0.35f, 0.45f, 1.0f};
  float ambient = 0.22f;
  float diffuse = 0.85f;
  float specular = 0.25f;
  float shininess = 32.0f;
  /// The colours as the file has them, no shading (a coloured scan's own
  /// light is in its colours; a headlight darkens what faces away).
  bool unlit = false;
};

struct RenderSettings {
  SplatMode mode = SplatMode::Fast;
  /// Multiplies every node's radius (model units) before drawing; > 1 closes gaps.
  float radius_scale = 1.0f;
  /// FixedSize mode: the smallest point diameter in pixels; a point is drawn
  /// at least as large as its splat's footprint, so surfaces stay closed and
  /// hide what lies behind them (at most 64 pixels).
  float point_size_px = 2.0f;
  /// HighQuality mode: how far the visibility pass is pushed back, in units of
  /// each splat's radius (Botsch et al.'s epsilon, made scale-free).
  float depth_offset = 0.6f;
  /// Skip nodes whose whole normal cone faces away from the eye.
  bool backface_culling = true;
  glm::vec3 background{0.11f, 0.12f, 0.14f};  ///< sRGB in [0, 1]
  Light light;
  /// Eye-dome lighting over the frame (Boucheny 2009, as in Potree and
  /// CloudCompare): depth edges darkened, no normals needed. Its strength,
  /// 0 = off, 1 = Potree's factor (the program's default is 0.25: every
  /// edge of an oriented disc is a depth step). Every mode but ObjectId.
  float eye_dome = 0.0f;
  /// Pixels from a pixel to the neighbours it is compared with.
  float eye_dome_radius = 1.4f;
  /// A clip box (issue 30): splats whose centre lies outside [clip_min,
  /// clip_max] (world coordinates: a single model's own) are not drawn.
  bool clip = false;
  glm::vec3 clip_min{0.0f}, clip_max{0.0f};
};

/// What one draw() did (feeds the HUD, the CSV of `treecut render` and tests).
struct FrameStats {
  std::size_t splats = 0;      ///< nodes in the drawn cut
  std::uint64_t points = 0;    ///< input points those nodes stand for
  double cpu_ms = 0.0;         ///< time to issue the frame (+ glFinish if asked)
  std::size_t draw_calls = 0;  ///< splat draw calls issued (per pass; a scene's is one per pass)
  bool finished = false;       ///< cpu_ms includes glFinish (the GPU work is done)
};

/// Where the node ids of a list point in a vertex buffer that does not hold
/// every node at its id: a paged model's GPU pool (node_pool.hpp).
class VertexMap {
 public:
  virtual ~VertexMap() = default;
  /// The vertex of each of IDS into OUT (IDS[0, CURRENT) the list drawn,
  /// the rest a fading exchange's leaving run); returns the largest.
  virtual std::uint32_t map(std::span<const NodeId> ids, std::size_t current,
                            std::vector<std::uint32_t>& out) = 0;
  /// A scene's lists (SceneCutBuffer): begin_lists() once for all of them,
  /// then map_list() for each object's list, ids of the map's model MODEL
  /// (the renderer's model index); the vertices into OUT (kNullVertex: not
  /// drawn), returns the largest.
  virtual void begin_lists() = 0;
  virtual std::uint32_t map_list(std::uint32_t model, std::span<const NodeId> ids,
                                 std::vector<std::uint32_t>& out) = 0;
  /// Vertex v lies in segment v >> segment_shift() of the pool
  /// (Renderer::pool_shift), at v & ((1 << segment_shift()) - 1).
  [[nodiscard]] virtual std::uint32_t segment_shift() const = 0;
};

/// One index list on the GPU. upload() replaces the content, writing into the
/// other of two GL buffers than the one drawn since the last upload (so the
/// write never touches a buffer a frame in flight reads); each grows (to the
/// next power of two) when needed and is never shrunk.
///
/// A fading exchange (upload with the previous list) stores three sorted runs
/// back to back: [stable | entering | leaving], the nodes in both lists, in the
/// new one only, in the old one only. size() is stable + entering (the new
/// list); the leaving run lies beyond it and is drawn only while fade() < 1.
class CutBuffer {
 public:
  CutBuffer() = default;
  /// Copies the node ids of a cut of `h`, in ascending id order (a radix sort
  /// unless already sorted: a spatially coherent draw order), and counts the
  /// input points they stand for (the sum of their point_count). O(nodes);
  /// allocates only when the cut is larger than any before. Ends a fade.
  void upload(const Hierarchy& h, std::span<const NodeId> nodes);
  /// An exchange that fades from `previous` (the list drawn so far) to `nodes`
  /// (FrameLists::previous and ::current while the stage blends): O(both),
  /// one merge of the two sorted lists; fade() starts at 0.
  void upload(const Hierarchy& h, std::span<const NodeId> nodes, std::span<const NodeId> previous);
  /// Once per frame after FeedbackStage::poll() / Controller::begin_frame():
  /// uploads a list of a new generation (fading from FrameLists::previous
  /// while the stage blends, StageOptions::blend_frames; plainly otherwise or
  /// across a model change) and sets the frame's fade weight. Returns whether
  /// it uploaded. The lists are copied here: the stage may reuse them at once.
  bool follow(const FrameLists& lists);
  /// Weight of the new list in [0, 1] (FrameLists::blend): a pixel shows the
  /// entering splats where its dither threshold is below it and the leaving
  /// ones elsewhere; 1 (and every plain upload) draws the new list alone.
  void set_fade(float weight) { fade_ = weight; }
  [[nodiscard]] float fade() const { return fade_; }
  /// Whether a draw now shows a mix of the two lists.
  [[nodiscard]] bool fading() const { return fade_ < 1.0f && (entering_ > 0 || leaving_ > 0); }
  [[nodiscard]] std::size_t size() const { return count_; }
  [[nodiscard]] std::uint64_t points() const { return points_; }
  /// The uploaded list in buffer order (what CutRange positions index):
  /// ascending ids, or stable then entering after a fading upload.
  [[nodiscard]] std::span<const NodeId> ids() const {
    return std::span<const NodeId>(sorted_).first(count_);
  }
  /// The runs of a fading upload (0, size(), 0 after a plain one).
  [[nodiscard]] std::size_t stable() const { return count_ - entering_; }
  [[nodiscard]] std::size_t entering() const { return entering_; }
  [[nodiscard]] std::size_t leaving() const { return leaving_; }
  /// The buffer holding the current list.
  [[nodiscard]] const gl::Buffer& buffer() const { return buffers_[current_]; }
  /// The hierarchy the uploaded ids belong to (null before the first
  /// upload). An identity for Renderer::draw's check, never dereferenced
  /// after upload() returns.
  [[nodiscard]] const Hierarchy* hierarchy() const { return hierarchy_; }
  /// The largest id in the buffer, the leaving run included (0 when empty).
  [[nodiscard]] NodeId max_id() const { return max_id_; }
  /// The largest vertex the buffer names: max_id() unless a map is set.
  [[nodiscard]] std::uint32_t max_vertex() const { return max_vertex_; }

  /// From the next upload on, the GPU buffer holds MAP's vertices of the
  /// ids (ids() stays the ids); null: the ids themselves. Not owned.
  void set_vertex_map(VertexMap* map) { map_ = map; }
  /// Maps the uploaded ids again and writes them (the map changed: pages
  /// that arrived on the GPU); nothing without a map.
  void refresh();

  /// Positions [first, first + count) of the buffer whose vertices lie in
  /// one segment of a pool, and the run they belong to (0 stable, 1
  /// entering, 2 leaving).
  struct SegmentRun {
    std::uint32_t first = 0;
    std::uint32_t count = 0;
    std::uint32_t segment = 0;
    std::uint32_t part = 0;
  };
  /// A mapped list whose vertices lie in several segments: the buffer holds
  /// each run grouped by segment (ascending ids within a group, each vertex
  /// as its segment's), and these are the groups in buffer order; its
  /// positions are no longer ids()' (Renderer::draw_ranges refuses it).
  /// Empty when every vertex lies in segment 0.
  [[nodiscard]] std::span<const SegmentRun> segment_runs() const { return segment_runs_; }

 private:
  void write(std::size_t current);
  // vertices_ grouped by segment (v >> SHIFT) into grouped_, the groups
  // into segment_runs_.
  void group_by_segment(std::uint32_t shift);

  VertexMap* map_ = nullptr;
  std::vector<std::uint32_t> vertices_;  // map_'s of sorted_ (reused)
  std::uint32_t max_vertex_ = 0;
  std::vector<std::uint32_t> grouped_;   // vertices_ by segment (reused)
  std::vector<std::uint32_t> group_at_;  // per segment: the next position (reused)
  std::vector<SegmentRun> segment_runs_;

  std::array<gl::Buffer, 2> buffers_;
  std::size_t current_ = 0;
  std::size_t count_ = 0;
  std::size_t entering_ = 0;
  std::size_t leaving_ = 0;
  float fade_ = 1.0f;
  std::uint64_t points_ = 0;
  std::uint64_t generation_ = 0;          // of the list follow() uploaded last
  const Hierarchy* hierarchy_ = nullptr;  // identity only (see hierarchy())
  NodeId max_id_ = 0;
  std::vector<NodeId> sorted_;           // the uploaded order (reused)
  std::vector<NodeId> scratch_;          // radix sort ping-pong (reused)
  std::vector<NodeId> current_sorted_;   // an unsorted input, sorted (reused)
  std::vector<NodeId> previous_sorted_;  // the same for the previous list
  std::vector<NodeId> entering_ids_;     // merge output (reused)
  std::vector<NodeId> leaving_ids_;
};

/// Positions [first, first + count) of a CutBuffer's list (CutBuffer::ids()).
struct CutRange {
  std::uint32_t first = 0;
  std::uint32_t count = 0;
};

/// The place in a frame where GPU queries requested by a strategy run. The
/// renderer calls run() once per draw(), after the depth of the visible
/// surface is complete and before it is resolved to color, with the scene
/// framebuffer bound (depth test on, depth writes off, color writes off) and
/// the viewport set. An implementation issues its gl::Query objects here and
/// polls earlier ones with Query::try_result(); it must never wait for a
/// result, and must restore any other state it changes.
class QueryHook {
 public:
  virtual ~QueryHook() = default;
  virtual void run(const ViewSnapshot& view) = 0;
};

/// Called between the ranges of Renderer::draw_ranges(), after range `index`
/// (the last one too), in the depth pass (fast and fixed: the only pass; hq:
/// the visibility pass), under the same state as QueryHook::run: the depth of
/// the ranges drawn so far, depth test on, color and depth writes off. It may
/// bind its own program, vertex array and buffers (the renderer binds its own
/// again before the next range) and must restore anything else it changes.
class RangeHook {
 public:
  virtual ~RangeHook() = default;
  virtual void after_range(std::size_t index, const ViewSnapshot& view) = 0;
};

class SceneCutBuffer;

class Renderer {
 public:
  /// Uploads all nodes of `h` into the static vertex buffer and creates the
  /// render targets for a `size` framebuffer. `h` need not outlive the
  /// renderer. POOL_VERTICES > 0: a pool of that many vertices for `h`'s
  /// nodes instead (set_pool: a paged model), none uploaded.
  Renderer(const Hierarchy& h, glm::ivec2 size, std::uint32_t pool_vertices = 0);
  Renderer(const Renderer&) = delete;
  Renderer& operator=(const Renderer&) = delete;
  ~Renderer();

  /// Re-creates the render targets; a no-op for the current size.
  void resize(glm::ivec2 size);
  [[nodiscard]] glm::ivec2 size() const { return size_; }
  /// Vertices in the buffer: the models' nodes, or the extent of a pool's
  /// segments (the last vertex + 1).
  [[nodiscard]] std::uint32_t node_count() const { return node_count_; }

  /// Replaces the static vertex buffer with the nodes of `h` (another model:
  /// FeedbackStage::set_model). Lists of the previous hierarchy can no longer
  /// be drawn (draw() refuses them); RenderThreadFrame calls this when the
  /// list it is about to draw belongs to another hierarchy. Like the
  /// constructor, it copies what it needs: `h` need not outlive the call.
  /// Throws std::invalid_argument for an empty hierarchy (the old one stays).
  void set_hierarchy(const Hierarchy& h);
  /// The nodes of several hierarchies in the one vertex buffer (a scene's
  /// distinct models, each once however many objects use it): model i's
  /// nodes start at model_base(i). draw() draws cuts of models[0]
  /// (hierarchy()); draw_scene() any object of any model. set_hierarchy(h)
  /// is set_models({&h}). Throws std::invalid_argument for no model, an
  /// empty one, or more than 2^31 - 1 nodes in all.
  void set_models(std::span<const Hierarchy* const> models);
  /// A pool for nodes of H placed where a VertexMap says (GpuNodePool: a
  /// paged model's pages on the GPU): vertex buffers of VERTICES each at
  /// most, its segments, vertex v lying in segment v >> pool_shift() at
  /// v & ((1 << pool_shift()) - 1); the first is made now (VERTICES), the
  /// others by add_pool_segment. Lists of H are drawn through the map, a
  /// segment at a time (CutBuffer::segment_runs). Each vertex is undefined
  /// until written (write_vertices) but the first: zeros (alpha 0, drawn as
  /// nothing), the null vertex a map points the nodes it does not draw at.
  /// When it holds such a pool for H already, its first segment is kept
  /// and the others dropped. Throws std::invalid_argument for no vertex or
  /// more than 2^31 - 1.
  void set_pool(const Hierarchy& h, std::uint32_t vertices);
  /// The same pool for the nodes of several hierarchies (a scene's models
  /// drawn from their pages, GpuNodePool): model_base() is 0 for each,
  /// their vertices where the map puts them.
  void set_pool(std::span<const Hierarchy* const> models, std::uint32_t vertices);
  /// A segment's vertices rounded up to a power of two, as a shift: the
  /// segment of each vertex of each list drawn is a shift away, not a
  /// division.
  [[nodiscard]] std::uint32_t pool_shift() const { return pool_shift_; }
  /// One more segment of the pool, of VERTICES (at most the first's): a
  /// buffer of its own, so nothing up moves or is copied, and the cost of
  /// a new buffer is the segment's, not the pool's (llvmpipe fills a new
  /// buffer with zeros when it is made: 217-240 ms for 256 MiB).
  void add_pool_segment(std::uint32_t vertices);
  /// The pool's segments (1 for models held whole: their buffer).
  [[nodiscard]] std::size_t segments() const { return segments_.size(); }
  /// A pool's vertices [FIRST, FIRST + NODES.count), all in one segment,
  /// set to nodes NODES of the pool's hierarchy H, in its own colours or
  /// those set_node_coloring gave.
  void write_vertices(std::uint32_t first, const Hierarchy& h, NodeRange nodes);
  /// A pool's hierarchy H (a model drawn from its pages) coloured by RULE
  /// as its nodes are written (write_vertices), with no colour per node of
  /// the model; null: its own colours. The pool writes its nodes again
  /// when coloring_version() changes (GpuNodePool::prepare).
  void set_node_coloring(const Hierarchy& h, std::shared_ptr<const NodeColoring> rule);
  [[nodiscard]] std::uint64_t coloring_version() const { return coloring_version_; }
  [[nodiscard]] std::size_t model_count() const { return model_base_.size(); }
  [[nodiscard]] std::uint32_t model_base(std::size_t model) const { return model_base_[model]; }
  [[nodiscard]] std::uint32_t model_nodes(std::size_t model) const { return model_nodes_[model]; }
  /// Colours to draw H's nodes with instead of its own (arrays().color), one
  /// per node, alpha 0 to hide a node (coloring.hpp makes them). Kept for H
  /// (by identity and node count) until replaced: whenever set_models
  /// uploads H it uses them, and H held now is updated at once. Empty
  /// COLORS: H's own again. Throws std::invalid_argument for a wrong count.
  void set_node_colors(const Hierarchy& h, std::vector<glm::u8vec4> colors);
  /// The hierarchy set_models() was given at `model` (identity only).
  [[nodiscard]] const Hierarchy* model_identity(std::size_t model) const {
    return model_ids_[model];
  }
  /// The hierarchy whose nodes are in the vertex buffer: an identity to
  /// compare a list's FrontList::hierarchy with, never dereferenced. It
  /// cannot be mistaken for a newer hierarchy at the same address: a list's
  /// hierarchy is alive while that list is drawn, and its successor is
  /// created before the exchange that retires it.
  [[nodiscard]] const Hierarchy* hierarchy() const { return hierarchy_; }
  /// Vertex buffers uploaded so far (1 after construction).
  [[nodiscard]] std::uint64_t hierarchy_uploads() const { return hierarchy_uploads_; }
  /// The largest node id the last draw sent to the GPU (CutBuffer::max_id);
  /// always below node_count(): draw() checks it.
  [[nodiscard]] NodeId last_max_id() const { return last_max_id_; }

  /// Draws `cut` into the renderer's own color target. With `finish`, waits for
  /// the GPU so FrameStats::cpu_ms is the whole frame time. Throws
  /// std::logic_error, before any GL call, for a cut uploaded for another
  /// hierarchy than the vertex buffer's or naming a node past it: new ids
  /// are never drawn against old vertices (O(1): CutBuffer keeps its max).
  FrameStats draw(const CutBuffer& cut, const Camera& camera, const RenderSettings& settings,
                  bool finish = false);

  /// Draws a scene: every object's cut, each node moved by its object's
  /// transform, in one draw call per pass whatever the number of objects
  /// (glMultiDrawElementsIndirect, a command per object; scene_draw.hpp).
  /// Every mode. Throws std::logic_error, before any GL call, for a buffer
  /// uploaded for other models than set_models() holds.
  FrameStats draw_scene(const SceneCutBuffer& scene, const Camera& camera,
                        const RenderSettings& settings, bool finish = false);

  /// Draws only `ranges` of `cut`, in the given order (CHC: front to back),
  /// calling `hook` (if any) after each range. The image of ranges that
  /// partition the cut, in any order, equals draw()'s: the depth of every
  /// pass is a minimum (order-free), hq's additive attribute pass draws the
  /// ranges in buffer order (the one-call primitive order), and fast/fixed
  /// color can differ only where two splats have exactly the same depth at
  /// a pixel (the first drawn wins; tests/splat/render_ranges_gl_test.cpp). A range
  /// past the list is clipped. A fading cut fades each range's entering part
  /// and draws the leaving run after the last range. FrameStats::splats
  /// counts the splats of the ranges (FrameStats::points is 0). Throws
  /// std::logic_error, before any GL call, for a list in several segments
  /// of a pool (CutBuffer::segment_runs), besides draw()'s checks.
  FrameStats draw_ranges(const CutBuffer& cut, std::span<const CutRange> ranges,
                         const Camera& camera, const RenderSettings& settings,
                         RangeHook* hook = nullptr, bool finish = false);

  /// In-frame drawing for a traversal that decides what to draw while it
  /// draws (CHC: splat/occlusion_device_gl.hpp). begin_frame_ranges clears
  /// the frame and makes `elements` (node ids of this renderer's hierarchy,
  /// the caller's buffer, none above `max_id`: checked like draw()'s) the
  /// element buffer; draw_frame_range draws positions [first, first + count)
  /// of it, one call; end_frame_ranges closes the frame (read_pixels and
  /// present show it). Between draws the scene framebuffer stays bound and
  /// the caller may draw into it with its own program, vertex array and
  /// color/depth masks (draw_frame_range sets the renderer's again). One-pass
  /// modes (fast, fixed); hq, whose later passes need the whole list first,
  /// throws std::invalid_argument; a pool (its vertices are not the node
  /// ids) std::logic_error.
  void begin_frame_ranges(const gl::Buffer& elements, NodeId max_id, const Camera& camera,
                          const RenderSettings& settings);
  void draw_frame_range(std::uint32_t first, std::uint32_t count);
  /// FrameStats::splats counts the splats of the frame's ranges.
  FrameStats end_frame_ranges(bool finish = false);
  /// The frame's matrices while a frame of ranges is open.
  [[nodiscard]] const ViewSnapshot& frame_view() const { return in_frame_view_; }

  /// Copies the last frame to the bound draw framebuffer 0 (a window), scaled
  /// to `window_size`.
  void present(glm::ivec2 window_size) const;

  /// The last frame as tightly packed RGBA8, top row first (image order).
  [[nodiscard]] std::vector<std::uint8_t> read_pixels() const;

  /// The world position of what the last frame drew at `pixel` (image
  /// order: x right, y down from the top row), seen by `camera` (the frame's
  /// camera): its depth unprojected in double relative to the eye; nullopt
  /// for the background or a pixel outside. In hq mode the depth is the
  /// visibility pass's, up to depth_offset radii behind the surface. Reads
  /// one pixel back: it waits for the frame (issue 30: picking, measuring).
  [[nodiscard]] std::optional<glm::vec3> pick(glm::ivec2 pixel, const Camera& camera) const;

  /// The hook runs inside every draw() until reset to null. Not owned.
  void set_query_hook(QueryHook* hook) { query_hook_ = hook; }

 private:
  // A run of the element buffer and how it fades (0 none, 1 in, 2 out).
  struct Run {
    std::uint32_t first = 0;
    std::uint32_t count = 0;  // elements; commands when indirect
    int fade = 0;
    bool indirect = false;      // a scene's commands (indirect_)
    std::uint32_t segment = 0;  // of a pool: the vertex buffer it reads
  };
  static constexpr GLuint kObjectBinding = 3;        // the per-object records (divisor 1)
  static constexpr GLuint kSplatRadiusBinding = 4;   // HierarchyArrays::splat_radius
  static constexpr GLuint kSplatRadiusLocation = 7;  // after the object rows' 3..6
  // Uniform locations of one program, looked up once after linking (-1: the
  // linker dropped it; glProgramUniform ignores -1).
  struct Uniforms {
    GLint view = -1, proj = -1, eye = -1, radius_scale = -1, cull = -1, min_radius_px = -1,
          viewport_h = -1, light_dir = -1, light = -1, depth_offset = -1, point_size = -1,
          inv_view_proj = -1, fade_mode = -1, fade = -1, clip = -1, clip_min = -1, clip_max = -1;
  };
  static Uniforms lookup_uniforms(const gl::Program& p);
  // The per-frame uniforms every splat program reads.
  void set_common_uniforms(const gl::Program& program, const Uniforms& u, const ViewSnapshot& frame,
                           const RenderSettings& settings, float fade) const;

  void create_targets();
  // The vertex array's four attributes and their bindings (once).
  void set_vertex_format();
  // A vertex buffer of N vertices (uninitialized), appended to segments_.
  void add_segment(std::uint32_t n);
  // Segment S's buffer bound to the vertex array.
  void bind_segment(std::uint32_t s);
  // A pool's vertex 0: zeros.
  void write_null_vertex();
  void check_cut(const CutBuffer& cut);
  void check_scene(const SceneCutBuffer& scene) const;
  void bind_objects(const gl::Buffer& records);
  // `cut` or `scene` (the other null).
  FrameStats render(const CutBuffer* cut, const SceneCutBuffer* scene,
                    std::span<const CutRange> ranges, bool whole, const Camera& camera,
                    const RenderSettings& settings, RangeHook* hook, bool finish);
  // Splits `ranges` at the cut's stable/entering boundary (fading) and adds
  // the leaving run; `sorted`: in buffer order (hq's additive pass).
  void plan_runs(const CutBuffer& cut, std::span<const CutRange> ranges, bool sorted);
  void draw_runs(GLuint elements, const gl::Program& program, const Uniforms& u, RangeHook* hook,
                 const ViewSnapshot& frame, GLuint fbo, bool depth_writes);
  // render()'s passes (renderer_draw.cpp): those of the mode, high quality's
  // three, and the query hook after a pass.
  void draw_passes(GLuint elements, const ViewSnapshot& frame, const RenderSettings& settings,
                   float fade_weight, RangeHook* hook, const CutBuffer* cut,
                   std::span<const CutRange> ranges, bool whole);
  void draw_high_quality(GLuint elements, const ViewSnapshot& frame, const RenderSettings& settings,
                         float fade_weight, RangeHook* hook, const CutBuffer* cut,
                         std::span<const CutRange> ranges, bool whole);
  void run_query_hook(GLuint fbo, const ViewSnapshot& frame);
  void draw_eye_dome(const ViewSnapshot& frame, const RenderSettings& settings);

  glm::ivec2 size_{0};
  std::uint32_t node_count_ = 0;
  const Hierarchy* hierarchy_ = nullptr;  // identity only (see hierarchy())
  std::uint64_t hierarchy_uploads_ = 0;
  struct NodeColors {
    const Hierarchy* model;
    std::uint32_t nodes;
    std::vector<glm::u8vec4> colors;
  };
  std::vector<NodeColors> node_colors_;  // set_node_colors
  // set_node_coloring: a pool's hierarchies and their rules.
  std::vector<std::pair<const Hierarchy*, std::shared_ptr<const NodeColoring>>> colorings_;
  [[nodiscard]] const NodeColoring* coloring_of(const Hierarchy& h) const;
  std::uint64_t coloring_version_ = 0;       // set_node_coloring calls
  std::vector<glm::u8vec4> colors_scratch_;  // write_vertices
  [[nodiscard]] std::span<const glm::u8vec4> colors_of(const Hierarchy& h) const;
  NodeId last_max_id_ = 0;
  bool pooled_ = false;  // set_pool
  // The vertex buffers: one holding the models' nodes in order, or a
  // pool's segments; each center_radius | normal_cone | color |
  // splat_radius, one region each.
  std::vector<gl::Buffer> segments_;
  std::vector<std::uint32_t> segment_vertices_;  // of each
  std::uint32_t pool_shift_ = 0;                 // pool_shift()
  std::uint32_t bound_segment_ = 0;              // to vao_
  std::vector<std::uint32_t> model_base_;        // first vertex of each model
  std::vector<std::uint32_t> model_nodes_;       // its node count
  std::vector<const Hierarchy*> model_ids_;      // identity only
  gl::Buffer identity_object_;                   // the object record of a single model
  GLuint indirect_ = 0;                          // the scene's commands while it is drawn
  std::size_t draw_calls_ = 0;                   // of the frame being drawn
  gl::VertexArray vao_;
  gl::VertexArray empty_vao_;  // for the full-screen pass (core profile needs a VAO)
  gl::Program fast_;
  gl::Program hq_visibility_;
  gl::Program hq_attributes_;
  gl::Program hq_normalize_;
  gl::Program fixed_;
  gl::Program object_id_;
  gl::Program eye_dome_;
  GLint eye_dome_near_ = -1, eye_dome_far_ = -1, eye_dome_perspective_ = -1,
        eye_dome_strength_ = -1, eye_dome_radius_ = -1;
  Uniforms fast_u_, hq_visibility_u_, hq_attributes_u_, hq_normalize_u_, fixed_u_, object_id_u_;
  std::vector<Run> runs_;              // reused by every draw
  std::vector<std::size_t> run_hook_;  // per run: the range it ends (SIZE_MAX: none)
  std::vector<CutRange> sorted_ranges_;
  gl::Texture color_;               // RGBA8, the frame
  gl::Texture depth_;               // DEPTH24, shared by every pass
  gl::Texture accum_color_;         // RGBA16F: sum w*rgb (linear), sum w
  gl::Texture accum_normal_;        // RGBA16F: sum w*n
  gl::Framebuffer scene_fbo_;       // color_ + depth_
  gl::Framebuffer visibility_fbo_;  // depth_ only
  gl::Framebuffer accum_fbo_;       // accum_color_ + accum_normal_ + depth_ (test only)
  gl::Framebuffer color_fbo_;       // color_ only: eye-dome lighting reads depth_ as a texture
  QueryHook* query_hook_ = nullptr;
  // The open frame of begin_frame_ranges (null program: none).
  const gl::Program* in_frame_program_ = nullptr;
  ViewSnapshot in_frame_view_;
  std::chrono::steady_clock::time_point in_frame_start_;
  std::size_t in_frame_splats_ = 0;
};

}  // namespace treecut::splat
