// From a model file to a ready Hierarchy: PLY or LAS import (chosen by the
// file's first bytes, not its name), attributes, build, and
// the on-disk cache in front of them. What `treecut build`, `treecut view` and
// the benchmarks call.
#pragma once

#include <filesystem>
#include <functional>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "treecut/attributes.hpp"
#include "treecut/cache.hpp"
#include "treecut/hierarchy.hpp"
#include "treecut/las.hpp"
#include "treecut/ply.hpp"

namespace treecut {

struct OpenOptions {
  AttributeOptions attributes;
  BuildOptions build;
  bool use_cache = true;  ///< read a valid cache, write one after a build
  /// Ignore a valid cache and rebuild (`build -f`); the old cache stays in
  /// place until the new one replaces it atomically.
  bool rebuild = false;
  /// The cache must be written (`build`): a cache that cannot be written is a
  /// std::runtime_error "PATH: REASON", checked before the build where it can
  /// be. Otherwise the model opens without it, with one warning.
  bool require_cache = false;
  std::optional<std::filesystem::path> cache_path;  ///< default: default_cache_path(model)
  /// A text cloud's columns, in order (load_text_cloud; `--columns`):
  /// empty for the file's own header or count rule. Part of the cache key;
  /// given for another format, an InputError.
  std::vector<std::string> columns;
  /// The coordinate system to draw in (`--crs`: "EPSG:32633", a WKT or a
  /// PROJ string): a file that names its own is reprojected to it. Empty:
  /// geographic input (longitude, latitude) goes to the UTM zone of its
  /// centre, any other stays as it is. Part of the cache key.
  std::string crs;
  /// The bytes a build may use (`--memory`); 0: default_build_budget().
  /// A model that needs more (build_memory_estimate) is built in chunks into
  /// its cache (a point cloud with a cache to write), else refused before
  /// it reads.
  std::uint64_t memory = 0;
  /// Whether the caller draws or inspects the hierarchy (true): a model
  /// built in chunks is then loaded from its cache whatever its size;
  /// `build` (false) loads it only when it fits the budget.
  bool need_hierarchy = true;
  WarningSink warn;  ///< PLY warnings and cache notes (may be empty)
  /// Called on the calling thread with the stage ("read", "attributes",
  /// "hierarchy", "cache") and (done, total) work units within it; may be empty.
  std::function<void(std::string_view stage, std::size_t done, std::size_t total)> progress;
};

/// How a build in chunks went (issue 44; chunks 0: the model was built
/// held in memory).
struct ChunkedBuildFigures {
  std::size_t chunks = 0;
  unsigned lanes = 0;               ///< chunks built at once (each with half the budget where 2)
  std::uint64_t largest_chunk = 0;  ///< points, halo included
  std::uint64_t halo_points = 0;    ///< copies of points in other chunks' halos
  /// The halo's width, model units: the reach of the neighbour search
  /// (NeighbourReach), so that every point has all its neighbours.
  float halo = 0.0f;
  std::uint64_t scratch_bytes = 0;  ///< the most temporary disk held at once
  std::uint64_t budget = 0;         ///< the memory it was built within
  std::uint64_t nodes = 0;          ///< of the hierarchy written
};

struct OpenedModel {
  /// Empty after a chunked build whose hierarchy is larger than the memory
  /// budget (the cache is written; drawing it needs paged drawing, issue 45).
  Hierarchy hierarchy;
  ChunkedBuildFigures chunked;
  std::filesystem::path cache;  ///< where the cache is (or would be)
  bool from_cache = false;
  bool cache_written = false;    ///< a cache was written after the build
  std::string cache_note;        ///< why a cache was not used, if one existed
  std::string format;            ///< "PLY" or "LAS" when built (empty from a cache)
  PlyLoadReport ply;             ///< when built from a PLY
  LasLoadReport las;             ///< when built from a LAS
  std::size_t input_points = 0;  ///< points after dropping non-finite ones
  std::size_t files = 1;         ///< the point files of the model (a folder's, a list)
  double read_seconds = 0, attribute_seconds = 0, build_seconds = 0, cache_seconds = 0;
  double hash_seconds = 0;  ///< the model's content hash (the cache key)
  /// The model's content was read and hashed: always when built, and on a
  /// cached open unless its identity decided (cache.hpp, the settled rule).
  bool hashed = false;
  /// A cache served after hashing was rewritten with the model's settled
  /// identity (so the next open skips the hash).
  bool cache_refreshed = false;
  [[nodiscard]] double total_seconds() const {
    return hash_seconds + read_seconds + attribute_seconds + build_seconds + cache_seconds;
  }
};

/// `${XDG_CACHE_HOME:-$HOME/.cache}/treecut/<file name>-<hash of the absolute path>.tch`.
/// A relative XDG_CACHE_HOME is ignored, as the XDG base-directory rules say;
/// without either, the temporary folder; without a usable one, an empty path
/// (no cache: open_model warns and goes on). The file name is cut to 180
/// bytes (the hash keeps caches apart).
std::filesystem::path default_cache_path(const std::filesystem::path& model);
/// The default cache of a model of several files: named after the first
/// ("a.las-and-11-more"), the hash over all their absolute paths.
std::filesystem::path default_cache_path(const std::vector<std::filesystem::path>& files);

/// The point files of FOLDER, one model (issue 44: a survey's tiles): its
/// regular files (not its subfolders) named .las, .laz, .ply, .pcd, .xyz,
/// .pts, .csv or .txt in any case, in byte order of their names (a .laz is
/// listed so that reading names it). InputError when there is none or the
/// folder cannot be listed.
std::vector<std::filesystem::path> point_files_in(const std::filesystem::path& folder);

/// The bits of the options that change a built hierarchy (part of the cache
/// key); a column mapping and a --crs as a 17-bit hash of their names (bits
/// 3-7, 20-31).
std::uint32_t options_bits(const AttributeOptions& attributes, const BuildOptions& build,
                           const std::vector<std::string>& columns = {},
                           const std::string& crs = {});

/// The peak bytes a point costs a build held in memory, through read,
/// attributes, hierarchy and cache write (`bench build`, 20 M points: 78-82
/// for terrain with one attribute or none, 118 for a survey with RGB and
/// seven varying fields; more below a few million; docs/files.md, "Memory").
inline constexpr std::uint64_t kBuildBytesPerPoint = 110;
/// The same for a LAS file, whose records carry a dozen fields (2 M
/// points of `gen survey`, eleven fields with RGB: 161 with the program).
inline constexpr std::uint64_t kLasBuildBytesPerPoint = 170;
/// The most points one hierarchy holds: its node ids (NodeId) are 32-bit
/// and a model has about 1.5 nodes a point.
inline constexpr std::uint64_t kMaxBuildPoints = 2'000'000'000;

/// What a build of FILES held in memory needs, from their headers alone:
/// the points they declare (LAS, PLY, PCD; a text cloud's by its size over
/// the length of its first lines) times kBuildBytesPerPoint
/// (kLasBuildBytesPerPoint for LAS). A file whose
/// header says nothing usable counts 0 (its reader says what is wrong).
struct BuildMemory {
  std::uint64_t points = 0;
  std::uint64_t bytes = 0;
};
BuildMemory build_memory_estimate(std::span<const std::filesystem::path> files);

/// The bytes this process may still take: /proc/meminfo's MemAvailable, or
/// less under a cgroup's memory.max.
std::uint64_t available_memory();

/// A build's memory when `--memory` says none: a quarter of the machine's
/// memory, or what is available if that is less.
std::uint64_t default_build_budget();

/// Why a build of NEED cannot run (empty: it can): past kMaxBuildPoints, or
/// more than BUDGET bytes (0: unknown, no limit). One line after NAME,
/// with the figures; BUDGET_GIVEN: it came from --memory.
std::string build_memory_problem(const std::string& name, const BuildMemory& need,
                                 std::uint64_t budget, bool budget_given);

/// Opens a model: a cache file (.tch) directly, or a PLY through its cache,
/// rebuilding (and rewriting the cache) when it is missing, stale or corrupt.
/// A cache is served only for the content it was built from (size and an
/// XXH3 hash of the model's bytes); the hash is skipped when the model's
/// identity is unchanged and settled (lookup_cache, cache.hpp). Throws InputError for a malformed
/// model file, a model that is not a regular file ("is a FIFO", never blocking) and a cache path
/// that names the model itself.
OpenedModel open_model(const std::filesystem::path& model, const OpenOptions& options = {});

/// Many files are one model (issue 44): a folder (MODEL above; its
/// point_files_in) or FILES in order, read one after another into one cloud
/// (PointSet::append) and cached as one, keyed on all of them
/// (cache_key_for of several files). Their coordinate systems must be the
/// same: another is an InputError naming both files. One file: open_model
/// of it.
OpenedModel open_model(const std::vector<std::filesystem::path>& files,
                       const OpenOptions& options = {});

/// The points of a model file as open_model reads them, chosen by its first
/// bytes (PLY, LAS, PCD or a text cloud), before attributes and build:
/// what `treecut export` converts. *FORMAT (if given) gets "PLY", "LAS",
/// "PCD" or "text". Throws InputError for a malformed file.
PointSet load_point_file(const std::filesystem::path& model, const WarningSink& warn = {},
                         std::string* format = nullptr,
                         const std::vector<std::string>& columns = {});

/// Builds from points already in memory (generated models, benchmarks).
Hierarchy build_from_points(PointSet points, const AttributeOptions& attributes = {},
                            const BuildOptions& build = {});

}  // namespace treecut
