// Address space for an array indexed by node id that only some ids use:
// reserved, not committed. The system gives memory pages on first write;
// untouched ones read as zeros and cost nothing, and release() gives pages
// back. What makes a per-node array proportional to the nodes in use, not
// to the hierarchy (a paged model's node arrays, the GPU pool's slots).
#pragma once

#include <sys/mman.h>
#include <unistd.h>

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <new>
#include <span>

namespace treecut {

template <class T>
class ReservedArray {
 public:
  /// N values of T, all zero, from a 2 MiB boundary (advise_huge()).
  explicit ReservedArray(std::size_t n) : bytes_(n * sizeof(T) + kHuge) {
    void* p = ::mmap(nullptr, bytes_, PROT_READ | PROT_WRITE,
                     MAP_PRIVATE | MAP_ANONYMOUS | MAP_NORESERVE, -1, 0);
    if (p == MAP_FAILED) throw std::bad_alloc();
    base_ = p;
    data_ = reinterpret_cast<T*>((reinterpret_cast<std::uintptr_t>(p) + kHuge - 1) / kHuge * kHuge);
  }
  ~ReservedArray() { ::munmap(base_, bytes_); }
  ReservedArray(const ReservedArray&) = delete;
  ReservedArray& operator=(const ReservedArray&) = delete;
  [[nodiscard]] T* data() const { return data_; }
  [[nodiscard]] std::span<const T> span(std::size_t n) const { return {data_, n}; }
  T& operator[](std::size_t i) const { return data_[i]; }

  /// Values [FIRST, FIRST + COUNT) back to zeros, the memory pages wholly
  /// inside given back to the system.
  void release(std::uint64_t first, std::uint64_t count) const {
    auto* begin = reinterpret_cast<unsigned char*>(data_ + first);
    auto* end = reinterpret_cast<unsigned char*>(data_ + first + count);
    static const auto page = static_cast<std::uintptr_t>(::sysconf(_SC_PAGESIZE));
    const auto lo = (reinterpret_cast<std::uintptr_t>(begin) + page - 1) / page * page;
    const auto hi = reinterpret_cast<std::uintptr_t>(end) / page * page;
    if (hi <= lo) {
      std::memset(begin, 0, static_cast<std::size_t>(end - begin));
      return;
    }
    std::memset(begin, 0, lo - reinterpret_cast<std::uintptr_t>(begin));
    std::memset(reinterpret_cast<void*>(hi), 0, reinterpret_cast<std::uintptr_t>(end) - hi);
    (void)::madvise(reinterpret_cast<void*>(lo), hi - lo, MADV_DONTNEED);
  }

  /// Asks for transparent huge pages under the 2 MiB pages wholly inside
  /// values [FIRST, FIRST + COUNT), before they are first written (a hint,
  /// ignored where unsupported): for values read in random order, where
  /// 4 KiB pages would make nearly every read miss the TLB too.
  void advise_huge(std::uint64_t first, std::uint64_t count) const {
    const auto begin = reinterpret_cast<std::uintptr_t>(data_ + first);
    const auto end = reinterpret_cast<std::uintptr_t>(data_ + first + count);
    const std::uintptr_t lo = (begin + kHuge - 1) / kHuge * kHuge, hi = end / kHuge * kHuge;
    if (lo < hi) (void)::madvise(reinterpret_cast<void*>(lo), hi - lo, MADV_HUGEPAGE);
  }

 private:
  static constexpr std::uintptr_t kHuge = std::uintptr_t{2} << 20;
  std::size_t bytes_;  // reserved from base_
  void* base_ = nullptr;
  T* data_ = nullptr;
};

}  // namespace treecut
