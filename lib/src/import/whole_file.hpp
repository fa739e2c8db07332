// A model file read whole into memory, for the readers that parse bytes in
// memory (PLY, text clouds): one read, checked, its size the file's.
#pragma once

#include <cstddef>
#include <filesystem>
#include <memory>
#include <string_view>

namespace treecut::detail {

struct WholeFile {
  std::unique_ptr<char[]> data;  // uninitialized, then overwritten by the read
  std::size_t size = 0;
  [[nodiscard]] std::string_view bytes() const { return {data.get(), size}; }
};

/// The bytes of PATH (a regular file). Throws InputError "NAME: reason"
/// (NAME the path as messages show it) when it cannot be read, and
/// FileChangedError when its size moved while it was read.
WholeFile read_whole_file(const std::filesystem::path& path);

}  // namespace treecut::detail
