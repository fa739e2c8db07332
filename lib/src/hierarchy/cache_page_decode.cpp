// Decoding a cache's pages (cache_pages.hpp): each page verified and
// decompressed in parallel, the links rebuilt by one walk over the levels
// (which also proves every node is reached once), the values scattered in
// parallel.
#include <sys/mman.h>
#include <zstd.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstring>
#include <tuple>

#include "cache_pages.hpp"
#include "node_arrays.hpp"
#include "page_codec.hpp"
#include "treecut/error.hpp"
#include "treecut/parallel.hpp"

namespace treecut::cache_pages {

using cache_layout::Checksum;
using cache_layout::kNoPage;
using cache_layout::PageRecord;

namespace {

struct OwnedNodes : detail::NodeArrays {
  std::vector<std::vector<float>> values;  // the attributes that are not constant
};

// Sizes V to N values of FILL, its memory advised into huge pages first
// where the kernel gives them on request (THP "madvise", as on Debian): the
// arrays of a large model are then a few hundred page faults, not some
// hundred thousand, most of the time that touching fresh memory costs.
// Advice only.
template <class T>
void size_huge(std::vector<T>& v, std::size_t n, T fill = T{}) {
  v.reserve(n);
  const auto at = reinterpret_cast<std::uintptr_t>(v.data());
  const std::uintptr_t page = 4096, begin = (at + page - 1) / page * page,
                       end = (at + n * sizeof(T)) / page * page;
  if (end > begin) (void)::madvise(reinterpret_cast<void*>(begin), end - begin, MADV_HUGEPAGE);
  v.assign(n, fill);
}

bool fail(std::string* why, std::string text) {
  if (why) *why = std::move(text);
  return false;
}

// A page's bytes verified and decompressed, or what is wrong with them.
// The first pass keeps only the head and the nodes' bytes (the links are
// made of them); the values are decompressed again by the second, a page at
// a time, so the decoded pages are never all in memory beside the nodes.
struct RawPage {
  std::vector<unsigned char> bytes;
  PageHead head{};
  std::string problem;
};

// Decompresses the R.bytes at PACKED into OUT; false when they do not.
bool decompress(const PageRecord& r, const unsigned char* packed, std::vector<unsigned char>& out) {
  out.resize(r.raw_bytes);
  const std::size_t got = ZSTD_decompress(out.data(), out.size(), packed, r.bytes);
  return !ZSTD_isError(got) && got == r.raw_bytes;
}

RawPage unpack(const PageRecord& r, const PageSource& source, std::uint32_t value_streams) {
  RawPage page;
  thread_local std::vector<unsigned char> buffer;
  const unsigned char* file = source(r, buffer);
  Checksum sum;
  sum.update(file, r.bytes);
  if (sum.finish() != r.checksum) return page.problem = "checksum mismatch (corrupted)", page;
  if (r.raw_bytes < sizeof(PageHead) ||
      r.raw_bytes > sizeof(PageHead) + std::uint64_t{r.node_count} * (26 + 4 * value_streams))
    return page.problem = "bad size", page;
  if (!decompress(r, file, page.bytes)) return page.problem = "does not decompress", page;
  std::memcpy(&page.head, page.bytes.data(), sizeof page.head);
  const PageHead& h = page.head;
  bool finite = std::isfinite(h.lo[0]) && std::isfinite(h.lo[1]) && std::isfinite(h.lo[2]);
  for (const std::int32_t e : h.step_exp) finite = finite && e >= -149 && e <= 127;
  if (!finite || h.radius_exp < -160 || h.radius_exp > 127 || (h.flags & ~(kLeafCones | kAlpha)) ||
      h.node_count != r.node_count || h.interior_count > h.node_count ||
      h.value_streams != value_streams || raw_size(h) != r.raw_bytes)
    return page.problem = "bad page header", page;
  // The interior nodes' planes are as long as the nodes with children.
  const unsigned char* counts = page.bytes.data() + sizeof(PageHead);
  const auto interior = std::count_if(counts, counts + h.node_count,
                                      [](unsigned char c) { return (c & kCountBits) != 0; });
  if (static_cast<std::uint32_t>(interior) != h.interior_count)
    return page.problem = "interior count disagrees", page;
  page.bytes.resize(sizeof(PageHead) + h.node_count);  // the head and the nodes' bytes
  page.bytes.shrink_to_fit();
  return page;
}

// The links: every page's nodes reached once from the root, level by level
// (the breadth-first ids), in-page children taken in order, each node with
// children elsewhere matched with the pages that say it is their parent.
// GID[first[p] + local] receives the ids.
bool link(std::span<const PageRecord> table, const std::vector<RawPage>& raw,
          const std::vector<std::uint64_t>& first, std::uint32_t level_count, OwnedNodes& o,
          std::vector<NodeId>& gid, std::vector<NodeId>& level_begin, std::string* why) {
  const std::size_t pages = table.size();
  // The child pages of each node, grouped: (parent page, parent local, page).
  std::vector<std::tuple<std::uint32_t, std::uint32_t, std::uint32_t>> groups;
  for (std::uint32_t q = 1; q < pages; ++q)
    groups.emplace_back(table[q].parent_page, table[q].parent_local, q);
  std::sort(groups.begin(), groups.end());
  std::vector<std::size_t> next_group(pages + 1, groups.size());
  for (std::size_t k = groups.size(); k-- > 0;) next_group[std::get<0>(groups[k])] = k;
  std::vector<std::uint32_t> cursor(pages, 1);
  auto page_fail = [&](std::size_t p, const std::string& what) {
    return fail(why, "page " + std::to_string(p) + " of " + std::to_string(pages) + ": " + what);
  };

  struct Loc {
    std::uint32_t page, local;
  };
  std::vector<Loc> level{{0, 0}}, next;
  NodeId id = 0;  // the next id to hand out; the level's nodes have [level_begin.back(), id)
  gid[0] = 0;
  id = 1;
  o.parent[0] = kNoNode;
  for (std::uint32_t d = 0; !level.empty(); ++d) {
    if (d >= level_count) return fail(why, "more levels than the header says");
    level_begin.push_back(id - NodeId(level.size()));
    next.clear();
    for (const Loc& at : level) {
      const NodeId self = gid[first[at.page] + at.local];
      o.depth[self] = static_cast<std::uint8_t>(d);
      const std::uint8_t byte = raw[at.page].bytes[sizeof(PageHead) + at.local];
      const unsigned cc = byte & kCountBits;
      o.child_count[self] = static_cast<std::uint8_t>(cc);
      if (cc > 4 || (byte & ~(kCountBits | kExternal | kNegativeZ)) ||
          (cc == 0 && (byte & kExternal)))
        return page_fail(at.page, "bad child count");
      if (cc == 0) continue;
      o.first_child[self] = id;
      auto reach = [&](Loc c) {
        gid[first[c.page] + c.local] = id;
        o.parent[id] = self;
        ++id;
        next.push_back(c);
      };
      if (!(byte & kExternal)) {
        std::uint32_t& cur = cursor[at.page];
        if (cc > table[at.page].node_count - cur)
          return page_fail(at.page, "child range out of bounds");
        for (unsigned k = 0; k < cc; ++k) reach({at.page, cur++});
        continue;
      }
      std::size_t& g = next_group[at.page];
      for (unsigned k = 0; k < cc; ++k, ++g) {
        if (g >= groups.size() || std::get<0>(groups[g]) != at.page ||
            std::get<1>(groups[g]) != at.local)
          return page_fail(at.page, "a node's child pages are missing");
        const std::uint32_t q = std::get<2>(groups[g]);
        if (k > 0 && q != std::get<2>(groups[g - 1]) + 1)
          return page_fail(q, "not next to its sibling pages");
        if (table[q].root_depth != d + 1) return page_fail(q, "root depth disagrees");
        reach({q, 0});
      }
      if (g < groups.size() && std::get<0>(groups[g]) == at.page &&
          std::get<1>(groups[g]) == at.local)
        return page_fail(at.page, "more child pages than children");
    }
    std::swap(level, next);
  }
  level_begin.push_back(id);
  for (std::size_t p = 0; p < pages; ++p) {
    if (cursor[p] != table[p].node_count) return page_fail(p, "a node is nobody's child");
    if (next_group[p] < groups.size() && std::get<0>(groups[next_group[p]]) == p)
      return page_fail(std::get<2>(groups[next_group[p]]), "its parent node has no child pages");
  }
  if (level_begin.size() != level_count + 1) return fail(why, "fewer levels than the header says");
  return true;
}

// Every value of page R's nodes, at their ids IDS (its bytes decompressed
// again into BUFFER: the first pass verified them).
void scatter(const PageRecord& r, const PageSource& source, const PageHead& head,
             std::span<const NodeId> ids, OwnedNodes& o, std::vector<unsigned char>& buffer) {
  thread_local std::vector<unsigned char> packed;
  const unsigned char* bytes = source(r, packed);
  // Verified again: the links were made of the first read's bytes, and a
  // file rewritten in between must not reach the planes.
  Checksum sum;
  sum.update(bytes, r.bytes);
  if (sum.finish() != r.checksum || !decompress(r, bytes, buffer))
    throw FileChangedError("changed while being read (a page differs between its two reads)");
  const PageCodes c = read_planes(head, buffer.data());
  const PageHead& h = c.head;
  AxisGrid grid[3];
  for (int axis = 0; axis < 3; ++axis) grid[axis] = AxisGrid::of(h.lo[axis], h.step_exp[axis]);
  for (std::size_t k = 0; k < h.node_count; ++k) {
    const NodeId i = ids[k];
    glm::vec3 center;
    for (int axis = 0; axis < 3; ++axis)
      center[axis] = decode_axis(c.q[static_cast<std::size_t>(axis)][k], grid[axis]);
    const float radius = decode_radius(c.radius[k], h.radius_exp);
    o.center_radius[i] = glm::vec4(center, radius);
    o.splat_radius[i] = (c.cc[k] & kCountBits) ? decode_splat(c.splat[k], radius) : radius;
    o.normal_cone[i] = glm::i16vec4(c.normal[0][k], c.normal[1][k], c.normal[2][k], c.normal[3][k]);
    o.color[i] = glm::u8vec4(c.color[0][k], c.color[1][k], c.color[2][k], c.color[3][k]);
    o.priority[i] = decode_priority(c.priority[k]);
    for (std::uint32_t s = 0; s < h.value_streams; ++s)
      std::memcpy(&o.values[s][i], &c.values[s][k], 4);
  }
}

}  // namespace

std::optional<Decoded> decode(std::span<const PageRecord> table, const PageSource& source,
                              std::uint64_t node_count, std::uint32_t value_streams,
                              std::uint32_t level_count, std::string* why) {
  const std::size_t pages = table.size();
  if (node_count == 0 || pages == 0) return fail(why, "no nodes"), std::nullopt;
  if (node_count >= kNoNode)
    return fail(why,
                std::to_string(node_count) +
                    " nodes: more than this build opens whole (2^32 - 1; paged drawing, issue 45)"),
           std::nullopt;
  std::vector<std::uint64_t> first(pages + 1, 0);
  for (std::size_t p = 0; p < pages; ++p) {
    const PageRecord& r = table[p];
    const bool linked = p == 0
                            ? r.parent_page == kNoPage && r.root_depth == 0
                            : r.parent_page < p && r.parent_local < table[r.parent_page].node_count;
    if (r.node_count == 0 || r.node_count > kPageNodes || !linked)
      return fail(why, "page " + std::to_string(p) + " of " + std::to_string(pages) +
                           ": bad page record"),
             std::nullopt;
    first[p + 1] = first[p] + r.node_count;
  }
  if (first[pages] != node_count) return fail(why, "the pages do not hold the nodes"), std::nullopt;

  std::vector<RawPage> raw(pages);
  parallel_for(
      pages,
      [&](std::size_t b, std::size_t e) {
        for (std::size_t p = b; p < e; ++p) raw[p] = unpack(table[p], source, value_streams);
      },
      0, 1);
  for (std::size_t p = 0; p < pages; ++p)
    if (!raw[p].problem.empty())
      return fail(why, "page " + std::to_string(p) + " of " + std::to_string(pages) + ": " +
                           raw[p].problem),
             std::nullopt;

  const auto n = static_cast<std::size_t>(node_count);
  auto o = std::make_shared<OwnedNodes>();
  size_huge(o->parent, n), size_huge(o->first_child, n, kNoNode), size_huge(o->child_count, n),
      size_huge(o->depth, n);
  std::vector<NodeId> gid, level_begin;
  size_huge(gid, n);
  if (!link(table, raw, first, level_count, *o, gid, level_begin, why)) return std::nullopt;

  size_huge(o->center_radius, n), size_huge(o->splat_radius, n), size_huge(o->normal_cone, n);
  size_huge(o->color, n), size_huge(o->priority, n), size_huge(o->point_count, n);
  o->values.resize(value_streams);
  for (std::vector<float>& v : o->values) size_huge(v, n);
  parallel_for(
      pages,
      [&](std::size_t b, std::size_t e) {
        std::vector<unsigned char> buffer;
        for (std::size_t p = b; p < e; ++p) {
          scatter(table[p], source, raw[p].head,
                  std::span<const NodeId>(gid.data() + first[p], table[p].node_count), *o, buffer);
          raw[p] = RawPage{};
        }
      },
      0, 1);
  // Point counts from the leaves up, a level's nodes in parallel: 64-bit
  // sums, refused past 32 bits.
  std::atomic<bool> overflow{false};
  for (std::size_t d = level_begin.size() - 1; d-- > 0;) {
    const NodeId lb = level_begin[d];
    parallel_for(level_begin[d + 1] - lb, [&](std::size_t b, std::size_t e) {
      bool over = false;
      for (NodeId i = lb + NodeId(b); i < lb + NodeId(e); ++i) {
        const unsigned cc = o->child_count[i];
        std::uint64_t count = cc == 0 ? 1 : 0;
        for (NodeId c = o->first_child[i]; c < o->first_child[i] + cc; ++c)
          count += o->point_count[c];
        over = over || count > 0xffffffffu;
        o->point_count[i] = static_cast<std::uint32_t>(count);
      }
      if (over) overflow = true;
    });
  }
  if (overflow) return fail(why, "more than 2^32 points under a node"), std::nullopt;

  Decoded out;
  out.arrays = o->spans();
  for (const std::vector<float>& v : o->values) out.attribute_values.emplace_back(v);
  out.level_begin = std::move(level_begin);
  out.storage = std::move(o);
  return out;
}

}  // namespace treecut::cache_pages
