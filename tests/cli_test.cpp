// The `treecut` program: exit codes (0 ok, 1 runtime failure, 2 bad input),
// --help on every command, no output written on failure.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <array>
#include <cstdio>
#include <fstream>

#include "test_support.hpp"

namespace fs = std::filesystem;

namespace {

struct CliRun {
  int code = -1;
  std::string out;
};

// Runs the treecut program with the given arguments (shell-quoted by the caller).
CliRun run_treecut(const std::string& args) {
  const fs::path bin = fs::path(TREECUT_BINARY_DIR) / "demo" / "treecut";
  const std::string cmd = "'" + bin.string() + "' " + args + " 2>&1";
  CliRun r;
  FILE* p = popen(cmd.c_str(), "r");
  if (!p) return r;
  std::array<char, 4096> buf;
  while (std::fgets(buf.data(), buf.size(), p)) r.out += buf.data();
  const int status = pclose(p);
  r.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}

std::string quote(const fs::path& p) { return "'" + p.string() + "'"; }

}  // namespace

TEST(Cli, HelpWorksForEveryCommand) {
  for (const char* c : {"", "build", "info", "gen", "bench build"}) {
    const CliRun r = run_treecut(std::string(c) + " --help");
    EXPECT_EQ(r.code, 0) << c << "\n" << r.out;
    EXPECT_NE(r.out.find("Usage"), std::string::npos) << c;
  }
}

TEST(Cli, UsageErrorsExitWithTwo) {
  EXPECT_EQ(run_treecut("").code, 2);
  EXPECT_EQ(run_treecut("no-such-command").code, 2);
  EXPECT_EQ(run_treecut("build").code, 2) << "missing MODEL";
  EXPECT_EQ(run_treecut("gen pyramid -o /tmp/x.ply").code, 2) << "unknown kind";
}

TEST(Cli, GenBuildInfoRoundTrip) {
  const fs::path dir = treecut::test::scratch_dir("cli_gen");
  CliRun r = run_treecut("gen terrain -n 20000 -o " + quote(dir / "t.ply"));
  ASSERT_EQ(r.code, 0) << r.out;
  ASSERT_TRUE(fs::exists(dir / "t.ply"));
  r = run_treecut("build " + quote(dir / "t.ply") + " -o " + quote(dir / "t.tch"));
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("points      20000"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("build time"), std::string::npos) << r.out;
  r = run_treecut("info " + quote(dir / "t.tch"));
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
    const CliRun r = run_treecut("build " + quote(*shared / "ply-corpus" / file) + " -o " + quote(out));
    EXPECT_EQ(r.code, 2) << file << "\n" << r.out;
    EXPECT_NE(r.out.find(file), std::string::npos) << "the message names the file: " << r.out;
    EXPECT_FALSE(fs::exists(out)) << file;
    ++checked;
  }
  EXPECT_GE(checked, 10);
  EXPECT_TRUE(fs::is_empty(dir)) << "no partial output of any kind";
}
