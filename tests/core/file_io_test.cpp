// Inputs that are not regular files are refused without blocking; text inputs
// have a size limit; outputs are atomic and a full disk leaves no trace.
#include "treecut/file_io.hpp"

#include <gtest/gtest.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <unistd.h>

#include <cstring>
#include <fstream>

#include "test_support.hpp"
#include "treecut/error.hpp"

namespace fs = std::filesystem;
using treecut::AtomicFile;
using treecut::InputError;

namespace {

std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), {}};
}

std::string input_error(auto&& f) {
  try {
    f();
  } catch (const InputError& e) {
    return e.what();
  }
  return "(no InputError)";
}

std::string runtime_error(auto&& f) {
  try {
    f();
  } catch (const std::runtime_error& e) {
    return e.what();
  }
  return "(no error)";
}

std::size_t entries(const fs::path& dir) {
  return static_cast<std::size_t>(std::distance(fs::directory_iterator(dir), {}));
}

}  // namespace

TEST(FileIo, InputsThatAreNotRegularFilesAreNamedNotOpened) {
  const fs::path dir = treecut::test::scratch_dir("file_io_kinds");
  const fs::path fifo = dir / "pipe";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  // A FIFO with no writer: open() without O_NONBLOCK would never return.
  EXPECT_NE(input_error([&] { treecut::read_text_file(fifo); }).find("pipe: is a FIFO"),
            std::string::npos);
  EXPECT_NE(input_error([&] { treecut::require_regular_file(fifo); }).find("is a FIFO"),
            std::string::npos);
  EXPECT_NE(input_error([&] { treecut::read_text_file(dir); }).find("is a directory"),
            std::string::npos);
  EXPECT_NE(input_error([&] { treecut::read_text_file("/dev/zero"); }).find("character device"),
            std::string::npos);
  EXPECT_NE(input_error([&] { treecut::read_text_file(dir / "absent"); }).find("no such file"),
            std::string::npos);

  const fs::path sock = dir / "sock";
  const int s = ::socket(AF_UNIX, SOCK_STREAM, 0);
  ASSERT_GE(s, 0);
  sockaddr_un addr{};
  addr.sun_family = AF_UNIX;
  ASSERT_LT(sock.string().size(), sizeof addr.sun_path);
  std::strcpy(addr.sun_path, sock.c_str());
  ASSERT_EQ(::bind(s, reinterpret_cast<const sockaddr*>(&addr), sizeof addr), 0);
  EXPECT_NE(input_error([&] { treecut::open_regular_file(sock); }).find("is a socket"),
            std::string::npos);
  ::close(s);
}

TEST(FileIo, TextInputsHaveALimit) {
  const fs::path dir = treecut::test::scratch_dir("file_io_limit");
  treecut::write_file_atomically(dir / "t", std::string(1000, 'x'));
  EXPECT_EQ(treecut::read_text_file(dir / "t", 1000).size(), 1000u);
  EXPECT_NE(input_error([&] { treecut::read_text_file(dir / "t", 999); }).find("larger than 999"),
            std::string::npos);
}

TEST(FileIo, SameFileSeesLinks) {
  const fs::path dir = treecut::test::scratch_dir("file_io_same");
  treecut::write_file_atomically(dir / "a", "a");
  fs::create_hard_link(dir / "a", dir / "hard");
  fs::create_symlink(dir / "a", dir / "soft");
  treecut::write_file_atomically(dir / "b", "a");
  EXPECT_TRUE(treecut::same_file(dir / "a", dir / "hard"));
  EXPECT_TRUE(treecut::same_file(dir / "soft", dir / "a"));
  EXPECT_TRUE(treecut::same_file(dir / "." / "a", dir / "a"));
  EXPECT_FALSE(treecut::same_file(dir / "a", dir / "b"));
  EXPECT_FALSE(treecut::same_file(dir / "a", dir / "absent"));
}

TEST(FileIo, AtomicFileReplacesOnlyOnCommit) {
  const fs::path dir = treecut::test::scratch_dir("file_io_atomic");
  const fs::path target = dir / "out.txt";
  treecut::write_file_atomically(target, "old");
  {
    AtomicFile f(target);
    f.write("new content");
    EXPECT_EQ(slurp(target), "old") << "visible only after commit";
    EXPECT_TRUE(fs::exists(f.temporary()));
  }
  EXPECT_EQ(slurp(target), "old") << "an abandoned write changes nothing";
  EXPECT_EQ(entries(dir), 1u) << "and leaves no temporary";
  {
    AtomicFile f(target);
    f.write(std::string(3u << 20, 'z'));  // several buffered chunks
    f.commit();
  }
  EXPECT_EQ(slurp(target).size(), 3u << 20);
  EXPECT_EQ(entries(dir), 1u);
  // A directory or FIFO at the target is never replaced.
  fs::create_directory(dir / "sub");
  EXPECT_NE(runtime_error([&] { AtomicFile f(dir / "sub"); }).find("is a directory"),
            std::string::npos);
  ASSERT_EQ(::mkfifo((dir / "fifo").c_str(), 0600), 0);
  EXPECT_NE(runtime_error([&] { AtomicFile f(dir / "fifo"); }).find("is a FIFO"),
            std::string::npos);
}

TEST(FileIo, FullDiskFailsNamingTheFileAndKeepsTheOldOne) {
  auto disk = treecut::test::SmallDisk::mount("file_io_full", 64 * 1024);
  if (!disk) GTEST_SKIP() << "cannot mount a tmpfs here (needs root)";
  const fs::path target = disk->path() / "big.bin";
  treecut::write_file_atomically(target, "previous");
  const std::string why =
      runtime_error([&] { treecut::write_file_atomically(target, std::string(1u << 20, 'x')); });
  EXPECT_NE(why.find("big.bin: No space left on device"), std::string::npos) << why;
  EXPECT_EQ(slurp(target), "previous");
  EXPECT_EQ(entries(disk->path()), 1u) << "no temporary left behind";
}

TEST(FileIo, ReadOnlyFolderFailsAtCreation) {
  if (::geteuid() == 0) {
    // root writes anywhere; a read-only mount shows the same path.
    auto disk = treecut::test::SmallDisk::mount("file_io_ro", 64 * 1024);
    if (!disk) GTEST_SKIP() << "cannot mount a tmpfs here";
    ASSERT_EQ(::system(("mount -o remount,ro " + treecut::test::quote(disk->path())).c_str()), 0);
    const std::string why =
        runtime_error([&] { treecut::write_file_atomically(disk->path() / "x", "x"); });
    EXPECT_NE(why.find("x: Read-only file system"), std::string::npos) << why;
    return;
  }
  const fs::path dir = treecut::test::scratch_dir("file_io_ro");
  fs::permissions(dir, fs::perms::owner_read | fs::perms::owner_exec);
  const std::string why = runtime_error([&] { treecut::write_file_atomically(dir / "x", "x"); });
  fs::permissions(dir, fs::perms::owner_all);
  EXPECT_NE(why.find("x: Permission denied"), std::string::npos) << why;
}
