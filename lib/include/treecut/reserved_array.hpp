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
#include <utility>
#include <vector>

namespace treecut {

/// Whether an array counts the values in use on each of its memory pages
/// (ReservedArray::use).
enum class PageSharing : std::uint8_t { alone, counted };

template <class T>
class ReservedArray {
 public:
  /// N values of T, all zero, from a 2 MiB boundary (advise_huge()).
  /// COUNTED: release() gives back a memory page once no value on it is in
  /// use (each told first to use(), in runs split or merged as they come).
  explicit ReservedArray(std::size_t n, PageSharing sharing = PageSharing::alone)
      : bytes_(n * sizeof(T) + kHuge) {
    base_ = map(bytes_);
    data_ =
        reinterpret_cast<T*>((reinterpret_cast<std::uintptr_t>(base_) + kHuge - 1) / kHuge * kHuge);
    if (sharing == PageSharing::counted) {
      // Pages of the system's size: a huge page (where they are on by
      // default) would hold 2 MiB for any run on it.
      (void)::madvise(base_, bytes_, MADV_NOHUGEPAGE);
      users_bytes_ = (bytes_ / page_size() + 1) * sizeof(std::uint32_t);
      try {
        users_ = static_cast<std::uint32_t*>(map(users_bytes_));
      } catch (...) {
        ::munmap(base_, bytes_);
        throw;
      }
    }
  }
  ~ReservedArray() {
    ::munmap(base_, bytes_);
    if (users_ != nullptr) ::munmap(users_, users_bytes_);
  }
  ReservedArray(const ReservedArray&) = delete;
  ReservedArray& operator=(const ReservedArray&) = delete;
  [[nodiscard]] T* data() const { return data_; }
  [[nodiscard]] std::span<const T> span(std::size_t n) const { return {data_, n}; }
  T& operator[](std::size_t i) const { return data_[i]; }

  /// A counted array: values [FIRST, FIRST + COUNT), not in use, are about
  /// to be written; the memory pages they lie on count their bytes in use.
  /// An alone array: nothing.
  void use(std::uint64_t first, std::uint64_t count) const {
    if (users_ == nullptr || count == 0) return;
    for_each_page(first, count, [&](std::uint64_t p, std::uint64_t from, std::uint64_t to) {
      users_[p] += static_cast<std::uint32_t>(to - from);
    });
  }

  /// Values [FIRST, FIRST + COUNT) back to zeros, and the memory pages
  /// nothing uses any more given back to the system: a counted array's
  /// pages with no value in use left (use()), an alone array's pages wholly
  /// inside the run. (Alone, a page that runs shared stays, zeros, once
  /// they all went one at a time: on a paged model the pages at the ends
  /// of the levels of its pages, which a long flight gathered.)
  void release(std::uint64_t first, std::uint64_t count) const {
    if (users_ != nullptr) {
      release_counted(first, count);
      return;
    }
    auto* begin = reinterpret_cast<unsigned char*>(data_ + first);
    auto* end = reinterpret_cast<unsigned char*>(data_ + first + count);
    const std::uintptr_t page = page_size();
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

  /// The bytes of the memory pages the system holds under values [0, N)
  /// (mincore: what RSS counts of them, and a page given back and read
  /// since, which maps the system's page of zeros). O(N) bits: for a
  /// report, not a frame.
  [[nodiscard]] std::uint64_t held_bytes(std::uint64_t n) const {
    if (n == 0) return 0;
    const auto [lo, hi] = pages_of(0, n);
    const std::uintptr_t page = page_size();
    std::vector<unsigned char> in(hi - lo + 1);
    if (::mincore(data_, (hi - lo + 1) * page, in.data()) != 0) return 0;
    return static_cast<std::uint64_t>(
               std::count_if(in.begin(), in.end(), [](unsigned char c) { return (c & 1) != 0; })) *
           page;
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
  static std::uintptr_t page_size() {
    static const auto page = static_cast<std::uintptr_t>(::sysconf(_SC_PAGESIZE));
    return page;
  }
  static void* map(std::size_t bytes) {
    void* p = ::mmap(nullptr, bytes, PROT_READ | PROT_WRITE,
                     MAP_PRIVATE | MAP_ANONYMOUS | MAP_NORESERVE, -1, 0);
    if (p == MAP_FAILED) throw std::bad_alloc();
    return p;
  }
  // The memory pages (from data_) of values [FIRST, FIRST + COUNT), COUNT > 0.
  [[nodiscard]] std::pair<std::uint64_t, std::uint64_t> pages_of(std::uint64_t first,
                                                                 std::uint64_t count) const {
    return {first * sizeof(T) / page_size(), ((first + count) * sizeof(T) - 1) / page_size()};
  }
  // FN(page, from, to) for each memory page of values [FIRST, FIRST +
  // COUNT), COUNT > 0, with the bytes [from, to) of them on it (from data_).
  template <class Fn>
  void for_each_page(std::uint64_t first, std::uint64_t count, Fn&& fn) const {
    const std::uint64_t page = page_size();
    const std::uint64_t begin = first * sizeof(T), end = (first + count) * sizeof(T);
    const auto [lo, hi] = pages_of(first, count);
    for (std::uint64_t p = lo; p <= hi; ++p)
      fn(p, std::max(begin, p * page), std::min(end, (p + 1) * page));
  }
  void release_counted(std::uint64_t first, std::uint64_t count) const {
    if (count == 0) return;
    const std::uint64_t page = page_size();
    auto* bytes = reinterpret_cast<unsigned char*>(data_);
    std::uint64_t free_from = 0, free_to = 0;  // a stretch of pages to give back
    const auto give_back = [&] {
      if (free_from < free_to)
        (void)::madvise(bytes + free_from * page, (free_to - free_from) * page, MADV_DONTNEED);
      free_from = free_to = 0;
    };
    for_each_page(first, count, [&](std::uint64_t p, std::uint64_t from, std::uint64_t to) {
      users_[p] -= static_cast<std::uint32_t>(to - from);
      if (users_[p] == 0) {
        if (free_from == free_to) free_from = p;
        free_to = p + 1;
        return;
      }
      give_back();
      // Other values on the page are in use: these back to zeros.
      std::memset(bytes + from, 0, to - from);
    });
    give_back();
  }

  std::size_t bytes_;  // reserved from base_
  void* base_ = nullptr;
  T* data_ = nullptr;
  std::uint32_t* users_ = nullptr;  // counted: by memory page from data_, its bytes in use
  std::size_t users_bytes_ = 0;
};

}  // namespace treecut
