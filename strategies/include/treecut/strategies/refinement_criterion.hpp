// The fold/unfold criterion of Zach & Karner, "Fast Event-Driven Refinement of
// Dynamic Levels of Detail" (2003), figure 4, shared by the `topdown` baseline
// and the `event_queue` refiner: both must decide every node with the very
// same function on the very same inputs, or "event_queue equals topdown node
// for node" would depend on rounding.
//
//   unfold = insideTest OR (visibilityTest AND thresholdTest)
//
// on the node's bounding sphere (c, r), the eye e and the unit view direction
// u of a perspective ViewSnapshot:
// - insideTest: |c - e| < r;
// - visibilityTest: the sphere meets the cone around the view direction that
//   contains the frustum (half-angle beta = atan of the half-diagonal of the
//   image plane at distance 1; the paper's sqrt(2) fov/2 for a square view):
//   alpha - phi <= beta with alpha = angle(u, c - e), phi = asin(r / |c - e|),
//   evaluated without trigonometry as cos(alpha) >= cos(beta + phi);
// - thresholdTest: the projected radius r * pixel_scale / |c - e| (pixels,
//   pixel_scale from the snapshot's field of view and viewport) >= theta.
//
// Evaluated in double precision from the float node data. A node that is a
// leaf is never unfolded. The event times below are lower bounds of the first
// frame in which the result can change when the eye moves at most rho and the
// view direction turns at most omega per frame; see the derivations beside
// each function in criterion.cpp.
#pragma once

#include <cmath>
#include <cstdint>
#include <glm/vec3.hpp>
#include <glm/vec4.hpp>

#include "treecut/view_snapshot.hpp"

namespace treecut::strategies {

/// What the criterion reads of a view, in double precision.
struct CriterionCamera {
  double ex = 0, ey = 0, ez = 0;   ///< eye, model space
  double ux = 0, uy = 0, uz = -1;  ///< unit view direction, model space
  double beta = 0;                 ///< half-angle of the cone around the frustum
  double cos_beta = 1, sin_beta = 0;
  double pixel_scale = 1;  ///< pixels per unit of radius / distance
  double theta = 1;        ///< threshold, pixels of projected radius
  bool perspective = true;

  /// From a finalized snapshot. Orthographic views set perspective = false
  /// (the criterion then has no distance: visibility is the frustum test and
  /// the threshold compares r * pixel_scale with theta).
  static CriterionCamera from_view(const ViewSnapshot& view, double theta);
  /// Same projection and threshold: only the eye and the direction differ, so
  /// the event times computed under one remain valid under the other.
  [[nodiscard]] bool same_lens(const CriterionCamera& o) const {
    return beta == o.beta && pixel_scale == o.pixel_scale && theta == o.theta &&
           perspective == o.perspective;
  }
};

/// The unfold test of figure 4 (perspective camera). Inline: the top-down pass
/// calls it for every active and boundary node.
[[gnu::always_inline]] inline bool unfold_test(const CriterionCamera& cam, const glm::vec4& cr) {
  const double dx = double(cr.x) - cam.ex;
  const double dy = double(cr.y) - cam.ey;
  const double dz = double(cr.z) - cam.ez;
  const double r = cr.w;
  const double d2 = dx * dx + dy * dy + dz * dz;
  if (d2 < r * r) return true;  // insideTest
  // thresholdTest, r * S / d >= theta, without the division.
  if (r * cam.pixel_scale < cam.theta * std::sqrt(d2)) return false;
  // visibilityTest: alpha <= beta + phi (both in [0, pi]), i.e.
  // d cos(alpha) >= cos(beta) d cos(phi) - sin(beta) d sin(phi).
  const double along = dx * cam.ux + dy * cam.uy + dz * cam.uz;  // d cos(alpha)
  return along >= cam.cos_beta * std::sqrt(d2 - r * r) - cam.sin_beta * r;
}

/// The same for any projection (orthographic views fall back to the frustum).
bool unfold_test(const CriterionCamera& cam, const ViewSnapshot& view, const glm::vec4& cr);

/// rho and omega with their safety margin, and the reciprocals the event
/// times divide by, computed once per iteration.
struct EventRates {
  EventRates(const CriterionCamera& cam, double rho, double omega, std::uint32_t cap);
  double rho, inv_rho, omega;
  double
      size_scale;  ///< pixel_scale / theta: the distance at which r reaches theta is r * size_scale
  double cap;
  std::uint32_t cap_frames;
};

/// Frames (>= 0, at most `cap`) before which unfold_test cannot become true
/// for a node for which it is false now, with the eye moving at most `rho`
/// and the direction turning at most `omega` radians per frame:
/// min(t_i, max(t_r, t_m)) (the paper's combination for a folded node).
std::uint32_t potential_unfold_time(const CriterionCamera& cam, const glm::vec4& cr, double rho,
                                    double omega, std::uint32_t cap);
/// Frames before which unfold_test cannot become false for a node for which
/// it is true now (the dual: leaving the sphere, or, outside it,
/// min(t_r, t_m) for turning it out of view or moving away from it).
std::uint32_t potential_fold_time(const CriterionCamera& cam, const glm::vec4& cr, double rho,
                                  double omega, std::uint32_t cap);
/// The same with the rates precomputed (the event queue's hot path).
std::uint32_t potential_unfold_time(const CriterionCamera& cam, const glm::vec4& cr,
                                    const EventRates& rates);
std::uint32_t potential_fold_time(const CriterionCamera& cam, const glm::vec4& cr,
                                  const EventRates& rates);

}  // namespace treecut::strategies
