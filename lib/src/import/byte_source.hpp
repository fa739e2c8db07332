// Where a streaming reader's bytes come from: memory (fuzzing, tests) or a
// file read in pieces at the offsets asked for, never whole (the LAS, PLY
// and PCD readers: a 20 M-point file is not read into memory to take a
// batch of it).
#pragma once

#include <cstdint>
#include <cstring>
#include <filesystem>
#include <string_view>

namespace treecut::detail {

class ByteSource {
 public:
  virtual ~ByteSource() = default;
  [[nodiscard]] virtual std::uint64_t size() const = 0;
  // Exactly n bytes at `at`; the caller checked at + n <= size().
  virtual void read(std::uint64_t at, void* out, std::size_t n) const = 0;
};

class MemorySource final : public ByteSource {
 public:
  explicit MemorySource(std::string_view bytes) : bytes_(bytes) {}
  [[nodiscard]] std::uint64_t size() const override { return bytes_.size(); }
  void read(std::uint64_t at, void* out, std::size_t n) const override {
    if (n > 0) std::memcpy(out, bytes_.data() + at, n);
  }

 private:
  std::string_view bytes_;
};

class FileSource final : public ByteSource {
 public:
  /// Opens PATH, a regular file (OPEN_FLAGS added to the read-only ones:
  /// O_NOFOLLOW, say). Throws InputError "NAME: reason".
  explicit FileSource(const std::filesystem::path& path, int open_flags = 0);
  ~FileSource() override;
  FileSource(const FileSource&) = delete;
  FileSource& operator=(const FileSource&) = delete;

  [[nodiscard]] std::uint64_t size() const override { return size_; }
  /// InputError on a failed read, FileChangedError where the file got
  /// shorter than it was when opened.
  void read(std::uint64_t at, void* out, std::size_t n) const override;

 private:
  int fd_ = -1;
  std::uint64_t size_ = 0;
  std::filesystem::path path_;
};

}  // namespace treecut::detail
