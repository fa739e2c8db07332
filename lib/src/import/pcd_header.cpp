// The header of a PCD file, line by line (pcd_header.hpp), and what tells a
// PCD from other files: looks_like_pcd, is_own_pcd (treecut/pcd.hpp).
#include "pcd_header.hpp"

#include <algorithm>
#include <charconv>
#include <string>

#include "little_endian.hpp"
#include "treecut/file_io.hpp"
#include "treecut/pcd.hpp"

namespace treecut {

namespace pcd {

std::string_view trim(std::string_view s) {
  while (!s.empty() && (s.back() == '\r' || s.back() == ' ' || s.back() == '\t'))
    s.remove_suffix(1);
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  return s;
}

std::vector<std::string_view> tokens_of(std::string_view line) {
  std::vector<std::string_view> out;
  std::size_t at = 0;
  while (at < line.size()) {
    at = line.find_first_not_of(" \t", at);
    if (at == std::string_view::npos) break;
    const std::size_t end = std::min(line.find_first_of(" \t", at), line.size());
    out.push_back(line.substr(at, end - at));
    at = end;
  }
  return out;
}

std::string shown(std::string_view t) {
  std::string s(t.substr(0, 40));
  for (char& c : s) {
    if (static_cast<unsigned char>(c) < 0x20 || static_cast<unsigned char>(c) >= 0x7f) c = '?';
  }
  return s;
}

namespace {

std::uint64_t whole(std::string_view keyword, std::string_view t) {
  std::uint64_t v = 0;
  const auto [end, ec] = std::from_chars(t.data(), t.data() + t.size(), v);
  if (ec != std::errc() || end != t.data() + t.size()) {
    throw PcdError(std::string(keyword) + ": '" + shown(t) + "' is not a whole number");
  }
  return v;
}

// The per-field lines (SIZE, TYPE, COUNT) after FIELDS: one value a field.
void per_field(std::string_view keyword, const std::vector<std::string_view>& t, Header& h) {
  if (h.fields.empty()) throw PcdError(std::string(keyword) + " before FIELDS");
  if (t.size() - 1 != h.fields.size()) {
    throw PcdError(std::string(keyword) + " has " + std::to_string(t.size() - 1) + " values for " +
                   std::to_string(h.fields.size()) + " fields");
  }
  for (std::size_t i = 0; i < h.fields.size(); ++i) {
    Field& f = h.fields[i];
    const std::string_view v = t[i + 1];
    if (keyword == "TYPE") {
      if (v != "I" && v != "U" && v != "F") {
        throw PcdError("TYPE '" + shown(v) + "' of field " + f.name + " (I, U or F)");
      }
      f.type = v[0];
    } else if (keyword == "SIZE") {
      f.size = static_cast<std::uint32_t>(std::min<std::uint64_t>(whole(keyword, v), 1u << 20));
    } else {
      const std::uint64_t c = whole(keyword, v);
      if (c == 0 || c > 100000)
        throw PcdError("COUNT " + std::to_string(c) + " of field " + f.name);
      f.count = static_cast<std::uint32_t>(c);
    }
  }
}

}  // namespace

Header parse_header(std::string_view file) {
  Header h;
  std::size_t at = 0, line_number = 0;
  bool have_size = false, have_type = false;
  while (at < file.size()) {
    const std::size_t end = std::min(file.find('\n', at), file.size());
    const std::string_view line = trim(file.substr(at, end - at));
    at = end + 1;
    ++line_number;
    if (!line.empty() && line.front() == '#' && h.comments.size() < 1024) {
      std::string_view text = line.substr(1);
      if (!text.empty() && text.front() == ' ') text.remove_prefix(1);
      h.comments.emplace_back(text);
    }
    if (line.empty() || line.front() == '#') continue;
    const std::vector<std::string_view> t = tokens_of(line);
    const std::string_view k = t.front();
    if (k == "VERSION") continue;
    if (k == "FIELDS" || k == "COLUMNS") {
      if (t.size() < 2) throw PcdError("FIELDS names no field");
      if (t.size() > 1025) throw PcdError("FIELDS names more than 1024 fields");
      h.fields.clear();
      for (std::size_t i = 1; i < t.size(); ++i) h.fields.push_back({std::string(t[i])});
    } else if (k == "SIZE" || k == "TYPE" || k == "COUNT") {
      per_field(k, t, h);
      have_size |= k == "SIZE";
      have_type |= k == "TYPE";
    } else if (k == "WIDTH" || k == "HEIGHT" || k == "POINTS") {
      if (t.size() != 2) throw PcdError(std::string(k) + " needs one number");
      const std::uint64_t v = whole(k, t[1]);
      (k == "WIDTH" ? h.width : k == "HEIGHT" ? h.height : h.points) = v;
      if (k == "POINTS") h.have_points = true;
    } else if (k == "VIEWPOINT") {
      if (t.size() != 8) throw PcdError("VIEWPOINT needs 7 numbers (tx ty tz qw qx qy qz)");
      for (std::size_t i = 0; i < 7; ++i) {
        const std::string_view v = t[i + 1];
        double x = 0;
        const auto [stop, ec] = std::from_chars(v.data(), v.data() + v.size(), x);
        if (ec != std::errc() || stop != v.data() + v.size() || !std::isfinite(x))
          throw PcdError("VIEWPOINT: '" + shown(v) + "' is not a finite number");
        h.viewpoint[i] = x;
      }
    } else if (k == "DATA") {
      if (t.size() != 2 || (t[1] != "ascii" && t[1] != "binary" && t[1] != "binary_compressed")) {
        throw PcdError("DATA '" + shown(t.size() > 1 ? t[1] : "") +
                       "' (ascii, binary or binary_compressed)");
      }
      h.data = t[1] == "ascii" ? Data::ascii : t[1] == "binary" ? Data::binary : Data::compressed;
      h.body = std::min(at, file.size());
      h.body_line = line_number + 1;
      break;
    } else {
      throw PcdError(std::to_string(line_number) + ": unknown header line '" + shown(line) + "'");
    }
  }
  if (h.body == 0) throw PcdError("no DATA line (the header never ends)");
  if (h.fields.empty()) throw PcdError("no FIELDS line");
  if (!have_size || !have_type) throw PcdError("the header needs SIZE and TYPE lines");
  if (!h.have_points) h.points = h.width * h.height;
  if (h.width == 0 || h.height == 0 || h.points == 0)
    throw PcdError("no points (WIDTH, HEIGHT or POINTS is 0)");
  if (h.width > (std::uint64_t{1} << 32) || h.height > (std::uint64_t{1} << 32) ||
      h.width * h.height != h.points) {
    throw PcdError("WIDTH " + std::to_string(h.width) + " x HEIGHT " + std::to_string(h.height) +
                   " is not POINTS " + std::to_string(h.points));
  }
  if (h.points >= (std::uint64_t{1} << 31)) throw PcdError("more than 2^31 points");
  std::uint64_t record = 0;
  for (Field& f : h.fields) {
    const bool ok = f.type == 'F' ? (f.size == 4 || f.size == 8)
                                  : (f.size == 1 || f.size == 2 || f.size == 4 || f.size == 8);
    if (!ok) {
      throw PcdError("field " + shown(f.name) + ": TYPE " + std::string(1, f.type) + " of SIZE " +
                     std::to_string(f.size) + " (I and U: 1, 2, 4, 8; F: 4, 8)");
    }
    f.offset = static_cast<std::uint32_t>(record);
    record += std::uint64_t{f.size} * f.count;
    if (record > (1u << 24)) throw PcdError("a point record of more than 16 MiB");
  }
  h.record = static_cast<std::uint32_t>(record);
  return h;
}

}  // namespace pcd

using namespace pcd;

bool looks_like_pcd(std::string_view bytes) {
  // PCL's own first line; else the first line that is no comment opens a
  // header (any of its keywords: WIDTH may come before VERSION).
  if (bytes.starts_with("# .PCD")) return true;
  static constexpr std::string_view kKeywords[] = {"VERSION",   "FIELDS", "COLUMNS", "SIZE",
                                                   "TYPE",      "COUNT",  "WIDTH",   "HEIGHT",
                                                   "VIEWPOINT", "POINTS", "DATA"};
  std::size_t at = 0;
  while (at < bytes.size()) {
    const std::size_t end = std::min(bytes.find('\n', at), bytes.size());
    const std::string_view line = trim(bytes.substr(at, end - at));
    at = end + 1;
    if (line.empty() || line.front() == '#') continue;
    const std::string_view first = line.substr(0, line.find_first_of(" \t"));
    return std::find(std::begin(kKeywords), std::end(kKeywords), first) != std::end(kKeywords);
  }
  return false;
}

bool is_own_pcd(const std::filesystem::path& path) {
  const FileHead head = read_file_head(path, 65536);
  if (!head.bytes.starts_with(kPcdSignature)) return false;
  try {
    // The header parses and the body is the size it says: a packed body
    // exactly, a compressed one its two sizes and the block.
    const Header h = parse_header(head.bytes);
    switch (h.data) {
      case Data::binary:
        return head.size == h.body + h.points * h.record;
      case Data::compressed: {
        if (head.bytes.size() < h.body + 8) return false;
        const auto* p = reinterpret_cast<const unsigned char*>(head.bytes.data()) + h.body;
        return head.size == h.body + 8 + detail::get_le<std::uint32_t>(p);
      }
      case Data::ascii:
        // save_pcd's ascii body is not what `gen` or `export` write, and its
        // end cannot be told from a note appended to it without reading it
        // all: never treecut's own to replace.
        return false;
    }
  } catch (const std::exception&) {
  }
  return false;
}

}  // namespace treecut
