// On-disk hierarchy cache: versioned, checksummed, memory-mapped on load.
//
// Layout: a fixed header (magic, format version, endianness tag, counts, the
// source file's size and modification time, the build options, per-array
// offsets) followed by the node arrays, each 64-byte aligned, and a 64-bit
// checksum over header and payload. Written to a temporary file and renamed,
// so a crash mid-write never leaves a cache that loads.
#pragma once

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>

#include "treecut/hierarchy.hpp"

namespace treecut {

/// What a cache was built from; a cache is stale when this differs.
struct CacheKey {
  std::uint64_t source_size = 0;
  std::int64_t source_mtime_ns = 0;
  std::uint32_t options_bits = 0;  ///< BuildOptions/AttributeOptions that change the output
};

CacheKey cache_key_for(const std::filesystem::path& source, std::uint32_t options_bits);

/// Writes atomically (temporary + rename). Throws std::runtime_error on I/O failure.
void save_cache(const Hierarchy& h, const CacheKey& key, const std::filesystem::path& cache);

/// Maps and verifies a cache. Returns nullopt and sets *why when the file is
/// missing, truncated, corrupted, of another version, or (when `expected` is
/// given) stale. Never crashes on any byte content.
std::optional<Hierarchy> load_cache(const std::filesystem::path& cache,
                                    const std::optional<CacheKey>& expected, std::string* why);

/// Reads the key stored in a cache header (for `treecut info CACHE`), after full verification.
std::optional<CacheKey> read_cache_key(const std::filesystem::path& cache, std::string* why);

}  // namespace treecut
