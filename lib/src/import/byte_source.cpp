#include "byte_source.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>

#include "treecut/error.hpp"
#include "treecut/file_io.hpp"

namespace treecut::detail {

FileSource::FileSource(const std::filesystem::path& path, int open_flags) : path_(path) {
  // O_NONBLOCK: a FIFO named by mistake does not hang the open (it is
  // refused below, not a regular file).
  fd_ = ::open(path.c_str(), O_RDONLY | O_CLOEXEC | O_NONBLOCK | open_flags);
  if (fd_ < 0) throw InputError(system_error_text(path, errno));
  struct stat st {};
  if (::fstat(fd_, &st) != 0) {
    const int e = errno;
    ::close(fd_);
    throw InputError(system_error_text(path, e));
  }
  if (!S_ISREG(st.st_mode)) {
    ::close(fd_);
    throw InputError(quoted_name(path) + ": not a regular file");
  }
  size_ = static_cast<std::uint64_t>(st.st_size);
}

FileSource::~FileSource() {
  ::close(fd_);
}

void FileSource::read(std::uint64_t at, void* out, std::size_t n) const {
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

StreamedFile::StreamedFile(const std::filesystem::path& file)
    : path(file), source(std::make_unique<FileSource>(file)), name(quoted_name(file)) {}

StreamedFile::StreamedFile(std::string_view in_memory, std::string file_name)
    : bytes(in_memory),
      source(std::make_unique<MemorySource>(in_memory)),
      name(std::move(file_name)) {}

}  // namespace treecut::detail
