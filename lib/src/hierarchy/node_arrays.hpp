// The node arrays of a hierarchy as one owner holds them while they are
// filled: the builder's (hierarchy.cpp) and a cache's decoder's
// (cache_page_decode.cpp), each handed to Hierarchy::from_arrays as the
// storage its spans point into. Private to the library.
#pragma once

#include <cstdint>
#include <vector>

#include "treecut/hierarchy.hpp"

namespace treecut::detail {

struct NodeArrays {
  std::vector<glm::vec4> center_radius;
  std::vector<float> splat_radius;
  std::vector<glm::i16vec4> normal_cone;
  std::vector<glm::u8vec4> color;
  std::vector<float> priority;
  std::vector<std::uint32_t> point_count;
  std::vector<NodeId> parent;
  std::vector<NodeId> first_child;
  std::vector<std::uint8_t> child_count;
  std::vector<std::uint8_t> depth;

  /// The spans a Hierarchy hands out, over these vectors.
  [[nodiscard]] HierarchyArrays spans() const {
    return {center_radius, splat_radius, normal_cone, color,       priority,
            point_count,   parent,       first_child, child_count, depth};
  }
};

}  // namespace treecut::detail
