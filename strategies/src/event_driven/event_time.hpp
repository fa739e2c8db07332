// The event times of criterion.cpp as inline functions on look()'s values,
// for the event queue's hot loop (decide() inlined into it) and for
// criterion.cpp's public functions: one implementation. The derivations are
// beside potential_unfold_event and potential_fold_event in criterion.cpp.
#pragma once

#include <algorithm>
#include <cmath>
#include <limits>

#include "treecut/strategies/refinement_criterion.hpp"

namespace treecut::strategies::event_time {

inline constexpr double kPi = 3.14159265358979323846;

// alpha - phi, the angle between the view direction and the nearest point of
// the sphere's silhouette (negative when the direction points into it), as
// d^2 (cos, sin) of it: from d sin(alpha) = |u x D|, d cos(alpha) = <u, D>,
// d sin(phi) = r, d cos(phi) = sqrt(d^2 - r^2).
struct SilhouetteAngle {
  double x, y;  // d^2 cos(alpha - phi), d^2 sin(alpha - phi)
};

// `tangent` = sqrt(d^2 - r^2), from look() where it computed it.
inline SilhouetteAngle silhouette_angle(const CriterionConstants& cam, const Sight& g,
                                        double tangent) {
  const double along = g.dx * cam.ux + g.dy * cam.uy + g.dz * cam.uz;
  const double cx = cam.uy * g.dz - cam.uz * g.dy;
  const double cy = cam.uz * g.dx - cam.ux * g.dz;
  const double cz = cam.ux * g.dy - cam.uy * g.dx;
  const double across = std::sqrt(cx * cx + cy * cy + cz * cz);
  return {along * tangent + across * g.r, across * tangent - along * g.r};
}

// Lower bounds of the angular gaps without trigonometry: sin(x) <= x for
// x in [0, pi], and both gaps lie in [-pi/2, pi) (alpha in [0, pi], phi and
// beta in [0, pi/2)); a negative result gives a negative bound, t = 0.
// beta - (alpha - phi) >= sin(beta - (alpha - phi)):
inline double gap_into_view(const CriterionConstants& cam, const SilhouetteAngle& a, double d2) {
  return (cam.sin_beta * a.x - cam.cos_beta * a.y) / d2;
}
// (alpha - phi) - beta >= sin((alpha - phi) - beta):
inline double gap_out_of_view(const CriterionConstants& cam, const SilhouetteAngle& a, double d2) {
  return (cam.cos_beta * a.y - cam.sin_beta * a.x) / d2;
}

// A real time x as the bound handed out: clamped to [0, cap], less an
// absolute margin for the rounding of the distances (a clock is a real
// number now, so an error cannot hide below a whole frame any more).
inline constexpr double kAbsoluteMargin = 1e-6;
inline double clock_bound(double x, double cap) {
  if (!(x > kAbsoluteMargin)) return 0.0;
  return std::min(cap, x - kAbsoluteMargin);
}

inline constexpr double kNever = std::numeric_limits<double>::infinity();

// k of the split, clamped to [b / 7, 7 b] (lambda = b / (b + k) in [1/8, 7/8]):
// a camera that has not turned for a while still gets a rotation time of at
// least G / (8 omega), so its first turn does not make every such node due.
inline double split_of(const EventRates& q, double b) {
  return std::clamp(q.split, b * (1.0 / 7.0), 7.0 * b);
}

// Both from look()'s values, so that decide() and the two functions below
// are the same code on the same numbers.
inline EventTime unfold_event(const CriterionConstants& cam, const Sight& g, const EventRates& q) {
  if (g.d2 < g.r * g.r || !cam.perspective) return {0.0, 0.0};
  const double d = g.d;  // computed by look() (outside)
  const double t_i = (d - g.r) * q.inv_rho;
  double t_m = (d - g.r * q.size_scale) * q.inv_rho;
  // A zoom counts as a translation of q.reach per factor e (criterion.cpp):
  // the bound is scaled for nodes farther than that; none nearer, none at
  // all when the lens is fixed (reach infinite).
  if (d > q.reach) t_m *= q.reach / d;
  if (t_m >= t_i) return {clock_bound(t_i, q.cap), kNever};  // max(t_r, t_m) >= t_i already
  // Visible now (the test's own inequality, no trigonometry): t_r = 0. When
  // look() got past the threshold the test failed on visibility: not visible.
  const bool tested = !std::isnan(g.tangent);
  const double tangent = tested ? g.tangent : std::sqrt(g.d2 - g.r * g.r);
  bool visible = false;
  if (!tested) {
    const double along = g.dx * cam.ux + g.dy * cam.uy + g.dz * cam.uz;
    visible = along >= cam.cos_beta * tangent - cam.sin_beta * g.r;
  }
  const double gap = visible ? 0.0 : gap_out_of_view(cam, silhouette_angle(cam, g, tangent), g.d2);
  if (!(gap > 0.0)) return {clock_bound(t_m, q.cap), kNever};
  const double k_max = std::min(q.cap, 0.5 * (d - g.r) * q.inv_rho);
  // b = rho / (d sqrt(1 - x1^2)) with x1 = (r + K rho) / d, as rho /
  // sqrt(d^2 - (r + K rho)^2): one division less. Clamped at 0 (b infinite,
  // t_r = 0) where rounding takes the root's argument below zero.
  const double reach = g.r + k_max * q.rho;
  const double b = q.rho / std::sqrt(std::max(0.0, g.d2 - reach * reach));
  const double t_r = std::min(k_max, gap / (b + split_of(q, b)));
  if (t_r <= t_m) return {clock_bound(t_m, q.cap), kNever};
  const double m = std::min(t_i, t_r);
  return {clock_bound(m, q.cap), clock_bound((gap - b * m) * q.inv_omega, q.cap_w)};
}

inline EventTime fold_event(const CriterionConstants& cam, const Sight& g, const EventRates& q) {
  if (!cam.perspective) return {0.0, 0.0};
  if (g.d2 < g.r * g.r) return {clock_bound((g.r - std::sqrt(g.d2)) * q.inv_rho, q.cap), kNever};
  // look() passed the threshold: d and the tangent are computed.
  const double d = g.d, tangent = g.tangent;
  const double threshold = g.r * q.size_scale;
  double t_m = (threshold - d) * q.inv_rho;
  if (threshold > q.reach) t_m *= q.reach / threshold;  // the zoom (criterion.cpp)
  const double k_max = std::min(q.cap, 0.5 * d * q.inv_rho);
  if (!(tangent > 0.0)) return {0.0, 0.0};
  // (pi/3) rho / d + rho r / (d tangent) with one division.
  const double b = q.rho * ((kPi / 3.0) * tangent + g.r) / (d * tangent);
  const double gap = gap_into_view(cam, silhouette_angle(cam, g, tangent), g.d2);
  if (!(gap > 0.0)) return {0.0, 0.0};
  const double m = std::min(std::min(t_m, k_max), gap / (b + split_of(q, b)));
  return {clock_bound(m, q.cap), clock_bound((gap - b * std::max(m, 0.0)) * q.inv_omega, q.cap_w)};
}

[[gnu::always_inline]] inline Decision decide(const CriterionConstants& cam, const glm::vec4& cr,
                                              const EventRates& q) {
  const Sight g = look(cam, cr);
  return {g.pass ? fold_event(cam, g, q) : unfold_event(cam, g, q), g.pass};
}

}  // namespace treecut::strategies::event_time
