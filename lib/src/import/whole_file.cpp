// Reading a model file whole (whole_file.hpp).
#include "whole_file.hpp"

#include <fstream>
#include <string>

#include "treecut/error.hpp"
#include "treecut/file_io.hpp"

namespace treecut::detail {

WholeFile read_whole_file(const std::filesystem::path& path) {
  const std::string name = quoted_name(path);
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) {
    throw InputError(name + ": " + (ec ? ec.message() : "not a regular file"));
  }
  const std::uintmax_t size = std::filesystem::file_size(path, ec);
  if (ec) throw InputError(name + ": " + ec.message());
  std::ifstream in(path, std::ios::binary);
  if (!in) throw InputError(name + ": cannot open for reading");
  WholeFile file{std::make_unique_for_overwrite<char[]>(static_cast<std::size_t>(size)),
                 static_cast<std::size_t>(size)};
  in.read(file.data.get(), static_cast<std::streamsize>(size));
  if (static_cast<std::uintmax_t>(in.gcount()) != size) {
    if (std::filesystem::file_size(path, ec) != size)
      throw FileChangedError(name + ": changed while being read (its size moved)");
    throw InputError(name + ": cannot read the whole file");
  }
  return file;
}

}  // namespace treecut::detail
