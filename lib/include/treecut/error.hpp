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

}  // namespace treecut
