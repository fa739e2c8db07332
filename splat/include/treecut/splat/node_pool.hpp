// A paged model's nodes on the GPU (issue 45, item 1): a pool of vertices
// within a memory budget that holds the pages the drawn list needs, copied
// up within a per-frame byte budget and given back by least recent use.
// The renderer's vertex buffers are the pool (Renderer::set_pool): segments
// of a fixed size added as pages need them, each its own buffer and draw
// calls, so the pool grows without moving what is up and a new segment
// costs its own size, not the pool's. The list's ids reach their vertices
// through this map (CutBuffer::set_vertex_map).
//
// The unit is a page of the cache (at most 8,192 nodes), or its levels down
// to the deepest one the list reaches (a cut through a page needs no more:
// most of a page's nodes lie in its deepest level), placed in blocks of
// kBlock vertices that need not be adjacent: a page's k-th node sits in its
// block k / kBlock, and a page that the list needs more of grows. A node of the list whose page is
// not on the GPU yet is drawn as its nearest ancestor that is (the root's page never leaves), as a
// strategy's node whose children are not resident stays a leaf: never a hole, never a wait. What
// the pool keeps is proportional to the budget (a slot a resident node, in reserved address space
// indexed by id; a byte a page), not to the model. Potree's viewer streams nodes to the GPU the
// same way, a few per frame, the rest drawn coarser meanwhile.
//
// Render thread only (every call makes GL calls through the renderer).
#pragma once

#include <cstdint>
#include <memory>
#include <span>
#include <unordered_map>
#include <unordered_set>
#include <utility>
#include <vector>

#include "treecut/paged_hierarchy.hpp"
#include "treecut/reserved_array.hpp"
#include "treecut/splat/renderer.hpp"

namespace treecut::splat {

struct GpuPoolOptions {
  /// The pool's vertex memory in bytes (kVertexBytes a node); 0: room for
  /// every node the RAM budget holds (PagingOptions::memory_bytes), and a
  /// quarter more for the ends of blocks that pages leave empty.
  std::uint64_t memory_bytes = 0;
  /// Bytes copied to the GPU per frame at most (a page at least).
  std::uint64_t upload_bytes = std::uint64_t{8} << 20;
  /// A segment's bytes (a block at least; the budget at most): the pool is
  /// one segment when the model opens and a segment more whenever pages
  /// need room, up to memory_bytes. A driver backs a buffer when it is
  /// made: llvmpipe took 1 GiB of RAM and a second for a pool of 1 GiB
  /// before the first frame, 24-37 ms for 32 MiB, 217-240 for 256 (a GPU
  /// does not touch it); a segment more is one draw call more a run.
  std::uint64_t segment_bytes = std::uint64_t{16} << 20;
};

/// One model the pool holds: a paged one's pages come and go; one held
/// whole (PAGED null: a scene's model that is no cache) is one page of all
/// its nodes, up as long as the pool lives.
struct PoolModel {
  const Hierarchy* hierarchy = nullptr;
  const PagedHierarchy* paged = nullptr;
};

/// What the pool holds and did (this frame: the last prepare()).
struct GpuPoolStats {
  std::uint64_t capacity_bytes = 0;   ///< the budget's vertices
  std::uint64_t allocated_bytes = 0;  ///< the segments' now (they are added as pages need)
  std::uint64_t segments = 0;         ///< the pool's now
  std::uint64_t resident_bytes = 0;   ///< of the blocks pages use
  std::uint64_t resident_pages = 0;
  std::uint64_t uploaded_bytes = 0;          ///< this frame
  std::uint64_t uploads = 0, evictions = 0;  ///< pages, since the pool was made
  std::uint64_t stand_ins = 0;               ///< list nodes drawn as an ancestor this frame
  std::uint64_t waiting_pages = 0;           ///< pages the list needs that are not up yet
};

class GpuNodePool final : public VertexMap {
 public:
  static constexpr std::uint32_t kBlock = 1024;
  /// Vertex 0: zeros, drawn as nothing (what the map gives a node it does
  /// not draw). A segment holds vertex 0 (the null vertex in the first,
  /// unused in the others) and blocks: block b's vertices start at vertex
  /// 1 + (b % B) * kBlock of segment b / B, B blocks a segment.
  static constexpr std::uint32_t kNullVertex = 0;
  /// A vertex: center and bound, normal cone, colour, drawn radius.
  static constexpr std::uint64_t kVertexBytes = 32;

  /// The budget OPTIONS give for MODELS, in bytes (memory_bytes, or its
  /// default: the paged models' default and the whole models' nodes).
  static std::uint64_t budget(std::span<const PoolModel> models, const GpuPoolOptions& options);
  static std::uint64_t budget(const PagedHierarchy& paged, const GpuPoolOptions& options);
  /// The nodes a pool of BYTES holds whole pages of: its vertices less a
  /// fifth for the ends of blocks that pages leave empty (the default
  /// budget's rule, inverted; PagingOptions::node_limit).
  static std::uint64_t nodes_within(std::uint64_t bytes) { return bytes / kVertexBytes / 5 * 4; }
  /// The blocks of a pool of that budget. Throws InputError "--gpu-memory:
  /// REASON" when it cannot hold every model's first page and the largest
  /// page beside them.
  static std::uint32_t blocks(std::span<const PoolModel> models, const GpuPoolOptions& options);
  static std::uint32_t blocks(const PagedHierarchy& paged, const GpuPoolOptions& options);
  /// The vertices of a segment (Renderer::set_pool): segment_bytes'
  /// blocks (one at least, the budget's at most) and vertex 0. Throws as
  /// blocks() does.
  static std::uint32_t segment_vertices(std::span<const PoolModel> models,
                                        const GpuPoolOptions& options);
  static std::uint32_t segment_vertices(const PagedHierarchy& paged, const GpuPoolOptions& options);

  /// Makes RENDERER's vertex buffer the pool of MODELS' hierarchies (a
  /// scene's, in its order: lists of model m are mapped by map_list(m, ...))
  /// and puts each one's first page in it. All must outlive the pool.
  GpuNodePool(Renderer& renderer, std::span<const PoolModel> models, const GpuPoolOptions& options);
  /// The pool of one paged model.
  GpuNodePool(Renderer& renderer, const PagedHierarchy& paged, const GpuPoolOptions& options);
  GpuNodePool(const GpuNodePool&) = delete;
  GpuNodePool& operator=(const GpuNodePool&) = delete;
  ~GpuNodePool() override;

  /// Each frame, before the frame's list is uploaded (CutBuffer::follow).
  void begin_frame();
  /// Each frame, after it: copies up the pages the list of CUT needs
  /// (coarsest first) within the frame's budget, giving back pages no
  /// node of this frame's lists uses, and maps CUT again if any arrived.
  /// CUT's nodes must be resident (a list the paged model's evict() knows).
  void prepare(CutBuffer& cut);
  /// The same for a scene's lists (SceneCutBuffer::set_vertex_map; its
  /// objects set for the renderer this pool made).
  void prepare(SceneCutBuffer& scene);

  std::uint32_t map(std::span<const NodeId> ids, std::size_t current,
                    std::vector<std::uint32_t>& out) override;
  void begin_lists() override;
  std::uint32_t map_list(std::uint32_t model, std::span<const NodeId> ids,
                         std::vector<std::uint32_t>& out) override;
  [[nodiscard]] std::uint32_t segment_shift() const override { return shift_; }

  [[nodiscard]] GpuPoolStats stats() const;
  /// The bytes of the memory pages the system holds under the pool's slots
  /// (4 B a node of its pages up; mincore): O(the models' nodes), for a
  /// report, not a frame.
  [[nodiscard]] std::uint64_t held_slot_bytes() const;
  /// The first model's hierarchy (the one model's).
  [[nodiscard]] const Hierarchy& hierarchy() const { return *models_.front().hierarchy; }

 private:
  // A model of the pool and where its pages start among all models' pages
  // (a page's number in up_, wanted_ and lru_ is that start plus its own).
  struct Held {
    const Hierarchy* hierarchy = nullptr;
    const PagedHierarchy* paged = nullptr;
    std::uint32_t first_page = 0;
    std::unique_ptr<ReservedArray<std::uint32_t>>
        slot;  // by node id: its vertex + 1, 0 when not up
  };
  // The model of page P (a number among all models' pages), and its own number there.
  [[nodiscard]] std::pair<std::uint32_t, std::uint32_t> model_page(std::uint32_t p) const;
  // The lists' nodes of model M to vertices (CURRENT: see map()).
  std::uint32_t map_into(std::uint32_t m, std::span<const NodeId> ids, std::size_t current,
                         std::vector<std::uint32_t>& out);
  // What prepare() does for lists that REFRESH maps again.
  template <class Refresh>
  void prepare_lists(Refresh&& refresh);
  // A page on the GPU: its first NODES nodes (in the page's order: its
  // levels from the top), in BLOCKS.
  struct Up {
    std::vector<std::uint32_t> blocks;
    std::uint32_t nodes = 0;
  };
  // Page PAGE's nodes [FROM, TO) in its order, as pieces of runs: FN(ids, k).
  template <class Fn>
  void for_each_run(std::uint32_t page, std::uint32_t from, std::uint32_t to, Fn&& fn);
  // Page PAGE's first PREFIX nodes up (the blocks they need are free).
  void upload(std::uint32_t page, std::uint32_t prefix);
  // Page PAGE's nodes [FROM, TO) in its order written to U's blocks.
  void write(std::uint32_t page, std::uint32_t from, std::uint32_t to, const Up& u);
  void give_back(std::uint32_t page);
  // Frees blocks until BLOCKS are free: segments added within the budget
  // (in one request a frame), else pages no list of this frame uses given
  // back, least recently used first; false when they cannot be (yet).
  bool make_room(std::size_t blocks);
  // Segments added until BLOCKS blocks are free or the budget is reached.
  void grow(std::size_t blocks);
  // The last frame a list used any of U's blocks.
  [[nodiscard]] std::uint64_t last_used(const Up& u) const;
  // Block B's first vertex, and the block of vertex V.
  [[nodiscard]] std::uint32_t first_vertex(std::uint32_t b) const {
    return (b / segment_blocks_ << shift_) + 1 + b % segment_blocks_ * kBlock;
  }
  [[nodiscard]] std::uint32_t block_of(std::uint32_t v) const {
    return (v >> shift_) * segment_blocks_ + ((v & ((1u << shift_) - 1)) - 1) / kBlock;
  }

  Renderer* renderer_;
  std::vector<Held> models_;
  GpuPoolOptions options_;
  std::uint32_t blocks_ = 0;                       // in the segments now (they grow to max_blocks_)
  std::uint32_t max_blocks_ = 0;                   // within the budget
  std::uint32_t segment_blocks_ = 0;               // in a segment (B)
  std::uint32_t shift_ = 0;                        // Renderer::pool_shift
  std::uint64_t grown_frame_ = ~std::uint64_t{0};  // the frame segments were last added in
  std::vector<std::uint32_t> free_;                // blocks
  std::vector<std::uint64_t> block_used_;          // by block: the frame a list last used it
  std::unordered_map<std::uint32_t, Up> up_;       // the pages up
  std::vector<std::uint32_t> wanted_mark_;         // by page: its place in wanted_ + 1 (0: none)
  std::vector<NodePlace> wanted_;  // pages the list needs, and how far, coarsest first
  std::vector<NodeRange> ranges_;  // (reused)
  std::unordered_set<std::uint32_t> stand_ins_;               // vertices standing in (map)
  std::vector<std::pair<std::uint64_t, std::uint32_t>> lru_;  // (last used, page): make_room
  std::size_t lru_next_ = 0;                                  // the next in lru_ to give back
  std::uint64_t lru_frame_ = ~std::uint64_t{0};               // the frame lru_ was gathered in
  std::uint64_t frame_ = 0;
  std::uint64_t coloring_version_ = 0;  // Renderer::coloring_version() the pages up are in
  bool mapped_ = false;                 // this frame
  GpuPoolStats stats_;
};

}  // namespace treecut::splat
