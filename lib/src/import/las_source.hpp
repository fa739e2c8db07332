// The LAS reader's internals shared by its two files: where the bytes come
// from, and the header as parsed (las_read.cpp: the header, VLRs and EVLRs;
// las_points.cpp: the point records, in batches). See treecut/las.hpp.
#pragma once

#include <unistd.h>

#include <cerrno>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <stdexcept>
#include <string_view>

#include "treecut/error.hpp"
#include "treecut/file_io.hpp"
#include "treecut/las.hpp"

namespace treecut::detail {

// A problem with the bytes, without the file's name (added by the caller).
class LasError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Where the bytes come from: memory (fuzzing, tests) or a file read in
// pieces (a 20 M-point LAS is not read into memory whole).
class LasSource {
 public:
  virtual ~LasSource() = default;
  [[nodiscard]] virtual std::uint64_t size() const = 0;
  // Exactly n bytes at `at`; the caller checked at + n <= size().
  virtual void read(std::uint64_t at, void* out, std::size_t n) const = 0;
};

class LasMemorySource final : public LasSource {
 public:
  explicit LasMemorySource(std::string_view bytes) : bytes_(bytes) {}
  [[nodiscard]] std::uint64_t size() const override { return bytes_.size(); }
  void read(std::uint64_t at, void* out, std::size_t n) const override {
    if (n > 0) std::memcpy(out, bytes_.data() + at, n);
  }

 private:
  std::string_view bytes_;
};

class LasFileSource final : public LasSource {
 public:
  LasFileSource(int fd, std::uint64_t size, std::filesystem::path path)
      : fd_(fd), size_(size), path_(std::move(path)) {}
  [[nodiscard]] std::uint64_t size() const override { return size_; }
  void read(std::uint64_t at, void* out, std::size_t n) const override {
    auto* p = static_cast<char*>(out);
    while (n > 0) {
      const ssize_t got = ::pread(fd_, p, n, static_cast<off_t>(at));
      if (got < 0 && errno == EINTR) continue;
      if (got < 0) throw InputError(system_error_text(path_, errno));
      if (got == 0) {
        throw FileChangedError(quoted_name(path_) + ": changed while being read (it got shorter)");
      }
      p += got, at += static_cast<std::uint64_t>(got), n -= static_cast<std::size_t>(got);
    }
  }

 private:
  int fd_;
  std::uint64_t size_;
  std::filesystem::path path_;
};

/// The header, checked: every count and offset inside the file.
struct LasParsed {
  LasInfo info;
  std::uint64_t point_offset = 0;
  std::uint64_t end = 0;  ///< of the last thing the header locates (points or EVLRs)
};

/// Parses and checks the header, the VLRs and the EVLRs; LasError for
/// malformed bytes (without the file's name), LAZ included.
LasParsed parse_las_header(const LasSource& f);

/// Where RGB starts in a record of each point format (0: no RGB).
inline constexpr std::uint32_t kLasRgbAt[11] = {0, 0, 20, 28, 0, 28, 0, 30, 30, 0, 30};

}  // namespace treecut::detail
