// Files the user owns: how treecut reads its inputs and writes its outputs.
//
// Inputs are checked before they are opened (a FIFO would block open(), a
// device would stream forever) and text inputs are read with a size limit.
// Outputs are written to a temporary beside the target, every write checked,
// and renamed into place only when complete: a failure (a full disk, a
// read-only folder) leaves the old file as it was and no truncated new one.
// Every error is one line naming the file and the system's reason.
#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <span>
#include <string>
#include <string_view>
#include <vector>

namespace treecut {

/// What a path names, without opening it (stat follows symbolic links).
enum class FileKind { Missing, Regular, Directory, Fifo, Socket, CharDevice, BlockDevice, Other };

FileKind file_kind(const std::filesystem::path& path);

/// "a directory", "a FIFO", "a socket", ... for messages ("PATH: is a FIFO").
std::string_view describe(FileKind kind);

/// Throws InputError unless `path` names a regular file: "PATH: no such file",
/// "PATH: is a FIFO", "PATH: is a directory", "PATH: permission denied".
/// Never opens the path, so a FIFO cannot block.
void require_regular_file(const std::filesystem::path& path);

/// Opens a regular file for reading without ever blocking: O_NONBLOCK, then
/// fstat() on the descriptor (the path may have changed since a check).
/// Returns the descriptor (caller closes it); throws InputError like
/// require_regular_file().
int open_regular_file(const std::filesystem::path& path);

/// Text inputs (camera paths, viewer scripts, scene files) are at most this big.
inline constexpr std::size_t kTextInputLimit = std::size_t{16} << 20;

/// Reads a whole regular file of at most `limit` bytes; throws InputError
/// "PATH: larger than N bytes (the limit for this input)" without reading
/// past the limit.
std::string read_text_file(const std::filesystem::path& path, std::size_t limit = kTextInputLimit);

/// Whether two paths name the same file (same device and inode: hard links
/// and symbolic links to it count). False when either does not exist.
bool same_file(const std::filesystem::path& a, const std::filesystem::path& b);

/// "PATH: REASON" where REASON is strerror(error), as one line.
std::string system_error_text(const std::filesystem::path& path, int error);

/// An output file under construction. The bytes go to a temporary file in
/// the target's folder (created with O_EXCL, never following a link); commit()
/// flushes, closes and renames it over the target. Destroying an uncommitted
/// AtomicFile removes the temporary, so a failed or abandoned write leaves
/// nothing behind and the previous target untouched. Errors throw
/// std::runtime_error "TARGET: REASON" (exit code 1 in the program).
class AtomicFile {
 public:
  explicit AtomicFile(std::filesystem::path target);
  AtomicFile(const AtomicFile&) = delete;
  AtomicFile& operator=(const AtomicFile&) = delete;
  ~AtomicFile();

  void write(const void* data, std::size_t size);
  void write(std::string_view text) { write(text.data(), text.size()); }
  /// Makes the new content visible at the target, atomically.
  void commit();

  [[nodiscard]] const std::filesystem::path& target() const { return target_; }
  [[nodiscard]] const std::filesystem::path& temporary() const { return temporary_; }
  [[nodiscard]] std::uint64_t bytes_written() const { return written_; }

 private:
  void buffer_flush();
  void discard() noexcept;

  std::filesystem::path target_;
  std::filesystem::path temporary_;
  int fd_ = -1;
  std::uint64_t written_ = 0;
  std::string buffer_;  // writes are batched into 1 MiB system calls
};

/// Writes `bytes` to `target` through an AtomicFile.
void write_file_atomically(const std::filesystem::path& target, std::string_view bytes);

/// A token of a user's text as it may appear in a one-line message: control
/// and non-ASCII bytes become '?' (a binary file must not garble the
/// terminal), and anything past `max_chars` is cut to "...".
std::string printable_excerpt(std::string_view text, std::size_t max_chars = 32);

/// A line of a user's text file (campath, scene) without the blanks around it
/// (spaces, tabs, a CR of a CRLF file).
std::string_view trim_blanks(std::string_view line);
/// The blank-separated tokens of a line (spaces and tabs), views into it.
std::vector<std::string_view> split_blanks(std::string_view line);

}  // namespace treecut
