// The checksum that ends every hierarchy cache file (cache_layout.hpp). Private, but
// shared with the cache fuzz target (tests/fuzz/cache_fuzz.cpp), which reseals
// mutated files with it to reach the structural checks behind the checksum.
#pragma once

#include <cstddef>
#include <cstdint>

namespace treecut::detail {

/// Over DATA[0, SIZE): the value stored in the last 8 bytes of a cache file,
/// computed over everything before them.
std::uint64_t cache_checksum(const unsigned char* data, std::size_t size);

}  // namespace treecut::detail
