// The checksum that ends every hierarchy cache file (cache_layout.hpp). Private, but
// shared with the cache fuzz target (tests/fuzz/cache_fuzz.cpp), which reseals
// mutated files with it to reach the structural checks behind the checksum.
#pragma once

#include <cstddef>
#include <cstdint>

namespace treecut::detail {

/// Over DATA[0, SIZE): the checksum a cache file stores of its meta part
/// (in its last 8 bytes) and of each page (in the page table).
std::uint64_t cache_checksum(const unsigned char* data, std::size_t size);

/// Rewrites every checksum of a cache file's bytes (each page's in the
/// table, where the table and the page lie inside the file, then the meta
/// part's) so that a mutated file reaches the checks behind them. For the
/// fuzz target and its regressions; false when the header is too broken to
/// say where anything is.
bool reseal_cache(unsigned char* data, std::size_t size);

}  // namespace treecut::detail
