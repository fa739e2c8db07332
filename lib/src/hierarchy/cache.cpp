// Hierarchy cache files: one header, the node arrays (64-byte aligned, so the
// loader can hand out spans straight into the bytes it read), and a trailing
// 64-bit checksum. Every field is checked before any of it is used, so any
// truncation or flipped byte is reported, never rendered. Which cache serves
// which model (identity, content hash, the lookup) is cache_lookup.cpp's.
//
// A cache is read into this process's own memory, not mapped (issue 43,
// item 8): the links the loader verifies (children, parents, counts) are
// what every strategy indexes with, unchecked on the hot path, and a
// mapping shows whatever another program writes into the file afterwards
// (`dd conv=notrunc` into a cache being drawn crashed the strategies). Read
// once and verified once, the bytes cannot change under the renderer; the
// checksum pass touched every page anyway.
#include "treecut/cache.hpp"

#include <fcntl.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <stdexcept>
#include <tuple>

#include "cache_checksum.hpp"
#include "cache_format.hpp"
#include "treecut/error.hpp"
#include "treecut/file_io.hpp"

namespace treecut {

namespace {

constexpr char kMagic[8] = {'T', 'C', 'U', 'T', 'H', 'I', 'E', 'R'};
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
constexpr std::uint32_t kVersion = 7;
constexpr std::uint32_t kEndianTag = 0x01020304u;
constexpr std::size_t kAlign = 64;
constexpr int kArrays = 10;
constexpr std::uint32_t kMaxCrsBytes = 4096;

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
constexpr std::uint32_t kMaxNotesBytes = 65536;

CacheKey key_of(const Header& h) {
  return {h.source_size,   h.source_mtime_ns, h.options_bits,    h.source_hash,
          h.source_device, h.source_inode,    h.source_ctime_ns, h.identity_ns};
}

constexpr std::array<std::size_t, kArrays> kElementSize = {
    sizeof(glm::vec4),    sizeof(float),         sizeof(glm::i16vec4), sizeof(glm::u8vec4),
    sizeof(float),        sizeof(std::uint32_t), sizeof(NodeId),       sizeof(NodeId),
    sizeof(std::uint8_t), sizeof(std::uint8_t)};

std::uint64_t align_up(std::uint64_t x) {
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

std::uint64_t checksum(const unsigned char* data, std::size_t size) {
  Checksum c;
  c.update(data, size);
  return c.finish();
}

bool fail(std::string* why, std::string text) {
  if (why) *why = std::move(text);
  return false;
}

// Structural sanity of the links, O(nodes): what a reader relies on to never
// index out of bounds. (Geometric invariants are the builder's business and
// are covered by the checksum.)
// Returns what is wrong, or nullptr.
const char* link_problem(const HierarchyArrays& a, std::span<const NodeId> levels) {
  const std::size_t n = a.center_radius.size();
  if (levels.size() < 2 || levels.front() != 0 || levels.back() != n)
    return "level table does not span the nodes";
  for (std::size_t d = 0; d + 1 < levels.size(); ++d)
    if (levels[d] >= levels[d + 1]) return "level table not increasing";
  if (a.parent[0] != kNoNode || a.depth[0] != 0) return "bad root";
  for (std::size_t d = 0; d + 1 < levels.size(); ++d) {
    std::uint64_t children = 0;  // of this level: must be the whole next level
    for (NodeId i = levels[d]; i < levels[d + 1]; ++i) {
      if (a.depth[i] != d) return "node depth disagrees with the level table";
      const unsigned cc = a.child_count[i];
      if (cc == 0) {
        if (a.point_count[i] != 1) return "leaf point count is not 1";
        continue;
      }
      const NodeId c0 = a.first_child[i];
      if (cc > 4 || c0 < levels[d + 1] || c0 > n || cc > n - c0 ||
          (d + 2 < levels.size() && c0 + cc > levels[d + 2]))
        return "child range out of bounds";
      std::uint64_t points = 0;
      for (NodeId c = c0; c < c0 + cc; ++c) {
        if (a.parent[c] != i) return "parent link broken";
        points += a.point_count[c];
      }
      // leaf_count() is the root's count and sizes allocations: every count
      // must be the sum of the children's, down to the leaves' 1.
      if (a.point_count[i] != points) return "point count is not the children's sum";
      children += cc;
    }
    // The parent links make the child ranges disjoint; covering the next
    // level as well leaves no node unreachable from the root.
    const std::uint64_t next = d + 2 < levels.size() ? levels[d + 2] - levels[d + 1] : 0;
    if (children != next) return "a node is nobody's child";
  }
  return nullptr;
}

// open_regular_file() without the exception: the reason as *why, without the
// path (the callers name it). Never blocks on a FIFO.
int open_for_reading(const std::filesystem::path& path, std::string* why) {
  const FileKind kind = file_kind(path);
  if (kind != FileKind::Regular && kind != FileKind::Missing)
    return fail(why, "is " + std::string(describe(kind)) + ", not a regular file"), -1;
  try {
    return open_regular_file(path);
  } catch (const InputError& e) {
    // "PATH: reason" -> "reason"
    const std::string text = e.what();
    const std::string prefix = quoted_name(path) + ": ";
    fail(why, text.rfind(prefix, 0) == 0 ? text.substr(prefix.size()) : text);
    return -1;
  }
}

// The model's CoordinateFrame (versions 4 and 7): a finite origin, known
// flags, a short coordinate-system text inside the payload, a finite
// viewpoint of unit orientation.
std::optional<CoordinateFrame> read_frame(const Header& h, const unsigned char* bytes,
                                          std::string* why) {
  for (const double o : h.origin) {
    if (!std::isfinite(o)) return fail(why, "the origin is not finite"), std::nullopt;
  }
  if ((h.flags & ~7u) != 0) return fail(why, "unknown flags"), std::nullopt;
  // The coordinate system's text: short (a WKT is cut to 400 bytes), inside.
  if (h.crs_size > kMaxCrsBytes ||
      (h.crs_size > 0 && (h.crs_offset < sizeof(Header) || h.crs_offset > h.payload_end ||
                          h.crs_size > h.payload_end - h.crs_offset)))
    return fail(why, "bad coordinate system record"), std::nullopt;
  CoordinateFrame frame;
  frame.origin = glm::dvec3(h.origin[0], h.origin[1], h.origin[2]);
  frame.z_up = (h.flags & 1u) != 0;
  frame.normals_estimated = (h.flags & 2u) != 0;
  if ((h.flags & 4u) != 0) {
    const double* v = h.viewpoint;
    for (int i = 0; i < 7; ++i) {
      if (!std::isfinite(v[i])) return fail(why, "the viewpoint is not finite"), std::nullopt;
    }
    const glm::dquat q(v[3], v[4], v[5], v[6]);
    if (!(std::fabs(glm::length(q) - 1.0) < 1e-6))
      return fail(why, "the viewpoint's rotation is not a unit quaternion"), std::nullopt;
    frame.viewpoint = Viewpoint{glm::dvec3(v[0], v[1], v[2]), q};
  }
  // (An empty text's offset may be anything: no pointer is made from it.)
  if (h.crs_size > 0)
    frame.crs.assign(reinterpret_cast<const char*>(bytes) + h.crs_offset, h.crs_size);
  return frame;
}

// The first read's notes (version 7): the format, then a warning a line.
std::optional<SourceNotes> read_notes(const Header& h, const unsigned char* bytes,
                                      std::string* why) {
  SourceNotes notes;
  if (h.notes_size == 0) return notes;
  if (h.notes_size > kMaxNotesBytes || h.notes_offset < sizeof(Header) ||
      h.notes_offset > h.payload_end || h.notes_size > h.payload_end - h.notes_offset)
    return fail(why, "bad notes record"), std::nullopt;
  const std::string text(reinterpret_cast<const char*>(bytes) + h.notes_offset, h.notes_size);
  std::size_t at = 0;
  const std::size_t end = std::min(text.find('\n'), text.size());
  notes.format = text.substr(0, end);
  at = end + 1;
  while (at < text.size()) {
    const std::size_t stop = std::min(text.find('\n', at), text.size());
    notes.warnings.push_back(text.substr(at, stop - at));
    at = stop + 1;
  }
  return notes;
}

// The attribute table (version 7): known kinds and flags, NUL-terminated
// names, a range that is ordered or NaN, values inside the payload.
template <class InBounds>
std::optional<std::vector<NodeAttribute>> read_attributes(const Header& h,
                                                          const unsigned char* bytes,
                                                          InBounds in_bounds, std::string* why) {
  std::vector<NodeAttribute> out;
  if (h.attribute_count == 0) return out;
  if (h.attribute_count > kMaxAttributes ||
      !in_bounds(h.attribute_table, std::uint64_t{h.attribute_count} * sizeof(AttributeRecord)))
    return fail(why, "attribute table out of bounds"), std::nullopt;
  std::vector<AttributeRecord> records(h.attribute_count);
  std::memcpy(records.data(), bytes + h.attribute_table, records.size() * sizeof(AttributeRecord));
  const std::size_t n = h.node_count;
  for (const AttributeRecord& r : records) {
    const bool range_ok = (std::isnan(r.min) && std::isnan(r.max)) ||
                          (std::isfinite(r.min) && std::isfinite(r.max) && r.min <= r.max);
    // A name as the readers make them: no control bytes (a forged cache's
    // escape sequence would reach the terminal through info and the HUD).
    const bool printable =
        std::none_of(r.name, r.name + strnlen(r.name, sizeof r.name),
                     [](char c) { return static_cast<unsigned char>(c) < 0x20 || c == 0x7f; });
    if (r.name[kMaxAttributeName] != '\0' || !printable || r.kind > 1 || (r.flags & ~1u) != 0 ||
        !range_ok || !std::isfinite(r.offset))
      return fail(why, "bad attribute record"), std::nullopt;
    NodeAttribute a{
        std::string(r.name), static_cast<AttributeKind>(r.kind), r.offset, r.min, r.max, {},
        r.constant};
    if ((r.flags & 1u) == 0) {
      if (!in_bounds(r.values, n * sizeof(float)))
        return fail(why, "attribute values out of bounds"), std::nullopt;
      a.values = {reinterpret_cast<const float*>(bytes + r.values), n};
    }
    out.push_back(std::move(a));
  }
  return out;
}

// A cache's bytes in anonymous pages of this process (see the top).
class CacheBytes {
 public:
  explicit CacheBytes(std::size_t size) : size_(size) {
    void* p = ::mmap(nullptr, size, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
    if (p == MAP_FAILED) throw std::bad_alloc();
    // Huge pages where the kernel gives them on request (THP "madvise", as on
    // Debian): a 400 MB cache is then ~200 page faults, not ~100,000, the
    // most of the time a read into fresh pages takes. Advice only: a kernel
    // without it reads the same bytes into small pages.
    (void)::madvise(p, size, MADV_HUGEPAGE);
    data_ = static_cast<unsigned char*>(p);
  }
  CacheBytes(const CacheBytes&) = delete;
  CacheBytes& operator=(const CacheBytes&) = delete;
  ~CacheBytes() { ::munmap(data_, size_); }
  [[nodiscard]] unsigned char* data() const { return data_; }

 private:
  unsigned char* data_;
  std::size_t size_;
};

// Reads the SIZE bytes an fstat saw of the file open as FD, and into SUM the
// checksum of all but the last 8 (the stored one). A piece at a time, each
// summed while it is still in the CPU's cache: one pass over memory, not
// two. A file that got shorter meanwhile is a FileChangedError, as for a
// model.
std::shared_ptr<CacheBytes> read_bytes(int fd, std::uint64_t size,
                                       const std::filesystem::path& path, std::uint64_t* sum) {
  auto bytes = std::make_shared<CacheBytes>(static_cast<std::size_t>(size));
  constexpr std::uint64_t kPiece = 1 << 20;
  Checksum checksum;
  std::uint64_t at = 0;
  while (at < size) {
    const std::size_t want = static_cast<std::size_t>(std::min(size - at, kPiece));
    const ssize_t got = ::pread(fd, bytes->data() + at, want, static_cast<off_t>(at));
    if (got < 0 && errno == EINTR) continue;
    if (got < 0) throw std::runtime_error(system_error_text(path, errno));
    if (got == 0) {
      throw FileChangedError(quoted_name(path) + ": changed while being read (it got shorter)");
    }
    const std::uint64_t end = at + static_cast<std::uint64_t>(got);
    const std::uint64_t summed_end = std::min(end, size - 8);
    if (summed_end > at) checksum.update(bytes->data() + at, summed_end - at);
    at = end;
  }
  *sum = checksum.finish();
  return bytes;
}

std::optional<Hierarchy> read_and_verify(const std::filesystem::path& path, Header* out_header,
                                         std::string* why) {
  const int fd = open_for_reading(path, why);
  if (fd < 0) return std::nullopt;
  struct Close {
    int fd;
    ~Close() { ::close(fd); }
  } closer{fd};
  struct stat st {};
  if (fstat(fd, &st) != 0) return fail(why, std::strerror(errno)), std::nullopt;
  const auto size = static_cast<std::uint64_t>(st.st_size);
  if (size < sizeof(Header) + 8)
    return fail(why, "truncated (shorter than a header)"), std::nullopt;
  Header h;
  if (::pread(fd, &h, sizeof h, 0) != static_cast<ssize_t>(sizeof h))
    return fail(why, "truncated (shorter than a header)"), std::nullopt;
  if (std::memcmp(h.magic, kMagic, sizeof kMagic) != 0)
    return fail(why, "not a treecut cache"), std::nullopt;
  if (h.version != kVersion)
    return fail(why, "cache format version " + std::to_string(h.version) + ", expected " +
                         std::to_string(kVersion)),
           std::nullopt;
  if (h.endian_tag != kEndianTag)
    return fail(why, "written on a machine of other endianness"), std::nullopt;
  if (h.header_size != sizeof(Header)) return fail(why, "header size mismatch"), std::nullopt;
  if (h.payload_end != size - 8)
    return fail(why, "truncated or extended (size mismatch)"), std::nullopt;
  std::shared_ptr<CacheBytes> storage;
  std::uint64_t sum = 0;
  try {
    storage = read_bytes(fd, size, path, &sum);
  } catch (const std::bad_alloc&) {
    return fail(why, "not enough memory to read it (" + std::to_string(size >> 20) + " MiB)"),
           std::nullopt;
  }
  const unsigned char* bytes = storage->data();
  std::memcpy(&h, bytes, sizeof h);
  std::uint64_t stored;
  std::memcpy(&stored, bytes + size - 8, 8);
  if (h.payload_end != size - 8 || sum != stored)
    return fail(why, "checksum mismatch (corrupted)"), std::nullopt;

  // The checksum only proves the file is what some writer wrote; still check
  // every offset before building spans.
  const std::uint64_t n = h.node_count;
  if (n == 0 || h.level_count == 0 || h.level_count > 256)
    return fail(why, "bad counts"), std::nullopt;
  std::optional<CoordinateFrame> frame = read_frame(h, bytes, why);
  if (!frame) return std::nullopt;
  std::optional<SourceNotes> notes = read_notes(h, bytes, why);
  if (!notes) return std::nullopt;
  auto in_bounds = [&](std::uint64_t off, std::uint64_t bytes_needed) {
    return off % kAlign == 0 && off >= sizeof(Header) && off <= h.payload_end &&
           bytes_needed <= h.payload_end - off;
  };
  if (!in_bounds(h.level_table, (h.level_count + 1) * sizeof(NodeId)))
    return fail(why, "level table out of bounds"), std::nullopt;
  for (int i = 0; i < kArrays; ++i)
    if (!in_bounds(h.offsets[i], n * kElementSize[static_cast<std::size_t>(i)]))
      return fail(why, "array out of bounds"), std::nullopt;
  auto at = [&](int i) { return bytes + h.offsets[i]; };
  const std::size_t nn = static_cast<std::size_t>(n);
  HierarchyArrays a{{reinterpret_cast<const glm::vec4*>(at(0)), nn},
                    {reinterpret_cast<const float*>(at(1)), nn},
                    {reinterpret_cast<const glm::i16vec4*>(at(2)), nn},
                    {reinterpret_cast<const glm::u8vec4*>(at(3)), nn},
                    {reinterpret_cast<const float*>(at(4)), nn},
                    {reinterpret_cast<const std::uint32_t*>(at(5)), nn},
                    {reinterpret_cast<const NodeId*>(at(6)), nn},
                    {reinterpret_cast<const NodeId*>(at(7)), nn},
                    {reinterpret_cast<const std::uint8_t*>(at(8)), nn},
                    {reinterpret_cast<const std::uint8_t*>(at(9)), nn}};
  std::optional<std::vector<NodeAttribute>> attributes = read_attributes(
      h, bytes,
      [&](std::uint64_t off, std::uint64_t bytes_needed) { return in_bounds(off, bytes_needed); },
      why);
  if (!attributes) return std::nullopt;
  std::vector<NodeId> levels(h.level_count + 1);
  std::memcpy(levels.data(), bytes + h.level_table, levels.size() * sizeof(NodeId));
  if (const char* problem = link_problem(a, levels)) return fail(why, problem), std::nullopt;
  if (out_header) *out_header = h;
  return Hierarchy::from_arrays(
             std::move(storage), a, std::move(levels), {h.bounds[0], h.bounds[1], h.bounds[2]},
             {h.bounds[3], h.bounds[4], h.bounds[5]}, std::move(*frame), std::move(*attributes))
      .with_notes(std::move(*notes));
}

// The header of CACHE as it is on disk, unverified (the checksum is checked
// by map_and_verify before anything is served): only to decide whether the
// content hash can be skipped. Never blocks.
bool peek_header(const std::filesystem::path& cache, Header* h) {
  const int fd = open_for_reading(cache, nullptr);
  if (fd < 0) return false;
  std::size_t got = 0;
  auto* bytes = reinterpret_cast<unsigned char*>(h);
  while (got < sizeof *h) {
    const ssize_t n = ::read(fd, bytes + got, sizeof *h - got);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) break;
    got += static_cast<std::size_t>(n);
  }
  ::close(fd);
  return got == sizeof *h && std::memcmp(h->magic, kMagic, sizeof kMagic) == 0 &&
         h->version == kVersion && h->endian_tag == kEndianTag && h->header_size == sizeof *h;
}

}  // namespace

std::optional<CacheKey> detail::peek_cache_key(const std::filesystem::path& cache) {
  Header h{};
  if (!peek_header(cache, &h)) return std::nullopt;
  return key_of(h);
}

bool looks_like_cache(const std::filesystem::path& path) {
  return file_starts_with(path, std::string_view(kMagic, sizeof kMagic));
}

bool is_own_cache(const std::filesystem::path& path) {
  const FileHead head = read_file_head(path, sizeof(Header));
  if (!head.regular || head.bytes.size() < 20) return false;
  const auto* b = reinterpret_cast<const unsigned char*>(head.bytes.data());
  std::uint32_t version, endian, header_size;
  std::memcpy(&version, b + 8, 4), std::memcpy(&endian, b + 12, 4);
  std::memcpy(&header_size, b + 16, 4);
  if (std::memcmp(b, kMagic, sizeof kMagic) != 0 || endian != kEndianTag) return false;
  // Where the header says the payload ends, and its own size, in the two
  // layouts whose headers can be verified: this one, and version 6's (264
  // bytes, the payload's end at byte 240) that the builds before issue 43
  // wrote. Older caches are not told apart from a user's file.
  std::uint64_t payload_end = 0;
  if (version == kVersion && header_size == sizeof(Header) && head.bytes.size() >= sizeof(Header)) {
    Header h;
    std::memcpy(&h, b, sizeof h);
    payload_end = h.payload_end;
  } else if (version == 6 && header_size == 264 && head.bytes.size() >= 248) {
    std::memcpy(&payload_end, b + 240, 8);
  } else {
    return false;
  }
  return payload_end >= header_size && payload_end + 8 == head.size;
}

namespace {

// The header's fields that say what the cache is of: the key, the bounds,
// the coordinate frame (the offsets are laid out by save_cache).
Header header_of(const Hierarchy& hier, const CacheKey& key) {
  Header h{};
  std::memcpy(h.magic, kMagic, sizeof kMagic);
  h.version = kVersion;
  h.endian_tag = kEndianTag;
  h.header_size = sizeof(Header);
  h.node_count = hier.node_count();
  h.level_count = static_cast<std::uint32_t>(hier.level_count());
  h.options_bits = key.options_bits;
  h.source_size = key.source_size;
  h.source_mtime_ns = key.source_mtime_ns;
  h.source_hash = key.content_hash;
  h.source_device = key.source_device;
  h.source_inode = key.source_inode;
  h.source_ctime_ns = key.source_ctime_ns;
  h.identity_ns = key.identity_ns;
  const glm::vec3 lo = hier.bounds_min(), hi = hier.bounds_max();
  const float b[6] = {lo.x, lo.y, lo.z, hi.x, hi.y, hi.z};
  std::memcpy(h.bounds, b, sizeof b);
  const CoordinateFrame& frame = hier.frame();
  h.origin[0] = frame.origin.x, h.origin[1] = frame.origin.y, h.origin[2] = frame.origin.z;
  h.flags =
      (frame.z_up ? 1u : 0u) | (frame.normals_estimated ? 2u : 0u) | (frame.viewpoint ? 4u : 0u);
  if (frame.viewpoint) {
    const Viewpoint& v = *frame.viewpoint;
    const double pose[7] = {v.position.x,    v.position.y,    v.position.z,   v.orientation.w,
                            v.orientation.x, v.orientation.y, v.orientation.z};
    std::memcpy(h.viewpoint, pose, sizeof pose);
  }
  return h;
}

// The first read's notes as the cache holds them: the format, then a
// warning a line, cut at a whole line to what a header can vouch for.
std::string notes_text(const SourceNotes& source) {
  std::string notes = source.format.substr(0, 4096);
  for (const std::string& w : source.warnings) {
    const std::string line = "\n" + w.substr(0, 4096);
    if (notes.size() + line.size() > kMaxNotesBytes) break;
    notes += line;
  }
  for (char& c : notes) {
    if (c == '\0') c = '?';
  }
  return notes;
}

// The attribute table, laid out from OFF on (advanced past the values).
std::vector<AttributeRecord> attribute_records(const std::vector<NodeAttribute>& attributes,
                                               std::uint64_t& off) {
  if (attributes.size() > kMaxAttributes)
    throw std::invalid_argument("save_cache: more than " + std::to_string(kMaxAttributes) +
                                " attributes");
  std::vector<AttributeRecord> records(attributes.size());
  for (std::size_t k = 0; k < attributes.size(); ++k) {
    const NodeAttribute& attribute = attributes[k];
    AttributeRecord& r = records[k];
    std::memset(&r, 0, sizeof r);
    std::memcpy(r.name, attribute.name.data(), std::min(attribute.name.size(), kMaxAttributeName));
    r.kind = static_cast<std::uint32_t>(attribute.kind);
    r.flags = attribute.is_constant() ? 1u : 0u;
    r.min = attribute.min, r.max = attribute.max, r.offset = attribute.offset;
    r.constant = attribute.constant;
    r.values = attribute.is_constant() ? 0 : off;
    off = align_up(off + attribute.values.size_bytes());
  }
  return records;
}

// Writes PIECES (data, size, offset; in increasing offsets) as the file
// CACHE, zero padding between them, then the checksum: through an
// AtomicFile (temporary + rename), so readers see the old file or the
// complete new one, and a failed write (full disk, read-only folder) leaves
// no file.
void write_pieces(const std::filesystem::path& cache,
                  const std::vector<std::tuple<const void*, std::size_t, std::uint64_t>>& pieces) {
  if (cache.has_parent_path()) {
    std::error_code ec;
    std::filesystem::create_directories(cache.parent_path(), ec);
    if (ec) throw std::runtime_error(system_error_text(cache.parent_path(), ec.value()));
  }
  AtomicFile out(cache);
  Checksum sum;
  std::uint64_t at = 0;
  const unsigned char zeros[kAlign] = {};
  for (const auto& [data, size, offset] : pieces) {
    while (at < offset) {  // alignment padding
      const auto pad = static_cast<std::size_t>(std::min<std::uint64_t>(offset - at, kAlign));
      out.write(zeros, pad);
      sum.update(zeros, pad);
      at += pad;
    }
    if (size == 0) continue;
    out.write(data, size);
    sum.update(static_cast<const unsigned char*>(data), size);
    at += size;
  }
  const std::uint64_t digest = sum.finish();
  out.write(&digest, sizeof digest);
  out.commit();
}

}  // namespace

void save_cache(const Hierarchy& hier, const CacheKey& key, const std::filesystem::path& cache) {
  const auto& a = hier.arrays();
  Header h = header_of(hier, key);
  const std::string crs = hier.frame().crs.substr(0, kMaxCrsBytes);
  h.crs_size = static_cast<std::uint32_t>(crs.size());
  const std::array<std::pair<const void*, std::size_t>, kArrays> arrays = {{
      {a.center_radius.data(), a.center_radius.size_bytes()},
      {a.splat_radius.data(), a.splat_radius.size_bytes()},
      {a.normal_cone.data(), a.normal_cone.size_bytes()},
      {a.color.data(), a.color.size_bytes()},
      {a.priority.data(), a.priority.size_bytes()},
      {a.point_count.data(), a.point_count.size_bytes()},
      {a.parent.data(), a.parent.size_bytes()},
      {a.first_child.data(), a.first_child.size_bytes()},
      {a.child_count.data(), a.child_count.size_bytes()},
      {a.depth.data(), a.depth.size_bytes()},
  }};
  std::vector<NodeId> levels;
  for (int d = 0; d <= hier.level_count(); ++d) levels.push_back(hier.level_begin(d));
  // The layout: each piece 64-byte aligned after the header.
  std::uint64_t off = align_up(sizeof(Header));
  h.level_table = off;
  off = align_up(off + levels.size() * sizeof(NodeId));
  for (int i = 0; i < kArrays; ++i) {
    h.offsets[i] = off;
    off = align_up(off + arrays[static_cast<std::size_t>(i)].second);
  }
  h.crs_offset = crs.empty() ? 0 : off;
  off = align_up(off + crs.size());
  const std::vector<NodeAttribute>& attributes = hier.attributes();
  h.attribute_count = static_cast<std::uint32_t>(attributes.size());
  h.attribute_table = attributes.empty() ? 0 : off;
  off = align_up(off + attributes.size() * sizeof(AttributeRecord));
  const std::vector<AttributeRecord> records = attribute_records(attributes, off);
  const std::string notes = notes_text(hier.notes());
  h.notes_size = static_cast<std::uint32_t>(notes.size());
  h.notes_offset = notes.empty() ? 0 : off;
  h.payload_end = align_up(off + notes.size());

  std::vector<std::tuple<const void*, std::size_t, std::uint64_t>> pieces = {
      {&h, sizeof h, 0}, {levels.data(), levels.size() * sizeof(NodeId), h.level_table}};
  for (int i = 0; i < kArrays; ++i)
    pieces.emplace_back(arrays[static_cast<std::size_t>(i)].first,
                        arrays[static_cast<std::size_t>(i)].second, h.offsets[i]);
  pieces.emplace_back(crs.data(), crs.size(), h.crs_offset);
  pieces.emplace_back(records.data(), records.size() * sizeof(AttributeRecord), h.attribute_table);
  for (std::size_t k = 0; k < records.size(); ++k)
    pieces.emplace_back(attributes[k].values.data(), attributes[k].values.size_bytes(),
                        records[k].values);
  pieces.emplace_back(notes.data(), notes.size(), h.notes_offset);
  pieces.emplace_back(nullptr, 0, h.payload_end);
  write_pieces(cache, pieces);
}

std::optional<Hierarchy> load_cache(const std::filesystem::path& cache,
                                    const std::optional<CacheKey>& expected, std::string* why) {
  Header h;
  auto hier = read_and_verify(cache, &h, why);
  if (!hier) return std::nullopt;
  if (expected && !cache_key_matches(key_of(h), *expected))
    return fail(why, "stale (the model or the build options changed)"), std::nullopt;
  return hier;
}

std::optional<Hierarchy> load_cache_and_key(const std::filesystem::path& cache, CacheKey* stored,
                                            std::string* why) {
  Header h;
  auto hier = read_and_verify(cache, &h, why);
  if (hier && stored) *stored = key_of(h);
  return hier;
}

std::optional<CacheKey> read_cache_key(const std::filesystem::path& cache, std::string* why) {
  Header h;
  if (!read_and_verify(cache, &h, why)) return std::nullopt;
  return key_of(h);
}

std::uint64_t detail::cache_checksum(const unsigned char* data, std::size_t size) {
  return checksum(data, size);
}

}  // namespace treecut
