// 64-bit integer mixing from SplitMix64 (Steele, Lea and Flood, "Fast
// splittable pseudorandom number generators", OOPSLA 2014): the generators'
// counter-based random numbers, the k-NN grid's cell hash, the selection
// benchmark's cut fingerprint. Not a cryptographic hash.
#pragma once

#include <cstdint>

namespace treecut {

/// SplitMix64's output function: a bijection of the 64-bit integers in which
/// every input bit reaches every output bit.
constexpr std::uint64_t mix64(std::uint64_t x) {
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ull;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebull;
  return x ^ (x >> 31);
}

/// One SplitMix64 output for the counter x: mix64 of x plus the
/// golden-ratio increment, so that 0 does not map to 0.
constexpr std::uint64_t splitmix64(std::uint64_t x) {
  return mix64(x + 0x9e3779b97f4a7c15ull);
}

}  // namespace treecut
