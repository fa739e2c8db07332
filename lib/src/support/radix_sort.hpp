// LSD radix sort of unsigned integers by a range of their bits, with 11-bit
// digits: one O(n) counting pass per digit, stable, so equal digits keep the
// order they came in (the tree cut's node ids; the neighbour grid's
// (cell, index) pairs, whose index then breaks ties).
#pragma once

#include <algorithm>
#include <array>
#include <cstddef>
#include <cstdint>
#include <type_traits>
#include <utility>
#include <vector>

namespace treecut::detail {

/// Sorts V by bits [LOW, LOW + BITS) of each value (the others ride along).
/// SCRATCH is the ping-pong buffer; both vectors keep their capacity.
template <class T>
requires std::is_unsigned_v<T>
void radix_sort(std::vector<T>& v, unsigned low, unsigned bits, std::vector<T>& scratch) {
  constexpr unsigned kBits = 11;
  constexpr std::size_t kBuckets = std::size_t{1} << kBits;
  const unsigned passes = (std::max(bits, 1u) + kBits - 1) / kBits;
  scratch.reserve(v.capacity());  // the buffers trade places: keep room to grow
  scratch.resize(v.size());
  std::array<std::size_t, kBuckets> offset{};
  for (unsigned pass = 0; pass < passes; ++pass) {
    const unsigned shift = low + pass * kBits;
    offset.fill(0);
    for (const T x : v) ++offset[(x >> shift) & (kBuckets - 1)];
    std::size_t sum = 0;
    for (std::size_t& o : offset) sum += std::exchange(o, sum);
    for (const T x : v) scratch[offset[(x >> shift) & (kBuckets - 1)]++] = x;
    v.swap(scratch);  // O(1): the sorted digits are now in `v`
  }
}

}  // namespace treecut::detail
