// Files that change under us, and signals: a model or cache that shrinks
// while it is mapped or read, a temporary that a signal or a kill must not
// leave behind. Each file is shrunk or replaced by another thread at a point
// the test controls (after it is mapped, before it is read), so every case is
// deterministic; the ones that end the process run as death tests. Named
// *_threaded_test: the TSan stage runs it too, with the handlers' jumps and
// the other thread's truncation.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <csignal>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <random>
#include <string>
#include <thread>

#include "hierarchy/cache_format.hpp"
#include "test_support.hpp"
#include "treecut/cache.hpp"
#include "treecut/error.hpp"
#include "treecut/file_io.hpp"
#include "treecut/mapped_file.hpp"
#include "treecut/model_io.hpp"
#include "treecut/ply.hpp"
#include "treecut/tools/generate.hpp"

namespace treecut {
namespace {

namespace fs = std::filesystem;
using test::read_all;

void write_bytes(const fs::path& p, std::size_t size, char fill = 'x') {
  std::ofstream(p, std::ios::binary) << std::string(size, fill);
}

// Truncates PATH to SIZE bytes on another thread and waits for it: the
// shrink happens exactly between the mapping and the read that follows.
void shrink_from_another_thread(const fs::path& path, off_t size) {
  std::thread([&] { ASSERT_EQ(::truncate(path.c_str(), size), 0); }).join();
}

int open_read(const fs::path& p) {
  const int fd = ::open(p.c_str(), O_RDONLY | O_CLOEXEC);
  EXPECT_GE(fd, 0) << p;
  return fd;
}

fs::path small_model(const fs::path& dir, const std::string& name, std::size_t points = 20000) {
  const fs::path p = dir / name;
  save_ply(p, tools::generate_model(tools::ModelKind::Sphere, points, 1));
  return p;
}

// DIR/m.tch, the cache of a small model DIR/m.ply.
fs::path built_cache(const fs::path& dir) {
  const fs::path cache = dir / "m.tch";
  OpenOptions options;
  options.cache_path = cache;
  (void)open_model(small_model(dir, "m.ply"), options);
  EXPECT_TRUE(fs::exists(cache));
  return cache;
}

std::size_t temporaries_in(const fs::path& dir) {
  std::size_t n = 0;
  for (const auto& e : fs::directory_iterator(dir))
    n += e.path().filename().string().find(".tmp-") != std::string::npos;
  return n;
}

// -- a mapping that shrinks ------------------------------------------------------

TEST(MappedFile, AReadOfAFileThatShrankUnderItFailsNamingTheFile) {
  const fs::path dir = test::scratch_dir("changes_mapped_read");
  const fs::path file = dir / "model.ply";
  write_bytes(file, 1 << 20);
  const int fd = open_read(file);
  const MappedFile map(fd, 1 << 20, file);
  ::close(fd);
  shrink_from_another_thread(file, 1000);
  std::uint64_t sum = 0;
  try {
    map.read_guarded([&] {
      for (std::size_t i = 0; i < map.size(); i += 4096) sum += map.data()[i];
    });
    ADD_FAILURE() << "read past the new end without an error";
  } catch (const FileChangedError& e) {
    EXPECT_EQ(std::string(e.what()),
              file.string() +
                  ": changed while being read (truncated or rewritten by another "
                  "program)");
  }
  // The bytes still inside the file read as before, and the guard is gone
  // after the throw: the next guarded read of them works.
  map.read_guarded([&] { sum = map.data()[0]; });
  EXPECT_EQ(sum, static_cast<std::uint64_t>('x'));
}

TEST(MappedFile, TheContentHashOfAShortenedFileIsAnErrorNotASignal) {
  const fs::path dir = test::scratch_dir("changes_hash");
  const fs::path file = dir / "model.ply";
  write_bytes(file, 1 << 20);
  const int fd = open_read(file);
  // The size an fstat saw before another program shrank the file.
  shrink_from_another_thread(file, 4096);
  EXPECT_THROW((void)detail::hash_descriptor(file, fd, 1 << 20), FileChangedError);
  EXPECT_EQ(detail::hash_descriptor(file, fd, 4096), content_hash_of(file));
  ::close(fd);
}

// A mapping read outside read_guarded that shrinks ends the process with
// exit code 1 and one line naming the file, and removes the temporaries of
// the outputs in progress first (what any unguarded reader of a mapping
// gets; caches are no longer mapped, below).
TEST(MappedFileDeathTest, AShrunkMappingEndsTheProcessWithOneLineAndNoTemporaries) {
  GTEST_FLAG_SET(death_test_style, "threadsafe");
  const fs::path dir = test::scratch_dir("changes_mapping_death");
  const fs::path file = dir / "m.bin";
  write_bytes(file, 1 << 20);
  EXPECT_EXIT(
      {
        const int fd = open_read(file);
        const MappedFile map(fd, 1 << 20, file);
        ::close(fd);
        AtomicFile output(dir / "frame.png");  // an output in progress
        output.write("half a frame");
        shrink_from_another_thread(file, 4096);
        volatile unsigned sum = 0;
        for (std::size_t i = 0; i < map.size(); i += 4096) sum = sum + map.data()[i];
        std::fprintf(stderr, "read %u without a signal\n", static_cast<unsigned>(sum));
      },
      ::testing::ExitedWithCode(1),
      "^treecut: error: " + file.string() +
          ": changed while being read \\(truncated or rewritten by another program\\)\n$");
  EXPECT_EQ(temporaries_in(dir), 0u) << "the output's temporary was left";
}

// Issue 43, item 8: a cache rewritten in place (`dd conv=notrunc`, same
// size) or truncated while a renderer draws from it changes nothing the
// loaded hierarchy holds: the bytes were read into the process and
// verified once, so the links every strategy indexes with stay the ones
// checked (a mapping showed the new bytes, and the strategies crashed).
TEST(CacheChanges, ACacheRewrittenInPlaceAfterItsLoadChangesNothingLoaded) {
  const fs::path dir = test::scratch_dir("changes_cache_rewritten");
  const fs::path cache = built_cache(dir);
  std::string why;
  const std::optional<Hierarchy> h = load_cache(cache, std::nullopt, &why);
  ASSERT_TRUE(h) << why;
  const HierarchyArrays& a = h->arrays();
  const std::vector<NodeId> first_child(a.first_child.begin(), a.first_child.end());
  const std::vector<NodeId> parent(a.parent.begin(), a.parent.end());
  const std::vector<glm::vec4> bounds(a.center_radius.begin(), a.center_radius.end());
  const auto size = fs::file_size(cache);
  std::thread([&] {
    // 8 blocks of 64 KiB of random bytes over the file, as dd conv=notrunc.
    std::FILE* f = std::fopen(cache.c_str(), "r+b");
    ASSERT_NE(f, nullptr);
    std::mt19937 rng(43);
    std::string noise(std::size_t{1} << 16, '\0');
    for (int block = 0; block < 8; ++block) {
      for (char& c : noise) c = static_cast<char>(rng());
      std::fseek(f, static_cast<long>((size / 8) * static_cast<unsigned>(block)), SEEK_SET);
      std::fwrite(noise.data(), 1, std::min<std::size_t>(noise.size(), size / 8), f);
    }
    std::fclose(f);
  }).join();
  EXPECT_EQ(fs::file_size(cache), size);
  EXPECT_TRUE(std::equal(first_child.begin(), first_child.end(), a.first_child.begin()));
  EXPECT_TRUE(std::equal(parent.begin(), parent.end(), a.parent.begin()));
  EXPECT_EQ(std::memcmp(bounds.data(), a.center_radius.data(), bounds.size() * sizeof(glm::vec4)),
            0);
  EXPECT_EQ(check_invariants(*h), "");
  // Truncated too: still nothing moves, and no signal.
  shrink_from_another_thread(cache, 64);
  EXPECT_TRUE(std::equal(parent.begin(), parent.end(), a.parent.begin()));
  // The rewritten file itself is refused at the next load, naming why.
  EXPECT_FALSE(load_cache(cache, std::nullopt, &why));
  EXPECT_FALSE(why.empty());
}

// A cache that shrinks while it is verified (the checksum reads all of it)
// is a FileChangedError from the loader, which the viewer survives.
TEST(MappedFile, ACacheThatShrinksWhileVerifiedIsAFileChangedError) {
  const fs::path dir = test::scratch_dir("changes_cache_verify");
  const fs::path cache = built_cache(dir);
  // Shrunk after its header was read (the size is taken from fstat when it
  // is mapped): the race of `truncate` with a load, at a fixed point.
  const int fd = open_read(cache);
  struct stat st {};
  ASSERT_EQ(::fstat(fd, &st), 0);
  const MappedFile map(fd, static_cast<std::uint64_t>(st.st_size), cache);
  ::close(fd);
  shrink_from_another_thread(cache, 64);
  EXPECT_THROW(map.read_guarded([&] {
    volatile unsigned char last = map.data()[map.size() - 1];
    (void)last;
  }),
               FileChangedError);
}

// -- a model that changes while it is read ---------------------------------------

// The stage callback runs on the loading thread between the content hash
// (the cache key) and the read: the other thread replaces or truncates the
// model there, as `cp new.ply model.ply` or `truncate` do during a load.
TEST(ModelChanges, AModelReplacedDuringTheLoadIsAnErrorNotAMixedCache) {
  const fs::path dir = test::scratch_dir("changes_model_replaced");
  const fs::path model = small_model(dir, "m.ply");
  const fs::path other = small_model(dir, "other.ply", 30000);
  for (const bool truncate : {false, true}) {
    OpenOptions options;
    options.cache_path = dir / "m.tch";
    options.progress = [&](std::string_view stage, std::size_t, std::size_t) {
      if (stage != "read") return;
      std::thread([&] {
        if (truncate)
          ASSERT_EQ(::truncate(model.c_str(), 100), 0);
        else
          fs::copy_file(other, model, fs::copy_options::overwrite_existing);
      }).join();
    };
    try {
      (void)open_model(model, options);
      ADD_FAILURE() << "loaded a model that changed while it was read";
    } catch (const FileChangedError& e) {
      EXPECT_EQ(std::string(e.what()).rfind(model.string() + ": changed while being read", 0), 0u)
          << e.what();
    }
    EXPECT_FALSE(fs::exists(dir / "m.tch")) << "a cache of one content under another's key";
    EXPECT_EQ(temporaries_in(dir), 0u);
    save_ply(model, tools::generate_model(tools::ModelKind::Sphere, 20000, 1));
  }
}

// -- signals and killed writers ------------------------------------------------

// SIGINT, SIGTERM, SIGHUP and SIGQUIT remove the temporary of an output in
// progress, then end the process as the signal does (the shell still sees
// "killed by SIGTERM"). The output itself is never created.
TEST(AtomicFileDeathTest, ATerminationSignalRemovesTheTemporary) {
  GTEST_FLAG_SET(death_test_style, "threadsafe");
  const fs::path dir = test::scratch_dir("changes_signal_temporary");
  for (const int sig : {SIGINT, SIGTERM, SIGHUP, SIGQUIT}) {
    EXPECT_EXIT(
        {
          AtomicFile output(dir / "big.tch");
          output.write(std::string(1 << 20, 'x'));
          std::raise(sig);
          std::fprintf(stderr, "survived signal %d\n", sig);
        },
        ::testing::KilledBySignal(sig), "");
    EXPECT_EQ(temporaries_in(dir), 0u) << "signal " << sig;
    EXPECT_FALSE(fs::exists(dir / "big.tch"));
  }
}

// A program that handles or ignores a signal itself keeps its choice: the
// guard is not installed over it, and the temporary stays until the
// program's own unwinding removes it.
TEST(AtomicFile, ASignalTheProgramIgnoresLeavesTheWriteAlone) {
  const fs::path dir = test::scratch_dir("changes_signal_ignored");
  const pid_t child = ::fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    std::signal(SIGHUP, SIG_IGN);
    AtomicFile output(dir / "kept.ply");
    output.write("ply\n");
    std::raise(SIGHUP);  // ignored: the write goes on
    output.commit();
    ::_exit(0);
  }
  int status = 0;
  ASSERT_EQ(::waitpid(child, &status, 0), child);
  ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << status;
  EXPECT_EQ(read_all(dir / "kept.ply"), "ply\n");
}

// A child made by fork() (bench build measures in one, plugins are tried in
// one) inherits the table of temporaries, not the writes: a signal that ends
// the child leaves the parent's output in progress alone.
TEST(AtomicFile, ASignalToAForkedChildLeavesTheParentsTemporary) {
  const fs::path dir = test::scratch_dir("changes_signal_child");
  AtomicFile output(dir / "parent.ply");
  output.write("ply\n");
  const pid_t child = ::fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    std::raise(SIGTERM);
    ::_exit(0);
  }
  int status = 0;
  ASSERT_EQ(::waitpid(child, &status, 0), child);
  EXPECT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == SIGTERM) << status;
  output.commit();
  EXPECT_EQ(read_all(dir / "parent.ply"), "ply\n");
}

// A process-directed signal goes to any thread that does not block it: one
// that lands on another thread while a temporary is being created (opened,
// not yet in the handler's table) must still not leave it behind. Threads
// create and remove temporaries without pause while SIGTERM comes at a
// different moment each round.
TEST(AtomicFile, ASignalOnAnotherThreadWhileATemporaryIsMadeLeavesNone) {
  const fs::path dir = test::scratch_dir("changes_signal_race");
  std::mt19937 random(7);
  for (int round = 0; round < 60; ++round) {
    int ready[2];
    ASSERT_EQ(::pipe(ready), 0);
    const pid_t child = ::fork();
    ASSERT_GE(child, 0);
    if (child == 0) {
      const auto churn = [&](int thread) {
        for (unsigned i = 0;; ++i) {
          AtomicFile output(dir / ("out" + std::to_string(thread) + "-" + std::to_string(i % 4)));
          if (i == 0 && thread == 0) (void)!::write(ready[1], "r", 1);
        }
      };
      std::thread other(churn, 1);
      std::thread idle([] {
        for (;;) ::pause();
      });
      churn(0);
    }
    ::close(ready[1]);
    char byte = 0;
    ASSERT_EQ(::read(ready[0], &byte, 1), 1);
    ::close(ready[0]);
    std::this_thread::sleep_for(std::chrono::microseconds(random() % 3000));
    ::kill(child, SIGTERM);
    int status = 0;
    ASSERT_EQ(::waitpid(child, &status, 0), child);
    ASSERT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == SIGTERM) << status;
    ASSERT_EQ(temporaries_in(dir), 0u) << "round " << round;
  }
}

// A PID that no longer runs: a child that has exited and been reaped.
pid_t dead_pid() {
  const pid_t child = ::fork();
  if (child == 0) ::_exit(0);
  int status = 0;
  ::waitpid(child, &status, 0);
  return child;
}

// kill -9 (or a power cut) leaves TARGET.tmp-PID-N behind; the next write of
// TARGET removes it. Only that: another program's live temporary, a
// user's file that merely looks like one, and other targets' stay.
TEST(AtomicFile, TheNextWriteRemovesTheTemporariesOfDeadWriters) {
  const fs::path dir = test::scratch_dir("changes_stale_temporaries");
  const std::string dead = std::to_string(dead_pid());
  const fs::path stale = dir / ("m.ply.tmp-" + dead + "-0");
  const fs::path stale2 = dir / ("m.ply.tmp-" + dead + "-17");
  const fs::path alive = dir / "m.ply.tmp-1-0";  // PID 1 always runs
  const fs::path users = dir / "m.ply.tmp-notes";
  const fs::path other = dir / ("n.ply.tmp-" + dead + "-0");
  for (const fs::path& p : {stale, stale2, alive, users, other}) write_bytes(p, 100);
  write_file_atomically(dir / "m.ply", "ply\n");
  EXPECT_FALSE(fs::exists(stale));
  EXPECT_FALSE(fs::exists(stale2));
  EXPECT_TRUE(fs::exists(alive));
  EXPECT_TRUE(fs::exists(users));
  EXPECT_TRUE(fs::exists(other)) << "another target's temporary is its own write's to remove";
  EXPECT_EQ(read_all(dir / "m.ply"), "ply\n");
}

// The cache folder is treecut's own: a killed build's temporary there goes
// whichever model it was for.
TEST(AtomicFile, StaleCacheTemporariesOfAnyModelAreRemovedFromTheCacheFolder) {
  const fs::path dir = test::scratch_dir("changes_stale_cache_folder");
  const std::string dead = std::to_string(dead_pid());
  write_bytes(dir / ("a.ply-0123.tch.tmp-" + dead + "-3"), 1000);
  write_bytes(dir / ("b.ply-4567.tch.tmp-" + dead + "-0"), 1000);
  write_bytes(dir / "a.ply-0123.tch.tmp-1-0", 10);          // a live writer's
  write_bytes(dir / ("notes.txt.tmp-" + dead + "-0"), 10);  // not a cache's
  EXPECT_EQ(remove_stale_temporaries(dir, ".tch"), 2u);
  EXPECT_EQ(temporaries_in(dir), 2u);
  EXPECT_TRUE(fs::exists(dir / "a.ply-0123.tch.tmp-1-0"));
}

// -- outputs that must not collide ---------------------------------------------

TEST(AtomicFile, CommitNewNeverReplacesAndFreeNamesCount) {
  const fs::path dir = test::scratch_dir("changes_free_names");
  write_bytes(dir / "b.png", 10, 'u');
  EXPECT_EQ(write_file_to_free_name(dir / "b.png", "one"), dir / "b-1.png");
  EXPECT_EQ(write_file_to_free_name(dir / "b.png", "two"), dir / "b-2.png");
  EXPECT_EQ(read_all(dir / "b.png"), std::string(10, 'u'));
  EXPECT_EQ(read_all(dir / "b-1.png"), "one");
  EXPECT_EQ(read_all(dir / "b-2.png"), "two");
  EXPECT_EQ(temporaries_in(dir), 0u);
}

TEST(FileNames, SameDestinationResolvesPathsThatDoNotExistYet) {
  const fs::path dir = test::scratch_dir("changes_same_destination");
  fs::create_directory(dir / "d");
  EXPECT_TRUE(same_destination(dir / "n.ply", dir / "d" / ".." / "n.ply"));
  EXPECT_TRUE(same_destination(dir / "n.ply", dir / "." / "n.ply"));
  fs::create_directory_symlink(dir / "d", dir / "link");
  EXPECT_TRUE(same_destination(dir / "d" / "x", dir / "link" / "x"));
  EXPECT_FALSE(same_destination(dir / "n.ply", dir / "n.campath"));
  write_bytes(dir / "a", 1);
  fs::create_hard_link(dir / "a", dir / "b");
  EXPECT_TRUE(same_destination(dir / "a", dir / "b"));
}

TEST(FileNames, NamesInMessagesAreQuotedWithControlCharactersEscaped) {
  EXPECT_EQ(quoted_name(fs::path("model.ply")), "model.ply");
  EXPECT_EQ(quoted_name(fs::path("dir/a-b_c+1,2@x%y=z~.ply")), "dir/a-b_c+1,2@x%y=z~.ply");
  EXPECT_EQ(quoted_name(fs::path("löwe.ply")), "löwe.ply");
  EXPECT_EQ(quoted_name(fs::path("my model.ply")), "'my model.ply'");
  EXPECT_EQ(quoted_name(fs::path("a\nb.ply")), "'a\\nb.ply'");
  EXPECT_EQ(quoted_name(fs::path("\x1b]0;owned\x07\x1b[2J.ply")),
            "'\\x1b]0;owned\\x07\\x1b[2J.ply'");
  EXPECT_EQ(quoted_name(fs::path("it's.ply")), "'it\\'s.ply'");
  EXPECT_EQ(quoted_name(fs::path("a\\b")), "'a\\\\b'");
  // A C1 control (U+009B, a CSI on some terminals) and invalid UTF-8 bytes.
  EXPECT_EQ(quoted_name(fs::path("x\xc2\x9b"
                                 "2J")),
            "'x\\xc2\\x9b2J'");
  EXPECT_EQ(quoted_name(fs::path("bad\xff.ply")), "'bad\\xff.ply'");
  EXPECT_EQ(quoted_name(std::string_view("")), "''");
  EXPECT_EQ(one_line("a.ply: line 1\nline 2\x1b[31m"), "a.ply: line 1\\nline 2\\x1b[31m");
}

}  // namespace
}  // namespace treecut
