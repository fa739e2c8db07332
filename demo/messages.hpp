// The program's lines on stderr besides main()'s: warnings and the errors a
// window reports and survives. Each is one line: one_line() escapes whatever
// control characters a file name or token brought into the text.
#pragma once

#include <charconv>
#include <cstdio>
#include <string>
#include <string_view>

#include "treecut/file_io.hpp"

namespace treecut::cli {

/// "warning: TEXT"
inline void print_warning(std::string_view text) {
  std::fprintf(stderr, "warning: %s\n", one_line(text).c_str());
}

/// "treecut: TEXT" for bad input, "treecut: error: TEXT" for a runtime
/// failure (main()'s prefixes), for a failure the program goes on after.
inline void print_error(std::string_view text, bool input_error = false) {
  std::fprintf(stderr, "treecut: %s%s\n", input_error ? "" : "error: ", one_line(text).c_str());
}

/// V in the fewest digits that read back as V (245379.3984, not
/// 245379.39840000001): a file's value shown exactly.
inline std::string exact_number(double v) {
  char text[32];
  const auto [end, ec] = std::to_chars(text, text + sizeof text, v);
  return ec == std::errc() ? std::string(text, end) : std::string("?");
}

}  // namespace treecut::cli
