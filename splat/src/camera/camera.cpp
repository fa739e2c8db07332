#include "treecut/splat/camera.hpp"

#include <algorithm>
#include <cmath>
#include <glm/geometric.hpp>
#include <glm/gtc/matrix_transform.hpp>
#include <glm/trigonometric.hpp>

namespace treecut::splat {

glm::mat4 Camera::view_matrix() const {
  // In double, rounded once: its translation is the eye's distance from the
  // origin, kilometres for map coordinates.
  return glm::mat4(glm::lookAt(glm::dvec3(eye), glm::dvec3(target), glm::dvec3(up)));
}

glm::mat4 Camera::projection_matrix(float aspect) const {
  return glm::perspective(glm::radians(fov_y_deg), aspect, near_plane, far_plane);
}

ViewSnapshot Camera::view(glm::ivec2 size) const {
  ViewSnapshot v;
  v.view = view_matrix();
  v.place_eye(eye);
  v.projection = projection_matrix(static_cast<float>(size.x) / static_cast<float>(size.y));
  v.viewport = size;
  v.finalize();
  return v;
}

glm::vec3 Camera::forward() const {
  const glm::vec3 d = target - eye;
  const float len = glm::length(d);
  return len > 0.0f ? d / len : glm::vec3(0.0f, 0.0f, -1.0f);
}

void fit_clip_planes(Camera& camera, glm::vec3 center, float radius) {
  const float r = std::max(radius, 1e-6f);
  const float d = glm::length(camera.eye - center);
  // Inside or near the sphere the near plane cannot bracket it; keep depth
  // precision reasonable with a near plane of radius / 1000.
  camera.near_plane = std::max(d - 1.05f * r, r * 1e-3f);
  camera.far_plane = std::max(d + 1.05f * r, camera.near_plane * 2.0f);
}

Camera fit_camera(glm::vec3 bmin, glm::vec3 bmax, float aspect, glm::vec3 direction, glm::vec3 up,
                  float fov_y_deg) {
  const glm::vec3 center = 0.5f * (bmin + bmax);
  const float radius = std::max(0.5f * glm::length(bmax - bmin), 1e-6f);
  const float half_y = glm::radians(fov_y_deg) * 0.5f;
  const float half_x = std::atan(std::tan(half_y) * std::max(aspect, 1e-3f));
  const float half = std::min(half_x, half_y);
  const float distance = radius / std::sin(half);
  const float len = glm::length(direction);
  const glm::vec3 dir = len > 0.0f ? direction / len : glm::vec3(0.0f, 0.0f, 1.0f);
  const float up_len = glm::length(up);
  glm::vec3 u = up_len > 0.0f ? up / up_len : glm::vec3(0.0f, 1.0f, 0.0f);
  // Looking along the up axis: any perpendicular up will do.
  if (std::abs(glm::dot(u, dir)) > 0.999f) {
    u = std::abs(dir.z) < 0.9f ? glm::vec3(0.0f, 0.0f, 1.0f) : glm::vec3(0.0f, 1.0f, 0.0f);
  }
  Camera c;
  c.target = center;
  c.eye = center + dir * distance;
  c.up = u;
  c.fov_y_deg = fov_y_deg;
  fit_clip_planes(c, center, radius);
  return c;
}

glm::vec3 orbit_direction(glm::vec3 up, float azimuth, float elevation) {
  const float up_len = glm::length(up);
  const glm::vec3 u = up_len > 0.0f ? up / up_len : glm::vec3(0.0f, 1.0f, 0.0f);
  const glm::vec3 ref =
      std::abs(u.z) < 0.9f ? glm::vec3(0.0f, 0.0f, 1.0f) : glm::vec3(0.0f, -1.0f, 0.0f);
  const glm::vec3 front = glm::normalize(ref - glm::dot(ref, u) * u);
  const glm::vec3 side = glm::cross(u, front);
  return std::cos(elevation) * (std::cos(azimuth) * front + std::sin(azimuth) * side) +
         std::sin(elevation) * u;
}

Camera default_camera(glm::vec3 bmin, glm::vec3 bmax, float aspect, glm::vec3 up) {
  return fit_camera(bmin, bmax, aspect, orbit_direction(up, 0.35f, 0.35f), up);
}

Camera orbit_camera(glm::vec3 bmin, glm::vec3 bmax, float aspect, float azimuth, float elevation,
                    glm::vec3 up, float fov_y_deg) {
  return fit_camera(bmin, bmax, aspect, orbit_direction(up, azimuth, elevation), up, fov_y_deg);
}

}  // namespace treecut::splat
