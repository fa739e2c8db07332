// GpuNodePool: a paged model's pages on the GPU (node_pool.hpp has the
// promises). Pages go up in blocks of vertices the list's nodes are mapped
// to; a node whose page is not up yet is drawn as its nearest ancestor
// that is, and pages no list of the frame uses are given back, least
// recently used first.
#include "treecut/splat/node_pool.hpp"

#include <algorithm>
#include <array>
#include <string>
#include <utility>

#include "treecut/error.hpp"
#include "treecut/file_io.hpp"
#include "treecut/splat/scene_draw.hpp"

namespace treecut::splat {

namespace {

std::uint32_t blocks_for(std::uint64_t nodes) {
  return static_cast<std::uint32_t>((nodes + GpuNodePool::kBlock - 1) / GpuNodePool::kBlock);
}

// A model's pages: a paged one's, or one page of all its nodes.
std::uint32_t pages_of(const PoolModel& m) {
  return m.paged ? m.paged->pages() : 1;
}
std::uint32_t page_nodes(const PoolModel& m, std::uint32_t p) {
  return m.paged ? m.paged->page_nodes(p) : m.hierarchy->node_count();
}

// Every model's first page and the largest page beside them: the least pool.
std::uint64_t least_blocks(std::span<const PoolModel> models) {
  std::uint64_t first = 0;
  std::uint32_t largest = 0;
  for (const PoolModel& m : models) {
    first += blocks_for(page_nodes(m, 0));
    for (std::uint32_t p = 1; p < pages_of(m); ++p) largest = std::max(largest, page_nodes(m, p));
  }
  return first + blocks_for(largest);
}

}  // namespace

std::uint64_t GpuNodePool::budget(std::span<const PoolModel> models,
                                  const GpuPoolOptions& options) {
  if (options.memory_bytes != 0) return options.memory_bytes;
  // Room for every node the RAM budgets hold, and a quarter more for the
  // blocks' last vertices that pages leave unused (nodes_within inverted);
  // a model held whole, all of its nodes.
  std::uint64_t bytes = 0;
  for (const PoolModel& m : models) {
    bytes += m.paged ? m.paged->memory_budget() / m.paged->bytes_per_node() * kVertexBytes / 4 * 5
                     : std::uint64_t{blocks_for(m.hierarchy->node_count())} * kBlock * kVertexBytes;
  }
  return bytes;
}

std::uint64_t GpuNodePool::budget(const PagedHierarchy& paged, const GpuPoolOptions& options) {
  const PoolModel one{&paged.hierarchy(), &paged};
  return budget(std::span<const PoolModel>(&one, 1), options);
}

std::uint32_t GpuNodePool::blocks(std::span<const PoolModel> models,
                                  const GpuPoolOptions& options) {
  const std::uint64_t bytes = budget(models, options);
  const std::uint64_t least = least_blocks(models) * kBlock * kVertexBytes;
  if (bytes < least)
    throw InputError("--gpu-memory: " + mib_text(bytes) + " is below the " + mib_text(least) +
                     (models.size() > 1 ? " the models' first pages" : " the model's first page") +
                     " and the largest page beside them take on the GPU");
  // The segments' vertices, a block's and one a segment (its vertex 0) at
  // most, address 2^31 - 1 (a GLint).
  return static_cast<std::uint32_t>(
      std::min<std::uint64_t>(bytes / (kBlock * kVertexBytes), 0x7fffffff / (kBlock + 1)));
}

std::uint32_t GpuNodePool::blocks(const PagedHierarchy& paged, const GpuPoolOptions& options) {
  const PoolModel one{&paged.hierarchy(), &paged};
  return blocks(std::span<const PoolModel>(&one, 1), options);
}

std::uint32_t GpuNodePool::segment_vertices(std::span<const PoolModel> models,
                                            const GpuPoolOptions& options) {
  const std::uint64_t most = blocks(models, options);
  const std::uint64_t wanted = options.segment_bytes / (kBlock * kVertexBytes);
  return static_cast<std::uint32_t>(1 + std::clamp<std::uint64_t>(wanted, 1, most) * kBlock);
}

std::uint32_t GpuNodePool::segment_vertices(const PagedHierarchy& paged,
                                            const GpuPoolOptions& options) {
  const PoolModel one{&paged.hierarchy(), &paged};
  return segment_vertices(std::span<const PoolModel>(&one, 1), options);
}

GpuNodePool::GpuNodePool(Renderer& renderer, const PagedHierarchy& paged,
                         const GpuPoolOptions& options)
    : GpuNodePool(renderer,
                  std::span<const PoolModel>(std::array{PoolModel{&paged.hierarchy(), &paged}}),
                  options) {}

GpuNodePool::GpuNodePool(Renderer& renderer, std::span<const PoolModel> models,
                         const GpuPoolOptions& options)
    : renderer_(&renderer), options_(options), max_blocks_(blocks(models, options)) {
  std::vector<const Hierarchy*> hierarchies;
  std::uint32_t pages = 0;
  for (const PoolModel& m : models) {
    Held held;
    held.hierarchy = m.hierarchy;
    held.paged = m.paged;
    held.first_page = pages;
    // What it keeps is a slot a resident node, in reserved address space.
    // counted: a page's runs go up in pieces and leave whole, and the memory
    // pages their ends share with other pages' runs go back with the last
    // (as the node arrays', PagedHierarchy::held_bytes).
    held.slot = std::make_unique<ReservedArray<std::uint32_t>>(m.hierarchy->node_count(),
                                                               PageSharing::counted);
    pages += pages_of(m);
    models_.push_back(std::move(held));
    hierarchies.push_back(m.hierarchy);
  }
  const std::uint32_t vertices = segment_vertices(models, options);
  segment_blocks_ = (vertices - 1) / kBlock;
  renderer.set_pool(hierarchies, vertices);
  shift_ = renderer.pool_shift();
  // The segments' vertices address 2^31 - 1, the last one's whatever it holds.
  const std::uint64_t segments = ((std::uint64_t{0x7fffffff} - vertices) >> shift_) + 1;
  max_blocks_ =
      static_cast<std::uint32_t>(std::min<std::uint64_t>(max_blocks_, segments * segment_blocks_));
  blocks_ = segment_blocks_;
  for (std::uint32_t b = blocks_; b-- > 0;) free_.push_back(b);  // low blocks first
  block_used_.resize(blocks_, 0);
  wanted_mark_.assign(pages, 0);
  stats_.capacity_bytes = std::uint64_t{max_blocks_} * kBlock * kVertexBytes;
  // Each model's first page, whole: every stand-in's last resort, never
  // given back (a model held whole: all of it).
  std::size_t first = 0;
  for (const PoolModel& m : models) first += blocks_for(page_nodes(m, 0));
  grow(first);
  coloring_version_ = renderer.coloring_version();
  for (const Held& m : models_)
    upload(m.first_page, page_nodes(PoolModel{m.hierarchy, m.paged}, 0));
}

std::pair<std::uint32_t, std::uint32_t> GpuNodePool::model_page(std::uint32_t p) const {
  const auto it = std::upper_bound(models_.begin(), models_.end(), p,
                                   [](std::uint32_t q, const Held& m) { return q < m.first_page; });
  const auto m = static_cast<std::uint32_t>(std::prev(it) - models_.begin());
  return {m, p - models_[m].first_page};
}

void GpuNodePool::grow(std::size_t blocks) {
  while (free_.size() < blocks && blocks_ < max_blocks_) {
    // The last segment holds what the budget has left.
    const std::uint32_t n = std::min(segment_blocks_, max_blocks_ - blocks_);
    renderer_->add_pool_segment(1 + n * kBlock);
    for (std::uint32_t b = blocks_ + n; b-- > blocks_;) free_.push_back(b);
    blocks_ += n;
    block_used_.resize(blocks_, 0);
  }
}

GpuNodePool::~GpuNodePool() = default;

void GpuNodePool::begin_frame() {
  ++frame_;
  mapped_ = false;
}

std::uint32_t GpuNodePool::map(std::span<const NodeId> ids, std::size_t current,
                               std::vector<std::uint32_t>& out) {
  begin_lists();
  return map_into(0, ids, current, out);
}

void GpuNodePool::begin_lists() {
  for (const NodePlace& w : wanted_) wanted_mark_[w.page] = 0;
  wanted_.clear();
  stats_.stand_ins = 0;
  mapped_ = true;
  stats_.waiting_pages = 0;
}

std::uint32_t GpuNodePool::map_list(std::uint32_t model, std::span<const NodeId> ids,
                                    std::vector<std::uint32_t>& out) {
  return map_into(model, ids, ids.size(), out);
}

std::uint32_t GpuNodePool::map_into(std::uint32_t m, std::span<const NodeId> ids,
                                    std::size_t current, std::vector<std::uint32_t>& out) {
  const Held& held = models_[m];
  const ReservedArray<std::uint32_t>& slot = *held.slot;
  const std::span<const NodeId> parent = held.hierarchy->arrays().parent;
  out.resize(ids.size());
  std::uint32_t most = 0;
  NodeId last_parent = kNoNode;  // siblings share their stand-in
  stand_ins_.clear();
  for (std::size_t i = 0; i < ids.size(); ++i) {
    const NodeId id = ids[i];
    std::uint32_t v = slot[id];
    if (v == 0 && i >= current) {
      // A fading exchange's leaving node whose page left the GPU: nothing
      // (its ancestors are no longer known to be resident).
      out[i] = kNullVertex;
      continue;
    }
    if (v == 0) {
      ++stats_.stand_ins;
      // Its page, up to its level: a cut through a page needs its levels
      // down to the cut's, not the whole page (most of a page's nodes lie
      // in its deepest level). Only a paged model has a page not up.
      NodePlace place = held.paged->place_of(id);
      place.page += held.first_page;
      if (std::uint32_t& mark = wanted_mark_[place.page]; mark == 0) {
        wanted_.push_back(place);
        mark = static_cast<std::uint32_t>(wanted_.size());
      } else {
        wanted_[mark - 1].prefix = std::max(wanted_[mark - 1].prefix, place.prefix);
      }
      // The nearest ancestor that is up stands in, once a list: the other
      // nodes below it draw nothing (an ancestor's disc covers them all;
      // drawn once per descendant it was most of a frame's fill). The
      // list's nodes and their ancestors are resident (the stage's evict()
      // knows the list): their parents can be read.
      if (parent[id] == last_parent) {
        out[i] = kNullVertex;
        continue;
      }
      NodeId up = last_parent = parent[id];
      while (slot[up] == 0) up = parent[up];  // the first page is always up
      v = slot[up];
      if (!stand_ins_.insert(v).second) {
        out[i] = kNullVertex;
        continue;
      }
    }
    out[i] = v - 1;
    block_used_[block_of(v - 1)] = frame_;
    most = std::max(most, v - 1);
  }
  stats_.waiting_pages = wanted_.size();
  return most;
}

void GpuNodePool::prepare(CutBuffer& cut) {
  stats_.uploaded_bytes = 0;
  if (cut.hierarchy() != models_.front().hierarchy) return;
  prepare_lists([&cut] { cut.refresh(); });
}

void GpuNodePool::prepare(SceneCutBuffer& scene) {
  stats_.uploaded_bytes = 0;
  const std::span<const Hierarchy* const> set = scene.models();
  if (set.size() != models_.size()) return;
  for (std::size_t m = 0; m < set.size(); ++m)
    if (set[m] != models_[m].hierarchy) return;
  prepare_lists([&scene] { scene.refresh(); });
}

template <class Refresh>
void GpuNodePool::prepare_lists(Refresh&& refresh) {
  if (renderer_->coloring_version() != coloring_version_) {
    // Coloured anew (Renderer::set_node_coloring): the pages up written
    // again in the new colours, whatever the frame's budget (a user's
    // choice, once; at most the pool).
    coloring_version_ = renderer_->coloring_version();
    for (const auto& [page, u] : up_) write(page, 0, u.nodes, u);
  }
  // The same list as last frame, still waiting for pages: mapped again, so
  // that its blocks count as used this frame.
  if (!mapped_ && !wanted_.empty()) refresh();
  if (wanted_.empty()) return;
  const std::vector<NodePlace> pages = wanted_;  // refresh() remakes wanted_
  std::size_t uploaded = 0;
  for (const NodePlace& w : pages) {
    const auto it = up_.find(w.page);
    const std::uint32_t have = it == up_.end() ? 0 : it->second.nodes;
    const std::uint64_t bytes = std::uint64_t{w.prefix - have} * kVertexBytes;
    if (uploaded > 0 && stats_.uploaded_bytes + bytes > options_.upload_bytes) break;
    // A page partly up that the list needs more of keeps what it has.
    if (it != up_.end())
      for (const std::uint32_t b : it->second.blocks) block_used_[b] = frame_;
    const std::size_t blocks = it == up_.end() ? 0 : it->second.blocks.size();
    if (!make_room(blocks_for(w.prefix) - blocks)) break;
    upload(w.page, w.prefix);
    ++uploaded;
    stats_.uploaded_bytes += bytes;
  }
  if (uploaded > 0) refresh();
}

template <class Fn>
void GpuNodePool::for_each_run(std::uint32_t page, std::uint32_t from, std::uint32_t to, Fn&& fn) {
  const auto [m, own] = model_page(page);
  const Held& held = models_[m];
  if (held.paged)
    held.paged->page_ranges(own, ranges_);
  else
    ranges_.assign(1, NodeRange{0, held.hierarchy->node_count()});
  std::uint32_t k = 0;
  for (const NodeRange& r : ranges_) {
    const std::uint32_t lo = std::max(k, from), hi = std::min(k + r.count, to);
    if (lo < hi) fn(NodeRange{r.first + (lo - k), hi - lo}, lo);
    k += r.count;
  }
}

void GpuNodePool::upload(std::uint32_t page, std::uint32_t prefix) {
  Up& u = up_[page];
  // The slots of the nodes going up now, in use from here to give_back().
  const ReservedArray<std::uint32_t>& slot = *models_[model_page(page).first].slot;
  for_each_run(page, u.nodes, prefix,
               [&](NodeRange r, std::uint32_t) { slot.use(r.first, r.count); });
  while (u.blocks.size() < blocks_for(prefix)) {
    const std::uint32_t b = free_.back();
    free_.pop_back();
    block_used_[b] = frame_;
    u.blocks.push_back(b);
  }
  write(page, u.nodes, prefix, u);
  if (u.nodes == 0) ++stats_.uploads;
  u.nodes = std::max(u.nodes, prefix);
}

void GpuNodePool::write(std::uint32_t page, std::uint32_t from, std::uint32_t to, const Up& u) {
  // The page's k-th node goes to vertex k % kBlock of its block k / kBlock:
  // one copy a piece of a run within a block.
  const Held& held = models_[model_page(page).first];
  ReservedArray<std::uint32_t>& slot = *held.slot;
  for_each_run(page, from, to, [&](NodeRange r, std::uint32_t k) {
    for (std::uint32_t done = 0; done < r.count;) {
      const std::uint32_t at = (k + done) % kBlock;
      const std::uint32_t len = std::min(r.count - done, kBlock - at);
      const std::uint32_t vertex = first_vertex(u.blocks[(k + done) / kBlock]) + at;
      renderer_->write_vertices(vertex, *held.hierarchy, {r.first + done, len});
      for (std::uint32_t j = 0; j < len; ++j) slot[r.first + done + j] = vertex + j + 1;
      done += len;
    }
  });
}

void GpuNodePool::give_back(std::uint32_t page) {
  const auto it = up_.find(page);
  ReservedArray<std::uint32_t>& slot = *models_[model_page(page).first].slot;
  for_each_run(page, 0, it->second.nodes,
               [&](NodeRange r, std::uint32_t) { slot.release(r.first, r.count); });
  free_.insert(free_.end(), it->second.blocks.begin(), it->second.blocks.end());
  up_.erase(it);
  ++stats_.evictions;
}

std::uint64_t GpuNodePool::last_used(const Up& u) const {
  std::uint64_t used = 0;
  for (const std::uint32_t b : u.blocks) used = std::max(used, block_used_[b]);
  return used;
}

bool GpuNodePool::make_room(std::size_t blocks) {
  if (free_.size() >= blocks) return true;
  if (blocks_ < max_blocks_) {
    // Room within the budget: segments added, for one request a frame (a
    // new buffer costs its size on a driver that fills it when it is
    // made, as llvmpipe does); the pages after it wait for the next frame,
    // and nothing is given back while the budget has room.
    if (grown_frame_ == frame_) return false;
    grown_frame_ = frame_;
    grow(blocks);
    if (free_.size() >= blocks) return true;
  }
  // The pages no list used this frame, least recently used first: gathered
  // once a frame (a frame that makes room for many pages would otherwise
  // scan every page up for each), and checked again when their turn comes,
  // since prepare() marks a partly-up page it needs more of as used.
  if (lru_frame_ != frame_) {
    lru_frame_ = frame_;
    lru_.clear();
    lru_next_ = 0;
    for (const auto& [page, u] : up_)
      if (const std::uint64_t used = last_used(u); model_page(page).second != 0 && used < frame_)
        lru_.emplace_back(used, page);
    std::sort(lru_.begin(), lru_.end());
  }
  while (free_.size() < blocks && lru_next_ < lru_.size()) {
    const std::uint32_t page = lru_[lru_next_++].second;
    const auto it = up_.find(page);
    if (it != up_.end() && last_used(it->second) < frame_) give_back(page);
  }
  return free_.size() >= blocks;
}

std::uint64_t GpuNodePool::held_slot_bytes() const {
  std::uint64_t bytes = 0;
  for (const Held& m : models_) bytes += m.slot->held_bytes(m.hierarchy->node_count());
  return bytes;
}

GpuPoolStats GpuNodePool::stats() const {
  GpuPoolStats s = stats_;
  s.resident_bytes =
      std::uint64_t{blocks_ - static_cast<std::uint32_t>(free_.size())} * kBlock * kVertexBytes;
  s.resident_pages = up_.size();
  s.allocated_bytes = std::uint64_t{blocks_} * kBlock * kVertexBytes;
  s.segments = (blocks_ + segment_blocks_ - 1) / segment_blocks_;
  return s;
}

}  // namespace treecut::splat
