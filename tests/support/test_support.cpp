#include "test_support.hpp"

#include <gtest/gtest.h>
#include <sys/mount.h>
#include <sys/wait.h>

#include <array>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <iterator>
#include <sstream>

namespace treecut::test {

namespace {
constexpr const char* kExitMarker = "treecut-test-exit-code ";
}  // namespace

std::optional<std::filesystem::path> shared_dir() {
  std::filesystem::path p = TREECUT_SHARED_DIR;
  if (const char* env = std::getenv("TREECUT_SHARED_DIR")) p = env;
  std::error_code ec;
  if (std::filesystem::is_directory(p, ec)) return p;
  return std::nullopt;
}

std::optional<std::filesystem::path> shared_asset(const std::string& name) {
  auto dir = shared_dir();
  if (!dir) return std::nullopt;
  auto p = *dir / "assets" / name;
  std::error_code ec;
  if (!std::filesystem::is_regular_file(p, ec)) return std::nullopt;
  return p;
}

std::filesystem::path scratch_dir(const std::string& name) {
  auto p = std::filesystem::path(TREECUT_BINARY_DIR) / "test-scratch" / name;
  std::filesystem::remove_all(p);
  std::filesystem::create_directories(p);
  return p;
}

void expect_failure(const CommandResult& r, int code, const std::string& text) {
  std::size_t lines = 0;
  std::istringstream in(r.out);
  for (std::string line; std::getline(in, line);) ++lines;
  EXPECT_EQ(r.code, code) << r.out;
  EXPECT_EQ(lines, 1u) << r.out;
  EXPECT_NE(r.out.find(text), std::string::npos) << "wanted: " << text << "\ngot: " << r.out;
}

CommandResult run_treecut(const std::string& args, int timeout_seconds) {
  const auto bin = std::filesystem::path(TREECUT_BINARY_DIR) / "demo" / "treecut";
  const std::string cmd =
      "timeout -k 5 " + std::to_string(timeout_seconds) + " " + quote(bin) + " " + args + " 2>&1";
  CommandResult r;
  FILE* p = popen(cmd.c_str(), "r");
  if (!p) return r;
  std::array<char, 4096> buf;
  while (std::fgets(buf.data(), static_cast<int>(buf.size()), p)) r.out += buf.data();
  const int status = pclose(p);
  r.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}

std::optional<CommandResult> run_treecut_in_xvfb(const std::string& args,
                                                 const std::filesystem::path& dir,
                                                 const std::string& screen,
                                                 const std::string& env) {
  if (std::system("command -v xvfb-run > /dev/null 2>&1") != 0) return std::nullopt;
  const auto bin = std::filesystem::path(TREECUT_BINARY_DIR) / "demo" / "treecut";
  const std::filesystem::path runner = dir / "run-in-xvfb.sh";
  {
    std::ofstream out(runner, std::ios::binary);
    out << "cd " << quote(dir) << " && " << env << " " << quote(bin) << " " << args
        << " 2>&1\necho \"" << kExitMarker << "$?\"\n";
    out.close();  // the write is checked after the flush
    if (!out) return CommandResult{-1, "cannot write " + runner.string()};
  }
  const std::string cmd =
      "LSAN_OPTIONS=detect_leaks=0 timeout -k 5 240 xvfb-run -a -s '-screen 0 " + screen + "' sh " +
      quote(runner) + " 2>&1";
  CommandResult r;
  FILE* p = popen(cmd.c_str(), "r");
  if (!p) return r;
  std::array<char, 4096> buf;
  while (std::fgets(buf.data(), static_cast<int>(buf.size()), p)) r.out += buf.data();
  pclose(p);
  const auto at = r.out.rfind(kExitMarker);
  if (at != std::string::npos) {
    r.code = std::atoi(r.out.c_str() + at + std::strlen(kExitMarker));
    r.out.erase(at, r.out.find('\n', at) - at + 1);  // the marker is not the program's output
  }
  return r;
}

std::string read_all(const std::filesystem::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), {}};
}

std::string cache_but_identity_time(std::string bytes) {
  if (bytes.size() < 96) return bytes;
  bytes.replace(80, 8, 8, '\0');
  bytes.replace(bytes.size() - 8, 8, 8, '\0');
  return bytes;
}

void write_text(const std::filesystem::path& p, const std::string& text) {
  std::ofstream out(p, std::ios::binary | std::ios::trunc);
  out << text;
  out.close();
  EXPECT_TRUE(out.good()) << "cannot write " << p;
}

std::string quote(const std::filesystem::path& p) {
  return "'" + p.string() + "'";
}

std::optional<SmallDisk> SmallDisk::mount(const std::string& name, std::size_t bytes) {
  const std::filesystem::path p = scratch_dir(name);
  const std::string options = "size=" + std::to_string(bytes) + ",mode=0755";
  if (::mount("tmpfs", p.c_str(), "tmpfs", 0, options.c_str()) != 0) return std::nullopt;
  return SmallDisk(p);
}

SmallDisk::~SmallDisk() {
  if (!path_.empty()) ::umount2(path_.c_str(), MNT_DETACH);
}

std::string node_difference(const HierarchyArrays& a, const HierarchyArrays& b, NodeId n) {
  if (a.center_radius[n] != b.center_radius[n]) return "center_radius";
  if (a.splat_radius[n] != b.splat_radius[n]) return "splat_radius";
  if (a.normal_cone[n] != b.normal_cone[n]) return "normal_cone";
  if (a.color[n] != b.color[n]) return "color";
  if (a.priority[n] != b.priority[n]) return "priority";
  if (a.point_count[n] != b.point_count[n]) return "point_count";
  if (a.parent[n] != b.parent[n]) return "parent";
  if (a.child_count[n] != b.child_count[n]) return "child_count";
  if (a.child_count[n] != 0 && a.first_child[n] != b.first_child[n]) return "first_child";
  if (a.depth[n] != b.depth[n]) return "depth";
  return {};
}

std::vector<NodeId> reachable(const Hierarchy& h) {
  std::vector<NodeId> order{h.root()};
  for (std::size_t i = 0; i < order.size(); ++i)
    for (NodeId c = h.first_child(order[i]); c < h.first_child(order[i]) + h.child_count(order[i]);
         ++c)
      order.push_back(c);
  return order;
}

void load_every_page(PagedHierarchy& paged) {
  for (int round = 0; round < 100; ++round) {
    std::vector<NodeId> hidden;
    for (const NodeId n : reachable(paged.hierarchy()))
      if (paged.hidden(n)) hidden.push_back(n);
    paged.request(hidden);
    ASSERT_TRUE(paged.wait_idle(20000));
    if (paged.publish() == 0) return;
  }
  FAIL() << "pages still arriving after 100 rounds";
}

}  // namespace treecut::test
