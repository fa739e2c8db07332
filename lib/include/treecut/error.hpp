// Error types shared by the library and the `treecut` program.
//
// The program maps them to exit codes: InputError -> 2 (bad input or usage),
// anything else derived from std::exception -> 1 (runtime failure).
#pragma once

#include <stdexcept>
#include <string>

namespace treecut {

/// The input (a file, a command line, a cache) is malformed. The message is one
/// line that names the file and the problem, e.g. "model.ply: header never ends".
class InputError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// A file changed while it was being read (it shrank under a mapping, or its
/// identity moved between the start and the end of a read): a runtime
/// failure (exit code 1), "NAME: changed while being read".
class FileChangedError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

}  // namespace treecut
