#include "treecut/view_snapshot.hpp"

#include <algorithm>
#include <glm/geometric.hpp>
#include <glm/gtc/matrix_transform.hpp>
#include <glm/matrix.hpp>

#include "treecut/query_proxy.hpp"

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

namespace {

// Eye depth (positive in front) of the plane at NDC depth z of projection p.
float eye_depth(const glm::mat4& p, float ndc_z, bool perspective) {
  // Perspective: ndc_z = (p22 z_e + p32) / -z_e; orthographic: ndc_z = p22 z_e + p32.
  return perspective ? p[3][2] / (p[2][2] + ndc_z) : (p[3][2] - ndc_z) / p[2][2];
}

}  // namespace

bool ViewSnapshot::perspective_frustum() const {
  return is_perspective_frustum(projection) && viewport.x > 0 && viewport.y > 0;
}

void ViewSnapshot::finalize() {
  const glm::mat4 inverse_view = glm::inverse(view);
  const glm::mat3 to_model = glm::mat3(inverse_view);
  derived.view_projection = projection * view;
  // The camera's own eye when it placed this view (what the renderer draws
  // relative to: the float inverse of a view 30 km out is millimetres off);
  // else the inverse's, which serves the strategies' distances (a scene's
  // per-object views, folded and finalized every iteration: no double
  // inverse on that path).
  derived.eye = view == placed_view ? placed_eye : glm::vec3(inverse_view[3]);
  derived.forward = glm::normalize(to_model * glm::vec3(0.0f, 0.0f, -1.0f));
  derived.frustum = frustum_planes(derived.view_projection);
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

  const glm::mat4& p = projection;
  derived.near_plane = eye_depth(p, -1.0f, derived.perspective);
  derived.far_plane = eye_depth(p, 1.0f, derived.perspective);
  const glm::mat4 inverse_projection = glm::inverse(p);
  float corner = 0.0f;
  for (const float x : {-1.0f, 1.0f}) {
    for (const float y : {-1.0f, 1.0f}) {
      const glm::vec4 e = inverse_projection * glm::vec4(x, y, -1.0f, 1.0f);
      corner = std::max(corner, glm::length(glm::vec3(e) / e.w));
    }
  }
  derived.near_radius = 1.01f * corner;
  if (perspective_frustum()) {
    derived.ray_x = to_model * glm::vec3(1.0f / p[0][0], 0.0f, 0.0f);
    derived.ray_y = to_model * glm::vec3(0.0f, 1.0f / p[1][1], 0.0f);
    derived.ray_0 = to_model * glm::vec3(p[2][0] / p[0][0], p[2][1] / p[1][1], -1.0f);
  } else {
    derived.ray_x = derived.ray_y = derived.ray_0 = glm::vec3(0.0f);
  }
}

ViewSnapshot ViewSnapshot::look_at(glm::vec3 eye, glm::vec3 target, glm::ivec2 viewport,
                                   float fov_y, float near_plane, float far_plane) {
  ViewSnapshot s;
  const glm::vec3 forward = glm::normalize(target - eye);
  const glm::vec3 up = std::abs(forward.y) > 0.99f ? glm::vec3(0, 0, 1) : glm::vec3(0, 1, 0);
  s.view = glm::lookAt(eye, target, up);
  s.place_eye(eye);
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
