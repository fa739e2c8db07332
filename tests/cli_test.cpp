// The `treecut` program: exit codes (0 ok, 1 runtime failure, 2 bad input),
// --help on every command, no output written on failure.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <array>
#include <cstdio>
#include <fstream>

#include "test_support.hpp"

namespace fs = std::filesystem;

TEST(Cli, HelpWorksForEveryCommand) {
  for (const char* c : {"", "build", "info", "gen", "bench build"}) {
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
