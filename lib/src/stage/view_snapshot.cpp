#include "treecut/view_snapshot.hpp"

#include <glm/geometric.hpp>
#include <glm/gtc/matrix_transform.hpp>
#include <glm/matrix.hpp>

namespace treecut {

std::array<glm::vec4, 6> frustum_planes(const glm::mat4& m) {
  // Each plane is row 3 +- row i of the clip matrix (glm is column-major, so
  // row i is m[0][i], m[1][i], ...).
  const auto row = [&m](int i) { return glm::vec4(m[0][i], m[1][i], m[2][i], m[3][i]); };
  const glm::vec4 r3 = row(3);
  std::array<glm::vec4, 6> planes;
  for (int i = 0; i < 3; ++i) {
    planes[static_cast<std::size_t>(2 * i)] = r3 + row(i);
    planes[static_cast<std::size_t>(2 * i + 1)] = r3 - row(i);
  }
  for (glm::vec4& p : planes) {
    const float len = glm::length(glm::vec3(p));
    if (len > 0.0f) p /= len;
  }
  return planes;
}

void ViewSnapshot::finalize() {
  const glm::mat4 inverse_view = glm::inverse(view);
  derived.eye = glm::vec3(inverse_view[3]);
  derived.frustum = frustum_planes(projection * view);
  for (std::size_t i = 0; i < 8; ++i) {
    // Lanes 6 and 7: 0 x + 1e30 >= -radius, a plane nothing is outside of.
    const Plane p = i < 6 ? derived.frustum[i] : Plane(0.0f, 0.0f, 0.0f, 1e30f);
    derived.lanes.x[i] = p.x;
    derived.lanes.y[i] = p.y;
    derived.lanes.z[i] = p.z;
    derived.lanes.w[i] = p.w;
  }
  // A perspective projection has w_clip = -z_eye, so its last row is (0,0,-1,0).
  derived.perspective = projection[3][3] == 0.0f;
  derived.pixel_scale = 0.5f * static_cast<float>(viewport.y) * projection[1][1];
}

ViewSnapshot ViewSnapshot::look_at(glm::vec3 eye, glm::vec3 target, glm::ivec2 viewport,
                                   float fov_y, float near_plane, float far_plane) {
  ViewSnapshot s;
  const glm::vec3 forward = glm::normalize(target - eye);
  const glm::vec3 up = std::abs(forward.y) > 0.99f ? glm::vec3(0, 0, 1) : glm::vec3(0, 1, 0);
  s.view = glm::lookAt(eye, target, up);
  const float aspect = static_cast<float>(viewport.x) / static_cast<float>(viewport.y);
  s.projection = glm::perspective(fov_y, aspect, near_plane, far_plane);
  s.viewport = viewport;
  s.light_dir = glm::normalize(eye - target);
  s.finalize();
  return s;
}

bool ViewSnapshot::backfacing(glm::vec3 center, float radius, glm::vec3 normal,
                              float cone_cos) const {
  // QSplat (Rusinkiewicz & Levoy 2000), backface culling with normal cones:
  // every normal n of the cone (half-angle a) faces away from every point of
  // the sphere, which the eye sees under the half-angle b, iff the angle
  // between the cone axis and the direction to the eye exceeds 90 + a + b.
  const glm::vec3 to_eye = derived.eye - center;
  const float dist = glm::length(to_eye);
  if (!derived.perspective || dist <= radius || cone_cos <= 0.0f) return false;
  const float sin_b = radius / dist;
  const float cos_b = std::sqrt(1.0f - sin_b * sin_b);
  const float sin_a = std::sqrt(std::max(0.0f, 1.0f - cone_cos * cone_cos));
  if (cone_cos * cos_b - sin_a * sin_b <= 0.0f) return false;  // a + b >= 90 degrees
  const float sin_ab = sin_a * cos_b + cone_cos * sin_b;
  return glm::dot(normal, to_eye) < -sin_ab * dist;
}

}  // namespace treecut
