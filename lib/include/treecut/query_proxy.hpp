// The window rectangle the View's query executor rasterizes for the query of
// a node's bounding sphere (splat/src/render/query_executor.cpp, docs/
// rendering.md "Queries"), as one function: the executor draws it, and a
// strategy that needs the pixels a query can count (the HOQ strategy's
// relative visibility, strategies/src/occlusion/hoq.cpp) computes it from
// the same numbers. Pure arithmetic on the frame's matrices; any thread.
#pragma once

#include <algorithm>
#include <cmath>
#include <glm/mat4x4.hpp>
#include <glm/vec2.hpp>
#include <glm/vec3.hpp>
#include <glm/vec4.hpp>

namespace treecut {

/// A perspective frustum (glm::perspective / glm::frustum): clip w = -z_eye,
/// x and y of clip space from x and y of the eye only. The rectangles below
/// assume one; another projection takes the executor's quad path.
inline bool is_perspective_frustum(const glm::mat4& p) {
  return p[0][1] == 0.0f && p[0][2] == 0.0f && p[0][3] == 0.0f && p[1][0] == 0.0f &&
         p[1][2] == 0.0f && p[1][3] == 0.0f && p[2][3] == -1.0f && p[3][0] == 0.0f &&
         p[3][1] == 0.0f && p[3][3] == 0.0f && p[0][0] > 0.0f && p[1][1] > 0.0f;
}

/// A sphere's rectangle in window coordinates (pixels, origin bottom left),
/// not clipped to the viewport, and the sphere's center in eye space.
struct SphereWindowRect {
  float x0 = 0.0f, x1 = 0.0f, y0 = 0.0f, y1 = 0.0f;
  glm::vec3 eye_center{0.0f};
};

/// Every pixel center inside the sphere's exact projection lies strictly
/// inside the rectangle: kSphereRectMarginPx wider on each side than the
/// tangent planes give, more than float rounding and the rasterizer's
/// snapping of a point's position and size to its subpixel grid (1/256 pixel
/// on llvmpipe, at least 1/16 on any GL 4.5 driver's 4 bits). A whole pixel
/// more would add 20 to 40 % to the fragments of a typical proxy of 5 to 10
/// pixels.
inline constexpr float kSphereRectMarginPx = 0.125f;

/// The rectangle of `sphere` (center, radius) seen through `view` and the
/// perspective frustum `projection` in a viewport of `size` pixels; false
/// when the sphere is not entirely in front of the eye's plane (with a
/// margin: near it the bounds grow without limit) or the numbers are not
/// finite.
inline bool sphere_window_rect(const glm::mat4& view, const glm::mat4& projection, glm::vec2 size,
                               glm::vec4 sphere, SphereWindowRect& out) {
  const glm::vec3 c = glm::vec3(view * glm::vec4(glm::vec3(sphere), 1.0f));
  const float r = sphere.w;
  const float depth = -c.z;
  if (!(depth > r * 1.001f + 1e-6f)) return false;
  // The slopes x / depth of the two planes through the eye tangent to a
  // circle at (x, depth) of radius r, depth > r: tan(theta -+ alpha), theta
  // the center's angle, sin(alpha) = r / |c|. Both denominators are > 0
  // exactly when depth > r.
  const auto slopes = [&](float x, float& lo, float& hi) {
    const float t = std::sqrt(std::max(x * x + depth * depth - r * r, 0.0f));
    lo = (x * t - r * depth) / (depth * t + x * r);
    hi = (x * t + r * depth) / (depth * t - x * r);
  };
  float sx0 = 0.0f, sx1 = 0.0f, sy0 = 0.0f, sy1 = 0.0f;
  slopes(c.x, sx0, sx1);
  slopes(c.y, sy0, sy1);
  // ndc = p00 * x / depth - p20 (clip w = depth), to window coordinates.
  const glm::mat4& p = projection;
  out.x0 = (p[0][0] * sx0 - p[2][0] + 1.0f) * 0.5f * size.x - kSphereRectMarginPx;
  out.x1 = (p[0][0] * sx1 - p[2][0] + 1.0f) * 0.5f * size.x + kSphereRectMarginPx;
  out.y0 = (p[1][1] * sy0 - p[2][1] + 1.0f) * 0.5f * size.y - kSphereRectMarginPx;
  out.y1 = (p[1][1] * sy1 - p[2][1] + 1.0f) * 0.5f * size.y + kSphereRectMarginPx;
  out.eye_center = c;
  return out.x0 <= out.x1 && out.y0 <= out.y1;  // false for NaN
}

}  // namespace treecut
