// Hierarchy: a QSplat-style bounding-sphere hierarchy over a PointSet
// (Rusinkiewicz & Levoy, "QSplat", SIGGRAPH 2000), stored as flat arrays.
//
// Node ids are breadth-first: the root is 0, the nodes of depth d are the
// contiguous range [level_begin(d), level_begin(d+1)), and the children of a
// node are the contiguous range [first_child, first_child + child_count).
// Every node is a splat; the leaves are exactly the input points.
//
// A Hierarchy is immutable once built. Copies are cheap and share storage, which
// may be heap memory or a read-only memory mapping of a cache file; every span
// returned stays valid as long as any copy of the Hierarchy lives. All const
// members may be called from any thread.
#pragma once

#include <cstdint>
#include <functional>
#include <glm/ext/vector_double3.hpp>
#include <glm/gtc/type_precision.hpp>
#include <glm/vec3.hpp>
#include <glm/vec4.hpp>
#include <limits>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "treecut/point_set.hpp"

namespace treecut {

using NodeId = std::uint32_t;
inline constexpr NodeId kNoNode = std::numeric_limits<NodeId>::max();

/// Consecutive node ids [first, first + count).
struct NodeRange {
  NodeId first = 0;
  std::uint32_t count = 0;
};

/// The colour of the points of a file without colours.
inline const glm::u8vec4 kUncoloured{200, 200, 200, 255};

/// The arrays of a hierarchy; all have node_count() elements.
struct HierarchyArrays {
  /// xyz: splat/sphere center, w: radius of the sphere bounding the node's whole
  /// subtree (for a leaf: its splat radius). Model units.
  std::span<const glm::vec4> center_radius;
  /// The radius of the disc drawn for the node: a leaf's splat radius; for an
  /// interior node the bounding radius, or less where its subtree is sparse
  /// (at most the radius of a disc as large as its leaves' discs together,
  /// with headroom), so a coarse cut over scattered points is not drawn as
  /// discs spanning the gaps between them. Model units; never above
  /// center_radius.w. Only drawing uses it: culling and refinement use the
  /// bound.
  std::span<const float> splat_radius;
  /// xyz: unit normal, w: cosine of the half-angle of the cone that contains the
  /// normals of the whole subtree (1 for a leaf), all snorm16 (divide by 32767).
  std::span<const glm::i16vec4> normal_cone;
  std::span<const glm::u8vec4> color;  ///< sRGB, alpha 255
  /// Static refinement priority: surface variation of the subtree, monotone
  /// (a parent's priority is >= each child's). In [0, 1].
  std::span<const float> priority;
  std::span<const std::uint32_t> point_count;  ///< leaves under the node (1 for a leaf)
  std::span<const NodeId> parent;              ///< kNoNode for the root
  std::span<const NodeId> first_child;         ///< meaningful only if child_count > 0
  std::span<const std::uint8_t> child_count;   ///< 0 for a leaf, else 2..4
  std::span<const std::uint8_t> depth;         ///< root 0
};

/// One of the file's per-point scalars over the nodes (PointSet::attributes):
/// a leaf holds its point's value, an interior node its subtree's summary
/// (a measure's point-weighted mean, a category's most frequent value), as
/// a float relative to `offset`, which keeps classes exact and a GPS time
/// to microseconds; an attribute with one value at every point holds it
/// once.
struct NodeAttribute {
  std::string name;
  AttributeKind kind = AttributeKind::measure;
  double offset = 0.0;  ///< the file's value is offset + value(n)
  /// The points' smallest and largest values, the file's (exact); NaN when
  /// none has a value.
  double min = 0.0, max = 0.0;
  std::span<const float> values;  ///< node_count() values, NaN: no value; empty: constant
  float constant = 0.0f;          ///< every node's value when `values` is empty

  [[nodiscard]] bool is_constant() const { return values.empty(); }
  [[nodiscard]] float value(NodeId n) const { return values.empty() ? constant : values[n]; }
};

/// What the model's file said when it was read, kept with the hierarchy
/// (and in its cache) so that a warm open says the same as the first
/// (issue 43, item 18).
struct SourceNotes {
  /// The file's format as `info` words it ("LAS 1.4, point format 6 (30
  /// bytes a point), from LAStools"; "PLY", "PCD", "text"); empty when
  /// unknown (built from points in memory).
  std::string format;
  /// The read's warnings, one line each, as they were printed.
  std::vector<std::string> warnings;
};

class Hierarchy {
 public:
  Hierarchy() = default;

  [[nodiscard]] bool empty() const { return node_count_ == 0; }
  [[nodiscard]] std::uint32_t node_count() const { return node_count_; }
  [[nodiscard]] std::uint32_t leaf_count() const { return leaf_count_; }
  [[nodiscard]] NodeId root() const { return 0; }
  /// Number of levels (max depth + 1).
  [[nodiscard]] int level_count() const { return static_cast<int>(level_begin_.size()) - 1; }
  /// First node id of depth d; level_begin(level_count()) == node_count().
  [[nodiscard]] NodeId level_begin(int d) const {
    return level_begin_[static_cast<std::size_t>(d)];
  }
  [[nodiscard]] glm::vec3 bounds_min() const { return bounds_min_; }
  [[nodiscard]] glm::vec3 bounds_max() const { return bounds_max_; }
  /// How the node positions relate to the model file's coordinates
  /// (PointSet::frame): a node at p lies at frame().origin + p there; 0 for
  /// models read as floats, near the points for map coordinates (LAS).
  [[nodiscard]] const CoordinateFrame& frame() const { return frame_; }
  /// What the file said when it was read (cached with the hierarchy).
  [[nodiscard]] const SourceNotes& notes() const { return notes_; }
  /// A copy (sharing the arrays) with NOTES.
  [[nodiscard]] Hierarchy with_notes(SourceNotes notes) const {
    Hierarchy h = *this;
    h.notes_ = std::move(notes);
    return h;
  }
  [[nodiscard]] const HierarchyArrays& arrays() const { return a_; }
  /// The file's other per-point scalars, in file order (may be none).
  [[nodiscard]] const std::vector<NodeAttribute>& attributes() const { return attributes_; }
  /// The attribute called NAME, or null.
  [[nodiscard]] const NodeAttribute* find_attribute(std::string_view name) const;
  /// Bytes held by the node arrays (what a cache maps).
  [[nodiscard]] std::size_t memory_bytes() const;

  [[nodiscard]] bool is_leaf(NodeId n) const { return a_.child_count[n] == 0; }
  /// A leaf only because its children are not resident (a paged hierarchy,
  /// paged_hierarchy.hpp: a leaf of more than one point); never true of a
  /// hierarchy held whole. What an iteration reports as wanted.
  [[nodiscard]] bool is_hidden(NodeId n) const {
    return a_.child_count[n] == 0 && a_.point_count[n] > 1;
  }
  [[nodiscard]] glm::vec3 center(NodeId n) const { return glm::vec3(a_.center_radius[n]); }
  [[nodiscard]] float radius(NodeId n) const { return a_.center_radius[n].w; }
  [[nodiscard]] float splat_radius(NodeId n) const { return a_.splat_radius[n]; }
  [[nodiscard]] glm::vec3 normal(NodeId n) const {
    return glm::vec3(a_.normal_cone[n]) * (1.0f / 32767.0f);
  }
  [[nodiscard]] float cone_cos(NodeId n) const { return a_.normal_cone[n].w * (1.0f / 32767.0f); }
  [[nodiscard]] NodeId first_child(NodeId n) const { return a_.first_child[n]; }
  [[nodiscard]] unsigned child_count(NodeId n) const { return a_.child_count[n]; }
  [[nodiscard]] NodeId parent(NodeId n) const { return a_.parent[n]; }
  /// True when `n` is the first of its siblings. Siblings are contiguous, so
  /// that is when its predecessor has another parent: two neighbouring loads
  /// instead of the dependent first_child[parent[n]].
  [[nodiscard]] bool is_first_child(NodeId n) const {
    return n != 0 && a_.parent[n - 1] != a_.parent[n];
  }

  /// Assembles a hierarchy from arrays (and attribute values) whose
  /// lifetime `storage` guarantees. Used by the builder and the cache
  /// loader; checks only the sizes.
  static Hierarchy from_arrays(std::shared_ptr<const void> storage, const HierarchyArrays& arrays,
                               std::vector<NodeId> level_begin, glm::vec3 bounds_min,
                               glm::vec3 bounds_max, CoordinateFrame frame = {},
                               std::vector<NodeAttribute> attributes = {});

 private:
  std::shared_ptr<const void> storage_;
  HierarchyArrays a_;
  std::vector<NodeId> level_begin_;
  std::uint32_t node_count_ = 0;
  std::uint32_t leaf_count_ = 0;
  glm::vec3 bounds_min_{0.0f};
  glm::vec3 bounds_max_{0.0f};
  CoordinateFrame frame_;
  std::vector<NodeAttribute> attributes_;
  SourceNotes notes_;
};

/// Packs a unit vector and a cone cosine into the snorm16 layout above.
glm::i16vec4 pack_normal_cone(glm::vec3 normal, float cone_cos);

struct BuildOptions {
  /// A parent splat sits on one of its real points (the one nearest the
  /// average) instead of the average, so splats do not move when the cut
  /// changes level (QSplat paper, section on possible enhancements).
  bool parent_at_real_point = false;
  /// Worker threads; 0 = all hardware threads.
  unsigned threads = 0;
  /// Called with (done, total) work units from the building thread, for a progress bar.
  std::function<void(std::size_t, std::size_t)> progress;
};

/// Builds the hierarchy. `points` must have normals, radii and curvature
/// (complete_attributes) and at least one point; it is consumed (its arrays are
/// released while the node arrays fill, which bounds the peak memory).
/// Deterministic: the same input gives byte-identical arrays for any thread count.
Hierarchy build_hierarchy(PointSet&& points, const BuildOptions& options = {});

/// About MOST of the leaves of the known part of H, evenly spaced by id: the
/// nodes of KNOWN (ranges in increasing ids) whose children are not in
/// KNOWN. Ids are breadth-first and a level's nodes spatially ordered, so a
/// stride samples the model evenly. KNOWN is {0, node_count()} for a model
/// held whole (its leaves) and a paged model's root page when it opens
/// (PagedHierarchy::page_ranges(0): its other nodes are not read yet, so
/// nothing may read them).
std::vector<NodeId> sample_leaves(const Hierarchy& h, std::span<const NodeRange> known,
                                  std::size_t most);

/// Checks every structural invariant (children inside the parent's sphere,
/// cone containing the children's normals, monotone priority, leaf count, depth
/// bound, parent/child links). Returns an empty string or the first violation.
std::string check_invariants(const Hierarchy& h);

/// Calls FN(n) for each leaf of H reached from the root through child
/// links, depth first: every leaf of a hierarchy held whole; of a paged one
/// (paged_hierarchy.hpp) the resident part's, hidden nodes included, and
/// never a node that is not resident. O(the nodes reached).
template <class Fn>
void for_each_resident_leaf(const Hierarchy& h, Fn&& fn) {
  if (h.empty()) return;
  std::vector<NodeId> stack{h.root()};
  while (!stack.empty()) {
    const NodeId n = stack.back();
    stack.pop_back();
    const std::uint32_t children = h.child_count(n);
    if (children == 0) {
      fn(n);
      continue;
    }
    for (std::uint32_t k = children; k-- > 0;) stack.push_back(h.first_child(n) + k);
  }
}

}  // namespace treecut
