// The chunked build (chunked_build.hpp): count, distribute, complete each
// chunk's attributes, build each chunk into pages, then the levels over
// them and the file.
#include "chunked_build.hpp"

#include <malloc.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstring>
#include <limits>
#include <mutex>
#include <optional>

#include "cache_format.hpp"
#include "cache_pages.hpp"
#include "chunk_plan.hpp"
#include "chunk_sources.hpp"
#include "model_read.hpp"
#include "point_blocks.hpp"
#include "subtree_roots.hpp"
#include "treecut/error.hpp"
#include "treecut/file_io.hpp"
#include "treecut/parallel.hpp"
#include "whole_ids.hpp"

namespace treecut::detail {

namespace {

using cache_layout::PageRecord;
using cache_layout::PageRun;
using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

// What a chunk freed goes back to the system before the next: the
// allocator would keep it (each worker thread's arena its own), and the
// budget bounds what the process holds, not what it uses.
void give_back_memory() {
  ::malloc_trim(0);
}

// ---- Chunks on disk ---------------------------------------------------------

struct Block {
  std::uint64_t offset, bytes;
};

struct ChunkBlocks {
  std::vector<Block> core, halo;  // the parts, in reading order
  std::vector<Block> done;        // the chunk's points with their attributes
};

// Points packed a slice at a time: the packing's buffers stay small beside
// the chunk.
constexpr std::size_t kSlicePoints = 16384;

// The file is shared by the chunks in flight: LOCK is held for its reads
// and appends alone, the packing and unpacking go on beside.
std::vector<Block> append_slices(ScratchFile& file, std::mutex& lock, const PointSet& ps) {
  std::vector<Block> blocks;
  std::vector<std::uint32_t> ids;
  for (std::size_t at = 0; at < ps.size(); at += kSlicePoints) {
    ids.clear();
    for (std::size_t i = at; i < std::min(ps.size(), at + kSlicePoints); ++i)
      ids.push_back(static_cast<std::uint32_t>(i));
    const std::vector<unsigned char> bytes = pack_points(ps, ids);
    std::lock_guard held(lock);
    blocks.push_back({file.append(bytes.data(), bytes.size()), bytes.size()});
  }
  return blocks;
}

PointSet read_blocks(ScratchFile& file, std::mutex& lock, const std::vector<Block>& blocks,
                     PointSet into = {}) {
  std::vector<unsigned char> bytes;
  for (const Block& b : blocks) {
    bytes.resize(b.bytes);
    {
      std::lock_guard held(lock);
      file.read(b.offset, bytes.data(), bytes.size());
    }
    into.append(unpack_points(bytes));
  }
  return into;
}

void release(ScratchFile& file, const std::vector<Block>& blocks) {
  for (const Block& b : blocks) file.release(b.offset, b.bytes);
}

// The median of the positive radii in FILE (floats, appended): a radix
// select over their bits (a positive float's order is its bits'), two
// passes of 64 Ki counters, never the radii in memory.
float median_of(ScratchFile& file, std::uint64_t count) {
  if (count == 0) return 0.0f;
  std::uint64_t rank = count / 2;  // nth_element's middle, as median_positive
  std::vector<std::uint64_t> hist(65536);
  std::vector<std::uint32_t> bits(1 << 20);
  std::uint32_t high = 0;
  for (int pass = 0; pass < 2; ++pass) {
    std::fill(hist.begin(), hist.end(), 0);
    for (std::uint64_t at = 0; at < count; at += bits.size()) {
      const auto n = static_cast<std::size_t>(std::min<std::uint64_t>(bits.size(), count - at));
      file.read(at * 4, bits.data(), n * 4);
      for (std::size_t i = 0; i < n; ++i) {
        if (pass == 0)
          ++hist[bits[i] >> 16];
        else if ((bits[i] >> 16) == high)
          ++hist[bits[i] & 0xffff];
      }
    }
    std::uint32_t bin = 0;
    while (rank >= hist[bin]) rank -= hist[bin++];
    if (pass == 0) {
      high = bin;
    } else {
      const std::uint32_t b = (high << 16) | bin;
      float m;
      std::memcpy(&m, &b, 4);
      return m;
    }
  }
  return 0.0f;
}

// A chunk built: its pages on disk and its root for the levels above.
struct ChunkPages {
  std::vector<PageRecord> table;           // offsets into the pages' scratch file
  std::vector<std::vector<PageRun>> runs;  // each page's, in the chunk's own ids and depths
  std::vector<std::uint64_t> points;       // under each page's root
  std::vector<std::uint64_t> level_begin;  // the chunk's own
  std::uint32_t levels = 0;
  std::uint64_t nodes = 0;
};

// What a point of a chunk (its halo's too) costs at the peak of its two
// stages: its arrays, the neighbour grid and the values found (attributes),
// or build_hierarchy and its pages (hierarchy), with what the allocator
// keeps; measured with a survey's eleven fields: 2 M points within 32 MiB
// (the program 16-17 of them), 20 M in 1 GiB and 256 MiB (docs/benchmarks.md,
// "Chunked build").
constexpr std::uint64_t kChunkBytesPerPoint = 170;
// What the stages hold beside the chunk: the scratch files' write buffers,
// the compressor's and a batch's blocks.
constexpr std::uint64_t kStageBytes = std::uint64_t{4} << 20;

// Chunks worked on at once. Each stage of a chunk has parts that one
// thread does (reading and packing its points, the hierarchy's top splits,
// the page encoder) and leave the other cores idle: a 2 M survey's chunks
// kept 1.42 of 2 cores busy one at a time. Two chunks in flight fill them,
// each with half the budget, where a chunk keeps at least kLanePoints:
// below it the halo's copies grow past a tenth of the points, and each
// lane's allocator arena past what the budget allows (32 MiB).
constexpr unsigned kMaxLanes = 2;
constexpr std::uint64_t kLanePoints = std::uint64_t{1} << 16;

// The sizes ROOM (the budget less what the program holds) allows: a
// chunk's points, a batch's, the grid's.
struct Sizes {
  std::uint64_t chunk_points;
  std::size_t batch_points;
  int grid_levels;
  unsigned lanes;
};

Sizes sizes_for(std::uint64_t room, unsigned threads) {
  Sizes s{};
  s.grid_levels = room >= (std::uint64_t{512} << 20) ? 7 : 6;
  const std::uint64_t grid = std::uint64_t{4} << (3 * s.grid_levels);
  // The grid, the stages' own, and an eighth for what the allocator keeps
  // between chunks.
  const std::uint64_t fixed = 2 * grid + kStageBytes + room / 8;
  const std::uint64_t left = room > 2 * fixed ? room - fixed : room / 2;
  // A batch on its way to the chunks (~120 bytes a point with its
  // blocks) takes a tenth, at most a million points.
  s.batch_points = static_cast<std::size_t>(
      std::clamp<std::uint64_t>(left / 10 / 120, 4096, std::uint64_t{1} << 20));
  s.chunk_points = std::max<std::uint64_t>(4096, left * 7 / 10 / kChunkBytesPerPoint);
  s.lanes = 1;
  while (s.lanes < std::min(kMaxLanes, worker_count(threads)) &&
         s.chunk_points / (s.lanes + 1) >= kLanePoints)
    ++s.lanes;
  s.chunk_points /= s.lanes;
  return s;
}

// One chunked build: the stages in order, each a method, their results in
// the members (chunked_build.hpp has the why).
class ChunkedBuild {
 public:
  ChunkedBuild(std::span<const std::filesystem::path> files, const OpenOptions& options,
               const std::filesystem::path& cache, std::uint64_t room, OpenedModel& out)
      : files_(files),
        options_(options),
        cache_(cache),
        sizes_(sizes_for(room, options.build.threads)),
        out_(out) {}

  void count();
  void distribute();
  void complete_chunks();
  void build_chunks();
  void levels_over_chunks();
  void write(const CacheKey& key, SourceNotes& notes);
  [[nodiscard]] const ChunkedBuildReport& report() const { return report_; }

 private:
  void progress(std::string_view stage, std::uint64_t done, std::uint64_t total) const {
    if (options_.progress) options_.progress(stage, done, total);
  }
  // FN(c) for every chunk, sizes_.lanes of them at once (the calling
  // thread one lane), each lane taking the next chunk; after a failure no
  // lane starts another, and the first is rethrown. What a chunk freed is
  // given back before its lane takes the next.
  template <class Fn>
  void for_each_chunk(Fn&& fn);
  void send_to_chunks(const PointSet& batch);
  void like_chunks(PointSet& ps) const;
  // The pages' table in file order, each page's bytes from memory (the top
  // levels') or the pages' scratch file.
  struct Source {
    const std::vector<unsigned char>* memory;
    std::uint64_t offset;
  };
  void add_page(const PageRecord& r, Source from, std::span<const PageRun> runs,
                std::uint64_t points) {
    table_.push_back(r);
    sources_.push_back(from);
    links_.runs.insert(links_.runs.end(), runs.begin(), runs.end());
    links_.run_index.push_back(links_.runs.size());
    links_.points.push_back(points);
  }
  void number_nodes(const TopLevels* top);

  std::span<const std::filesystem::path> files_;
  const OpenOptions& options_;
  std::filesystem::path cache_;
  Sizes sizes_;
  OpenedModel& out_;
  ChunkedBuildReport report_;
  // Held by a chunk's lane for the scratch files, the report and the
  // progress (whatever the lanes share); the rest of a chunk is its own.
  std::mutex mutex_;
  std::uint64_t declared_ = 0;  // points the headers declare
  std::optional<ChunkPlan> plan_;
  std::vector<ChunkBlocks> blocks_;
  std::vector<std::vector<std::uint32_t>> core_ids_, halo_ids_;  // send_to_chunks
  Whole whole_;
  CoordinateFrame frame_;
  // Each scratch file goes when it is read for the last time (and its
  // write buffer with it).
  std::optional<ScratchFile> parts_, done_, radii_, pages_;
  std::uint64_t positive_radii_ = 0;
  bool radii_from_neighbours_ = false;
  float median_radius_ = 0.0f;
  std::vector<NodeAttribute> model_;
  std::vector<ChunkPages> built_;
  std::vector<SubtreeRoot> roots_;
  // The file: its pages, their sources, the levels and nodes.
  std::vector<PageRecord> table_;
  std::vector<Source> sources_;
  cache_pages::PageLinks links_{{}, {0}, {}, {}};
  // The ids of the whole (whole_ids.hpp), and each chunk's levels and the
  // depth of its root they are made of.
  std::optional<WholeIds> ids_;
  std::vector<std::vector<std::uint64_t>> chunk_levels_;
  std::vector<std::uint32_t> depth_;
  cache_pages::Encoded top_pages_;
  std::uint32_t levels_ = 0;
  std::uint64_t nodes_ = 0;
};

template <class Fn>
void ChunkedBuild::for_each_chunk(Fn&& fn) {
  std::atomic<bool> failed = false;
  WorkerPool lanes(report_.lanes);
  lanes.run(report_.chunks, 1, [&](std::size_t c, std::size_t, std::size_t) {
    if (failed.load(std::memory_order_relaxed)) return;
    try {
      fn(c);
    } catch (...) {
      failed.store(true, std::memory_order_relaxed);
      throw;
    }
    give_back_memory();
  });
}

// 1. The points counted on the plan's grid, the chunks cut.
void ChunkedBuild::count() {
  declared_ = build_memory_estimate(files_).points;
  const auto [lo, hi] = model_box(files_, options_.columns, sizes_.batch_points);
  plan_.emplace(lo, hi, sizes_.grid_levels);
  NeighbourReach reach(lo, hi);
  Whole frame_only;
  OpenedModel ignored;
  std::uint64_t done = 0;
  for_each_batch(
      files_, sizes_.batch_points, {}, options_.columns, ignored,
      [&](PointSet& b, std::size_t f) {
        if (!frame_only.started) refuse_reprojection(b, files_.front());
        join_frame(b, files_[f], files_.front(), frame_only, {});
        plan_->count(b.positions);
        reach.count(b.positions);
        progress("count points", done += b.size(), declared_);
      },
      true);  // the positions alone: the fields cost twice their parsing
  plan_->plan(sizes_.chunk_points, reach.reach(std::max(3, options_.attributes.k)));
  report_.chunks = plan_->chunks().size();
  report_.lanes = std::min<std::size_t>(sizes_.lanes, report_.chunks);
  report_.halo = plan_->halo();
}

// 2. Each batch's points to their chunks and to the halos they lie in, as
// blocks in the parts' scratch file; the whole's figures on the way.
void ChunkedBuild::distribute() {
  parts_.emplace(cache_.string() + ".parts");
  blocks_.resize(report_.chunks);
  for_each_batch(files_, sizes_.batch_points, options_.warn, options_.columns, out_,
                 [&](PointSet& b, std::size_t f) {
                   join_frame(b, files_[f], files_.front(), whole_, options_.warn);
                   gather(b, whole_);
                   send_to_chunks(b);
                   progress("distribute points", whole_.points, declared_);
                 });
  report_.points = out_.input_points = whole_.points;
  if (whole_.points == 0) throw InputError(quoted_name(files_.front()) + ": no points");
  out_.files = files_.size();
  report_.scratch_bytes = parts_->held();
  std::vector<std::vector<std::uint32_t>>().swap(core_ids_);
  std::vector<std::vector<std::uint32_t>>().swap(halo_ids_);
  frame_ = whole_.first.frame;
}

void ChunkedBuild::send_to_chunks(const PointSet& b) {
  const std::size_t chunks = report_.chunks;
  // Each chunk's points of the batch, its own and its halo's (kept between
  // batches for their capacity).
  std::vector<std::vector<std::uint32_t>>& core = core_ids_;
  std::vector<std::vector<std::uint32_t>>& halo = halo_ids_;
  core.resize(chunks), halo.resize(chunks);
  std::vector<std::uint32_t> touched;
  const auto touch = [&](std::uint32_t c) {
    if (core[c].empty() && halo[c].empty()) touched.push_back(c);
  };
  std::vector<std::uint32_t> near;
  for (std::uint32_t i = 0; i < b.size(); ++i) {
    const glm::vec3 p = b.positions[i];
    const std::uint32_t c = plan_->chunk_of(p);
    touch(c);
    core[c].push_back(i);
    plan_->halo_chunks(p, c, near);
    for (const std::uint32_t h : near) touch(h), halo[h].push_back(i);
  }
  for (const std::uint32_t c : touched) {
    for (auto [ids, to] :
         {std::pair{&core[c], &blocks_[c].core}, std::pair{&halo[c], &blocks_[c].halo}}) {
      if (ids->empty()) continue;
      const std::vector<unsigned char> bytes = pack_points(b, *ids);
      to->push_back({parts_->append(bytes.data(), bytes.size()), bytes.size()});
      if (to == &blocks_[c].halo) report_.halo_points += ids->size();
      ids->clear();
    }
  }
}

// 3. Each chunk's normals, radii and curvature from its points and halo
// (the whole's centroid); its points kept with them, the positive radii
// apart for the whole's median.
void ChunkedBuild::complete_chunks() {
  done_.emplace(cache_.string() + ".points");
  radii_.emplace(cache_.string() + ".radii");
  const glm::vec3 centroid(whole_.sum / double(whole_.points));
  std::size_t finished = 0;
  bool normals_estimated = false;
  for_each_chunk([&](std::size_t c) {
    CloudPart part{centroid, 0, plan_->halo()};
    PointSet ps = read_blocks(*parts_, mutex_, blocks_[c].core);
    part.queried = ps.size();
    ps = read_blocks(*parts_, mutex_, blocks_[c].halo, std::move(ps));
    const std::uint64_t with_halo = ps.size();
    like_chunks(ps);
    const bool from_neighbours = complete_part_attributes(ps, options_.attributes, part);
    keep_first(ps, part.queried);
    std::vector<float> kept;  // for the whole's median
    for (const float r : ps.radii)
      if (r > 0.0f && std::isfinite(r)) kept.push_back(r);
    std::vector<Block> done = append_slices(*done_, mutex_, ps);
    std::lock_guard lock(mutex_);
    report_.largest_chunk = std::max(report_.largest_chunk, with_halo);
    radii_from_neighbours_ = from_neighbours;
    normals_estimated = normals_estimated || ps.frame.normals_estimated;
    radii_->append(kept.data(), kept.size() * sizeof(float));
    positive_radii_ += kept.size();
    blocks_[c].done = std::move(done);
    report_.scratch_bytes =
        std::max(report_.scratch_bytes, parts_->held() + done_->held() + radii_->held());
    release(*parts_, blocks_[c].core), release(*parts_, blocks_[c].halo);
    progress("chunks: attributes", ++finished, report_.chunks);
  });
  frame_.normals_estimated = frame_.normals_estimated || normals_estimated;
  parts_.reset();
  median_radius_ = median_of(*radii_, positive_radii_);
  radii_.reset();
}

// As a chunk is made: the model's frame, and only the arrays every file
// has (the others computed for all, as for a file without them).
void ChunkedBuild::like_chunks(PointSet& ps) const {
  if (!whole_.normals) ps.normals.clear();
  if (!whole_.radii) ps.radii.clear();
  if (!whole_.curvature) ps.curvature.clear();
  ps.frame = frame_;
}

// 4. Each chunk's radii finished with the whole's median, its hierarchy
// built and paged into the pages' scratch file; its root kept.
void ChunkedBuild::build_chunks() {
  model_ = model_attributes(whole_);
  pages_.emplace(cache_.string() + ".pages");
  built_.resize(report_.chunks);
  roots_.resize(report_.chunks);
  BuildOptions build = options_.build;
  build.progress = nullptr;
  std::size_t finished = 0;
  for_each_chunk([&](std::size_t c) {
    PointSet ps = read_blocks(*done_, mutex_, blocks_[c].done);
    ps.frame = frame_;
    finish_part_radii(ps.radii, median_radius_, radii_from_neighbours_);
    double cover2 = 0.0;
    for (const float r : ps.radii) cover2 += double(r) * double(r);
    match_fields(ps, model_);
    const Hierarchy h = build_hierarchy(std::move(ps), build);
    to_model_offsets(h, model_);
    const cache_pages::Encoded e = cache_pages::encode(h);
    SubtreeRoot& root = roots_[c];
    root.center_radius = glm::vec4(e.root.center, e.root.radius);
    root.cover = static_cast<float>(std::sqrt(cover2));
    root.normal_cone = h.arrays().normal_cone[0];
    root.color = h.arrays().color[0];
    root.priority = h.arrays().priority[0];
    root.point_count = h.leaf_count();
    for (const NodeAttribute& a : h.attributes()) root.values.push_back(a.value(0));
    ChunkPages& cp = built_[c];
    cp.levels = static_cast<std::uint32_t>(h.level_count());
    cp.nodes = h.node_count();
    cp.runs = e.runs;
    cp.points = e.points;
    for (int d = 0; d <= h.level_count(); ++d) cp.level_begin.push_back(h.level_begin(d));
    std::lock_guard lock(mutex_);
    release(*done_, blocks_[c].done);
    for (std::size_t q = 0; q < e.table.size(); ++q) {
      PageRecord r = e.table[q];
      r.offset = pages_->append(e.pages[q].data(), e.pages[q].size());
      cp.table.push_back(r);
    }
    report_.scratch_bytes = std::max(report_.scratch_bytes, done_->held() + pages_->held());
    progress("chunks: hierarchy", ++finished, report_.chunks);
  });
  done_.reset();
}

// The whole's ids (whole_ids.hpp) over TOP (null: a single chunk); its
// levels and nodes.
void ChunkedBuild::number_nodes(const TopLevels* top) {
  chunk_levels_.clear();
  for (const ChunkPages& cp : built_) chunk_levels_.push_back(cp.level_begin);
  ids_.emplace(top, chunk_levels_, depth_);
  links_.level_begin = ids_->level_begin();
  nodes_ = links_.level_begin.back();
  levels_ = static_cast<std::uint32_t>(links_.level_begin.size() - 1);
}

// 5. The levels over the chunks' roots, and the page table in file order:
// the top's pages (a chunk's first page where the top has its root), then
// the chunks' other pages, chunk after chunk.
void ChunkedBuild::levels_over_chunks() {
  const std::size_t chunks = report_.chunks;
  std::vector<std::uint32_t> first_page(chunks, 0);
  depth_.assign(chunks, 0);
  std::optional<TopLevels> top;
  if (chunks == 1) {
    number_nodes(nullptr);
    add_page(built_[0].table[0], {nullptr, built_[0].table[0].offset},
             ids_->chunk_runs(0, built_[0].runs[0]), built_[0].points[0]);
  } else {
    top = build_over_roots(roots_, model_, frame_, options_.build.parent_at_real_point);
    const Hierarchy& t = top->hierarchy;
    std::vector<cache_pages::Root> leaf_roots(t.node_count());
    for (NodeId i = 0; i < t.node_count(); ++i) {
      if (top->root_of[i] == kNoNode) continue;
      const glm::vec4 s = roots_[top->root_of[i]].center_radius;
      leaf_roots[i] = {glm::vec3(s), s.w};
      depth_[top->root_of[i]] = t.arrays().depth[i];
    }
    top_pages_ = cache_pages::encode_over(t, leaf_roots);
    number_nodes(&*top);
    for (std::size_t q = 0; q < top_pages_.table.size(); ++q) {
      const NodeId c = top->root_of[top_pages_.roots[q]];
      if (c == kNoNode) {
        add_page(top_pages_.table[q], {&top_pages_.pages[q], 0}, ids_->top_runs(top_pages_.runs[q]),
                 top_pages_.points[q]);
        continue;
      }
      PageRecord r = built_[c].table[0];
      r.parent_page = top_pages_.table[q].parent_page;
      r.parent_local = top_pages_.table[q].parent_local;
      r.root_depth = depth_[c];
      first_page[c] = static_cast<std::uint32_t>(table_.size());
      add_page(r, {nullptr, built_[c].table[0].offset}, ids_->chunk_runs(c, built_[c].runs[0]),
               built_[c].points[0]);
    }
  }
  for (std::size_t c = 0; c < chunks; ++c) {
    const auto base = static_cast<std::uint32_t>(table_.size());
    for (std::size_t q = 1; q < built_[c].table.size(); ++q) {
      PageRecord r = built_[c].table[q];
      const std::uint64_t at = r.offset;
      r.parent_page = r.parent_page == 0 ? first_page[c] : base + r.parent_page - 1;
      r.root_depth += depth_[c];
      add_page(r, {nullptr, at}, ids_->chunk_runs(c, built_[c].runs[q]), built_[c].points[q]);
    }
  }
  report_.nodes = nodes_;
  for (const NodeAttribute& a : model_) report_.value_streams += !a.is_constant();
  if (levels_ > 256)
    throw std::runtime_error(quoted_name(cache_) + ": the model's hierarchy is " +
                             std::to_string(levels_) + " levels deep; a cache holds 256");
}

// 6. The cache file: its meta part, the pages in the table's order, the
// checksum; through an AtomicFile, so nothing is at the name until all is.
void ChunkedBuild::write(const CacheKey& key, SourceNotes& notes) {
  notes.format = format_text(out_);
  const CacheMeta meta{key,           frame_,  whole_.lo, whole_.hi, nodes_,
                       whole_.points, levels_, model_,    notes};
  const std::vector<unsigned char> bytes = cache_meta(meta, table_, links_);
  create_cache_folder(cache_);
  AtomicFile file(cache_);
  file.write(bytes.data(), bytes.size());
  std::vector<unsigned char> page;
  for (std::size_t q = 0; q < table_.size(); ++q) {
    if (sources_[q].memory) {
      file.write(sources_[q].memory->data(), sources_[q].memory->size());
      continue;
    }
    page.resize(table_[q].bytes);
    pages_->read(sources_[q].offset, page.data(), page.size());
    file.write(page.data(), page.size());
  }
  const std::array<unsigned char, 8> sum = meta_checksum(bytes);
  file.write(sum.data(), sum.size());
  file.commit();
  pages_.reset();
}

}  // namespace

ChunkedBuildReport build_chunked(std::span<const std::filesystem::path> files,
                                 const OpenOptions& options, const CacheKey& key,
                                 const std::filesystem::path& cache, std::uint64_t room,
                                 const std::function<void()>& after_read, SourceNotes& notes,
                                 OpenedModel& out) {
  ChunkedBuild b(files, options, cache, room, out);
  auto t0 = Clock::now();
  b.count();
  b.distribute();
  after_read();
  out.read_seconds = seconds_since(t0);
  t0 = Clock::now();
  b.complete_chunks();
  out.attribute_seconds = seconds_since(t0);
  t0 = Clock::now();
  b.build_chunks();
  b.levels_over_chunks();
  out.build_seconds = seconds_since(t0);
  t0 = Clock::now();
  options.progress ? options.progress("cache", 0, 1) : void();
  b.write(key, notes);
  out.cache_seconds = seconds_since(t0);
  return b.report();
}

}  // namespace treecut::detail
