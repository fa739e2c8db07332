// Helpers shared by the tests: paths to ../shared and to generated fixtures.
#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "treecut/hierarchy.hpp"
#include "treecut/paged_hierarchy.hpp"

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
/// Runs the built `treecut` program with `args` (already shell-quoted), under
/// `timeout`: a command that hangs fails the test with code 124 instead of
/// stalling the suite.
CommandResult run_treecut(const std::string& args, int timeout_seconds = 300);
/// The house rule for a failure (docs/files.md): exit CODE and exactly one
/// line of output, which contains TEXT (an EXPECT each).
void expect_failure(const CommandResult& r, int code, const std::string& text);
/// Runs the built `treecut` with `args` (already shell-quoted) in a window
/// under Xvfb (`xvfb-run -a`, screen WxHxDEPTH), from folder `dir`, with the
/// environment assignments `env` ("A=1 B=2") and no leak check (Mesa's GLX
/// driver leaks when the window closes: tests/viewer_window_test/check.cmake).
/// The code is the program's own, printed inside the X session: xvfb-run's is
/// not (it exits 5 when it cannot remove its temporary folder, whatever the
/// program did). nullopt when xvfb-run is not installed.
std::optional<CommandResult> run_treecut_in_xvfb(const std::string& args,
                                                 const std::filesystem::path& dir,
                                                 const std::string& screen,
                                                 const std::string& env = "");
/// 'path', single-quoted for the shell.
std::string quote(const std::filesystem::path& p);

/// The bytes of a file (empty when it cannot be read).
std::string read_all(const std::filesystem::path& p);
/// A cache file's bytes but for when the build read its model (the
/// header's identity_ns, bytes 80-87, and so the checksum, the last 8):
/// what two builds of the same input share.
std::string cache_but_identity_time(std::string bytes);
/// Writes TEXT as the whole file P; a failed write fails the test.
void write_text(const std::filesystem::path& p, const std::string& text);

/// A small tmpfs mounted at a scratch folder, for tests of a full disk:
/// writes past `bytes` fail with ENOSPC. Unmounted on destruction.
class SmallDisk {
 public:
  /// nullopt when this process may not mount (not root, no CAP_SYS_ADMIN);
  /// the caller GTEST_SKIPs with a message.
  static std::optional<SmallDisk> mount(const std::string& name, std::size_t bytes);
  SmallDisk(SmallDisk&& other) noexcept : path_(std::move(other.path_)) { other.path_.clear(); }
  SmallDisk(const SmallDisk&) = delete;
  SmallDisk& operator=(const SmallDisk&) = delete;
  SmallDisk& operator=(SmallDisk&&) = delete;
  ~SmallDisk();
  [[nodiscard]] const std::filesystem::path& path() const { return path_; }

 private:
  explicit SmallDisk(std::filesystem::path p) : path_(std::move(p)) {}
  std::filesystem::path path_;
};

/// The first of node N's values that differs between A and B (its name:
/// "center_radius", "parent", ...; first_child only where the node has
/// children), or empty: two loads of one hierarchy, node by node.
std::string node_difference(const HierarchyArrays& a, const HierarchyArrays& b, NodeId n);

/// The nodes reachable from H's root as it shows them now, breadth first.
std::vector<NodeId> reachable(const Hierarchy& h);
/// Every page of PAGED that reads: the hidden nodes asked for, read and
/// published, until nothing more arrives (a gtest failure otherwise).
void load_every_page(PagedHierarchy& paged);

}  // namespace treecut::test

/// Skips the current test with a clear message when a shared asset is absent.
#define TREECUT_REQUIRE_ASSET(var, name)                                         \
  const auto var##_opt = ::treecut::test::shared_asset(name);                    \
  if (!var##_opt) GTEST_SKIP() << "../shared/assets/" << (name) << " is absent"; \
  const std::filesystem::path& var = *var##_opt
