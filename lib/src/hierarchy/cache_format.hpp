// What cache_lookup.cpp needs of the cache file beyond the public cache.hpp:
// the key in a cache's header without verifying the file. Private to the
// library; the layout itself stays in cache_layout.hpp, for cache.cpp and
// cache_write.cpp.
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "../import/byte_source.hpp"
#include "cache_layout.hpp"
#include "cache_pages.hpp"
#include "treecut/cache.hpp"

namespace treecut {

/// A cache file's bytes made in memory from a hierarchy, once: what
/// save_cache writes. A build goes through one, its hierarchy quantized as
/// the file loads it (cache_pages.hpp), so a model is the same opened cold
/// or from its cache.
class CacheImage {
 public:
  CacheImage(const Hierarchy& h, const CacheKey& key);
  /// The image of a hierarchy that is its own (a build's), H rewritten on
  /// the way to the values the file decodes to (cache_pages::
  /// encode_in_place), so that nothing is decoded: hierarchy() is then the
  /// same, value for value, as the saved file loads.
  CacheImage(Hierarchy&& h, const CacheKey& key);
  [[nodiscard]] const Hierarchy& hierarchy() const { return hierarchy_; }
  /// Writes the file atomically (AtomicFile); throws "PATH: REASON".
  void save(const std::filesystem::path& cache) const;
  /// The file's size.
  [[nodiscard]] std::size_t size() const;

 private:
  void make(const Hierarchy& h, const CacheKey& key, bool in_place);
  std::vector<unsigned char> meta_;                // header, tables, records, notes
  std::vector<std::vector<unsigned char>> pages_;  // compressed, in file order
  std::array<unsigned char, 8> checksum_{};        // of meta_
  Hierarchy hierarchy_;                            // with the second constructor
};

}  // namespace treecut

namespace treecut::detail {

/// What a cache's meta part says of its model beside the page table.
struct CacheMeta {
  const CacheKey& key;
  const CoordinateFrame& frame;
  glm::vec3 bounds_min, bounds_max;
  std::uint64_t node_count, point_count;
  std::uint32_t level_count;
  const std::vector<NodeAttribute>& attributes;  ///< their records (values ignored)
  const SourceNotes& notes;
};

/// The meta part of a cache file (header, page table and LINKS, crs,
/// attribute records, notes) for pages of TABLE's sizes written in its
/// order right after it: TABLE's offsets are set. What CacheImage and the
/// chunked build (which writes its pages from disk) write first.
std::vector<unsigned char> cache_meta(const CacheMeta& meta,
                                      std::vector<cache_layout::PageRecord>& table,
                                      const cache_pages::PageLinks& links);
/// Creates the folder CACHE is to be written in, if missing; throws
/// std::runtime_error "FOLDER: REASON".
void create_cache_folder(const std::filesystem::path& cache);

/// The checksum a cache file ends with: of its meta part.
std::array<unsigned char, 8> meta_checksum(std::span<const unsigned char> meta);

/// The key recorded in CACHE's header as it is on disk, unverified (the
/// checksum is checked by load_cache_and_key before anything is served): only
/// to decide whether the content hash can be skipped. nullopt when CACHE is
/// not a readable cache of this format version. Never blocks.
std::optional<CacheKey> peek_cache_key(const std::filesystem::path& cache);

/// Reads COUNT bytes at AT of the file open as FD (named PATH) into OUT.
/// Throws FileChangedError "PATH: changed while being read (it got
/// shorter)" when the file no longer has them, std::runtime_error
/// "PATH: REASON" on a read error.
void read_exactly(int fd, std::uint64_t at, std::size_t count, unsigned char* out,
                  const std::filesystem::path& path);

/// What a cache's meta part says of its model, verified, without a page.
struct CacheOutline {
  cache_pages::PageIndex index;  ///< what decodes any page alone
  CoordinateFrame frame;
  SourceNotes notes;
  std::vector<NodeAttribute> attributes;  ///< without values: the pages hold the varying ones'
  std::vector<bool> varying;              ///< each attribute's: its values in the pages
  glm::vec3 bounds_min, bounds_max;
  std::uint64_t point_count;
};

/// The outline of the cache SOURCE holds, its meta part read and
/// verified, no page read (what paged drawing opens with: a file, or a
/// URL). nullopt and *WHY when it is no cache of this format or its meta
/// part does not check out; what SOURCE throws when a read fails.
std::optional<CacheOutline> read_cache_outline(const ByteSource& source, std::string* why);

/// XXH3-64 of the first SIZE bytes (what an fstat saw) of the file open as
/// FD, named SOURCE in messages. Throws FileChangedError when the file is
/// shorter than that by the time its pages are read.
std::uint64_t hash_descriptor(const std::filesystem::path& source, int fd, std::uint64_t size);

}  // namespace treecut::detail
