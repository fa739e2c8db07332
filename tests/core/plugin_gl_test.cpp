// Plugins: loading errors are InputErrors; the example plugin (built out of
// tree against an installed treecut by the example_plugin_roundtrip test, which
// passes its path in TREECUT_EXAMPLE_PLUGIN) registers and runs its strategy.
#include <gtest/gtest.h>

#include <cstdlib>
#include <fstream>
#include <iterator>
#include <memory>
#include <string>
#include <vector>

#include "strategy_fixtures.hpp"
#include "test_support.hpp"
#include "treecut/error.hpp"
#include "treecut/feedback_stage.hpp"
#include "treecut/model.hpp"
#include "treecut/plugin.hpp"
#include "treecut/registry.hpp"
#include "treecut/strategies/builtin.hpp"

namespace treecut {
namespace {

std::string message_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const InputError& e) {
    return e.what();
  }
  return "no InputError";
}

TEST(Plugin, AMissingFileIsAnInputErrorNamingIt) {
  StrategyRegistry r;
  const std::string m = message_of([&] { r.load_plugin("/nonexistent/libnothing.so"); });
  EXPECT_EQ(m, "/nonexistent/libnothing.so: no such file");
}

// The C library this test runs with, by its absolute path (from the
// process's own mappings: under ASan, dladdr of a libc function finds the
// interceptor in the test program instead).
std::string libc_path() {
  std::ifstream maps("/proc/self/maps");
  for (std::string line; std::getline(maps, line);) {
    const auto slash = line.find('/');
    if (slash != std::string::npos && line.ends_with("/libc.so.6")) return line.substr(slash);
  }
  return {};
}

TEST(Plugin, ALibraryWithoutEntryPointsIsRefused) {
  const std::string libc = libc_path();
  if (libc.empty() || libc.front() != '/') GTEST_SKIP() << "no path for the C library";
  StrategyRegistry r;
  const std::string m = message_of([&] { r.load_plugin(libc); });
  EXPECT_NE(m.find("not a treecut plugin"), std::string::npos) << m;
  EXPECT_TRUE(r.names().empty());
}

// A plugin path is a path: a bare name that is no file here is "no such
// file", never a search of the library path (which loaded the system's libz
// and ran its constructors before saying it was no plugin).
TEST(Plugin, ABareNameIsAFileNotALibrarySearch) {
  StrategyRegistry r;
  EXPECT_EQ(message_of([&] { r.load_plugin("libz.so.1"); }), "libz.so.1: no such file");
  EXPECT_EQ(message_of([&] { r.load_plugin("libc.so.6"); }), "libc.so.6: no such file");
}

// What dlopen would map past the end of the file (a SIGBUS inside it) or
// refuse with a cryptic message is named before dlopen sees it.
TEST(Plugin, TruncatedForeignAndNonLibraryFilesAreRefusedBeforeDlopen) {
  const std::string libc = libc_path();
  if (libc.empty() || libc.front() != '/') GTEST_SKIP() << "no path for the C library";
  const auto dir = test::scratch_dir("plugin_not_libraries");
  std::string bytes;
  {
    std::ifstream in(libc, std::ios::binary);
    bytes.assign(std::istreambuf_iterator<char>(in), {});
  }
  ASSERT_GT(bytes.size(), 65536u);
  auto write = [&](const std::string& name, const std::string& content) {
    std::ofstream(dir / name, std::ios::binary) << content;
    return (dir / name).string();
  };
  struct Case {
    std::string path, says;
  };
  std::string foreign = bytes;
  foreign[18] = 40;  // e_machine: EM_ARM
  foreign[19] = 0;
  std::string executable = bytes;
  executable[16] = 2;  // e_type: ET_EXEC
  executable[17] = 0;
  const std::vector<Case> cases{
      {write("t.so", bytes.substr(0, 4096)), "truncated"},
      {write("half.so", bytes.substr(0, bytes.size() / 2)), "truncated"},
      {write("empty.so", ""), "not a shared library (no ELF header)"},
      {write("notes.so", "just some text\n"), "not a shared library (no ELF header)"},
      {write("header.so", bytes.substr(0, 40)), "truncated (shorter than an ELF header)"},
      {write("arm.so", foreign), "an ELF file for another kind of machine"},
      {write("exec.so", executable), "an ELF executable, not a shared library"},
  };
  for (const Case& c : cases) {
    StrategyRegistry r;
    const std::string m = message_of([&] { r.load_plugin(c.path); });
    EXPECT_EQ(m.rfind(c.path + ": ", 0), 0u) << m;
    EXPECT_NE(m.find(c.says), std::string::npos) << c.path << " -> " << m;
    EXPECT_TRUE(r.names().empty());
  }
}

// Libraries whose loading crashes (here a constructor; in the hostile run a
// bad pointer in the dynamic section of a complete copy of libz), ends the
// process (exit 0 or 42 in a constructor) or whose entry points are
// variables are tried in a child process first: an error naming each, and
// the host lives on, its registry untouched.
TEST(Plugin, LibrariesThatCrashExitOrLieAreErrorsNotTheHostsEnd) {
  const std::string dir = TREECUT_ODD_LIBRARY_DIR;
  const std::vector<std::pair<std::string, std::string>> cases{
      // A crash: a signal, or under ASan without abort_on_error an exit status.
      {"libtreecut_odd_crash.so", ": cannot load plugin: loading it "},
      {"libtreecut_odd_exit0.so",
       ": cannot load plugin: loading it ended a test process (exit status 0)"},
      {"libtreecut_odd_exit42.so",
       ": cannot load plugin: loading it ended a test process (exit status 42)"},
      {"libtreecut_odd_data.so", ": cannot load plugin: loading it "},
  };
  for (const auto& c : cases) {  // not a structured binding: clang 14 cannot capture one
    const std::string path = dir + "/" + c.first;
    StrategyRegistry r = strategies::builtin_registry();
    const std::size_t before = r.names().size();
    const std::string m = message_of([&] { r.load_plugin(path); });
    EXPECT_EQ(m.rfind(path + c.second, 0), 0u) << m;
    EXPECT_EQ(r.names().size(), before);
  }
}

TEST(ExamplePlugin, RegistersAndRunsItsStrategyInAFeedbackStage) {
  const char* path = std::getenv("TREECUT_EXAMPLE_PLUGIN");
  if (path == nullptr) GTEST_SKIP() << "run by the example_plugin_roundtrip test";
  StrategyRegistry registry = strategies::builtin_registry();
  registry.load_plugin(path);
  ASSERT_TRUE(registry.contains("uniform_depth"));
  for (const StrategyInfo& info : registry.list()) {
    EXPECT_EQ(info.origin, info.name == "uniform_depth" ? std::string(path) : "built-in");
  }
  EXPECT_THROW(registry.load_plugin(path), InputError) << "a second load duplicates the name";
  EXPECT_TRUE(registry.contains("uniform_depth"));

  const auto h = test::small_hierarchy(tools::ModelKind::Terrain, 5000);
  StageOptions options;
  options.launch = Launch::Manual;
  FeedbackStage stage(Model{h, TreeCut::root_cut(*h)}, registry.create("uniform_depth"), options);
  stage.set_param("depth", 1.0);
  for (int i = 0; i < 4 * h->level_count() && !stage.counters().converged; ++i) {
    const FrameLists f = stage.poll();
    ASSERT_EQ(TreeCut::validate(*h, f.current.nodes), "");
    stage.step();
  }
  ASSERT_TRUE(stage.counters().converged);
  EXPECT_EQ(stage.front().nodes.size(), h->leaf_count()) << "depth 1.0: every leaf";
}

#ifdef TREECUT_MISBEHAVING_PLUGIN
// tests/misbehaving_plugin.cpp: each strategy breaks one rule of the guide.
const std::string kBadPlugin = TREECUT_MISBEHAVING_PLUGIN;

std::string first_error(FeedbackStage& stage) {
  for (int i = 0; i < 4; ++i) {
    try {
      stage.poll();
    } catch (const StrategyError& e) {
      return e.what();
    }
    stage.step();
  }
  return "no StrategyError";
}

TEST(MisbehavingPlugin, EveryErrorNamesTheStrategyAndThePluginFile) {
  StrategyRegistry registry;
  registry.load_plugin(kBadPlugin);
  const auto h = test::small_hierarchy(tools::ModelKind::Sphere, 3000);
  StageOptions o;
  o.launch = Launch::Manual;
  o.validate = false;  // the checks that run in every build
  struct Case {
    const char* strategy;
    const char* problem;
  };
  for (const Case& c : {Case{"drops_node", "returned an invalid cut: its nodes hold "},
                        Case{"empty_cut", "returned an invalid cut: the cut is empty"},
                        Case{"throws_int", "threw an exception of type int"}}) {
    FeedbackStage stage(Model{h, TreeCut::root_cut(*h)}, registry.create(c.strategy), o);
    const std::string m = first_error(stage);
    const std::string prefix =
        "strategy '" + std::string(c.strategy) + "' (plugin " + kBadPlugin + "): ";
    EXPECT_EQ(m.rfind(prefix, 0), 0u) << m;
    EXPECT_NE(m.find(c.problem), std::string::npos) << m;
    EXPECT_EQ(stage.front().nodes.size(), 1u) << c.strategy << ": the root stays on screen";
    EXPECT_EQ(stage.counters().errors, 1u);
  }
}

// `treecut render` of a small generated model, no PNGs, with STRATEGY of the
// misbehaving plugin, OPTIONS (frames, --sync, --validate) and the output OUT.
test::CommandResult render_misbehaving(const std::string& strategy, const std::string& options,
                                       const std::filesystem::path& out,
                                       int timeout_seconds = 300) {
  return test::run_treecut("render " + options + " --plugin " + test::quote(kBadPlugin) + " -s " +
                               strategy +
                               " --warmup 0 --no-png --width 64 --height 48 "
                               "--default-points 3000 --out " +
                               test::quote(out),
                           timeout_seconds);
}

// `treecut render` with a failing strategy: exit 1 and one line naming the
// strategy and the plugin (--sync: the iteration runs in the frame, so the
// error arrives at the next one).
TEST(MisbehavingPlugin, RenderExitsOneWithOneLineNamingStrategyAndPlugin) {
  const auto dir = test::scratch_dir("misbehaving_render");
  for (const char* s : {"drops_node", "throws_int"}) {
    const test::CommandResult r = render_misbehaving(s, "--sync --frames 3", dir / s);
    EXPECT_EQ(r.code, 1) << r.out;
    const std::string line =
        "treecut: error: strategy '" + std::string(s) + "' (plugin " + kBadPlugin + "): ";
    EXPECT_NE(r.out.find(line), std::string::npos) << r.out;
  }
}

// The full check behind --validate (always on in checked builds) rejects a cut
// the cheap one lets through: a node listed twice, the point total right.
TEST(MisbehavingPlugin, RenderValidateRejectsADuplicateNode) {
  const auto dir = test::scratch_dir("misbehaving_validate");
  const test::CommandResult r =
      render_misbehaving("duplicate", "--validate --sync --frames 3", dir);
  EXPECT_EQ(r.code, 1) << r.out;
  EXPECT_NE(r.out.find("treecut: error: strategy 'duplicate' (plugin " + kBadPlugin +
                       "): returned an invalid cut: node "),
            std::string::npos)
      << r.out;
  EXPECT_NE(r.out.find(" listed twice"), std::string::npos) << r.out;
}

// A strategy that ignores cancellation does not hold the program: the stage
// reports it after StageOptions::cancel_timeout and treecut exits 1.
TEST(MisbehavingPlugin, RenderWithAStrategyIgnoringCancellationEndsAndSaysSo) {
  const auto dir = test::scratch_dir("misbehaving_cancel");
  const test::CommandResult r = render_misbehaving("ignores_cancel", "--frames 2", dir,
                                                   50);  // the strategy itself would take 60 s
  EXPECT_EQ(r.code, 1) << r.out;
  EXPECT_NE(r.out.find("warning: ignores_cancel: no strategy iteration completed in "),
            std::string::npos)
      << r.out;
  EXPECT_NE(r.out.find("treecut: error: strategy 'ignores_cancel' (plugin " + kBadPlugin +
                       ") ignored cancellation for "),
            std::string::npos)
      << r.out;
}
#endif

}  // namespace
}  // namespace treecut
