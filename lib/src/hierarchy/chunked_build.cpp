// The chunked build (chunked_build.hpp): count, distribute, complete each
// chunk's attributes, build each chunk into pages, then the levels over
// them and the file.
#include "chunked_build.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <limits>
#include <optional>

#include "cache_format.hpp"
#include "cache_pages.hpp"
#include "chunk_plan.hpp"
#include "model_read.hpp"
#include "point_blocks.hpp"
#include "reproject.hpp"
#include "subtree_roots.hpp"
#include "treecut/error.hpp"
#include "treecut/file_io.hpp"
#include "treecut/las.hpp"

namespace treecut::detail {

namespace {

using cache_layout::PageRecord;
using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

// ---- Reading: every file in batches ----------------------------------------

// A file's points in batches: a LAS file's from its reader, any other's
// whole, as one batch (their readers do not stream yet).
class Batches {
 public:
  Batches(const std::filesystem::path& file, const WarningSink& warn,
          const std::vector<std::string>& columns)
      : file_(file), warn_(warn), columns_(columns) {
    if (read_head(file, 4).starts_with("LASF")) las_.emplace(file, warn);
  }
  /// The next batch of at most MAX points; none at the end.
  PointSet next(std::size_t max, OpenedModel& out) {
    if (las_) {
      out.format = "LAS";
      out.las.info = las_->info();
      return las_->next(max);
    }
    if (done_) return {};
    done_ = true;
    PointSet all = read_point_file(file_, out, warn_, columns_);
    if (!all.triangles.empty())
      throw InputError(quoted_name(file_) +
                       ": a mesh is built held in memory (its faces join points that chunks "
                       "would part); --memory SIZE with room for it");
    return all;
  }
  [[nodiscard]] const LasInfo* las_info() const { return las_ ? &las_->info() : nullptr; }

 private:
  std::filesystem::path file_;
  WarningSink warn_;
  const std::vector<std::string>& columns_;
  std::optional<LasReader> las_;
  bool done_ = false;
};

// What the whole model is, gathered as the batches go by, in the order a
// build held whole reads them.
struct Whole {
  PointSet first;  // the first batch's frame, records (no points)
  bool started = false;
  std::uint64_t points = 0;
  glm::vec3 lo{INFINITY}, hi{-INFINITY};
  glm::dvec3 sum{0.0};  // of the float positions, for the centroid
  // Arrays every file has (one without them: computed for all, as append does).
  bool normals = true, radii = true, curvature = true;
  struct Field {
    std::string name;
    AttributeKind kind = AttributeKind::measure;
    double lo = INFINITY, hi = -INFINITY;
    bool seen = false, varies = false;
    double first = 0.0;
    void add(double v) {
      if (!std::isnan(v)) lo = std::min(lo, v), hi = std::max(hi, v);
      if (!seen) {
        seen = true, first = v;
      } else if (!varies) {
        varies = !(v == first || (std::isnan(v) && std::isnan(first)));
      }
    }
  };
  std::vector<Field> fields;
};

// Moves a batch of FILE to the model's frame (the first file's origin, as
// PointSet::append moves it) and checks it belongs to the model.
void join_frame(PointSet& batch, const std::filesystem::path& file,
                const std::filesystem::path& first_file, Whole& whole, const WarningSink& warn) {
  if (!whole.started) {
    whole.first.frame = batch.frame;
    whole.first.records = batch.records;
    whole.first.adjusted_gps_time = batch.adjusted_gps_time;
    whole.started = true;
  } else {
    check_same_system(first_file, whole.first, file, batch, warn);
    CoordinateFrame& f = whole.first.frame;
    if (f.resolution != batch.frame.resolution || f.grid_offset != batch.frame.grid_offset)
      f.resolution = glm::dvec3(0.0), f.grid_offset = glm::dvec3(0.0);
  }
  const glm::dvec3 shift = batch.frame.origin - whole.first.frame.origin;
  for (glm::vec3& p : batch.positions) p = glm::vec3(glm::dvec3(p) + shift);
  std::vector<glm::dvec3>().swap(batch.exact_positions);  // the hierarchy is floats
  batch.frame.origin = whole.first.frame.origin;
}

// Calls FN(batch, file index) for every batch of every file, in order.
template <class Fn>
void for_each_batch(std::span<const std::filesystem::path> files, std::size_t batch_points,
                    const WarningSink& warn, const std::vector<std::string>& columns,
                    OpenedModel& out, Fn&& fn) {
  for (std::size_t f = 0; f < files.size(); ++f) {
    Batches batches(files[f], warn, columns);
    OpenedModel one;
    for (;;) {
      PointSet batch = batches.next(batch_points, f == 0 ? out : one);
      if (batch.size() == 0) break;
      fn(batch, f);
    }
    if (f > 0) out.las.dropped_nonfinite += one.las.dropped_nonfinite;
  }
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

std::vector<Block> append_slices(ScratchFile& file, const PointSet& ps) {
  std::vector<Block> blocks;
  std::vector<std::uint32_t> ids;
  for (std::size_t at = 0; at < ps.size(); at += kSlicePoints) {
    ids.clear();
    for (std::size_t i = at; i < std::min(ps.size(), at + kSlicePoints); ++i)
      ids.push_back(static_cast<std::uint32_t>(i));
    const std::vector<unsigned char> bytes = pack_points(ps, ids);
    blocks.push_back({file.append(bytes.data(), bytes.size()), bytes.size()});
  }
  return blocks;
}

PointSet read_blocks(ScratchFile& file, const std::vector<Block>& blocks, PointSet into = {}) {
  std::vector<unsigned char> bytes;
  for (const Block& b : blocks) {
    bytes.resize(b.bytes);
    file.read(b.offset, bytes.data(), bytes.size());
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

// The model's attributes as the file records them: a field's offset as the
// builder picks it for its whole range (node_attributes.cpp), one that
// never varies stored once.
std::vector<NodeAttribute> model_attributes(const Whole& whole) {
  static const float kVaries = 0.0f;  // a non-empty span marks a field that varies
  std::vector<NodeAttribute> out;
  for (const Whole::Field& f : whole.fields) {
    NodeAttribute a;
    a.name = f.name, a.kind = f.kind;
    const bool any = f.lo <= f.hi;
    a.min = any ? f.lo : std::numeric_limits<double>::quiet_NaN();
    a.max = any ? f.hi : std::numeric_limits<double>::quiet_NaN();
    if (!f.varies) {
      a.offset = std::isnan(f.first) || std::fabs(f.first) < 16777216.0 ? 0.0 : std::round(f.first);
      a.constant = static_cast<float>(f.first - a.offset);
    } else {
      const double mid = any ? std::round(0.5 * f.lo + 0.5 * f.hi) : 0.0;
      a.offset = !any || (std::fabs(mid) < 16777216.0 && f.lo == std::round(f.lo) &&
                          f.hi == std::round(f.hi))
                     ? 0.0
                     : mid;
      a.values = std::span<const float>(&kVaries, 1);
    }
    out.push_back(std::move(a));
  }
  return out;
}

// A chunk's attributes in the model's order and forms: a field the chunk
// lacks is NaN, one that varies in the model is stored per point here too
// (so every page has the same value streams).
void match_fields(PointSet& ps, const std::vector<NodeAttribute>& model) {
  std::vector<PointAttribute> fields;
  for (const NodeAttribute& m : model) {
    auto it = std::find_if(ps.attributes.begin(), ps.attributes.end(),
                           [&](const PointAttribute& a) { return a.name == m.name; });
    PointAttribute a;
    if (it != ps.attributes.end()) a = std::move(*it);
    a.name = m.name, a.kind = m.kind;
    if (a.is_constant() && !m.is_constant()) a.wide.assign(ps.size(), a.constant);
    fields.push_back(std::move(a));
  }
  ps.attributes = std::move(fields);
}

// The chunk's node values moved to the model's offsets (the builder chose
// the chunk's own; H is this build's alone).
void to_model_offsets(const Hierarchy& h, const std::vector<NodeAttribute>& model) {
  for (std::size_t k = 0; k < model.size(); ++k) {
    const NodeAttribute& own = h.attributes()[k];
    if (own.is_constant() || own.offset == model[k].offset) continue;
    auto* v = const_cast<float*>(own.values.data());
    for (std::size_t i = 0; i < own.values.size(); ++i)
      if (!std::isnan(v[i])) v[i] = static_cast<float>(own.offset + double(v[i]) - model[k].offset);
  }
}

// ---- The passes -------------------------------------------------------------

// The box around the model, in the first file's frame: a LAS file's from
// its header (a point outside it counts in the nearest cell of the grid),
// any other's from its points.
std::pair<glm::vec3, glm::vec3> model_box(std::span<const std::filesystem::path> files,
                                          const std::vector<std::string>& columns) {
  glm::vec3 lo(INFINITY), hi(-INFINITY);
  std::optional<glm::dvec3> origin;
  for (const std::filesystem::path& file : files) {
    if (read_head(file, 4).starts_with("LASF")) {
      LasReader reader(file);
      const LasInfo& info = reader.info();
      if (!origin) origin = reader.next(0).frame.origin;
      if (info.point_count == 0) continue;
      for (int a = 0; a < 3; ++a) {
        lo[a] = std::min(lo[a], static_cast<float>(info.min[a] - (*origin)[a]));
        hi[a] = std::max(hi[a], static_cast<float>(info.max[a] - (*origin)[a]));
      }
      continue;
    }
    OpenedModel ignored;
    const PointSet all = read_point_file(file, ignored, {}, columns);
    if (!origin) origin = all.frame.origin;
    const glm::dvec3 shift = all.frame.origin - *origin;
    for (const glm::vec3& p : all.positions) {
      const glm::vec3 q(glm::dvec3(p) + shift);
      lo = glm::min(lo, q), hi = glm::max(hi, q);
    }
  }
  if (!(lo.x <= hi.x)) lo = hi = glm::vec3(0.0f);
  return {lo, hi};
}

// The running figures of the whole from one batch (in the model's frame).
void gather(const PointSet& b, Whole& whole) {
  for (const glm::vec3& p : b.positions) {
    whole.sum += glm::dvec3(p);
    whole.lo = glm::min(whole.lo, p), whole.hi = glm::max(whole.hi, p);
  }
  whole.normals = whole.normals && b.has_normals();
  whole.radii = whole.radii && b.has_radii();
  whole.curvature = whole.curvature && b.has_curvature();
  const bool earlier = whole.points > 0;
  for (const PointAttribute& a : b.attributes) {
    const bool known = std::any_of(whole.fields.begin(), whole.fields.end(),
                                   [&](const Whole::Field& f) { return f.name == a.name; });
    if (known || whole.fields.size() == kMaxAttributes) continue;
    Whole::Field& f = whole.fields.emplace_back();
    f.name = a.name, f.kind = a.kind;
    if (earlier) f.add(std::numeric_limits<double>::quiet_NaN());  // the earlier points lack it
  }
  for (Whole::Field& f : whole.fields) {
    const auto it = std::find_if(b.attributes.begin(), b.attributes.end(),
                                 [&](const PointAttribute& a) { return a.name == f.name; });
    if (it == b.attributes.end() || it->is_constant()) {
      f.add(it == b.attributes.end() ? std::numeric_limits<double>::quiet_NaN() : it->constant);
      continue;
    }
    for (std::size_t i = 0; i < b.size(); ++i) f.add(it->value(i));
  }
  whole.points += b.size();
}

// Geographic input is reprojected around its centre, which a chunk does
// not know: such a model is built held in memory.
void refuse_reprojection(const PointSet& first, const std::filesystem::path& file) {
  PointSet one;
  one.frame = first.frame;
  one.positions.assign(first.positions.begin(), first.positions.begin() + 1);
  if (!reproject(one, {}, quoted_name(file)).empty())
    throw InputError(quoted_name(file) +
                     ": geographic coordinates are reprojected in a build held in memory; this "
                     "model needs more than its memory budget (--memory SIZE)");
}

// A chunk built: its pages on disk and its root for the levels above.
struct ChunkPages {
  std::vector<PageRecord> table;  // offsets into the pages' scratch file
  std::uint32_t levels = 0;
  std::uint64_t nodes = 0;
};

// What a point of a chunk (its halo's too) costs at the peak of its two
// stages: its arrays, the neighbour grid and the values found (attributes),
// or build_hierarchy and its pages (hierarchy); about 125 bytes measured
// with a survey's eleven fields (docs/files.md, "Memory").
constexpr std::uint64_t kChunkBytesPerPoint = 180;

// The sizes ROOM (the budget less what the program holds) allows: a
// chunk's points, a batch's, the grid's.
struct Sizes {
  std::uint64_t chunk_points;
  std::size_t batch_points;
  int grid_levels;
};

Sizes sizes_for(std::uint64_t room) {
  Sizes s{};
  s.grid_levels = room >= (std::uint64_t{512} << 20) ? 7 : 6;
  const std::uint64_t grid = std::uint64_t{4} << (3 * s.grid_levels);
  const std::uint64_t left = room > 4 * grid ? room - 2 * grid : room / 2;
  // A batch on its way to the chunks (~120 bytes a point with its
  // blocks) takes a tenth, at most a million points.
  s.batch_points = static_cast<std::size_t>(
      std::clamp<std::uint64_t>(left / 10 / 120, 4096, std::uint64_t{1} << 20));
  s.chunk_points = std::max<std::uint64_t>(4096, left * 6 / 10 / kChunkBytesPerPoint);
  return s;
}

}  // namespace

ChunkedBuildReport build_chunked(std::span<const std::filesystem::path> files,
                                 const OpenOptions& options, const CacheKey& key,
                                 const std::filesystem::path& cache, std::uint64_t room,
                                 SourceNotes& notes, OpenedModel& out) {
  ChunkedBuildReport report;
  const Sizes sizes = sizes_for(room);
  const auto progress = [&](std::string_view stage, std::uint64_t done, std::uint64_t total) {
    if (options.progress) options.progress(stage, done, total);
  };
  const std::vector<std::string>& columns = options.columns;
  auto t0 = Clock::now();

  // 1. Count.
  const BuildMemory declared = build_memory_estimate(files);
  const auto [box_lo, box_hi] = model_box(files, columns);
  ChunkPlan plan(box_lo, box_hi, sizes.grid_levels);
  {
    Whole frame_only;
    OpenedModel ignored;
    std::uint64_t done = 0;
    for_each_batch(files, sizes.batch_points, {}, columns, ignored,
                   [&](PointSet& b, std::size_t f) {
                     if (!frame_only.started) refuse_reprojection(b, files.front());
                     join_frame(b, files[f], files.front(), frame_only, {});
                     plan.count(b.positions);
                     progress("count", done += b.size(), declared.points);
                   });
  }
  plan.plan(sizes.chunk_points, std::max(3, options.attributes.k));
  const std::size_t chunks = plan.chunks().size();
  report.chunks = chunks;
  report.halo = plan.halo();

  // 2. Distribute: each batch's points to their chunks and halos.
  // Each scratch file goes as soon as it is read for the last time (its
  // write buffer with it).
  std::optional<ScratchFile> parts_file(std::in_place, cache.string() + ".parts");
  ScratchFile& parts = *parts_file;
  std::vector<ChunkBlocks> blocks(chunks);
  Whole whole;
  {
    std::vector<std::vector<std::uint32_t>> core(chunks), halo(chunks);
    std::vector<std::uint32_t> touched;
    for_each_batch(
        files, sizes.batch_points, options.warn, columns, out, [&](PointSet& b, std::size_t f) {
          join_frame(b, files[f], files.front(), whole, options.warn);
          gather(b, whole);
          std::uint32_t near[26];
          for (std::uint32_t i = 0; i < b.size(); ++i) {
            const glm::vec3 p = b.positions[i];
            const std::uint32_t c = plan.chunk_of(p);
            if (core[c].empty() && halo[c].empty()) touched.push_back(c);
            core[c].push_back(i);
            for (int k = plan.halo_chunks(p, c, near); k-- > 0;) {
              if (core[near[k]].empty() && halo[near[k]].empty()) touched.push_back(near[k]);
              halo[near[k]].push_back(i);
            }
          }
          for (const std::uint32_t c : touched) {
            for (auto [ids, to] :
                 {std::pair{&core[c], &blocks[c].core}, std::pair{&halo[c], &blocks[c].halo}}) {
              if (ids->empty()) continue;
              const std::vector<unsigned char> bytes = pack_points(b, *ids);
              to->push_back({parts.append(bytes.data(), bytes.size()), bytes.size()});
              if (to == &blocks[c].halo) report.halo_points += ids->size();
              ids->clear();
            }
          }
          touched.clear();
          progress("distribute", whole.points, declared.points);
        });
  }
  report.points = out.input_points = whole.points;
  if (whole.points == 0) throw InputError(quoted_name(files.front()) + ": no points");
  out.files = files.size();
  out.read_seconds = seconds_since(t0);
  std::uint64_t& held = report.scratch_bytes;
  held = parts.held();

  // 3. Each chunk's attributes from its points and halo.
  t0 = Clock::now();
  CoordinateFrame frame = whole.first.frame;
  const CloudPart part_of_whole{glm::vec3(whole.sum / double(whole.points)), 0};
  std::optional<ScratchFile> done_file(std::in_place, cache.string() + ".points");
  std::optional<ScratchFile> radii_file(std::in_place, cache.string() + ".radii");
  ScratchFile &done = *done_file, &radii = *radii_file;
  std::uint64_t positive = 0;
  bool from_neighbours = false;
  for (std::size_t c = 0; c < chunks; ++c) {
    PointSet ps = read_blocks(parts, blocks[c].core);
    const std::size_t queried = ps.size();
    ps = read_blocks(parts, blocks[c].halo, std::move(ps));
    report.largest_chunk = std::max<std::uint64_t>(report.largest_chunk, ps.size());
    if (!whole.normals) ps.normals.clear();
    if (!whole.radii) ps.radii.clear();
    if (!whole.curvature) ps.curvature.clear();
    ps.frame = frame;
    CloudPart part = part_of_whole;
    part.queried = queried;
    std::vector<float> reach;
    from_neighbours = complete_part_attributes(ps, options.attributes, part, &reach);
    frame.normals_estimated = frame.normals_estimated || ps.frame.normals_estimated;
    for (std::size_t i = 0; i < queried; ++i)
      report.short_neighbours +=
          !plan.covers(static_cast<std::uint32_t>(c), ps.positions[i], reach[i]);
    keep_first(ps, queried);
    std::vector<float> kept;
    for (const float r : ps.radii)
      if (r > 0.0f && std::isfinite(r)) kept.push_back(r);
    radii.append(kept.data(), kept.size() * sizeof(float));
    positive += kept.size();
    std::vector<float>().swap(reach);
    blocks[c].done = append_slices(done, ps);
    held = std::max(held, parts.held() + done.held() + radii.held());
    release(parts, blocks[c].core), release(parts, blocks[c].halo);
    progress("attributes", c + 1, chunks);
  }
  parts_file.reset();
  const float median = median_of(radii, positive);
  radii_file.reset();
  out.attribute_seconds = seconds_since(t0);

  // 4. Each chunk built and written as pages.
  t0 = Clock::now();
  const std::vector<NodeAttribute> model = model_attributes(whole);
  ScratchFile pages(cache.string() + ".pages");
  std::vector<ChunkPages> built(chunks);
  std::vector<SubtreeRoot> roots(chunks);
  BuildOptions build = options.build;
  build.progress = nullptr;
  for (std::size_t c = 0; c < chunks; ++c) {
    PointSet ps = read_blocks(done, blocks[c].done);
    release(done, blocks[c].done);
    if (c + 1 == chunks) done_file.reset();
    ps.frame = frame;
    finish_part_radii(ps.radii, median, from_neighbours);
    double cover2 = 0.0;
    for (const float r : ps.radii) cover2 += double(r) * double(r);
    match_fields(ps, model);
    const Hierarchy h = build_hierarchy(std::move(ps), build);
    to_model_offsets(h, model);
    cache_pages::Encoded e = cache_pages::encode(h);
    ChunkPages& cp = built[c];
    for (std::size_t q = 0; q < e.table.size(); ++q) {
      PageRecord r = e.table[q];
      r.offset = pages.append(e.pages[q].data(), e.pages[q].size());
      cp.table.push_back(r);
    }
    cp.levels = static_cast<std::uint32_t>(h.level_count());
    cp.nodes = h.node_count();
    SubtreeRoot& root = roots[c];
    root.center_radius = glm::vec4(e.root.center, e.root.radius);
    root.cover = static_cast<float>(std::sqrt(cover2));
    root.normal_cone = h.arrays().normal_cone[0];
    root.color = h.arrays().color[0];
    root.priority = h.arrays().priority[0];
    root.point_count = h.leaf_count();
    for (const NodeAttribute& a : h.attributes()) root.values.push_back(a.value(0));
    held = std::max(held, done.held() + pages.held());
    progress("hierarchy", c + 1, chunks);
  }

  // 5. The levels over the chunks, and the file: the top's pages (a
  // chunk's first page where the top has its root), then the chunks' other
  // pages, chunk after chunk.
  std::vector<PageRecord> table;
  struct Source {
    const std::vector<unsigned char>* memory;
    std::uint64_t offset;
  };
  std::vector<Source> sources;
  std::vector<std::uint32_t> first_page(chunks), depth(chunks, 0);
  cache_pages::Encoded top_pages;
  std::uint32_t levels = 0;
  std::uint64_t nodes = 0;
  if (chunks == 1) {
    first_page[0] = 0;
    table.push_back(built[0].table[0]);
    sources.push_back({nullptr, built[0].table[0].offset});
  } else {
    const TopLevels top = build_over_roots(roots, model, frame, options.build.parent_at_real_point);
    const Hierarchy& t = top.hierarchy;
    std::vector<cache_pages::Root> leaf_roots(t.node_count());
    for (NodeId i = 0; i < t.node_count(); ++i)
      if (top.root_of[i] != kNoNode) {
        const glm::vec4 s = roots[top.root_of[i]].center_radius;
        leaf_roots[i] = {glm::vec3(s), s.w};
        depth[top.root_of[i]] = t.arrays().depth[i];
      }
    top_pages = cache_pages::encode_over(t, leaf_roots);
    for (std::size_t q = 0; q < top_pages.table.size(); ++q) {
      const NodeId root = top_pages.roots[q];
      if (top.root_of[root] == kNoNode) {
        table.push_back(top_pages.table[q]);
        sources.push_back({&top_pages.pages[q], 0});
        continue;
      }
      const std::uint32_t c = top.root_of[root];
      PageRecord r = built[c].table[0];
      sources.push_back({nullptr, r.offset});
      r.parent_page = top_pages.table[q].parent_page;
      r.parent_local = top_pages.table[q].parent_local;
      r.root_depth = depth[c];
      first_page[c] = static_cast<std::uint32_t>(table.size());
      table.push_back(r);
    }
    levels = static_cast<std::uint32_t>(t.level_count());
    nodes = t.node_count() - chunks;
  }
  for (std::size_t c = 0; c < chunks; ++c) {
    const auto base = static_cast<std::uint32_t>(table.size());
    for (std::size_t q = 1; q < built[c].table.size(); ++q) {
      PageRecord r = built[c].table[q];
      sources.push_back({nullptr, r.offset});
      r.parent_page = r.parent_page == 0 ? first_page[c] : base + r.parent_page - 1;
      r.root_depth += depth[c];
      table.push_back(r);
    }
    levels = std::max(levels, depth[c] + built[c].levels);
    nodes += built[c].nodes;
  }
  report.nodes = nodes;
  for (const NodeAttribute& a : model) report.value_streams += !a.is_constant();
  if (levels > 256)
    throw std::runtime_error(quoted_name(cache) + ": the model's hierarchy is " +
                             std::to_string(levels) + " levels deep; a cache holds 256");
  out.build_seconds = seconds_since(t0);

  t0 = Clock::now();
  progress("cache", 0, 1);
  notes.format = format_text(out);
  const CacheMeta meta{key, frame, whole.lo, whole.hi, nodes, whole.points, levels, model, notes};
  const std::vector<unsigned char> bytes = cache_meta(meta, table);
  if (cache.has_parent_path()) {
    std::error_code ec;
    std::filesystem::create_directories(cache.parent_path(), ec);
    if (ec) throw std::runtime_error(system_error_text(cache.parent_path(), ec.value()));
  }
  AtomicFile file(cache);
  file.write(bytes.data(), bytes.size());
  std::vector<unsigned char> page;
  for (std::size_t q = 0; q < table.size(); ++q) {
    if (sources[q].memory) {
      file.write(sources[q].memory->data(), sources[q].memory->size());
      continue;
    }
    page.resize(table[q].bytes);
    pages.read(sources[q].offset, page.data(), page.size());
    file.write(page.data(), page.size());
  }
  const std::array<unsigned char, 8> sum = meta_checksum(bytes);
  file.write(sum.data(), sum.size());
  file.commit();
  out.cache_seconds = seconds_since(t0);
  return report;
}

}  // namespace treecut::detail
