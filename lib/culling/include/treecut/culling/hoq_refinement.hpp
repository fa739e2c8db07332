// The pure functions of HOQ-coherent HLOD refinement: J. P. Charalambos,
// J. Bittner, M. Wimmer, E. Romero, "Optimized HLOD Refinement Driven by
// Hardware Occlusion Queries", ISVC 2007
// (../shared/papers/hoq-driven-hlod-refinement.txt), section 3.2 and figure 3:
// the sigmoid bias B_{s,t}(mu), VMSSE = B * SSE (equation 1), the
// screen-space error of an HLOD block, the relative visibility mu of a query
// answer and PredictRefinement. Functions of explicit inputs, shared by the
// in-frame traversals (hlod_traversal.hpp) and the Feedback Stage strategy
// `hoq` (treecut/culling/hoq_refinement.hpp).
#pragma once

#include <cstddef>
#include <cstdint>
#include <glm/mat4x4.hpp>
#include <glm/vec2.hpp>
#include <glm/vec3.hpp>
#include <span>

#include "treecut/culling/hlod_blocks.hpp"
#include "treecut/view_snapshot.hpp"

namespace treecut::culling::hoq {
/// The sigmoid bias B_{s,t}(mu) of section 3.2 (figure 1-a): the paper names
/// its properties, not its formula, so this is the smooth quadratic sigmoid
/// with turn-over t,
///     S_t(mu) = mu^2 / t                      for mu <= t  (aggressive: S < mu)
///     S_t(mu) = 1 - (1 - mu)^2 / (1 - t)      for mu >  t  (conservative: S > mu)
/// (continuous with a continuous slope at t, S_t(0) = 0, S_t(1) = 1), and the
/// smoothness s interpolating linearly between mu and it:
///     B_{s,t}(mu) = (1 - s) mu + s S_t(mu).
/// Hence s = 0 gives mu, mu = 1 gives 1 for every s and t, B is
/// non-decreasing in mu, and a t closer to 0 modulates less (more
/// conservative), as the paper asks. mu, s and t are clamped to [0, 1].
[[nodiscard]] float sigmoid_bias(float mu, float s, float t);

/// Equation 1: VMSSE = B_{s,t}(mu) * SSE.
[[nodiscard]] inline float vmsse(float bias, float sse) {
  return bias * sse;
}

/// Distance from `eye` to the nearest point of `box` (0 inside it).
[[nodiscard]] float distance_to_box(glm::vec3 eye, const Box& box);

/// The screen-space error of an HLOD block in pixels: `error_radius` (the
/// largest splat radius of the block's representation, 0 for a leaf block,
/// which is full detail) projected at the nearest distance of the block's
/// box, as ViewSnapshot::projected_radius_px projects a radius. Conservative:
/// every splat the block draws lies inside its box, so none is nearer than
/// that distance and none is larger than that radius: no splat of the
/// representation projects larger than this. Orthographic: radius times the
/// pixel scale.
[[nodiscard]] float block_sse(const ViewSnapshot& view, const Box& box, float error_radius);

/// The pixels the View's executor rasterizes for the query of a sphere
/// (treecut/splat/query_executor.hpp): its window rectangle (exact tangent
/// planes, 1/8 pixel wider on each side) clipped to the viewport, as the
/// point sprite of the longer side centred on it, clipped to the viewport
/// again. 0 when the rectangle misses the view. Negative (no analytic count)
/// when the sphere is not entirely in front of the eye's plane or the
/// projection is not a perspective frustum: the executor then draws a quad
/// or answers on the host, and relative_visibility() treats any sample as
/// mu = 1.
[[nodiscard]] double proxy_pixels(const ViewSnapshot& camera, glm::vec3 center, float radius);

/// mu = unoccluded pixels / projected pixels in [0, 1]; 0 for no sample; 1
/// for any sample when `projected_pixels` <= 0 (no analytic count: never
/// aggressive).
[[nodiscard]] float relative_visibility(std::uint32_t samples_passed, double projected_pixels);

enum class Prediction : std::uint8_t { Refine, Stop, Delay };

/// What PredictRefinement reads of a node: the state cached in the last frame.
struct NodeState {
  bool visited_last_frame = false;  ///< node.lastVisited = frameID - 1
  bool visible = false;             ///< node.visible (last frame's answer)
  bool stop_refinement = false;     ///< node.stopRefinement (a termination node last frame)
  float bias = 1.0f;                ///< node.bias: B(mu) of last frame's answer
};

/// What it reads of each child: its stop flag and cached bias, and its SSE
/// in this frame.
struct ChildState {
  bool stop_refinement = false;
  float bias = 1.0f;
  float sse = 0.0f;
};

/// AvgBias: the mean cached bias of the children (1 for none).
[[nodiscard]] float average_bias(std::span<const ChildState> children);

/// PredictRefinement(node), the paper's figure 3, line by line:
///     if not visited last frame or invisible:                 Delay
///     if not stopped last frame (refined):
///        candidate to shift up = every child stopped and
///                                child.bias * SSE(child) <= tau
///        if candidate and AvgBias(children) * SSE(node) <= tau: Delay
///     else if node.bias * SSE(node) <= tau:                   Stop
///     Refine
/// `sse` is the node's SSE in this frame; `children` is read only for a
/// refined node.
[[nodiscard]] Prediction predict_refinement(const NodeState& node, float sse,
                                            std::span<const ChildState> children, float tau);

}  // namespace treecut::culling::hoq
