// PointSet's own operations (point_set.hpp): the value types and keeping
// some points with every array in step.
#include "treecut/point_set.hpp"

#include <cstdint>
#include <limits>

namespace treecut {

bool is_integer(ValueType type) {
  return type != ValueType::f32 && type != ValueType::f64;
}

bool is_signed(ValueType type) {
  switch (type) {
    case ValueType::i8:
    case ValueType::i16:
    case ValueType::i32:
    case ValueType::i64:
    case ValueType::f32:
    case ValueType::f64:
      return true;
    default:
      return false;
  }
}

std::size_t value_size(ValueType type) {
  static constexpr std::size_t kSize[10] = {1, 1, 2, 2, 4, 4, 8, 8, 4, 8};
  return kSize[static_cast<std::size_t>(type)];
}

std::string_view value_type_name(ValueType type) {
  static constexpr std::string_view kName[10] = {"u8",  "i8",  "u16", "i16", "u32",
                                                 "i32", "u64", "i64", "f32", "f64"};
  return kName[static_cast<std::size_t>(type)];
}

namespace {

template <class T>
void compact(std::vector<T>& array, const std::vector<bool>& keep) {
  if (array.empty()) return;
  std::size_t k = 0;
  for (std::size_t i = 0; i < keep.size(); ++i) {
    if (keep[i]) array[k++] = array[i];
  }
  array.resize(k);
  array.shrink_to_fit();
}

}  // namespace

void PointSet::keep_if(const std::vector<bool>& keep) {
  constexpr auto kDropped = std::numeric_limits<std::uint32_t>::max();
  std::vector<std::uint32_t> remap;
  if (!triangles.empty()) {
    remap.assign(keep.size(), kDropped);
    std::uint32_t next = 0;
    for (std::size_t i = 0; i < keep.size(); ++i) {
      if (keep[i]) remap[i] = next++;
    }
  }
  compact(positions, keep), compact(exact_positions, keep), compact(normals, keep);
  compact(radii, keep);
  compact(colors, keep), compact(colors16, keep), compact(curvature, keep);
  for (PointAttribute& a : attributes) {
    compact(a.values, keep), compact(a.wide, keep), compact(a.integers, keep);
  }
  std::size_t faces = 0;
  for (const glm::uvec3& t : triangles) {
    const glm::uvec3 r(remap[t.x], remap[t.y], remap[t.z]);
    if (r.x != kDropped && r.y != kDropped && r.z != kDropped) triangles[faces++] = r;
  }
  triangles.resize(faces);
}

}  // namespace treecut
