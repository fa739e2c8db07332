// From a model file to a ready Hierarchy: PLY import, attributes, build, and
// the on-disk cache in front of them. What `treecut build`, `treecut view` and
// the benchmarks call.
#pragma once

#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <string_view>

#include "treecut/attributes.hpp"
#include "treecut/cache.hpp"
#include "treecut/hierarchy.hpp"
#include "treecut/ply.hpp"

namespace treecut {

struct OpenOptions {
  AttributeOptions attributes;
  BuildOptions build;
  bool use_cache = true;                            ///< read a valid cache, write one after a build
  std::optional<std::filesystem::path> cache_path;  ///< default: default_cache_path(model)
  WarningSink warn;                                 ///< PLY warnings and cache notes (may be empty)
  /// Called on the calling thread with the stage ("read", "attributes",
  /// "hierarchy", "cache") and (done, total) work units within it; may be empty.
  std::function<void(std::string_view stage, std::size_t done, std::size_t total)> progress;
};

struct OpenedModel {
  Hierarchy hierarchy;
  std::filesystem::path cache;  ///< where the cache is (or would be)
  bool from_cache = false;
  std::string cache_note;        ///< why a cache was not used, if one existed
  PlyLoadReport ply;             ///< when built
  std::size_t input_points = 0;  ///< points after dropping non-finite ones
  double read_seconds = 0, attribute_seconds = 0, build_seconds = 0, cache_seconds = 0;
  [[nodiscard]] double total_seconds() const {
    return read_seconds + attribute_seconds + build_seconds + cache_seconds;
  }
};

/// `${XDG_CACHE_HOME:-$HOME/.cache}/treecut/<file name>-<hash of the absolute path>.tch`.
std::filesystem::path default_cache_path(const std::filesystem::path& model);

/// The bits of the options that change a built hierarchy (part of the cache key).
std::uint32_t options_bits(const AttributeOptions& attributes, const BuildOptions& build);

/// Opens a model: a cache file (.tch) directly, or a PLY through its cache,
/// rebuilding (and rewriting the cache) when it is missing, stale or corrupt.
/// Throws InputError for a malformed model file.
OpenedModel open_model(const std::filesystem::path& model, const OpenOptions& options = {});

/// Builds from points already in memory (generated models, benchmarks).
Hierarchy build_from_points(PointSet points, const AttributeOptions& attributes = {},
                            const BuildOptions& build = {});

}  // namespace treecut
