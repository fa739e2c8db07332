// The layout of a hierarchy cache file (cache.cpp reads it, cache_write.cpp
// writes it): one header, the level table and the node arrays, each 64-byte
// aligned so the loader can hand out spans straight into the bytes it read,
// the coordinate system's text, the attribute records and their values, the
// first read's notes, and a trailing 64-bit checksum of everything before
// it. Private to the library.
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
// Bump whenever the layout or the meaning of any array changes.
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
inline constexpr std::uint32_t kVersion = 7;
inline constexpr std::uint32_t kEndianTag = 0x01020304u;
inline constexpr std::size_t kAlign = 64;
inline constexpr int kArrays = 10;
inline constexpr std::uint32_t kMaxCrsBytes = 4096;

struct Header {
  char magic[8];
  std::uint32_t version;
  std::uint32_t endian_tag;
  std::uint32_t header_size;
  std::uint32_t node_count;
  std::uint32_t level_count;
  std::uint32_t options_bits;
  std::uint64_t source_size;
  std::int64_t source_mtime_ns;
  std::uint64_t source_hash;  // XXH3-64 of the source file's bytes
  std::uint64_t source_device;
  std::uint64_t source_inode;
  std::int64_t source_ctime_ns;
  std::int64_t identity_ns;  // CLOCK_REALTIME when the identity was taken
  float bounds[6];
  double origin[3];                // Hierarchy::frame(): origin,
  std::uint32_t flags;             // bit 0: z_up, bit 1: normals_estimated,
  std::uint32_t crs_size;          // and the crs text's bytes
  std::uint64_t crs_offset;        // where they are (after the arrays)
  std::uint64_t level_table;       // offset of level_count + 1 NodeIds
  std::uint64_t offsets[kArrays];  // in HierarchyArrays member order
  std::uint64_t payload_end;       // checksum follows, file size = payload_end + 8
  std::uint32_t attribute_count;   // Hierarchy::attributes(), at most kMaxAttributes,
  std::uint32_t notes_size;        // the notes' bytes (format, then warnings, a line each),
  std::uint64_t attribute_table;   // where their AttributeRecords are
  std::uint64_t notes_offset;      // and where the notes are
  double viewpoint[7];             // frame().viewpoint when flags bit 2: x y z, w x y z
};
static_assert(std::is_trivially_copyable_v<Header>);

// One attribute: its name (NUL-padded), kind, offset, range and values.
struct AttributeRecord {
  char name[kMaxAttributeName + 1];
  std::uint32_t kind;
  std::uint32_t flags;  // bit 0: constant (no values; `constant` at every node)
  double min, max;      // the file's values
  double offset;
  float constant;
  std::uint32_t reserved;
  std::uint64_t values;  // offset of node_count floats (0 when constant)
};
static_assert(std::is_trivially_copyable_v<AttributeRecord> && sizeof(AttributeRecord) == 96);
inline constexpr std::uint32_t kMaxNotesBytes = 65536;

inline constexpr std::array<std::size_t, kArrays> kElementSize = {
    sizeof(glm::vec4),    sizeof(float),         sizeof(glm::i16vec4), sizeof(glm::u8vec4),
    sizeof(float),        sizeof(std::uint32_t), sizeof(NodeId),       sizeof(NodeId),
    sizeof(std::uint8_t), sizeof(std::uint8_t)};

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
