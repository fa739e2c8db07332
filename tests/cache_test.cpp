// Hierarchy cache: round trip, determinism, and detection of every truncation,
// flipped byte and stale source.
#include "treecut/cache.hpp"

#include <gtest/gtest.h>
#include <sys/resource.h>

#include <csignal>
#include <cstdlib>
#include <fstream>
#include <iterator>

#include "test_support.hpp"
#include "treecut/error.hpp"
#include "treecut/generate.hpp"
#include "treecut/model_io.hpp"
#include "treecut/ply.hpp"

using namespace treecut;
namespace fs = std::filesystem;

namespace {

std::vector<char> read_all(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), {}};
}

void write_all(const fs::path& p, const std::vector<char>& bytes, std::size_t n) {
  std::ofstream out(p, std::ios::binary | std::ios::trunc);
  out.write(bytes.data(), static_cast<std::streamsize>(n));
}

Hierarchy small(std::size_t n = 300) {
  return build_from_points(generate_model(ModelKind::Sphere, n, 4));
}

}  // namespace

TEST(Cache, RoundTripGivesTheSameArrays) {
  const fs::path dir = test::scratch_dir("cache_roundtrip");
  const Hierarchy h = small(5000);
  const CacheKey key{123, 456, 7};
  save_cache(h, key, dir / "a.tch");
  std::string why;
  auto loaded = load_cache(dir / "a.tch", key, &why);
  ASSERT_TRUE(loaded) << why;
  EXPECT_EQ(loaded->node_count(), h.node_count());
  EXPECT_EQ(loaded->level_count(), h.level_count());
  EXPECT_EQ(check_invariants(*loaded), "");
  for (NodeId n = 0; n < h.node_count(); ++n) {
    ASSERT_EQ(loaded->arrays().center_radius[n], h.arrays().center_radius[n]);
    ASSERT_EQ(loaded->arrays().first_child[n], h.arrays().first_child[n]);
  }
  for (const auto& e : fs::directory_iterator(dir))
    EXPECT_EQ(e.path().extension(), ".tch") << "temporary left behind: " << e.path();
}

TEST(Cache, SameInputGivesAByteIdenticalFile) {
  const fs::path dir = test::scratch_dir("cache_deterministic");
  BuildOptions one, two;
  one.threads = 1;
  two.threads = 3;
  save_cache(build_from_points(generate_model(ModelKind::Terrain, 20000, 2), {}, one), {1, 2, 3},
             dir / "a.tch");
  save_cache(build_from_points(generate_model(ModelKind::Terrain, 20000, 2), {}, two), {1, 2, 3},
             dir / "b.tch");
  EXPECT_EQ(read_all(dir / "a.tch"), read_all(dir / "b.tch"));
}

TEST(Cache, EveryTruncationIsDetected) {
  const fs::path dir = test::scratch_dir("cache_truncate");
  save_cache(small(), {1, 2, 3}, dir / "full.tch");
  const auto bytes = read_all(dir / "full.tch");
  for (std::size_t len = 0; len < bytes.size(); ++len) {
    write_all(dir / "cut.tch", bytes, len);
    std::string why;
    ASSERT_FALSE(load_cache(dir / "cut.tch", std::nullopt, &why)) << "length " << len;
    ASSERT_FALSE(why.empty());
  }
}

TEST(Cache, EverySingleFlippedByteIsDetected) {
  const fs::path dir = test::scratch_dir("cache_flip");
  save_cache(small(200), {1, 2, 3}, dir / "full.tch");
  auto bytes = read_all(dir / "full.tch");
  for (std::size_t i = 0; i < bytes.size(); ++i) {
    for (unsigned char mask : {0x01, 0x80}) {
      bytes[i] = static_cast<char>(bytes[i] ^ mask);
      write_all(dir / "flip.tch", bytes, bytes.size());
      bytes[i] = static_cast<char>(bytes[i] ^ mask);
      ASSERT_FALSE(load_cache(dir / "flip.tch", std::nullopt, nullptr)) << "byte " << i;
    }
  }
}

TEST(Cache, StaleKeyIsRejected) {
  const fs::path dir = test::scratch_dir("cache_stale");
  save_cache(small(), {10, 20, 0}, dir / "a.tch");
  std::string why;
  EXPECT_FALSE(load_cache(dir / "a.tch", CacheKey{11, 20, 0}, &why));
  EXPECT_NE(why.find("stale"), std::string::npos);
  EXPECT_FALSE(load_cache(dir / "a.tch", CacheKey{10, 20, 1}, &why)) << "other build options";
  EXPECT_TRUE(load_cache(dir / "a.tch", CacheKey{10, 20, 0}, &why));
}

TEST(Cache, StaleWhenTheContentHashDiffers) {
  const fs::path dir = test::scratch_dir("cache_stale_hash");
  save_cache(small(), {10, 20, 0, 0x1234}, dir / "a.tch");
  std::string why;
  EXPECT_FALSE(load_cache(dir / "a.tch", CacheKey{10, 20, 0, 0x1235}, &why));
  EXPECT_NE(why.find("stale"), std::string::npos) << why;
  EXPECT_TRUE(load_cache(dir / "a.tch", CacheKey{10, 99, 0, 0x1234}, &why))
      << "another mtime, the same content: " << why;
  const auto key = read_cache_key(dir / "a.tch", &why);
  ASSERT_TRUE(key) << why;
  EXPECT_EQ(key->content_hash, 0x1234u);
  EXPECT_EQ(key->source_mtime_ns, 20);
}

// A model edited in place (same size) with its modification time restored, as
// `touch -d` or a careful editor does: the content hash notices.
TEST(Cache, AModelEditedInPlaceWithItsMtimeRestoredIsRebuilt) {
  const fs::path dir = test::scratch_dir("cache_edit_in_place");
  save_ply(dir / "m.ply", generate_model(ModelKind::Terrain, 4000, 3));
  OpenOptions o;
  o.cache_path = dir / "m.tch";
  const OpenedModel first = open_model(dir / "m.ply", o);
  ASSERT_FALSE(first.from_cache);
  ASSERT_TRUE(open_model(dir / "m.ply", o).from_cache);
  const auto size = fs::file_size(dir / "m.ply");
  const auto mtime = fs::last_write_time(dir / "m.ply");
  {
    // The first point's x, one byte of it: the same size, other content.
    std::fstream f(dir / "m.ply", std::ios::in | std::ios::out | std::ios::binary);
    std::string text(4096, '\0');
    f.read(text.data(), static_cast<std::streamsize>(text.size()));
    const auto body = text.find("end_header\n");
    ASSERT_NE(body, std::string::npos);
    f.seekp(static_cast<std::streamoff>(body + 11 + 1));
    f.put(static_cast<char>(text[body + 11 + 1] ^ 0x40));
  }
  fs::last_write_time(dir / "m.ply", mtime);
  ASSERT_EQ(fs::file_size(dir / "m.ply"), size);
  ASSERT_EQ(fs::last_write_time(dir / "m.ply"), mtime);
  const OpenedModel edited = open_model(dir / "m.ply", o);
  EXPECT_FALSE(edited.from_cache) << "served a cache built from other content";
  EXPECT_NE(edited.cache_note.find("stale"), std::string::npos) << edited.cache_note;
  EXPECT_TRUE(open_model(dir / "m.ply", o).from_cache) << "the rebuilt cache was written back";
}

TEST(Cache, ContentHashIsOfTheBytes) {
  const fs::path dir = test::scratch_dir("cache_content_hash");
  std::ofstream(dir / "a") << "same bytes";
  std::ofstream(dir / "b") << "same bytes";
  std::ofstream(dir / "c") << "same bytez";
  EXPECT_EQ(content_hash_of(dir / "a"), content_hash_of(dir / "b"));
  EXPECT_NE(content_hash_of(dir / "a"), content_hash_of(dir / "c"));
  std::ofstream(dir / "empty");
  EXPECT_NO_THROW(content_hash_of(dir / "empty"));
  EXPECT_THROW(content_hash_of(dir / "missing"), InputError);
  EXPECT_THROW(content_hash_of(dir), InputError) << "a directory";
}

TEST(Cache, OpenModelUsesTheCacheAndRebuildsACorruptOne) {
  const fs::path dir = test::scratch_dir("cache_open");
  save_ply(dir / "m.ply", generate_model(ModelKind::City, 3000, 1));
  OpenOptions o;
  o.cache_path = dir / "m.tch";
  std::vector<std::string> warnings;
  o.warn = [&](const std::string& w) { warnings.push_back(w); };

  const OpenedModel first = open_model(dir / "m.ply", o);
  EXPECT_FALSE(first.from_cache);
  const OpenedModel second = open_model(dir / "m.ply", o);
  EXPECT_TRUE(second.from_cache) << "the second load skips the build";
  EXPECT_EQ(second.hierarchy.node_count(), first.hierarchy.node_count());

  auto bytes = read_all(dir / "m.tch");
  bytes[bytes.size() / 2] ^= 0x10;
  write_all(dir / "m.tch", bytes, bytes.size());
  const OpenedModel third = open_model(dir / "m.ply", o);
  EXPECT_FALSE(third.from_cache);
  EXPECT_NE(third.cache_note.find("checksum"), std::string::npos) << third.cache_note;
  ASSERT_FALSE(warnings.empty());
  EXPECT_TRUE(open_model(dir / "m.ply", o).from_cache) << "the rebuilt cache was written back";

  // The content decides, not the modification time: a touch keeps the cache...
  fs::last_write_time(dir / "m.ply", fs::last_write_time(dir / "m.ply") + std::chrono::seconds(5));
  EXPECT_TRUE(open_model(dir / "m.ply", o).from_cache) << "only the mtime changed";
  // ...and other content of the same size makes it stale.
  save_ply(dir / "m.ply", generate_model(ModelKind::City, 3000, 2));
  const OpenedModel fourth = open_model(dir / "m.ply", o);
  EXPECT_FALSE(fourth.from_cache);
  EXPECT_NE(fourth.cache_note.find("stale"), std::string::npos);

  // A cache file opened directly.
  const OpenedModel direct = open_model(dir / "m.tch", o);
  EXPECT_TRUE(direct.from_cache);
  EXPECT_EQ(direct.hierarchy.node_count(), first.hierarchy.node_count());
}

// End to end: whatever prefix of its cache survives, open_model() notices,
// says why, rebuilds from the PLY and writes the complete cache back.
TEST(Cache, OpenModelRebuildsFromThePlyAfterEveryTruncationOfItsCache) {
  const fs::path dir = test::scratch_dir("cache_open_truncate");
  save_ply(dir / "m.ply", generate_model(ModelKind::Sphere, 24, 5));
  OpenOptions o;
  o.cache_path = dir / "m.tch";
  std::size_t rebuild_warnings = 0;
  o.warn = [&](const std::string& w) {
    rebuild_warnings += w.find("rebuilding") != std::string::npos;
  };
  const OpenedModel built = open_model(dir / "m.ply", o);
  ASSERT_FALSE(built.from_cache);
  const auto bytes = read_all(dir / "m.tch");
  ASSERT_FALSE(bytes.empty());
  for (std::size_t len = 0; len < bytes.size(); ++len) {
    write_all(dir / "m.tch", bytes, len);
    const OpenedModel m = open_model(dir / "m.ply", o);
    ASSERT_FALSE(m.from_cache) << "length " << len;
    ASSERT_FALSE(m.cache_note.empty()) << "length " << len;
    ASSERT_EQ(m.hierarchy.node_count(), built.hierarchy.node_count());
    ASSERT_EQ(read_all(dir / "m.tch"), bytes) << "length " << len << ": not rewritten";
  }
  EXPECT_EQ(rebuild_warnings, bytes.size());
  EXPECT_TRUE(open_model(dir / "m.ply", o).from_cache);
}

TEST(Cache, OpenModelRebuildsFromThePlyAfterAnyFlippedByteInItsCache) {
  const fs::path dir = test::scratch_dir("cache_open_flip");
  save_ply(dir / "m.ply", generate_model(ModelKind::Terrain, 24, 5));
  OpenOptions o;
  o.cache_path = dir / "m.tch";
  const OpenedModel built = open_model(dir / "m.ply", o);
  auto bytes = read_all(dir / "m.tch");
  for (std::size_t i = 0; i < bytes.size(); ++i) {
    bytes[i] = static_cast<char>(bytes[i] ^ 0x04);
    write_all(dir / "m.tch", bytes, bytes.size());
    bytes[i] = static_cast<char>(bytes[i] ^ 0x04);
    const OpenedModel m = open_model(dir / "m.ply", o);
    ASSERT_FALSE(m.from_cache) << "byte " << i;
    ASSERT_EQ(m.hierarchy.node_count(), built.hierarchy.node_count());
    ASSERT_EQ(read_all(dir / "m.tch"), bytes) << "byte " << i << ": not rewritten";
  }
}

// A cache file opened directly has no PLY to fall back on: every damaged
// version is an InputError naming the file, never a crash or a hierarchy.
TEST(Cache, OpeningADamagedCacheDirectlyIsAnInputError) {
  const fs::path dir = test::scratch_dir("cache_open_direct");
  save_cache(small(40), {1, 2, 3}, dir / "full.tch");
  const auto bytes = read_all(dir / "full.tch");
  for (std::size_t len = 0; len < bytes.size(); len += 7) {
    write_all(dir / "cut.tch", bytes, len);
    try {
      open_model(dir / "cut.tch");
      FAIL() << "length " << len << " opened";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find("cut.tch"), std::string::npos) << e.what();
    }
  }
}

namespace {

// The child of the death test below: save_cache() under a file size limit,
// which kills the process with SIGXFSZ once the limit is reached.
[[noreturn]] void save_cache_under_size_limit(const Hierarchy& h, const CacheKey& key,
                                              const fs::path& cache, rlim_t limit) {
  const rlimit no_core{0, 0};
  setrlimit(RLIMIT_CORE, &no_core);
  const rlimit size{limit, limit};
  setrlimit(RLIMIT_FSIZE, &size);
  save_cache(h, key, cache);
  std::_Exit(0);
}

}  // namespace

// A writer that dies mid-write (here: killed by the file size limit, SIGXFSZ,
// after part of the file went to disk) leaves the previous cache untouched and
// at most a partial temporary, which never loads and which open_model never
// reads.
TEST(CacheDeathTest, AWriterKilledMidWriteLeavesNoCacheThatLoads) {
  const fs::path dir = test::scratch_dir("cache_killed_writer");
  const Hierarchy before = small(300);
  const Hierarchy after = small(5000);
  save_cache(before, {1, 2, 3}, dir / "a.tch");
  const auto old_bytes = read_all(dir / "a.tch");
  constexpr rlim_t kLimit = 20000;  // bytes: a few arrays of the new file
  const CacheKey new_key{4, 5, 6};
  EXPECT_EXIT(save_cache_under_size_limit(after, new_key, dir / "a.tch", kLimit),
              testing::KilledBySignal(SIGXFSZ), "");

  EXPECT_EQ(read_all(dir / "a.tch"), old_bytes) << "the previous cache was touched";
  EXPECT_TRUE(load_cache(dir / "a.tch", CacheKey{1, 2, 3}, nullptr));
  std::string why;
  EXPECT_FALSE(load_cache(dir / "a.tch", CacheKey{4, 5, 6}, &why)) << "the new key";
  EXPECT_NE(why.find("stale"), std::string::npos) << why;
  std::vector<fs::path> temporaries;
  for (const auto& e : fs::directory_iterator(dir))
    if (e.path().filename() != "a.tch") temporaries.push_back(e.path());
  ASSERT_EQ(temporaries.size(), 1u) << "the dead writer's temporary";
  EXPECT_EQ(temporaries[0].filename().string().rfind("a.tch.tmp-", 0), 0u) << temporaries[0];
  EXPECT_GT(fs::file_size(temporaries[0]), 0u);
  EXPECT_LE(fs::file_size(temporaries[0]), kLimit);
  EXPECT_FALSE(load_cache(temporaries[0], std::nullopt, &why));
  EXPECT_THROW(open_model(temporaries[0]), InputError);
}
