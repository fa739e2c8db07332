// Text inputs (camera paths, viewer scripts) and what the program reads
// besides models (plugins): a FIFO, a device or a directory is refused at once
// and named, a text input is read with a size limit, and a number that does
// not fit is an error naming FILE:LINE (docs/camera-paths.md).
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <sys/types.h>

#include <cmath>
#include <fstream>
#include <glm/geometric.hpp>
#include <random>
#include <string>

#include "test_support.hpp"
#include "treecut/error.hpp"
#include "treecut/file_io.hpp"
#include "treecut/splat/camera_path.hpp"
#include "treecut/strategies/builtin.hpp"
#include "view_script.hpp"

namespace fs = std::filesystem;

namespace treecut {
namespace {

template <class F>
std::string input_error_of(F&& f) {
  try {
    f();
  } catch (const InputError& e) {
    return e.what();
  }
  return "no InputError";
}

void write_text(const fs::path& file, const std::string& text) {
  std::ofstream out(file, std::ios::binary);
  out << text;
  ASSERT_TRUE(out.good()) << file;
}

// The files that are not regular files, made by the test: what each must be
// called in the message.
struct Special {
  fs::path path;
  const char* named;
};

std::vector<Special> special_files(const fs::path& dir) {
  const fs::path fifo = dir / "fifo";
  EXPECT_EQ(::mkfifo(fifo.c_str(), 0600), 0) << fifo;
  fs::create_directories(dir / "folder");
  return {{fifo, "is a FIFO"},
          {dir / "folder", "is a directory"},
          {"/dev/zero", "is a character device"}};
}

constexpr const char* kKey = "0  0 0 5  0 0 0  0 1 0  45\n";
const std::string kHeader = "treecut-camera-path 1\n";

TEST(CameraPathFile, RefusesFifoDirectoryAndDeviceByName) {
  const fs::path dir = test::scratch_dir("text_inputs_special_path");
  for (const Special& s : special_files(dir)) {
    const std::string m = input_error_of([&] { (void)splat::load_camera_path(s.path); });
    EXPECT_NE(m.find(s.path.string() + ": " + s.named), std::string::npos) << m;
    EXPECT_EQ(m.find("no such file"), std::string::npos) << m;
  }
  const std::string m = input_error_of([&] { (void)splat::load_camera_path(dir / "absent"); });
  EXPECT_NE(m.find("absent: no such file"), std::string::npos) << m;
}

TEST(CameraPathFile, RefusesAFileOverTheLimitWithoutReadingIt) {
  const fs::path dir = test::scratch_dir("text_inputs_big_path");
  // A valid path followed by comments up to 17 MiB: only the size is wrong.
  std::string text = kHeader + kKey;
  const std::string comment = "# " + std::string(1020, 'x') + "\n";
  while (text.size() < (std::size_t{17} << 20)) text += comment;
  write_text(dir / "big.campath", text);
  const std::string m = input_error_of([&] { (void)splat::load_camera_path(dir / "big.campath"); });
  EXPECT_NE(m.find("big.campath: larger than " + std::to_string(kTextInputLimit) + " bytes"),
            std::string::npos)
      << m;
  // The same content under the limit loads.
  write_text(dir / "small.campath", text.substr(0, kTextInputLimit - comment.size()));
  EXPECT_EQ(splat::load_camera_path(dir / "small.campath").keys.size(), 1u);
}

TEST(CameraPathText, NumbersThatDoNotFitNameFileLineAndToken) {
  struct Case {
    std::string key;
    std::string says;
  };
  const Case cases[] = {
      {"1e400 0 0 5 0 0 0 0 1 0 45", "time '1e400' is out of range"},
      {"0 0 0 1e300 0 0 0 0 1 0 45",
       "eye.z '1e300' is out of range (coordinates are at most 1e18 in magnitude)"},
      {"0 0 0 2e19 0 0 0 0 1 0 45",
       "eye.z '2e19' is out of range (coordinates are at most 1e18 in magnitude)"},
      {"0 0 0 5 0 0 0 0 1e39 0 45", "up.y '1e39' is out of range (single precision)"},
      {"0 0 0 5 0 0 0 0 1 0 1e-400", "fov_y_deg '1e-400' is out of range"},
      {"0 0 0 5 0 0 0 0 inf 0 45", "up.y 'inf' is not a finite number"},
      {"0 0 0 5 0 0 0 0 1 0 4x5", "fov_y_deg '4x5' is not a number"},
      {"0 0 0 5 0 0 0 0 1 0 45 \x01\x02",
       "'?"
       "?' is not a number"},
      {"-1 0 0 5 0 0 0 0 1 0 45", "negative time"},
      {"0 0 0 5 0 0 0 0 1 0 0", "fov_y_deg outside (1, 170)"},
      {"0 0 0 5 0 0 0 0 1 0 180", "fov_y_deg outside (1, 170)"},
      {"0 0 0 5 0 0 0 0 1 0 -45", "fov_y_deg outside (1, 170)"},
  };
  for (const Case& c : cases) {
    const std::string text = kHeader + "# a comment\n" + kKey + c.key + "\n";
    const std::string m =
        input_error_of([&] { (void)splat::parse_camera_path(text, "p.campath"); });
    EXPECT_NE(m.find("p.campath:4: " + c.says), std::string::npos) << c.key << " -> " << m;
    EXPECT_EQ(m.find('\n'), std::string::npos) << "one line: " << m;
  }
}

TEST(CameraPathText, UpParallelToTheViewIsAnErrorNamingTheLine) {
  // Eye on +z looking at the origin: the view direction is -z.
  for (const char* up : {"0 0 1", "0 0 -1", "0 0 0", "0 0.0001 1"}) {
    const std::string text = kHeader + kKey + "1  0 0 5  0 0 0  " + up + "  45\n";
    const std::string m = input_error_of([&] { (void)splat::parse_camera_path(text, "p"); });
    EXPECT_NE(m.find("p:3: "), std::string::npos) << up << " -> " << m;
    EXPECT_TRUE(m.find("parallel to the view direction") != std::string::npos ||
                m.find("zero up vector") != std::string::npos)
        << up << " -> " << m;
  }
  // One degree off the view direction is a valid (if odd) roll.
  const std::string ok = kHeader + kKey + "1  0 0 5  0 0 0  0 0.01745 1  45\n";
  EXPECT_EQ(splat::parse_camera_path(ok, "ok").keys.size(), 2u);
  // Eye and target one float step apart at 1e6 are the same point.
  const std::string same = kHeader + "0  1e6 0 0  1000000.03 0 0  0 1 0  45\n";
  EXPECT_NE(input_error_of([&] {
              (void)splat::parse_camera_path(same, "s");
            }).find("s:2: eye and target coincide"),
            std::string::npos);
}

// Keys as far apart as the coordinate limit allows load (their squared
// distance used to overflow a float past 1.8e19: "eye and target coincide"),
// and an up vector of any float length is as good as a unit one.
TEST(CameraPathText, KeysAtTheCoordinateLimitLoad) {
  const std::string text = kHeader + kKey + "1  1e18 1e18 1e18  -1e18 -1e18 -1e18  0 0 1  45\n" +
                           "2  -1e18 0 0  1e18 0 0  0 0 1e30  45\n";
  const splat::CameraPath path = splat::parse_camera_path(text, "far.campath");
  ASSERT_EQ(path.keys.size(), 3u);
  EXPECT_FLOAT_EQ(path.keys[1].camera.eye.x, 1e18f);
  EXPECT_FLOAT_EQ(glm::length(path.keys[2].camera.up), 1.0f);
  const splat::Camera mid = path.at(1.5);
  EXPECT_TRUE(std::isfinite(mid.eye.x) && std::isfinite(mid.up.z)) << mid.eye.x;
}

TEST(CameraPathText, InterpolatedUpIsNeverParallelToTheView) {
  // Each key is valid, but halfway both the blended view direction and the
  // blended up are (1, 1, 0)/sqrt(2): lookAt would have no roll there.
  const std::string text = kHeader +
                           "0  0 0 0  1 0 0  0 1 0  45\n"
                           "1  0 0 0  0 1 0  1 0 0  45\n";
  const splat::CameraPath p = splat::parse_camera_path(text, "blend");
  for (double t : {0.25, 0.5, 0.75}) {
    const splat::Camera c = p.at(t);
    const glm::vec3 dir = glm::normalize(c.target - c.eye);
    EXPECT_NEAR(glm::length(c.up), 1.0f, 1e-5f) << t;
    EXPECT_GT(glm::length(glm::cross(dir, c.up)), 0.5f) << "t = " << t;
  }
}

TEST(CameraPathFile, SaveOnAFullDiskLeavesNothing) {
  auto disk = test::SmallDisk::mount("text_inputs_full", 64 * 1024);
  if (!disk) GTEST_SKIP() << "cannot mount a tmpfs here";
  const splat::CameraPath p = splat::orbit_path({-1, -1, -1}, {1, 1, 1}, 1.0f, 10.0, 4000);
  EXPECT_THROW(splat::save_camera_path(disk->path() / "big.campath", p), std::runtime_error);
  EXPECT_TRUE(fs::is_empty(disk->path())) << "no truncated path, no temporary";
  // A folder at the target is not replaced.
  fs::create_directories(disk->path() / "taken");
  EXPECT_THROW(splat::save_camera_path(disk->path() / "taken",
                                       splat::orbit_path({0, 0, 0}, {1, 1, 1}, 1.0f, 1.0, 2)),
               std::runtime_error);
  EXPECT_TRUE(fs::is_directory(disk->path() / "taken"));
}

TEST(CameraPathText, MutatedPathsEitherLoadValidOrFailWithInputError) {
  const std::string good = kHeader +
                           "0    0 -3.6 1.4   0 0 0   0 0 1   45\n"
                           "0.75 2.5 -2.5 1.4 0 0 0   0 0 1   45\n"
                           "1.5  3.6 0 1.4    0 0 0   0 0 1   45\n";
  std::string alphabet = "0123456789.-+eE \t\n#xinfa";
  alphabet += '\0';  // binary bytes too
  alphabet += '\xff';
  std::mt19937 random(9);  // fixed: the same mutations on every run
  int loaded = 0;
  for (int i = 0; i < 3000; ++i) {
    std::string text = good;
    for (int edits = 1 + int(random() % 4); edits > 0; --edits) {
      const std::size_t at = random() % (text.size() + 1);
      const char c = alphabet[random() % alphabet.size()];
      switch (random() % 3) {
        case 0:
          if (at < text.size()) text[at] = c;
          break;
        case 1:
          text.insert(text.begin() + std::ptrdiff_t(at), c);
          break;
        default:
          if (at < text.size()) text.erase(at, 1);
      }
    }
    splat::CameraPath path;
    try {
      path = splat::parse_camera_path(text, "m");
    } catch (const InputError& e) {
      EXPECT_EQ(std::string(e.what()).find('\n'), std::string::npos) << e.what();
      continue;
    }
    ++loaded;
    for (const splat::CameraKey& k : path.keys) {
      const glm::vec3 dir = k.camera.target - k.camera.eye;
      ASSERT_TRUE(std::isfinite(glm::length(dir)) && glm::length(dir) > 0.0f) << text;
      EXPECT_NEAR(glm::length(k.camera.up), 1.0f, 1e-5f) << text;
      EXPECT_GE(glm::length(glm::cross(glm::normalize(dir), k.camera.up)), 1.7e-3f) << text;
      EXPECT_TRUE(k.camera.fov_y_deg > 1.0f && k.camera.fov_y_deg < 170.0f) << text;
    }
    for (double t = 0.0; t <= path.duration(); t += path.duration() / 7.0 + 1e-3) {
      const splat::Camera c = path.at(t);
      EXPECT_TRUE(std::isfinite(glm::length(c.eye)) && std::isfinite(glm::length(c.up))) << text;
    }
  }
  EXPECT_GT(loaded, 100) << "the mutations also produce valid paths";
}

// -- viewer scripts ------------------------------------------------------------

const std::string kScript = "treecut-view-script 1\n";

TEST(ViewScript, RefusesFifoDirectoryDeviceAndOversizedFiles) {
  const fs::path dir = test::scratch_dir("text_inputs_special_script");
  for (const Special& s : special_files(dir)) {
    const std::string m = input_error_of([&] { (void)cli::load_view_script(s.path); });
    EXPECT_NE(m.find(s.path.string() + ": " + s.named), std::string::npos) << m;
  }
  std::string big = kScript;
  while (big.size() <= kTextInputLimit) big += "frames 1   # " + std::string(100, 'x') + "\n";
  write_text(dir / "big.script", big);
  const std::string m = input_error_of([&] { (void)cli::load_view_script(dir / "big.script"); });
  EXPECT_NE(m.find("big.script: larger than"), std::string::npos) << m;
  // `play` of a FIFO is refused when the script is read, not when it plays.
  write_text(dir / "plays_fifo.script", kScript + "play fifo\n");
  const std::string p =
      input_error_of([&] { (void)cli::load_view_script(dir / "plays_fifo.script"); });
  EXPECT_NE(p.find("plays_fifo.script:2: play: "), std::string::npos) << p;
  EXPECT_NE(p.find("is a FIFO"), std::string::npos) << p;
}

TEST(ViewScript, CountsAndNumbersThatDoNotFitAreErrorsNamingFileLine) {
  struct Case {
    const char* line;
    const char* says;
  };
  const Case cases[] = {
      {"frames 99999999999", "frames: '99999999999' is out of range"},
      {"frames 2147483648", "frames: '2147483648' is out of range"},
      {"frames -1", "frames: '-1' is out of range"},
      {"frames 3.5", "frames: '3.5' is not a whole number"},
      {"converge 1e30", "converge: '1e30' is not a whole number"},
      {"converge", "converge needs a count"},
      {"frames 1 2", "frames takes a count, not '2'"},
      {"param min_size 1e400", "param: '1e400' is out of range"},
      {"param min_size nan", "param: 'nan' is not a finite number"},
      {"param min_size", "param needs NAME VALUE"},
      {"orbit 1e30", "orbit: '1e30' is out of range"},
      {"orbit -inf", "orbit: '-inf' is not a finite number"},
      {"exit now", "exit takes no argument, not 'now'"},
      {"jump 3", "unknown command 'jump'"},
      {"\x7f\x45LF\x01", "unknown command '?ELF?'"},
      {"mode sparkly", "mode: unknown splat mode 'sparkly'"},
      {"classes 2,x", "classes: --classes '2,x': expected class numbers 0-255"},
      {"color", "color needs an argument"},
      {"clip 0 0 2 1 1 1", "clip: the first corner's z (2) is past the second's (1)"},
  };
  for (const Case& c : cases) {
    const std::string text = kScript + "frames 2  # fine\n" + c.line + "\n";
    const std::string m = input_error_of([&] { (void)cli::parse_view_script(text, "run.script"); });
    EXPECT_NE(m.find(std::string("run.script:3: ") + c.says), std::string::npos)
        << c.line << " -> " << m;
    EXPECT_EQ(m.find('\n'), std::string::npos) << m;
  }
  // The extremes that fit.
  const auto ok =
      cli::parse_view_script(kScript + "frames 0\nconverge 2147483647\norbit -360\n", "ok");
  ASSERT_EQ(ok.size(), 3u);
  EXPECT_EQ(ok[1].number, 2147483647.0);
  EXPECT_EQ(ok[1].line, 3);
  EXPECT_EQ(ok[2].number, -360.0);
}

TEST(ViewScript, MutatedScriptsEitherParseInRangeOrFailWithInputError) {
  const StrategyRegistry registry = strategies::builtin_registry();
  const std::string good = kScript +
                           "frames 3\nconverge 300 # comment\nparam max_nodes 20000\n"
                           "orbit 45\nstrategy recursive\nparam min_size 2\nmode hq\nfit\nexit\n";
  std::string alphabet = "0123456789.-+eE \t\n#xinfa";
  alphabet += '\0';
  alphabet += '\xff';
  std::mt19937 random(10);
  int parsed = 0;
  for (int i = 0; i < 3000; ++i) {
    std::string text = good;
    for (int edits = 1 + int(random() % 3); edits > 0; --edits) {
      const std::size_t at = random() % (text.size() + 1);
      const char c = alphabet[random() % alphabet.size()];
      if (random() % 2 == 0 && at < text.size()) {
        text[at] = c;
      } else {
        text.insert(text.begin() + std::ptrdiff_t(at), c);
      }
    }
    std::vector<cli::ScriptCommand> commands;
    try {
      commands = cli::parse_view_script(text, "m.script", {&registry, "optimization", {}});
    } catch (const InputError& e) {
      EXPECT_EQ(std::string(e.what()).rfind("m.script", 0), 0u) << e.what();
      continue;
    }
    ++parsed;
    for (const cli::ScriptCommand& c : commands) {
      ASSERT_TRUE(std::isfinite(c.number)) << text;
      if (c.verb == "frames" || c.verb == "converge") {
        EXPECT_TRUE(c.number >= 0 && c.number <= cli::kMaxScriptFrames &&
                    c.number == std::floor(c.number))
            << text;
      }
      if (c.verb == "orbit") {
        EXPECT_LE(std::abs(c.number), cli::kMaxOrbitDegrees) << text;
      }
    }
  }
  EXPECT_GT(parsed, 100) << "the mutations also produce valid scripts";
}

// A screenshot is a name in --screenshot-dir: a path out of it (absolute,
// or up a level) is an error naming the line, before the window opens.
TEST(ViewScript, ScreenshotsStayInTheScreenshotFolder) {
  for (const char* name : {"/tmp/x.png", "../x.png", "shots/../../x.png", "..", "sub/x.png"}) {
    const std::string m = input_error_of([&] {
      (void)cli::parse_view_script(std::string("treecut-view-script 1\nscreenshot ") + name + "\n",
                                   "s.script");
    });
    EXPECT_NE(m.find("s.script:2: screenshot takes a file name in --screenshot-dir"),
              std::string::npos)
        << name << " -> " << m;
  }
  EXPECT_EQ(cli::parse_view_script("treecut-view-script 1\nscreenshot a.png\n", "ok").size(), 1u);
}

// Issue 30: `screenshot NAME hud` takes the window with its HUD, a plain one
// the scene alone; `hud on|off` shows or hides it. Anything else is an
// error naming the line.
TEST(ViewScript, HudCommandsAndScreenshotsWithTheHud) {
  const auto commands = cli::parse_view_script(
      "treecut-view-script 1\nscreenshot a.png\nscreenshot b.png hud\nhud off\nhud on\n", "ok");
  ASSERT_EQ(commands.size(), 4u);
  EXPECT_EQ(commands[0].number, 0.0);
  EXPECT_EQ(commands[1].arg, "b.png");
  EXPECT_EQ(commands[1].number, 1.0);
  EXPECT_EQ(commands[2].verb, "hud");
  EXPECT_EQ(commands[2].arg, "off");
  const auto error = [](const std::string& body) {
    return input_error_of(
        [&] { (void)cli::parse_view_script("treecut-view-script 1\n" + body, "h.script"); });
  };
  EXPECT_EQ(error("hud maybe\n"), "h.script:2: hud: 'maybe' is not on or off");
  EXPECT_EQ(error("hud\n"), "h.script:2: hud needs an argument");
  EXPECT_EQ(error("screenshot a.png window\n"),
            "h.script:2: screenshot: 'window' is neither hud nor a size WxH (16 to 16384 each)");
  EXPECT_EQ(error("screenshot a.png 10x10\n"),
            "h.script:2: screenshot: '10x10' is neither hud nor a size WxH (16 to 16384 each)");
  EXPECT_EQ(error("pick 10\n"), "h.script:2: pick needs a pixel x y");
  EXPECT_EQ(error("bookmark 0\n"), "h.script:2: bookmark: '0' is not a slot from 1 to 9");
  EXPECT_EQ(error("bookmark keep 3\n"),
            "h.script:2: bookmark takes a slot 1 to 9 (or save and a slot), not '3'");
  const auto marks =
      cli::parse_view_script("treecut-view-script 1\nbookmark save 3\nbookmark 3\n", "ok");
  ASSERT_EQ(marks.size(), 2u);
  EXPECT_EQ(marks[0].arg, "save");
  EXPECT_EQ(marks[0].number, 3.0);
  EXPECT_EQ(marks[1].arg, "");
  EXPECT_EQ(error("pick 10 -3\n").rfind("h.script:2: pick: '-3'", 0), 0u);
  EXPECT_EQ(error("screenshot a.png hud hud\n"),
            "h.script:2: screenshot takes an argument, not 'hud'");
}

TEST(ViewScript, HeaderIsRequired) {
  EXPECT_NE(input_error_of([] { (void)cli::parse_view_script("", "e"); }).find("e: empty script"),
            std::string::npos);
  EXPECT_NE(input_error_of([] {
              (void)cli::parse_view_script("# nothing\nframes 1\n", "h");
            }).find("h:2: expected 'treecut-view-script 1'"),
            std::string::npos);
  EXPECT_NE(input_error_of([] {
              (void)cli::parse_view_script("treecut-view-script 2\n", "v");
            }).find("v:1: expected"),
            std::string::npos);
}

TEST(ViewScript, StrategiesAndParametersAreCheckedAgainstTheRegistry) {
  const StrategyRegistry registry = strategies::builtin_registry();
  const cli::ScriptChecks checks{&registry, "optimization", {}};
  auto error = [&](const std::string& body) {
    return input_error_of([&] { (void)cli::parse_view_script(kScript + body, "s", checks); });
  };
  EXPECT_NE(error("param max_nodes 1e30\n").find("s:2: param: max_nodes"), std::string::npos)
      << error("param max_nodes 1e30\n");
  EXPECT_NE(error("strategy nosuch\n").find("s:2: strategy: unknown strategy 'nosuch'"),
            std::string::npos);
  // After `strategy recursive` the parameters are recursive's.
  EXPECT_NE(error("param max_nodes 5000\nstrategy recursive\nparam max_nodes 5000\n")
                .find("s:4: param: strategy 'recursive' has no parameter 'max_nodes'"),
            std::string::npos);
  EXPECT_EQ(cli::parse_view_script(kScript + "param max_nodes 5000\nstrategy recursive\n"
                                             "param min_size 2\n",
                                   "s", checks)
                .size(),
            3u);
}

// A script that runs on a scene may not switch to a strategy that cannot run
// on one (hoq asks for GPU queries): an error naming the line and the scene,
// before the window opens.
TEST(ViewScript, AStrategyThatCannotRunOnTheSceneIsAnErrorNamingBoth) {
  const StrategyRegistry registry = strategies::builtin_registry();
  const std::string text = "treecut-view-script 1\nframes 1\nstrategy hoq\n";
  const std::string m = input_error_of([&] {
    (void)cli::parse_view_script(text, "s.script", {&registry, "optimization", "city.scene"});
  });
  EXPECT_NE(m.find("s.script:3: strategy: city.scene: strategy 'hoq' (built-in) asks for GPU "
                   "occlusion queries"),
            std::string::npos)
      << m;
  EXPECT_EQ(cli::parse_view_script(text, "s.script", {&registry, "optimization", {}}).size(), 2u)
      << "a single model answers queries";
}

TEST(ViewScript, TheWindowTestsScriptParses) {
  const fs::path script = fs::path(TREECUT_SOURCE_DIR) / "tests/viewer_window_test/run.script";
  const StrategyRegistry registry = strategies::builtin_registry();
  const auto commands = cli::load_view_script(script, {&registry, "optimization", {}});
  ASSERT_EQ(commands.size(), 19u);
  EXPECT_EQ(commands[4].number, 1.0) << "screenshot start-hud.png hud";
  EXPECT_EQ(commands[5].verb, "hud");
  EXPECT_EQ(commands[8].width, 1280);
  EXPECT_EQ(commands[8].height, 800);
  EXPECT_EQ(commands[10].verb, "pick");
  EXPECT_EQ(commands[10].number, 320.0);
  EXPECT_EQ(commands[10].second, 200.0);
  EXPECT_EQ(commands[15].verb, "color");
  EXPECT_EQ(commands[15].arg, "elevation");
  EXPECT_EQ(commands[12].verb, "play");
  EXPECT_EQ(fs::path(commands[12].arg).filename(), "orbit.campath");
  EXPECT_TRUE(fs::exists(commands[12].arg)) << "resolved against the script's folder";
}

// -- plugins -------------------------------------------------------------------

TEST(PluginPath, AFifoOrADirectoryIsRefusedBeforeDlopen) {
  const fs::path dir = test::scratch_dir("text_inputs_plugin");
  for (const Special& s : special_files(dir)) {
    StrategyRegistry registry;
    const std::string m = input_error_of([&] { registry.load_plugin(s.path); });
    EXPECT_NE(m.find(s.path.string() + ": " + s.named), std::string::npos) << m;
  }
  // A bare name is a file in the current folder, never a search of the
  // library path.
  const fs::path previous = fs::current_path();
  fs::current_path(dir);
  StrategyRegistry registry;
  const std::string bare = input_error_of([&] { registry.load_plugin("fifo"); });
  const std::string text = input_error_of([&] {
    write_text("notes.txt", "not a library\n");
    registry.load_plugin("notes.txt");
  });
  fs::current_path(previous);
  EXPECT_EQ(bare.rfind("fifo: is a FIFO", 0), 0u) << bare;
  EXPECT_EQ(text, "notes.txt: not a shared library (no ELF header)");
}

}  // namespace
}  // namespace treecut
