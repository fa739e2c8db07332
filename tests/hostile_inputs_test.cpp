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
#include "treecut/generate.hpp"
#include "treecut/ply.hpp"

namespace fs = std::filesystem;
using treecut::test::CommandResult;
using treecut::test::quote;
using treecut::test::run_treecut;
using treecut::test::scratch_dir;

namespace {

std::string read_all(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), {}};
}

void write_text(const fs::path& p, const std::string& text) {
  std::ofstream(p, std::ios::binary | std::ios::trunc) << text;
}

std::size_t line_count(const std::string& text) {
  std::size_t n = 0;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) ++n;
  return n;
}

// Exit CODE, exactly one line of output, which contains TEXT.
void expect_failure(const CommandResult& r, int code, const std::string& text) {
  EXPECT_EQ(r.code, code) << r.out;
  EXPECT_EQ(line_count(r.out), 1u) << r.out;
  EXPECT_NE(r.out.find(text), std::string::npos) << "wanted: " << text << "\ngot: " << r.out;
}

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
    ::setenv("XDG_CACHE_HOME", scratch_dir("hostile_cache").c_str(), 1);
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
  treecut::save_ply(dir / name, treecut::generate_model(treecut::ModelKind::Sphere, points, 1));
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
                 "survey.las: not a PLY file: a LAS/LAZ point cloud");
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

}  // namespace
