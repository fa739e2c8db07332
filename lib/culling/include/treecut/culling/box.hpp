// The one box of the engine's culling vocabulary (docs/architecture.md,
// "## Vocabulary"): axis-aligned, lo and hi corners, in the units of the
// space it is given in (an HLOD block's in model space, a scene object's in
// world space), and the frustum test against it.
#pragma once

#include <array>
#include <glm/mat4x4.hpp>
#include <glm/vec3.hpp>
#include <glm/vec4.hpp>

#include "treecut/view_snapshot.hpp"

namespace treecut::culling {

/// An axis-aligned box.
struct Box {
  glm::vec3 lo{0.0f};
  glm::vec3 hi{0.0f};
  [[nodiscard]] glm::vec3 center() const { return 0.5f * (lo + hi); }
  [[nodiscard]] glm::vec3 size() const { return hi - lo; }
  [[nodiscard]] bool contains_sphere(glm::vec3 c, float r) const;
  /// Distance from `p` to the box (0 inside): the front-to-back key of both
  /// traversals and the nearest distance of a block's screen-space error.
  [[nodiscard]] float distance_to(glm::vec3 p) const;
};

/// False only when the box lies wholly outside one of the view's frustum
/// planes (ViewSnapshot::derived.frustum; its corner farthest along the
/// plane's normal is behind it): conservative.
[[nodiscard]] bool may_be_in_frustum(const ViewSnapshot& view, const Box& box);

}  // namespace treecut::culling
