// A look-at perspective camera and the helpers that place it around a model.
// Plain data, no GL; any thread. A Camera is the viewer's pose (what the user
// moves); the view everyone else reads is the ViewSnapshot it makes
// (Camera::view, docs/architecture.md "Vocabulary").
#pragma once

#include <glm/mat4x4.hpp>
#include <glm/vec2.hpp>
#include <glm/vec3.hpp>

#include "treecut/view_snapshot.hpp"

namespace treecut::splat {

struct Camera {
  glm::vec3 eye{0.0f, 0.0f, 3.0f};  ///< model units
  glm::vec3 target{0.0f};           ///< the point looked at (the orbit pivot)
  glm::vec3 up{0.0f, 1.0f, 0.0f};
  float fov_y_deg = 45.0f;   ///< vertical field of view, degrees
  float near_plane = 0.01f;  ///< model units, > 0
  float far_plane = 100.0f;  ///< model units, > near_plane

  [[nodiscard]] glm::mat4 view_matrix() const;
  /// OpenGL clip space (z in [-1, 1]); aspect = width / height.
  [[nodiscard]] glm::mat4 projection_matrix(float aspect) const;
  [[nodiscard]] glm::vec3 forward() const;
  /// The view of this camera drawing into a `size` framebuffer: view,
  /// projection and viewport, finalized. No light (splat::view_snapshot adds
  /// it) and no frame numbers.
  [[nodiscard]] ViewSnapshot view(glm::ivec2 size) const;
};

/// Sets the clip planes so the sphere (center, radius) lies between them as
/// seen from camera.eye, with a near plane no closer than radius / 1000.
void fit_clip_planes(Camera& camera, glm::vec3 center, float radius);

/// A camera that looks at the centre of the box [bmin, bmax] from
/// `direction` (center -> eye, any length), as near as it can be with every
/// corner of the box in view for `aspect` (5 % margins), with `up` as up.
Camera fit_camera(glm::vec3 bmin, glm::vec3 bmax, float aspect, glm::vec3 direction,
                  glm::vec3 up = {0.0f, 1.0f, 0.0f}, float fov_y_deg = 45.0f);

/// The unit direction (center -> eye) at `azimuth` radians about the unit
/// `up` axis and `elevation` radians above the plane normal to it. Azimuth 0
/// looks from +z for a y-up model and from -y for a z-up model.
glm::vec3 orbit_direction(glm::vec3 up, float azimuth, float elevation);

/// The default view of a model: fit_camera() from a little above and to the side.
Camera default_camera(glm::vec3 bmin, glm::vec3 bmax, float aspect,
                      glm::vec3 up = {0.0f, 1.0f, 0.0f});

/// fit_camera() from orbit_direction(up, azimuth, elevation).
Camera orbit_camera(glm::vec3 bmin, glm::vec3 bmax, float aspect, float azimuth, float elevation,
                    glm::vec3 up = {0.0f, 1.0f, 0.0f}, float fov_y_deg = 45.0f);

}  // namespace treecut::splat
