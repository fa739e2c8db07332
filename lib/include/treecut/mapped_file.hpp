// A read-only mapping of a whole file that another program may shrink while
// it is mapped (a user's `truncate`, `cp new old` over a model being read).
// Touching a page past the new end raises SIGBUS, which would kill the
// process without a word; a MappedFile turns it into the house rule instead:
//
// - inside read_guarded(), the read fails with FileChangedError
//   ("NAME: changed while being read"), which the caller reports or retries;
// - anywhere else (a renderer drawing from a mapped cache), the process ends
//   with exit code 1 and that one line on stderr, after removing its
//   temporary files (support/signal_guard.hpp).
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <string>
#include <type_traits>

namespace treecut {

class MappedFile {
 public:
  /// Maps the first SIZE bytes (the size the caller's fstat saw) of the
  /// regular file open as FD, which the caller keeps and may close. NAME is
  /// the file as messages show it. Throws std::runtime_error "NAME: REASON"
  /// when the system cannot map it. SIZE 0 maps nothing.
  MappedFile(int fd, std::uint64_t size, const std::filesystem::path& name);
  MappedFile(const MappedFile&) = delete;
  MappedFile& operator=(const MappedFile&) = delete;
  ~MappedFile();

  [[nodiscard]] const unsigned char* data() const { return data_; }
  [[nodiscard]] std::size_t size() const { return size_; }
  [[nodiscard]] const std::filesystem::path& name() const { return name_; }

  /// Calls fn() on this thread; throws FileChangedError when the file shrank
  /// under it. FN must not hold objects with non-trivial destructors while it
  /// reads the mapping (it is left by a jump): loops over bytes only.
  template <class F>
  void read_guarded(F&& fn) const {
    if (!run_guarded([](void* f) { (*static_cast<std::remove_reference_t<F>*>(f))(); },
                     static_cast<void*>(&fn)))
      throw_changed();
  }

 private:
  bool run_guarded(void (*fn)(void*), void* ctx) const;
  [[noreturn]] void throw_changed() const;

  const unsigned char* data_ = nullptr;
  std::size_t size_ = 0;
  std::filesystem::path name_;
  int slot_ = -1;
};

}  // namespace treecut
