#include "treecut/mapped_file.hpp"

#include <sys/mman.h>

#include <cerrno>

#include "support/signal_guard.hpp"
#include "treecut/error.hpp"
#include "treecut/file_io.hpp"

namespace treecut {

MappedFile::MappedFile(int fd, std::uint64_t size, const std::filesystem::path& name)
    : size_(static_cast<std::size_t>(size)), name_(name) {
  if (size_ == 0) return;
  void* base = ::mmap(nullptr, size_, PROT_READ, MAP_PRIVATE, fd, 0);
  if (base == MAP_FAILED) throw std::runtime_error(system_error_text(name_, errno));
  data_ = static_cast<const unsigned char*>(base);
  slot_ = detail::register_mapping(data_, size_, quoted_name(name_));
}

MappedFile::~MappedFile() {
  if (data_ != nullptr) ::munmap(const_cast<unsigned char*>(data_), size_);
  detail::unregister_mapping(slot_);
}

bool MappedFile::run_guarded(void (*fn)(void*), void* ctx) const {
  return detail::run_guarded(data_, size_, fn, ctx);
}

void MappedFile::throw_changed() const {
  throw FileChangedError(quoted_name(name_) +
                         ": changed while being read (truncated or rewritten by another program)");
}

}  // namespace treecut
