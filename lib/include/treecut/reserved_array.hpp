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
  /// N values of T, all zero.
  explicit ReservedArray(std::size_t n) : bytes_(std::max<std::size_t>(n * sizeof(T), 1)) {
    void* p = ::mmap(nullptr, bytes_, PROT_READ | PROT_WRITE,
                     MAP_PRIVATE | MAP_ANONYMOUS | MAP_NORESERVE, -1, 0);
    if (p == MAP_FAILED) throw std::bad_alloc();
    data_ = static_cast<T*>(p);
  }
  ~ReservedArray() { ::munmap(data_, bytes_); }
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

 private:
  std::size_t bytes_;
  T* data_ = nullptr;
};

}  // namespace treecut
