// The file's per-point scalars over the hierarchy (issue 29, item 3): every
// node holds each attribute's summary of its subtree, so a cut at any level
// can be coloured by it. A measure's summary is its point-weighted mean, a
// category's the value with the most points among the children's values
// (the mode of modes: exact at the leaves and their parents, an estimate
// above, never a value no point has). NaN (no value) counts for nothing; a
// node without any value is NaN. Private to the builder (hierarchy.cpp).
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "treecut/hierarchy.hpp"
#include "treecut/point_set.hpp"

namespace treecut::detail {

struct OwnedAttribute {
  std::string name;
  AttributeKind kind = AttributeKind::measure;
  double offset = 0.0;
  double min = 0.0, max = 0.0;  // of the points' finite values, the file's
  std::vector<float> values;    // one per node, or empty: `constant` at every node
  float constant = 0.0f;
};

/// Copies each point attribute to the leaves (LEAF_POINT[i]: the point of
/// leaf i, for the nodes with CHILD_COUNT 0) and releases the point values
/// one attribute at a time. Interior values are left for fill_interior_values.
std::vector<OwnedAttribute> fill_leaf_values(std::vector<PointAttribute>& points,
                                             std::span<const NodeId> leaf_point,
                                             std::span<const std::uint8_t> child_count,
                                             unsigned threads);

/// Every interior node's summary, level by level from the deepest.
void fill_interior_values(std::vector<OwnedAttribute>& attributes,
                          std::span<const std::uint8_t> child_count,
                          std::span<const NodeId> first_child,
                          std::span<const std::uint32_t> point_count,
                          std::span<const NodeId> level_begin, unsigned threads);

/// The attributes as the Hierarchy hands them out (spans into ATTRIBUTES).
std::vector<NodeAttribute> node_attribute_views(const std::vector<OwnedAttribute>& attributes);

}  // namespace treecut::detail
