#include "treecut/file_io.hpp"

#include <dirent.h>
#include <fcntl.h>
#include <signal.h>
#include <stdio.h>
#include <sys/stat.h>
#include <unistd.h>
#include <xxhash.h>

#include <algorithm>
#include <atomic>
#include <cctype>
#include <cerrno>
#include <charconv>
#include <cstdio>
#include <cstring>
#include <map>
#include <mutex>
#include <optional>
#include <stdexcept>

#include "support/signal_guard.hpp"
#include "treecut/error.hpp"

namespace treecut {

namespace {

FileKind kind_of(mode_t mode) {
  if (S_ISREG(mode)) return FileKind::Regular;
  if (S_ISDIR(mode)) return FileKind::Directory;
  if (S_ISFIFO(mode)) return FileKind::Fifo;
  if (S_ISSOCK(mode)) return FileKind::Socket;
  if (S_ISCHR(mode)) return FileKind::CharDevice;
  if (S_ISBLK(mode)) return FileKind::BlockDevice;
  return FileKind::Other;
}

[[noreturn]] void throw_input(const std::filesystem::path& path, int error) {
  if (error == ENOENT || error == ENOTDIR) throw InputError(quoted_name(path) + ": no such file");
  throw InputError(system_error_text(path, error));
}

[[noreturn]] void throw_not_regular(const std::filesystem::path& path, FileKind kind) {
  throw InputError(quoted_name(path) + ": is " + std::string(describe(kind)) +
                   ", not a regular file");
}

// -- how names are shown -------------------------------------------------------

// The length of the UTF-8 sequence at TEXT[I] and its code point, or 0 when
// it is not well formed (overlong, surrogate, past U+10FFFF, cut short).
std::size_t utf8_sequence(std::string_view text, std::size_t i, char32_t* code) {
  const auto byte = [&](std::size_t k) { return static_cast<unsigned char>(text[i + k]); };
  const unsigned char c = byte(0);
  std::size_t n = 0;
  char32_t cp = 0;
  if (c >= 0xc2 && c <= 0xdf)
    n = 2, cp = c & 0x1fu;
  else if (c >= 0xe0 && c <= 0xef)
    n = 3, cp = c & 0x0fu;
  else if (c >= 0xf0 && c <= 0xf4)
    n = 4, cp = c & 0x07u;
  else
    return 0;
  if (i + n > text.size()) return 0;
  for (std::size_t k = 1; k < n; ++k) {
    if ((byte(k) & 0xc0u) != 0x80u) return 0;
    cp = (cp << 6) | (byte(k) & 0x3fu);
  }
  if ((n == 3 && cp < 0x800) || (n == 4 && (cp < 0x10000 || cp > 0x10ffff)) ||
      (cp >= 0xd800 && cp <= 0xdfff))
    return 0;
  *code = cp;
  return n;
}

void append_hex(std::string& out, unsigned char c) {
  static constexpr char kDigits[] = "0123456789abcdef";
  out += "\\x";
  out += kDigits[c >> 4];
  out += kDigits[c & 15];
}

void append_control(std::string& out, unsigned char c) {
  switch (c) {
    case '\n':
      out += "\\n";
      return;
    case '\t':
      out += "\\t";
      return;
    case '\r':
      out += "\\r";
      return;
    default:
      append_hex(out, c);
  }
}

// TEXT with control characters and bad UTF-8 escaped; *PLAIN false when
// anything outside the plain set (see quoted_name()) was met.
std::string escaped(std::string_view text, bool quote_marks, bool* plain) {
  std::string out;
  out.reserve(text.size());
  bool clean = !text.empty();
  for (std::size_t i = 0; i < text.size();) {
    const auto c = static_cast<unsigned char>(text[i]);
    if (c < 0x80) {
      if (c < 0x20 || c == 0x7f) {
        append_control(out, c);
        clean = false;
      } else if (quote_marks && (c == '\'' || c == '\\')) {
        out += '\\';
        out += static_cast<char>(c);
        clean = false;
      } else {
        if (std::isalnum(c) == 0 && std::strchr("._/+,:@%=~-", c) == nullptr) clean = false;
        out += static_cast<char>(c);
      }
      ++i;
      continue;
    }
    char32_t code = 0;
    const std::size_t n = utf8_sequence(text, i, &code);
    // The C1 controls (U+0080..U+009F; U+009B is a CSI on some terminals)
    // and the line and paragraph separators are escaped byte by byte.
    if (n == 0 || code <= 0x9f || code == 0x2028 || code == 0x2029) {
      for (std::size_t k = 0; k < std::max<std::size_t>(n, 1); ++k)
        append_hex(out, static_cast<unsigned char>(text[i + k]));
      clean = false;
      i += std::max<std::size_t>(n, 1);
      continue;
    }
    out.append(text.substr(i, n));
    i += n;
  }
  if (plain != nullptr) *plain = clean;
  return out;
}

}  // namespace

FileKind file_kind(const std::filesystem::path& path) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) return FileKind::Missing;
  return kind_of(st.st_mode);
}

std::string_view describe(FileKind kind) {
  switch (kind) {
    case FileKind::Missing:
      return "missing";
    case FileKind::Regular:
      return "a regular file";
    case FileKind::Directory:
      return "a directory";
    case FileKind::Fifo:
      return "a FIFO";
    case FileKind::Socket:
      return "a socket";
    case FileKind::CharDevice:
      return "a character device";
    case FileKind::BlockDevice:
      return "a block device";
    case FileKind::Other:
      break;
  }
  return "not a regular file";
}

std::string quoted_name(std::string_view name) {
  bool plain = false;
  std::string body = escaped(name, true, &plain);
  return plain ? body : "'" + body + "'";
}

std::string quoted_name(const std::filesystem::path& path) {
  return quoted_name(std::string_view(path.native()));
}

std::string mib_text(std::uint64_t bytes) {
  char text[32];
  std::snprintf(text, sizeof text, "%.1f MiB", double(bytes) / double(1 << 20));
  return text;
}

std::string one_line(std::string_view text) {
  return escaped(text, false, nullptr);
}

std::string system_error_text(const std::filesystem::path& path, int error) {
  return quoted_name(path) + ": " + std::strerror(error);
}

void require_regular_file(const std::filesystem::path& path) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) throw_input(path, errno);
  const FileKind kind = kind_of(st.st_mode);
  if (kind != FileKind::Regular) throw_not_regular(path, kind);
  if (::access(path.c_str(), R_OK) != 0) throw_input(path, errno);
}

int open_regular_file(const std::filesystem::path& path) {
  // O_NONBLOCK: open() of a FIFO with no writer would wait for one forever.
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC | O_NONBLOCK | O_NOCTTY);
  if (fd < 0) {
    const int error = errno;
    const FileKind kind = file_kind(path);
    if (kind != FileKind::Regular && kind != FileKind::Missing) throw_not_regular(path, kind);
    throw_input(path, error);
  }
  struct stat st {};
  if (::fstat(fd, &st) != 0) {
    const int error = errno;
    ::close(fd);
    throw_input(path, error);
  }
  if (!S_ISREG(st.st_mode)) {
    ::close(fd);
    throw_not_regular(path, kind_of(st.st_mode));
  }
  // A regular file never blocks; clear the flag so reads behave as usual.
  const int flags = ::fcntl(fd, F_GETFL);
  if (flags >= 0) ::fcntl(fd, F_SETFL, flags & ~O_NONBLOCK);
  return fd;
}

std::string read_text_file(const std::filesystem::path& path, std::size_t limit) {
  const int fd = open_regular_file(path);
  std::string text;
  char chunk[1 << 16];
  for (;;) {
    const ssize_t n = ::read(fd, chunk, sizeof chunk);
    if (n < 0) {
      if (errno == EINTR) continue;
      const int error = errno;
      ::close(fd);
      throw_input(path, error);
    }
    if (n == 0) break;
    if (text.size() + static_cast<std::size_t>(n) > limit) {
      ::close(fd);
      throw InputError(quoted_name(path) + ": larger than " + std::to_string(limit) +
                       " bytes (the limit for this input)");
    }
    text.append(chunk, static_cast<std::size_t>(n));
  }
  ::close(fd);
  return text;
}

bool file_starts_with(const std::filesystem::path& path, std::string_view prefix) {
  if (file_kind(path) != FileKind::Regular) return false;
  int fd = -1;
  try {
    fd = open_regular_file(path);
  } catch (const std::exception&) {
    return false;
  }
  std::string head(prefix.size(), '\0');
  std::size_t got = 0;
  while (got < head.size()) {
    const ssize_t n = ::read(fd, head.data() + got, head.size() - got);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) break;
    got += static_cast<std::size_t>(n);
  }
  ::close(fd);
  return got == head.size() && head == prefix;
}

FileHead read_file_head(const std::filesystem::path& path, std::size_t n) {
  FileHead head;
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC | O_NONBLOCK | O_NOFOLLOW);
  if (fd < 0) return head;
  struct stat st {};
  if (::fstat(fd, &st) == 0 && S_ISREG(st.st_mode)) {
    head.regular = true;
    head.size = static_cast<std::uint64_t>(st.st_size);
    head.bytes.resize(static_cast<std::size_t>(std::min<std::uint64_t>(n, head.size)));
    std::size_t got = 0;
    while (got < head.bytes.size()) {
      const ssize_t r = ::read(fd, head.bytes.data() + got, head.bytes.size() - got);
      if (r < 0 && errno == EINTR) continue;
      if (r <= 0) break;
      got += static_cast<std::size_t>(r);
    }
    head.bytes.resize(got);
  }
  ::close(fd);
  return head;
}

bool same_file(const std::filesystem::path& a, const std::filesystem::path& b) {
  struct stat sa {
  }, sb{};
  if (::stat(a.c_str(), &sa) != 0 || ::stat(b.c_str(), &sb) != 0) return false;
  return sa.st_dev == sb.st_dev && sa.st_ino == sb.st_ino;
}

bool same_destination(const std::filesystem::path& a, const std::filesystem::path& b) {
  if (same_file(a, b)) return true;
  std::error_code ea, eb;
  const auto ca = std::filesystem::weakly_canonical(std::filesystem::absolute(a, ea), ea);
  const auto cb = std::filesystem::weakly_canonical(std::filesystem::absolute(b, eb), eb);
  return !ea && !eb && ca == cb;
}

// -- temporaries of writers that died -----------------------------------------

namespace {

struct TemporaryName {
  std::string owner;  // the target's file name
  pid_t pid = 0;
};

// "NAME.tmp-PID-N" -> {NAME, PID}.
std::optional<TemporaryName> parse_temporary_name(std::string_view file) {
  const std::size_t at = file.rfind(".tmp-");
  if (at == std::string_view::npos || at == 0) return std::nullopt;
  const std::string_view tail = file.substr(at + 5);
  const std::size_t dash = tail.find('-');
  if (dash == std::string_view::npos || dash == 0 || dash + 1 == tail.size()) return std::nullopt;
  long long pid = 0;
  auto [p, ec] = std::from_chars(tail.data(), tail.data() + dash, pid);
  if (ec != std::errc() || p != tail.data() + dash || pid <= 0 || pid > 0x3fffffff)
    return std::nullopt;
  for (char c : tail.substr(dash + 1))
    if (c < '0' || c > '9') return std::nullopt;
  return TemporaryName{std::string(file.substr(0, at)), static_cast<pid_t>(pid)};
}

// The name a target's temporaries start with: the target's own file name,
// or, when "NAME.tmp-PID-N" would pass NAME_MAX (255 bytes), a cut of it and
// a hash of the whole (a legal 250-byte name still gets its temporary).
std::string temporary_owner(const std::string& file_name) {
  constexpr std::size_t kLongest = 215;  // + ".tmp-" + a 10-digit PID + "-" + a serial
  if (file_name.size() <= kLongest) return file_name;
  char hex[17];
  std::snprintf(hex, sizeof hex, "%016llx",
                static_cast<unsigned long long>(XXH3_64bits(file_name.data(), file_name.size())));
  return file_name.substr(0, kLongest - 17) + "~" + hex;
}

// A regular file of this user whose writer no longer runs (kill(pid, 0):
// ESRCH; EPERM means some process of another user runs under that PID).
bool left_by_dead_writer(const std::filesystem::path& file, pid_t pid) {
  if (pid == ::getpid()) return false;
  struct stat st {};
  if (::lstat(file.c_str(), &st) != 0 || !S_ISREG(st.st_mode) || st.st_uid != ::geteuid())
    return false;
  return ::kill(pid, 0) != 0 && errno == ESRCH;
}

// The temporaries of each folder, listed once per process (a render writes
// thousands of frames into one folder; each would list it again).
class StaleTemporaries {
 public:
  void remove_for(const std::filesystem::path& target) {
    const std::filesystem::path folder = target.parent_path();
    const std::string owner = temporary_owner(target.filename().string());
    std::lock_guard lock(mutex_);
    auto [it, fresh] = folders_.try_emplace(folder.string());
    if (fresh) it->second = full_names_in(folder);
    auto& names = it->second;
    std::erase_if(names, [&](const std::string& name) {
      const auto t = parse_temporary_name(name);
      if (!t || t->owner != owner) return false;
      const std::filesystem::path file = folder / name;
      if (left_by_dead_writer(file, t->pid)) ::unlink(file.c_str());
      return true;
    });
  }

 private:
  static std::vector<std::string> full_names_in(const std::filesystem::path& folder) {
    std::vector<std::string> out;
    DIR* dir = ::opendir(folder.empty() ? "." : folder.c_str());
    if (dir == nullptr) return out;
    while (const dirent* e = ::readdir(dir))
      if (parse_temporary_name(e->d_name)) out.emplace_back(e->d_name);
    ::closedir(dir);
    return out;
  }
  std::mutex mutex_;
  std::map<std::string, std::vector<std::string>> folders_;
};

StaleTemporaries g_stale;

}  // namespace

std::size_t remove_stale_temporaries(const std::filesystem::path& folder, std::string_view suffix) {
  std::size_t removed = 0;
  DIR* dir = ::opendir(folder.empty() ? "." : folder.c_str());
  if (dir == nullptr) return 0;
  std::vector<std::string> names;
  while (const dirent* e = ::readdir(dir)) names.emplace_back(e->d_name);
  ::closedir(dir);
  for (const std::string& name : names) {
    const auto t = parse_temporary_name(name);
    if (!t || !std::string_view(t->owner).ends_with(suffix)) continue;
    const std::filesystem::path file = folder / name;
    if (left_by_dead_writer(file, t->pid) && ::unlink(file.c_str()) == 0) ++removed;
  }
  return removed;
}

// -- AtomicFile ---------------------------------------------------------------

namespace {
constexpr std::size_t kWriteChunk = std::size_t{1} << 20;
std::atomic<unsigned> g_temporary_serial{0};
}  // namespace

AtomicFile::AtomicFile(std::filesystem::path target) : target_(std::move(target)) {
  const FileKind kind = file_kind(target_);
  if (kind != FileKind::Missing && kind != FileKind::Regular)
    throw std::runtime_error(quoted_name(target_) + ": is " + std::string(describe(kind)) +
                             "; refusing to replace it");
  g_stale.remove_for(target_);
  // Beside the target, so the final rename stays on one file system.
  for (int attempt = 0; attempt < 100; ++attempt) {
    temporary_ = target_;
    temporary_.replace_filename(
        temporary_owner(target_.filename().string()) + ".tmp-" + std::to_string(::getpid()) + "-" +
        std::to_string(g_temporary_serial.fetch_add(1, std::memory_order_relaxed)));
    const detail::TemporaryInTheMaking making;
    fd_ = ::open(temporary_.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC | O_NOFOLLOW, 0644);
    if (fd_ >= 0) {
      std::error_code ec;
      const std::filesystem::path absolute = std::filesystem::absolute(temporary_, ec);
      signal_slot_ = detail::register_temporary(ec ? temporary_.native() : absolute.native());
      break;
    }
    if (errno != EEXIST) {
      const int error = errno;
      temporary_.clear();
      throw std::runtime_error(system_error_text(target_, error));
    }
  }
  if (fd_ < 0) throw std::runtime_error(quoted_name(target_) + ": cannot create a temporary file");
  buffer_.reserve(kWriteChunk);
}

AtomicFile::~AtomicFile() {
  discard();
}

void AtomicFile::discard() noexcept {
  if (fd_ >= 0) ::close(fd_);
  fd_ = -1;
  if (!temporary_.empty()) ::unlink(temporary_.c_str());
  temporary_.clear();
  detail::unregister_temporary(signal_slot_);
  signal_slot_ = -1;
}

void AtomicFile::buffer_flush() {
  const char* p = buffer_.data();
  std::size_t left = buffer_.size();
  while (left > 0) {
    const ssize_t n = ::write(fd_, p, left);
    if (n < 0) {
      if (errno == EINTR) continue;
      const int error = errno;
      discard();
      throw std::runtime_error(system_error_text(target_, error));
    }
    p += n;
    left -= static_cast<std::size_t>(n);
  }
  buffer_.clear();
}

void AtomicFile::write(const void* data, std::size_t size) {
  if (fd_ < 0) throw std::logic_error("AtomicFile::write after commit or failure");
  const char* p = static_cast<const char*>(data);
  written_ += size;
  while (size > 0) {
    const std::size_t take = std::min(size, kWriteChunk - buffer_.size());
    buffer_.append(p, take);
    p += take;
    size -= take;
    if (buffer_.size() == kWriteChunk) buffer_flush();
  }
}

void AtomicFile::flush() {
  if (fd_ < 0) throw std::logic_error("AtomicFile::flush after commit or failure");
  buffer_flush();
}

// -- ScratchFile --------------------------------------------------------------

ScratchFile::ScratchFile(const std::filesystem::path& target) : file_(target) {
  fd_ = ::open(file_.temporary().c_str(), O_RDWR | O_CLOEXEC | O_NOFOLLOW);
  if (fd_ < 0) throw std::runtime_error(system_error_text(target, errno));
}

ScratchFile::~ScratchFile() {
  if (fd_ >= 0) ::close(fd_);
}  // file_ removes the temporary

std::uint64_t ScratchFile::append(const void* data, std::size_t size) {
  const std::uint64_t at = file_.bytes_written();
  file_.write(data, size);
  dirty_ = true;
  return at;
}

void ScratchFile::read(std::uint64_t offset, void* data, std::size_t size) {
  if (offset + size > file_.bytes_written())
    throw std::logic_error("ScratchFile::read past what was written");
  if (dirty_) file_.flush(), dirty_ = false;
  auto* p = static_cast<char*>(data);
  while (size > 0) {
    const ssize_t n = ::pread(fd_, p, size, static_cast<off_t>(offset));
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0)
      throw std::runtime_error(n < 0 ? system_error_text(file_.target(), errno)
                                     : quoted_name(file_.temporary()) + ": shorter than written");
    p += n, offset += static_cast<std::uint64_t>(n), size -= static_cast<std::size_t>(n);
  }
}

void ScratchFile::release(std::uint64_t offset, std::uint64_t size) noexcept {
  if (size == 0) return;
  released_ += size;
  (void)::fallocate(fd_, FALLOC_FL_PUNCH_HOLE | FALLOC_FL_KEEP_SIZE, static_cast<off_t>(offset),
                    static_cast<off_t>(size));
}

void AtomicFile::close_checked() {
  if (fd_ < 0) {
    if (temporary_.empty()) throw std::logic_error("AtomicFile::commit twice or after a failure");
    return;  // closed by an earlier commit_new() that found its name taken
  }
  buffer_flush();
  // No fsync: a full disk is reported by write() on the file systems in use
  // (delayed allocation reserves blocks at write time); close() is checked
  // for the rest (NFS). Caches carry a checksum against a torn write.
  const int fd = fd_;
  fd_ = -1;
  if (::close(fd) != 0) {
    const int error = errno;
    discard();
    throw std::runtime_error(system_error_text(target_, error));
  }
}

void AtomicFile::commit() {
  close_checked();
  if (::rename(temporary_.c_str(), target_.c_str()) != 0) {
    const int error = errno;
    discard();
    throw std::runtime_error(system_error_text(target_, error));
  }
  temporary_.clear();
  discard();  // only unregisters: the temporary is the target now
}

bool AtomicFile::commit_new(const std::filesystem::path& name) {
  close_checked();
  // renameat2(RENAME_NOREPLACE) where the file system has it; else link()
  // (which never replaces either) and removing the temporary's name.
  int result = ::renameat2(AT_FDCWD, temporary_.c_str(), AT_FDCWD, name.c_str(), RENAME_NOREPLACE);
  if (result != 0 && (errno == EINVAL || errno == ENOSYS)) {
    result = ::link(temporary_.c_str(), name.c_str());
    if (result == 0) ::unlink(temporary_.c_str());
  }
  if (result != 0) {
    if (errno == EEXIST) return false;
    const int error = errno;
    discard();
    throw std::runtime_error(system_error_text(name, error));
  }
  temporary_.clear();
  discard();
  return true;
}

void write_file_atomically(const std::filesystem::path& target, std::string_view bytes) {
  AtomicFile file(target);
  file.write(bytes);
  file.commit();
}

std::filesystem::path write_file_to_free_name(const std::filesystem::path& wanted,
                                              std::string_view bytes) {
  std::optional<AtomicFile> file;
  for (int i = 0;; ++i) {
    std::filesystem::path name = wanted;
    if (i > 0)
      name.replace_filename(wanted.stem().string() + "-" + std::to_string(i) +
                            wanted.extension().string());
    // Taken by anything (a file, a folder, a link even to nowhere): the next.
    struct stat st {};
    if (::lstat(name.c_str(), &st) == 0) continue;
    if (!file) {
      file.emplace(name);
      file->write(bytes);
    }
    if (file->commit_new(name)) return name;  // else taken since the lstat
  }
}

std::string printable_excerpt(std::string_view text, std::size_t max_chars) {
  std::string out;
  const std::size_t n = std::min(text.size(), max_chars);
  out.reserve(n + 3);
  for (std::size_t i = 0; i < n; ++i) {
    const auto c = static_cast<unsigned char>(text[i]);
    out.push_back(c >= 0x20 && c < 0x7f ? static_cast<char>(c) : '?');
  }
  if (text.size() > max_chars) out += "...";
  return out;
}

std::string_view trim_blanks(std::string_view line) {
  const auto first = line.find_first_not_of(" \t\r");
  if (first == std::string_view::npos) return {};
  const auto last = line.find_last_not_of(" \t\r");
  return line.substr(first, last - first + 1);
}

std::vector<std::string_view> split_blanks(std::string_view line) {
  std::vector<std::string_view> out;
  std::size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && (line[i] == ' ' || line[i] == '\t')) ++i;
    if (i >= line.size()) break;
    std::size_t j = i;
    while (j < line.size() && line[j] != ' ' && line[j] != '\t') ++j;
    out.push_back(line.substr(i, j - i));
    i = j;
  }
  return out;
}

}  // namespace treecut
