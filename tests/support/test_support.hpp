// Helpers shared by the tests: paths to ../shared and to generated fixtures.
#pragma once

#include <filesystem>
#include <optional>
#include <string>

namespace treecut::test {

/// ../shared (papers, assets, ply-corpus), or nullopt when it is absent.
std::optional<std::filesystem::path> shared_dir();
/// ../shared/assets/NAME, or nullopt (the caller GTEST_SKIPs with a message).
std::optional<std::filesystem::path> shared_asset(const std::string& name);
/// A fresh empty directory under the build tree for this test's outputs.
std::filesystem::path scratch_dir(const std::string& name);

/// Exit code (-1 when it did not exit normally) and merged stdout+stderr.
struct CommandResult {
  int code = -1;
  std::string out;
};
/// Runs the built `treecut` program with `args` (already shell-quoted).
CommandResult run_treecut(const std::string& args);
/// 'path', single-quoted for the shell.
std::string quote(const std::filesystem::path& p);

}  // namespace treecut::test

/// Skips the current test with a clear message when a shared asset is absent.
#define TREECUT_REQUIRE_ASSET(var, name)                                         \
  const auto var##_opt = ::treecut::test::shared_asset(name);                    \
  if (!var##_opt) GTEST_SKIP() << "../shared/assets/" << (name) << " is absent"; \
  const std::filesystem::path& var = *var##_opt
