// Body validation and row decoding for binary and ascii PLY bodies.
#include <array>
#include <bit>
#include <charconv>
#include <cmath>
#include <cstring>
#include <limits>

#include "ply_format.hpp"

namespace treecut::ply {

namespace {

template <class T>
T load(const char* p, bool big_endian) {
  std::array<char, sizeof(T)> bytes;
  std::memcpy(bytes.data(), p, sizeof(T));
  if (big_endian != (std::endian::native == std::endian::big)) {
    for (std::size_t i = 0; i < sizeof(T) / 2; ++i) std::swap(bytes[i], bytes[sizeof(T) - 1 - i]);
  }
  T value;
  std::memcpy(&value, bytes.data(), sizeof(T));
  return value;
}

// List lengths, decoded inline: the layout walk reads one per face row.
inline std::int64_t load_length(const char* p, Type type, bool big_endian) {
  switch (type) {
    case Type::i8:
      return load<std::int8_t>(p, big_endian);
    case Type::u8:
      return static_cast<unsigned char>(*p);
    case Type::i16:
      return load<std::int16_t>(p, big_endian);
    case Type::u16:
      return load<std::uint16_t>(p, big_endian);
    case Type::i32:
      return load<std::int32_t>(p, big_endian);
    case Type::u32:
      return load<std::uint32_t>(p, big_endian);
    default:
      return -1;  // the header only allows integer length types
  }
}

std::string row_context(const Element& element, std::uint64_t row) {
  return "element '" + printable(element.name) + "' row " + std::to_string(row + 1) + " of " +
         std::to_string(element.count);
}

// List lengths are bounded by the bytes that follow, but a length that does not
// fit an int could not be handed to OpenMesh (which stores it in an int).
constexpr std::int64_t kMaxListLength = std::numeric_limits<std::int32_t>::max();

double integral_max(Type type) {
  switch (type) {
    case Type::i8:
      return 127;
    case Type::u8:
      return 255;
    case Type::i16:
      return 32767;
    case Type::u16:
      return 65535;
    case Type::i32:
      return 2147483647.0;
    case Type::u32:
      return 4294967295.0;
    default:
      return 0;
  }
}

double integral_min(Type type) {
  switch (type) {
    case Type::i8:
      return -128;
    case Type::i16:
      return -32768;
    case Type::i32:
      return -2147483648.0;
    default:
      return 0;
  }
}

// Ascii numbers: std::from_chars (locale-independent, no allocation), which
// does not take a leading '+', so one is skipped here. Overflow is an error;
// underflow (a negative exponent out of range) reads as zero.
bool parse_number(std::string_view token, Type type, double& out) {
  const char* begin = token.data();
  const char* end = begin + token.size();
  if (begin != end && *begin == '+' && end - begin > 1 && begin[1] != '-' && begin[1] != '+') {
    ++begin;
  }
  if (is_integral(type)) {
    std::int64_t value = 0;
    auto [ptr, ec] = std::from_chars(begin, end, value);
    if (ec != std::errc() || ptr != end) return false;
    out = static_cast<double>(value);
    return out >= integral_min(type) && out <= integral_max(type);
  }
  auto underflow = [&] {
    out = 0.0;
    return token.find("e-") != std::string_view::npos || token.find("E-") != std::string_view::npos;
  };
  if (type == Type::f32) {
    float value = 0.0f;
    auto [ptr, ec] = std::from_chars(begin, end, value);
    if (ptr != end) return false;
    if (ec == std::errc::result_out_of_range) return underflow();
    if (ec != std::errc()) return false;
    out = value;
    return true;
  }
  double value = 0.0;
  auto [ptr, ec] = std::from_chars(begin, end, value);
  if (ptr != end) return false;
  if (ec == std::errc::result_out_of_range) return underflow();
  if (ec != std::errc()) return false;
  out = value;
  return true;
}

}  // namespace

double load_scalar(const char* p, Type type, bool big_endian) {
  switch (type) {
    case Type::i8:
      return load<std::int8_t>(p, big_endian);
    case Type::u8:
      return load<std::uint8_t>(p, big_endian);
    case Type::i16:
      return load<std::int16_t>(p, big_endian);
    case Type::u16:
      return load<std::uint16_t>(p, big_endian);
    case Type::i32:
      return load<std::int32_t>(p, big_endian);
    case Type::u32:
      return load<std::uint32_t>(p, big_endian);
    case Type::f32:
      return load<float>(p, big_endian);
    case Type::f64:
      return load<double>(p, big_endian);
  }
  return 0.0;
}

float to_float(double value) {
  constexpr double kMax = std::numeric_limits<float>::max();
  if (value > kMax) return std::numeric_limits<float>::infinity();
  if (value < -kMax) return -std::numeric_limits<float>::infinity();
  return static_cast<float>(value);
}

std::uint8_t color_channel(double value, Type type) {
  if (std::isnan(value)) return 0;
  double scaled = value;
  if (!is_integral(type)) {
    scaled = std::round(value * 255.0);
  } else if (type == Type::u16 || type == Type::i16) {
    scaled = std::round(value / 257.0);
  }
  if (scaled <= 0.0) return 0;
  if (scaled >= 255.0) return 255;
  return static_cast<std::uint8_t>(scaled);
}

namespace {

// The walk of one element from POS; throws Error when it does not match its header.
std::size_t walk_element(const Element& element, std::string_view file, std::size_t pos,
                         bool big_endian) {
  const std::size_t end = file.size();
  if (!element.has_lists()) {
    const std::size_t stride = element.fixed_stride();
    const std::size_t left = end - pos;
    if (element.count > left / stride) {
      // The row it ends in, so the message names the row as for list elements.
      throw Error("binary body is truncated inside " + row_context(element, left / stride) + " (" +
                  std::to_string(element.count) + (element.count == 1 ? " row of " : " rows of ") +
                  std::to_string(stride) + " bytes, only " + std::to_string(left) +
                  " bytes are left)");
    }
    pos += static_cast<std::size_t>(element.count) * stride;
  } else {
    // Per-property sizes hoisted out of the row loop: this walk visits every
    // face of a mesh before OpenMesh reads it.
    struct Step {
      bool is_list;
      Type count_type;
      std::size_t count_size;
      std::size_t size;
    };
    std::vector<Step> steps;
    for (const Property& p : element.properties) {
      steps.push_back({p.is_list, p.count_type, type_size(p.count_type), type_size(p.type)});
    }
    for (std::uint64_t row = 0; row < element.count; ++row) {
      for (const Step& step : steps) {
        std::size_t n = 1;
        if (step.is_list) {
          if (end - pos < step.count_size) {
            throw Error("binary body is truncated inside " + row_context(element, row));
          }
          const std::int64_t length = load_length(file.data() + pos, step.count_type, big_endian);
          pos += step.count_size;
          if (length < 0) {
            throw Error("negative list length in " + row_context(element, row));
          }
          if (length > kMaxListLength) {
            throw Error("list too long in " + row_context(element, row));
          }
          n = static_cast<std::size_t>(length);
        }
        if (n > (end - pos) / step.size) {
          throw Error("binary body is truncated inside " + row_context(element, row));
        }
        pos += n * step.size;
      }
    }
  }
  return pos;
}

}  // namespace

BinaryLayout binary_layout(const Header& header, std::string_view file) {
  const bool big_endian = header.format == Format::binary_big_endian;
  const int vertex = header.find("vertex");
  BinaryLayout layout;
  std::size_t pos = header.body_offset;
  for (std::size_t e = 0; e < header.elements.size(); ++e) {
    Range range{pos, pos};
    try {
      pos = walk_element(header.elements[e], file, pos, big_endian);
    } catch (const Error& error) {
      // Up to the vertex element a problem hides the vertex rows: an error.
      // After it, the points are intact and only this element and the ones
      // after it are lost.
      if (static_cast<int>(e) == vertex) throw;
      if (static_cast<int>(e) < vertex) {
        throw Error(std::string(error.what()) + ", so the vertex element after it cannot be found");
      }
      layout.broken = static_cast<int>(e);
      layout.problem = error.what();
      return layout;
    }
    range.end = pos;
    layout.elements.push_back(range);
  }
  layout.trailing_bytes = file.size() - pos;
  return layout;
}

void check_ascii_capacity(const Header& header, std::string_view file) {
  const std::size_t body = file.size() - header.body_offset;
  const std::uint64_t capacity = (static_cast<std::uint64_t>(body) + 1) / 2;
  std::uint64_t needed = 0;
  const int vertex = header.find("vertex");
  for (int e = 0; e <= vertex; ++e) {
    const Element& element = header.elements[static_cast<std::size_t>(e)];
    // A list needs at least its length token, a scalar its value.
    const std::uint64_t per_row = element.properties.size();
    if (element.count > (capacity - needed) / per_row) {
      throw Error("ascii body of " + std::to_string(body) + " bytes is too short for element '" +
                  printable(element.name) + "' (" + std::to_string(element.count) + " rows)");
    }
    needed += element.count * per_row;
  }
}

BinaryRows::BinaryRows(const Element& element, std::string_view bytes, bool big_endian)
    : element_(element), bytes_(bytes), big_endian_(big_endian) {}

void BinaryRows::next(Row& row) {
  const std::size_t props = element_.properties.size();
  row.values.clear();
  row.first.resize(props);
  row.size.resize(props);
  for (std::size_t i = 0; i < props; ++i) {
    const Property& p = element_.properties[i];
    std::size_t n = 1;
    if (p.is_list) {
      const std::size_t count_size = type_size(p.count_type);
      if (bytes_.size() - pos_ < count_size) throw Error("binary row overruns its element");
      double length = load_scalar(bytes_.data() + pos_, p.count_type, big_endian_);
      pos_ += count_size;
      if (length < 0 || length > kMaxListLength) throw Error("invalid list length");
      n = static_cast<std::size_t>(length);
    }
    const std::size_t size = type_size(p.type);
    if (n > (bytes_.size() - pos_) / size) throw Error("binary row overruns its element");
    row.first[i] = row.values.size();
    row.size[i] = n;
    for (std::size_t k = 0; k < n; ++k) {
      row.values.push_back(load_scalar(bytes_.data() + pos_, p.type, big_endian_));
      pos_ += size;
    }
  }
}

AsciiRows::AsciiRows(std::string_view file, const Header& header)
    : file_(file), pos_(header.body_offset), line_(header.body_line - 1) {}

bool AsciiRows::next_line(std::string_view& line) {
  while (pos_ < file_.size()) {
    const char* start = file_.data() + pos_;
    const std::size_t left = file_.size() - pos_;
    const void* newline = std::memchr(start, '\n', left);
    const std::size_t length =
        newline ? static_cast<std::size_t>(static_cast<const char*>(newline) - start) : left;
    pos_ += newline ? length + 1 : length;
    ++line_;
    line = std::string_view(start, length);
    for (char c : line) {
      if (c != ' ' && c != '\t' && c != '\r') return true;
    }
  }
  return false;
}

void AsciiRows::next(const Element& element, std::uint64_t row_index, Row& row) {
  std::string_view line;
  if (!next_line(line)) {
    throw Error("ascii body ends before " + row_context(element, row_index));
  }
  std::size_t i = 0;
  auto next_token = [&](std::string_view& token) {
    while (i < line.size() && (line[i] == ' ' || line[i] == '\t' || line[i] == '\r')) ++i;
    if (i == line.size()) return false;
    std::size_t start = i;
    while (i < line.size() && line[i] != ' ' && line[i] != '\t' && line[i] != '\r') ++i;
    token = line.substr(start, i - start);
    return true;
  };
  auto where = [&] {
    return "line " + std::to_string(line_) + " (" + row_context(element, row_index) + ")";
  };
  auto value = [&](const Property& p, Type type, double& out) {
    std::string_view token;
    if (!next_token(token)) {
      throw Error(where() + ": too few values, property '" + printable(p.name) + "' is missing");
    }
    if (!parse_number(token, type, out)) {
      throw Error(where() + ": '" + printable(token) + "' is not a valid " +
                  std::string(type_name(type)) + " for property '" + printable(p.name) + "'");
    }
  };

  const std::size_t props = element.properties.size();
  row.values.clear();
  row.first.resize(props);
  row.size.resize(props);
  for (std::size_t k = 0; k < props; ++k) {
    const Property& p = element.properties[k];
    std::size_t n = 1;
    if (p.is_list) {
      double length = 0;
      value(p, p.count_type, length);
      if (length < 0) throw Error(where() + ": negative list length");
      // Each item needs at least two characters of this line, which bounds
      // the loop below by the line length rather than by the number.
      if (length > static_cast<double>(line.size() - i) ||
          length > static_cast<double>(kMaxListLength)) {
        throw Error(where() + ": list '" + printable(p.name) + "' is longer than its line");
      }
      n = static_cast<std::size_t>(length);
    }
    row.first[k] = row.values.size();
    row.size[k] = n;
    for (std::size_t item = 0; item < n; ++item) {
      double v = 0;
      value(p, p.type, v);
      row.values.push_back(v);
    }
  }
  std::string_view extra;
  if (next_token(extra)) {
    throw Error(where() + ": more values than the header declares ('" + printable(extra) + "')");
  }
}

void AsciiRows::skip(const Element& element, std::uint64_t row_index) {
  next(element, row_index, scratch_);
}

bool AsciiRows::skip_line() {
  std::string_view line;
  return next_line(line);
}

std::size_t AsciiRows::trailing_lines() {
  std::size_t count = 0;
  std::string_view line;
  while (next_line(line)) ++count;
  return count;
}

}  // namespace treecut::ply
