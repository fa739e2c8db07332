// CutBuffer: a cut's node ids on the GPU (renderer.hpp). Sorts them into
// the coherent submission order, merges a fading exchange into its three
// runs and writes the GL buffer no frame in flight reads. No draw here.
#include <algorithm>
#include <bit>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "treecut/splat/renderer.hpp"
#include "treecut/tree_cut.hpp"

namespace treecut::splat {

void CutBuffer::group_by_segment(std::uint32_t shift) {
  // A counting sort of each run by segment: stable, so each group keeps
  // the ascending ids of the coherent submission order (upload()).
  const std::size_t segments = (max_vertex_ >> shift) + 1;
  const std::uint32_t place = (std::uint32_t{1} << shift) - 1;
  const std::size_t bounds[] = {0, count_ - entering_, count_, count_ + leaving_};
  grouped_.resize(vertices_.size());
  for (std::uint32_t part = 0; part < 3; ++part) {
    group_at_.assign(segments, 0);
    for (std::size_t i = bounds[part]; i < bounds[part + 1]; ++i)
      ++group_at_[vertices_[i] >> shift];
    auto at = static_cast<std::uint32_t>(bounds[part]);
    for (std::uint32_t s = 0; s < segments; ++s) {
      const std::uint32_t n = group_at_[s];
      if (n > 0) segment_runs_.push_back(SegmentRun{at, n, s, part});
      group_at_[s] = at;
      at += n;
    }
    for (std::size_t i = bounds[part]; i < bounds[part + 1]; ++i) {
      const std::uint32_t v = vertices_[i];
      grouped_[group_at_[v >> shift]++] = v & place;
    }
  }
}

void CutBuffer::write(std::size_t current) {
  // Through the map (a paged model's pool) or the ids themselves.
  std::span<const std::uint32_t> ids = sorted_;
  segment_runs_.clear();
  if (map_ != nullptr) {
    max_vertex_ = map_->map(sorted_, current, vertices_);
    ids = vertices_;
    // A pool of several segments is drawn a segment at a time.
    if (const std::uint32_t shift = map_->segment_shift(); (max_vertex_ >> shift) > 0) {
      group_by_segment(shift);
      ids = grouped_;
    }
  } else {
    max_vertex_ = max_id_;
  }
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
  count_ = nodes.size();
  entering_ = 0;
  leaving_ = 0;
  fade_ = 1.0f;
  points_ = points;
  hierarchy_ = &h;
  max_id_ = sorted_.empty() ? 0 : sorted_.back();
  write(count_);
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
  count_ = cur.size();
  entering_ = entering_ids_.size();
  leaving_ = leaving_ids_.size();
  fade_ = 0.0f;
  points_ = points;
  hierarchy_ = &h;
  max_id_ = std::max(cur.empty() ? NodeId{0} : cur.back(), prev.back());
  write(count_);
}

void CutBuffer::refresh() {
  if (map_ != nullptr && hierarchy_ != nullptr) write(count_);
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

}  // namespace treecut::splat
