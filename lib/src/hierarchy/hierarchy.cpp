// QSplat-style bounding-sphere hierarchy, built top-down by median splits and
// filled bottom-up (Rusinkiewicz & Levoy, "QSplat: A Multiresolution Point
// Rendering System for Large Meshes", SIGGRAPH 2000, section 3.1; cited as
// [Rus00] in ../shared/papers/parallel-treecut-manipulation.txt).
//
// build_hierarchy runs five named stages; each consumes the previous one's
// output and releases what it no longer needs, so the peak memory stays near
// the size of the result:
//   1. order_points:   PointSet positions -> build items and bounding box;
//   2. build_topology: items -> the tree's shape, level by level, by QSplat's
//                      split (median of the longest axis, twice: four children);
//   3. fill_leaves:    PointSet attributes -> the leaves' node arrays;
//   4. fill_interior:  children -> parents, deepest level first (QSplat's
//                      bottom-up pass: bounding sphere, normal cone, color,
//                      and the splat drawn for the node);
//   5. assemble:       node arrays -> an immutable Hierarchy.
// Stages 2-4 are data-parallel over the nodes of one level. Nothing depends on
// the thread count, so the output is byte-identical for any number of workers.
#include "treecut/hierarchy.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <functional>
#include <glm/geometric.hpp>
#include <iterator>
#include <numeric>
#include <stdexcept>
#include <thread>
#include <vector>

#include "bottom_up.hpp"
#include "node_arrays.hpp"
#include "node_attributes.hpp"
#include "subtree_roots.hpp"
#include "treecut/parallel.hpp"

namespace treecut {

namespace {

struct OwnedArrays : detail::NodeArrays {
  std::vector<detail::OwnedAttribute> attributes;  // the file's scalars per node
};

struct Item {  // a point in build order: its position and its index in the PointSet
  glm::vec3 p;
  std::uint32_t index;
};

struct Range {
  std::uint32_t begin, end;
};

int longest_axis(const Item* first, const Item* last) {
  // Plain scalar min/max: the compiler vectorizes this, glm's calls it does not.
  float lx = INFINITY, ly = INFINITY, lz = INFINITY, hx = -INFINITY, hy = -INFINITY, hz = -INFINITY;
  for (const Item* it = first; it != last; ++it) {
    lx = std::min(lx, it->p.x), hx = std::max(hx, it->p.x);
    ly = std::min(ly, it->p.y), hy = std::max(hy, it->p.y);
    lz = std::min(lz, it->p.z), hz = std::max(hz, it->p.z);
  }
  const float ex = hx - lx, ey = hy - ly, ez = hz - lz;
  return ex >= ey && ex >= ez ? 0 : (ey >= ez ? 1 : 2);
}

// The children of a range: up to four, from two levels of binary median
// splits (QSplat's branching factor). Ranges of two to four points get one
// leaf per point, so every leaf is one point and the depth is at most
// ceil(log2(n) / 2) + 1, even for duplicate or colinear points. A range of
// seven or eight points takes one split, two children of three or four:
// four children of about two would be four parents of two leaves each
// (13 nodes for 8 points, 11 this way). Where the levels leave such ranges
// at the bottom (n / 4^levels near 2) that is most of the tree: a survey of
// 2 M points had 1.65 nodes a point, 1.44 this way. Five or six points
// split four ways still: two children would hold more than one point each.
// The split positions depend on the counts only, so the topology is known
// before any point moves; partition() then moves the points to match.
int child_ranges(Range r, Range out[4]) {
  const std::uint32_t n = r.end - r.begin;
  if (n <= 1) return 0;
  if (n <= 4) {
    for (std::uint32_t i = 0; i < n; ++i) out[i] = {r.begin + i, r.begin + i + 1};
    return static_cast<int>(n);
  }
  const std::uint32_t m = r.begin + n / 2;
  if (n >= 7 && n <= 8) {
    out[0] = {r.begin, m};
    out[1] = {m, r.end};
    return 2;
  }
  const std::uint32_t m0 = r.begin + (m - r.begin) / 2;
  const std::uint32_t m1 = m + (r.end - m) / 2;
  out[0] = {r.begin, m0};
  out[1] = {m0, m};
  out[2] = {m, m1};
  out[3] = {m1, r.end};
  return 4;
}

// Moves the points of [b, e) so that [b, m) lies below m along the longest
// axis of the range. One thread owns a range and nth_element is
// deterministic, so the result is a pure function of the input.
template <int Axis>
void select(Item* items, std::uint32_t b, std::uint32_t m, std::uint32_t e) {
  // A compile-time axis: glm's operator[] is a switch, too slow for the comparator.
  auto key = [](const Item& it) { return Axis == 0 ? it.p.x : Axis == 1 ? it.p.y : it.p.z; };
  std::nth_element(items + b, items + m, items + e,
                   [key](const Item& l, const Item& r) { return key(l) < key(r); });
}

void split_at(Item* items, std::uint32_t b, std::uint32_t m, std::uint32_t e) {
  switch (longest_axis(items + b, items + e)) {
    case 0:
      return select<0>(items, b, m, e);
    case 1:
      return select<1>(items, b, m, e);
    default:
      return select<2>(items, b, m, e);
  }
}

void partition(Item* items, Range r) {
  Range c[4];
  const int cc = child_ranges(r, c);
  if (r.end - r.begin <= 4) return;  // single points need no order
  if (cc == 2) return split_at(items, r.begin, c[1].begin, r.end);
  split_at(items, r.begin, c[2].begin, r.end);
  // The halves are disjoint: at the top of the tree, where a level has fewer
  // nodes than threads, split them at the same time.
  if (r.end - r.begin >= (1u << 17) && worker_count() > 1) {
    std::jthread other([&] { split_at(items, r.begin, c[1].begin, c[2].begin); });
    split_at(items, c[2].begin, c[3].begin, r.end);
    return;
  }
  split_at(items, r.begin, c[1].begin, c[2].begin);
  split_at(items, c[2].begin, c[3].begin, r.end);
}

template <class T>
void release(std::vector<T>& v) {
  std::vector<T>().swap(v);
}

// Angle between two directions of any length: atan2 stays accurate for small
// angles, where acos of a dot product of slightly non-unit (quantized)
// vectors is off by more than the angle itself.
float angle_between(glm::vec3 a, glm::vec3 b) {
  return std::atan2(glm::length(glm::cross(a, b)), glm::dot(a, b));
}

float clamp01(float x) {
  return std::min(1.0f, std::max(0.0f, x));
}

// A node's own geometric error: how far its normals spread, (1 - cos)/2 in [0,1].
float cone_priority(float cone_cos) {
  return clamp01(0.5f * (1.0f - cone_cos));
}

// Progress in work units, reported from the building thread: N per topology
// level (capped at N), then N / levels per interior level (capped at 2N).
class BuildProgress {
 public:
  BuildProgress(const BuildOptions& options, std::uint32_t points)
      : report_(options.progress), total_(2 * std::size_t{points}) {}
  void topology_level(std::size_t units) {
    done_ += units;
    report(std::min(done_, total_ / 2));
  }
  void interior_level(std::size_t units) {
    done_ += units;
    report(std::min(done_, total_));
  }
  void finish() { report(total_); }

 private:
  void report(std::size_t done) const {
    if (report_) report_(done, total_);
  }
  const std::function<void(std::size_t, std::size_t)>& report_;
  std::size_t done_ = 0;
  std::size_t total_;
};

// ---- Stage 1: order the points ---------------------------------------------

struct BuildOrder {
  std::vector<Item> items;  // every point, moved by build_topology into split order
  glm::vec3 bounds_min{INFINITY}, bounds_max{-INFINITY};
};

// Consumes points.positions (and the triangles, which the hierarchy ignores);
// produces one Item per point in input order and the model's bounding box.
BuildOrder order_points(PointSet& points) {
  const auto N = static_cast<std::uint32_t>(points.size());
  BuildOrder o;
  o.items.resize(N);
  for (std::uint32_t i = 0; i < N; ++i) {
    o.items[i] = {points.positions[i], i};
    o.bounds_min = glm::min(o.bounds_min, points.positions[i]);
    o.bounds_max = glm::max(o.bounds_max, points.positions[i]);
  }
  release(points.positions);
  release(points.triangles);
  return o;
}

// ---- Stage 2: topology -----------------------------------------------------

struct Topology {
  std::vector<Range> ranges;        // each node's span of the items; a leaf's is one point
  std::vector<NodeId> level_begin;  // first node of each depth, then the node count
};

// QSplat's split (section 3.1), one level at a time: partition() reorders each
// node's items about the medians, child_ranges() names the children. Produces
// a.parent, a.depth, a.first_child and a.child_count in breadth-first order,
// and every node's range of `items`, which fill_leaves consumes.
Topology build_topology(std::vector<Item>& items, OwnedArrays& a, unsigned threads,
                        BuildProgress& progress) {
  const auto N = static_cast<std::uint32_t>(items.size());
  Topology t{{{0, N}}, {0}};
  std::vector<Range>& ranges = t.ranges;
  std::vector<NodeId>& level_begin = t.level_begin;
  // Capacity only: untouched pages cost no memory. Interior nodes < N.
  ranges.reserve(2 * std::size_t{N});
  a.parent.reserve(2 * std::size_t{N});
  a.depth.reserve(2 * std::size_t{N});
  a.first_child.reserve(2 * std::size_t{N});
  a.child_count.reserve(2 * std::size_t{N});
  a.parent.push_back(kNoNode);
  a.depth.push_back(0);
  for (int depth = 0;; ++depth) {
    const std::size_t lb = level_begin.back(), le = ranges.size();
    if (lb == le) break;
    if (depth > 255) throw std::logic_error("build_hierarchy: depth exceeds 255");
    level_begin.push_back(static_cast<NodeId>(le));
    parallel_for(
        le - lb,
        [&](std::size_t b, std::size_t e) {
          for (std::size_t i = lb + b; i < lb + e; ++i) partition(items.data(), ranges[i]);
        },
        threads, 1);
    for (std::size_t i = lb; i < le; ++i) {
      Range c[4];
      const int cc = child_ranges(ranges[i], c);
      a.first_child.push_back(cc ? static_cast<NodeId>(ranges.size()) : kNoNode);
      a.child_count.push_back(static_cast<std::uint8_t>(cc));
      for (int k = 0; k < cc; ++k) {
        ranges.push_back(c[k]);
        a.parent.push_back(static_cast<NodeId>(i));
        a.depth.push_back(static_cast<std::uint8_t>(depth + 1));
      }
    }
    progress.topology_level(N);
  }
  return t;
}

// ---- Stage 3: leaves -------------------------------------------------------

// Consumes the ranges, the items and the PointSet's radii, normals, colors and
// curvature, one array at a time (each released as soon as it is copied);
// produces every leaf's center_radius, normal_cone, color, priority and
// point_count. Interior entries are sized but left for fill_interior.
void fill_leaves(OwnedArrays& a, std::vector<Range>&& ranges, std::vector<Item>&& items,
                 PointSet& points, unsigned threads) {
  const std::size_t M = ranges.size();
  // A leaf's point, in `items` order; remembered in first_child (unused by
  // leaves) until the arrays are final.
  std::vector<NodeId>& leaf_point = a.first_child;
  for (std::size_t i = 0; i < M; ++i)
    if (a.child_count[i] == 0) leaf_point[i] = ranges[i].begin;
  release(ranges);

  a.center_radius.resize(M);
  a.splat_radius.resize(M);
  parallel_for(
      M,
      [&](std::size_t b, std::size_t e) {
        for (std::size_t i = b; i < e; ++i)
          if (a.child_count[i] == 0) {
            const Item& it = items[leaf_point[i]];
            const float r = points.radii[it.index];
            a.center_radius[i] = glm::vec4(it.p, r);
            a.splat_radius[i] = r;
          }
      },
      threads);
  // From here on a leaf refers to its PointSet index directly.
  for (std::size_t i = 0; i < M; ++i)
    if (a.child_count[i] == 0) leaf_point[i] = items[leaf_point[i]].index;
  release(items);
  release(points.radii);

  a.normal_cone.resize(M);
  parallel_for(
      M,
      [&](std::size_t b, std::size_t e) {
        for (std::size_t i = b; i < e; ++i)
          if (a.child_count[i] == 0) {
            const glm::vec3 nrm = points.normals[leaf_point[i]];
            const float len = glm::length(nrm);
            // A point without a defined normal can face anywhere: full cone.
            a.normal_cone[i] = len > 0.5f ? pack_normal_cone(nrm / len, 1.0f)
                                          : pack_normal_cone(glm::vec3(0.0f), -1.0f);
          }
      },
      threads);
  release(points.normals);

  a.color.resize(M);
  const bool has_colors = points.has_colors();
  parallel_for(
      M,
      [&](std::size_t b, std::size_t e) {
        for (std::size_t i = b; i < e; ++i)
          if (a.child_count[i] == 0)
            a.color[i] = has_colors ? points.colors[leaf_point[i]] : kUncoloured;
      },
      threads);
  release(points.colors);

  a.attributes = detail::fill_leaf_values(points.attributes, leaf_point, a.child_count, threads);

  a.priority.resize(M);
  a.point_count.resize(M);
  parallel_for(
      M,
      [&](std::size_t b, std::size_t e) {
        for (std::size_t i = b; i < e; ++i)
          if (a.child_count[i] == 0) {
            // Surface variation lies in [0, 1/3]; scale it to [0, 1].
            a.priority[i] = clamp01(3.0f * points.curvature[leaf_point[i]]);
            a.point_count[i] = 1;
            leaf_point[i] = kNoNode;
          }
      },
      threads);
  release(points.curvature);
}

// ---- Stage 4: interior nodes -----------------------------------------------

// The sphere of node i from its children's spheres c0 .. c0 + cc: center at
// the midpoint of the box [lo, hi] around them (or, with at_real_point, the
// child center nearest to it), radius the smallest that bounds them.
glm::vec4 enclosing_sphere(const OwnedArrays& a, std::size_t c0, unsigned cc, glm::vec3 lo,
                           glm::vec3 hi, bool at_real_point) {
  glm::vec3 center = 0.5f * (lo + hi);
  if (at_real_point) {
    std::size_t best = c0;
    float best_d = INFINITY;
    for (std::size_t c = c0; c < c0 + cc; ++c) {
      const float dd = glm::distance(glm::vec3(a.center_radius[c]), center);
      if (dd < best_d) best_d = dd, best = c;
    }
    center = glm::vec3(a.center_radius[best]);
  }
  float radius = 0.0f;
  for (std::size_t c = c0; c < c0 + cc; ++c)
    radius = std::max(radius,
                      glm::distance(center, glm::vec3(a.center_radius[c])) + a.center_radius[c].w);
  // Guard the containment invariant against float rounding.
  radius = radius * (1.0f + 4e-6f) + 1e-30f;
  return glm::vec4(center, radius);
}

// The cone cosine around the (non-zero) weighted normal sum `nsum` that covers
// every child's cone, measured with the quantized values that are stored;
// -1 (full cone) when the sum vanishes or a child faces anywhere. Writes the
// cone's axis to `nrm`.
float children_cone_cos(const OwnedArrays& a, std::size_t c0, unsigned cc, glm::vec3 nsum,
                        glm::vec3& nrm) {
  const float nlen = glm::length(nsum);
  nrm = glm::vec3(0.0f);
  if (!(nlen > 1e-6f)) return -1.0f;
  nrm = nsum / nlen;
  const glm::i16vec4 qn = pack_normal_cone(nrm, 1.0f);
  const glm::vec3 u = glm::normalize(glm::vec3(qn));
  // Work with versines v = 1 - cos and sines: v(a + b) = va + vb - va vb
  // + sa sb. No inverse trigonometry per child, and small angles keep
  // their precision (1 - dot rounds them to zero in float).
  float widest = 0.0f;  // versine of the cone's half-angle
  for (std::size_t c = c0; c < c0 + cc; ++c) {
    const glm::i16vec4 k = a.normal_cone[c];
    const glm::vec3 kv = glm::vec3(k);
    const float cb = static_cast<float>(k.w) * (1.0f / 32767.0f);
    if (glm::dot(kv, kv) < 0.25f * 32767.0f * 32767.0f || cb <= -1.0f + 1e-6f) {
      widest = 2.0f;  // a child facing anywhere: full cone
      break;
    }
    const glm::vec3 w = glm::normalize(kv);
    const glm::vec3 uw = u - w;
    const float va = 0.5f * glm::dot(uw, uw), sa = glm::length(glm::cross(u, w));
    const float vb = 1.0f - cb, sb = std::sqrt(std::max(0.0f, vb * (2.0f - vb)));
    const float ca = 1.0f - va;
    if (sa * cb + ca * sb < 0.0f) {  // the angles add up beyond pi
      widest = 2.0f;
      break;
    }
    widest = std::max(widest, va + vb - va * vb + sa * sb);
  }
  // Widen by 2e-4 rad for the snorm16 rounding of the normals:
  // v(t + e) ~ v(t) + e sin(t) + e^2 / 2.
  if (widest < 2.0f) widest += 2e-4f * std::sqrt(std::max(0.0f, widest * (2.0f - widest))) + 2e-8f;
  return std::max(-1.0f, 1.0f - widest);
}

// One interior node from its children, which are final: QSplat's bounding
// sphere and normal cone (section 3.1), the point-weighted average color, and
// a priority never below a child's (parallel-treecut, section 4.1).
void fill_interior_node(OwnedArrays& a, std::size_t i, bool at_real_point) {
  const unsigned cc = a.child_count[i];
  const std::size_t c0 = a.first_child[i];
  glm::vec3 lo(INFINITY), hi(-INFINITY), nsum(0.0f);
  glm::vec4 csum(0.0f);
  std::uint32_t count = 0;
  float prio = 0.0f;
  double cover2 = 0.0;  // in double: discs of 1e-23 squared underflow a float to 0
  for (std::size_t c = c0; c < c0 + cc; ++c) {
    const glm::vec4 s = a.center_radius[c];
    cover2 += double(a.splat_radius[c]) * double(a.splat_radius[c]);
    lo = glm::min(lo, glm::vec3(s) - s.w);
    hi = glm::max(hi, glm::vec3(s) + s.w);
    const float w = static_cast<float>(a.point_count[c]);
    nsum += w * glm::vec3(a.normal_cone[c]) * (1.0f / 32767.0f);
    csum += w * glm::vec4(a.color[c]);
    count += a.point_count[c];
    prio = std::max(prio, a.priority[c]);
  }
  a.center_radius[i] = enclosing_sphere(a, c0, cc, lo, hi, at_real_point);
  glm::vec3 nrm;
  const float cone_cos = children_cone_cos(a, c0, cc, nsum, nrm);
  a.normal_cone[i] = pack_normal_cone(nrm, cone_cos);
  const glm::vec4 avg = csum / static_cast<float>(count);
  a.color[i] = glm::u8vec4(glm::round(glm::clamp(avg, 0.0f, 255.0f)));
  a.priority[i] = std::max(prio, cone_priority(cone_cos));
  a.point_count[i] = count;
  a.splat_radius[i] =
      static_cast<float>(std::sqrt(cover2));  // the cover; finish_splat_radii bounds it
}

// How much larger than its leaves' discs together (in radius) an interior
// splat may be. On a dense surface the leaves' discs overlap, so their areas
// add up to more than the surface's, and the bounding sphere (QSplat's splat)
// is the smaller of the two: nothing changes there. Where points are
// scattered (vegetation, stray returns) the sum is far below the sphere's
// disc, and the splat keeps the leaves' coverage instead of filling the gaps.
constexpr float kCoverHeadroom = 2.0f;

// Turns every interior node's cover (sqrt of the sum of its leaves' squared
// splat radii, left by fill_interior_node) into the radius drawn.
void finish_splat_radii(OwnedArrays& a, unsigned threads) {
  parallel_for(
      a.splat_radius.size(),
      [&](std::size_t b, std::size_t e) {
        for (std::size_t i = b; i < e; ++i)
          if (a.child_count[i] != 0)
            a.splat_radius[i] = std::min(a.center_radius[i].w, kCoverHeadroom * a.splat_radius[i]);
      },
      threads);
}

// Consumes the leaves' arrays and the topology; produces every interior
// node's center_radius, splat_radius, normal_cone, color, priority and
// point_count, level by level from the deepest, so a node's children are
// final when it is filled.
void fill_interior(OwnedArrays& a, const std::vector<NodeId>& level_begin, std::uint32_t points,
                   bool at_real_point, unsigned threads, BuildProgress& progress) {
  const auto levels = static_cast<std::size_t>(std::max<int>(int(level_begin.size()) - 1, 1));
  detail::for_each_interior_bottom_up(
      level_begin, a.child_count, threads,
      [&](std::size_t i) { fill_interior_node(a, i, at_real_point); },
      [&] { progress.interior_level(points / levels); });
  finish_splat_radii(a, threads);
}

// ---- Stage 5: assemble -----------------------------------------------------

// Hands the node arrays to an immutable Hierarchy that owns them. No
// shrink_to_fit: the spare capacity of the topology arrays was never touched,
// so it costs address space only, while shrinking would copy.
Hierarchy assemble(OwnedArrays&& a, std::vector<NodeId>&& level_begin, const BuildOrder& order,
                   CoordinateFrame frame) {
  auto owned = std::make_shared<OwnedArrays>(std::move(a));
  const HierarchyArrays spans = owned->spans();
  std::vector<NodeAttribute> attributes = detail::node_attribute_views(owned->attributes);
  return Hierarchy::from_arrays(owned, spans, std::move(level_begin), order.bounds_min,
                                order.bounds_max, std::move(frame), std::move(attributes));
}

}  // namespace

detail::TopLevels detail::build_over_roots(std::span<const SubtreeRoot> roots,
                                           const std::vector<NodeAttribute>& attributes,
                                           CoordinateFrame frame, bool parent_at_real_point) {
  if (roots.empty()) throw std::invalid_argument("build_over_roots: no roots");
  const auto N = static_cast<std::uint32_t>(roots.size());
  const BuildOptions quiet;
  BuildProgress progress(quiet, N);
  BuildOrder order;
  for (std::uint32_t k = 0; k < N; ++k) {
    const glm::vec4 s = roots[k].center_radius;
    order.items.push_back({glm::vec3(s), k});
    order.bounds_min = glm::min(order.bounds_min, glm::vec3(s) - s.w);
    order.bounds_max = glm::max(order.bounds_max, glm::vec3(s) + s.w);
  }
  OwnedArrays a;
  Topology t = build_topology(order.items, a, 1, progress);
  const std::size_t M = t.ranges.size();
  TopLevels top;
  top.root_of.assign(M, kNoNode);
  a.center_radius.resize(M), a.splat_radius.resize(M), a.normal_cone.resize(M);
  a.color.resize(M), a.priority.resize(M), a.point_count.resize(M);
  for (const NodeAttribute& shape : attributes) {
    OwnedAttribute& owned = a.attributes.emplace_back();
    owned.name = shape.name, owned.kind = shape.kind, owned.offset = shape.offset;
    owned.min = shape.min, owned.max = shape.max, owned.constant = shape.constant;
    if (!shape.is_constant()) owned.values.resize(M);
  }
  for (std::size_t i = 0; i < M; ++i) {
    if (a.child_count[i] != 0) continue;
    const std::uint32_t k = order.items[t.ranges[i].begin].index;
    const SubtreeRoot& r = roots[k];
    top.root_of[i] = k;
    a.center_radius[i] = r.center_radius;
    a.splat_radius[i] = r.cover;  // the cover, as an interior child's is while parents fill
    a.normal_cone[i] = r.normal_cone;
    a.color[i] = r.color;
    a.priority[i] = r.priority;
    a.point_count[i] = r.point_count;
    for (std::size_t s = 0; s < a.attributes.size(); ++s)
      if (!a.attributes[s].values.empty()) a.attributes[s].values[i] = r.values.at(s);
  }
  fill_interior(a, t.level_begin, N, parent_at_real_point, 1, progress);
  detail::fill_interior_values(a.attributes, a.child_count, a.first_child, a.point_count,
                               t.level_begin, 1);
  // The leaves keep their covers as drawn radii: they stand for the roots,
  // whose pages are written apart (the leaves themselves are not).
  top.hierarchy = assemble(std::move(a), std::move(t.level_begin), order, std::move(frame));
  return top;
}

glm::i16vec4 pack_normal_cone(glm::vec3 normal, float cone_cos) {
  auto q = [](float v) {  // round to nearest (lround is a library call, this is not)
    const float x = std::clamp(v, -1.0f, 1.0f) * 32767.0f;
    return static_cast<std::int16_t>(x + (x >= 0.0f ? 0.5f : -0.5f));
  };
  // The cone is rounded towards wider (smaller cosine) so it stays conservative.
  const auto c =
      static_cast<std::int16_t>(std::floor(std::clamp(cone_cos, -1.0f, 1.0f) * 32767.0f));
  return {q(normal.x), q(normal.y), q(normal.z), std::max<std::int16_t>(c, -32767)};
}

std::size_t Hierarchy::memory_bytes() const {
  const std::size_t n = node_count_;
  std::size_t bytes =
      n * (sizeof(glm::vec4) + sizeof(float) + sizeof(glm::i16vec4) + sizeof(glm::u8vec4) +
           sizeof(float) + sizeof(std::uint32_t) + 2 * sizeof(NodeId) + 2 * sizeof(std::uint8_t));
  for (const NodeAttribute& a : attributes_) bytes += a.values.size_bytes();
  return bytes;
}

const NodeAttribute* Hierarchy::find_attribute(std::string_view name) const {
  for (const NodeAttribute& a : attributes_) {
    if (a.name == name) return &a;
  }
  return nullptr;
}

Hierarchy Hierarchy::from_arrays(std::shared_ptr<const void> storage, const HierarchyArrays& a,
                                 std::vector<NodeId> level_begin, glm::vec3 bounds_min,
                                 glm::vec3 bounds_max, CoordinateFrame frame,
                                 std::vector<NodeAttribute> attributes) {
  const std::size_t n = a.center_radius.size();
  for (const NodeAttribute& attribute : attributes) {
    if (!attribute.values.empty() && attribute.values.size() != n)
      throw std::invalid_argument("attribute values differ in size");
  }
  if (a.splat_radius.size() != n || a.normal_cone.size() != n || a.color.size() != n ||
      a.priority.size() != n || a.point_count.size() != n || a.parent.size() != n ||
      a.first_child.size() != n || a.child_count.size() != n || a.depth.size() != n)
    throw std::invalid_argument("hierarchy arrays differ in size");
  if (level_begin.empty() || level_begin.front() != 0 || level_begin.back() != n)
    throw std::invalid_argument("hierarchy level table does not span the nodes");
  Hierarchy h;
  h.storage_ = std::move(storage);
  h.a_ = a;
  h.level_begin_ = std::move(level_begin);
  h.node_count_ = static_cast<std::uint32_t>(n);
  h.leaf_count_ = n ? a.point_count[0] : 0;
  h.bounds_min_ = bounds_min;
  h.bounds_max_ = bounds_max;
  h.frame_ = std::move(frame);
  h.attributes_ = std::move(attributes);
  return h;
}

Hierarchy build_hierarchy(PointSet&& points, const BuildOptions& options) {
  const std::size_t n_points = points.size();
  if (n_points == 0) throw std::invalid_argument("build_hierarchy: no points");
  if (n_points >= (std::size_t{1} << 31))
    throw std::invalid_argument("build_hierarchy: more than 2^31 points");
  if (!points.has_normals() || !points.has_radii() || !points.has_curvature())
    throw std::invalid_argument("build_hierarchy: normals, radii and curvature are required");
  const unsigned threads = worker_count(options.threads);
  const auto N = static_cast<std::uint32_t>(n_points);
  BuildProgress progress(options, N);

  CoordinateFrame frame = points.frame;
  BuildOrder order = order_points(points);
  OwnedArrays a;
  Topology topology = build_topology(order.items, a, threads, progress);
  fill_leaves(a, std::move(topology.ranges), std::move(order.items), points, threads);
  fill_interior(a, topology.level_begin, N, options.parent_at_real_point, threads, progress);
  detail::fill_interior_values(a.attributes, a.child_count, a.first_child, a.point_count,
                               topology.level_begin, threads);
  progress.finish();
  return assemble(std::move(a), std::move(topology.level_begin), order, std::move(frame));
}

std::string check_invariants(const Hierarchy& h) {
  if (h.empty()) return "empty hierarchy";
  const auto& a = h.arrays();
  const std::uint32_t M = h.node_count();
  auto fail = [](NodeId n, const std::string& what) {
    return "node " + std::to_string(n) + ": " + what;
  };
  if (a.parent[0] != kNoNode) return fail(0, "root has a parent");
  std::uint64_t leaves = 0;
  for (int d = 0; d < h.level_count(); ++d)
    for (NodeId n = h.level_begin(d); n < h.level_begin(d + 1); ++n)
      if (a.depth[n] != d) return fail(n, "depth does not match its level");
  for (NodeId n = 0; n < M; ++n) {
    const unsigned cc = a.child_count[n];
    const glm::vec4 s = a.center_radius[n];
    if (!std::isfinite(s.x) || !std::isfinite(s.y) || !std::isfinite(s.z) || !(s.w > 0.0f) ||
        !std::isfinite(s.w))
      return fail(n, "non-finite center or non-positive radius");
    if (cc == 0) {
      ++leaves;
      if (a.point_count[n] != 1) return fail(n, "leaf does not hold exactly one point");
      if (a.splat_radius[n] != s.w) return fail(n, "leaf splat radius is not its radius");
      continue;
    }
    if (cc < 2 || cc > 4) return fail(n, "child count outside 2..4");
    const NodeId c0 = a.first_child[n];
    if (c0 <= n || c0 + cc > M) return fail(n, "children out of range");
    std::uint64_t count = 0;
    const glm::vec3 pn = h.normal(n);
    const float pc = h.cone_cos(n);
    const float p_half = std::acos(std::clamp(pc, -1.0f, 1.0f));
    for (NodeId c = c0; c < c0 + cc; ++c) {
      if (a.parent[c] != n) return fail(c, "parent link does not match");
      if (a.depth[c] != a.depth[n] + 1) return fail(c, "depth is not parent's + 1");
      count += a.point_count[c];
      const glm::vec4 cs = a.center_radius[c];
      const float reach = glm::distance(glm::vec3(cs), glm::vec3(s)) + cs.w;
      if (reach > s.w * (1.0f + 1e-5f)) return fail(c, "sphere not inside the parent's sphere");
      if (a.priority[c] > a.priority[n]) return fail(c, "priority above the parent's");
      if (pc > -1.0f + 1e-4f) {
        const glm::vec3 cn = h.normal(c);
        if (glm::dot(cn, cn) < 0.25f) return fail(c, "normal undefined inside a bounded cone");
        const float between = angle_between(pn, cn);
        const float c_half = std::acos(std::clamp(h.cone_cos(c), -1.0f, 1.0f));
        if (between + c_half > p_half + 5e-4f)
          return fail(c, "normal cone not inside the parent's");
      }
    }
    if (count != a.point_count[n]) return fail(n, "point count is not the children's sum");
    if (!(a.splat_radius[n] > 0.0f) || !(a.splat_radius[n] <= s.w))
      return fail(n, "splat radius not in (0, bounding radius]");
  }
  if (leaves != h.leaf_count()) return "leaf count differs from the root's point count";
  // Median splits halve the points at every binary level: depth <= ceil(log4 n) + 1.
  const double bound =
      std::ceil(std::log2(std::max<double>(2.0, static_cast<double>(leaves))) / 2.0) + 1.0;
  if (h.level_count() - 1 > bound)
    return "depth " + std::to_string(h.level_count() - 1) + " exceeds the bound";
  return {};
}

std::vector<NodeId> sample_leaves(const Hierarchy& h, std::span<const NodeRange> known,
                                  std::size_t most) {
  const auto is_known = [&](NodeId id) {
    const auto after = std::upper_bound(known.begin(), known.end(), id,
                                        [](NodeId v, const NodeRange& r) { return v < r.first; });
    return after != known.begin() && id - std::prev(after)->first < std::prev(after)->count;
  };
  // Children are consecutive and in one page: the first tells.
  const auto known_leaf = [&](NodeId n) {
    return h.child_count(n) == 0 || !is_known(h.first_child(n));
  };
  std::uint64_t total = 0;
  for (const NodeRange& r : known) total += r.count;
  const std::uint64_t stride = std::max<std::uint64_t>(1, total / std::max<std::size_t>(most, 1));
  std::vector<NodeId> out;
  std::uint64_t k = 0, base = 0;  // the next sample's place among KNOWN's nodes, a range's
  for (const NodeRange& r : known) {
    for (; k < base + r.count; k += stride)
      if (const auto n = static_cast<NodeId>(r.first + (k - base)); known_leaf(n)) out.push_back(n);
    base += r.count;
  }
  if (out.empty()) {
    // Only possible with a stride that skipped every leaf: read them all.
    for (const NodeRange& r : known)
      for (NodeId n = r.first; n < r.first + r.count; ++n)
        if (known_leaf(n)) out.push_back(n);
  }
  return out;
}

}  // namespace treecut
