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

namespace {

// The distance along DIR (unit) from the box's centre at which all eight
// corners lie inside the frustum of half angles HALF_X and HALF_Y, seen with
// U (unit, across DIR) up: each corner at (x, y) across the view and z
// towards the eye needs D >= z + |x| / tan(half_x) and likewise for y. Also
// the corners' nearest and farthest z (for the clip planes).
struct BoxFit {
  float distance = 0.0f;
  float z_min = 0.0f, z_max = 0.0f;
};

BoxFit box_fit(glm::vec3 bmin, glm::vec3 bmax, glm::vec3 dir, glm::vec3 u, float half_x,
               float half_y) {
  const glm::vec3 center = 0.5f * (bmin + bmax);
  const glm::vec3 right = glm::normalize(glm::cross(-dir, u));
  const glm::vec3 up = glm::cross(right, -dir);
  const float tx = std::tan(half_x), ty = std::tan(half_y);
  BoxFit fit;
  fit.z_min = INFINITY, fit.z_max = -INFINITY;
  for (int c = 0; c < 8; ++c) {
    const glm::vec3 corner((c & 1) ? bmax.x : bmin.x, (c & 2) ? bmax.y : bmin.y,
                           (c & 4) ? bmax.z : bmin.z);
    const glm::vec3 q = corner - center;
    const float z = glm::dot(q, dir);
    fit.distance = std::max({fit.distance, z + std::fabs(glm::dot(q, right)) / tx,
                             z + std::fabs(glm::dot(q, up)) / ty});
    fit.z_min = std::min(fit.z_min, z), fit.z_max = std::max(fit.z_max, z);
  }
  return fit;
}

}  // namespace

Camera fit_camera(glm::vec3 bmin, glm::vec3 bmax, float aspect, glm::vec3 direction, glm::vec3 up,
                  float fov_y_deg) {
  const glm::vec3 center = 0.5f * (bmin + bmax);
  const float radius = std::max(0.5f * glm::length(bmax - bmin), 1e-6f);
  // A 5 % margin on each side of the frame.
  const float half_y = glm::radians(fov_y_deg) * 0.5f / 1.05f;
  const float half_x =
      std::atan(std::tan(glm::radians(fov_y_deg) * 0.5f) * std::max(aspect, 1e-3f)) / 1.05f;
  const float len = glm::length(direction);
  const glm::vec3 dir = len > 0.0f ? direction / len : glm::vec3(0.0f, 0.0f, 1.0f);
  const float up_len = glm::length(up);
  glm::vec3 u = up_len > 0.0f ? up / up_len : glm::vec3(0.0f, 1.0f, 0.0f);
  // Looking along the up axis: any perpendicular up will do.
  if (std::abs(glm::dot(u, dir)) > 0.999f) {
    u = std::abs(dir.z) < 0.9f ? glm::vec3(0.0f, 0.0f, 1.0f) : glm::vec3(0.0f, 1.0f, 0.0f);
  }
  // The box itself, not its bounding sphere: a flat terrain fills a 16:9
  // frame instead of its middle third (issue 43, item 12). The eye stays
  // 1.2 radii out, so the clip planes keep depth precision.
  const BoxFit fit = box_fit(bmin, bmax, dir, u, half_x, half_y);
  const float distance = std::max({fit.distance, 1.2f * radius, 1e-6f});
  Camera c;
  c.target = center;
  c.eye = center + dir * distance;
  c.up = u;
  c.fov_y_deg = fov_y_deg;
  // The planes bracket the box's corners (tighter than its sphere).
  c.near_plane = std::max(0.95f * (distance - fit.z_max), radius * 1e-3f);
  c.far_plane = std::max(1.05f * (distance - fit.z_min), c.near_plane * 2.0f);
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
