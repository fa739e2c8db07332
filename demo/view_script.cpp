#include "view_script.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <system_error>

#include "messages.hpp"
#include "treecut/error.hpp"
#include "treecut/feedback_stage.hpp"
#include "treecut/file_io.hpp"
#include "treecut/splat/camera_path.hpp"
#include "treecut/splat/coloring.hpp"
#include "treecut/splat/renderer.hpp"
#include "treecut/strategy.hpp"

namespace treecut::cli {

namespace {

std::vector<std::string_view> split_blanks(std::string_view line) {
  std::vector<std::string_view> out;
  std::size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && (line[i] == ' ' || line[i] == '\t' || line[i] == '\r')) ++i;
    std::size_t j = i;
    while (j < line.size() && line[j] != ' ' && line[j] != '\t' && line[j] != '\r') ++j;
    if (j > i) out.push_back(line.substr(i, j - i));
    i = j;
  }
  return out;
}

std::string shown(std::string_view token) {
  return "'" + printable_excerpt(token) + "'";
}

// A count of frames: a whole number that fits the viewer's int counter. No
// wrap, no silent zero: "99999999999", "1e30", "-1" and "3.5" are errors.
int parse_count(std::string_view token, const std::string& where) {
  int v = 0;
  const auto [ptr, ec] = std::from_chars(token.data(), token.data() + token.size(), v);
  const bool whole = ptr == token.data() + token.size();
  if (ec == std::errc::result_out_of_range ||
      (ec == std::errc() && whole && (v < 0 || v > kMaxScriptFrames))) {
    throw InputError(where + shown(token) + " is out of range (a count from 0 to " +
                     std::to_string(kMaxScriptFrames) + ")");
  }
  if (ec != std::errc() || !whole)
    throw InputError(where + shown(token) + " is not a whole number");
  return v;
}

double parse_real(std::string_view token, const std::string& where) {
  double v = 0.0;
  const auto [ptr, ec] = std::from_chars(token.data(), token.data() + token.size(), v);
  if (ec == std::errc::result_out_of_range)
    throw InputError(where + shown(token) + " is out of range");
  if (ec != std::errc() || ptr != token.data() + token.size())
    throw InputError(where + shown(token) + " is not a number");
  if (!std::isfinite(v)) throw InputError(where + shown(token) + " is not a finite number");
  return v;
}

// Exactly `args` words after the verb, else an error saying what it takes.
void require_arguments(const std::vector<std::string_view>& words, std::size_t args,
                       const char* what, const std::string& where, const std::string& verb) {
  if (words.size() - 1 < args) throw InputError(where + verb + " needs " + what);
  if (words.size() - 1 > args)
    throw InputError(where + verb + " takes " + what + ", not " + shown(words[args + 1]));
}

// play, screenshot, strategy, mode, color, classes, hud: one argument, checked
// now (color's source against the model when it opens) so that a bad
// one fails before the window opens. A `strategy` line changes `strategy`,
// the one later `param` lines are checked against.
// WxH of a screenshot: whole numbers from 16 to 16384 each.
void parse_size(std::string_view text, const std::string& at, int& width, int& height) {
  const auto x = text.find('x');
  const auto whole = [&](std::string_view s, int& out) {
    const auto r = std::from_chars(s.data(), s.data() + s.size(), out);
    return r.ec == std::errc() && r.ptr == s.data() + s.size() && out >= 16 && out <= 16384;
  };
  if (x == std::string_view::npos || !whole(text.substr(0, x), width) ||
      !whole(text.substr(x + 1), height))
    throw InputError(at + shown(text) + " is neither hud nor a size WxH (16 to 16384 each)");
}

void check_named_argument(ScriptCommand& c, const std::vector<std::string_view>& words,
                          const std::string& where, const std::filesystem::path& file,
                          const ScriptChecks& checks, std::string& strategy) {
  // `screenshot NAME hud`: the window with the HUD (number 1);
  // `screenshot NAME WxH`: the scene drawn at that size.
  const bool third = c.verb == "screenshot" && words.size() == 3;
  const bool with_hud = third && words[2] == "hud";
  if (third && !with_hud) parse_size(words[2], where + c.verb + ": ", c.width, c.height);
  const std::vector<std::string_view> named(words.begin(), words.end() - (third ? 1 : 0));
  require_arguments(named, 1, c.verb == "play" ? "a camera path" : "an argument", where, c.verb);
  c.number = with_hud ? 1.0 : 0.0;
  c.arg = std::string(words[1]);
  if (c.verb == "hud" && c.arg != "on" && c.arg != "off")
    throw InputError(where + "hud: " + shown(words[1]) + " is not on or off");
  // A screenshot is a PNG name in --screenshot-dir, never a path out of it.
  if (c.verb == "screenshot" &&
      (c.arg.find('/') != std::string::npos || c.arg == "." || c.arg == ".."))
    throw InputError(where + "screenshot takes a file name in --screenshot-dir, not the path " +
                     shown(words[1]));
  try {
    if (c.verb == "play") {
      c.arg = (file.parent_path() / c.arg).string();
      (void)splat::load_camera_path(c.arg);  // fail before the window opens
    } else if (c.verb == "mode") {
      (void)splat::parse_splat_mode(c.arg);
    } else if (c.verb == "classes") {
      splat::ColorBy by;
      if (c.arg != "all") splat::parse_class_filter(c.arg, by);
    } else if (c.verb == "strategy" && checks.registry != nullptr) {
      const std::unique_ptr<Strategy> s = checks.registry->create(c.arg);
      if (const std::string why = scene_strategy_problem(*s); !checks.scene.empty() && !why.empty())
        throw InputError(quoted_name(checks.scene) + ": " + why);
      strategy = c.arg;
    }
  } catch (const InputError& e) {
    // The path's own FILE:LINE (or the registry's reason) after ours.
    throw InputError(where + c.verb + ": " + e.what());
  }
}

// param NAME VALUE: with a registry, NAME must be a parameter of `strategy`
// and VALUE in its range.
void check_param_command(ScriptCommand& c, const std::vector<std::string_view>& words,
                         const std::string& where, const std::string& at,
                         const ScriptChecks& checks, const std::string& strategy) {
  require_arguments(words, 2, "NAME VALUE", where, c.verb);
  c.arg = std::string(words[1]);
  c.number = parse_real(words[2], at);
  if (checks.registry != nullptr) {
    const auto specs = checks.registry->create(strategy)->param_specs();
    const auto spec = std::find_if(specs.begin(), specs.end(),
                                   [&](const ParamSpec& s) { return s.name == c.arg; });
    if (spec == specs.end())
      throw InputError(at + "strategy '" + strategy + "' has no parameter " + shown(c.arg));
    if (const std::string why = check_param(*spec, c.number); !why.empty())
      throw InputError(at + why);
  }
}

// One command line after the header (its words), checked; `where` is
// "FILE:LINE: ".
ScriptCommand parse_command(const std::vector<std::string_view>& words, int line,
                            const std::string& where, const std::filesystem::path& file,
                            const ScriptChecks& checks, std::string& strategy) {
  ScriptCommand c;
  c.verb = std::string(words[0]);
  c.line = line;
  const std::string at = where + c.verb + ": ";
  if (c.verb == "frames" || c.verb == "converge") {
    require_arguments(words, 1, "a count", where, c.verb);
    c.number = parse_count(words[1], at);
  } else if (c.verb == "play" || c.verb == "screenshot" || c.verb == "strategy" ||
             c.verb == "mode" || c.verb == "color" || c.verb == "classes" || c.verb == "hud") {
    check_named_argument(c, words, where, file, checks, strategy);
  } else if (c.verb == "open") {
    // Another model, resolved like `play`; it must be a regular file now (a
    // missing one fails before the window opens), whether it loads is seen
    // when the viewer opens it.
    require_arguments(words, 1, "a model file (PLY or .tch)", where, c.verb);
    c.arg = (file.parent_path() / std::string(words[1])).string();
    try {
      require_regular_file(c.arg);
    } catch (const InputError& e) {
      throw InputError(where + c.verb + ": " + e.what());
    }
  } else if (c.verb == "param") {
    check_param_command(c, words, where, at, checks, strategy);
  } else if (c.verb == "edl") {
    require_arguments(words, 1, "on or off", where, c.verb);
    c.arg = std::string(words[1]);
    if (c.arg != "on" && c.arg != "off")
      throw InputError(at + shown(words[1]) + " is not on or off");
  } else if (c.verb == "clip") {
    // clip X0 Y0 Z0 X1 Y1 Z1 (the file's coordinates) | clip off
    if (words.size() == 2 && words[1] == "off") return c;
    require_arguments(words, 6, "six numbers X0 Y0 Z0 X1 Y1 Z1 (or off)", where, c.verb);
    for (std::size_t i = 1; i <= 6; ++i) c.box.push_back(parse_real(words[i], at));
    check_box_corners(c.box, at);
  } else if (c.verb == "bookmark") {
    // bookmark N (go back to view N) | bookmark save N (keep the view as N)
    const bool save = words.size() == 3 && words[1] == "save";
    const std::vector<std::string_view> slot(words.begin() + (save ? 1 : 0), words.end());
    require_arguments(slot, 1, "a slot 1 to 9 (or save and a slot)", where, c.verb);
    c.arg = save ? "save" : "";
    c.number = parse_count(slot[1], at);
    if (c.number < 1 || c.number > 9)
      throw InputError(at + shown(slot[1]) + " is not a slot from 1 to 9");
  } else if (c.verb == "pick") {
    // pick X Y: a framebuffer pixel, x right and y down from the top left.
    require_arguments(words, 2, "a pixel x y", where, c.verb);
    c.number = parse_count(words[1], at);
    c.second = parse_count(words[2], at);
  } else if (c.verb == "orbit") {
    require_arguments(words, 1, "degrees", where, c.verb);
    c.number = parse_real(words[1], at);
    if (std::abs(c.number) > kMaxOrbitDegrees)
      throw InputError(at + shown(words[1]) + " is out of range (-360 to 360 degrees)");
  } else if (c.verb == "exit" || c.verb == "fit") {
    require_arguments(words, 0, "no argument", where, c.verb);
  } else {
    throw InputError(where + "unknown command " + shown(c.verb));
  }
  return c;
}

}  // namespace

void check_box_corners(const std::vector<double>& box, const std::string& what) {
  for (std::size_t k = 0; k < 3 && box.size() == 6; ++k) {
    if (box[k] > box[k + 3]) {
      throw InputError(what + "the first corner's " + "xyz"[k] + " (" + exact_number(box[k]) +
                       ") is past the second's (" + exact_number(box[k + 3]) +
                       "); give X0 Y0 Z0 X1 Y1 Z1 with X0 <= X1, Y0 <= Y1, Z0 <= Z1");
    }
  }
}

std::vector<ScriptCommand> parse_view_script(std::string_view text,
                                             const std::filesystem::path& file,
                                             const ScriptChecks& checks) {
  const std::string name = quoted_name(file);
  std::vector<ScriptCommand> out;
  std::string strategy = checks.strategy;
  bool header = false;
  int n = 0;
  while (!text.empty()) {
    const auto nl = text.find('\n');
    std::string_view line = text.substr(0, nl);
    text = nl == std::string_view::npos ? std::string_view{} : text.substr(nl + 1);
    ++n;
    if (const auto hash = line.find('#'); hash != std::string_view::npos)
      line = line.substr(0, hash);
    const std::vector<std::string_view> words = split_blanks(line);
    if (words.empty()) continue;
    const std::string where = name + ":" + std::to_string(n) + ": ";
    if (!header) {
      if (words.size() != 2 || words[0] != "treecut-view-script" || words[1] != "1")
        throw InputError(where + "expected 'treecut-view-script 1'");
      header = true;
      continue;
    }
    out.push_back(parse_command(words, n, where, file, checks, strategy));
  }
  if (!header) throw InputError(name + ": empty script (no 'treecut-view-script 1' line)");
  return out;
}

std::vector<ScriptCommand> load_view_script(const std::filesystem::path& file,
                                            const ScriptChecks& checks) {
  return parse_view_script(read_text_file(file, kTextInputLimit), file, checks);
}

}  // namespace treecut::cli
