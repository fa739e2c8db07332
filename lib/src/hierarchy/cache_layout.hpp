// The layout of a hierarchy cache file (cache.cpp reads it, cache_write.cpp
// writes it, cache_pages.cpp and cache_page_decode.cpp its pages): one header, the
// page table, the coordinate system's text, the attribute records and the
// first read's notes (the "meta" part, up to meta_end), then the pages, one
// after the other without gaps, and last a 64-bit checksum of the meta part.
// Each page carries its own checksum in the page table, so a reader can
// verify the table and read any page alone, and every byte of the file is
// under exactly one checksum. Private to the library.
#pragma once

#include <array>
#include <bit>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <type_traits>

#include "treecut/hierarchy.hpp"

namespace treecut::cache_layout {

inline constexpr char kMagic[8] = {'T', 'C', 'U', 'T', 'H', 'I', 'E', 'R'};
// Bump whenever the layout or the meaning of any field changes.
// 2: the header carries the source's content hash.
// 3: and the source's identity (device, inode, ctime) and when it was taken.
// 4: and the model's CoordinateFrame: the positions' double-precision
//    origin, the format's z-up and the coordinate system's text (map
//    coordinates, issue 29).
// 5: and the file's per-point attributes per node: a table of records
//    (name, kind, offset, range, where the values are) after the crs text.
// 6: and HierarchyArrays::splat_radius, after center_radius (issue 30).
// 7: attributes at the file's precision: an exact double range, a constant
//    stored once; the sensor's viewpoint; the first read's notes (format
//    and warnings) (issue 43).
// 8: paged (issue 44): nodes in pages of whole subtrees, each compressed
//    and checksummed on its own, positions and radii quantized per page
//    (cache_pages.hpp); 64-bit node and point counts.
// 9: pages of up to 8,192 nodes (4,096), priorities in 12 bits (16): a
//    survey tile's cache 7 % smaller (25.4 -> 23.6 bytes a point).
// 10: each page's place in the whole (PageLinks: the ids of its nodes as
//    runs, the points under its root) and the levels' first ids after the
//    page table, so a page decodes alone (issue 45: drawing from pages).
inline constexpr std::uint32_t kVersion = 10;
/// The first version with this header (what is_own_cache recognises).
inline constexpr std::uint32_t kFirstPagedVersion = 8;
inline constexpr std::uint32_t kEndianTag = 0x01020304u;
inline constexpr std::size_t kAlign = 8;
inline constexpr std::uint32_t kMaxCrsBytes = 4096;
/// Version 7's header: what is_own_cache still recognises as a cache
/// treecut wrote (its size, and where it kept the payload's end).
inline constexpr std::uint32_t kV7HeaderSize = 328, kV7PayloadEndAt = 240;

struct Header {
  char magic[8];
  std::uint32_t version;
  std::uint32_t endian_tag;
  std::uint32_t header_size;
  std::uint32_t level_count;
  std::uint64_t node_count;
  std::uint64_t point_count;  // the root's: leaves
  std::uint64_t page_count;
  std::uint64_t page_table;  // offset of page_count PageRecords
  std::uint64_t meta_end;    // the first page starts here
  std::uint64_t source_size;
  std::int64_t source_mtime_ns;
  std::int64_t identity_ns;   // CLOCK_REALTIME when the identity was taken (at byte 80,
                              // as in every version before: tests compare caches but it)
  std::uint64_t source_hash;  // XXH3-64 of the source file's bytes
  std::uint64_t source_device;
  std::uint64_t source_inode;
  std::int64_t source_ctime_ns;
  std::uint32_t options_bits;
  float bounds[6];
  std::uint32_t flags;            // bit 0: z_up, bit 1: normals_estimated, bit 2: viewpoint
  double origin[3];               // Hierarchy::frame(): origin,
  std::uint64_t crs_offset;       // where the crs text is,
  std::uint32_t crs_size;         // and its bytes
  std::uint32_t attribute_count;  // Hierarchy::attributes(), at most kMaxAttributes,
  std::uint64_t attribute_table;  // where their AttributeRecords are
  std::uint64_t notes_offset;     // the notes (format, then warnings, a line each)
  std::uint32_t notes_size;
  std::uint32_t reserved;
  std::uint64_t payload_end;  // the pages end here; the checksum follows
  double viewpoint[7];        // frame().viewpoint when flags bit 2: x y z, w x y z
};
static_assert(std::is_trivially_copyable_v<Header> && sizeof(Header) % 8 == 0 &&
              offsetof(Header, identity_ns) == 80);

// One page (cache_pages.hpp): where its compressed bytes are, what they
// hold, and where it hangs in the hierarchy. Page 0 holds the root; every
// other page's root is a child of node PARENT_LOCAL of page PARENT_PAGE,
// an earlier page.
struct PageRecord {
  std::uint64_t offset;    // of the compressed bytes
  std::uint64_t checksum;  // Checksum of those bytes
  std::uint32_t bytes;     // compressed
  std::uint32_t raw_bytes;
  std::uint32_t node_count;
  std::uint32_t parent_page;  // 0xffffffff for page 0
  std::uint32_t parent_local;
  std::uint32_t root_depth;
  float bounds[6];  // the box around its nodes' spheres, as loaded
};
static_assert(std::is_trivially_copyable_v<PageRecord> && sizeof(PageRecord) == 64);
inline constexpr std::uint32_t kNoPage = 0xffffffffu;

// A run of a page's nodes whose ids follow one another, all of depth
// DEPTH. A page's nodes in its own order (breadth-first from its root, as
// its bytes hold them) have increasing ids, so its runs, in order, give
// each of them its id: its node k is the k-th id of its runs.
struct PageRun {
  std::uint64_t first;
  std::uint32_t count;
  std::uint32_t depth;
};
static_assert(std::is_trivially_copyable_v<PageRun> && sizeof(PageRun) == 16);

// Where each page sits in the whole, after the page table in this order,
// each part 8-byte aligned: the points under each page's root (u64 a page:
// its nodes' point counts are made of them), where each page's runs begin
// (u64 a page and one more: the runs' count), the first id of each level
// (u64, level_count + 1), then the runs, page after page. What lets a
// reader decode one page without the others (cache_pages::decode_page).
struct PageLinksAt {
  std::uint64_t points, run_index, level_begin, runs;
  static PageLinksAt after(std::uint64_t page_table, std::uint64_t pages, std::uint64_t levels) {
    PageLinksAt at{};
    at.points = page_table + pages * sizeof(PageRecord);
    at.run_index = at.points + pages * 8;
    at.level_begin = at.run_index + (pages + 1) * 8;
    at.runs = at.level_begin + (levels + 1) * 8;
    return at;
  }
};

// One attribute: its name (NUL-padded), kind, offset and range; the values
// of one that is not constant are in the pages, in the records' order.
struct AttributeRecord {
  char name[kMaxAttributeName + 1];
  std::uint32_t kind;
  std::uint32_t flags;  // bit 0: constant (no values; `constant` at every node)
  double min, max;      // the file's values
  double offset;
  float constant;
  std::uint32_t reserved;
  std::uint64_t reserved2;
};
static_assert(std::is_trivially_copyable_v<AttributeRecord> && sizeof(AttributeRecord) == 96);
inline constexpr std::uint32_t kMaxNotesBytes = 65536;

inline std::uint64_t align_up(std::uint64_t x) {
  return (x + kAlign - 1) / kAlign * kAlign;
}

// Four independent multiply-rotate lanes over 8-byte words (bandwidth-bound,
// several GB/s), folded together with the length. Streaming, so the writer
// never holds a second copy of the arrays.
class Checksum {
 public:
  void update(const unsigned char* data, std::size_t size) {
    if (size == 0) return;
    size_ += size;
    if (fill_) {
      const std::size_t take = std::min(size, sizeof block_ - fill_);
      std::memcpy(block_ + fill_, data, take);
      fill_ += take, data += take, size -= take;
      if (fill_ < sizeof block_) return;
      mix(block_);
      fill_ = 0;
    }
    for (; size >= sizeof block_; data += sizeof block_, size -= sizeof block_) mix(data);
    std::memcpy(block_, data, size);
    fill_ = size;
  }
  [[nodiscard]] std::uint64_t finish() const {
    std::uint64_t h = static_cast<std::uint64_t>(size_) * P1;
    for (auto v : lane_) h = std::rotl(h ^ (v * P2), 27) * P1 + P2;
    for (std::size_t i = 0; i < fill_; ++i) h = std::rotl(h ^ (block_[i] * P1), 11) * P2;
    h ^= h >> 33;
    h *= P2;
    return h ^ (h >> 29);
  }

 private:
  static constexpr std::uint64_t P1 = 0x9e3779b185ebca87ull, P2 = 0xc2b2ae3d27d4eb4full;
  void mix(const unsigned char* b) {
    for (int l = 0; l < 4; ++l) {
      std::uint64_t w;
      std::memcpy(&w, b + 8 * l, 8);
      lane_[l] = std::rotl(lane_[l] ^ (w * P2), 31) * P1;
    }
  }
  std::uint64_t lane_[4] = {P1, P2, P1 ^ P2, ~P1};
  unsigned char block_[32] = {};
  std::size_t fill_ = 0;
  std::uint64_t size_ = 0;
};

}  // namespace treecut::cache_layout
