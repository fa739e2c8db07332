// Writing a hierarchy cache file (the layout is cache_layout.hpp's): the
// header, every array at its aligned offset, the checksum streamed over the
// pieces as they are written, all through a temporary renamed into place.
#include <algorithm>
#include <array>
#include <cstring>
#include <stdexcept>
#include <string>
#include <tuple>
#include <vector>

#include "cache_layout.hpp"
#include "treecut/cache.hpp"
#include "treecut/file_io.hpp"

namespace treecut {

using namespace cache_layout;

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

}  // namespace treecut
