// Which cache serves which model: the model's identity (device, inode, size,
// mtime, ctime) and content hash (XXH3-64), the settled rule that lets the
// identity alone decide, and the lookup that runs the hash beside the cache's
// verification. The file itself (layout, checksum, reading and writing) is
// cache_layout.hpp's, cache.cpp's and cache_write.cpp's; this file sees it
// only through cache_format.hpp.
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>
#include <xxhash.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <ctime>
#include <future>
#include <memory>
#include <optional>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

#include "cache_format.hpp"
#include "treecut/cache.hpp"
#include "treecut/error.hpp"
#include "treecut/file_io.hpp"
#include "treecut/mapped_file.hpp"

namespace treecut {

namespace {

std::int64_t ns_of(const timespec& t) {
  return static_cast<std::int64_t>(t.tv_sec) * 1000000000 + t.tv_nsec;
}

// The identity of the file behind FD and the wall-clock time just before it
// was taken (so before any of the content is read).
CacheKey identity_of_descriptor(const std::filesystem::path& source, int fd,
                                std::uint32_t options_bits) {
  timespec now{};
  ::clock_gettime(CLOCK_REALTIME, &now);
  struct stat st {};
  if (::fstat(fd, &st) != 0) throw std::runtime_error(system_error_text(source, errno));
  CacheKey key;
  key.source_size = static_cast<std::uint64_t>(st.st_size);
  key.source_mtime_ns = ns_of(st.st_mtim);
  key.options_bits = options_bits;
  key.source_device = static_cast<std::uint64_t>(st.st_dev);
  key.source_inode = static_cast<std::uint64_t>(st.st_ino);
  key.source_ctime_ns = ns_of(st.st_ctim);
  key.identity_ns = ns_of(now);
  return key;
}

}  // namespace

// XXH3-64 of the SIZE bytes behind FD. Through a read-only mapping (no copy
// into a buffer; the model was usually just read, so its pages are in the
// page cache and hashing runs at memory bandwidth). A file that shrinks
// meanwhile (or is shorter than SIZE, the size an earlier fstat saw) is a
// FileChangedError, not a SIGBUS.
std::uint64_t detail::hash_descriptor(const std::filesystem::path& source, int fd,
                                      std::uint64_t size) {
  if (size == 0) return XXH3_64bits(nullptr, 0);
  const MappedFile map(fd, size, source);
  auto* bytes = const_cast<unsigned char*>(map.data());
  ::madvise(bytes, map.size(), MADV_SEQUENTIAL);
  // A window at a time, each let go once hashed: the file's pages stay in
  // the page cache but not in this process's memory, which a build's
  // budget bounds (a survey's tiles of tens of GB; issue 44).
  constexpr std::size_t kWindow = std::size_t{1} << 20;
  const std::unique_ptr<XXH3_state_t, XXH_errorcode (*)(XXH3_state_t*)> owned(XXH3_createState(),
                                                                              XXH3_freeState);
  XXH3_state_t* state = owned.get();
  if (!state) throw std::bad_alloc();
  XXH3_64bits_reset(state);
  map.read_guarded([&] {
    for (std::size_t at = 0; at < map.size(); at += kWindow) {
      const std::size_t n = std::min(kWindow, map.size() - at);
      XXH3_64bits_update(state, bytes + at, n);
      ::madvise(bytes + at, n, MADV_DONTNEED);
    }
  });
  return XXH3_64bits_digest(state);
}

namespace {

CacheKey key_of_descriptor(const std::filesystem::path& source, int fd,
                           std::uint32_t options_bits) {
  CacheKey key = identity_of_descriptor(source, fd, options_bits);
  key.content_hash = detail::hash_descriptor(source, fd, key.source_size);
  return key;
}

struct Descriptor {
  int fd;
  explicit Descriptor(int f) : fd(f) {}
  Descriptor(const Descriptor&) = delete;
  Descriptor& operator=(const Descriptor&) = delete;
  ~Descriptor() { ::close(fd); }
};

bool settled(const CacheKey& k) {
  return k.identity_ns != 0 && k.source_ctime_ns <= k.identity_ns - kSettledNs;
}

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace

namespace {

// The key of a model made of SOURCES (one file, or the tiles of one cloud):
// one file's own key, else one key over all, whose fields still say what
// cache_identity_serves() and cache_key_matches() ask: the sizes summed, the
// content hash over each file's name and hash in order (a renamed or
// reordered tile is another model), the devices, inodes and modification
// times hashed with the names, the newest change time (settled when every
// file is) and the first identity time. Each file's identity and hash come
// from one descriptor, opened in turn (a folder of thousands of tiles holds
// no more than one open).
CacheKey key_of_files(std::span<const std::filesystem::path> sources, std::uint32_t options_bits,
                      bool hash) {
  if (sources.empty()) throw std::invalid_argument("a model of no files");
  std::vector<CacheKey> keys;
  keys.reserve(sources.size());
  for (const std::filesystem::path& source : sources) {
    const Descriptor file(open_regular_file(source));  // InputError: missing, a FIFO...
    keys.push_back(hash ? key_of_descriptor(source, file.fd, options_bits)
                        : identity_of_descriptor(source, file.fd, options_bits));
  }
  if (keys.size() == 1) return keys.front();
  XXH3_state_t* identity = XXH3_createState();
  XXH3_state_t* content = XXH3_createState();
  if (!identity || !content) throw std::bad_alloc();
  XXH3_64bits_reset(identity);
  XXH3_64bits_reset(content);
  CacheKey all = keys.front();
  all.source_size = 0;
  for (std::size_t i = 0; i < keys.size(); ++i) {
    const CacheKey& k = keys[i];
    const std::string name = sources[i].filename().string();
    const std::uint64_t fields[] = {k.source_device, k.source_inode,
                                    static_cast<std::uint64_t>(k.source_mtime_ns), k.source_size};
    XXH3_64bits_update(identity, name.data(), name.size() + 1);
    XXH3_64bits_update(identity, fields, sizeof fields);
    const std::uint64_t named[] = {k.source_size, k.content_hash};
    XXH3_64bits_update(content, name.data(), name.size() + 1);
    XXH3_64bits_update(content, named, sizeof named);
    all.source_size += k.source_size;
    all.source_ctime_ns = std::max(all.source_ctime_ns, k.source_ctime_ns);
  }
  all.source_device = 0;
  all.source_inode = XXH3_64bits_digest(identity);
  all.source_mtime_ns = static_cast<std::int64_t>(all.source_inode >> 1);
  all.content_hash = hash ? XXH3_64bits_digest(content) : 0;
  XXH3_freeState(identity);
  XXH3_freeState(content);
  return all;
}

}  // namespace

CacheKey cache_key_for(std::span<const std::filesystem::path> sources, std::uint32_t options_bits) {
  return key_of_files(sources, options_bits, true);
}

CacheKey cache_identity_of(std::span<const std::filesystem::path> sources,
                           std::uint32_t options_bits) {
  return key_of_files(sources, options_bits, false);
}

CacheKey cache_key_for(const std::filesystem::path& source, std::uint32_t options_bits) {
  return cache_key_for(std::span(&source, 1), options_bits);
}

CacheKey cache_identity_of(const std::filesystem::path& source, std::uint32_t options_bits) {
  return cache_identity_of(std::span(&source, 1), options_bits);
}

bool cache_identity_serves(const CacheKey& stored, const CacheKey& now) {
  return settled(stored) && stored.options_bits == now.options_bits &&
         stored.source_device == now.source_device && stored.source_inode == now.source_inode &&
         stored.source_size == now.source_size && stored.source_mtime_ns == now.source_mtime_ns &&
         stored.source_ctime_ns == now.source_ctime_ns;
}

CacheLookup lookup_cache(std::span<const std::filesystem::path> sources,
                         const std::filesystem::path& cache, std::uint32_t options_bits,
                         bool refresh) {
  CacheLookup out;
  // One file is held open from its identity to its hash; a model of many
  // files takes each file's identity and hash from one descriptor, and a
  // file that changes between the identity pass and the hash is caught by
  // the key's identity fields (the hash pass's replace them).
  std::optional<Descriptor> file;
  if (sources.size() == 1) {
    file.emplace(open_regular_file(sources.front()));  // InputError: missing, a FIFO...
    out.key = identity_of_descriptor(sources.front(), file->fd, options_bits);
  } else {
    out.key = key_of_files(sources, options_bits, false);
  }
  auto hash = [&] {
    const auto t0 = std::chrono::steady_clock::now();
    std::uint64_t h = 0;
    if (file) {
      h = detail::hash_descriptor(sources.front(), file->fd, out.key.source_size);
    } else {
      const CacheKey hashed = key_of_files(sources, options_bits, true);
      h = hashed.content_hash;
      if (hashed.source_inode != out.key.source_inode || hashed.source_size != out.key.source_size)
        throw FileChangedError(quoted_name(sources.front().parent_path()) +
                               ": a file of the model changed while it was hashed");
    }
    out.hash_seconds = seconds_since(t0);
    return h;
  };
  const std::optional<CacheKey> peeked = detail::peek_cache_key(cache);
  const bool identity_decides = peeked && cache_identity_serves(*peeked, out.key);
  // Otherwise the content hash (memory bandwidth over the whole model) runs
  // beside the cache's own verification (its checksum over the whole cache):
  // a cached open costs the longer of the two, not their sum. (A thread only
  // pays for itself on a large model.)
  const bool large = out.key.source_size >= (std::uint64_t{64} << 20);
  std::future<std::uint64_t> pending;
  if (!identity_decides)
    pending = std::async(large ? std::launch::async : std::launch::deferred, hash);
  const auto t0 = std::chrono::steady_clock::now();
  CacheKey stored{};
  auto hier = load_cache_and_key(cache, &stored, &out.why);
  out.cache_seconds = seconds_since(t0);
  if (hier && identity_decides && cache_identity_serves(stored, out.key)) {
    out.key.content_hash = stored.content_hash;
    out.hierarchy = std::move(hier);
    return out;
  }
  // Not decided by the identity (or the cache changed between the two reads):
  // the content decides.
  out.key.content_hash = pending.valid() ? pending.get() : hash();
  out.hashed = true;
  if (!hier) return out;
  if (!cache_key_matches(stored, out.key)) {
    out.why = "stale (the model or the build options changed)";
    return out;
  }
  out.hierarchy = std::move(hier);
  // The same content under another identity (touched, copied) or a build that
  // was not settled yet: once settled, rewrite the cache with the identity of
  // now so the next open skips the hash. Only an optimization: a failure
  // (read-only folder, full disk) leaves the cache as it was.
  if (refresh && settled(out.key) && !cache_identity_serves(stored, out.key)) {
    try {
      const auto t1 = std::chrono::steady_clock::now();
      save_cache(*out.hierarchy, out.key, cache);
      out.cache_seconds += seconds_since(t1);
      out.refreshed = true;
    } catch (const std::exception&) {
    }
  }
  return out;
}

CacheLookup lookup_cache(const std::filesystem::path& source, const std::filesystem::path& cache,
                         std::uint32_t options_bits, bool refresh) {
  return lookup_cache(std::span(&source, 1), cache, options_bits, refresh);
}

std::uint64_t content_hash_of(const std::filesystem::path& source) {
  return cache_key_for(source, 0).content_hash;
}

bool cache_key_matches(const CacheKey& stored, const CacheKey& expected) {
  // The modification time does not decide: an edit with the mtime restored
  // changes the hash, and a touch (or a copy) that changes nothing keeps the cache.
  return stored.source_size == expected.source_size &&
         stored.content_hash == expected.content_hash &&
         stored.options_bits == expected.options_bits;
}

}  // namespace treecut
