// PLY header parsing and validation (see ply_format.hpp for the reference).
#include <array>
#include <charconv>
#include <optional>
#include <unordered_set>

#include "ply_format.hpp"

namespace treecut::ply {

namespace {

struct TypeSpelling {
  std::string_view name;
  Type type;
};

// Both spellings of the spec: the original names and the sized ones.
constexpr std::array<TypeSpelling, 16> kTypeSpellings{{{"char", Type::i8},
                                                       {"int8", Type::i8},
                                                       {"uchar", Type::u8},
                                                       {"uint8", Type::u8},
                                                       {"short", Type::i16},
                                                       {"int16", Type::i16},
                                                       {"ushort", Type::u16},
                                                       {"uint16", Type::u16},
                                                       {"int", Type::i32},
                                                       {"int32", Type::i32},
                                                       {"uint", Type::u32},
                                                       {"uint32", Type::u32},
                                                       {"float", Type::f32},
                                                       {"float32", Type::f32},
                                                       {"double", Type::f64},
                                                       {"float64", Type::f64}}};

std::optional<Type> parse_type(std::string_view name) {
  for (const auto& spelling : kTypeSpellings) {
    if (spelling.name == name) return spelling.type;
  }
  return std::nullopt;
}

bool is_blank(char c) {
  return c == ' ' || c == '\t' || c == '\r';
}

// Splits a header line at blanks. Header lines are short; a line with more
// than kMaxTokens tokens is malformed whatever its keyword.
constexpr std::size_t kMaxTokens = 6;
struct Tokens {
  std::array<std::string_view, kMaxTokens> items;
  std::size_t size = 0;
  bool overflow = false;
};

Tokens split(std::string_view line) {
  Tokens tokens;
  std::size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && is_blank(line[i])) ++i;
    if (i == line.size()) break;
    std::size_t start = i;
    while (i < line.size() && !is_blank(line[i])) ++i;
    if (tokens.size == kMaxTokens) {
      tokens.overflow = true;
      break;
    }
    tokens.items[tokens.size++] = line.substr(start, i - start);
  }
  return tokens;
}

std::uint64_t parse_count(std::string_view text, std::string_view element) {
  if (!text.empty() && text.front() == '-') {
    throw Error("negative element count " + printable(text) + " for element '" +
                printable(element) + "'");
  }
  std::uint64_t count = 0;
  auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), count);
  if (ec == std::errc::result_out_of_range) {
    throw Error("element count " + printable(text) + " for element '" + printable(element) +
                "' is out of range");
  }
  if (ec != std::errc() || end != text.data() + text.size()) {
    throw Error("invalid element count '" + printable(text) + "' for element '" +
                printable(element) + "'");
  }
  return count;
}

Type require_type(std::string_view name) {
  auto type = parse_type(name);
  if (!type) throw Error("unknown property type '" + printable(name) + "'");
  return *type;
}

// Names seen so far, so that a header with many thousands of declarations
// is still checked for duplicates in linear time.
struct SeenNames {
  std::unordered_set<std::string> elements;
  std::unordered_set<std::string> properties;  ///< of the current element
};

void add_property(Header& header, const Tokens& t, SeenNames& seen) {
  if (header.elements.empty()) throw Error("property declared before any element");
  Element& element = header.elements.back();
  Property property;
  if (t.size >= 2 && t.items[1] == "list") {
    if (t.size != 5)
      throw Error("malformed list property line (want: property list TYPE TYPE NAME)");
    property.is_list = true;
    property.count_type = require_type(t.items[2]);
    property.type = require_type(t.items[3]);
    property.name = std::string(t.items[4]);
    if (!is_integral(property.count_type)) {
      throw Error("list property '" + printable(property.name) +
                  "' has a non-integer length type '" + std::string(t.items[2]) + "'");
    }
  } else {
    if (t.size != 3) throw Error("malformed property line (want: property TYPE NAME)");
    property.type = require_type(t.items[1]);
    property.name = std::string(t.items[2]);
  }
  if (!seen.properties.insert(property.name).second) {
    throw Error("element '" + printable(element.name) + "' declares property '" +
                printable(property.name) + "' twice");
  }
  element.properties.push_back(std::move(property));
}

void validate(const Header& header) {
  for (const Element& element : header.elements) {
    if (element.properties.empty()) {
      throw Error("element '" + printable(element.name) + "' has no properties");
    }
  }
  int v = header.find("vertex");
  if (v < 0) throw Error("no vertex element");
  const Element& vertex = header.elements[static_cast<std::size_t>(v)];
  for (std::string_view axis : {"x", "y", "z"}) {
    int p = vertex.find(axis);
    if (p < 0) throw Error("vertex element has no " + std::string(axis) + " property");
    if (vertex.properties[static_cast<std::size_t>(p)].is_list) {
      throw Error("vertex property " + std::string(axis) + " is a list");
    }
  }
  if (vertex.count == 0) throw Error("no points (element vertex 0)");
  for (std::string_view name : {"face", "tristrips"}) {
    int e = header.find(name);
    if (e < 0) continue;
    const Element& element = header.elements[static_cast<std::size_t>(e)];
    for (const Property& p : element.properties) {
      if ((p.name == "vertex_indices" || p.name == "vertex_index") &&
          (!p.is_list || !is_integral(p.type))) {
        throw Error(std::string(name) + " property " + p.name + " is not a list of integers");
      }
    }
  }
}

}  // namespace

std::size_t type_size(Type type) {
  switch (type) {
    case Type::i8:
    case Type::u8:
      return 1;
    case Type::i16:
    case Type::u16:
      return 2;
    case Type::i32:
    case Type::u32:
    case Type::f32:
      return 4;
    case Type::f64:
      return 8;
  }
  return 0;
}

bool is_integral(Type type) {
  return type != Type::f32 && type != Type::f64;
}

std::string_view type_name(Type type) {
  switch (type) {
    case Type::i8:
      return "char";
    case Type::u8:
      return "uchar";
    case Type::i16:
      return "short";
    case Type::u16:
      return "ushort";
    case Type::i32:
      return "int";
    case Type::u32:
      return "uint";
    case Type::f32:
      return "float";
    case Type::f64:
      return "double";
  }
  return "?";
}

int Element::find(std::string_view property_name) const {
  for (std::size_t i = 0; i < properties.size(); ++i) {
    if (properties[i].name == property_name) return static_cast<int>(i);
  }
  return -1;
}

bool Element::has_lists() const {
  for (const Property& p : properties) {
    if (p.is_list) return true;
  }
  return false;
}

std::size_t Element::fixed_stride() const {
  std::size_t stride = 0;
  for (const Property& p : properties) stride += type_size(p.type);
  return stride;
}

int Header::find(std::string_view element_name) const {
  for (std::size_t i = 0; i < elements.size(); ++i) {
    if (elements[i].name == element_name) return static_cast<int>(i);
  }
  return -1;
}

std::string printable(std::string_view text) {
  constexpr std::size_t kMax = 40;
  std::string out;
  for (char c : text.substr(0, kMax)) {
    auto u = static_cast<unsigned char>(c);
    out += (u >= 0x20 && u < 0x7f) ? c : '?';
  }
  if (text.size() > kMax) out += "...";
  return out;
}

std::string_view other_format(std::string_view file) {
  struct Signature {
    std::string_view magic, name;
  };
  static constexpr Signature kKnown[] = {
      {"LASF", "a LAS/LAZ point cloud (LASF signature)"},
      {"ASTM-E57", "an E57 point cloud"},
      {"# .PCD", "a PCL point cloud (.pcd)"},
      {"TCUTHIER", "a treecut cache"},
      {"\x89PNG", "a PNG image"},
      {"\x7F"
       "ELF",
       "an ELF program or library"},
      {"PK\x03\x04", "a ZIP archive"},
      {"\x1f\x8b", "a gzip-compressed file"},
      {"treecut-", "a treecut text file (camera path, scene or script)"},
  };
  for (const Signature& s : kKnown)
    if (file.starts_with(s.magic)) return s.name;
  return {};
}

namespace {

// The two ways a text editor commonly spoils a PLY header, named as such
// rather than as a missing magic line; and other formats, named.
void check_magic_line(std::string_view file) {
  if (file.starts_with("\xEF\xBB\xBF")) {
    throw Error("starts with a UTF-8 byte-order mark (3 bytes before 'ply'); save it without one");
  }
  if (const std::string_view other = other_format(file); !other.empty())
    throw Error("not a PLY file: " + std::string(other));
  const std::size_t newline = file.find('\n');
  const std::string_view first = file.substr(0, newline);
  // "ply" then a CR followed by more text: the lines end in CR alone (a CR
  // that ends the first line is a CRLF file).
  if (first.starts_with("ply\r") && first.size() > 4) {
    throw Error("uses CR-only line endings (classic Mac); convert them to LF or CRLF");
  }
}

}  // namespace

Header parse_header(std::string_view file) {
  if (file.empty()) throw Error("empty file");
  check_magic_line(file);
  Header header;
  bool have_format = false;
  SeenNames seen;
  std::size_t pos = 0;
  std::size_t line_number = 0;
  while (pos < file.size()) {
    std::size_t newline = file.find('\n', pos);
    std::size_t line_end = newline == std::string_view::npos ? file.size() : newline;
    std::string_view line = file.substr(pos, line_end - pos);
    pos = newline == std::string_view::npos ? file.size() : newline + 1;
    ++line_number;
    Tokens t = split(line);

    if (line_number == 1) {
      if (t.size != 1 || t.items[0] != "ply") throw Error("not a PLY file (no 'ply' magic line)");
      continue;
    }
    if (t.size == 0) continue;
    std::string_view keyword = t.items[0];
    // obj_info is part of the spec (as free text like comment) even though
    // OpenMesh's reader mis-parses it; the header we give OpenMesh drops both.
    if (keyword == "comment" && line.size() > 8 && header.comments.size() < 1024) {
      std::string_view text = line.substr(8);
      if (!text.empty() && text.back() == '\r') text.remove_suffix(1);
      header.comments.emplace_back(text);
    }
    if (keyword == "comment" || keyword == "obj_info") continue;
    if (t.overflow) throw Error("malformed header line " + std::to_string(line_number));
    if (keyword == "format") {
      if (have_format) throw Error("second format line");
      if (t.size != 3) throw Error("malformed format line");
      if (t.items[1] == "ascii") {
        header.format = Format::ascii;
      } else if (t.items[1] == "binary_little_endian") {
        header.format = Format::binary_little_endian;
      } else if (t.items[1] == "binary_big_endian") {
        header.format = Format::binary_big_endian;
      } else {
        throw Error("unknown format '" + printable(t.items[1]) + "'");
      }
      if (t.items[2] != "1.0" && t.items[2] != "1") {
        throw Error("unsupported PLY version '" + printable(t.items[2]) + "'");
      }
      have_format = true;
    } else if (keyword == "element") {
      if (!have_format) throw Error("element declared before the format line");
      if (t.size != 3) throw Error("malformed element line (want: element NAME COUNT)");
      Element element;
      element.name = std::string(t.items[1]);
      element.count = parse_count(t.items[2], element.name);
      element.count_at = static_cast<std::size_t>(t.items[2].data() - file.data());
      element.count_size = t.items[2].size();
      if (!seen.elements.insert(element.name).second) {
        throw Error("element '" + printable(element.name) + "' declared twice");
      }
      seen.properties.clear();
      header.elements.push_back(std::move(element));
    } else if (keyword == "property") {
      add_property(header, t, seen);
    } else if (keyword == "end_header") {
      if (t.size != 1) throw Error("malformed end_header line");
      if (!have_format) throw Error("no format line");
      header.body_offset = pos;
      header.body_line = line_number + 1;
      validate(header);
      return header;
    } else {
      throw Error("unknown header keyword '" + printable(keyword) + "' on line " +
                  std::to_string(line_number));
    }
  }
  throw Error("header never ends (no end_header line)");
}

}  // namespace treecut::ply
