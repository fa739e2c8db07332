// The PLY structure as our guard sees it: a header model, the exact byte layout
// of a binary body, and row decoders for binary and ascii bodies.
//
// Format reference: Greg Turk, "The PLY Polygon File Format" (1994), as
// documented by Paul Bourke. Everything here treats the file as untrusted bytes:
// every count is checked against the bytes that are actually there before it is
// used to size anything, and every failure is a ply::Error whose message is the
// problem alone (load_ply prefixes the path).
#pragma once

#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

namespace treecut::ply {

/// Malformed content. The message is one line without the file name.
class Error : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

enum class Format : std::uint8_t { ascii, binary_little_endian, binary_big_endian };

/// The eight scalar types of the PLY spec (each has two spellings).
enum class Type : std::uint8_t { i8, u8, i16, u16, i32, u32, f32, f64 };

std::size_t type_size(Type type);
bool is_integral(Type type);
/// The spelling OpenMesh's PLY reader understands for every type.
std::string_view type_name(Type type);

struct Property {
  std::string name;
  Type type = Type::f32;  ///< the scalar type, or the item type of a list
  bool is_list = false;
  Type count_type = Type::u8;  ///< list length type (integral), lists only
};

struct Element {
  std::string name;
  std::uint64_t count = 0;
  /// Where COUNT is written in the header (its first byte and length): a
  /// streamed read writes a header for part of the rows (PlyReader).
  std::size_t count_at = 0, count_size = 0;
  std::vector<Property> properties;

  /// Index of the property called NAME, or -1.
  [[nodiscard]] int find(std::string_view property_name) const;
  [[nodiscard]] bool has_lists() const;
  /// Bytes per row in a binary body; only meaningful without lists.
  [[nodiscard]] std::size_t fixed_stride() const;
};

struct Header {
  Format format = Format::ascii;
  std::vector<Element> elements;
  std::size_t body_offset = 0;  ///< first byte after the end_header line
  std::size_t body_line = 0;    ///< 1-based line number of the first body line
  /// The text of the comment lines (after "comment "), for treecut's own
  /// metadata (file_metadata.hpp).
  std::vector<std::string> comments;

  /// Index of the element called NAME, or -1.
  [[nodiscard]] int find(std::string_view element_name) const;
};

/// Point-cloud and image formats a user may hand treecut by mistake, by the
/// signature FILE starts with ("an E57 point cloud", "a PNG image"), named
/// rather than "no 'ply' magic line"; empty for none of them.
std::string_view other_format(std::string_view file);

/// Parses and validates the header: magic, format line, element and property
/// declarations with known types, unique names, a vertex element with scalar
/// x/y/z and at least one row, integer vertex_indices lists. Throws Error.
Header parse_header(std::string_view file);

/// Byte range [begin, end) of one element's rows in the file.
struct Range {
  std::size_t begin = 0;
  std::size_t end = 0;
};

struct BinaryLayout {
  /// One per header element before `broken` (all of them when nothing broke),
  /// in header order.
  std::vector<Range> elements;
  std::size_t trailing_bytes = 0;  ///< 0 when an element broke
  /// Index of the first element after the vertex element that does not match
  /// its header (truncated, a list length out of range), or -1. It and every
  /// element after it cannot be located; the vertex rows are intact.
  int broken = -1;
  std::string problem;  ///< what is wrong with element `broken`, one line
};

/// Walks a binary body: fixed-size elements are sized by arithmetic, elements
/// with lists row by row, every read bounds-checked. Throws Error when the
/// vertex element (or one before it) is shorter than the header promises or a
/// list length there is out of range; the same problem in a later element
/// only ends the walk (see BinaryLayout::broken): only the vertex element
/// decides whether a file loads.
BinaryLayout binary_layout(const Header& header, std::string_view file);

/// Cheap upper bound for an ascii body: every value needs at least one
/// character and one separator, so a body of B bytes holds at most (B + 1) / 2
/// values. Throws Error when the rows up to and including the vertex element
/// cannot possibly fit, so absurd counts fail before anything is reserved.
/// Later elements are not sized from their counts (they are read row by row,
/// and a short one is a warning), so their counts are not checked here.
void check_ascii_capacity(const Header& header, std::string_view file);

/// One decoded row: the values of every property in declaration order, list
/// items flattened (the length itself is not stored).
struct Row {
  std::vector<double> values;
  std::vector<std::size_t> first;  ///< per property: index of its first value
  std::vector<std::size_t> size;   ///< per property: number of values (1 for scalars)

  [[nodiscard]] double scalar(int property) const {
    return values[first[static_cast<std::size_t>(property)]];
  }
};

/// Decodes rows of one binary element from a validated range.
class BinaryRows {
 public:
  BinaryRows(const Element& element, std::string_view bytes, bool big_endian);
  /// Decodes the next row; throws Error if the range ends inside it.
  void next(Row& row);

 private:
  const Element& element_;
  std::string_view bytes_;
  std::size_t pos_ = 0;
  bool big_endian_;
};

/// Decodes ascii rows, one row per non-blank line, checking that every token
/// is a number of the declared type and that each line holds exactly one row.
class AsciiRows {
 public:
  AsciiRows(std::string_view file, const Header& header);
  /// Decodes row ROW_INDEX of ELEMENT from the next non-blank line.
  void next(const Element& element, std::uint64_t row_index, Row& row);
  /// Skips a row of ELEMENT, still checking every token.
  void skip(const Element& element, std::uint64_t row_index);
  /// Skips the next non-blank line without looking at it (the rest of an
  /// element that no longer matches its header). False at the end of the body.
  bool skip_line();
  /// Number of non-blank lines after the last row.
  std::size_t trailing_lines();

 private:
  bool next_line(std::string_view& line);

  std::string_view file_;
  std::size_t pos_;
  std::size_t line_;  ///< number of the line last returned
  Row scratch_;
};

/// Reads a scalar of TYPE from P (at least type_size(type) bytes).
double load_scalar(const char* p, Type type, bool big_endian);

/// Double to float without undefined behaviour: out-of-range values become
/// +-infinity, NaN stays NaN.
float to_float(double value);

/// One colour channel: integer types are clamped to [0, 255] (16-bit types are
/// scaled down), float types map [0, 1] to [0, 255] with rounding; NaN -> 0.
std::uint8_t color_channel(double value, Type type);

/// TEXT made safe for a one-line message: at most 40 characters, control and
/// non-ASCII bytes replaced by '?'.
std::string printable(std::string_view text);

}  // namespace treecut::ply
