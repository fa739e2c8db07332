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
// leaf is never unfolded. The event times below are lower bounds of how far
// the eye must move (in units of rho) or the view direction turn (in units
// of omega) before the result can change; see the derivations beside each
// function in criterion.cpp.
#pragma once

#include <cmath>
#include <cstdint>
#include <glm/vec3.hpp>
#include <glm/vec4.hpp>
#include <limits>

#include "treecut/view_snapshot.hpp"

namespace treecut::strategies {

/// The criterion's constants for one view (the ViewSnapshot, the one view
/// type, holds the view): its eye and direction in double precision, the
/// cone around the frustum and the threshold, so that event times and the
/// top-down test agree to the last bit (event-driven paper, section 4).
struct CriterionConstants {
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
  static CriterionConstants from_view(const ViewSnapshot& view, double theta);
};

/// The unfold test of figure 4 (perspective camera) with what it computed on
/// the way: the event times (criterion.cpp) need the same distance and
/// tangent length, and recomputing them was a third of an event's cost.
struct Sight {
  double dx, dy, dz, r, d2;
  double d;        ///< |c - e|; NaN when not computed (inside)
  double tangent;  ///< sqrt(d^2 - r^2); NaN when not computed (inside, or below the threshold)
  bool pass;
};
[[gnu::always_inline]] inline Sight look(const CriterionConstants& cam, const glm::vec4& cr) {
  Sight s;
  s.dx = double(cr.x) - cam.ex;
  s.dy = double(cr.y) - cam.ey;
  s.dz = double(cr.z) - cam.ez;
  s.r = cr.w;
  s.d2 = s.dx * s.dx + s.dy * s.dy + s.dz * s.dz;
  s.d = s.tangent = std::numeric_limits<double>::quiet_NaN();
  if (s.d2 < s.r * s.r) {  // insideTest
    s.pass = true;
    return s;
  }
  // thresholdTest, r * S / d >= theta, without the division.
  s.d = std::sqrt(s.d2);
  if (s.r * cam.pixel_scale < cam.theta * s.d) {
    s.pass = false;
    return s;
  }
  // visibilityTest: alpha <= beta + phi (both in [0, pi]), i.e.
  // d cos(alpha) >= cos(beta) d cos(phi) - sin(beta) d sin(phi).
  const double along = s.dx * cam.ux + s.dy * cam.uy + s.dz * cam.uz;  // d cos(alpha)
  s.tangent = std::sqrt(s.d2 - s.r * s.r);
  s.pass = along >= cam.cos_beta * s.tangent - cam.sin_beta * s.r;
  return s;
}

/// The unfold test of figure 4 (perspective camera). Inline: the top-down pass
/// calls it for every active and boundary node.
[[gnu::always_inline]] inline bool unfold_test(const CriterionConstants& cam, const glm::vec4& cr) {
  return look(cam, cr).pass;
}

/// The same for any projection (orthographic views fall back to the frustum).
bool unfold_test(const CriterionConstants& cam, const ViewSnapshot& view, const glm::vec4& cr);

/// When a node's test can change next, on two clocks: `m` counts the eye's
/// translation in units of rho, `w` the view direction's rotation in units
/// of omega, both real numbers. The test cannot change while the eye has
/// moved less than m rho AND the direction has turned less than w omega since
/// the time was computed (w = infinity: rotation alone cannot change it). Two
/// clocks rather than frames of both: a camera that only flies does not use
/// up the rotation budget, one that only turns not the translation budget.
struct EventTime {
  double m;
  double w;
};

/// rho and omega with their safety margin, the reciprocals the event times
/// divide by, and how the visibility gap is split between the two clocks,
/// computed once per iteration.
struct EventRates {
  /// `turn_per_move`: the camera's recent rotation (in omega units) per unit
  /// of translation (in rho units), which sets the split; any split gives a
  /// correct bound, this one the latest events for a camera that keeps its
  /// pace. `cap`, `cap_w`: the farthest times returned on each clock.
  /// `reach`: what a change of the lens by a factor e (pixel_scale, the
  /// field of view or the viewport) counts as on the translation clock, in
  /// model units; infinity (the default) when the lens is fixed. A zoom by
  /// e^z is charged as a translation of z * reach (a change of the cone's
  /// half-angle beta as a rotation by the same angle); the threshold times
  /// are scaled so that this is a lower bound (criterion.cpp).
  EventRates(const CriterionConstants& cam, double rho, double omega, double cap, double cap_w,
             double turn_per_move = 1.0, double reach = std::numeric_limits<double>::infinity());
  double rho, inv_rho, omega, inv_omega;
  double
      size_scale;  ///< pixel_scale / theta: the distance at which r reaches theta is r * size_scale
  double cap, cap_w;
  double split;  ///< omega * turn_per_move: radians per rho unit the camera turns
  double reach;  ///< model units a zoom by a factor e counts as
};

/// When unfold_test, false now, can become true (a folded node): translation
/// min(t_i, max(t_r, t_m)) with t_r's gap split between the clocks; rotation
/// only moves it into view, so w is finite only when visibility is what
/// keeps the translation time late.
EventTime potential_unfold_event(const CriterionConstants& cam, const glm::vec4& cr,
                                 const EventRates& rates);
/// When unfold_test, true now, can become false (an unfolded node): leaving
/// the sphere, or min(t_r, t_m) outside it.
EventTime potential_fold_event(const CriterionConstants& cam, const glm::vec4& cr,
                               const EventRates& rates);

/// unfold_test and the event time for its result in one: {pass, the fold
/// event} when it passes, {false, the unfold event} when not; the very values
/// of unfold_test, potential_fold_event and potential_unfold_event (the same
/// code on the intermediate values of look(); tests/strategies/event_queue_gl_test.cpp
/// compares them), at about half the cost of calling them one after the other.
struct Decision {
  EventTime t;
  bool pass;
};
Decision decide(const CriterionConstants& cam, const glm::vec4& cr, const EventRates& rates);

/// Frames (>= 0, at most `cap`) before which unfold_test cannot become true
/// for a node for which it is false now, with the eye moving at most `rho`
/// and the direction turning at most `omega` radians per frame, both at once:
/// min(m, w) of potential_unfold_event, floored.
std::uint32_t potential_unfold_time(const CriterionConstants& cam, const glm::vec4& cr, double rho,
                                    double omega, std::uint32_t cap);
/// Frames before which unfold_test cannot become false for a node for which
/// it is true now (the dual).
std::uint32_t potential_fold_time(const CriterionConstants& cam, const glm::vec4& cr, double rho,
                                  double omega, std::uint32_t cap);

}  // namespace treecut::strategies
