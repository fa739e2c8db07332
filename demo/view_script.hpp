// Viewer scripts (`treecut view --script FILE`, docs/camera-paths.md): the
// parser, apart from the window so that it can be tested without one and so
// that a bad script fails before a window opens.
#pragma once

#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

#include "treecut/registry.hpp"

namespace treecut::cli {

/// One line of a script. `number` holds the count of frames/converge (a whole
/// number in [0, kMaxScriptFrames]), the value of param and the degrees of
/// orbit; `arg` the strategy, mode, screenshot name, parameter name, or the
/// camera path or model file of play and open (resolved against the script's
/// folder).
struct ScriptCommand {
  std::string verb;
  std::string arg;
  double number = 0.0;
  double second = 0.0;  ///< pick's y
  /// screenshot NAME WxH: drawn at that size, not the window's (0: the window).
  int width = 0, height = 0;
  /// clip X0 Y0 Z0 X1 Y1 Z1: the box (file coordinates); empty for `clip off`.
  std::vector<double> box;
  int line = 0;
};

/// The largest count of `frames` and `converge`: the viewer counts frames in
/// an int.
inline constexpr int kMaxScriptFrames = 2147483647;
/// `orbit` turns at most one full turn per command.
inline constexpr double kMaxOrbitDegrees = 360.0;

/// What a script is checked against besides its syntax: with a registry,
/// `strategy NAME` must name a strategy and `param NAME VALUE` a parameter of
/// the strategy in use at that line, in its range.
struct ScriptChecks {
  const StrategyRegistry* registry = nullptr;
  std::string strategy = "optimization";  ///< in use before the first `strategy` line
  /// The scene file the script runs on (empty: a single model): a `strategy`
  /// line naming one that cannot run on a scene is an error naming it.
  std::string scene;
};

/// Throws InputError "WHAT the first corner's x (1) is past the second's (0)
/// ..." unless the box X0 Y0 Z0 X1 Y1 Z1 has X0 <= X1, Y0 <= Y1, Z0 <= Z1:
/// a reversed box (--clip, a script's `clip`) is a mistake, not a box to
/// draw blank frames in.
void check_box_corners(const std::vector<double>& box, const std::string& what);

/// Parses a script's text; `file` names it in messages and locates `play`
/// paths. Throws InputError "FILE:LINE: problem" for a missing header, an
/// unknown command, a missing or extra argument, a number that is not one or
/// does not fit, or a camera path that does not load.
std::vector<ScriptCommand> parse_view_script(std::string_view text,
                                             const std::filesystem::path& file,
                                             const ScriptChecks& checks = {});

/// Reads FILE (a regular file of at most kTextInputLimit bytes: a FIFO, a
/// device or a directory is refused without being opened) and parses it.
std::vector<ScriptCommand> load_view_script(const std::filesystem::path& file,
                                            const ScriptChecks& checks = {});

}  // namespace treecut::cli
