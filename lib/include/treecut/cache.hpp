// On-disk hierarchy cache: versioned, checksummed, memory-mapped on load.
//
// Layout: a fixed header (magic, format version, endianness tag, counts, the
// source file's size, modification time and content hash, the build options,
// per-array offsets) followed by the node arrays, each 64-byte aligned, and a
// 64-bit checksum over header and payload. Written through an AtomicFile
// (temporary + rename, every write checked), so a crash or a full disk never
// leaves a cache that loads.
#pragma once

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>

#include "treecut/hierarchy.hpp"

namespace treecut {

/// What a cache was built from. A cache is stale when the size, the options
/// or the content hash differ; the modification time is recorded (for `info`)
/// but does not decide: a file edited in place with its mtime restored has
/// another hash, and a file only touched keeps its cache.
struct CacheKey {
  std::uint64_t source_size = 0;
  std::int64_t source_mtime_ns = 0;
  std::uint32_t options_bits = 0;  ///< BuildOptions/AttributeOptions that change the output
  std::uint64_t content_hash = 0;  ///< XXH3-64 of the source file's bytes
};

/// Size, mtime and content hash of SOURCE (read through a mapping, never
/// blocking: a FIFO or directory is an InputError naming what it is).
CacheKey cache_key_for(const std::filesystem::path& source, std::uint32_t options_bits);

/// XXH3-64 of a whole regular file (what CacheKey::content_hash holds).
std::uint64_t content_hash_of(const std::filesystem::path& source);

/// Whether PATH is a regular file that starts like a treecut cache (magic
/// bytes only; load_cache verifies the rest). Never blocks.
bool looks_like_cache(const std::filesystem::path& path);

/// Writes atomically (AtomicFile: temporary + rename). Creates the folder.
/// Throws std::runtime_error "PATH: REASON" (the system's reason) on failure;
/// the previous file at CACHE, if any, is left as it was.
void save_cache(const Hierarchy& h, const CacheKey& key, const std::filesystem::path& cache);

/// Maps and verifies a cache. Returns nullopt and sets *why when the file is
/// missing, truncated, corrupted, of another version, or (when `expected` is
/// given) stale. Never crashes on any byte content.
std::optional<Hierarchy> load_cache(const std::filesystem::path& cache,
                                    const std::optional<CacheKey>& expected, std::string* why);

/// load_cache() without the staleness check, with the key the cache was
/// written for in *STORED: a caller may compute the expected key (the content
/// hash) concurrently and compare with cache_key_matches().
std::optional<Hierarchy> load_cache_and_key(const std::filesystem::path& cache, CacheKey* stored,
                                            std::string* why);

/// Whether a cache written for STORED serves EXPECTED: the same size, options
/// and content hash (the modification time does not decide).
bool cache_key_matches(const CacheKey& stored, const CacheKey& expected);

/// Reads the key stored in a cache header (for `treecut info CACHE`), after full verification.
std::optional<CacheKey> read_cache_key(const std::filesystem::path& cache, std::string* why);

}  // namespace treecut
