// Reading hierarchy cache files (the layout is cache_layout.hpp's, the writer
// cache_write.cpp, the pages cache_page_decode.cpp's). Every field is
// checked before any of it is used, so any truncation or flipped byte is
// reported, never rendered. Which cache serves which model (identity,
// content hash, the lookup) is cache_lookup.cpp's.
//
// A cache is read into this process's own memory, not mapped (issue 43,
// item 8): the links the loader verifies (children, parents, counts) are
// what every strategy indexes with, unchecked on the hot path, and a
// mapping shows whatever another program writes into the file afterwards
// (`dd conv=notrunc` into a cache being drawn crashed the strategies). The
// header and the meta part are read whole, the pages one at a time as they
// are decoded, each verified when read: the decoded arrays cannot change
// under the renderer.
#include "treecut/cache.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <memory>
#include <stdexcept>

#include "cache_checksum.hpp"
#include "cache_format.hpp"
#include "cache_layout.hpp"
#include "cache_pages.hpp"
#include "treecut/error.hpp"
#include "treecut/file_io.hpp"

namespace treecut {

using namespace cache_layout;

namespace {

CacheKey key_of(const Header& h) {
  return {h.source_size,   h.source_mtime_ns, h.options_bits,    h.source_hash,
          h.source_device, h.source_inode,    h.source_ctime_ns, h.identity_ns};
}

bool fail(std::string* why, std::string text) {
  if (why) *why = std::move(text);
  return false;
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
      (h.crs_size > 0 && (h.crs_offset < sizeof(Header) || h.crs_offset > h.meta_end ||
                          h.crs_size > h.meta_end - h.crs_offset)))
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
      h.notes_offset > h.meta_end || h.notes_size > h.meta_end - h.notes_offset)
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

// The attribute table: known kinds and flags, NUL-terminated names, a range
// that is ordered or NaN; the values of those not constant are the pages'
// (VALUES, in the records' order, checked for their number by the pages).
template <class InBounds>
std::optional<std::vector<NodeAttribute>> read_attributes(const Header& h,
                                                          const unsigned char* bytes,
                                                          InBounds in_bounds,
                                                          std::vector<bool>& varying,
                                                          std::string* why) {
  std::vector<NodeAttribute> out;
  if (h.attribute_count == 0) return out;
  if (h.attribute_count > kMaxAttributes ||
      !in_bounds(h.attribute_table, std::uint64_t{h.attribute_count} * sizeof(AttributeRecord)))
    return fail(why, "attribute table out of bounds"), std::nullopt;
  std::vector<AttributeRecord> records(h.attribute_count);
  std::memcpy(records.data(), bytes + h.attribute_table, records.size() * sizeof(AttributeRecord));
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
    out.push_back({std::string(r.name),
                   static_cast<AttributeKind>(r.kind),
                   r.offset,
                   r.min,
                   r.max,
                   {},
                   r.constant});
    varying.push_back((r.flags & 1u) == 0);
  }
  return out;
}

// The header's own checks: magic, version, byte order, size.
bool header_problem(const Header& h, std::string* why) {
  if (std::memcmp(h.magic, kMagic, sizeof kMagic) != 0) return !fail(why, "not a treecut cache");
  if (h.version != kVersion)
    return !fail(why, "cache format version " + std::to_string(h.version) + ", expected " +
                          std::to_string(kVersion));
  if (h.endian_tag != kEndianTag) return !fail(why, "written on a machine of other endianness");
  if (h.header_size != sizeof(Header)) return !fail(why, "header size mismatch");
  return false;
}

// The header's word on where its parts are, against the file's SIZE.
bool meta_in_place(const Header& h, std::uint64_t size, std::string* why) {
  if (header_problem(h, why)) return false;
  if (h.payload_end != size - 8) return fail(why, "truncated or extended (size mismatch)");
  if (h.meta_end < sizeof(Header) || h.meta_end > h.payload_end) return fail(why, "bad meta part");
  return true;
}

// The pages' links (PageLinksAt), after the page table (whose place the
// caller checked), each part inside the meta part.
std::optional<cache_pages::PageLinks> read_links(const Header& h, const unsigned char* bytes,
                                                 std::string* why) {
  const PageLinksAt at = PageLinksAt::after(h.page_table, h.page_count, h.level_count);
  if (at.runs > h.meta_end) return fail(why, "page links out of bounds"), std::nullopt;
  cache_pages::PageLinks links;
  auto read = [&](auto& v, std::uint64_t from, std::uint64_t count) {
    v.resize(static_cast<std::size_t>(count));
    if (count != 0) std::memcpy(v.data(), bytes + from, v.size() * sizeof v[0]);  // (no runs: null)
  };
  read(links.points, at.points, h.page_count);
  read(links.run_index, at.run_index, h.page_count + 1);
  read(links.level_begin, at.level_begin, std::uint64_t{h.level_count} + 1);
  const std::uint64_t runs = links.run_index.back();
  if (runs > (h.meta_end - at.runs) / sizeof(PageRun))
    return fail(why, "page links out of bounds"), std::nullopt;
  read(links.runs, at.runs, runs);
  return links;
}

// What a cache's meta part says, verified (read_meta).
struct Meta {
  Header header;
  CoordinateFrame frame;
  SourceNotes notes;
  std::vector<NodeAttribute> attributes;  // the varying ones' values are the pages'
  std::vector<bool> varying;
  std::optional<cache_pages::PageIndex> index;
};

// The meta part (at least H.meta_end bytes at META), verified by its
// checksum STORED, and everything in it checked before it is used.
std::optional<Meta> read_meta(const unsigned char* meta, std::uint64_t stored, std::string* why) {
  Meta m;
  Header& h = m.header;
  std::memcpy(&h, meta, sizeof h);
  const unsigned char* bytes = meta;
  if (detail::cache_checksum(bytes, h.meta_end) != stored)
    return fail(why, "checksum mismatch (corrupted)"), std::nullopt;

  // The checksum only proves the meta part is what some writer wrote; still
  // check every offset before anything is read at it.
  if (h.node_count == 0 || h.level_count == 0 || h.level_count > 256 || h.page_count == 0 ||
      h.page_count > h.node_count)
    return fail(why, "bad counts"), std::nullopt;
  auto in_meta = [&](std::uint64_t off, std::uint64_t bytes_needed) {
    return off >= sizeof(Header) && off <= h.meta_end && bytes_needed <= h.meta_end - off;
  };
  if (h.page_count > h.meta_end / sizeof(PageRecord) ||
      !in_meta(h.page_table, h.page_count * sizeof(PageRecord)))
    return fail(why, "page table out of bounds"), std::nullopt;
  std::optional<CoordinateFrame> frame = read_frame(h, bytes, why);
  if (!frame) return std::nullopt;
  m.frame = std::move(*frame);
  std::optional<SourceNotes> notes = read_notes(h, bytes, why);
  if (!notes) return std::nullopt;
  m.notes = std::move(*notes);
  std::optional<std::vector<NodeAttribute>> attributes =
      read_attributes(h, bytes, in_meta, m.varying, why);
  if (!attributes) return std::nullopt;
  m.attributes = std::move(*attributes);
  std::vector<PageRecord> table(static_cast<std::size_t>(h.page_count));
  std::memcpy(table.data(), bytes + h.page_table, table.size() * sizeof(PageRecord));
  std::optional<cache_pages::PageLinks> links = read_links(h, bytes, why);
  if (!links) return std::nullopt;
  // The pages tile the rest of the file, in order, with no byte outside one.
  std::uint64_t at = h.meta_end;
  for (std::size_t p = 0; p < table.size(); ++p) {
    if (table[p].offset != at || table[p].bytes == 0 || table[p].bytes > h.payload_end - at)
      return fail(why, "page " + std::to_string(p) + " of " + std::to_string(table.size()) +
                           ": out of place"),
             std::nullopt;
    at += table[p].bytes;
  }
  if (at != h.payload_end) return fail(why, "bytes after the last page"), std::nullopt;
  const auto streams =
      static_cast<std::uint32_t>(std::count(m.varying.begin(), m.varying.end(), true));
  m.index = cache_pages::PageIndex::make(std::move(table), std::move(*links), h.node_count,
                                         h.level_count, streams, why);
  if (!m.index) return std::nullopt;
  return m;
}

// The meta part verified (read_meta), and the pages read through SOURCE.
std::optional<Hierarchy> decode_cache(const unsigned char* meta, std::uint64_t stored,
                                      const cache_pages::PageSource& source, CacheKey* key,
                                      std::string* why) {
  std::optional<Meta> m = read_meta(meta, stored, why);
  if (!m) return std::nullopt;
  const Header& h = m->header;
  std::optional<cache_pages::Decoded> nodes = cache_pages::decode(*m->index, source, why);
  if (!nodes) return std::nullopt;
  if (nodes->arrays.point_count[0] != h.point_count)
    return fail(why, "point count disagrees with the pages"), std::nullopt;
  for (std::size_t k = 0, s = 0; k < m->attributes.size(); ++k)
    if (m->varying[k]) m->attributes[k].values = nodes->attribute_values[s++];
  if (key) *key = key_of(h);
  return Hierarchy::from_arrays(
             std::move(nodes->storage), nodes->arrays, std::move(nodes->level_begin),
             {h.bounds[0], h.bounds[1], h.bounds[2]}, {h.bounds[3], h.bounds[4], h.bounds[5]},
             std::move(m->frame), std::move(m->attributes))
      .with_notes(std::move(m->notes));
}

// A cache file open, its header and meta part read and in place (not yet
// checksummed).
// A cache's header, its meta part [0, meta_end) and the meta part's
// checksum as stored, read from a file or a URL.
struct MetaPart {
  Header header{};
  std::vector<unsigned char> meta;
  std::uint64_t stored = 0;
};

bool read_meta_part(const detail::ByteSource& source, MetaPart& c, std::string* why) {
  const std::uint64_t size = source.size();
  Header& h = c.header;
  if (size < sizeof(Header) + 8) return fail(why, "truncated (shorter than a header)");
  source.read(0, &h, sizeof h);
  if (!meta_in_place(h, size, why)) return false;
  try {
    c.meta.resize(static_cast<std::size_t>(h.meta_end));
  } catch (const std::bad_alloc&) {
    return fail(why, "not enough memory to read it (" + std::to_string(h.meta_end >> 20) + " MiB)");
  }
  source.read(0, c.meta.data(), c.meta.size());
  source.read(h.payload_end, &c.stored, 8);
  return true;
}

// A file open as FD as a source (read_exactly's messages name PATH).
class DescriptorSource final : public detail::ByteSource {
 public:
  DescriptorSource(int fd, std::uint64_t size, const std::filesystem::path& path)
      : fd_(fd), size_(size), path_(path) {}
  [[nodiscard]] std::uint64_t size() const override { return size_; }
  void read(std::uint64_t at, void* out, std::size_t n) const override {
    detail::read_exactly(fd_, at, n, static_cast<unsigned char*>(out), path_);
  }

 private:
  int fd_;
  std::uint64_t size_;
  const std::filesystem::path& path_;
};

struct OpenCache : MetaPart {
  int fd = -1;
  OpenCache() = default;
  OpenCache(const OpenCache&) = delete;
  OpenCache& operator=(const OpenCache&) = delete;
  ~OpenCache() {
    if (fd >= 0) ::close(fd);
  }
};

bool open_cache(const std::filesystem::path& path, OpenCache& c, std::string* why) {
  c.fd = open_for_reading(path, why);
  if (c.fd < 0) return false;
  struct stat st {};
  if (fstat(c.fd, &st) != 0) return fail(why, std::strerror(errno));
  return read_meta_part(DescriptorSource(c.fd, static_cast<std::uint64_t>(st.st_size), path), c,
                        why);
}

// The header and the meta part are read whole; each page is read when it
// is decoded (twice: cache_pages::decode), so the file's bytes are never
// all in memory beside the nodes they decode to.
std::optional<Hierarchy> read_and_verify(const std::filesystem::path& path, CacheKey* key,
                                         std::string* why) {
  OpenCache c;
  if (!open_cache(path, c, why)) return std::nullopt;
  try {
    return decode_cache(
        c.meta.data(), c.stored,
        [&](const PageRecord& r, std::vector<unsigned char>& buffer) {
          buffer.resize(r.bytes);
          detail::read_exactly(c.fd, r.offset, r.bytes, buffer.data(), path);
          return static_cast<const unsigned char*>(buffer.data());
        },
        key, why);
  } catch (const FileChangedError& e) {  // a page rewritten between its two reads
    const std::string text = e.what();
    if (text.rfind(quoted_name(path), 0) == 0) throw;
    throw FileChangedError(quoted_name(path) + ": " + text);
  }
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
  // layouts whose headers can be verified: this one (paged caches, from
  // version 8), and version 7's (328 bytes, the payload's end at byte 240)
  // that the builds before the paged cache (issue 44) wrote. Older caches
  // are not told apart from a user's file.
  std::uint64_t payload_end = 0;
  if (version >= kFirstPagedVersion && version <= kVersion && header_size == sizeof(Header) &&
      head.bytes.size() >= sizeof(Header)) {
    Header h;
    std::memcpy(&h, b, sizeof h);
    payload_end = h.payload_end;
  } else if (version == 7 && header_size == kV7HeaderSize &&
             head.bytes.size() >= kV7PayloadEndAt + 8) {
    std::memcpy(&payload_end, b + kV7PayloadEndAt, 8);
  } else {
    return false;
  }
  return payload_end >= header_size && payload_end + 8 == head.size;
}

std::optional<Hierarchy> load_cache(const std::filesystem::path& cache,
                                    const std::optional<CacheKey>& expected, std::string* why) {
  CacheKey stored{};
  auto hier = read_and_verify(cache, &stored, why);
  if (!hier) return std::nullopt;
  if (expected && !cache_key_matches(stored, *expected))
    return fail(why, "stale (the model or the build options changed)"), std::nullopt;
  return hier;
}

std::optional<Hierarchy> load_cache_and_key(const std::filesystem::path& cache, CacheKey* stored,
                                            std::string* why) {
  return read_and_verify(cache, stored, why);
}

std::optional<std::vector<CachePage>> read_cache_pages(const std::filesystem::path& cache,
                                                       std::string* why) {
  OpenCache c;
  if (!open_cache(cache, c, why)) return std::nullopt;
  const Header& h = c.header;
  const std::vector<unsigned char>& meta = c.meta;
  if (detail::cache_checksum(meta.data(), meta.size()) != c.stored)
    return fail(why, "checksum mismatch (corrupted)"), std::nullopt;
  if (h.page_count == 0 || h.page_table < sizeof(Header) || h.page_table > h.meta_end ||
      h.page_count > (h.meta_end - h.page_table) / sizeof(PageRecord))
    return fail(why, "page table out of bounds"), std::nullopt;
  std::vector<CachePage> pages(static_cast<std::size_t>(h.page_count));
  for (std::size_t p = 0; p < pages.size(); ++p) {
    PageRecord r;
    std::memcpy(&r, meta.data() + h.page_table + p * sizeof r, sizeof r);
    pages[p] = {r.node_count,
                r.bytes,
                p == 0 ? 0 : r.parent_page,
                r.root_depth,
                {r.bounds[0], r.bounds[1], r.bounds[2]},
                {r.bounds[3], r.bounds[4], r.bounds[5]}};
  }
  return pages;
}

std::optional<detail::CacheOutline> detail::read_cache_outline(const ByteSource& source,
                                                               std::string* why) {
  MetaPart c;
  if (!read_meta_part(source, c, why)) return std::nullopt;
  std::optional<Meta> m = read_meta(c.meta.data(), c.stored, why);
  if (!m) return std::nullopt;
  const Header& h = m->header;
  return CacheOutline{std::move(*m->index),
                      std::move(m->frame),
                      std::move(m->notes),
                      std::move(m->attributes),
                      std::move(m->varying),
                      {h.bounds[0], h.bounds[1], h.bounds[2]},
                      {h.bounds[3], h.bounds[4], h.bounds[5]},
                      h.point_count};
}

std::optional<CacheKey> read_cache_key(const std::filesystem::path& cache, std::string* why) {
  CacheKey key{};
  if (!read_and_verify(cache, &key, why)) return std::nullopt;
  return key;
}

void detail::read_exactly(int fd, std::uint64_t at, std::size_t count, unsigned char* out,
                          const std::filesystem::path& path) {
  std::size_t done = 0;
  while (done < count) {
    const ssize_t got = ::pread(fd, out + done, count - done, static_cast<off_t>(at + done));
    if (got < 0 && errno == EINTR) continue;
    if (got < 0) throw std::runtime_error(system_error_text(path, errno));
    if (got == 0)
      throw FileChangedError(quoted_name(path) + ": changed while being read (it got shorter)");
    done += static_cast<std::size_t>(got);
  }
}

std::uint64_t detail::cache_checksum(const unsigned char* data, std::size_t size) {
  Checksum c;
  c.update(data, size);
  return c.finish();
}

bool detail::reseal_cache(unsigned char* data, std::size_t size) {
  Header h;
  if (size < sizeof h + 8) return false;
  std::memcpy(&h, data, sizeof h);
  const std::uint64_t meta = std::min<std::uint64_t>(h.meta_end, size - 8);
  if (h.page_table >= sizeof h && h.page_table <= meta &&
      h.page_count <= (meta - h.page_table) / sizeof(PageRecord)) {
    for (std::uint64_t p = 0; p < h.page_count; ++p) {
      PageRecord r;
      unsigned char* at = data + h.page_table + p * sizeof r;
      std::memcpy(&r, at, sizeof r);
      if (r.offset > size - 8 || r.bytes > size - 8 - r.offset) continue;
      r.checksum = cache_checksum(data + r.offset, r.bytes);
      std::memcpy(at, &r, sizeof r);
    }
  }
  const std::uint64_t sum = cache_checksum(data, meta);
  std::memcpy(data + size - 8, &sum, 8);
  return true;
}

}  // namespace treecut
