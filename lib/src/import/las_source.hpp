// The LAS reader's internals shared by its two files: where the bytes come
// from, and the header as parsed (las_read.cpp: the header, VLRs and EVLRs;
// las_points.cpp: the point records, in batches). See treecut/las.hpp.
// The bytes come from a ByteSource (byte_source.hpp).
#pragma once

#include <cerrno>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <stdexcept>
#include <string_view>

#include "byte_source.hpp"
#include "treecut/las.hpp"

namespace treecut::detail {

// A problem with the bytes, without the file's name (added by the caller).
class LasError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// The header, checked: every count and offset inside the file.
struct LasParsed {
  LasInfo info;
  std::uint64_t point_offset = 0;
  std::uint64_t end = 0;  ///< of the last thing the header locates (points or EVLRs)
};

/// Parses and checks the header, the VLRs and the EVLRs; LasError for
/// malformed bytes (without the file's name), LAZ included.
LasParsed parse_las_header(const ByteSource& f);

/// Where RGB starts in a record of each point format (0: no RGB).
inline constexpr std::uint32_t kLasRgbAt[11] = {0, 0, 20, 28, 0, 28, 0, 30, 30, 0, 30};

}  // namespace treecut::detail
