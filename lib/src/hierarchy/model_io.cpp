#include "treecut/model_io.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <mutex>
#include <optional>
#include <stdexcept>

#include "cache_format.hpp"
#include "chunk_sources.hpp"
#include "chunked_build.hpp"
#include "model_read.hpp"
#include "reproject.hpp"
#include "treecut/cache_folder.hpp"
#include "treecut/error.hpp"
#include "treecut/file_io.hpp"

namespace treecut {

namespace {

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

std::uint64_t fnv1a(const std::string& s) {
  std::uint64_t h = 0xcbf29ce484222325ull;
  for (unsigned char c : s) h = (h ^ c) * 0x100000001b3ull;
  return h;
}

// DIR/NAME-HASH.tch, NAME cut so that the cache's name (and its
// temporary's) stays within NAME_MAX.
std::filesystem::path cache_named(const std::filesystem::path& dir, const std::string& name,
                                  const std::string& identity) {
  char hex[17];
  std::snprintf(hex, sizeof hex, "%016llx", static_cast<unsigned long long>(fnv1a(identity)));
  return dir / (name.substr(0, 180) + "-" + hex + ".tch");
}

}  // namespace

std::filesystem::path default_cache_path(const std::filesystem::path& model) {
  const std::filesystem::path dir = default_cache_folder();
  if (dir.empty()) return {};
  std::error_code ec;
  const auto abs = std::filesystem::weakly_canonical(model, ec);
  // The hash names the model; its file name is for people ("tiles/" names
  // its folder).
  const std::filesystem::path& named = ec ? model : abs;
  const std::string name =
      model.filename().empty() ? named.filename().string() : model.filename().string();
  return cache_named(dir, name, named.string());
}

std::filesystem::path default_cache_path(const std::vector<std::filesystem::path>& files) {
  if (files.size() == 1) return default_cache_path(files.front());
  const std::filesystem::path dir = default_cache_folder();
  if (dir.empty() || files.empty()) return {};
  std::string identity;
  for (const std::filesystem::path& f : files) {
    std::error_code ec;
    const auto abs = std::filesystem::weakly_canonical(f, ec);
    identity += (ec ? f : abs).string() + '\n';
  }
  return cache_named(dir,
                     files.front().filename().string().substr(0, 160) + "-and-" +
                         std::to_string(files.size() - 1) + "-more",
                     identity);
}

// Revision of what the pipeline computes (attributes and build). Bump it when
// their output changes, so that caches written by an older build are stale.
// 3: caches are keyed on the model's content hash.
// 4: radii from the neighbours are capped at 4 times the median (issue 30).
// 5: radii along lines from the density along them, interior covers summed
//    in double (issue 43).
// 6: a point's neighbours are its k nearest within a reach of the model's
//    spacing (NeighbourReach; issue 44), ties by position.
// 7: children of whole groups of four points (1.33 nodes a point).
constexpr std::uint32_t kPipelineRevision = 7;

std::uint32_t options_bits(const AttributeOptions& attributes, const BuildOptions& build,
                           const std::vector<std::string>& columns, const std::string& crs) {
  std::uint32_t mapping = 0;
  if (!columns.empty() || !crs.empty()) {
    std::uint64_t h = 0x9e3779b97f4a7c15ull;  // FNV-style over the names and separators
    for (const std::string& c : columns) {
      for (const char ch : c + '\0') h = (h ^ static_cast<unsigned char>(ch)) * 0x100000001b3ull;
    }
    for (const char ch : "\x01" + crs) h = (h ^ static_cast<unsigned char>(ch)) * 0x100000001b3ull;
    h ^= h >> 29;
    mapping = static_cast<std::uint32_t>(h % 131071u) + 1u;  // never 0: "no mapping"
  }
  return (build.parent_at_real_point ? 1u : 0u) | (attributes.recompute_normals ? 2u : 0u) |
         (attributes.recompute_radii ? 4u : 0u) | ((mapping & 31u) << 3) |
         (static_cast<std::uint32_t>(std::clamp(attributes.k, 0, 255)) << 8) |
         (kPipelineRevision << 16) | ((mapping >> 5) << 20);
}

Hierarchy build_from_points(PointSet points, const AttributeOptions& attributes,
                            const BuildOptions& build) {
  complete_attributes(points, attributes);
  return build_hierarchy(std::move(points), build);
}

namespace {

// Fails before a long build when the cache could not be written anyway: the
// folder is created and a temporary made and removed in it (a read-only
// folder, XDG_CACHE_HOME naming a file, a directory or FIFO at the path).
void probe_cache_destination(const std::filesystem::path& cache) {
  detail::create_cache_folder(cache);
  AtomicFile probe(cache);  // never committed: the destructor removes it
}

bool same_identity(const CacheKey& a, const CacheKey& b) {
  return a.source_device == b.source_device && a.source_inode == b.source_inode &&
         a.source_size == b.source_size && a.source_mtime_ns == b.source_mtime_ns &&
         a.source_ctime_ns == b.source_ctime_ns;
}

void report_stage(const OpenOptions& options, std::string_view name) {
  if (options.progress) options.progress(name, 0, 1);
}

// MODEL is a treecut cache: loaded as it is.
OpenedModel open_cache_file(const std::filesystem::path& model) {
  OpenedModel out;
  std::string why;
  auto t0 = std::chrono::steady_clock::now();
  auto h = load_cache(model, std::nullopt, &why);
  if (!h) throw InputError(quoted_name(model) + ": " + why);
  out.hierarchy = std::move(*h);
  out.cache = model;
  out.from_cache = true;
  out.cache_seconds = seconds_since(t0);
  return out;
}

// Why `cache` cannot be the model's cache (empty: it can): none at all, or
// the model itself (an error when the caller named it).
std::string cache_problem(std::span<const std::filesystem::path> files,
                          const std::filesystem::path& cache, const OpenOptions& options) {
  if (cache.empty()) {
    return "no cache folder (HOME and XDG_CACHE_HOME are unset and there is no usable temporary "
           "folder)";
  }
  for (const std::filesystem::path& model : files) {
    if (!same_file(cache, model)) continue;
    std::string no_cache = quoted_name(cache) + ": is the model itself (" + quoted_name(model) +
                           "); refusing to write a cache over it";
    if (options.cache_path) throw InputError(no_cache);
    return no_cache;
  }
  return {};
}

CacheKey hash_model(std::span<const std::filesystem::path> files, std::uint32_t bits,
                    OpenedModel& out) {
  const auto t0 = std::chrono::steady_clock::now();
  CacheKey k = cache_key_for(files, bits);
  out.hash_seconds = seconds_since(t0);
  out.hashed = true;
  return k;
}

// Positions are floats relative to the model's origin (point_set.hpp): a
// float's spacing is at most 2^-9 within 32,768 units, so rounding stays
// under 1 mm there (half the spacing) and a model up to 65 km across (LAS:
// the origin at its bounds' centre) keeps millimetres at any map
// coordinate; the renderer draws relative to the eye (shaders.hpp), so that
// is what the screen shows. Past that the spacing grows (7.8 mm at 100 km):
// said once, with the figure.
std::string float_precision_warning(const PointSet& points) {
  float reach = 0.0f;
  for (const glm::vec3& p : points.positions) {
    reach = std::max({reach, std::fabs(p.x), std::fabs(p.y), std::fabs(p.z)});
  }
  if (!(reach >= 32768.0f)) return {};
  const float spacing = std::nextafter(reach, INFINITY) - reach;
  char line[200];
  std::snprintf(line, sizeof line,
                "points lie up to %.0f units from the model's origin: as floats their spacing "
                "there is %.3g units (rounding under 1/1000 within 32768 units)",
                double(reach), double(spacing));
  return line;
}

// The neighbour search's reach over the box the files declare, as a build
// in chunks takes it (chunked_build.hpp): a point has the same neighbours
// either way. 0 (over the points' own box) for files that declare none or
// points reprojected since (IN_FILE_FRAME false).
float neighbour_reach(std::span<const std::filesystem::path> files, const PointSet& points,
                      bool in_file_frame, int k) {
  const auto box = in_file_frame ? detail::declared_box(files) : std::nullopt;
  if (!box) return 0.0f;
  NeighbourReach reach(box->first, box->second);
  reach.count(points.positions);
  return reach.reach(std::max(3, k));
}

// Read, attributes, hierarchy: the model built into `out`, each stage timed,
// in pages as its cache holds it (the image returned, to be saved): a model
// is the same opened cold or warm. The read's warnings go out as they come
// and into the hierarchy's notes (cached: a warm open says them again).
CacheImage read_and_build(std::span<const std::filesystem::path> files, std::uint32_t bits,
                          const CacheKey& key, const OpenOptions& given, OpenedModel& out) {
  // One file names itself; a cloud of many, the folder of its first.
  const std::filesystem::path& model =
      files.size() == 1 ? files.front() : files.front().parent_path();
  SourceNotes notes;
  OpenOptions options = given;
  options.warn = [&](const std::string& w) {
    notes.warnings.push_back(w);
    if (given.warn) given.warn(w);
  };
  report_stage(options, "read");
  auto t0 = std::chrono::steady_clock::now();
  // The key (and the cache it names) is for the bytes hashed before the
  // read: a model replaced or edited meanwhile (`cp new.ply model.ply` during
  // a load) would give a hierarchy of one content under the key of another,
  // or a parse error about bytes the user never wrote.
  const auto changed = [&] { return !same_identity(cache_identity_of(files, bits), key); };
  const auto changed_error = [&] {
    return FileChangedError(quoted_name(model) +
                            (files.size() == 1
                                 ? ": changed while being read (its size, times or inode moved)"
                                 : ": a file of the model changed while being read"));
  };
  PointSet points;
  try {
    points = files.size() == 1 ? detail::read_point_file(model, out, options.warn, options.columns)
                               : detail::read_point_files(files, out, options.warn, options.columns,
                                                          options.progress);
    out.files = files.size();
  } catch (const InputError&) {
    if (changed()) throw changed_error();
    throw;
  }
  out.read_seconds = seconds_since(t0);
  if (changed()) throw changed_error();
  out.input_points = points.size();
  const std::string moved = detail::reproject(points, options.crs, quoted_name(model));
  if (!moved.empty() && options.warn)
    options.warn(quoted_name(model) + ": reprojected to " + moved);
  std::vector<glm::dvec3>().swap(points.exact_positions);  // an export's; the hierarchy is floats
  if (options.warn) {
    if (const std::string w = float_precision_warning(points); !w.empty()) options.warn(w);
  }
  report_stage(options, "attributes");
  t0 = std::chrono::steady_clock::now();
  complete_attributes(points, options.attributes,
                      neighbour_reach(files, points, moved.empty(), options.attributes.k));
  out.attribute_seconds = seconds_since(t0);
  report_stage(options, "hierarchy");
  BuildOptions build = options.build;
  if (options.progress)
    build.progress = [&](std::size_t done, std::size_t total) {
      if (options.build.progress) options.build.progress(done, total);
      options.progress("hierarchy", done, total);
    };
  t0 = std::chrono::steady_clock::now();
  notes.format = detail::format_text(out);
  CacheImage image(build_hierarchy(std::move(points), build).with_notes(std::move(notes)), key);
  out.hierarchy = image.hierarchy();
  out.build_seconds = seconds_since(t0);
  return image;
}

// The built hierarchy saved as the model's cache; failing to is an error
// only when the cache is required, else a note and a warning.
// The default folder stays under its limit (cache_size_limit): after a
// write, the least recently used caches go, never the one just written.
// Said in one warning; a failure to list or remove is one too, never an
// error (the model is open).
void hold_cache_limit(const std::filesystem::path& written, const WarningSink& warn) {
  try {
    const std::uint64_t limit = cache_size_limit();
    const std::vector<CacheFileInfo> all = list_caches(written.parent_path());
    const std::vector<CacheFileInfo> old = caches_over_limit(all, limit, written);
    if (old.empty()) return;
    const std::vector<std::string> failed = remove_caches(old);
    std::uint64_t bytes = 0;
    for (const CacheFileInfo& c : old) bytes += c.bytes;
    if (warn) {
      char line[160];
      std::snprintf(line, sizeof line,
                    ": removed %zu least recently used cache(s), %.1f MB, to stay under %.1f MB "
                    "(TREECUT_CACHE_LIMIT)",
                    old.size() - failed.size(), double(bytes) / 1e6, double(limit) / 1e6);
      warn(quoted_name(written.parent_path()) + line);
      for (const std::string& f : failed) warn(f);
    }
  } catch (const std::exception& e) {
    if (warn) warn(e.what());
  }
}

void write_model_cache(const CacheImage& image, const OpenOptions& options, OpenedModel& out) {
  report_stage(options, "cache");
  const auto t0 = std::chrono::steady_clock::now();
  // The default cache folder is treecut's own: what killed writers left
  // there (a cache's temporary of hundreds of MB after a kill -9) goes,
  // whichever model it was for. Elsewhere only the target's own
  // temporaries are removed (AtomicFile).
  if (!options.cache_path) {
    static std::once_flag swept;
    std::call_once(swept, [&] { remove_stale_temporaries(out.cache.parent_path(), ".tch"); });
  }
  try {
    image.save(out.cache);
    out.cache_written = true;
  } catch (const std::exception& e) {
    if (options.require_cache) throw;
    // A read-only cache folder must not stop anyone from viewing a model.
    out.cache_note = e.what();
    if (options.warn) options.warn(std::string(e.what()) + " (continuing without a cache)");
  }
  if (out.cache_written && !options.cache_path) hold_cache_limit(out.cache, options.warn);
  out.cache_seconds += seconds_since(t0);
}

// The least memory a chunked build runs in beside the program: its grid,
// a batch of points and a chunk of some thousands.
constexpr std::uint64_t kLeastChunkedRoom = std::uint64_t{8} << 20;
// What the program holds before a build (the command-line tool: 16-17 MiB).
constexpr std::uint64_t kProgramBytes = std::uint64_t{17} << 20;

// A model past BUDGET built in chunks straight into its cache, then
// loaded from it when its hierarchy fits the budget (the nodes' arrays).
void build_in_chunks(std::span<const std::filesystem::path> files, const CacheKey& key,
                     std::uint64_t budget, const OpenOptions& given, OpenedModel& out) {
  const std::string name =
      quoted_name(files.size() == 1 ? files.front() : files.front().parent_path());
  // The budget bounds the process: what it holds already is not the build's.
  // Sized by the program's usual size when it holds less (and in steps of
  // 1 MiB), so that the chunks, and the cache, are the same from one run to
  // the next.
  const std::uint64_t resident = detail::resident_bytes();
  const std::uint64_t held = std::max(resident, kProgramBytes);
  const std::uint64_t room = budget > held ? (budget - held) / (1u << 20) * (1u << 20) : 0;
  if (room < kLeastChunkedRoom) {
    char line[240];
    std::snprintf(line, sizeof line,
                  ": --memory allows %.1f MiB, of which the program holds %.1f MiB; a build in "
                  "chunks needs %.0f MiB beside it",
                  double(budget) / double(1u << 20), double(resident) / double(1u << 20),
                  double(kLeastChunkedRoom) / double(1u << 20));
    throw std::runtime_error(name + line);
  }
  SourceNotes notes;
  OpenOptions options = given;
  options.warn = [&](const std::string& w) {
    notes.warnings.push_back(w);
    if (given.warn) given.warn(w);
  };
  if (!options.crs.empty())
    throw InputError(name +
                     ": --crs reprojects a model built held in memory; this one needs more "
                     "than --memory allows");
  // The model read meanwhile changed: its cache would be of other bytes
  // than its key says (checked before anything is at the cache's name).
  const auto changed = [&] {
    return !same_identity(cache_identity_of(files, key.options_bits), key);
  };
  const auto after_read = [&] {
    if (changed()) throw FileChangedError(name + ": a file of the model changed while being read");
  };
  detail::ChunkedBuildReport r;
  try {
    r = detail::build_chunked(files, options, key, out.cache, room, after_read, notes, out);
  } catch (const InputError&) {
    if (changed()) throw FileChangedError(name + ": a file of the model changed while being read");
    throw;
  }
  out.cache_written = true;
  out.chunked.chunks = r.chunks;
  out.chunked.lanes = r.lanes;
  out.chunked.largest_chunk = r.largest_chunk;
  out.chunked.halo_points = r.halo_points;
  out.chunked.halo = r.halo;
  out.chunked.scratch_bytes = r.scratch_bytes;
  out.chunked.budget = budget;
  out.chunked.nodes = r.nodes;
  const auto t0 = std::chrono::steady_clock::now();
  // Loaded for a caller that draws it, and otherwise when its arrays fit
  // the budget (Hierarchy::memory_bytes: 45 bytes a node and 4 an
  // attribute's value; with the decoder's own, half as much again).
  if (given.need_hierarchy ||
      (r.nodes * (45 + 4 * r.value_streams) * 3 / 2 <= room && r.nodes < kNoNode)) {
    std::string why;
    if (auto h = load_cache(out.cache, std::nullopt, &why))
      out.hierarchy = std::move(*h);
    else
      throw std::runtime_error(quoted_name(out.cache) + ": " + why);
  }
  out.cache_seconds += seconds_since(t0);
  if (!given.cache_path) hold_cache_limit(out.cache, given.warn);
}

// The cached open of a model made of FILES (one, or a cloud's tiles), its
// default cache DEFAULT_CACHE.
OpenedModel open_sources(std::span<const std::filesystem::path> files,
                         const std::filesystem::path& default_cache, const OpenOptions& options) {
  OpenedModel out;
  const std::uint32_t bits =
      options_bits(options.attributes, options.build, options.columns, options.crs);
  out.cache = options.cache_path ? *options.cache_path : default_cache;
  // A cache that cannot be: named by the caller, an error; the default one,
  // a warning, and the model opens without it.
  const std::string no_cache = cache_problem(files, out.cache, options);
  const bool use_cache = options.use_cache && no_cache.empty();
  if (options.use_cache && !no_cache.empty()) {
    if (options.require_cache) throw std::runtime_error(no_cache);
    out.cache_note = no_cache;
    if (options.warn) options.warn(no_cache + " (continuing without a cache)");
  }
  const FileKind kind = use_cache ? file_kind(out.cache) : FileKind::Missing;
  std::optional<CacheKey> key;
  bool write_cache = use_cache;
  if (kind != FileKind::Missing && kind != FileKind::Regular) {
    const std::string what =
        quoted_name(out.cache) + ": is " + std::string(describe(kind)) + ", not a cache file";
    if (options.require_cache) throw std::runtime_error(what);
    out.cache_note = what;
    if (options.warn) options.warn(what + " (continuing without a cache)");
    write_cache = false;
  }
  if (use_cache && kind == FileKind::Regular && !options.rebuild) {
    // The cache module decides (cache.hpp): the model's identity when it is
    // unchanged and settled, its content hash otherwise.
    CacheLookup found = lookup_cache(files, out.cache, bits, write_cache);
    out.hashed = found.hashed;
    out.hash_seconds = found.hash_seconds;
    out.cache_seconds += found.cache_seconds;
    out.cache_refreshed = found.refreshed;
    if (found.hierarchy) {
      out.hierarchy = std::move(*found.hierarchy);
      out.from_cache = true;
      // What the first read said, said again.
      if (options.warn) {
        for (const std::string& w : out.hierarchy.notes().warnings) options.warn(w);
      }
      // Used now: the default folder's eviction goes by it.
      if (!options.cache_path) mark_cache_used(out.cache);
      return out;
    }
    out.cache_note = found.why;
    if (options.warn) options.warn(quoted_name(out.cache) + ": " + out.cache_note + "; rebuilding");
    key = found.key;
  } else {
    key = hash_model(files, bits, out);
  }
  if (write_cache && options.require_cache) probe_cache_destination(out.cache);
  // A model past the memory budget is built in chunks into its cache; one
  // that cannot be (no cache to write) is refused with its figures before
  // it reads, not ended by the kernel's out-of-memory kill, which says
  // nothing.
  const std::uint64_t budget = options.memory ? options.memory : default_build_budget();
  const BuildMemory need = build_memory_estimate(files);
  const std::string name =
      quoted_name(files.size() == 1 ? files.front() : files.front().parent_path());
  // The budget bounds the process: what it holds already counts.
  if (need.bytes + detail::resident_bytes() > budget && write_cache) {
    build_in_chunks(files, *key, budget, options, out);
    return out;
  }
  if (const std::string why = build_memory_problem(name, need, budget, options.memory != 0);
      !why.empty())
    throw std::runtime_error(why);
  const CacheImage image = read_and_build(files, bits, *key, options, out);
  if (write_cache) write_model_cache(image, options, out);
  return out;
}

}  // namespace

PointSet load_point_file(const std::filesystem::path& model, const WarningSink& warn,
                         std::string* format, const std::vector<std::string>& columns) {
  require_regular_file(model);
  OpenedModel opened;
  PointSet points = detail::read_point_file(model, opened, warn, columns);
  if (format) *format = opened.format;
  return points;
}

OpenedModel open_model(const std::filesystem::path& model, const OpenOptions& options) {
  std::error_code ec;
  if (std::filesystem::is_directory(model, ec)) {
    const std::vector<std::filesystem::path> files = point_files_in(model);
    return open_sources(files, default_cache_path(model), options);
  }
  // Checked without opening: a FIFO would block, a directory is "no such file" to ifstream.
  require_regular_file(model);
  if (looks_like_cache(model)) return open_cache_file(model);
  // A .tch that is not a cache is named as such, not as a bad PLY (unless it
  // is a PLY under that name).
  if (model.extension() == ".tch" && !file_starts_with(model, "ply"))
    throw InputError(quoted_name(model) +
                     ": not a treecut cache (it does not start with a cache's signature)");
  return open_sources(std::span(&model, 1), default_cache_path(model), options);
}

OpenedModel open_model(const std::vector<std::filesystem::path>& files,
                       const OpenOptions& options) {
  if (files.size() == 1) return open_model(files.front(), options);
  if (files.empty()) throw InputError("a model of no files");
  for (const std::filesystem::path& f : files) {
    require_regular_file(f);
    if (looks_like_cache(f))
      throw InputError(quoted_name(f) +
                       ": is a treecut cache; a model of several files is made of point files");
  }
  return open_sources(files, default_cache_path(files), options);
}

}  // namespace treecut
