// Encoding a cache's pages (cache_pages.hpp has the format's promises,
// page_codec.hpp the bytes of one page): the partition into subtrees, the
// per-page grids, the radii recomputed bottom-up on the quantized centers,
// then each page's planes through zstd, the pages in parallel.
#include "cache_pages.hpp"

#include <zstd.h>

#include <algorithm>
#include <cstring>
#include <limits>
#include <stdexcept>

#include "page_codec.hpp"
#include "treecut/parallel.hpp"

namespace treecut::cache_pages {

using cache_layout::Checksum;
using cache_layout::kNoPage;
using cache_layout::PageRecord;

namespace {

// ---- The partition ----------------------------------------------------------

// Which page each node is in, and where: pages are subtrees (or their tops)
// of at most kPageNodes, cut bottom-up: a node whose open part (itself and
// what of its children's subtrees is not yet paged) would pass the limit
// closes each child's open part as a page. Pages are numbered by their
// roots' ids, so a page comes after its parent's, and a page's nodes in
// increasing id are a breadth-first order of it.
struct Partition {
  std::vector<std::uint32_t> page_of, local;
  std::vector<std::uint64_t> first;  // page p: list[first[p], first[p + 1])
  std::vector<NodeId> list;
};

Partition partition(const Hierarchy& h) {
  const HierarchyArrays& a = h.arrays();
  const std::size_t n = h.node_count();
  std::vector<std::uint32_t> open(n, 1);
  std::vector<std::uint8_t> is_root(n, 0);
  is_root[0] = 1;
  for (int d = h.level_count() - 2; d >= 0; --d) {
    const NodeId lb = h.level_begin(d), le = h.level_begin(d + 1);
    parallel_for(le - lb, [&](std::size_t b, std::size_t e) {
      for (NodeId i = lb + NodeId(b); i < lb + NodeId(e); ++i) {
        const unsigned cc = a.child_count[i];
        if (cc == 0) continue;
        std::uint64_t sum = 1;
        for (NodeId c = a.first_child[i]; c < a.first_child[i] + cc; ++c) sum += open[c];
        if (sum > kPageNodes) {
          for (NodeId c = a.first_child[i]; c < a.first_child[i] + cc; ++c) is_root[c] = 1;
          sum = 1;
        }
        open[i] = static_cast<std::uint32_t>(sum);
      }
    });
  }
  open = {};
  Partition p;
  p.page_of.resize(n);
  p.local.resize(n);
  std::vector<std::uint32_t> size;
  for (NodeId i = 0; i < n; ++i) {
    if (is_root[i]) {
      p.page_of[i] = static_cast<std::uint32_t>(size.size());
      size.push_back(0);
    } else {
      p.page_of[i] = p.page_of[a.parent[i]];
    }
    p.local[i] = size[p.page_of[i]]++;
  }
  p.first.assign(size.size() + 1, 0);
  for (std::size_t k = 0; k < size.size(); ++k) p.first[k + 1] = p.first[k] + size[k];
  p.list.resize(n);
  for (NodeId i = 0; i < n; ++i) p.list[p.first[p.page_of[i]] + p.local[i]] = i;
  return p;
}

// ---- Encoding ---------------------------------------------------------------

// A page's grids, and its nodes' centers on them (in page order).
struct Grid {
  std::array<AxisGrid, 3> axis;
  std::vector<glm::vec3> centers;
  int radius_exp = 0;  // set once the radii are known
};

Grid page_grid(const Hierarchy& h, std::span<const NodeId> nodes) {
  Grid g;
  std::vector<float> values(nodes.size());
  for (int a = 0; a < 3; ++a) {
    for (std::size_t k = 0; k < nodes.size(); ++k) values[k] = h.center(nodes[k])[a];
    std::optional<AxisGrid> exact = exact_grid(values);
    if (!exact) {
      round_to_grid(values);
      exact = exact_grid(values);
    }
    g.axis[static_cast<std::size_t>(a)] = *exact;
    if (g.centers.empty()) g.centers.resize(nodes.size());
    for (std::size_t k = 0; k < nodes.size(); ++k) g.centers[k][a] = values[k];
  }
  return g;
}

// The radius index of every node: leaves' radii rounded up, interior
// nodes' the smallest sphere around their children's as decoded, about the
// node's decoded center (the builder's enclosing_sphere with its guard).
// Sets each page's radius_exp: its smallest index's octave.
std::vector<std::int32_t> radius_indices(const Hierarchy& h, const Partition& p,
                                         std::vector<Grid>& grids) {
  const HierarchyArrays& a = h.arrays();
  const std::size_t n = h.node_count();
  std::vector<glm::vec4> decoded(n);
  std::vector<std::int32_t> index(n);
  parallel_for(n, [&](std::size_t b, std::size_t e) {
    for (std::size_t i = b; i < e; ++i)
      decoded[i] = glm::vec4(grids[p.page_of[i]].centers[p.local[i]], 0.0f);
  });
  for (int d = h.level_count() - 1; d >= 0; --d) {
    const NodeId lb = h.level_begin(d), le = h.level_begin(d + 1);
    parallel_for(le - lb, [&](std::size_t b, std::size_t e) {
      for (NodeId i = lb + NodeId(b); i < lb + NodeId(e); ++i) {
        float need = h.radius(i);
        if (const unsigned cc = a.child_count[i]; cc != 0) {
          need = 0.0f;
          for (NodeId c = a.first_child[i]; c < a.first_child[i] + cc; ++c)
            need = std::max(
                need, glm::distance(glm::vec3(decoded[c]), glm::vec3(decoded[i])) + decoded[c].w);
          need = need * (1.0f + 4e-6f) + 1e-30f;
        }
        index[i] = radius_index(need);
        decoded[i].w = radius_at(index[i]);
      }
    });
  }
  for (std::size_t page = 0; page + 1 < p.first.size(); ++page) {
    std::int32_t lo = std::numeric_limits<std::int32_t>::max(),
                 hi = std::numeric_limits<std::int32_t>::min();
    for (std::uint64_t k = p.first[page]; k < p.first[page + 1]; ++k)
      lo = std::min(lo, index[p.list[k]]), hi = std::max(hi, index[p.list[k]]);
    const std::int32_t octave = lo >= 0 ? lo / 512 : -((511 - lo) / 512);
    if (hi - 512 * octave > 65535) throw std::runtime_error("a page's radii span more than 2^127");
    grids[page].radius_exp = octave;
  }
  return index;
}

PageCodes page_codes(const Hierarchy& h, std::span<const NodeId> nodes, const Grid& g,
                     const std::vector<std::int32_t>& radius, const Partition& p,
                     std::uint32_t page) {
  const HierarchyArrays& a = h.arrays();
  PageHead head{};
  for (std::size_t k = 0; k < 3; ++k) head.lo[k] = g.axis[k].lo, head.step_exp[k] = g.axis[k].exp;
  head.radius_exp = g.radius_exp;
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
    const glm::i16vec4 nc = a.normal_cone[i];
    const bool no_normal = nc.x == 0 && nc.y == 0 && nc.z == 0;
    c.cc[k] = static_cast<std::uint8_t>(
        cc | (cc != 0 && p.page_of[a.first_child[i]] != page ? kExternal : 0) |
        (no_normal ? kNoNormal : 0));
    if (!no_normal) {
      const Oct code = encode_oct({nc.x, nc.y, nc.z});
      c.oct[0][k] = code[0], c.oct[1][k] = code[1];
    }
    for (std::size_t axis = 0; axis < 3; ++axis)
      c.q[axis][k] = encode_axis(g.centers[k][static_cast<int>(axis)], g.axis[axis]);
    c.radius[k] = static_cast<std::uint16_t>(radius[i] - 512 * g.radius_exp);
    for (int m = 0; m < 4; ++m) c.normal[m][k] = a.normal_cone[i][m];
    for (int m = 0; m < 4; ++m) c.color[m][k] = a.color[i][m];
    c.priority[k] = encode_priority(a.priority[i]);
    if (cc != 0) c.splat[k] = encode_splat(a.splat_radius[i], radius_at(radius[i]));
    std::size_t s = 0;
    for (const NodeAttribute& attribute : h.attributes())
      if (!attribute.is_constant()) std::memcpy(&c.values[s++][k], &attribute.values[i], 4);
  }
  return c;
}

}  // namespace

Encoded encode(const Hierarchy& h) {
  const Partition p = partition(h);
  const std::size_t pages = p.first.size() - 1;
  auto nodes_of = [&](std::size_t page) {
    return std::span<const NodeId>(p.list.data() + p.first[page],
                                   p.first[page + 1] - p.first[page]);
  };
  std::vector<Grid> grids(pages);
  parallel_for(
      pages,
      [&](std::size_t b, std::size_t e) {
        for (std::size_t k = b; k < e; ++k) grids[k] = page_grid(h, nodes_of(k));
      },
      0, 1);
  const std::vector<std::int32_t> radius = radius_indices(h, p, grids);

  Encoded out;
  out.table.resize(pages);
  out.pages.resize(pages);
  parallel_for(
      pages,
      [&](std::size_t b, std::size_t e) {
        for (std::size_t k = b; k < e; ++k) {
          const std::span<const NodeId> nodes = nodes_of(k);
          const std::vector<unsigned char> raw = write_planes(
              page_codes(h, nodes, grids[k], radius, p, static_cast<std::uint32_t>(k)));
          std::vector<unsigned char>& packed = out.pages[k];
          packed.resize(ZSTD_compressBound(raw.size()));
          const std::size_t size =
              ZSTD_compress(packed.data(), packed.size(), raw.data(), raw.size(), 3);
          if (ZSTD_isError(size))
            throw std::runtime_error(std::string("zstd: ") + ZSTD_getErrorName(size));
          packed.resize(size);
          PageRecord& r = out.table[k];
          std::memset(&r, 0, sizeof r);
          Checksum sum;
          sum.update(packed.data(), packed.size());
          r.checksum = sum.finish();
          r.bytes = static_cast<std::uint32_t>(size);
          r.raw_bytes = static_cast<std::uint32_t>(raw.size());
          r.node_count = static_cast<std::uint32_t>(nodes.size());
          const NodeId root = nodes[0];
          r.parent_page = root == 0 ? kNoPage : p.page_of[h.parent(root)];
          r.parent_local = root == 0 ? 0 : p.local[h.parent(root)];
          r.root_depth = h.arrays().depth[root];
          glm::vec3 lo(INFINITY), hi(-INFINITY);
          for (std::size_t m = 0; m < nodes.size(); ++m) {
            const float r_i = radius_at(radius[nodes[m]]);
            lo = glm::min(lo, grids[k].centers[m] - r_i),
            hi = glm::max(hi, grids[k].centers[m] + r_i);
          }
          grids[k] = Grid{};  // its centers: no longer needed
          for (int a = 0; a < 3; ++a) r.bounds[a] = lo[a], r.bounds[a + 3] = hi[a];
        }
      },
      0, 1);
  return out;
}
}  // namespace treecut::cache_pages
