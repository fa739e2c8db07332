// Text point clouds (XYZ, PTS, CSV; treecut/text_cloud.hpp): every line
// parsed and checked, positions in double relative to an origin where they
// need one (position_frame.hpp).
#include "treecut/text_cloud.hpp"

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstring>
#include <fstream>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "attribute_column.hpp"
#include "position_frame.hpp"
#include "treecut/error.hpp"
#include "treecut/file_io.hpp"
#include "unit_normal.hpp"

namespace treecut {

namespace {

class TextError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

constexpr std::string_view kSeparators = " \t,;";

// The tokens of a line, split at runs of separators (a trailing CR goes).
void split(std::string_view line, std::vector<std::string_view>& out) {
  out.clear();
  if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
  std::size_t at = 0;
  while (at < line.size()) {
    at = line.find_first_not_of(kSeparators, at);
    if (at == std::string_view::npos) break;
    const std::size_t end = std::min(line.find_first_of(kSeparators, at), line.size());
    out.push_back(line.substr(at, end - at));
    at = end;
  }
}

bool parse_number(std::string_view t, double& v) {
  if (!t.empty() && t.front() == '+') t.remove_prefix(1);
  const auto [end, ec] = std::from_chars(t.data(), t.data() + t.size(), v);
  return ec == std::errc() && end == t.data() + t.size() && std::isfinite(v);
}

// A number, or no value: "nan" (an organized cloud's hole, an attribute
// without a value), as the PCD reader takes it.
bool parse_value(std::string_view t, double& v) {
  if (t == "nan" || t == "NaN" || t == "-nan" || t == "NAN") {
    v = std::numeric_limits<double>::quiet_NaN();
    return true;
  }
  return parse_number(t, v);
}

bool all_numbers(const std::vector<std::string_view>& tokens) {
  double v;
  return !tokens.empty() && std::all_of(tokens.begin(), tokens.end(),
                                        [&](std::string_view t) { return parse_value(t, v); });
}

bool comment(std::string_view line) {
  const std::size_t at = line.find_first_not_of(" \t");
  return at == std::string_view::npos || line[at] == '#' ||
         (line.substr(at, 2) == "//" && line.substr(at, 3) != "//x" && line.substr(at, 3) != "//X");
}

// What each column holds; -1: absent.
struct Columns {
  int count = 0;
  int xyz[3] = {-1, -1, -1};
  int rgb[3] = {-1, -1, -1};
  int normal[3] = {-1, -1, -1};
  std::vector<std::pair<int, std::string>> attributes;  // column, name
  /// The first few columns not kept, and how many there are (a line of 25
  /// million numbers must not make a warning of 25 million names).
  std::vector<std::string> not_kept;
  std::size_t not_kept_count = 0;
  /// What sets the count, for a line that has another.
  std::string count_from = "the first line of points has";

  void keep(int column, std::string name) {
    if (attributes.size() < kMaxAttributes) {
      attributes.emplace_back(column, std::move(name));
    } else {
      not_keep(std::move(name));
    }
  }
  void not_keep(std::string name) {
    if (not_kept.size() < 8) not_kept.push_back(std::move(name));
    ++not_kept_count;
  }
  [[nodiscard]] std::string not_kept_text() const {
    std::string out = detail::join(not_kept);
    if (not_kept_count > not_kept.size())
      out += " and " + std::to_string(not_kept_count - not_kept.size()) + " more";
    return out;
  }
};

std::string lower(std::string_view t) {
  std::string s;
  for (const char c : t) {
    if (c != '"' && c != '\'')
      s.push_back(static_cast<char>(std::tolower(static_cast<unsigned char>(c))));
  }
  if (s.rfind("//", 0) == 0) s.erase(0, 2);
  return s;
}

// "x, y, z" of NAMES, the first few.
std::string names_text(const std::vector<std::string_view>& names) {
  std::vector<std::string> shown;
  for (std::size_t i = 0; i < names.size() && i < 8; ++i)
    shown.push_back(std::string(names[i].substr(0, 24)));
  std::string text = detail::join(shown);
  if (names.size() > 8) text += " and " + std::to_string(names.size() - 8) + " more";
  return text;
}

Columns from_header(const std::vector<std::string_view>& names) {
  Columns c;
  c.count = static_cast<int>(names.size());
  static constexpr const char* kAxis[3] = {"x", "y", "z"};
  static const std::vector<std::vector<std::string_view>> kRoles = {
      {"x", "east", "easting"},
      {"y", "north", "northing"},
      {"z", "height", "elevation", "alt", "altitude"},
      {"r", "red"},
      {"g", "green"},
      {"b", "blue"},
      {"nx", "normal_x", "normalx"},
      {"ny", "normal_y", "normaly"},
      {"nz", "normal_z", "normalz"}};
  for (int i = 0; i < c.count; ++i) {
    const std::string n = lower(names[static_cast<std::size_t>(i)]);
    if (n == "_" || n == "skip") continue;  // a column nobody wants
    int role = -1;
    for (std::size_t k = 0; k < kRoles.size() && role < 0; ++k) {
      if (std::find(kRoles[k].begin(), kRoles[k].end(), n) != kRoles[k].end()) role = int(k);
    }
    int* slot = role < 0   ? nullptr
                : role < 3 ? &c.xyz[role]
                : role < 6 ? &c.rgb[role - 3]
                           : &c.normal[role - 6];
    if (slot != nullptr && *slot >= 0 && role < 3) {
      // A position named twice is a mistake, not an attribute.
      throw TextError("the header names " + std::string(kAxis[role]) + " twice (columns " +
                      std::to_string(*slot + 1) + " and " + std::to_string(i + 1) + ": " +
                      names_text(names) + ")");
    }
    if (slot != nullptr && *slot < 0) {
      *slot = i;
    } else {
      c.keep(i, n.empty() ? "column_" + std::to_string(i + 1) : n);
    }
  }
  std::vector<std::string> missing;
  for (int a = 0; a < 3; ++a) {
    if (c.xyz[a] < 0) missing.push_back(kAxis[a]);
  }
  if (!missing.empty()) {
    throw TextError("the header names no " + detail::join(missing) + " column" +
                    (missing.size() > 1 ? "s" : "") + " (it names " + names_text(names) + ")");
  }
  // A colour or a normal is kept only whole: red without green is not kept.
  for (int* triple : {c.rgb, c.normal}) {
    if (triple[0] >= 0 && triple[1] >= 0 && triple[2] >= 0) continue;
    for (int k = 0; k < 3; ++k) {
      if (triple[k] >= 0) c.not_keep(std::string(names[static_cast<std::size_t>(triple[k])]));
      triple[k] = -1;
    }
  }
  return c;
}

bool byte_colour(std::string_view t) {
  double v;
  return parse_number(t, v) && v == std::floor(v) && v >= 0 && v <= 255;
}

// Without a header: by the count (and, for 6, whether the last three are
// colours on the first lines: `colours6`).
Columns from_count(const std::vector<std::string_view>& first, bool pts, bool colours6) {
  Columns c;
  c.count = static_cast<int>(first.size());
  if (c.count < 3) throw TextError("fewer than 3 numbers on a line (x y z)");
  c.xyz[0] = 0, c.xyz[1] = 1, c.xyz[2] = 2;
  if (c.count == 7 || (pts && c.count >= 7)) {
    c.keep(3, "intensity");
    c.rgb[0] = 4, c.rgb[1] = 5, c.rgb[2] = 6;
  } else if (c.count == 6 && colours6) {
    c.rgb[0] = 3, c.rgb[1] = 4, c.rgb[2] = 5;
  } else if (c.count == 6) {
    c.normal[0] = 3, c.normal[1] = 4, c.normal[2] = 5;
  }
  const int kept = c.rgb[0] >= 0 ? c.rgb[2] + 1 : c.normal[0] >= 0 ? 6 : 3;
  for (int i = kept; i < c.count; ++i) {
    if (c.attributes.size() < kMaxAttributes) {
      c.keep(i, "column_" + std::to_string(i + 1));
    } else {
      c.not_kept_count += static_cast<std::size_t>(c.count - i);  // named by the first few
      for (int j = i; j < c.count && c.not_kept.size() < 8; ++j)
        c.not_kept.push_back("column_" + std::to_string(j + 1));
      break;
    }
  }
  return c;
}

// The lines of a text: from memory, or read from its file a block at a
// time, so that a text cloud of any size is parsed in a few MiB (the
// chunked build's batches, issue 44). Comment lines are skipped. A line's
// view lasts until the next call.
class Lines {
 public:
  explicit Lines(std::string_view text) : text_(text) {}
  explicit Lines(const std::filesystem::path& path)
      : file_(std::make_shared<std::ifstream>(path, std::ios::binary)), end_(false) {
    require_regular_file(path);
    if (!*file_) throw InputError(system_error_text(path, errno));
  }

  bool next(std::string_view& line) {
    for (;;) {
      // A line ends at LF, CR LF or a lone CR (old Mac exports); one that
      // may go on in the next block (a CR last: CR LF?) waits for it.
      std::size_t end = text_.find_first_of("\r\n", at_);
      if (!end_ && (end == std::string_view::npos || end + 1 == text_.size())) {
        read_block();
        continue;
      }
      if (at_ >= text_.size()) return false;
      end = std::min(end, text_.size());
      line = text_.substr(at_, end - at_);
      const bool crlf = end + 1 < text_.size() && text_[end] == '\r' && text_[end + 1] == '\n';
      at_ = end + (crlf ? 2 : 1);
      ++number_;
      if (!comment(line)) return true;
    }
  }
  [[nodiscard]] std::size_t line_number() const { return number_; }
  // The complete lines read so far and not yet handed out, as lines of
  // their own that read no further (the layout's look ahead).
  [[nodiscard]] Lines ahead() const {
    // AT_ is one past the end after a last line without a line end.
    std::string_view rest = text_.substr(std::min(at_, text_.size()));
    if (!end_) rest = rest.substr(0, rest.find_last_of("\r\n") + 1);  // npos + 1: none
    Lines out(rest);
    out.number_ = number_;
    return out;
  }
  void skip(std::string_view prefix) {
    if (!end_ && text_.size() < prefix.size()) read_block();
    if (text_.substr(at_).starts_with(prefix)) at_ += prefix.size();
  }

 private:
  static constexpr std::size_t kBlock = std::size_t{4} << 20;
  // No line is longer: past it a file is no text cloud, and no buffer grows
  // without bound.
  static constexpr std::size_t kLongestLine = std::size_t{64} << 20;

  void read_block() {
    buffer_.erase(0, at_);
    at_ = 0;
    if (buffer_.size() >= kLongestLine)
      throw TextError(std::to_string(number_ + 1) + ": a line longer than 64 MiB");
    const std::size_t had = buffer_.size();
    buffer_.resize(had + kBlock);
    file_->read(buffer_.data() + had, static_cast<std::streamsize>(kBlock));
    buffer_.resize(had + static_cast<std::size_t>(file_->gcount()));
    if (file_->bad())
      throw TextError("cannot be read on (" + std::string(std::strerror(errno)) + ")");
    end_ = file_->eof();
    text_ = buffer_;
  }

  std::string_view text_;  // the lines from at_ on (the buffer's, from a file)
  std::size_t at_ = 0;
  std::size_t number_ = 0;
  std::string buffer_;
  std::shared_ptr<std::ifstream> file_;
  bool end_ = true;  // nothing more to read
};

// The first lines: a PTS count line or a header (or neither), and what the
// columns hold. Leaves `line` at the first line of points.
struct Layout {
  Columns columns;
  bool pts = false;
  // As written and as a number: a count past any size_t (a hostile file's
  // 5e128) is still compared, never converted.
  std::string pts_text;
  double pts_count = 0;
};

Layout read_layout(Lines& r, std::string_view& line, std::vector<std::string_view>& tokens,
                   const std::vector<std::string>& mapping) {
  Layout out;
  if (!r.next(line)) throw TextError("no points (an empty text cloud)");
  split(line, tokens);
  double whole = 0;
  if (tokens.size() == 1 && parse_number(tokens[0], whole) && whole == std::floor(whole) &&
      whole >= 0) {
    out.pts = true;  // a PTS count line
    out.pts_count = whole;
    out.pts_text = std::string(tokens[0]);
    if (!r.next(line)) throw TextError("a PTS count line and no points");
  } else if (!all_numbers(tokens)) {
    // A header: the columns' names, unless --columns names them instead.
    if (mapping.empty()) out.columns = from_header(tokens);
    if (!r.next(line)) throw TextError("a header and no points");
  }
  if (!mapping.empty()) {
    const std::vector<std::string_view> names(mapping.begin(), mapping.end());
    try {
      out.columns = from_header(names);
    } catch (const TextError& e) {
      throw TextError(std::string("--columns: ") + e.what());
    }
    out.columns.count_from = "--columns names";
  }
  split(line, tokens);
  if (out.columns.count == 0) {
    // Six columns: colours when the last three are bytes on the first 256
    // lines (x y z r g b), else normals (x y z nx ny nz).
    bool colours6 = tokens.size() == 6;
    Lines ahead = r.ahead();
    std::vector<std::string_view> t = tokens;
    std::string_view l;
    for (int i = 0; colours6 && i < 256; ++i) {
      colours6 = t.size() != 6 || (byte_colour(t[3]) && byte_colour(t[4]) && byte_colour(t[5]));
      if (!ahead.next(l)) break;
      split(l, t);
    }
    out.columns = from_count(tokens, out.pts, colours6);
  }
  return out;
}

TextError line_error(std::size_t number, const std::string& what) {
  return TextError(std::to_string(number) + ": " + what);
}

// One line of points into `points` (its position into DOUBLES).
void read_point(const Columns& columns, const std::vector<std::string_view>& tokens,
                std::size_t number, std::vector<double>& values, std::vector<glm::dvec3>& doubles,
                PointSet& points, std::vector<detail::AttributeColumn>& attributes) {
  if (static_cast<int>(tokens.size()) != columns.count) {
    throw line_error(number, std::to_string(tokens.size()) + " values, where " +
                                 columns.count_from + " " + std::to_string(columns.count));
  }
  values.resize(tokens.size());
  for (std::size_t i = 0; i < tokens.size(); ++i) {
    if (!parse_value(tokens[i], values[i])) {
      throw line_error(number, "'" + std::string(tokens[i].substr(0, 40)) + "' is not a number");
    }
  }
  auto value = [&](int column) { return values[static_cast<std::size_t>(column)]; };
  doubles.emplace_back(value(columns.xyz[0]), value(columns.xyz[1]), value(columns.xyz[2]));
  for (std::size_t k = 0; k < attributes.size(); ++k) {
    attributes[k].push_back(value(columns.attributes[k].first));
  }
  if (columns.rgb[0] >= 0) {
    glm::u8vec4 c(0, 0, 0, 255);
    for (int k = 0; k < 3; ++k) {
      const double v = value(columns.rgb[k]);
      if (!(v >= 0 && v <= 255 && v == std::floor(v))) {
        throw line_error(
            number,
            "colour " +
                std::string(tokens[static_cast<std::size_t>(columns.rgb[k])].substr(0, 20)) +
                " is not a whole number from 0 to 255");
      }
      c[k] = static_cast<std::uint8_t>(v);
    }
    points.colors.push_back(c);
  }
  if (columns.normal[0] >= 0) {
    points.normals.push_back(detail::unit_or_zero(
        value(columns.normal[0]), value(columns.normal[1]), value(columns.normal[2])));
  }
}

constexpr std::string_view kByteOrderMark = "\xEF\xBB\xBF";

// TextError as the InputError the user reads: "NAME:LINE: ..." where it
// has a line number, "NAME: ..." where not.
template <class F>
auto named(const std::string& name, F&& f) {
  try {
    return f();
  } catch (const TextError& e) {
    const std::string what = e.what();
    const bool numbered = !what.empty() && std::isdigit(static_cast<unsigned char>(what[0]));
    throw InputError(name + (numbered ? ":" : ": ") + what);
  }
}

}  // namespace

bool looks_like_text_cloud(std::string_view bytes) {
  std::string_view head = bytes.substr(0, 4096);
  if (head.starts_with(kByteOrderMark)) head.remove_prefix(kByteOrderMark.size());
  if (head.find_first_not_of(" \t\r\n") == std::string_view::npos) return false;
  // Printable ASCII, tabs and line ends, or UTF-8 (a header in another
  // language; a sequence cut by the 4096 bytes counts), but for a stray
  // byte or two (a NUL on line 2, an escape in a column's name): the text
  // reader then names the line and the token. A binary file has far more.
  std::size_t stray = 0;
  for (std::size_t i = 0; i < head.size(); ++i) {
    const auto u = static_cast<unsigned char>(head[i]);
    if (u < 0x80) {
      stray += (u < 0x20 && u != '\n' && u != '\r' && u != '\t') || u == 0x7f;
      continue;
    }
    const std::size_t more = (u & 0xE0) == 0xC0   ? 1
                             : (u & 0xF0) == 0xE0 ? 2
                             : (u & 0xF8) == 0xF0 ? 3
                                                  : 0;
    bool valid = more > 0 && u >= 0xC2;
    for (std::size_t k = 1; valid && k <= more && i + k < head.size(); ++k)
      valid = (static_cast<unsigned char>(head[i + k]) & 0xC0) == 0x80;
    if (!valid) {
      ++stray;
      continue;
    }
    i += more;
  }
  return stray <= std::max<std::size_t>(1, head.size() / 100);
}

// A text cloud being read: its lines, its layout, and what the batches so
// far found (the origin the first chose, the points dropped).
struct TextCloudReader::State {
  State(Lines from, const std::string& file_name, const WarningSink& sink,
        const std::vector<std::string>& mapping)
      : lines(std::move(from)), name(file_name) {
    if (sink) warn = [this, sink](const std::string& w) { sink(name + ": " + w); };
    named(name, [&] {
      lines.skip(kByteOrderMark);
      layout = read_layout(lines, line, tokens, mapping);
      return 0;
    });
    if (warn && layout.columns.not_kept_count > 0)
      warn("not kept: " + layout.columns.not_kept_text());
  }

  PointSet next(std::size_t max_points);
  void finish();

  Lines lines;
  std::string name;
  WarningSink warn;
  Layout layout;
  std::string_view line;  // the next point's, read ahead
  bool more = true;       // LINE holds one
  std::vector<std::string_view> tokens;
  std::vector<double> values;
  std::optional<glm::dvec3> origin;
  std::size_t read = 0, kept = 0;
  detail::Dropped dropped;  // over the batches so far
};

PointSet TextCloudReader::State::next(std::size_t max_points) {
  for (;;) {
    if (!more) return {};
    const Columns& columns = layout.columns;
    PointSet points;
    std::vector<detail::AttributeColumn> attributes;
    for (const auto& [column, field] : columns.attributes) attributes.emplace_back(field, 0);
    std::vector<glm::dvec3> doubles;
    while (more && doubles.size() < max_points) {
      split(line, tokens);
      read_point(columns, tokens, lines.line_number(), values, doubles, points, attributes);
      more = lines.next(line);
    }
    const std::size_t before = read;
    read += doubles.size();
    detail::take_columns(attributes, points.attributes);
    const detail::Dropped d = detail::place_points(std::move(doubles), points, origin);
    dropped.add(d, before);
    // The origin is the first batch's with a point in it: every later
    // batch's positions are relative to it.
    if (!origin && points.size() > 0) origin = points.frame.origin;
    kept += points.size();
    if (!more) finish();
    if (points.size() > 0 || !more) return points;
  }
}

// The file's checks once its last line is read.
void TextCloudReader::State::finish() {
  if (layout.pts && static_cast<double>(read) != layout.pts_count) {
    throw TextError("1: the PTS count line says " + layout.pts_text + " points, the file has " +
                    std::to_string(read));
  }
  if (kept == 0) {
    throw TextError(dropped.far > 0
                        ? "no usable points (" + dropped.far_message(dropped.first_far + 1) + ")"
                        : "no points with a finite position (every one is nan)");
  }
  if (dropped.nonfinite > 0 && warn) {
    warn("dropped " + std::to_string(dropped.nonfinite) + " points without a finite position");
  }
  if (dropped.far > 0 && warn) warn(dropped.far_message(dropped.first_far + 1));
}

TextCloudReader::TextCloudReader(const std::filesystem::path& path, const WarningSink& warn,
                                 const std::vector<std::string>& columns)
    : state_(std::make_unique<State>(Lines(path), quoted_name(path), warn, columns)) {}

TextCloudReader::TextCloudReader(std::string_view bytes, const std::string& name,
                                 const WarningSink& warn, const std::vector<std::string>& columns)
    : state_(std::make_unique<State>(Lines(bytes), name, warn, columns)) {}

TextCloudReader::~TextCloudReader() = default;
TextCloudReader::TextCloudReader(TextCloudReader&&) noexcept = default;
TextCloudReader& TextCloudReader::operator=(TextCloudReader&&) noexcept = default;

PointSet TextCloudReader::next(std::size_t max_points) {
  return named(state_->name, [&] { return state_->next(std::max<std::size_t>(max_points, 1)); });
}

PointSet load_text_cloud_from_memory(std::string_view bytes, const std::string& name,
                                     const WarningSink& warn,
                                     const std::vector<std::string>& columns) {
  return TextCloudReader(bytes, name, warn, columns).next(SIZE_MAX);
}

PointSet load_text_cloud(const std::filesystem::path& path, const WarningSink& warn,
                         const std::vector<std::string>& columns) {
  return TextCloudReader(path, warn, columns).next(SIZE_MAX);
}

}  // namespace treecut
