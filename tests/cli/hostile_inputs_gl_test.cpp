// The second hostile run (issue 26), as the `treecut` program meets it: two
// outputs that are one file, an output that is an input, screenshots of one
// name, NaN and malformed numbers, seeds out of range, transforms that info
// and render judged differently, messages that named the wrong reason, file
// names that carried newlines and terminal escapes, plugins that crashed in
// dlopen, and a kill that left a temporary. Every failure is exit code 2 (or
// 1) and one line; nothing of the user's is touched.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <csignal>
#include <cstdlib>
#include <fstream>
#include <iterator>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "test_support.hpp"
#include "treecut/ply.hpp"
#include "treecut/tools/generate.hpp"

namespace fs = std::filesystem;
using treecut::test::CommandResult;
using treecut::test::quote;
using treecut::test::read_all;
using treecut::test::run_treecut;
using treecut::test::scratch_dir;
using treecut::test::write_text;

namespace {

std::size_t line_count(const std::string& text) {
  std::size_t n = 0;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) ++n;
  return n;
}

using treecut::test::expect_failure;

std::vector<fs::path> files_in(const fs::path& dir) {
  std::vector<fs::path> out;
  for (const auto& e : fs::directory_iterator(dir)) out.push_back(e.path().filename());
  std::sort(out.begin(), out.end());
  return out;
}

// Caches of the commands run here go to a scratch folder.
class Hostile : public ::testing::Test {
 protected:
  void SetUp() override {
    const char* old = std::getenv("XDG_CACHE_HOME");
    if (old != nullptr) saved_ = old;
    // Each test its own (ctest runs them in parallel; a fresh scratch folder
    // is emptied first).
    const std::string test = ::testing::UnitTest::GetInstance()->current_test_info()->name();
    ::setenv("XDG_CACHE_HOME", scratch_dir("hostile_cache_" + test).c_str(), 1);
  }
  void TearDown() override {
    if (saved_)
      ::setenv("XDG_CACHE_HOME", saved_->c_str(), 1);
    else
      ::unsetenv("XDG_CACHE_HOME");
  }

 private:
  std::optional<std::string> saved_;
};

fs::path sphere(const fs::path& dir, const std::string& name, std::size_t points = 3000) {
  treecut::save_ply(dir / name,
                    treecut::tools::generate_model(treecut::tools::ModelKind::Sphere, points, 1));
  return dir / name;
}

// -- files lost ------------------------------------------------------------------

TEST_F(Hostile, TwoOutputsThatAreOneFileAreRefusedBeforeAnyWork) {
  const fs::path dir = scratch_dir("hostile_two_outputs");
  fs::create_directory(dir / "d");
  expect_failure(run_treecut("gen city -n 2000 -o " + quote(dir / "n.ply") + " --walk " +
                             quote(dir / "n.ply")),
                 2, "n.ply: named as both the model (-o) and the camera path (--walk)");
  expect_failure(run_treecut("gen city -n 2000 -o " + quote(dir / "n.ply") + " --walk " +
                             quote(dir / "d" / ".." / "n.ply")),
                 2, "named as both");
  expect_failure(run_treecut("gen city-block --objects 10 -n 500 -o " + quote(dir / "x.scene") +
                             " --walk " + quote(dir / "x.scene")),
                 2, "x.scene: named as both the scene (-o) and the camera path (--walk)");
  EXPECT_EQ(files_in(dir), std::vector<fs::path>{"d"}) << "something was written";
}

TEST_F(Hostile, NoCommandWritesOverAFileItReads) {
  const fs::path dir = scratch_dir("hostile_source_output");
  const fs::path scan = sphere(dir, "scan.ply");
  const std::string before = read_all(scan);
  expect_failure(run_treecut("gen field --source " + quote(scan) + " -o " + quote(scan)), 2,
                 "scan.ply: is the source scan (--source), which this command reads");
  expect_failure(run_treecut("gen field --source " + quote(scan) + " -o " + quote(dir / "f.ply") +
                             " --walk " + quote(dir / "." / "scan.ply")),
                 2, "is the source scan (--source)");
  fs::create_hard_link(scan, dir / "alias.ply");
  expect_failure(
      run_treecut("gen field --source " + quote(scan) + " -o " + quote(dir / "alias.ply")), 2,
      "alias.ply: is the source scan");
  EXPECT_EQ(read_all(scan), before);
  EXPECT_FALSE(fs::exists(dir / "f.ply"));
}

// kill -9 leaves the temporary; the next write of the same output removes
// it. SIGTERM removes it at once and the command dies of the signal.
TEST_F(Hostile, AKilledWritersTemporaryGoesWithTheNextWrite) {
  const fs::path dir = scratch_dir("hostile_killed");
  const pid_t dead = [] {
    const pid_t child = ::fork();
    if (child == 0) ::_exit(0);
    ::waitpid(child, nullptr, 0);
    return child;
  }();
  const fs::path stale = dir / ("m.ply.tmp-" + std::to_string(dead) + "-0");
  write_text(stale, std::string(100000, 'x'));
  const CommandResult r = run_treecut("gen sphere -n 1000 -o " + quote(dir / "m.ply"));
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_FALSE(fs::exists(stale));
  EXPECT_EQ(files_in(dir), std::vector<fs::path>{"m.ply"});
}

// -- wrong exit codes and misleading messages ---------------------------------------

TEST_F(Hostile, OneInvertibilityTestAtParseTimeForInfoAndRender) {
  const fs::path dir = scratch_dir("hostile_transforms");
  for (const std::string transform : {"scale 1 1 1e-13", "matrix 1 1e6 0 0 0 1 0 0 0 0 1 0"}) {
    const fs::path scene = dir / "s.scene";
    write_text(scene, "treecut-scene 1\ngenerate m sphere 1 1000\nobject m " + transform + "\n");
    for (const std::string& command : std::vector<std::string>{
             "info ", "render --frames 1 --no-png --out " + quote(dir / "out") + " "}) {
      expect_failure(run_treecut(command + quote(scene)), 2,
                     scene.string() + ":3: " +
                         (transform.starts_with("matrix") ? "matrix: not invertible"
                                                          : "the transform is not invertible"));
    }
  }
  EXPECT_FALSE(fs::exists(dir / "out"));
}

TEST_F(Hostile, NanAndInfinityAreRefusedUpFrontByEveryFloatingOption) {
  const fs::path dir = scratch_dir("hostile_nan");
  const fs::path model = sphere(dir, "m.ply");
  const std::string render =
      "render " + quote(model) + " --frames 1 --out " + quote(dir / "o") + " ";
  for (const std::string option :
       {"--radius-scale", "--orbit-seconds", "--point-size", "--target-fps"}) {
    for (const std::string value : {"nan", "-nan", "inf", "NaN"}) {
      expect_failure(run_treecut(render + option + " " + value), 2,
                     option + ": '" + value + "' is not a finite number");
    }
  }
  write_text(dir / "p.campath", "treecut-camera-path 1\n0 0 0 5 0 0 0 0 1 0 45\n");
  for (const std::string option : {"--tau", "--fps", "--from", "--to"}) {
    const CommandResult r = run_treecut("bench occlusion " + quote(model) + " --path " +
                                        quote(dir / "p.campath") + " " + option + " nan");
    expect_failure(r, 2, option + ": 'nan' is not a finite number");
  }
  expect_failure(run_treecut(render + "-p max_nodes=nan"), 2, "is not a finite number");
  EXPECT_FALSE(fs::exists(dir / "o"));
}

TEST_F(Hostile, WholeNumbersSayWhatIsWrongWithTheToken) {
  const fs::path dir = scratch_dir("hostile_whole");
  const fs::path model = sphere(dir, "m.ply");
  const std::string render = "render " + quote(model) + " --out " + quote(dir / "o") + " ";
  expect_failure(run_treecut(render + "--frames 1e3"), 2,
                 "--frames: '1e3' is not a whole number (a whole number from 1 to 1000000)");
  expect_failure(run_treecut(render + "--height abc"), 2,
                 "--height: 'abc' is not a whole number (a whole number from 16 to 8192)");
  expect_failure(run_treecut(render + "--width 1.5"), 2, "'1.5' is not a whole number");
  expect_failure(run_treecut(render + "--frames 0"), 2, "'0' is out of range");
  expect_failure(run_treecut(render + "--warmup 99999999999999999999999"), 2, "is out of range");
  const std::string gen = "gen sphere -n 100 -o " + quote(dir / "g.ply") + " ";
  expect_failure(run_treecut(gen + "--seed -1"), 2,
                 "--seed: '-1' is out of range (a whole number from 0 to 18446744073709551615)");
  expect_failure(run_treecut(gen + "--seed 18446744073709551616"), 2,
                 "'18446744073709551616' is out of range");
  expect_failure(run_treecut(gen + "--seed 0x10"), 2, "'0x10' is not a whole number");
  EXPECT_EQ(run_treecut(gen + "--seed 18446744073709551615").code, 0);
  EXPECT_FALSE(fs::exists(dir / "o"));
}

TEST_F(Hostile, MessagesNameTheRealReason) {
  const fs::path dir = scratch_dir("hostile_reasons");
  write_text(dir / "double_1e300.ply",
             "ply\nformat ascii 1.0\nelement vertex 3\nproperty double x\nproperty double y\n"
             "property double z\nend_header\n1e300 0 0\n0 1e300 0\n0 0 1e300\n");
  expect_failure(run_treecut("info " + quote(dir / "double_1e300.ply")), 2,
                 "double_1e300.ply: no usable points (all 3 vertices are finite but beyond the "
                 "coordinate limit");
  write_text(dir / "notes.tch", "my notes about the cache\n");
  expect_failure(run_treecut("info " + quote(dir / "notes.tch")), 2,
                 "notes.tch: not a treecut cache");
  std::string las = "LASF" + std::string(4, '\0') + "\x01\x02\r\n" + std::string(300, '\0');
  write_text(dir / "survey.las", las);
  expect_failure(run_treecut("info " + quote(dir / "survey.las")), 2,
                 "survey.las: LAS version 0.0 is not read (1.0 to 1.4 are)");
  // Neither PLY nor LAS: named, and what treecut reads said.
  write_text(dir / "scan.e57", "ASTM-E57 and more\n");
  expect_failure(
      run_treecut("info " + quote(dir / "scan.e57")), 2,
      "scan.e57: not a PLY file: an E57 point cloud; treecut reads PLY, LAS, PCD and text (XYZ, "
      "PTS, CSV) point files");
  EXPECT_EQ(read_all(dir / "notes.tch"), "my notes about the cache\n");
}

// A file name is a single line on the terminal and sends it nothing: a
// newline and an escape sequence (retitle the window, clear the screen) are
// shown escaped, in quotes.
TEST_F(Hostile, FileNamesWithControlCharactersStayOneEscapedLine) {
  const fs::path dir = scratch_dir("hostile_names");
  const std::string evil = "a\nb\x1b]0;owned\x07\x1b[2J.ply";
  write_text(dir / evil, "ply\nformat ascii 1.0\nend_header\n");
  for (const std::string& command : std::vector<std::string>{
           "info ", "build ", "render --frames 1 --out " + quote(dir / "o") + " "}) {
    const CommandResult r = run_treecut(command + quote(dir / evil));
    EXPECT_EQ(r.code, 2) << r.out;
    EXPECT_EQ(line_count(r.out), 1u) << r.out;
    EXPECT_EQ(r.out.find('\x1b'), std::string::npos) << r.out;
    EXPECT_EQ(r.out.find('\x07'), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("a\\nb\\x1b]0;owned\\x07\\x1b[2J.ply'"), std::string::npos) << r.out;
  }
  const CommandResult missing = run_treecut("info " + quote(dir / "x\ny.ply"));
  expect_failure(missing, 2, "x\\ny.ply': no such file");
}

TEST_F(Hostile, PluginsAreCheckedAsFilesBeforeDlopen) {
  const fs::path dir = scratch_dir("hostile_plugins");
  const std::vector<std::string> libc_candidates{
      "/lib/x86_64-linux-gnu/libc.so.6", "/usr/lib/x86_64-linux-gnu/libc.so.6", "/lib64/libc.so.6"};
  std::string libc;
  for (const std::string& c : libc_candidates)
    if (fs::exists(c)) libc = c;
  if (libc.empty()) GTEST_SKIP() << "no libc.so.6 at a known path";
  write_text(dir / "t.so", read_all(libc).substr(0, 4096));
  expect_failure(run_treecut("strategies --plugin " + quote(dir / "t.so")), 2, "t.so: truncated");
  // A bare name is a file name: not found here, it is not searched for.
  expect_failure(run_treecut("strategies --plugin libz.so.1"), 2, "libz.so.1: no such file");
}

// -- the hostile run's own finds (cases not in the issue) -------------------------

// A command that runs treecut under `sh -c` with its own redirections and
// environment: stdout and stderr apart.
CommandResult run_shell(const std::string& command_line) {
  const auto bin = fs::path(TREECUT_BINARY_DIR) / "demo" / "treecut";
  const std::string cmd =
      "export T=" + quote(bin) + "; timeout -k 5 120 sh -c " + quote(command_line);
  CommandResult r;
  FILE* p = popen((cmd + " 2>&1").c_str(), "r");
  if (p == nullptr) return r;
  char buf[4096];
  while (std::fgets(buf, sizeof buf, p) != nullptr) r.out += buf;
  const int status = pclose(p);
  r.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}

TEST_F(Hostile, APathOfNoFramesCountIsRefusedNotACrash) {
  const fs::path dir = scratch_dir("hostile_long_path");
  const fs::path model = sphere(dir, "m.ply");
  write_text(dir / "long.campath",
             "treecut-camera-path 1\n0 0 -3 1 0 0 0 0 0 1 45\n1e300 3 0 1 0 0 0 0 0 1 45\n");
  expect_failure(run_treecut("bench occlusion " + quote(model) + " --path " +
                             quote(dir / "long.campath") + " --no-hlod"),
                 2, "long.campath: 1e+300 s of path at 10 fps is 1e+301 frames, more than 1000000");
}

TEST_F(Hostile, AnEmptyPathIsAMistakeNotTheDefault) {
  const fs::path dir = scratch_dir("hostile_empty_paths");
  const fs::path model = sphere(dir, "m.ply");
  expect_failure(run_treecut("gen sphere -n 10 -o ''"), 2, "--output: an empty path");
  expect_failure(run_treecut("render '' --frames 1 --out " + quote(dir / "o")), 2,
                 "MODEL: an empty path");
  expect_failure(run_treecut("render " + quote(model) + " --path '' --out " + quote(dir / "o")), 2,
                 "--path: an empty path");
  expect_failure(run_treecut("render " + quote(model) + " --out ''"), 2, "--out: an empty path");
  expect_failure(run_treecut("strategies --plugin ''"), 2, "--plugin: an empty path");
  EXPECT_FALSE(fs::exists(dir / "o"));
  EXPECT_FALSE(fs::exists("assets/sphere.ply"));
}

TEST_F(Hostile, BuildOfACacheIsRefusedNotSilentlySkipped) {
  const fs::path dir = scratch_dir("hostile_build_cache");
  const fs::path model = sphere(dir, "m.ply");
  ASSERT_EQ(run_treecut("build " + quote(model) + " -o " + quote(dir / "m.tch")).code, 0);
  expect_failure(run_treecut("build " + quote(dir / "m.tch") + " -o " + quote(dir / "other.tch")),
                 2, "m.tch: is a treecut cache already; build takes a point file");
  EXPECT_FALSE(fs::exists(dir / "other.tch"));
}

TEST_F(Hostile, AStrategyThatAsksQueriesIsRefusedForAScene) {
  const fs::path dir = scratch_dir("hostile_scene_queries");
  ASSERT_EQ(run_treecut("gen city-block --objects 4 -n 200 -o " + quote(dir / "cb.scene")).code, 0);
  expect_failure(run_treecut("render " + quote(dir / "cb.scene") + " -s hoq --frames 2 --out " +
                             quote(dir / "o")),
                 2, "strategy 'hoq' (built-in) asks for GPU occlusion queries");
  EXPECT_FALSE(fs::exists(dir / "o")) << "refused before any output";
}

TEST_F(Hostile, GenWritesOnlyScenesThatLoad) {
  const fs::path dir = scratch_dir("hostile_scene_loads");
  // Past the 16 MiB a scene file may hold (a text input's limit).
  expect_failure(
      run_treecut("gen city-block --objects 200000 -n 10 -o " + quote(dir / "big.scene")), 2,
      "more than the 16777216 a scene file may hold; use fewer --objects");
  // A source of one point has no size to scale into the hall.
  write_text(dir / "point.ply",
             "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n"
             "property float z\nend_header\n0.1 0.2 0.3\n");
  expect_failure(run_treecut("gen hall --source " + quote(dir / "point.ply") + " -o " +
                             quote(dir / "h.scene")),
                 2, "point.ply: its points span no volume");
  EXPECT_FALSE(fs::exists(dir / "big.scene"));
  EXPECT_FALSE(fs::exists(dir / "h.scene"));
}

// Paths in a scene resolve as the system resolves them: through a link in
// the scene's folder, `..` is the link target's parent.
TEST_F(Hostile, AHallWrittenThroughALinkLoadsFromBothPaths) {
  const fs::path dir = scratch_dir("hostile_hall_link");
  const fs::path model = sphere(dir, "m.ply");
  fs::create_directories(dir / "real" / "deep");
  fs::create_directory_symlink(dir / "real" / "deep", dir / "lnk");
  ASSERT_EQ(run_treecut("gen hall --objects 4 -n 200 --source " + quote(model) + " -o " +
                        quote(dir / "lnk" / "h.scene"))
                .code,
            0);
  EXPECT_EQ(run_treecut("info " + quote(dir / "lnk" / "h.scene")).code, 0);
  const CommandResult r = run_treecut("info " + quote(dir / "real" / "deep" / "h.scene"));
  EXPECT_EQ(r.code, 0) << r.out;
}

TEST_F(Hostile, RenderWritesNothingOutsideItsOwnOutputs) {
  const fs::path dir = scratch_dir("hostile_render_out");
  const fs::path model = sphere(dir, "m.ply");
  const std::string render = "render " + quote(model) + " --frames 2 --width 32 --height 32 ";
  // An earlier output whose strategy subfolder was made a link to photos.
  fs::create_directory(dir / "photos");
  write_text(dir / "photos" / "frame_00000.png", "a photo\n");
  ASSERT_EQ(run_treecut(render + "-s optimization -s bucket --out " + quote(dir / "prev")).code, 0);
  fs::remove_all(dir / "prev" / "optimization");
  fs::create_directory_symlink(dir / "photos", dir / "prev" / "optimization");
  expect_failure(run_treecut(render + "-s optimization -s bucket --out " + quote(dir / "prev")), 2,
                 "optimization: is a symbolic link; refusing to write render output through it");
  EXPECT_EQ(read_all(dir / "photos" / "frame_00000.png"), "a photo\n");
  // An old output in a subfolder does not make the folder itself one.
  fs::create_directories(dir / "proj" / "old");
  write_text(dir / "proj" / "plot.svg", "the user's plot\n");
  fs::copy_file(dir / "prev" / "bucket" / "stats.csv", dir / "proj" / "old" / "stats.csv");
  expect_failure(run_treecut(render + "--out " + quote(dir / "proj")), 2,
                 "folder is not empty and not an earlier treecut render output");
  EXPECT_EQ(read_all(dir / "proj" / "plot.svg"), "the user's plot\n");
  // Inputs inside the output folder, and a frame name taken by a folder.
  ASSERT_EQ(run_treecut(render + "--out " + quote(dir / "rin")).code, 0);
  fs::copy_file(model, dir / "rin" / "model.ply");
  expect_failure(run_treecut("render " + quote(dir / "rin" / "model.ply") + " --frames 2 --out " +
                             quote(dir / "rin")),
                 2, "model.ply: is inside the output folder");
  fs::create_directory(dir / "rin" / "frame_00007.png");
  expect_failure(run_treecut(render + "--out " + quote(dir / "rin")), 2,
                 "frame_00007.png: is a directory; refusing to write render output there");
}

TEST_F(Hostile, ThePlotOfAModelWithMarkupInItsNameIsWellFormed) {
  const fs::path dir = scratch_dir("hostile_svg");
  const fs::path model = sphere(dir, "a&b<c>.ply");
  ASSERT_EQ(run_treecut("render " + quote(model) +
                        " --frames 2 --width 32 --height 32 --no-png "
                        "--out " +
                        quote(dir / "o"))
                .code,
            0);
  const std::string svg = read_all(dir / "o" / "plot.svg");
  EXPECT_NE(svg.find("a&amp;b&lt;c&gt;.ply"), std::string::npos) << svg.substr(0, 400);
  EXPECT_EQ(svg.find("<c>"), std::string::npos);
}

TEST_F(Hostile, LegalLongNamesGetTheirTemporariesAndCaches) {
  const fs::path dir = scratch_dir("hostile_long_names");
  const std::string name = std::string(246, 'n') + ".ply";  // 250 bytes
  ASSERT_EQ(run_treecut("gen sphere -n 500 -o " + quote(dir / name)).code, 0);
  const CommandResult r = run_treecut("build " + quote(dir / name));
  EXPECT_EQ(r.code, 0) << r.out;
  EXPECT_EQ(files_in(dir), std::vector<fs::path>{name});
}

TEST_F(Hostile, OutputThatCannotBeWrittenIsAFailure) {
  const fs::path dir = scratch_dir("hostile_stdout");
  const fs::path model = sphere(dir, "m.ply");
  const CommandResult r = run_shell("\"$T\" info " + quote(model) + " > /dev/full");
  EXPECT_EQ(r.code, 1) << r.out;
  EXPECT_EQ(r.out, "treecut: error: standard output: No space left on device\n");
  EXPECT_EQ(run_shell("\"$T\" strategies > /dev/full").code, 1);
}

TEST_F(Hostile, NoHomeAndNoTemporaryFolderMeansNoCacheNotAFailure) {
  const fs::path dir = scratch_dir("hostile_no_home");
  const fs::path model = sphere(dir, "m.ply");
  const CommandResult r =
      run_shell("env -u HOME -u XDG_CACHE_HOME TMPDIR=/nonexistent \"$T\" info " + quote(model));
  EXPECT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("warning: no cache folder"), std::string::npos) << r.out;
}

TEST_F(Hostile, ParameterMessagesShowTheValueAsGiven) {
  const fs::path dir = scratch_dir("hostile_param_text");
  const fs::path model = sphere(dir, "m.ply");
  expect_failure(
      run_treecut("render " + quote(model) + " -p max_nodes=4000000001 --out " + quote(dir / "o")),
      2, "max_nodes = 4000000001 is out of range [1, 4000000000]");
  expect_failure(run_treecut("render " + quote(model) + " -p max_nodes=100000.0000000001 --out " +
                             quote(dir / "o")),
                 2, "max_nodes = 100000.0000000001 must be a whole number");
}

}  // namespace
