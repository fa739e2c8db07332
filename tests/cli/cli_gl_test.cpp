// The `treecut` program: exit codes (0 ok, 1 runtime failure, 2 bad input),
// --help on every command, no output written on failure.
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <sys/wait.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cstdio>
#include <fstream>

#include "test_support.hpp"

namespace fs = std::filesystem;

TEST(Cli, HelpWorksForEveryCommand) {
  for (const char* c : {"", "build", "info", "gen", "cache", "bench build"}) {
    const treecut::test::CommandResult r = treecut::test::run_treecut(std::string(c) + " --help");
    EXPECT_EQ(r.code, 0) << c << "\n" << r.out;
    EXPECT_NE(r.out.find("Usage"), std::string::npos) << c;
  }
}

TEST(Cli, UsageErrorsExitWithTwo) {
  EXPECT_EQ(treecut::test::run_treecut("").code, 2);
  EXPECT_EQ(treecut::test::run_treecut("no-such-command").code, 2);
  EXPECT_EQ(treecut::test::run_treecut("build").code, 2) << "missing MODEL";
  EXPECT_EQ(treecut::test::run_treecut("gen pyramid -o /tmp/x.ply").code, 2) << "unknown kind";
}

TEST(Cli, GenBuildInfoRoundTrip) {
  const fs::path dir = treecut::test::scratch_dir("cli_gen");
  treecut::test::CommandResult r =
      treecut::test::run_treecut("gen terrain -n 20000 -o " + treecut::test::quote(dir / "t.ply"));
  ASSERT_EQ(r.code, 0) << r.out;
  ASSERT_TRUE(fs::exists(dir / "t.ply"));
  r = treecut::test::run_treecut("build " + treecut::test::quote(dir / "t.ply") + " -o " +
                                 treecut::test::quote(dir / "t.tch"));
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("points      20000"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("build time"), std::string::npos) << r.out;
  r = treecut::test::run_treecut("info " + treecut::test::quote(dir / "t.tch"));
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("points      20000"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("from cache"), std::string::npos) << r.out;
}

// Issue 30: the command line speaks in points: `--points N` is the budget of
// whichever strategy has one (optimization's max_nodes); one without is
// told so (exit 2).
TEST(Cli, PointsIsTheStrategysBudget) {
  const fs::path dir = treecut::test::scratch_dir("cli_points");
  using treecut::test::quote;
  using treecut::test::run_treecut;
  treecut::test::CommandResult r = run_treecut(
      "render --default-points 30000 --frames 3 --warmup 5 --sync --no-png --points 5000 -o " +
      quote(dir / "a"));
  ASSERT_EQ(r.code, 0) << r.out;
  const auto at = r.out.find("cut ");
  ASSERT_NE(at, std::string::npos) << r.out;
  const long cut = std::strtol(r.out.c_str() + at + 4, nullptr, 10);
  EXPECT_GT(cut, 1000);
  EXPECT_LE(cut, 5000) << r.out;
  r = run_treecut("render --default-points 3000 --frames 1 -s bucket --points 5000 -o " +
                  quote(dir / "b"));
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.out.find("--points: no selected strategy has a budget in points"), std::string::npos)
      << r.out;
  // A clip box takes six numbers: five are a usage error (exit 2).
  EXPECT_EQ(
      run_treecut("render --default-points 3000 --frames 1 --clip 0 0 0 1 1 -o " + quote(dir / "c"))
          .code,
      2);
}

// Issue 30: `treecut cache` lists the caches of a folder with size, last use
// and model, and removes them (--older-than, --max-size, --clear), nothing
// but caches; a bad size is one line and exit 2.
TEST(Cli, CacheListsAndRemovesOnlyCaches) {
  const fs::path dir = treecut::test::scratch_dir("cli_cache");
  const fs::path folder = dir / "caches";
  using treecut::test::quote;
  using treecut::test::run_treecut;
  for (const char* name : {"one", "two"}) {
    ASSERT_EQ(
        run_treecut("gen sphere -n 3000 -o " + quote(dir / (std::string(name) + ".ply"))).code, 0);
    ASSERT_EQ(run_treecut("build " + quote(dir / (std::string(name) + ".ply")) + " -o " +
                          quote(folder / (std::string(name) + ".tch")))
                  .code,
              0);
  }
  std::ofstream(folder / "mine.tch") << "not a cache\n";
  fs::last_write_time(folder / "one.tch",
                      fs::file_time_type::clock::now() - std::chrono::hours(24 * 10));
  treecut::test::CommandResult r = run_treecut("cache --folder " + quote(folder));
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("2 cache(s)"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("  one  (one.tch)"), std::string::npos) << r.out;
  r = run_treecut("cache --folder " + quote(folder) + " --older-than 7");
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("removed   " + (folder / "one.tch").string()), std::string::npos) << r.out;
  EXPECT_TRUE(fs::exists(folder / "two.tch"));
  EXPECT_EQ(run_treecut("cache --folder " + quote(folder) + " --max-size lots").code, 2);
  r = run_treecut("cache --folder " + quote(folder) + " --max-size 1K");
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_FALSE(fs::exists(folder / "two.tch"));
  EXPECT_NE(r.out.find("0 cache(s)"), std::string::npos) << r.out;
  EXPECT_TRUE(fs::exists(folder / "mine.tch")) << "not a cache: never removed";
  ASSERT_EQ(run_treecut("cache --folder " + quote(folder) + " --clear").code, 0);
  EXPECT_TRUE(fs::exists(folder / "mine.tch"));
}

// A model at map coordinates, written as LAS by gen and read back: the
// origin is kept (in the cache too) and shown with the file's bounds.
TEST(Cli, GenLasAtMapCoordinatesAndInfo) {
  using treecut::test::quote;
  using treecut::test::run_treecut;
  const fs::path dir = treecut::test::scratch_dir("cli_las");
  treecut::test::CommandResult r =
      run_treecut("gen sphere -n 5000 --origin 500000 5000000 100 -o " + quote(dir / "s.las"));
  ASSERT_EQ(r.code, 0) << r.out;
  r = run_treecut("build " + quote(dir / "s.las") + " -o " + quote(dir / "s.tch"));
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("format      LAS 1.2, point format 2"), std::string::npos) << r.out;
  EXPECT_EQ(r.out.find("warning"), std::string::npos) << r.out;
  for (const char* model : {"s.las", "s.tch"}) {
    r = run_treecut("info " + quote(dir / model));
    ASSERT_EQ(r.code, 0) << r.out;
    EXPECT_NE(r.out.find("origin      [500000.000 5000000.000 100.000]"), std::string::npos)
        << model << "\n"
        << r.out;
    EXPECT_NE(r.out.find("file bounds [499999.0"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("bounds      [-0.99"), std::string::npos) << "relative to it: " << r.out;
    // What gen writes beyond the intensity is the same at every point: kept
    // (issue 43, item 1), and the format line from the cache too (item 18).
    EXPECT_NE(r.out.find("attributes  10 (colour by one with --color NAME)\n  intensity"),
              std::string::npos)
        << model << "\n"
        << r.out;
    EXPECT_NE(r.out.find("  return_number          category 1 at every point\n"), std::string::npos)
        << r.out;
    EXPECT_NE(r.out.find("format      LAS 1.2, point format 2"), std::string::npos) << r.out;
  }
  // A PLY holds the same map coordinates in double (issue 43, item 2).
  r = run_treecut("gen sphere -n 100 --origin 500000 5000000 0 -o " + quote(dir / "s.ply"));
  ASSERT_EQ(r.code, 0) << r.out;
  r = run_treecut("info " + quote(dir / "s.ply"));
  EXPECT_NE(r.out.find("origin      [500000.000 5000000.000 0.000]"), std::string::npos) << r.out;
  // gen replaces a LAS only: not a PLY (or anything else) under a .las name.
  r = run_treecut("gen sphere -n 100 -o " + quote(dir / "p.ply"));
  ASSERT_EQ(r.code, 0);
  fs::copy_file(dir / "p.ply", dir / "p.las");
  r = run_treecut("gen sphere -n 100 -o " + quote(dir / "p.las"));
  EXPECT_EQ(r.code, 2) << r.out;
  EXPECT_NE(r.out.find("is not a LAS file"), std::string::npos) << r.out;
}

// Issue 29, item 3: a classified survey coloured by its attributes; a
// colour the model cannot give is one line and exit 2 before any output.
TEST(Cli, RenderColoursByAnAttributeAndHidesClasses) {
  using treecut::test::quote;
  using treecut::test::run_treecut;
  const fs::path dir = treecut::test::scratch_dir("cli_color");
  treecut::test::CommandResult r = run_treecut("gen city -n 20000 -o " + quote(dir / "c.las"));
  ASSERT_EQ(r.code, 0) << r.out;
  r = run_treecut("info " + quote(dir / "c.las"));
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("  classification         category 2 .. 6"), std::string::npos) << r.out;
  const std::string common = " --frames 1 --width 96 --height 64 --gl osmesa --no-png -o ";
  r = run_treecut("render " + quote(dir / "c.las") + " --color classification --classes 2" +
                  common + quote(dir / "out"));
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("colour    classification: 2 ground"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("6 building"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("% (hidden)"), std::string::npos) << r.out;
  r = run_treecut("render " + quote(dir / "c.las") + " --color intensity --color-map grey" +
                  common + quote(dir / "out2"));
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("colour    intensity: grey from "), std::string::npos) << r.out;
  for (const std::string bad :
       {"--color height", "--classes 2,-7", "--color-range 5 1", "--color-map jet"}) {
    r = run_treecut("render " + quote(dir / "c.las") + " " + bad + common + quote(dir / "bad"));
    EXPECT_EQ(r.code, 2) << bad << "\n" << r.out;
    EXPECT_FALSE(fs::exists(dir / "bad")) << bad;
  }
}

// `export`: LAS to PLY (relative, by request), to PCD and back to LAS with
// the attributes, a class filter, and every refusal before anything is
// written.
TEST(Cli, ExportConvertsBetweenFormatsKeepingTheAttributes) {
  using treecut::test::quote;
  using treecut::test::run_treecut;
  const fs::path dir = treecut::test::scratch_dir("cli_export");
  treecut::test::CommandResult r =
      run_treecut("gen city -n 5000 --origin 500000 5000000 10 -o " + quote(dir / "c.las"));
  ASSERT_EQ(r.code, 0) << r.out;
  // Map coordinates go to a PLY in double, nothing to ask (issue 43).
  r = run_treecut("export " + quote(dir / "c.las") + " -o " + quote(dir / "c.ply"));
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("(5000 of 5000 points, 10 attributes, from LAS)"), std::string::npos)
      << r.out;
  r = run_treecut("info " + quote(dir / "c.ply"));
  EXPECT_NE(r.out.find("origin      [500000.000 5000000.000 10.000]"), std::string::npos) << r.out;
  // --relative asks for floats, the origin printed and in a comment that
  // treecut reads back.
  r = run_treecut("export " + quote(dir / "c.las") + " --relative -o " + quote(dir / "r.ply"));
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("origin 500000.000 5000000.000 10.000: add it"), std::string::npos) << r.out;
  r = run_treecut("info " + quote(dir / "r.ply"));
  EXPECT_NE(r.out.find("origin      [500000.000 5000000.000 10.000]"), std::string::npos) << r.out;
  r = run_treecut("export " + quote(dir / "c.ply") + " -o " + quote(dir / "c.pcd"));
  ASSERT_EQ(r.code, 0) << r.out;
  r = run_treecut("export " + quote(dir / "c.pcd") + " --classes 6 -o " + quote(dir / "b.las"));
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("from PCD"), std::string::npos) << r.out;
  r = run_treecut("info " + quote(dir / "b.las"));
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("  intensity"), std::string::npos) << r.out;
  // Only buildings: one class, kept as what it is.
  EXPECT_NE(r.out.find("  classification         category 6 at every point"), std::string::npos)
      << r.out;
  r = run_treecut("export " + quote(dir / "b.las") + " -o " + quote(dir / "b.pcd"));
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_EQ(r.out.find("warning"), std::string::npos) << r.out;
  r = run_treecut("export " + quote(dir / "b.pcd") + " --classes 6 -o " + quote(dir / "c6.las"));
  EXPECT_EQ(r.code, 0) << "a constant classification still filters: " << r.out;
  // Refused, nothing written: the input itself, another kind of file, a
  // format it does not write, a filter that keeps nothing.
  std::ofstream(dir / "notes.las") << "my notes\n";
  for (const auto& [args, error] : std::vector<std::pair<std::string, std::string>>{
           {quote(dir / "c.las") + " -o " + quote(dir / "c.las"), "which this command reads"},
           {quote(dir / "c.las") + " -o " + quote(dir / "notes.las"), "is not a LAS file"},
           {quote(dir / "c.las") + " -o " + quote(dir / "c.txt"),
            "export writes .las, .ply or .pcd"},
           {quote(dir / "c.las") + " --classes 9 -o " + quote(dir / "w.las"), "keeps no point"}}) {
    r = run_treecut("export " + args);
    EXPECT_EQ(r.code, 2) << args << "\n" << r.out;
    EXPECT_NE(r.out.find(error), std::string::npos) << r.out;
  }
  EXPECT_FALSE(fs::exists(dir / "w.las"));
  EXPECT_FALSE(fs::exists(dir / "c.txt"));
  std::ifstream notes(dir / "notes.las");
  EXPECT_EQ(std::string((std::istreambuf_iterator<char>(notes)), {}), "my notes\n");
}

// `--columns` reaches the reader from build, info and export, and is part of
// the cache key: another mapping of the same file is another hierarchy.
TEST(Cli, ColumnsNameATextCloudsColumnsAndKeyTheCache) {
  using treecut::test::quote;
  using treecut::test::run_treecut;
  const fs::path dir = treecut::test::scratch_dir("cli_columns");
  {
    std::ofstream xyz(dir / "s.txt");
    for (int i = 0; i < 400; ++i) {
      xyz << i % 20 << " " << i / 20 << " " << (i * 7) % 5 << " " << i % 3 << " " << 100 + i
          << "\n";
    }
  }
  treecut::test::CommandResult r =
      run_treecut("info " + quote(dir / "s.txt") + " --columns x,y,z,label,intensity");
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("  label                  category 0 .. 2"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("  intensity              measure  100 .. 499"), std::string::npos) << r.out;
  r = run_treecut("info " + quote(dir / "s.txt") + " --columns x,y,z,_,intensity");
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_EQ(r.out.find("  label"), std::string::npos) << "a cached hierarchy of another mapping\n"
                                                      << r.out;
  EXPECT_NE(r.out.find("attributes  1 "), std::string::npos) << r.out;
  r = run_treecut("export " + quote(dir / "s.txt") + " --columns x,y,z,label,_ -o " +
                  quote(dir / "s.las"));
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("1 attributes, from text"), std::string::npos) << r.out;
  r = run_treecut("info " + quote(dir / "s.las") + " --columns x,y,z");
  EXPECT_EQ(r.code, 2) << r.out;
  EXPECT_NE(r.out.find("--columns names the columns of a text cloud"), std::string::npos) << r.out;
}

TEST(Cli, MalformedPlyExitsWithTwoAndWritesNothing) {
  const auto shared = treecut::test::shared_dir();
  if (!shared) GTEST_SKIP() << "../shared is absent";
  const fs::path dir = treecut::test::scratch_dir("cli_bad");
  std::ifstream manifest(*shared / "ply-corpus" / "MANIFEST.tsv");
  std::string line;
  int checked = 0;
  while (std::getline(manifest, line)) {
    const auto tab = line.find('\t');
    if (tab == std::string::npos || line.find("\terror\t") == std::string::npos) continue;
    const std::string file = line.substr(0, tab);
    const fs::path out = dir / (file + ".tch");
    const treecut::test::CommandResult r =
        treecut::test::run_treecut("build " + treecut::test::quote(*shared / "ply-corpus" / file) +
                                   " -o " + treecut::test::quote(out));
    EXPECT_EQ(r.code, 2) << file << "\n" << r.out;
    EXPECT_NE(r.out.find(file), std::string::npos) << "the message names the file: " << r.out;
    EXPECT_FALSE(fs::exists(out)) << file;
    ++checked;
  }
  EXPECT_GE(checked, 10);
  EXPECT_TRUE(fs::is_empty(dir)) << "no partial output of any kind";
}

// -- text inputs and usage messages (issue 9: nothing hangs, nothing reads
// without bound; messages that name the real problem) ------------------------

namespace {

constexpr const char* kFastRender =
    "render --default-points 2000 --width 64 --height 48 --frames 2 --warmup 0 --no-png";

std::size_t lines_of(const std::string& out) {
  return static_cast<std::size_t>(std::count(out.begin(), out.end(), '\n'));
}

void write_file(const fs::path& file, const std::string& text) {
  std::ofstream out(file, std::ios::binary);
  out << text;
  ASSERT_TRUE(out.good()) << file;
}

}  // namespace

TEST(Cli, TextInputsAndPluginsThatAreNotRegularFilesAreNamedAtOnce) {
  const fs::path dir = treecut::test::scratch_dir("cli_special_inputs");
  ASSERT_EQ(::mkfifo((dir / "fifo").c_str(), 0600), 0);
  fs::create_directories(dir / "folder");
  const std::pair<fs::path, const char*> specials[] = {{dir / "fifo", "is a FIFO"},
                                                       {dir / "folder", "is a directory"},
                                                       {"/dev/zero", "is a character device"}};
  const std::string out = " --out " + treecut::test::quote(dir / "out");
  for (const auto& [path, named] : specials) {
    const std::string p = treecut::test::quote(path);
    for (const std::string& args :
         {std::string(kFastRender) + out + " --path " + p, "view --path " + p, "view --script " + p,
          "strategies --plugin " + p, std::string(kFastRender) + out + " --plugin " + p}) {
      // 60 s: a command that blocks in open() or reads /dev/zero is killed (124).
      const treecut::test::CommandResult r = treecut::test::run_treecut(args, 60);
      EXPECT_EQ(r.code, 2) << args << "\n" << r.out;
      EXPECT_NE(r.out.find(path.string() + ": " + named), std::string::npos) << args << "\n"
                                                                             << r.out;
      EXPECT_EQ(r.out.find("no such file"), std::string::npos) << r.out;
      EXPECT_EQ(lines_of(r.out), 1u) << args << "\n" << r.out;
    }
  }
  EXPECT_FALSE(fs::exists(dir / "out")) << "nothing written before the inputs were checked";
}

TEST(Cli, TextInputsOverTheLimitAreRefused) {
  const fs::path dir = treecut::test::scratch_dir("cli_big_inputs");
  const std::string filler = "# " + std::string(1000, 'x') + "\n";
  std::string path = "treecut-camera-path 1\n0 0 0 5 0 0 0 0 1 0 45\n";
  std::string script = "treecut-view-script 1\nexit\n";
  while (path.size() < (std::size_t{17} << 20)) path += filler, script += filler;
  write_file(dir / "big.campath", path);
  write_file(dir / "big.script", script);
  for (const std::string& args :
       {std::string(kFastRender) + " --out " + treecut::test::quote(dir / "out") + " --path " +
            treecut::test::quote(dir / "big.campath"),
        "view --path " + treecut::test::quote(dir / "big.campath"),
        "view --script " + treecut::test::quote(dir / "big.script")}) {
    const treecut::test::CommandResult r = treecut::test::run_treecut(args, 60);
    EXPECT_EQ(r.code, 2) << args << "\n" << r.out;
    EXPECT_NE(r.out.find(": larger than 16777216 bytes"), std::string::npos) << r.out;
    EXPECT_EQ(lines_of(r.out), 1u) << r.out;
  }
}

TEST(Cli, NumbersThatDoNotFitAndBadKeysNameFileAndLine) {
  const fs::path dir = treecut::test::scratch_dir("cli_bad_numbers");
  const std::string head = "treecut-camera-path 1\n0 0 0 5 0 0 0 0 1 0 45\n";
  const std::pair<std::string, std::string> paths[] = {
      {"1e400 0 0 5 0 0 0 0 1 0 45", "time.campath:3: time '1e400' is out of range"},
      {"1 0 0 5 0 0 0 0 0 1 45", "up.campath:3: up vector is parallel to the view direction"},
      {"1 0 0 5 0 0 0 0 1 0 200", "fov.campath:3: fov_y_deg outside (1, 170)"},
  };
  for (const auto& [key, says] : paths) {
    const fs::path file = dir / says.substr(0, says.find(':'));
    write_file(file, head + key + "\n");
    const treecut::test::CommandResult r = treecut::test::run_treecut(
        std::string(kFastRender) + " --out " + treecut::test::quote(dir / "out") + " --path " +
        treecut::test::quote(file));
    EXPECT_EQ(r.code, 2) << r.out;
    EXPECT_NE(r.out.find(file.string() + says.substr(says.find(':'))), std::string::npos) << r.out;
    EXPECT_EQ(lines_of(r.out), 1u) << r.out;
  }
  const std::pair<std::string, std::string> scripts[] = {
      {"frames 99999999999", "frames: '99999999999' is out of range"},
      {"converge 1e30", "converge: '1e30' is not a whole number"},
      {"frames -5", "frames: '-5' is out of range"},
      {"param max_nodes 1e30", "param: max_nodes"},
  };
  for (const auto& [line, says] : scripts) {
    const fs::path file = dir / "run.script";
    write_file(file, "treecut-view-script 1\nframes 1\n" + line + "\nexit\n");
    // Checked before a window opens: no display is needed for this.
    const treecut::test::CommandResult r =
        treecut::test::run_treecut("view --script " + treecut::test::quote(file), 60);
    EXPECT_EQ(r.code, 2) << line << "\n" << r.out;
    EXPECT_NE(r.out.find(file.string() + ":3: " + says), std::string::npos) << r.out;
    EXPECT_EQ(lines_of(r.out), 1u) << r.out;
  }
  // A valid path still renders.
  write_file(dir / "ok.campath", head + "1 0 5 0 0 0 0 0 0 1 45\n");
  const treecut::test::CommandResult ok = treecut::test::run_treecut(
      std::string(kFastRender) + " --out " + treecut::test::quote(dir / "out") + " --path " +
      treecut::test::quote(dir / "ok.campath"));
  EXPECT_EQ(ok.code, 0) << ok.out;
}

TEST(Cli, UnknownCommandsAndOptionsAreNamedOnOneLine) {
  const std::pair<std::string, std::string> cases[] = {
      {"frobnicate", "treecut: unknown command 'frobnicate' (see treecut --help)"},
      {"--frobnicate", "treecut: unknown option '--frobnicate' (see treecut --help)"},
      {"render --frobnicate=3", "treecut render: unknown option '--frobnicate'"},
      {"info a.ply b.ply", "treecut info: unexpected argument 'b.ply'"},
      {"bench frob", "treecut bench: unknown command 'frob' (see treecut bench --help)"},
      {"", "treecut: no command given; one of build, info, gen"},
  };
  for (const auto& [args, says] : cases) {
    const treecut::test::CommandResult r = treecut::test::run_treecut(args);
    EXPECT_EQ(r.code, 2) << args << "\n" << r.out;
    EXPECT_EQ(r.out.rfind(says, 0), 0u) << args << "\n" << r.out;
    EXPECT_EQ(lines_of(r.out), 1u) << args << "\n" << r.out;
  }
}

// bench cache (issue 44): one row a model, its cache's bytes a point; the
// scratch cache it measured is gone; a malformed model is one line.
TEST(Cli, BenchCacheMeasuresEachModelsCacheAndLeavesNothing) {
  const fs::path dir = treecut::test::scratch_dir("cli_bench_cache");
  const fs::path model = dir / "sphere.ply";
  ASSERT_EQ(treecut::test::run_treecut("gen sphere -n 3000 -o " + treecut::test::quote(model)).code,
            0);
  treecut::test::CommandResult r =
      treecut::test::run_treecut("bench cache -r 2 " + treecut::test::quote(model));
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("| model | points | nodes | arrays MiB | cache MiB"), std::string::npos)
      << r.out;
  const std::size_t row = r.out.find("| sphere.ply | 3000 | ");
  ASSERT_NE(row, std::string::npos) << r.out;
  EXPECT_EQ(lines_of(r.out), 3u) << r.out;
  for (const auto& e : fs::directory_iterator(fs::temp_directory_path()))
    EXPECT_EQ(e.path().filename().string().rfind("treecut-bench-cache-", 0), std::string::npos)
        << e.path();
  std::ofstream(dir / "bad.ply") << "ply\nformat nonsense 1.0\nend_header\n";
  r = treecut::test::run_treecut("bench cache " + treecut::test::quote(dir / "bad.ply"));
  EXPECT_EQ(r.code, 2) << r.out;
  EXPECT_EQ(lines_of(r.out), 1u) << r.out;
}

TEST(Cli, BenchBuildOnAMalformedPlyExitsWithTwoAndOneLine) {
  const auto shared = treecut::test::shared_dir();
  if (!shared) GTEST_SKIP() << "../shared is absent";
  const fs::path bad = *shared / "ply-corpus" / "bad_format.ply";
  if (!fs::exists(bad)) GTEST_SKIP() << bad << " is absent";
  treecut::test::CommandResult r =
      treecut::test::run_treecut("bench build -r 2 " + treecut::test::quote(bad));
  EXPECT_EQ(r.code, 2) << r.out;
  EXPECT_EQ(r.out.rfind("treecut: " + bad.string() + ": ", 0), 0u) << r.out;
  EXPECT_EQ(lines_of(r.out), 1u) << "no table header, no second message:\n" << r.out;
  // A FIFO is refused before any run (a child would block on it).
  const fs::path dir = treecut::test::scratch_dir("cli_bench_fifo");
  ASSERT_EQ(::mkfifo((dir / "model.ply").c_str(), 0600), 0);
  r = treecut::test::run_treecut("bench build " + treecut::test::quote(dir / "model.ply"), 60);
  EXPECT_EQ(r.code, 2) << r.out;
  EXPECT_NE(r.out.find("model.ply: is a FIFO"), std::string::npos) << r.out;
  EXPECT_EQ(lines_of(r.out), 1u) << r.out;
}
