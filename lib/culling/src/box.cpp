// The culling layer's box and its frustum test (treecut/culling/box.hpp).
#include "treecut/culling/box.hpp"

#include <glm/common.hpp>
#include <glm/geometric.hpp>

namespace treecut::culling {

bool Box::contains_sphere(glm::vec3 c, float r) const {
  return c.x - r >= lo.x && c.y - r >= lo.y && c.z - r >= lo.z && c.x + r <= hi.x &&
         c.y + r <= hi.y && c.z + r <= hi.z;
}

float Box::distance_to(glm::vec3 p) const {
  const glm::vec3 d = glm::max(glm::max(lo - p, p - hi), glm::vec3(0.0f));
  return glm::length(d);
}

bool may_be_in_frustum(const ViewSnapshot& view, const Box& box) {
  for (const glm::vec4& p : view.derived.frustum) {
    const glm::vec3 corner(p.x >= 0.0f ? box.hi.x : box.lo.x, p.y >= 0.0f ? box.hi.y : box.lo.y,
                           p.z >= 0.0f ? box.hi.z : box.lo.z);
    if (p.x * corner.x + p.y * corner.y + p.z * corner.z + p.w < 0.0f) return false;
  }
  return true;
}

}  // namespace treecut::culling
