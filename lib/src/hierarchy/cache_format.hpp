// What cache_lookup.cpp needs of the cache file beyond the public cache.hpp:
// the key in a cache's header without verifying the file. Private to the
// library; the layout itself stays in cache_layout.hpp, for cache.cpp and
// cache_write.cpp.
#pragma once

#include <cstdint>
#include <filesystem>
#include <optional>

#include "treecut/cache.hpp"

namespace treecut::detail {

/// The key recorded in CACHE's header as it is on disk, unverified (the
/// checksum is checked by load_cache_and_key before anything is served): only
/// to decide whether the content hash can be skipped. nullopt when CACHE is
/// not a readable cache of this format version. Never blocks.
std::optional<CacheKey> peek_cache_key(const std::filesystem::path& cache);

/// XXH3-64 of the first SIZE bytes (what an fstat saw) of the file open as
/// FD, named SOURCE in messages. Throws FileChangedError when the file is
/// shorter than that by the time its pages are read.
std::uint64_t hash_descriptor(const std::filesystem::path& source, int fd, std::uint64_t size);

}  // namespace treecut::detail
