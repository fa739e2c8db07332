// The cache folder as a user sees it (issue 30): which caches it holds, how
// big and how recently used, and its size held under a limit by removing the
// caches used least recently. Only files that are treecut caches (named
// *.tch and starting with a cache's signature) are ever listed or removed:
// nothing else a user keeps there is touched. Any thread.
#pragma once

#include <cstdint>
#include <filesystem>
#include <optional>
#include <span>
#include <string>
#include <vector>

namespace treecut {

/// `${XDG_CACHE_HOME:-$HOME/.cache}/treecut`, the temporary folder's
/// `treecut` without either, or empty without a usable one (where
/// default_cache_path puts caches).
std::filesystem::path default_cache_folder();

struct CacheFileInfo {
  std::filesystem::path file;
  std::string model;  ///< the model's file name, as the cache's name keeps it
  std::uint64_t bytes = 0;
  /// Written, or last opened through open_model (which marks it): what
  /// least-recently-used eviction orders by.
  std::filesystem::file_time_type last_used{};
};

/// The caches in FOLDER, most recently used first; none when it is missing.
/// Throws std::runtime_error "FOLDER: REASON" when it cannot be read.
std::vector<CacheFileInfo> list_caches(const std::filesystem::path& folder);

/// Marks CACHE used now (its modification time; best effort: a read-only
/// folder only loses the order).
void mark_cache_used(const std::filesystem::path& cache) noexcept;

/// The caches of CACHES (most recently used first, as list_caches gives
/// them) to remove so that the rest hold at most MAX_BYTES: the least
/// recently used ones, never KEEP (the cache just written).
std::vector<CacheFileInfo> caches_over_limit(std::span<const CacheFileInfo> caches,
                                             std::uint64_t max_bytes,
                                             const std::filesystem::path& keep = {});

/// Removes each (only if it still looks like a cache); returns a line
/// "FILE: REASON" per one that could not be removed.
std::vector<std::string> remove_caches(std::span<const CacheFileInfo> caches);

/// The default folder's limit: TREECUT_CACHE_LIMIT (bytes, or with a K, M,
/// G or T suffix; 0 for none), else 20 GiB. Throws InputError naming the
/// variable for a value that is not a size.
std::uint64_t cache_size_limit();

/// "1.5G", "200M", "4096": a size in bytes; nullopt when TEXT is none.
std::optional<std::uint64_t> parse_byte_size(const std::string& text);

}  // namespace treecut
