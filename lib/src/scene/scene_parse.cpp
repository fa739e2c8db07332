// The scene file parser (scene.hpp, docs/scene-files.md). In the manner of
// the camera paths (splat/src/camera/camera_path.cpp): a versioned header,
// '#' comments, and every malformed line an InputError "FILE:LINE: REASON"
// that names the field and the token, never a silent default.
#include <sys/stat.h>
#include <unistd.h>

#include <charconv>
#include <cmath>
#include <glm/gtc/matrix_transform.hpp>
#include <glm/mat3x3.hpp>
#include <limits>
#include <map>
#include <numbers>
#include <optional>
#include <unordered_map>

#include "treecut/error.hpp"
#include "treecut/file_io.hpp"
#include "treecut/paged_hierarchy.hpp"
#include "treecut/scene.hpp"

namespace treecut {

namespace {

using Mat = glm::dmat4;

bool is_number_token(std::string_view t) {
  // A token that starts like a number counts as one, so "1e400", "+1",
  // "2x", "nan" and "inf" are reported as bad numbers, not as unknown
  // transform steps.
  if (t.empty()) return false;
  if (std::string_view("+-.0123456789").find(t[0]) != std::string_view::npos) return true;
  auto starts = [&](std::string_view w) {
    if (t.size() < w.size()) return false;
    for (std::size_t i = 0; i < w.size(); ++i)
      if ((t[i] | 0x20) != w[i]) return false;
    return true;
  };
  return starts("nan") || starts("inf");
}

// A transform number: finite and within float range, since the matrices are
// stored as floats (1e300 would become infinity without a word).
double number(std::string_view field, std::string_view token) {
  double v = 0.0;
  const auto [ptr, ec] = std::from_chars(token.data(), token.data() + token.size(), v);
  const std::string shown = "'" + printable_excerpt(token) + "'";
  const std::string what(field);
  if (ec == std::errc::result_out_of_range)
    throw InputError(what + ": " + shown + " is out of range");
  if (ec != std::errc() || ptr != token.data() + token.size())
    throw InputError(what + ": " + shown + " is not a number");
  if (!std::isfinite(v)) throw InputError(what + ": " + shown + " is not a finite number");
  if (std::abs(v) > double(std::numeric_limits<float>::max()))
    throw InputError(what + ": " + shown + " is out of range (single precision)");
  return v;
}

std::uint64_t whole(std::string_view field, std::string_view token, std::uint64_t lo,
                    std::uint64_t hi) {
  std::uint64_t v = 0;
  const auto [ptr, ec] = std::from_chars(token.data(), token.data() + token.size(), v);
  const std::string shown = "'" + printable_excerpt(token) + "'";
  const std::string range =
      " (a whole number from " + std::to_string(lo) + " to " + std::to_string(hi) + ")";
  if (ec == std::errc::result_out_of_range ||
      (ec == std::errc() && ptr == token.data() + token.size() && (v < lo || v > hi)))
    throw InputError(std::string(field) + ": " + shown + " is out of range" + range);
  if (ec != std::errc() || ptr != token.data() + token.size())
    throw InputError(std::string(field) + ": " + shown + " is not a whole number" + range);
  return v;
}

constexpr const char* kNotInvertible =
    "the transform is not invertible (singular, or so near it that floats cannot invert it)";

bool invertible(const Mat& m) {
  return invertible_transform(glm::dmat3(m));
}

// Ops are applied in the order written: the first one to the model's points.
// Returns the composed transform; throws InputError "REASON" (the caller adds
// FILE:LINE).
Mat parse_transform(const std::vector<std::string_view>& t, std::size_t i) {
  Mat m(1.0);
  while (i < t.size()) {
    const std::string_view op = t[i++];
    std::vector<double> v;
    std::size_t j = i;
    while (j < t.size() && is_number_token(t[j])) ++j;
    const std::size_t n = j - i;
    auto args = [&](std::initializer_list<std::size_t> allowed, const char* what) {
      bool ok = false;
      for (std::size_t a : allowed) ok = ok || n == a;
      if (!ok)
        throw InputError(std::string(op) + ": expected " + what + ", got " + std::to_string(n) +
                         (n == 1 ? " number" : " numbers"));
      for (std::size_t k = i; k < j; ++k) v.push_back(number(op, t[k]));
      i = j;
    };
    Mat step(1.0);
    if (op == "translate") {
      args({3}, "3 numbers (x y z)");
      step = glm::translate(Mat(1.0), glm::dvec3(v[0], v[1], v[2]));
    } else if (op == "rotate") {
      args({4}, "4 numbers (axis x y z, degrees)");
      const glm::dvec3 axis(v[0], v[1], v[2]);
      const double len = glm::length(axis);
      if (!(len > 1e-30)) throw InputError("rotate: zero axis");
      step = glm::rotate(Mat(1.0), v[3] * std::numbers::pi / 180.0, axis / len);
    } else if (op == "turn") {
      args({1}, "1 number (degrees about +z, the up axis)");
      step = glm::rotate(Mat(1.0), v[0] * std::numbers::pi / 180.0, glm::dvec3(0, 0, 1));
    } else if (op == "scale") {
      args({1, 3}, "1 number (uniform) or 3 (x y z)");
      const glm::dvec3 s = v.size() == 1 ? glm::dvec3(v[0]) : glm::dvec3(v[0], v[1], v[2]);
      if (s.x == 0.0 || s.y == 0.0 || s.z == 0.0)
        throw InputError("scale: a zero factor is not invertible");
      step = glm::scale(Mat(1.0), s);
    } else if (op == "matrix") {
      args({12}, "12 numbers (the rows of a 3x4 matrix [A | t])");
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 4; ++c) step[c][r] = v[static_cast<std::size_t>(r * 4 + c)];
      if (!invertible(step))
        throw InputError(
            "matrix: not invertible (singular, or so near it that floats cannot "
            "invert it)");
    } else if (is_number_token(op)) {
      throw InputError("'" + printable_excerpt(op) + "': a number where a transform was expected");
    } else {
      throw InputError("unknown transform '" + printable_excerpt(op) +
                       "' (translate, rotate, turn, scale or matrix)");
    }
    m = step * m;
  }
  if (!invertible(m)) throw InputError(kNotInvertible);
  return m;
}

struct FileId {
  dev_t dev;
  ino_t ino;
};

std::optional<FileId> file_id(const std::filesystem::path& p) {
  struct stat st {};
  if (::stat(p.c_str(), &st) != 0) return std::nullopt;
  return FileId{st.st_dev, st.st_ino};
}

struct Parser {
  SceneDescription out;
  SceneParseOptions options;
  // The files being parsed, outermost first (include cycles), with their ids.
  std::vector<std::pair<std::filesystem::path, FileId>> stack;

  // PATH as spelled, beside the scene file in DIR: the system resolves `..`
  // after any link in the folder (a lexical `lnk/../m.ply` -> `m.ply` would
  // name another file than the one `cd lnk; ls ../m.ply` shows).
  static std::filesystem::path resolve(const std::filesystem::path& dir, std::string_view p) {
    const std::filesystem::path path(p);
    const std::filesystem::path joined = path.is_absolute() || dir.empty() ? path : dir / path;
    std::filesystem::path kept;  // without its "." components (harmless to drop)
    for (const auto& part : joined)
      if (part != ".") kept /= part;
    return kept.empty() ? joined : kept;
  }

  // Where a `model` or `generate` line's model comes from (T its fields).
  [[nodiscard]] SceneModelSource model_source(const std::vector<std::string_view>& t,
                                              const std::string& model_name,
                                              const std::filesystem::path& dir) const {
    SceneModelSource source;
    if (t[0] == "model" && is_cache_url(t[2])) {
      // A cache on a web server (issue 45, item 2): read by range requests
      // when the scene loads, drawn from its pages.
      source.type = SceneModelSource::Type::File;
      source.file = std::filesystem::path(std::string(t[2]));
    } else if (t[0] == "model") {
      source.type = SceneModelSource::Type::File;
      source.file = resolve(dir, t[2]);
      try {
        require_regular_file(source.file);
      } catch (const InputError& e) {
        throw InputError("model '" + printable_excerpt(model_name) + "': " + e.what());
      }
    } else {
      source.type = SceneModelSource::Type::Generated;
      source.kind = std::string(t[2]);
      bool known = false;
      std::string kinds;
      for (const auto& k : options.generator.kinds) {
        known = known || k == source.kind;
        kinds += (kinds.empty() ? "" : ", ") + k;
      }
      if (!known)
        throw InputError(
            "generate: unknown kind '" + printable_excerpt(t[2]) + "' (" +
            (kinds.empty() ? "no generator given: SceneParseOptions::generator" : kinds) + ")");
      source.seed = whole("generate: seed", t[3], 0, std::numeric_limits<std::uint64_t>::max());
      source.points = whole("generate: points", t[4], 1, kMaxGeneratedPoints);
    }
    return source;
  }

  // O placed by WORLD (an object line's transform after its includes'),
  // its inverse beside it, both checked to hold in floats.
  static void place(SceneObject& o, const Mat& world) {
    if (!invertible(world)) throw InputError(kNotInvertible);
    const Mat inverse = glm::inverse(world);
    // Checked in double: casting a double past the float range is undefined.
    for (int c = 0; c < 4; ++c)
      for (int r = 0; r < 4; ++r)
        if (!(std::abs(world[c][r]) <= double(std::numeric_limits<float>::max())) ||
            !(std::abs(inverse[c][r]) <= double(std::numeric_limits<float>::max())))
          throw InputError("the transform or its inverse does not fit in floats");
    o.world = glm::mat4(world);
    o.world_inverse = glm::mat4(inverse);
    // The engine keeps both in floats: after rounding they must still be
    // inverses. A shear or scale spread near float precision (a column
    // of 3e7 beside columns of 1) passes the determinant test, but its
    // float pair is off by tenths and would move the lighting and the
    // culling of the object.
    const glm::mat4 product = o.world * o.world_inverse;
    for (int c = 0; c < 4; ++c)
      for (int r = 0; r < 4; ++r)
        if (!(std::abs(product[c][r] - (c == r ? 1.0f : 0.0f)) <= 1e-3f))
          throw InputError(
              "the transform is too badly conditioned for single precision (its float "
              "inverse is not one)");
  }

  // An included FILE (at DEPTH below the outermost): a regular file, no
  // cycle through the files being parsed, not too deep. Returns its id.
  [[nodiscard]] FileId check_include(const std::filesystem::path& file, int depth) const {
    require_regular_file(file);
    const FileId id = file_id(file).value_or(FileId{0, 0});
    for (std::size_t k = 0; k < stack.size(); ++k) {
      if (stack[k].second.dev == id.dev && stack[k].second.ino == id.ino) {
        std::string chain;
        for (std::size_t m = k; m < stack.size(); ++m)
          chain += quoted_name(stack[m].first) + " -> ";
        throw InputError("include cycle: " + chain + file.string());
      }
    }
    if (depth + 1 >= kMaxSceneIncludeDepth)
      throw InputError("includes nested deeper than " + std::to_string(kMaxSceneIncludeDepth));
    return id;
  }

  void parse(std::string_view text, const std::filesystem::path& name, const Mat& parent,
             int depth) {
    const auto file = static_cast<std::uint32_t>(out.files.size());
    out.files.push_back(name);
    const std::filesystem::path dir = name.parent_path();
    // Names are those of this file: an included file's models are its own.
    std::unordered_map<std::string, std::uint32_t> names;
    bool header = false;
    std::uint32_t line_no = 0;
    struct {
      bool pending = false;
      std::filesystem::path file;
      Mat world{1.0};
      std::string text;
      FileId id{};
    } include;
    while (!text.empty()) {
      const auto nl = text.find('\n');
      const std::string_view raw = text.substr(0, nl);
      text = nl == std::string_view::npos ? std::string_view{} : text.substr(nl + 1);
      ++line_no;
      std::string_view line = raw;
      if (const auto hash = line.find('#'); hash != std::string_view::npos)
        line = line.substr(0, hash);
      line = trim_blanks(line);
      if (line.empty()) continue;
      const std::string where = quoted_name(name) + ":" + std::to_string(line_no) + ": ";
      try {
        if (!header) {
          if (line != kSceneHeader)
            throw InputError("expected '" + std::string(kSceneHeader) + "'");
          header = true;
          continue;
        }
        const std::vector<std::string_view> t = split_blanks(line);
        const std::string_view key = t[0];
        if (key == "model" || key == "generate") {
          if (key == "model" && t.size() != 3)
            throw InputError("model: expected NAME PATH, got " + std::to_string(t.size() - 1) +
                             " fields");
          if (key == "generate" && t.size() != 5)
            throw InputError("generate: expected NAME KIND SEED POINTS, got " +
                             std::to_string(t.size() - 1) + " fields");
          const std::string model_name(t[1]);
          if (names.count(model_name))
            throw InputError(std::string(key) + ": model '" + printable_excerpt(model_name) +
                             "' is already declared");
          SceneModelDecl d;
          d.name = model_name;
          d.file = file;
          d.line = line_no;
          d.source = model_source(t, model_name, dir);
          names.emplace(model_name, static_cast<std::uint32_t>(out.models.size()));
          out.models.push_back(std::move(d));
        } else if (key == "object") {
          if (t.size() < 2) throw InputError("object: expected NAME [TRANSFORM...]");
          const auto it = names.find(std::string(t[1]));
          if (it == names.end())
            throw InputError("object: unknown model '" + printable_excerpt(t[1]) +
                             "' (declare it above with 'model' or 'generate')");
          if (out.objects.size() >= options.max_objects)
            throw InputError("more than " + std::to_string(options.max_objects) +
                             " objects (the limit for a scene)");
          SceneObject o;
          o.model = it->second;  // the declaration (load_scene maps it)
          place(o, parent * parse_transform(t, 2));
          o.file = file;
          o.line = line_no;
          out.objects.push_back(o);
        } else if (key == "include") {
          if (t.size() < 2) throw InputError("include: expected FILE [TRANSFORM...]");
          include.file = resolve(dir, t[1]);
          include.world = parent * parse_transform(t, 2);
          include.id = check_include(include.file, depth);
          include.text = read_text_file(include.file, kTextInputLimit);
          include.pending = true;
        } else {
          throw InputError("unknown keyword '" + printable_excerpt(key) +
                           "' (model, generate, object or include)");
        }
      } catch (const InputError& e) {
        throw InputError(where + e.what());
      }
      // Outside the line's try: an error inside the included file names its
      // own FILE:LINE.
      if (include.pending) {
        include.pending = false;
        stack.emplace_back(include.file, include.id);
        parse(include.text, include.file, include.world, depth + 1);
        stack.pop_back();
        include.text.clear();
      }
    }
    if (!header)
      throw InputError(quoted_name(name) + ": empty scene (no '" + std::string(kSceneHeader) +
                       "')");
  }
};

}  // namespace

std::string SceneModelSource::describe() const {
  if (type == Type::File) return file.string();
  return kind + " seed " + std::to_string(seed) + " points " + std::to_string(points);
}

SceneDescription parse_scene_text(std::string_view text, const std::filesystem::path& name,
                                  const SceneParseOptions& options) {
  Parser p;
  p.options = options;
  const auto id = file_id(name);
  p.stack.emplace_back(name, id.value_or(FileId{0, 0}));
  p.parse(text, name, Mat(1.0), 0);
  if (p.out.objects.empty()) throw InputError(quoted_name(name) + ": scene has no objects");
  return std::move(p.out);
}

SceneDescription parse_scene_file(const std::filesystem::path& file,
                                  const SceneParseOptions& options) {
  // Refuses a FIFO, a device or a directory without opening it; at most
  // kTextInputLimit bytes.
  return parse_scene_text(read_text_file(file, kTextInputLimit), file, options);
}

bool looks_like_scene(const std::filesystem::path& path) {
  if (path.extension() == ".scene") return true;
  if (file_kind(path) != FileKind::Regular) return false;
  try {
    const int fd = open_regular_file(path);
    char head[13] = {};
    const bool scene =
        ::read(fd, head, sizeof head) == 13 && std::string_view(head, 13) == "treecut-scene";
    ::close(fd);
    return scene;
  } catch (const std::exception&) {
    return false;
  }
}

}  // namespace treecut
