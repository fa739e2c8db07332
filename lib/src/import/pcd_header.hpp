// The header of a PCD file (PCL's point cloud format): its lines checked one
// by one into the fields' layout, the point count, the viewpoint and the
// body's encoding. Private to the PCD reader (pcd_read.cpp), with the few
// text helpers its ascii body shares.
#pragma once

#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace treecut::pcd {

class PcdError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct Field {
  std::string name;
  std::uint32_t size = 4;  // bytes of one element
  char type = 'F';         // I signed, U unsigned, F float
  std::uint32_t count = 1;
  std::uint32_t offset = 0;  // in a binary record
};

enum class Data { ascii, binary, compressed };

struct Header {
  std::vector<Field> fields;
  double viewpoint[7] = {0, 0, 0, 1, 0, 0, 0};  // tx ty tz qw qx qy qz
  std::vector<std::string> comments;            // the text after "# " (file_metadata.hpp)
  std::uint64_t width = 0, height = 1, points = 0;
  bool have_points = false;
  Data data = Data::ascii;
  std::size_t body = 0;       // first byte after the DATA line
  std::size_t body_line = 0;  // its line number (ascii messages)
  std::uint32_t record = 0;   // bytes of one packed point
};

/// The header of FILE (its first bytes are enough); throws PcdError naming
/// the line or keyword that is wrong.
Header parse_header(std::string_view file);

/// S without the blanks (and a CR) around it.
std::string_view trim(std::string_view s);

/// LINE split at blanks.
std::vector<std::string_view> tokens_of(std::string_view line);

/// At most 40 characters of T, any control byte as '?': a token in a message.
std::string shown(std::string_view t);

}  // namespace treecut::pcd
