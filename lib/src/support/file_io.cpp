#include "treecut/file_io.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <cstring>
#include <stdexcept>

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
  if (error == ENOENT || error == ENOTDIR) throw InputError(path.string() + ": no such file");
  throw InputError(system_error_text(path, error));
}

[[noreturn]] void throw_not_regular(const std::filesystem::path& path, FileKind kind) {
  throw InputError(path.string() + ": is " + std::string(describe(kind)) + ", not a regular file");
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

std::string system_error_text(const std::filesystem::path& path, int error) {
  return path.string() + ": " + std::strerror(error);
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
      throw InputError(path.string() + ": larger than " + std::to_string(limit) +
                       " bytes (the limit for this input)");
    }
    text.append(chunk, static_cast<std::size_t>(n));
  }
  ::close(fd);
  return text;
}

bool same_file(const std::filesystem::path& a, const std::filesystem::path& b) {
  struct stat sa {
  }, sb{};
  if (::stat(a.c_str(), &sa) != 0 || ::stat(b.c_str(), &sb) != 0) return false;
  return sa.st_dev == sb.st_dev && sa.st_ino == sb.st_ino;
}

// -- AtomicFile ---------------------------------------------------------------

namespace {
constexpr std::size_t kWriteChunk = std::size_t{1} << 20;
std::atomic<unsigned> g_temporary_serial{0};
}  // namespace

AtomicFile::AtomicFile(std::filesystem::path target) : target_(std::move(target)) {
  const FileKind kind = file_kind(target_);
  if (kind != FileKind::Missing && kind != FileKind::Regular)
    throw std::runtime_error(target_.string() + ": is " + std::string(describe(kind)) +
                             "; refusing to replace it");
  // Beside the target, so the final rename stays on one file system.
  for (int attempt = 0; attempt < 100; ++attempt) {
    temporary_ = target_;
    temporary_ += ".tmp-" + std::to_string(::getpid()) + "-" +
                  std::to_string(g_temporary_serial.fetch_add(1, std::memory_order_relaxed));
    fd_ = ::open(temporary_.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC | O_NOFOLLOW, 0644);
    if (fd_ >= 0) break;
    if (errno != EEXIST) {
      const int error = errno;
      temporary_.clear();
      throw std::runtime_error(system_error_text(target_, error));
    }
  }
  if (fd_ < 0) throw std::runtime_error(target_.string() + ": cannot create a temporary file");
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

void AtomicFile::commit() {
  if (fd_ < 0) throw std::logic_error("AtomicFile::commit twice or after a failure");
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
  if (::rename(temporary_.c_str(), target_.c_str()) != 0) {
    const int error = errno;
    discard();
    throw std::runtime_error(system_error_text(target_, error));
  }
  temporary_.clear();
}

void write_file_atomically(const std::filesystem::path& target, std::string_view bytes) {
  AtomicFile file(target);
  file.write(bytes);
  file.commit();
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
