// HOQ-coherent HLOD refinement, the pure functions of section 3.2 and
// figure 3 (../shared/papers/hoq-driven-hlod-refinement.txt; hoq_refinement.hpp).
#include "treecut/culling/hoq_refinement.hpp"

#include <algorithm>
#include <cmath>
#include <glm/geometric.hpp>
#include <glm/vec4.hpp>

#include "treecut/query_proxy.hpp"

namespace treecut::culling::hoq {
float sigmoid_bias(float mu, float s, float t) {
  mu = std::clamp(mu, 0.0f, 1.0f);
  s = std::clamp(s, 0.0f, 1.0f);
  t = std::clamp(t, 0.0f, 1.0f);
  float sig = 0.0f;
  if (mu <= t) {
    sig = t > 0.0f ? mu * mu / t : 0.0f;
  } else {
    const float u = 1.0f - mu;
    sig = 1.0f - u * u / (1.0f - t);  // t < mu <= 1, so 1 - t > 0
  }
  // mu = 1 gives exactly 1 whatever the rounding of the mix.
  if (mu >= 1.0f) return 1.0f;
  return (1.0f - s) * mu + s * sig;
}

float distance_to_box(glm::vec3 eye, const Box& box) {
  return box.distance_to(eye);
}

float block_sse(const ViewSnapshot& view, const Box& box, float error_radius) {
  if (error_radius <= 0.0f) return 0.0f;
  if (!view.derived.perspective) return error_radius * view.derived.pixel_scale;
  constexpr float kMinDistance = 1e-6f;  // as projected_radius_px: the eye inside is "huge"
  const float dist = std::max(distance_to_box(view.derived.eye, box), kMinDistance);
  return error_radius * view.derived.pixel_scale / dist;
}

double proxy_pixels(const ViewSnapshot& camera, glm::vec3 center, float radius) {
  // The rectangle the executor rasterizes (treecut/query_proxy.hpp); not
  // wholly in front of the eye: the executor's quad path or host answer.
  if (!is_perspective_frustum(camera.projection)) return -1.0;
  const float w = float(camera.viewport.x), h = float(camera.viewport.y);
  SphereWindowRect rect;
  if (!sphere_window_rect(camera.view, camera.projection, glm::vec2(w, h),
                          glm::vec4(center, radius), rect)) {
    return -1.0;
  }
  const float x0 = rect.x0, x1 = rect.x1, y0 = rect.y0, y1 = rect.y1;
  const float cx0 = std::max(x0, 0.0f), cx1 = std::min(x1, w);
  const float cy0 = std::max(y0, 0.0f), cy1 = std::min(y1, h);
  if (cx0 >= cx1 || cy0 >= cy1) return 0.0;
  // The sprite: the square of the clipped rectangle's longer side, centred
  // on it, and what of it lies in the viewport.
  const double side = std::max(cx1 - cx0, cy1 - cy0);
  const double mx = 0.5 * (double(cx0) + cx1), my = 0.5 * (double(cy0) + cy1);
  const double sw = std::min(mx + 0.5 * side, double(w)) - std::max(mx - 0.5 * side, 0.0);
  const double sh = std::min(my + 0.5 * side, double(h)) - std::max(my - 0.5 * side, 0.0);
  return std::max(sw, 0.0) * std::max(sh, 0.0);
}

float relative_visibility(std::uint32_t samples_passed, double projected_pixels) {
  if (samples_passed == 0) return 0.0f;
  if (!(projected_pixels > 0.0)) return 1.0f;
  return static_cast<float>(std::min(1.0, double(samples_passed) / projected_pixels));
}

float average_bias(std::span<const ChildState> children) {
  if (children.empty()) return 1.0f;
  float sum = 0.0f;
  for (const ChildState& c : children) sum += c.bias;
  return sum / float(children.size());
}

Prediction predict_refinement(const NodeState& node, float sse,
                              std::span<const ChildState> children, float tau) {
  if (!node.visited_last_frame || !node.visible) return Prediction::Delay;
  if (!node.stop_refinement) {
    bool candidate_to_shift_up = true;
    for (const ChildState& child : children) {
      if (!child.stop_refinement || !(vmsse(child.bias, child.sse) <= tau)) {
        candidate_to_shift_up = false;
      }
    }
    if (candidate_to_shift_up) {
      if (vmsse(average_bias(children), sse) <= tau) return Prediction::Delay;
    }
  } else if (vmsse(node.bias, sse) <= tau) {
    return Prediction::Stop;
  }
  return Prediction::Refine;
}

}  // namespace treecut::culling::hoq
