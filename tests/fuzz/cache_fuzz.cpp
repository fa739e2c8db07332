// libFuzzer target: hierarchy cache loading (load_cache, read_cache_key) on
// arbitrary file contents. Each input is loaded twice: as it is, and resealed
// with valid checksums (the meta part's and every page's), which reaches the
// checks behind them (header fields, offsets, the page table, the pages'
// decompression and links). A rejection must say why; a cache
// that loads must be safe to traverse (fuzz_checks.hpp). Seeded with small
// caches written by cache_seeds; run by .ci/fuzz.
#include <fcntl.h>
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

#include "fuzz_checks.hpp"
#include "hierarchy/cache_checksum.hpp"
#include "treecut/cache.hpp"

namespace {

[[noreturn]] void fail(const std::string& what) {
  std::fprintf(stderr, "cache_fuzz: %s\n", what.c_str());
  std::abort();
}

// load_cache maps a file by path: one scratch file per process, removed
// after every input. (An atexit handler did not do it: every CI fuzz run
// left its file in the temp folder.)
const std::filesystem::path& scratch() {
  static const std::filesystem::path path =
      std::filesystem::temp_directory_path() /
      ("treecut-cache-fuzz-" + std::to_string(::getpid()) + ".tch");
  return path;
}

struct RemoveScratch {
  ~RemoveScratch() {
    std::error_code ec;
    std::filesystem::remove(scratch(), ec);
  }
};

void write_file(const std::uint8_t* data, std::size_t size) {
  const int fd = ::open(scratch().c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0600);
  if (fd < 0) fail("cannot create " + scratch().string());
  for (std::size_t done = 0; done < size;) {
    const ssize_t w = ::write(fd, data + done, size - done);
    if (w <= 0) fail("cannot write " + scratch().string());
    done += static_cast<std::size_t>(w);
  }
  ::close(fd);
}

void load(const std::uint8_t* data, std::size_t size) {
  const RemoveScratch remove_after;  // last to go: after the hierarchy that maps it
  write_file(data, size);
  std::string why;
  const auto h = treecut::load_cache(scratch(), std::nullopt, &why);
  std::string key_why;
  const bool key = treecut::read_cache_key(scratch(), &key_why).has_value();
  if (key != h.has_value()) fail("load_cache and read_cache_key disagree");
  if (!h) {
    if (why.empty() || key_why != why) fail("rejected without the same reason twice");
    return;
  }
  if (std::string problem = treecut::fuzz::check_loaded_hierarchy(*h); !problem.empty()) {
    fail("accepted a cache that is unsafe to use: " + problem);
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  load(data, size);
  if (size > 8) {
    std::vector<std::uint8_t> sealed(data, data + size);
    if (treecut::detail::reseal_cache(sealed.data(), sealed.size()))
      load(sealed.data(), sealed.size());
  }
  return 0;
}
