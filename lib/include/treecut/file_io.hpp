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

/// Whether PATH is a readable regular file whose first bytes are PREFIX (a
/// format's magic). Never blocks; false for anything it cannot read.
bool file_starts_with(const std::filesystem::path& path, std::string_view prefix);

/// The first bytes of a regular file and its size, read without following
/// a final symbolic link and without blocking (a FIFO, a directory, a link
/// or an unreadable file: `regular` false, nothing read).
struct FileHead {
  bool regular = false;
  std::uint64_t size = 0;
  std::string bytes;  ///< at most the N asked for
};
FileHead read_file_head(const std::filesystem::path& path, std::size_t n);

/// Whether two paths name the same file (same device and inode: hard links
/// and symbolic links to it count). False when either does not exist.
bool same_file(const std::filesystem::path& a, const std::filesystem::path& b);

/// Whether writing A would write B: the same file now (same_file), or, for
/// files that do not exist yet, the same place once `.`, `..` and symbolic
/// links in their folders are resolved ("n.ply" and "./d/../n.ply").
bool same_destination(const std::filesystem::path& a, const std::filesystem::path& b);

/// A file name as a one-line message shows it: as it is when it holds only
/// letters, digits and `._/+,:@%=~-` (or printable non-ASCII UTF-8), else in
/// single quotes with control characters, invalid UTF-8 and the C1 controls
/// escaped (\n, \t, \x1b, ...) and `'` and `\` backslashed: a name can
/// neither break the one-line rule nor send the terminal an escape sequence.
std::string quoted_name(const std::filesystem::path& path);
std::string quoted_name(std::string_view name);
inline std::string quoted_name(const std::string& name) {
  return quoted_name(std::string_view(name));
}
inline std::string quoted_name(const char* name) {
  return quoted_name(std::string_view(name));
}

/// BYTES as a one-line message shows a size or a budget: "1.4 MiB".
std::string mib_text(std::uint64_t bytes);

/// TEXT with every control character (C0, DEL, the C1 controls) and invalid
/// UTF-8 escaped as in quoted_name(): the last guard of the one-line rule, applied
/// by the program to every message it prints.
std::string one_line(std::string_view text);

/// "PATH: REASON" where REASON is strerror(error), as one line (PATH quoted_name()).
std::string system_error_text(const std::filesystem::path& path, int error);

/// An output file under construction. The bytes go to a temporary file in
/// the target's folder, "TARGET.tmp-PID-N" (created with O_EXCL, never
/// following a link); commit() flushes, closes and renames it over the
/// target. Destroying an uncommitted AtomicFile removes the temporary, so a
/// failed or abandoned write leaves nothing behind and the previous target
/// untouched; so does SIGINT, SIGTERM, SIGHUP or SIGQUIT (the temporary is
/// registered with the signal guard), and the temporaries of a process that
/// died without a chance (kill -9, a power cut) are removed by the next
/// AtomicFile of the same target: "TARGET.tmp-PID-N" of a PID that no longer
/// runs, owned by this user. Errors throw std::runtime_error "TARGET: REASON"
/// (exit code 1 in the program).
class AtomicFile {
 public:
  explicit AtomicFile(std::filesystem::path target);
  AtomicFile(const AtomicFile&) = delete;
  AtomicFile& operator=(const AtomicFile&) = delete;
  ~AtomicFile();

  void write(const void* data, std::size_t size);
  void write(std::string_view text) { write(text.data(), text.size()); }
  /// Hands what write() buffered to the file (so that the temporary can be
  /// read back: ScratchFile).
  void flush();
  /// Makes the new content visible at the target, atomically.
  void commit();
  /// Makes it visible at NAME (in the target's folder) only if nothing is
  /// there, atomically (no other writer can slip in between a check and the
  /// rename); false when NAME exists, and the content stays to be committed
  /// under another name.
  bool commit_new(const std::filesystem::path& name);

  [[nodiscard]] const std::filesystem::path& target() const { return target_; }
  [[nodiscard]] const std::filesystem::path& temporary() const { return temporary_; }
  [[nodiscard]] std::uint64_t bytes_written() const { return written_; }

 private:
  void buffer_flush();
  void discard() noexcept;

  void close_checked();

  std::filesystem::path target_;
  std::filesystem::path temporary_;
  int fd_ = -1;
  int signal_slot_ = -1;  // support/signal_guard.hpp
  std::uint64_t written_ = 0;
  std::string buffer_;  // writes are batched into 1 MiB system calls
};

/// Intermediate results too large for memory (the chunked build's points,
/// issue 44) in a file that is never a user's: AtomicFile's temporary beside
/// TARGET, never committed, so it is removed when the ScratchFile goes, by
/// SIGINT, SIGTERM, SIGHUP or SIGQUIT, and, after a kill -9, by the next
/// AtomicFile or ScratchFile of the same target. Appended to, read back
/// anywhere, and what was read for the last time released (a hole punched
/// where the file system can: the disk is freed as the build goes). Errors
/// throw std::runtime_error "TARGET: REASON" (a full disk). Not for use
/// from several threads at once.
class ScratchFile {
 public:
  explicit ScratchFile(const std::filesystem::path& target);
  ScratchFile(const ScratchFile&) = delete;
  ScratchFile& operator=(const ScratchFile&) = delete;
  ~ScratchFile();

  /// Appends SIZE bytes; returns where they start.
  std::uint64_t append(const void* data, std::size_t size);
  /// SIZE bytes at OFFSET, which an append wrote.
  void read(std::uint64_t offset, void* data, std::size_t size);
  /// The bytes [OFFSET, OFFSET + SIZE) will not be read again: their disk
  /// space is given back (fallocate's punched hole; nothing where the file
  /// system cannot).
  void release(std::uint64_t offset, std::uint64_t size) noexcept;
  [[nodiscard]] std::uint64_t size() const { return file_.bytes_written(); }
  /// The bytes appended and not released.
  [[nodiscard]] std::uint64_t held() const { return file_.bytes_written() - released_; }
  [[nodiscard]] const std::filesystem::path& path() const { return file_.temporary(); }

 private:
  AtomicFile file_;
  int fd_ = -1;  // read and punch: the writer's descriptor is write-only
  bool dirty_ = false;
  std::uint64_t released_ = 0;
};

/// Writes `bytes` to `target` through an AtomicFile.
void write_file_atomically(const std::filesystem::path& target, std::string_view bytes);

/// Writes `bytes` to the first name of WANTED, STEM-1.EXT, STEM-2.EXT, ...
/// that is free when the file is committed (AtomicFile::commit_new), and
/// returns it: never over an existing file, even one written a moment ago.
std::filesystem::path write_file_to_free_name(const std::filesystem::path& wanted,
                                              std::string_view bytes);

/// Removes "NAME.tmp-PID-N" files in FOLDER whose NAME ends with SUFFIX,
/// whose PID no longer runs and which this user owns: what killed writers
/// left. For folders that are treecut's own (the cache folder); AtomicFile
/// does this for its own target everywhere. Returns how many were removed.
std::size_t remove_stale_temporaries(const std::filesystem::path& folder, std::string_view suffix);

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
