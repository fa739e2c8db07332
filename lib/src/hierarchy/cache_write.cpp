// Writing a hierarchy cache file (the layout is cache_layout.hpp's, the
// pages cache_pages.cpp's): the header and the tables, the pages after them,
// the meta part's checksum last; the whole image is made in memory (its
// pages are compressed: a fraction of the hierarchy) and written through a
// temporary renamed into place.
#include <algorithm>
#include <array>
#include <cstring>
#include <stdexcept>
#include <string>
#include <vector>

#include "cache_format.hpp"
#include "cache_layout.hpp"
#include "cache_pages.hpp"
#include "treecut/cache.hpp"
#include "treecut/file_io.hpp"

namespace treecut {

using namespace cache_layout;

namespace {

// The header's fields that say what the cache is of: the key, the bounds,
// the coordinate frame (the offsets are laid out by cache_meta).
Header header_of(const detail::CacheMeta& m) {
  const CacheKey& key = m.key;
  Header h{};
  std::memcpy(h.magic, kMagic, sizeof kMagic);
  h.version = kVersion;
  h.endian_tag = kEndianTag;
  h.header_size = sizeof(Header);
  h.node_count = m.node_count;
  h.point_count = m.point_count;
  h.level_count = m.level_count;
  h.options_bits = key.options_bits;
  h.source_size = key.source_size;
  h.source_mtime_ns = key.source_mtime_ns;
  h.source_hash = key.content_hash;
  h.source_device = key.source_device;
  h.source_inode = key.source_inode;
  h.source_ctime_ns = key.source_ctime_ns;
  h.identity_ns = key.identity_ns;
  const glm::vec3 lo = m.bounds_min, hi = m.bounds_max;
  const float b[6] = {lo.x, lo.y, lo.z, hi.x, hi.y, hi.z};
  std::memcpy(h.bounds, b, sizeof b);
  const CoordinateFrame& frame = m.frame;
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

// The attribute table (the values are in the pages).
std::vector<AttributeRecord> attribute_records(const std::vector<NodeAttribute>& attributes) {
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
  }
  return records;
}

}  // namespace

CacheImage::CacheImage(const Hierarchy& hier, const CacheKey& key) {
  make(hier, key, false);
}

CacheImage::CacheImage(Hierarchy&& hier, const CacheKey& key) : hierarchy_(std::move(hier)) {
  make(hierarchy_, key, true);
}

std::vector<unsigned char> detail::cache_meta(const CacheMeta& m, std::vector<PageRecord>& table,
                                              const cache_pages::PageLinks& links) {
  Header h = header_of(m);
  const std::string crs = m.frame.crs.substr(0, kMaxCrsBytes);
  const std::vector<AttributeRecord> records = attribute_records(m.attributes);
  const std::string notes = notes_text(m.notes);
  // The meta part: header, page table and links, crs text, attribute
  // records, notes.
  std::uint64_t off = align_up(sizeof(Header));
  h.page_count = table.size();
  h.page_table = off;
  const PageLinksAt links_at = PageLinksAt::after(h.page_table, table.size(), m.level_count);
  off = align_up(links_at.runs + links.runs.size() * sizeof(PageRun));
  h.crs_size = static_cast<std::uint32_t>(crs.size());
  h.crs_offset = crs.empty() ? 0 : off;
  off = align_up(off + crs.size());
  h.attribute_count = static_cast<std::uint32_t>(m.attributes.size());
  h.attribute_table = m.attributes.empty() ? 0 : off;
  off = align_up(off + records.size() * sizeof(AttributeRecord));
  h.notes_size = static_cast<std::uint32_t>(notes.size());
  h.notes_offset = notes.empty() ? 0 : off;
  h.meta_end = align_up(off + notes.size());
  off = h.meta_end;
  for (PageRecord& r : table) {
    r.offset = off;
    off += r.bytes;
  }
  h.payload_end = off;
  std::vector<unsigned char> meta(h.meta_end, 0);
  unsigned char* b = meta.data();
  std::memcpy(b, &h, sizeof h);
  std::memcpy(b + h.page_table, table.data(), table.size() * sizeof(PageRecord));
  if (links.points.size() != table.size() || links.run_index.size() != table.size() + 1 ||
      links.level_begin.size() != std::size_t{m.level_count} + 1)
    throw std::logic_error("cache_meta: the links do not match the page table");
  std::memcpy(b + links_at.points, links.points.data(), links.points.size() * 8);
  std::memcpy(b + links_at.run_index, links.run_index.data(), links.run_index.size() * 8);
  std::memcpy(b + links_at.level_begin, links.level_begin.data(), links.level_begin.size() * 8);
  std::memcpy(b + links_at.runs, links.runs.data(), links.runs.size() * sizeof(PageRun));
  if (!crs.empty()) std::memcpy(b + h.crs_offset, crs.data(), crs.size());
  if (!records.empty())
    std::memcpy(b + h.attribute_table, records.data(), records.size() * sizeof(AttributeRecord));
  if (!notes.empty()) std::memcpy(b + h.notes_offset, notes.data(), notes.size());
  return meta;
}

std::array<unsigned char, 8> detail::meta_checksum(std::span<const unsigned char> meta) {
  Checksum sum;
  sum.update(meta.data(), meta.size());
  const std::uint64_t digest = sum.finish();
  std::array<unsigned char, 8> out;
  std::memcpy(out.data(), &digest, sizeof digest);
  return out;
}

void CacheImage::make(const Hierarchy& hier, const CacheKey& key, bool in_place) {
  cache_pages::Encoded pages =
      in_place ? cache_pages::encode_in_place(hier) : cache_pages::encode(hier);
  const detail::CacheMeta m{key,
                            hier.frame(),
                            hier.bounds_min(),
                            hier.bounds_max(),
                            hier.node_count(),
                            hier.leaf_count(),
                            static_cast<std::uint32_t>(hier.level_count()),
                            hier.attributes(),
                            hier.notes()};
  // The pages stay as they were compressed (written after the meta part
  // one by one: never a second copy of them).
  meta_ = detail::cache_meta(m, pages.table, cache_pages::links_of(pages, hier));
  pages_ = std::move(pages.pages);
  checksum_ = detail::meta_checksum(meta_);
}

std::size_t CacheImage::size() const {
  std::size_t bytes = meta_.size() + checksum_.size();
  for (const std::vector<unsigned char>& page : pages_) bytes += page.size();
  return bytes;
}

// Through an AtomicFile (temporary + rename), so readers see the old file or
// the complete new one, and a failed write (full disk, read-only folder)
// leaves no file.
void detail::create_cache_folder(const std::filesystem::path& cache) {
  if (!cache.has_parent_path()) return;
  std::error_code ec;
  std::filesystem::create_directories(cache.parent_path(), ec);
  if (ec) throw std::runtime_error(system_error_text(cache.parent_path(), ec.value()));
}

void CacheImage::save(const std::filesystem::path& cache) const {
  detail::create_cache_folder(cache);
  AtomicFile out(cache);
  out.write(meta_.data(), meta_.size());
  for (const std::vector<unsigned char>& page : pages_) out.write(page.data(), page.size());
  out.write(checksum_.data(), checksum_.size());
  out.commit();
}

void save_cache(const Hierarchy& hier, const CacheKey& key, const std::filesystem::path& cache) {
  CacheImage(hier, key).save(cache);
}

}  // namespace treecut
