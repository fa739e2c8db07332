// Where a streaming reader's bytes come from: memory (fuzzing, tests) or a
// file read in pieces at the offsets asked for, never whole (the LAS, PLY
// and PCD readers: a 20 M-point file is not read into memory to take a
// batch of it).
#pragma once

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <memory>
#include <string>
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

// A file a batch reader (PlyReader, PcdReader) streams: its bytes, and the
// name its messages give it.
struct StreamedFile {
  std::filesystem::path path;  // empty for bytes in memory
  std::string_view bytes;      // the bytes in memory, else empty
  std::unique_ptr<ByteSource> source;
  std::string name;

  /// PATH opened (FileSource; InputError where it cannot be).
  explicit StreamedFile(const std::filesystem::path& file);
  /// BYTES (which must outlive it); NAME stands for the path.
  StreamedFile(std::string_view in_memory, std::string file_name);

  /// The whole file through the format's whole read: FROM_FILE(path) or
  /// FROM_MEMORY(bytes, name).
  template <class FromFile, class FromMemory>
  auto whole(FromFile&& from_file, FromMemory&& from_memory) const {
    return path.empty() ? from_memory(bytes, name) : from_file(path);
  }

  /// Calls PARSE(prefix) on the file's first 64 KiB, then on four times as
  /// many bytes each time it throws ERROR (a header that goes on past the
  /// prefix), up to the file's end or 16 MiB (comments by the thousand);
  /// false where it never returned (a malformed header: the whole read
  /// names it).
  template <class Error, class Parse>
  bool parse_head(Parse&& parse) const {
    constexpr std::uint64_t kMaxHeader = std::uint64_t{16} << 20;
    const std::uint64_t size = source->size();
    std::string prefix;
    for (std::uint64_t want = std::uint64_t{1} << 16;; want *= 4) {
      prefix.resize(static_cast<std::size_t>(std::min({want, size, kMaxHeader})));
      source->read(0, prefix.data(), prefix.size());
      try {
        parse(std::string_view(prefix));
        return true;
      } catch (const Error&) {
        if (prefix.size() == size || prefix.size() == kMaxHeader) return false;
      }
    }
  }
};

}  // namespace treecut::detail
