// Decoding a cache's pages (cache_pages.hpp): the page table and the
// pages' links checked once as a whole (PageIndex: every id held by one
// page, at its depth), then each page alone (decode_page: verified,
// decompressed, its links and values written at its nodes' ids), all of
// them in parallel for a whole load.
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

using cache_layout::PageRun;

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

// Decompresses the R.bytes at PACKED into OUT; false when they do not.
bool decompress(const PageRecord& r, const unsigned char* packed, std::vector<unsigned char>& out) {
  out.resize(r.raw_bytes);
  const std::size_t got = ZSTD_decompress(out.data(), out.size(), packed, r.bytes);
  return !ZSTD_isError(got) && got == r.raw_bytes;
}

// Page R's bytes read, verified and decompressed into RAW; its head into
// HEAD. Empty, or what is wrong with them.
std::string unpack(const PageRecord& r, const PageSource& source, std::uint32_t value_streams,
                   std::vector<unsigned char>& raw, PageHead& head) {
  thread_local std::vector<unsigned char> buffer;
  const unsigned char* file = source(r, buffer);
  Checksum sum;
  sum.update(file, r.bytes);
  if (sum.finish() != r.checksum) return "checksum mismatch (corrupted)";
  if (r.raw_bytes < sizeof(PageHead) ||
      r.raw_bytes > sizeof(PageHead) + std::uint64_t{r.node_count} * (26 + 4 * value_streams))
    return "bad size";
  if (!decompress(r, file, raw)) return "does not decompress";
  std::memcpy(&head, raw.data(), sizeof head);
  const PageHead& h = head;
  bool finite = std::isfinite(h.lo[0]) && std::isfinite(h.lo[1]) && std::isfinite(h.lo[2]);
  for (const std::int32_t e : h.step_exp) finite = finite && e >= -149 && e <= 127;
  if (!finite || h.radius_exp < -160 || h.radius_exp > 127 || (h.flags & ~(kLeafCones | kAlpha)) ||
      h.node_count != r.node_count || h.interior_count > h.node_count ||
      h.value_streams != value_streams || raw_size(h) != r.raw_bytes)
    return "bad page header";
  // The interior nodes' planes are as long as the nodes with children.
  const unsigned char* counts = raw.data() + sizeof(PageHead);
  const auto interior = std::count_if(counts, counts + h.node_count,
                                      [](unsigned char c) { return (c & kCountBits) != 0; });
  if (static_cast<std::uint32_t>(interior) != h.interior_count) return "interior count disagrees";
  return {};
}

// A page's shape from its nodes' bytes: each node's parent in the page and
// level below the page's root (the page's order is breadth-first: every
// node but the root is the child of an earlier one, in order).
struct Shape {
  std::vector<std::uint32_t> parent, level, first;  // first: in-page first child, or kNone
  static constexpr std::uint32_t kNone = 0xffffffffu;
};

std::string shape_of(const unsigned char* counts, std::uint32_t n, Shape& s) {
  s.parent.assign(n, Shape::kNone), s.level.assign(n, 0), s.first.assign(n, Shape::kNone);
  std::uint32_t cursor = 1;
  for (std::uint32_t k = 0; k < n; ++k) {
    if (k > 0 && k >= cursor) return "a node is nobody's child";
    const std::uint8_t byte = counts[k];
    const unsigned cc = byte & kCountBits;
    if (cc > 4 || (byte & ~(kCountBits | kExternal | kNegativeZ)) ||
        (cc == 0 && (byte & kExternal)))
      return "bad child count";
    if (cc == 0 || (byte & kExternal)) continue;
    if (cc > n - cursor) return "child range out of bounds";
    s.first[k] = cursor;
    for (unsigned j = 0; j < cc; ++j, ++cursor)
      s.parent[cursor] = k, s.level[cursor] = s.level[k] + 1;
  }
  if (cursor != n) return "a node is nobody's child";
  return {};
}

// The values of page R's nodes (its planes in RAW) at their ids IDS.
void scatter(const PageHead& head, const unsigned char* raw, std::span<const NodeId> ids,
             const NodeSink& o) {
  const PageCodes c = read_planes(head, raw);
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

// ---- PageIndex --------------------------------------------------------------

std::optional<PageIndex> PageIndex::make(std::vector<PageRecord> table, PageLinks links,
                                         std::uint64_t node_count, std::uint32_t level_count,
                                         std::uint32_t value_streams, std::string* why) {
  const std::size_t pages = table.size();
  auto page_fail = [&](std::size_t p, const std::string& what) {
    return fail(why, "page " + std::to_string(p) + " of " + std::to_string(pages) + ": " + what),
           std::nullopt;
  };
  if (node_count == 0 || pages == 0) return fail(why, "no nodes"), std::nullopt;
  if (node_count >= kNoNode)
    return fail(why, std::to_string(node_count) + " nodes: more than this build opens (2^32 - 1)"),
           std::nullopt;
  const std::vector<std::uint64_t>& lb = links.level_begin;
  if (lb.size() != std::size_t{level_count} + 1 || lb.front() != 0 || lb.back() != node_count ||
      std::adjacent_find(lb.begin(), lb.end(), std::greater_equal<>()) != lb.end())
    return fail(why, "bad level table"), std::nullopt;
  if (links.points.size() != pages || links.run_index.size() != pages + 1 ||
      links.run_index.front() != 0 || links.run_index.back() != links.runs.size() ||
      !std::is_sorted(links.run_index.begin(), links.run_index.end()))
    return fail(why, "bad run table"), std::nullopt;
  std::uint64_t nodes = 0;
  for (std::size_t p = 0; p < pages; ++p) {
    const PageRecord& r = table[p];
    const bool linked = p == 0
                            ? r.parent_page == kNoPage && r.root_depth == 0
                            : r.parent_page < p && r.parent_local < table[r.parent_page].node_count;
    if (r.node_count == 0 || r.node_count > kPageNodes || !linked || links.points[p] == 0)
      return page_fail(p, "bad page record");
    nodes += r.node_count;
    // Its runs: in increasing ids, each inside its depth's level, the
    // first at the page's root, as many ids as the page has nodes.
    const std::span<const PageRun> runs = links.runs_of(p);
    std::uint64_t held = 0, next = 0;
    std::uint32_t depth = r.root_depth;
    for (const PageRun& run : runs) {
      if (run.count == 0 || run.depth >= level_count || run.depth < depth ||
          run.first < std::max(next, lb[run.depth]) || run.first > lb[run.depth + 1] ||
          run.count > lb[run.depth + 1] - run.first)
        return page_fail(p, "bad node runs");
      held += run.count, next = run.first + run.count, depth = run.depth;
    }
    if (runs.empty() || held != r.node_count || runs.front().depth != r.root_depth)
      return page_fail(p, "bad node runs");
  }
  if (nodes != node_count) return fail(why, "the pages do not hold the nodes"), std::nullopt;
  // Every id held by exactly one page.
  std::vector<std::pair<std::uint64_t, std::uint32_t>> starts;  // (first, count)
  starts.reserve(links.runs.size());
  for (const PageRun& run : links.runs) starts.emplace_back(run.first, run.count);
  std::sort(starts.begin(), starts.end());
  std::uint64_t covered = 0;
  for (const auto& [first, count] : starts) {
    if (first != covered) return fail(why, "the pages' nodes overlap or leave gaps"), std::nullopt;
    covered += count;
  }

  PageIndex index;
  index.table_ = std::move(table);
  index.links_ = std::move(links);
  index.node_count_ = node_count;
  index.value_streams_ = value_streams;
  // The child pages of each node, grouped: (parent page, parent local, page).
  std::vector<std::tuple<std::uint32_t, std::uint32_t, std::uint32_t>> groups;
  for (std::uint32_t q = 1; q < pages; ++q)
    groups.emplace_back(index.table_[q].parent_page, index.table_[q].parent_local, q);
  std::sort(groups.begin(), groups.end());
  index.children_.reserve(groups.size());
  index.group_begin_.assign(pages + 1, 0);
  for (const auto& [pp, pl, q] : groups) {
    index.children_.push_back({pl, q});
    ++index.group_begin_[pp + 1];
  }
  for (std::size_t p = 0; p < pages; ++p) index.group_begin_[p + 1] += index.group_begin_[p];
  // Sibling pages: one after the other, their roots' ids too, a level
  // below the node they hang from.
  for (std::size_t g = 0; g < groups.size(); ++g) {
    const auto [pp, pl, q] = groups[g];
    const bool first =
        g == 0 || std::get<0>(groups[g - 1]) != pp || std::get<1>(groups[g - 1]) != pl;
    if (first) {
      if (index.table_[q].root_depth != index.depth_of(pp, pl) + 1)
        return page_fail(q, "root depth disagrees");
    } else if (q != std::get<2>(groups[g - 1]) + 1 ||
               index.root_id(q) != index.root_id(q - 1) + 1 ||
               index.table_[q].root_depth != index.table_[q - 1].root_depth) {
      return page_fail(q, "not next to its sibling pages");
    }
  }
  return index;
}

std::pair<NodeId, std::uint32_t> PageIndex::locate(std::uint32_t page, std::uint32_t local) const {
  for (const PageRun& run : links_.runs_of(page)) {
    if (local < run.count) return {static_cast<NodeId>(run.first + local), run.depth};
    local -= run.count;
  }
  return {kNoNode, 0};  // (make() checked LOCAL against the page's nodes)
}

std::span<const PageIndex::Child> PageIndex::child_pages(std::uint32_t page) const {
  return std::span(children_).subspan(group_begin_[page],
                                      group_begin_[page + 1] - group_begin_[page]);
}

// ---- One page ---------------------------------------------------------------

std::string decode_page(const PageIndex& index, std::uint32_t p, const PageSource& source,
                        const NodeSink& out, std::vector<unsigned char>& raw) {
  const PageRecord& r = index.record(p);
  PageHead head{};
  if (std::string problem = unpack(r, source, index.value_streams(), raw, head); !problem.empty())
    return problem;
  const std::uint32_t n = r.node_count;
  const unsigned char* counts = raw.data() + sizeof(PageHead);
  thread_local Shape shape;
  if (std::string problem = shape_of(counts, n, shape); !problem.empty()) return problem;
  // Each node's id, from the runs, at the depth its place in the page gives.
  thread_local std::vector<NodeId> id;
  id.resize(n);
  std::uint32_t k = 0;
  for (const PageRun& run : index.links().runs_of(p))
    for (std::uint32_t j = 0; j < run.count; ++j, ++k) {
      if (run.depth != r.root_depth + shape.level[k])
        return "its nodes' depths disagree with its runs";
      id[k] = static_cast<NodeId>(run.first + j);
    }
  // The links: in-page children (their ids one after the other), child
  // pages (as many as the node has children), parents.
  const std::span<const PageIndex::Child> children = index.child_pages(p);
  thread_local std::vector<std::uint64_t> points;  // under each node
  points.assign(n, 0);
  std::size_t g = 0;
  for (k = 0; k < n; ++k) {
    const unsigned cc = counts[k] & kCountBits;
    const NodeId self = id[k];
    out.child_count[self] = static_cast<std::uint8_t>(cc);
    out.depth[self] = static_cast<std::uint8_t>(r.root_depth + shape.level[k]);
    out.parent[self] = k > 0    ? id[shape.parent[k]]
                       : p == 0 ? kNoNode
                                : index.locate(r.parent_page, r.parent_local).first;
    out.first_child[self] = kNoNode;
    if (cc == 0) continue;
    if (shape.first[k] != Shape::kNone) {
      const std::uint32_t c = shape.first[k];
      for (unsigned j = 1; j < cc; ++j)
        if (id[c + j] != id[c] + j) return "a node's children are not one after the other";
      out.first_child[self] = id[c];
      continue;
    }
    while (g < children.size() && children[g].local < k) ++g;
    std::size_t held = 0;
    while (g + held < children.size() && children[g + held].local == k) ++held;
    if (held < cc) return "a node's child pages are missing";
    if (held > cc) return "more child pages than children";
    out.first_child[self] = index.root_id(children[g].page);
    for (; held > 0; --held, ++g) points[k] += index.links().points[children[g].page];
  }
  // Point counts from the leaves and the child pages' roots up.
  for (k = n; k-- > 0;) {
    if ((counts[k] & kCountBits) == 0) points[k] = 1;
    if (k > 0) points[shape.parent[k]] += points[k];
    if (points[k] > 0xffffffffu) return "more than 2^32 points under a node";
    out.point_count[id[k]] = static_cast<std::uint32_t>(points[k]);
  }
  if (points[0] != index.links().points[p]) return "point count disagrees with the page table";
  scatter(head, raw.data(), id, out);
  return {};
}

// ---- Every page -------------------------------------------------------------

std::optional<Decoded> decode(const PageIndex& index, const PageSource& source, std::string* why) {
  const std::size_t pages = index.pages();
  const auto n = static_cast<std::size_t>(index.node_count());
  auto o = std::make_shared<OwnedNodes>();
  size_huge(o->parent, n), size_huge(o->first_child, n, kNoNode), size_huge(o->child_count, n),
      size_huge(o->depth, n);
  size_huge(o->center_radius, n), size_huge(o->splat_radius, n), size_huge(o->normal_cone, n);
  size_huge(o->color, n), size_huge(o->priority, n), size_huge(o->point_count, n);
  o->values.resize(index.value_streams());
  for (std::vector<float>& v : o->values) size_huge(v, n);
  NodeSink sink{o->center_radius.data(),
                o->splat_radius.data(),
                o->normal_cone.data(),
                o->color.data(),
                o->priority.data(),
                o->point_count.data(),
                o->parent.data(),
                o->first_child.data(),
                o->child_count.data(),
                o->depth.data(),
                {}};
  for (std::vector<float>& v : o->values) sink.values.push_back(v.data());
  // The first page (in order) that fails names the problem.
  std::vector<std::string> problems(pages);
  std::atomic<bool> failed = false;
  parallel_for(
      pages,
      [&](std::size_t b, std::size_t e) {
        std::vector<unsigned char> raw;
        for (std::size_t p = b; p < e && !failed.load(std::memory_order_relaxed); ++p) {
          problems[p] = decode_page(index, static_cast<std::uint32_t>(p), source, sink, raw);
          if (!problems[p].empty()) failed = true;
        }
      },
      0, 1);
  for (std::size_t p = 0; p < pages; ++p)
    if (!problems[p].empty())
      return fail(why, "page " + std::to_string(p) + " of " + std::to_string(pages) + ": " +
                           problems[p]),
             std::nullopt;
  // Every page hangs from a node with children elsewhere: the pages'
  // decodes took each child page once (its node's count), so all of them
  // were taken when the counts of such nodes add up to the pages less one.
  std::uint64_t taken = 0;
  for (std::size_t p = 0; p < pages; ++p) {
    const std::span<const PageIndex::Child> children =
        index.child_pages(static_cast<std::uint32_t>(p));
    for (std::size_t g = 0; g < children.size(); ++g)
      if (g == 0 || children[g].local != children[g - 1].local) {
        const NodeId at = index.locate(static_cast<std::uint32_t>(p), children[g].local).first;
        if (o->first_child[at] == index.root_id(children[g].page)) taken += o->child_count[at];
      }
  }
  if (taken != pages - 1)
    return fail(why, "a page hangs from a node without child pages"), std::nullopt;

  Decoded result;
  result.arrays = o->spans();
  for (const std::vector<float>& v : o->values) result.attribute_values.emplace_back(v);
  result.level_begin.assign(index.links().level_begin.begin(), index.links().level_begin.end());
  result.storage = std::move(o);
  return result;
}

}  // namespace treecut::cache_pages
