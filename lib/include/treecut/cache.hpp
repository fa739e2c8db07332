// On-disk hierarchy cache: versioned, checksummed, memory-mapped on load.
//
// Layout: a fixed header (magic, format version, endianness tag, counts, the
// source file's size, modification time and content hash, its identity
// (device, inode, change time) and when that identity was taken, the build
// options, per-array offsets) followed by the node arrays, each 64-byte
// aligned, and a 64-bit checksum over header and payload. Written through an
// AtomicFile (temporary + rename, every write checked), so a crash or a full
// disk never leaves a cache that loads.
//
// When a cache serves a model (lookup_cache): the content decides, the
// identity saves reading it. A cache is served for the content it was built
// from: the same size, build options and XXH3-64 of the model's bytes. The
// hash is skipped, as git skips a "racily clean" check, only when the model's
// identity is exactly the one recorded (st_dev, st_ino, size, mtime ns,
// ctime ns) AND the recorded ctime was at least kSettledNs older than the
// moment the identity was taken (just before the content was read). ctime
// cannot be set by users: an edit in place with its mtime restored still
// moves it. The margin covers file systems with coarse timestamps: an edit
// made after the content was read, in the same timestamp tick as the change
// before it, would leave ctime as recorded; once the recorded ctime is 2 s
// older than the read, any later edit lands in a later tick. Otherwise (a
// touched, copied or just-written model) the content is hashed and decides,
// and a served cache whose identity is now settled is rewritten with it, so
// the next open skips the hash.
#pragma once

#include <cstdint>
#include <filesystem>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "treecut/hierarchy.hpp"

namespace treecut {

/// What a cache was built from. A cache is stale when the size, the options
/// or the content hash differ; the modification time does not decide: a file
/// edited in place with its mtime restored has another hash, and a file only
/// touched keeps its cache. The identity fields only let lookup_cache() skip
/// the hash (see the top of this file); 0 in identity_ns means "unknown".
struct CacheKey {
  std::uint64_t source_size = 0;
  std::int64_t source_mtime_ns = 0;
  std::uint32_t options_bits = 0;   ///< BuildOptions/AttributeOptions that change the output
  std::uint64_t content_hash = 0;   ///< XXH3-64 of the source file's bytes
  std::uint64_t source_device = 0;  ///< st_dev
  std::uint64_t source_inode = 0;   ///< st_ino
  std::int64_t source_ctime_ns = 0;
  /// Wall clock (CLOCK_REALTIME, ns) when the identity was taken, before the
  /// content was read: no later than the cache's write, and the stricter
  /// reference for the settled rule when the build in between is long.
  std::int64_t identity_ns = 0;
};

/// How much older than identity_ns the recorded ctime must be for the
/// identity alone to serve a cache (coarse file-system timestamps: FAT's 2 s).
inline constexpr std::int64_t kSettledNs = 2'000'000'000;

/// Size, mtime, identity and content hash of SOURCE (read through a mapping,
/// never blocking: a FIFO or directory is an InputError naming what it is).
CacheKey cache_key_for(const std::filesystem::path& source, std::uint32_t options_bits);

/// cache_key_for() without reading the content (content_hash 0): one fstat.
CacheKey cache_identity_of(const std::filesystem::path& source, std::uint32_t options_bits);

/// The key of a model made of several files, in order (a folder of tiles,
/// issue 44): one file's own key, else the sizes summed, the content hash
/// over each file's name, size and hash, the identity fields over each
/// file's (the newest change time: settled when every file is). A renamed,
/// added, removed or edited file gives another key.
CacheKey cache_key_for(std::span<const std::filesystem::path> sources, std::uint32_t options_bits);
CacheKey cache_identity_of(std::span<const std::filesystem::path> sources,
                           std::uint32_t options_bits);

/// Whether a cache written for STORED serves a source whose identity is NOW
/// without hashing it: the same options, device, inode, size, mtime and ctime,
/// and STORED's ctime at least kSettledNs older than STORED's identity_ns.
bool cache_identity_serves(const CacheKey& stored, const CacheKey& now);

/// XXH3-64 of a whole regular file (what CacheKey::content_hash holds).
std::uint64_t content_hash_of(const std::filesystem::path& source);

/// Whether PATH is a regular file that starts like a treecut cache (magic
/// bytes only; load_cache verifies the rest). Never blocks.
bool looks_like_cache(const std::filesystem::path& path);

/// Whether PATH is a cache treecut wrote, as far as its header can tell
/// without reading the rest: not a symbolic link, the magic, this format
/// version or the one before (6), this machine's byte order, that
/// version's header size, and the file's exact size as its header gives it.
/// What `build -o`, `cache --clear` and the folder's size limit may replace
/// or remove (a 25-byte file that starts with the magic is the user's, and
/// so is one that claims an older version).
bool is_own_cache(const std::filesystem::path& path);

/// Writes atomically (AtomicFile: temporary + rename). Creates the folder.
/// Throws std::runtime_error "PATH: REASON" (the system's reason) on failure;
/// the previous file at CACHE, if any, is left as it was.
void save_cache(const Hierarchy& h, const CacheKey& key, const std::filesystem::path& cache);

/// Maps and verifies a cache. Returns nullopt and sets *why when the file is
/// missing, truncated, corrupted, of another version, or (when `expected` is
/// given) stale. Never crashes on any byte content.
std::optional<Hierarchy> load_cache(const std::filesystem::path& cache,
                                    const std::optional<CacheKey>& expected, std::string* why);

/// load_cache() without the staleness check, with the key the cache was
/// written for in *STORED: a caller may compute the expected key (the content
/// hash) concurrently and compare with cache_key_matches().
std::optional<Hierarchy> load_cache_and_key(const std::filesystem::path& cache, CacheKey* stored,
                                            std::string* why);

/// Whether a cache written for STORED serves EXPECTED: the same size, options
/// and content hash (the modification time does not decide).
bool cache_key_matches(const CacheKey& stored, const CacheKey& expected);

/// What lookup_cache() found.
struct CacheLookup {
  std::optional<Hierarchy> hierarchy;  ///< the cache's, when it serves the source
  CacheKey key;                        ///< the source's key now (content_hash valid when hashed)
  bool hashed = false;     ///< the content was read and hashed (the identity did not decide)
  bool refreshed = false;  ///< served after hashing, and rewritten with the settled identity
  std::string why;         ///< why the cache did not serve (missing, corrupt, stale)
  double hash_seconds = 0, cache_seconds = 0;
};

/// The cached open of SOURCE through CACHE (the rule at the top of this
/// file). When the identity does not decide, the content hash runs beside the
/// cache's own verification (for a large model). With REFRESH, a cache served
/// after hashing whose source is now settled is rewritten with the current
/// key (atomically; a failure only means the next open hashes again).
/// Throws InputError when SOURCE is not a readable regular file.
CacheLookup lookup_cache(const std::filesystem::path& source, const std::filesystem::path& cache,
                         std::uint32_t options_bits, bool refresh);
/// lookup_cache() for a model of several files (cache_key_for of them).
CacheLookup lookup_cache(std::span<const std::filesystem::path> sources,
                         const std::filesystem::path& cache, std::uint32_t options_bits,
                         bool refresh);

/// One page of a cache (format 8, issue 44) as its page table gives it.
struct CachePage {
  std::uint32_t nodes = 0;        ///< at most 4,096: a subtree, or the top of one
  std::uint32_t bytes = 0;        ///< compressed, on disk
  std::uint32_t parent_page = 0;  ///< the page its root hangs from (itself for page 0)
  std::uint32_t root_depth = 0;
  glm::vec3 bounds_min{0.0f}, bounds_max{0.0f};  ///< around its nodes' spheres
};

/// The page table of CACHE, read with the header and the records and
/// verified by their checksum, without reading a page (what a reader that
/// loads pages on demand starts from). nullopt and *WHY when the file is no
/// cache of this format or its table does not check out.
std::optional<std::vector<CachePage>> read_cache_pages(const std::filesystem::path& cache,
                                                       std::string* why);

/// Reads the key stored in a cache header (for `treecut info CACHE`), after full verification.
std::optional<CacheKey> read_cache_key(const std::filesystem::path& cache, std::string* why);

}  // namespace treecut
