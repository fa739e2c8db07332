// Encoding a cache's pages (cache_pages.hpp has the format's promises,
// page_codec.hpp the bytes of one page): the partition into subtrees, the
// per-page grids, the radii recomputed bottom-up on the quantized centers,
// then each page's planes through zstd, the pages in parallel.
#include "cache_pages.hpp"

#include <zstd.h>

#include <algorithm>
#include <cstring>
#include <stdexcept>

#include "page_codec.hpp"
#include "treecut/parallel.hpp"

namespace treecut::cache_pages {

using cache_layout::Checksum;
using cache_layout::kNoPage;
using cache_layout::PageRecord;
using cache_layout::PageRun;

namespace {

// ---- The partition ----------------------------------------------------------

// Where the pages are: subtrees (or their tops) of at most kPageNodes, cut
// bottom-up: a node whose open part (itself and what of its children's
// subtrees is not yet paged) would pass the limit closes each child's open
// part as a page. Pages are numbered by their roots' ids, so a page comes
// after its parent's. One byte a node: the pages' nodes are found again by
// walking down from their roots.
struct Partition {
  std::vector<std::uint8_t> is_root;
  std::vector<NodeId> roots;  // page q's root: roots[q], increasing
  [[nodiscard]] std::uint32_t page_of_root(NodeId root) const {
    return static_cast<std::uint32_t>(std::lower_bound(roots.begin(), roots.end(), root) -
                                      roots.begin());
  }
};

// With LEAVES_APART (encode_over), every leaf is a page's root, and so
// are its siblings.
Partition partition(const Hierarchy& h, bool leaves_apart) {
  const HierarchyArrays& a = h.arrays();
  const std::size_t n = h.node_count();
  Partition p;
  p.is_root.assign(n, 0);
  p.is_root[0] = 1;
  std::vector<std::uint16_t> open(n, 1);  // at most kPageNodes
  for (int d = h.level_count() - 2; d >= 0; --d) {
    const NodeId lb = h.level_begin(d), le = h.level_begin(d + 1);
    parallel_for(le - lb, [&](std::size_t b, std::size_t e) {
      for (NodeId i = lb + NodeId(b); i < lb + NodeId(e); ++i) {
        const unsigned cc = a.child_count[i];
        if (cc == 0) continue;
        std::uint32_t sum = 1;
        bool leaf_child = false;
        for (NodeId c = a.first_child[i]; c < a.first_child[i] + cc; ++c)
          sum += open[c], leaf_child = leaf_child || a.child_count[c] == 0;
        if (sum > kPageNodes || (leaves_apart && leaf_child)) {
          for (NodeId c = a.first_child[i]; c < a.first_child[i] + cc; ++c) p.is_root[c] = 1;
          sum = 1;
        }
        open[i] = static_cast<std::uint16_t>(sum);
      }
    });
  }
  for (NodeId i = 0; i < n; ++i)
    if (p.is_root[i]) p.roots.push_back(i);
  return p;
}

// A page's nodes in its order, breadth-first from its root without
// entering other pages (so in increasing id), and each one's first child
// in the page (kNoLocal: none, or its children are other pages' roots).
constexpr std::uint32_t kNoLocal = 0xffffffffu;
struct PageNodes {
  std::vector<NodeId> nodes;
  std::vector<std::uint32_t> first_local;
};

PageNodes page_nodes(const Hierarchy& h, const Partition& p, std::uint32_t page) {
  const HierarchyArrays& a = h.arrays();
  PageNodes out;
  out.nodes.push_back(p.roots[page]);
  for (std::size_t k = 0; k < out.nodes.size(); ++k) {
    const NodeId i = out.nodes[k];
    const unsigned cc = a.child_count[i];
    if (cc == 0 || p.is_root[a.first_child[i]]) {
      out.first_local.push_back(kNoLocal);
      continue;
    }
    out.first_local.push_back(static_cast<std::uint32_t>(out.nodes.size()));
    for (NodeId c = a.first_child[i]; c < a.first_child[i] + cc; ++c) out.nodes.push_back(c);
  }
  return out;
}

// NODES (increasing ids, a page's) as runs of consecutive ids of one depth.
std::vector<PageRun> runs_of(const Hierarchy& h, const std::vector<NodeId>& nodes) {
  std::vector<PageRun> runs;
  for (const NodeId i : nodes) {
    const std::uint32_t depth = h.arrays().depth[i];
    if (!runs.empty() && runs.back().first + runs.back().count == i && runs.back().depth == depth)
      ++runs.back().count;
    else
      runs.push_back({i, 1, depth});
  }
  return runs;
}

// ---- Encoding ---------------------------------------------------------------

// A page's grids and its nodes' centers on them (in page order).
struct Grid {
  std::array<AxisGrid, 3> axis;
  std::vector<glm::vec3> centers;
};

Grid page_grid(const Hierarchy& h, const std::vector<NodeId>& nodes) {
  Grid g;
  g.centers.resize(nodes.size());
  std::vector<float> values(nodes.size());
  for (int a = 0; a < 3; ++a) {
    for (std::size_t k = 0; k < nodes.size(); ++k) values[k] = h.center(nodes[k])[a];
    std::optional<AxisGrid> exact = exact_grid(values);
    if (!exact) {
      round_to_grid(values);
      exact = exact_grid(values);
    }
    g.axis[static_cast<std::size_t>(a)] = *exact;
    for (std::size_t k = 0; k < nodes.size(); ++k) g.centers[k][a] = values[k];
  }
  return g;
}

// The radius index of each of a page's nodes, deepest first: a leaf's
// radius rounded up, an interior node's the smallest sphere around its
// children's as decoded (in this page, or the roots of theirs), about its
// decoded center (the builder's enclosing_sphere with its guard).
std::vector<std::int32_t> page_radii(const Hierarchy& h, const Partition& p, const PageNodes& pn,
                                     const Grid& g, const std::vector<Root>& roots,
                                     std::vector<float>& decoded) {
  const HierarchyArrays& a = h.arrays();
  const std::vector<NodeId>& nodes = pn.nodes;
  std::vector<std::int32_t> index(nodes.size());
  decoded.assign(nodes.size(), 0.0f);
  for (std::size_t k = nodes.size(); k-- > 0;) {  // children after their parents
    const NodeId i = nodes[k];
    float need = h.radius(i);
    if (const unsigned cc = a.child_count[i]; cc != 0) {
      need = 0.0f;
      for (unsigned j = 0; j < cc; ++j) {
        const std::uint32_t local = pn.first_local[k];
        const Root child = local != kNoLocal ? Root{g.centers[local + j], decoded[local + j]}
                                             : roots[p.page_of_root(a.first_child[i] + j)];
        need = std::max(need, glm::distance(child.center, g.centers[k]) + child.radius);
      }
      need = need * (1.0f + 4e-6f) + 1e-30f;
    }
    index[k] = radius_index(need);
    decoded[k] = radius_at(index[k]);
  }
  return index;
}

PageCodes page_codes(const Hierarchy& h, const PageNodes& pn, const Grid& g,
                     const std::vector<std::int32_t>& radius) {
  const HierarchyArrays& a = h.arrays();
  const std::vector<NodeId>& nodes = pn.nodes;
  PageHead head{};
  for (std::size_t k = 0; k < 3; ++k) head.lo[k] = g.axis[k].lo, head.step_exp[k] = g.axis[k].exp;
  const std::int32_t lowest = *std::min_element(radius.begin(), radius.end());
  head.radius_exp = lowest >= 0 ? lowest / 512 : -((511 - lowest) / 512);
  if (*std::max_element(radius.begin(), radius.end()) - 512 * head.radius_exp > 65535)
    throw std::runtime_error("a page's radii span more than 2^127");
  head.node_count = static_cast<std::uint32_t>(nodes.size());
  for (const NodeId i : nodes) {
    const glm::i16vec4 nc = a.normal_cone[i];
    if (a.child_count[i] != 0)
      ++head.interior_count;
    else if (nc.w != leaf_cone(nc))
      head.flags |= kLeafCones;
    if (a.color[i].w != 255) head.flags |= kAlpha;
  }
  for (const NodeAttribute& attribute : h.attributes())
    head.value_streams += !attribute.is_constant();
  PageCodes c(head);
  for (std::size_t k = 0; k < nodes.size(); ++k) {
    const NodeId i = nodes[k];
    const unsigned cc = a.child_count[i];
    c.cc[k] =
        static_cast<std::uint8_t>(cc | (cc != 0 && pn.first_local[k] == kNoLocal ? kExternal : 0) |
                                  (a.normal_cone[i].z < 0 ? kNegativeZ : 0));
    for (std::size_t axis = 0; axis < 3; ++axis)
      c.q[axis][k] = encode_axis(g.centers[k][static_cast<int>(axis)], g.axis[axis]);
    c.radius[k] = static_cast<std::uint16_t>(radius[k] - 512 * head.radius_exp);
    for (int m = 0; m < 4; ++m) c.normal[m][k] = a.normal_cone[i][m];
    for (int m = 0; m < 4; ++m) c.color[m][k] = a.color[i][m];
    c.priority[k] = encode_priority(a.priority[i]);
    if (cc != 0) c.splat[k] = encode_splat(a.splat_radius[i], radius_at(radius[k]));
    std::size_t s = 0;
    for (const NodeAttribute& attribute : h.attributes())
      if (!attribute.is_constant()) std::memcpy(&c.values[s++][k], &attribute.values[i], 4);
  }
  return c;
}

// Where the decoded values go when the hierarchy takes them itself
// (encode_in_place), else null.
struct Outputs {
  glm::vec4* center_radius;
  float* splat_radius;
  float* priority;
};

// One page: its grid, radii, codes, compressed planes and record; its root
// into ROOTS; with OUT, its nodes' values as they decode.
void encode_page(const Hierarchy& h, const Partition& p, std::uint32_t page,
                 std::vector<Root>& roots, const Outputs* out, Encoded& result) {
  const PageNodes pn = page_nodes(h, p, page);
  const std::vector<NodeId>& nodes = pn.nodes;
  const Grid g = page_grid(h, nodes);
  std::vector<float> radius;
  const std::vector<std::int32_t> index = page_radii(h, p, pn, g, roots, radius);
  const PageCodes codes = page_codes(h, pn, g, index);
  const std::vector<unsigned char> raw = write_planes(codes);
  // Compressed into a scratch buffer of the worst case's size, kept at its
  // exact size (a shrinking resize would keep the worst case's capacity).
  thread_local std::vector<unsigned char> scratch;
  scratch.resize(ZSTD_compressBound(raw.size()));
  const std::size_t size = ZSTD_compress(scratch.data(), scratch.size(), raw.data(), raw.size(), 3);
  if (ZSTD_isError(size)) throw std::runtime_error(std::string("zstd: ") + ZSTD_getErrorName(size));
  std::vector<unsigned char>& packed = result.pages[page];
  packed.assign(scratch.begin(), scratch.begin() + static_cast<std::ptrdiff_t>(size));
  PageRecord& r = result.table[page];
  Checksum sum;
  sum.update(packed.data(), packed.size());
  r.checksum = sum.finish();
  r.bytes = static_cast<std::uint32_t>(size);
  r.raw_bytes = static_cast<std::uint32_t>(raw.size());
  r.node_count = static_cast<std::uint32_t>(nodes.size());
  r.root_depth = h.arrays().depth[nodes[0]];
  if (page == 0) r.parent_page = kNoPage, r.parent_local = 0;
  glm::vec3 lo(INFINITY), hi(-INFINITY);
  for (std::size_t k = 0; k < nodes.size(); ++k)
    lo = glm::min(lo, g.centers[k] - radius[k]), hi = glm::max(hi, g.centers[k] + radius[k]);
  for (int a = 0; a < 3; ++a) r.bounds[a] = lo[a], r.bounds[a + 3] = hi[a];
  roots[page] = {g.centers[0], radius[0]};
  if (page == 0) result.root = roots[0];
  result.runs[page] = runs_of(h, nodes);
  result.points[page] = h.arrays().point_count[nodes[0]];
  // The child pages' records learn where they hang (they were encoded first).
  const HierarchyArrays& a = h.arrays();
  for (std::size_t k = 0; k < nodes.size(); ++k)
    if (codes.cc[k] & kExternal)
      for (unsigned j = 0; j < a.child_count[nodes[k]]; ++j) {
        PageRecord& child = result.table[p.page_of_root(a.first_child[nodes[k]] + j)];
        child.parent_page = page, child.parent_local = static_cast<std::uint32_t>(k);
      }
  if (!out) return;
  for (std::size_t k = 0; k < nodes.size(); ++k) {  // as decode's scatter makes them
    const NodeId i = nodes[k];
    out->center_radius[i] = glm::vec4(g.centers[k], radius[k]);
    out->splat_radius[i] =
        (codes.cc[k] & kCountBits) ? decode_splat(codes.splat[k], radius[k]) : radius[k];
    out->priority[i] = decode_priority(codes.priority[k]);
  }
}

// LEAF_ROOTS: encode_over's (the leaves' pages are not encoded here), or
// empty.
Encoded encode_pages(const Hierarchy& h, const Outputs* out, std::span<const Root> leaf_roots) {
  const bool leaves_apart = !leaf_roots.empty();
  const Partition p = partition(h, leaves_apart);
  const std::size_t pages = p.roots.size();
  // A page needs the roots of its child pages: the pages level by level of
  // the page tree, deepest first, those of one level in parallel.
  std::vector<std::uint32_t> level(pages, 0);
  std::uint32_t levels = 1;
  for (std::uint32_t q = 1; q < pages; ++q) {
    NodeId up = h.parent(p.roots[q]);
    while (!p.is_root[up]) up = h.parent(up);
    level[q] = level[p.page_of_root(up)] + 1;
    levels = std::max(levels, level[q] + 1);
  }
  std::vector<std::vector<std::uint32_t>> by_level(levels);
  for (std::uint32_t q = 0; q < pages; ++q) by_level[level[q]].push_back(q);
  Encoded result;
  result.roots = p.roots;
  result.table.assign(pages, PageRecord{});
  result.pages.resize(pages);
  result.runs.resize(pages);
  result.points.assign(pages, 0);
  std::vector<Root> roots(pages);
  for (std::uint32_t l = levels; l-- > 0;) {
    const std::vector<std::uint32_t>& these = by_level[l];
    parallel_for(
        these.size(),
        [&](std::size_t b, std::size_t e) {
          for (std::size_t k = b; k < e; ++k) {
            const NodeId root = p.roots[these[k]];
            if (leaves_apart && h.arrays().child_count[root] == 0) {
              roots[these[k]] = leaf_roots[root];
              result.table[these[k]].root_depth = h.arrays().depth[root];
              continue;
            }
            encode_page(h, p, these[k], roots, out, result);
          }
        },
        0, 1);
  }
  return result;
}

}  // namespace

Encoded encode(const Hierarchy& h) {
  return encode_pages(h, nullptr, {});
}

Encoded encode_over(const Hierarchy& top, std::span<const Root> leaf_roots) {
  if (leaf_roots.size() != top.node_count())
    throw std::invalid_argument("encode_over: a sphere for each node");
  return encode_pages(top, nullptr, leaf_roots);
}

Encoded encode_in_place(const Hierarchy& h) {
  const HierarchyArrays& a = h.arrays();
  const Outputs out{const_cast<glm::vec4*>(a.center_radius.data()),
                    const_cast<float*>(a.splat_radius.data()),
                    const_cast<float*>(a.priority.data())};
  return encode_pages(h, &out, {});
}

PageLinks links_of(const Encoded& e, const Hierarchy& h) {
  PageLinks links;
  links.points = e.points;
  links.run_index.push_back(0);
  for (const std::vector<PageRun>& runs : e.runs) {
    links.runs.insert(links.runs.end(), runs.begin(), runs.end());
    links.run_index.push_back(links.runs.size());
  }
  for (int d = 0; d <= h.level_count(); ++d) links.level_begin.push_back(h.level_begin(d));
  return links;
}

}  // namespace treecut::cache_pages
