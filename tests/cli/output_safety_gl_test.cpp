// No file of the user's is ever lost and every failure is reported: `build`,
// `gen` and `render` as a user runs them against the files a user has
// (the model itself under another name, another model, notes, a FIFO, a
// directory), on a read-only and on a full file system. Every file here is
// made by the test under its scratch folder or on a SmallDisk.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <sys/mount.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iterator>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "test_support.hpp"
#include "treecut/ply.hpp"
#include "treecut/splat/camera_path.hpp"
#include "treecut/tools/generate.hpp"

namespace fs = std::filesystem;
using treecut::test::cache_but_identity_time;
using treecut::test::CommandResult;
using treecut::test::quote;
using treecut::test::read_all;
using treecut::test::run_treecut;
using treecut::test::scratch_dir;
using treecut::test::SmallDisk;
using treecut::test::write_text;

namespace {

fs::path small_model(const fs::path& dir, const std::string& name, std::size_t points = 3000,
                     std::uint64_t seed = 1) {
  const fs::path p = dir / name;
  treecut::save_ply(
      p, treecut::tools::generate_model(treecut::tools::ModelKind::Sphere, points, seed));
  return p;
}

std::vector<std::string> lines_of(const std::string& text) {
  std::vector<std::string> lines;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  return lines;
}

std::size_t count_lines_with(const std::string& text, const std::string& needle) {
  std::size_t n = 0;
  for (const std::string& line : lines_of(text)) n += line.find(needle) != std::string::npos;
  return n;
}

// The house rule for a failure: exit CODE and one line, which says TEXT
// (CONTEXT goes before the output in a failure's message).
void expect_one_line_failure(const CommandResult& r, int code, const std::string& text,
                             const std::string& context = "") {
  EXPECT_EQ(r.code, code) << context << r.out;
  EXPECT_EQ(lines_of(r.out).size(), 1u) << r.out;
  EXPECT_NE(r.out.find(text), std::string::npos) << r.out;
}

std::vector<fs::path> files_under(const fs::path& dir) {
  std::vector<fs::path> out;
  for (const auto& e : fs::recursive_directory_iterator(dir))
    if (!e.is_directory()) out.push_back(e.path());
  return out;
}

// Sets an environment variable for the commands this test runs; restores it.
class ScopedEnv {
 public:
  ScopedEnv(const char* name, const std::string& value) : name_(name) {
    if (const char* old = std::getenv(name)) old_ = old;
    ::setenv(name, value.c_str(), 1);
  }
  ScopedEnv(const ScopedEnv&) = delete;
  ScopedEnv& operator=(const ScopedEnv&) = delete;
  ~ScopedEnv() {
    if (old_)
      ::setenv(name_, old_->c_str(), 1);
    else
      ::unsetenv(name_);
  }

 private:
  const char* name_;
  std::optional<std::string> old_;
};

// The default cache of MODEL as `treecut build` prints it ("cache       PATH").
fs::path printed_cache(const std::string& out) {
  for (const std::string& line : lines_of(out))
    if (line.rfind("cache       ", 0) == 0) return line.substr(12);
  return {};
}

const std::string kTinyRender =
    "render --width 48 --height 32 --frames 2 --warmup 0 --sync --default-points 2000 ";

}  // namespace

// -- build -o PATH ------------------------------------------------------------

TEST(OutputSafety, BuildNeverOverwritesTheModelItself) {
  const fs::path dir = scratch_dir("safety_build_self");
  const fs::path model = small_model(dir, "bun.ply");
  const std::string bytes = read_all(model);
  fs::create_hard_link(model, dir / "hard.ply");
  fs::create_symlink(model, dir / "link.ply");
  for (const char* force : {"", "-f "}) {
    for (const fs::path& out : {model, dir / "hard.ply", dir / "link.ply"}) {
      const CommandResult r =
          run_treecut("build " + std::string(force) + quote(model) + " -o " + quote(out));
      expect_one_line_failure(r, 2, out.string() + ": is the model itself",
                              force + out.string() + "\n");
      EXPECT_EQ(read_all(model), bytes) << "the model was replaced through " << out;
    }
  }
  EXPECT_TRUE(fs::is_symlink(dir / "link.ply"));
}

TEST(OutputSafety, BuildNeverOverwritesAnotherModelOrAnyOtherFile) {
  const fs::path dir = scratch_dir("safety_build_other");
  const fs::path model = small_model(dir, "bun.ply");
  const fs::path lion = small_model(dir, "lion.ply", 2000, 7);
  const std::string lion_bytes = read_all(lion);
  write_text(dir / "notes.txt", "my notes\n");
  write_text(dir / "bad.ply",
             "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n"
             "end_header\n1\n");
  for (const char* force : {"", "-f "}) {
    CommandResult r =
        run_treecut("build " + std::string(force) + quote(model) + " -o " + quote(lion));
    EXPECT_EQ(r.code, 2) << r.out;
    EXPECT_NE(r.out.find(lion.string() + ": exists and is not a treecut cache"), std::string::npos)
        << r.out;
    EXPECT_EQ(read_all(lion), lion_bytes);
    // The output is checked before the model is read: a malformed model
    // cannot cost the user a file.
    r = run_treecut("build " + std::string(force) + quote(dir / "bad.ply") + " -o " +
                    quote(dir / "notes.txt"));
    EXPECT_EQ(r.code, 2) << r.out;
    EXPECT_EQ(lines_of(r.out).size(), 1u) << r.out;
    EXPECT_EQ(read_all(dir / "notes.txt"), "my notes\n");
  }
}

TEST(OutputSafety, BuildForceReplacesTheCacheOnlyWhenTheNewOneIsComplete) {
  const fs::path dir = scratch_dir("safety_build_force");
  const fs::path model = small_model(dir, "m.ply");
  const fs::path cache = dir / "m.tch";
  CommandResult r = run_treecut("build " + quote(model) + " -o " + quote(cache));
  ASSERT_EQ(r.code, 0) << r.out;
  const std::string old_cache = read_all(cache);
  r = run_treecut("build -f " + quote(model) + " -o " + quote(cache));
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("build time"), std::string::npos) << "-f rebuilds: " << r.out;
  // The same input gives the same cache, but for when the build read the
  // model (the header's identity_ns, bytes 80-87, and so the checksum).
  const std::string rebuilt = read_all(cache);
  EXPECT_EQ(cache_but_identity_time(rebuilt), cache_but_identity_time(old_cache))
      << "the same input gives the same cache";
  // The model turns malformed: -f fails and the earlier cache stays.
  write_text(model, "ply\nformat ascii 1.0\nelement vertex 9\nproperty float x\nend_header\n1\n");
  r = run_treecut("build -f " + quote(model) + " -o " + quote(cache));
  EXPECT_EQ(r.code, 2) << r.out;
  EXPECT_EQ(read_all(cache), rebuilt) << "-f removed the cache before the build succeeded";
  EXPECT_EQ(files_under(dir).size(), 2u) << "no temporary left behind";
}

// A cache given by name whose page is corrupted: one line naming the file
// and the page, a non-zero exit, nothing drawn (issue 44).
TEST(OutputSafety, ACorruptedPageOfANamedCacheIsOneLineNamingFileAndPage) {
  const fs::path dir = treecut::test::scratch_dir("cli_page");
  const fs::path model = dir / "m.ply", cache = dir / "m.tch";
  ASSERT_EQ(run_treecut("gen sphere -n 6000 -o " + quote(model)).code, 0);
  const auto built = run_treecut("build " + quote(model) + " -o " + quote(cache));
  ASSERT_EQ(built.code, 0) << built.out;
  EXPECT_NE(built.out.find("\npages       "), std::string::npos) << built.out;
  std::string bytes = read_all(cache);
  bytes[bytes.size() - 9] = static_cast<char>(bytes[bytes.size() - 9] ^ 0x20);
  std::ofstream(cache, std::ios::binary | std::ios::trunc) << bytes;
  for (const std::string& command :
       {std::string("info "), "render -o " + quote(dir / "frames") + " "}) {
    const auto r = run_treecut(command + quote(cache));
    EXPECT_NE(r.code, 0) << command << r.out;
    EXPECT_EQ(std::count(r.out.begin(), r.out.end(), '\n'), 1) << r.out;
    EXPECT_NE(r.out.find("m.tch"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find(": page "), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("checksum mismatch (corrupted)"), std::string::npos) << r.out;
  }
  EXPECT_FALSE(fs::exists(dir / "frames")) << "nothing drawn";
}

TEST(OutputSafety, BuildRefusesADirectoryOrAFifoAtTheOutput) {
  const fs::path dir = scratch_dir("safety_build_kinds");
  const fs::path model = small_model(dir, "m.ply");
  fs::create_directory(dir / "folder");
  ASSERT_EQ(::mkfifo((dir / "fifo").c_str(), 0644), 0);
  for (const char* force : {"", "-f "}) {
    CommandResult r = run_treecut(
        "build " + std::string(force) + quote(model) + " -o " + quote(dir / "folder"), 30);
    EXPECT_EQ(r.code, 2) << r.out;
    EXPECT_NE(r.out.find((dir / "folder").string() + ": is a directory"), std::string::npos)
        << r.out;
    r = run_treecut("build " + std::string(force) + quote(model) + " -o " + quote(dir / "fifo"),
                    30);
    EXPECT_EQ(r.code, 2) << "a FIFO must never block: " << r.out;
    EXPECT_NE(r.out.find((dir / "fifo").string() + ": is a FIFO"), std::string::npos) << r.out;
  }
  EXPECT_TRUE(fs::is_empty(dir / "folder"));
}

// -- the model and the default cache are not regular files -------------------

TEST(OutputSafety, AFifoOrADirectoryAsTheModelIsNamedAtOnce) {
  const fs::path dir = scratch_dir("safety_model_kinds");
  ASSERT_EQ(::mkfifo((dir / "model.ply").c_str(), 0644), 0);
  fs::create_directory(dir / "folder.ply");
  const ScopedEnv xdg("XDG_CACHE_HOME", (dir / "xdg").string());
  for (const std::string& command :
       std::vector<std::string>{"build ", "build -f ", "info ", kTinyRender}) {
    const std::string out = command == kTinyRender ? " -o " + quote(dir / "r")
                            : command == "info "   ? std::string()
                                                   : " -o " + quote(dir / "c.tch");
    CommandResult r = run_treecut(command + quote(dir / "model.ply") + out, 30);
    EXPECT_EQ(r.code, 2) << command << r.out;
    EXPECT_NE(r.out.find("model.ply: is a FIFO"), std::string::npos) << command << r.out;
    EXPECT_EQ(r.out.find("no such file"), std::string::npos) << r.out;
    r = run_treecut(command + quote(dir / "folder.ply") + out, 30);
    EXPECT_EQ(r.code, 2) << command << r.out;
    EXPECT_NE(r.out.find("folder.ply: is a directory"), std::string::npos) << command << r.out;
  }
  EXPECT_FALSE(fs::exists(dir / "c.tch"));
  EXPECT_FALSE(fs::exists(dir / "r"));
}

TEST(OutputSafety, AFifoOrADirectoryAtTheDefaultCachePath) {
  const fs::path dir = scratch_dir("safety_cache_kinds");
  const fs::path model = small_model(dir, "m.ply");
  const ScopedEnv xdg("XDG_CACHE_HOME", (dir / "xdg").string());
  CommandResult r = run_treecut("build " + quote(model));
  ASSERT_EQ(r.code, 0) << r.out;
  const fs::path cache = printed_cache(r.out);
  ASSERT_EQ(cache.parent_path(), dir / "xdg" / "treecut") << r.out;
  fs::remove(cache);
  ASSERT_EQ(::mkfifo(cache.c_str(), 0644), 0);
  for (int kind = 0; kind < 2; ++kind) {
    const std::string what = kind == 0 ? "is a FIFO" : "is a directory";
    if (kind == 1) {
      fs::remove(cache);
      fs::create_directory(cache);
    }
    for (const char* force : {"", "-f "}) {
      r = run_treecut("build " + std::string(force) + quote(model), 30);
      expect_one_line_failure(r, 1, cache.string() + ": " + what, what + "\n");
    }
    // info goes on without the cache, with one warning.
    r = run_treecut("info " + quote(model), 30);
    EXPECT_EQ(r.code, 0) << what << "\n" << r.out;
    EXPECT_EQ(count_lines_with(r.out, "warning:"), 1u) << r.out;
    EXPECT_NE(r.out.find(cache.string() + ": " + what), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("points      3000"), std::string::npos) << r.out;
  }
}

// -- the cache cannot be written ---------------------------------------------

TEST(OutputSafety, BuildFailsWhenTheCacheCannotBeWrittenAndInfoGoesOn) {
  const fs::path dir = scratch_dir("safety_cache_unwritable");
  const fs::path model = small_model(dir, "m.ply");
  write_text(dir / "a-file", "not a folder\n");
  const ScopedEnv xdg("XDG_CACHE_HOME", (dir / "a-file").string());
  for (const char* force : {"", "-f "}) {
    const CommandResult r = run_treecut("build " + std::string(force) + quote(model));
    expect_one_line_failure(r, 1, (dir / "a-file" / "treecut").string() + ": Not a directory");
    EXPECT_EQ(r.out.find("cache       "), std::string::npos) << "printed as written: " << r.out;
  }
  const CommandResult r = run_treecut("info " + quote(model));
  EXPECT_EQ(r.code, 0) << r.out;
  EXPECT_EQ(count_lines_with(r.out, "warning:"), 1u) << r.out;
  EXPECT_NE(r.out.find("Not a directory"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("cache       none (not written: "), std::string::npos)
      << "a cache that was not written is not printed as the cache: " << r.out;
  EXPECT_EQ(read_all(dir / "a-file"), "not a folder\n");
}

TEST(OutputSafety, BuildFailsOnAReadOnlyFolderAndRenderGoesOn) {
  const fs::path dir = scratch_dir("safety_cache_readonly");
  const fs::path model = small_model(dir, "m.ply");
  std::optional<SmallDisk> disk = SmallDisk::mount("safety_cache_readonly_disk", 1 << 20);
  if (!disk) GTEST_SKIP() << "cannot mount a tmpfs here (not root)";
  // Root ignores permission bits: a read-only mount is read-only for everyone.
  ASSERT_EQ(::mount(nullptr, disk->path().c_str(), nullptr, MS_REMOUNT | MS_RDONLY, nullptr), 0);
  for (const char* force : {"", "-f "}) {
    const CommandResult r = run_treecut("build " + std::string(force) + quote(model) + " -o " +
                                        quote(disk->path() / "m.tch"));
    expect_one_line_failure(r, 1, (disk->path() / "m.tch").string() + ": Read-only file system");
  }
  const ScopedEnv xdg("XDG_CACHE_HOME", disk->path().string());
  const CommandResult r =
      run_treecut(kTinyRender + quote(model) + " --no-png -o " + quote(dir / "out"));
  EXPECT_EQ(r.code, 0) << r.out;
  // One warning of ours about the cache (Mesa says its own about its shader cache).
  EXPECT_EQ(count_lines_with(r.out, "warning: " + disk->path().string()), 1u) << r.out;
  EXPECT_EQ(count_lines_with(r.out, "without a cache"), 1u) << r.out;
  EXPECT_NE(r.out.find("Read-only file system"), std::string::npos) << r.out;
  EXPECT_TRUE(fs::is_regular_file(dir / "out" / "stats.csv"));
}

TEST(OutputSafety, BuildOnAFullDiskFailsAndLeavesNoFile) {
  const fs::path dir = scratch_dir("safety_cache_full");
  const fs::path model = small_model(dir, "m.ply", 20000);
  std::optional<SmallDisk> disk = SmallDisk::mount("safety_cache_full_disk", 256 << 10);
  if (!disk) GTEST_SKIP() << "cannot mount a tmpfs here (not root)";
  for (const char* force : {"", "-f "}) {
    const CommandResult r = run_treecut("build " + std::string(force) + quote(model) + " -o " +
                                        quote(disk->path() / "m.tch"));
    expect_one_line_failure(r, 1, (disk->path() / "m.tch").string() + ": No space left on device");
    EXPECT_TRUE(fs::is_empty(disk->path())) << "a truncated cache or temporary was left";
  }
}

TEST(OutputSafety, ARelativeXdgCacheHomeIsIgnored) {
  const fs::path dir = scratch_dir("safety_xdg_relative");
  const fs::path model = small_model(dir, "m.ply");
  const ScopedEnv home("HOME", (dir / "home").string());
  const ScopedEnv xdg("XDG_CACHE_HOME", "relative-cache");
  const CommandResult r = run_treecut("build " + quote(model));
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_EQ(printed_cache(r.out).parent_path(), dir / "home" / ".cache" / "treecut") << r.out;
  EXPECT_FALSE(fs::exists("relative-cache"));
}

// -- the content decides ------------------------------------------------------

TEST(OutputSafety, AModelEditedInPlaceWithItsMtimeRestoredIsRebuilt) {
  const fs::path dir = scratch_dir("safety_fingerprint");
  const ScopedEnv xdg("XDG_CACHE_HOME", (dir / "xdg").string());
  const fs::path a = small_model(dir, "a.ply", 3000, 1);
  small_model(dir, "b.ply", 3000, 2);  // the same size, other points
  ASSERT_EQ(fs::file_size(a), fs::file_size(dir / "b.ply"));
  CommandResult r = run_treecut("build " + quote(a));
  ASSERT_EQ(r.code, 0) << r.out;
  r = run_treecut("info " + quote(a));
  ASSERT_NE(r.out.find("from cache"), std::string::npos) << r.out;
  const std::string before = r.out.substr(r.out.find("bounds"));
  // Edited in place (the same inode), then the mtime put back with `touch -r`.
  ASSERT_EQ(std::system(("touch -r " + quote(a) + " " + quote(dir / "stamp")).c_str()), 0);
  {
    std::ofstream out(a, std::ios::binary | std::ios::in | std::ios::out);
    out << read_all(dir / "b.ply");
  }
  ASSERT_EQ(std::system(("touch -r " + quote(dir / "stamp") + " " + quote(a)).c_str()), 0);
  ASSERT_EQ(fs::last_write_time(a), fs::last_write_time(dir / "stamp"));
  r = run_treecut("info " + quote(a));
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_EQ(r.out.find("from cache"), std::string::npos) << "served the old content's cache";
  EXPECT_NE(r.out.find("stale"), std::string::npos) << r.out;
  const std::string fresh = run_treecut("info " + quote(dir / "b.ply")).out;
  EXPECT_EQ(r.out.substr(r.out.find("bounds"), 60), fresh.substr(fresh.find("bounds"), 60))
      << "the rebuilt hierarchy is the new content's";
  EXPECT_NE(before.substr(0, 60), fresh.substr(fresh.find("bounds"), 60));
}

// -- gen -o PATH ---------------------------------------------------------------

TEST(OutputSafety, GenReplacesOnlyAPlyAndNeverBlocks) {
  const fs::path dir = scratch_dir("safety_gen");
  fs::create_directory(dir / "folder");
  ASSERT_EQ(::mkfifo((dir / "fifo").c_str(), 0644), 0);
  write_text(dir / "notes.txt", "my notes\n");
  const std::vector<std::pair<fs::path, std::string>> cases = {
      {dir / "folder", ": is a directory"},
      {dir / "fifo", ": is a FIFO"},
      {dir / "notes.txt", ": exists and is not a PLY file"}};
  for (const auto& [out, why] : cases) {
    const CommandResult r = run_treecut("gen sphere -n 100 -o " + quote(out), 30);
    expect_one_line_failure(r, 2, out.string() + why, out.string() + "\n");
  }
  EXPECT_EQ(read_all(dir / "notes.txt"), "my notes\n");
  // A PLY is what gen replaces (regenerating a model).
  const fs::path model = small_model(dir, "m.ply", 100);
  const CommandResult r = run_treecut("gen sphere -n 200 -o " + quote(model));
  EXPECT_EQ(r.code, 0) << r.out;
  EXPECT_NE(read_all(model).find("element vertex 200\n"), std::string::npos);
}

TEST(OutputSafety, GenOnAFullDiskFailsAndKeepsTheOldModel) {
  std::optional<SmallDisk> disk = SmallDisk::mount("safety_gen_full", 256 << 10);
  if (!disk) GTEST_SKIP() << "cannot mount a tmpfs here (not root)";
  const fs::path model = small_model(disk->path(), "m.ply", 1000);
  const std::string bytes = read_all(model);
  CommandResult r = run_treecut("gen terrain -n 100000 -o " + quote(model));
  expect_one_line_failure(r, 1, model.string() + ": No space left on device");
  EXPECT_EQ(read_all(model), bytes) << "the old model was replaced by a partial one";
  EXPECT_EQ(files_under(disk->path()).size(), 1u) << "a temporary was left behind";
  r = run_treecut("gen terrain -n 100000 -o " + quote(disk->path() / "new.ply"));
  EXPECT_EQ(r.code, 1) << r.out;
  EXPECT_FALSE(fs::exists(disk->path() / "new.ply")) << "a truncated model looks complete";
}

// -- render --out DIR ------------------------------------------------------------

TEST(OutputSafety, RenderRefusesAFolderOfTheUsersAndReusesItsOwn) {
  const fs::path dir = scratch_dir("safety_render_folder");
  fs::create_directory(dir / "mine");
  write_text(dir / "mine" / "notes.txt", "my notes\n");
  write_text(dir / "mine" / "stats.csv", "my own table\n");
  CommandResult r = run_treecut(kTinyRender + "-o " + quote(dir / "mine"));
  expect_one_line_failure(r, 2, (dir / "mine").string() + ": folder is not empty");
  EXPECT_EQ(files_under(dir / "mine").size(), 2u) << "wrote into the user's folder";
  EXPECT_EQ(read_all(dir / "mine" / "stats.csv"), "my own table\n");

  write_text(dir / "a-file", "x\n");
  r = run_treecut(kTinyRender + "-o " + quote(dir / "a-file"));
  EXPECT_EQ(r.code, 2) << r.out;
  EXPECT_NE(r.out.find("a-file: is a regular file, not a folder"), std::string::npos) << r.out;

  // An empty folder, then the same folder again: it is an earlier output.
  fs::create_directory(dir / "out");
  r = run_treecut(kTinyRender + "-o " + quote(dir / "out"));
  ASSERT_EQ(r.code, 0) << r.out;
  r = run_treecut(kTinyRender + "-o " + quote(dir / "out"));
  EXPECT_EQ(r.code, 0) << "an earlier render output is reused: " << r.out;
  for (const fs::path& f : files_under(dir / "out")) {
    const std::string name = f.filename().string();
    EXPECT_TRUE(name.rfind("frame_", 0) == 0 || name == "stats.csv" || name == "summary.json" ||
                name == "plot.svg" || name == ".treecut-render")
        << "not render output: " << f;
  }
}

TEST(OutputSafety, RenderOfTheSameStrategyTwiceIsRefused) {
  const fs::path dir = scratch_dir("safety_render_twice");
  const CommandResult r = run_treecut(kTinyRender + "-s bucket -s bucket -o " + quote(dir / "out"));
  expect_one_line_failure(r, 2, "bucket given twice");
  EXPECT_FALSE(fs::exists(dir / "out"));
}

TEST(OutputSafety, RenderOnAFullDiskFailsNamingTheFileAndLeavesNoTruncatedFile) {
  std::optional<SmallDisk> disk = SmallDisk::mount("safety_render_full", 256 << 10);
  if (!disk) GTEST_SKIP() << "cannot mount a tmpfs here (not root)";
  // Frames of noise-like content do not compress: a few fill 256 KiB.
  const CommandResult r = run_treecut(
      "render --width 320 --height 240 --frames 40 --warmup 0 --sync --default-points 20000 -o " +
      quote(disk->path() / "out"));
  EXPECT_EQ(r.code, 1) << r.out;
  ASSERT_EQ(count_lines_with(r.out, "error:"), 1u) << r.out;
  std::string last;
  for (const std::string& line : lines_of(r.out))
    if (line.find("error:") != std::string::npos) last = line;
  EXPECT_NE(last.find(disk->path().string()), std::string::npos) << "names the file: " << last;
  EXPECT_NE(last.find("No space left on device"), std::string::npos) << last;
  EXPECT_EQ(r.out.find("wrote "), std::string::npos) << r.out;
  for (const fs::path& f : files_under(disk->path())) {
    const std::string name = f.filename().string();
    EXPECT_EQ(name.find(".tmp-"), std::string::npos) << "temporary left: " << f;
    if (f.extension() == ".png") {
      const std::string png = read_all(f);
      ASSERT_GE(png.size(), 12u) << f;
      EXPECT_EQ(png.substr(png.size() - 8, 4), "IEND") << "a truncated PNG: " << f;
    }
  }
}

TEST(OutputSafety, PsnrOfIdenticalImagesIsInfinite) {
  const fs::path dir = scratch_dir("safety_psnr_inf");
  // Recursion without a size or back-face stop: the cut is the leaves in view,
  // so the LOD frame is the full-detail frame.
  const CommandResult r = run_treecut(
      "render --width 48 --height 32 --frames 2 --warmup 200 --sync --default-points 500 "
      "-s recursive -p min_size=0 -p backface=0 --psnr --no-png -o " +
      quote(dir / "out"));
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_EQ(r.out.find("nan"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("PSNR inf dB"), std::string::npos) << r.out;
  const std::string csv = read_all(dir / "out" / "stats.csv");
  EXPECT_EQ(count_lines_with(csv, ",inf"), 2u) << csv;
  const std::string summary = read_all(dir / "out" / "summary.json");
  EXPECT_NE(summary.find("\"mean_psnr_db\": \"inf\""), std::string::npos) << summary;
  EXPECT_NE(summary.find("\"psnr_identical_frames\": 2"), std::string::npos) << summary;
}

// -- viewer screenshots ------------------------------------------------------------

namespace {

// `treecut view --script SCRIPT --screenshot-dir DIR` under Xvfb (nullopt
// without xvfb-run), from the script's folder.
std::optional<CommandResult> run_view_script(const fs::path& script, const fs::path& dir) {
  return treecut::test::run_treecut_in_xvfb(
      "view --default-points 2000 --width 160 --height 120 "
      "--script " +
          quote(script) + " --screenshot-dir " + quote(dir),
      script.parent_path(), "640x480x24");
}

}  // namespace

TEST(OutputSafety, ViewerScreenshotsNeverReplaceAnyFile) {
  const fs::path dir = scratch_dir("safety_screenshot_names");
  write_text(dir / "run.script",
             "treecut-view-script 1\nframes 2\nscreenshot shot.png\nframes 1\n"
             "screenshot shot.png\nscreenshot new.png\nscreenshot b.png\nscreenshot b.png\n"
             "screenshot b.png\nscreenshot b.png\nexit\n");
  fs::create_directory(dir / "shots");
  write_text(dir / "shots" / "shot.png", "the user's picture\n");
  const auto r = run_view_script(dir / "run.script", dir / "shots");
  if (!r) GTEST_SKIP() << "xvfb-run is not installed";
  ASSERT_EQ(r->code, 0) << r->out;
  EXPECT_EQ(read_all(dir / "shots" / "shot.png"), "the user's picture\n");
  // Every shot is a file of its own, even one of the same name a moment
  // ago: the name is taken as the file is committed.
  for (const char* name :
       {"shot-1.png", "shot-2.png", "new.png", "b.png", "b-1.png", "b-2.png", "b-3.png"}) {
    EXPECT_EQ(read_all(dir / "shots" / name).substr(1, 3), "PNG") << name;
    EXPECT_NE(r->out.find("screenshot " + (dir / "shots" / name).string()), std::string::npos)
        << r->out;
  }
  EXPECT_EQ(files_under(dir / "shots").size(), 8u);
}

// Issue 30: camera bookmarks are kept beside the model in MODEL.views (a
// camera path, the slots its key times); a MODEL.views of the user's is
// never replaced (the script's run ends, exit 1, naming it).
TEST(OutputSafety, ViewerBookmarksLiveBesideTheModelAndReplaceNoUserFile) {
  const fs::path dir = scratch_dir("safety_bookmarks");
  ASSERT_EQ(treecut::test::run_treecut("gen sphere -n 2000 -o " + quote(dir / "m.ply")).code, 0);
  write_text(dir / "run.script",
             "treecut-view-script 1\nframes 2\nbookmark save 2\norbit 90\nbookmark save 5\n"
             "bookmark 2\nframes 1\nexit\n");
  const auto view = [&] {
    return treecut::test::run_treecut_in_xvfb("view m.ply --width 160 --height 120 --script " +
                                                  quote(dir / "run.script") + " --screenshot-dir " +
                                                  quote(dir),
                                              dir, "640x480x24");
  };
  auto r = view();
  if (!r) GTEST_SKIP() << "xvfb-run is not installed";
  ASSERT_EQ(r->code, 0) << r->out;
  const std::string views = read_all(dir / "m.ply.views");
  EXPECT_EQ(views.rfind("treecut-camera-path 1", 0), 0u) << views;
  const treecut::splat::CameraPath path = treecut::splat::load_camera_path(dir / "m.ply.views");
  ASSERT_EQ(path.keys.size(), 2u);
  EXPECT_EQ(path.keys[0].time, 2.0);
  EXPECT_EQ(path.keys[1].time, 5.0);
  EXPECT_GT(glm::distance(path.keys[0].camera.eye, path.keys[1].camera.eye), 0.01f)
      << "the orbit moved the camera between the two";
  // The user's own m.ply.views stays.
  write_text(dir / "m.ply.views", "my notes about m.ply\n");
  r = view();
  ASSERT_TRUE(r);
  EXPECT_EQ(r->code, 1) << r->out;
  EXPECT_NE(r->out.find("m.ply.views: exists and is not treecut's list of views; not replaced"),
            std::string::npos)
      << r->out;
  EXPECT_EQ(read_all(dir / "m.ply.views"), "my notes about m.ply\n");
}

TEST(OutputSafety, AViewerScreenshotOnAFullDiskEndsTheScriptNamingTheFile) {
  std::optional<SmallDisk> disk = SmallDisk::mount("safety_screenshot_full", 16 << 10);
  if (!disk) GTEST_SKIP() << "cannot mount a tmpfs here (not root)";
  const fs::path dir = scratch_dir("safety_screenshot_full_script");
  write_text(dir / "run.script", "treecut-view-script 1\nframes 2\nscreenshot big.png\nexit\n");
  // Fill the disk to the last byte (the write past it fails): no PNG fits.
  std::ofstream(disk->path() / "filler", std::ios::binary) << std::string(64 << 10, 'x');
  const auto r = run_view_script(dir / "run.script", disk->path());
  if (!r) GTEST_SKIP() << "xvfb-run is not installed";
  EXPECT_EQ(r->code, 1) << r->out;
  EXPECT_EQ(count_lines_with(r->out, "treecut: error:"), 1u) << r->out;
  EXPECT_NE(r->out.find((disk->path() / "big.png").string() + ": No space left on device"),
            std::string::npos)
      << r->out;
  EXPECT_EQ(files_under(disk->path()).size(), 1u) << "a partial screenshot was left";
}
