// Event times of the fold/unfold criterion (Zach & Karner 2003, section 3):
// lower bounds of how far the eye must move (in units of rho) or the view
// direction turn (in units of omega) before unfold_test can change. Each
// bound is derived below from the geometry; the velocities carry a relative
// margin of 1e-6 and every result an absolute one of 1e-6 units, so rounding
// errors (of the order of 1e-15 in double) can only make an event earlier,
// never later. The event_queue strategy's exactness against topdown
// (tests/event_queue_test.cpp) rests on these bounds.
#include <algorithm>
#include <cmath>
#include <glm/mat4x4.hpp>
#include <limits>

#include "treecut/strategies/refinement_criterion.hpp"

namespace treecut::strategies {
namespace {

constexpr double kVelocityMargin = 1.0 + 1e-6;
constexpr double kPi = 3.14159265358979323846;

// Frames from a real lower bound x: floored, 0 for negative or NaN, at most
// cap. The true first frame k* of a change is an integer >= x, so any
// computed x' < x + 1 still gives floor(x') <= k*: errors below one frame
// are harmless.
std::uint32_t frames(double x, std::uint32_t cap) {
  if (!(x > 0.0)) return 0;
  if (x >= double(cap)) return cap;
  return static_cast<std::uint32_t>(x);
}

// alpha - phi, the angle between the view direction and the nearest point of
// the sphere's silhouette (negative when the direction points into it), as
// d^2 (cos, sin) of it: from d sin(alpha) = |u x D|, d cos(alpha) = <u, D>,
// d sin(phi) = r, d cos(phi) = sqrt(d^2 - r^2).
struct SilhouetteAngle {
  double x, y;  // d^2 cos(alpha - phi), d^2 sin(alpha - phi)
};

// `tangent` = sqrt(d^2 - r^2), from look() where it computed it.
SilhouetteAngle silhouette_angle(const CriterionCamera& cam, const Sight& g, double tangent) {
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
double gap_into_view(const CriterionCamera& cam, const SilhouetteAngle& a, double d2) {
  return (cam.sin_beta * a.x - cam.cos_beta * a.y) / d2;
}
// (alpha - phi) - beta >= sin((alpha - phi) - beta):
double gap_out_of_view(const CriterionCamera& cam, const SilhouetteAngle& a, double d2) {
  return (cam.cos_beta * a.y - cam.sin_beta * a.x) / d2;
}

}  // namespace

CriterionCamera CriterionCamera::from_view(const ViewSnapshot& view, double theta) {
  CriterionCamera c;
  c.ex = view.derived.eye.x;
  c.ey = view.derived.eye.y;
  c.ez = view.derived.eye.z;
  // The camera looks along -z of eye space: the model-space direction is
  // minus the third row of the view matrix (glm is column-major).
  const double fx = -double(view.view[0][2]);
  const double fy = -double(view.view[1][2]);
  const double fz = -double(view.view[2][2]);
  const double len = std::sqrt(fx * fx + fy * fy + fz * fz);
  if (len > 0.0) {
    c.ux = fx / len;
    c.uy = fy / len;
    c.uz = fz / len;
  }
  c.perspective = view.derived.perspective;
  const double px = view.projection[0][0];
  const double py = view.projection[1][1];
  // The cone around a symmetric frustum: its half-diagonal at distance 1 is
  // sqrt(tan(fov_x/2)^2 + tan(fov_y/2)^2).
  const double tx = px != 0.0 ? 1.0 / px : 0.0;
  const double ty = py != 0.0 ? 1.0 / py : 0.0;
  c.beta = std::atan(std::sqrt(tx * tx + ty * ty));
  c.cos_beta = std::cos(c.beta);
  c.sin_beta = std::sin(c.beta);
  c.pixel_scale = 0.5 * double(view.viewport.y) * py;
  c.theta = theta;
  return c;
}

bool unfold_test(const CriterionCamera& cam, const ViewSnapshot& view, const glm::vec4& cr) {
  if (cam.perspective) return unfold_test(cam, cr);
  return double(cr.w) * cam.pixel_scale >= cam.theta && !view.outside_frustum(glm::vec3(cr), cr.w);
}

// A folded node (unfold_test false, so the eye is outside the sphere).
// Let s <= m rho be how far the eye has moved and w omega how far the view
// direction has turned since.
// - t_i: inside needs |c - e_k| < r, and |c - e_k| >= d - s, so m > (d - r) / rho.
// - t_m: the threshold needs |c - e_k| <= R = r S / theta, so m >= (d - R) / rho
//   (moving straight at the center is the fastest way, figure 5).
// - t_r: seen from e_k the sphere looks like the sphere (c - (e_k - e), r)
//   seen from e, which lies inside the sphere (c, r + s); so visible needs
//   angle(u_k, D) <= beta + asin((r + s) / d), and angle(u_k, D) >=
//   alpha - w omega. For m <= K with x1 = (r + K rho) / d < 1, asin is
//   convex, so asin((r + m rho) / d) <= phi + m b with b = rho / (d sqrt(1 -
//   x1^2)): visible needs w omega + m b >= G = alpha - phi - beta (replaced
//   by its sine, a lower bound: gap_out_of_view), or m > K. (The paper's t_r
//   = (alpha - phi - sqrt(2) fov/2) / omega leaves out that translation
//   turns the direction to the sphere too.)
// The two clocks share G: with M = min(K, G / (b + k)) for any k > 0, while
// m < M and w < W = (G - b M) / omega the sum w omega + m b stays below G.
// k is the camera's own recent ratio of rotation to translation (rates.split,
// clamped to [b / 7, 7 b]), which makes both come after about the same time
// for a camera that keeps its pace; with both clocks in step (k = omega) M
// is the single-clock t_r = G / (omega + b).
// Unfold needs inside, or visible and the threshold: m >= min(t_i, max(t_r, t_m)).
// When M <= t_m the threshold alone keeps the node folded until t_m and
// rotation cannot change that (w = infinity); else the node waits for
// min(t_i, M) on the translation clock or W on the rotation clock.

EventRates::EventRates(const CriterionCamera& cam, double rho_, double omega_, double cap_,
                       double cap_w_, double turn_per_move)
    : rho(rho_ * kVelocityMargin),
      inv_rho(1.0 / (rho_ * kVelocityMargin)),
      omega(omega_ * kVelocityMargin),
      inv_omega(1.0 / (omega_ * kVelocityMargin)),
      size_scale(cam.pixel_scale / cam.theta),
      cap(cap_),
      cap_w(cap_w_),
      split(omega_ * turn_per_move) {}

namespace {

// A real time x as the bound handed out: clamped to [0, cap], less an
// absolute margin for the rounding of the distances (a clock is a real
// number now, so an error cannot hide below a whole frame any more).
constexpr double kAbsoluteMargin = 1e-6;
double clock_bound(double x, double cap) {
  if (!(x > kAbsoluteMargin)) return 0.0;
  return std::min(cap, x - kAbsoluteMargin);
}

constexpr double kNever = std::numeric_limits<double>::infinity();

// k of the split, clamped to [b / 7, 7 b] (lambda = b / (b + k) in [1/8, 7/8]):
// a camera that has not turned for a while still gets a rotation time of at
// least G / (8 omega), so its first turn does not make every such node due.
double split_of(const EventRates& q, double b) {
  return std::clamp(q.split, b * (1.0 / 7.0), 7.0 * b);
}

}  // namespace

namespace {

// Both from look()'s values, so that decide() and the two functions below
// are the same code on the same numbers.
EventTime unfold_event(const CriterionCamera& cam, const Sight& g, const EventRates& q) {
  if (g.d2 < g.r * g.r || !cam.perspective) return {0.0, 0.0};
  const double d = g.d;  // computed by look() (outside)
  const double t_i = (d - g.r) * q.inv_rho;
  const double t_m = (d - g.r * q.size_scale) * q.inv_rho;
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

EventTime fold_event(const CriterionCamera& cam, const Sight& g, const EventRates& q) {
  if (!cam.perspective) return {0.0, 0.0};
  if (g.d2 < g.r * g.r) return {clock_bound((g.r - std::sqrt(g.d2)) * q.inv_rho, q.cap), kNever};
  // look() passed the threshold: d and the tangent are computed.
  const double d = g.d, tangent = g.tangent;
  const double t_m = (g.r * q.size_scale - d) * q.inv_rho;
  const double k_max = std::min(q.cap, 0.5 * d * q.inv_rho);
  if (!(tangent > 0.0)) return {0.0, 0.0};
  // (pi/3) rho / d + rho r / (d tangent) with one division.
  const double b = q.rho * ((kPi / 3.0) * tangent + g.r) / (d * tangent);
  const double gap = gap_into_view(cam, silhouette_angle(cam, g, tangent), g.d2);
  if (!(gap > 0.0)) return {0.0, 0.0};
  const double m = std::min(std::min(t_m, k_max), gap / (b + split_of(q, b)));
  return {clock_bound(m, q.cap), clock_bound((gap - b * std::max(m, 0.0)) * q.inv_omega, q.cap_w)};
}

}  // namespace

EventTime potential_unfold_event(const CriterionCamera& cam, const glm::vec4& cr,
                                 const EventRates& q) {
  return unfold_event(cam, look(cam, cr), q);
}

Decision decide(const CriterionCamera& cam, const glm::vec4& cr, const EventRates& q) {
  const Sight g = look(cam, cr);
  return {g.pass ? fold_event(cam, g, q) : unfold_event(cam, g, q), g.pass};
}

// An unfolded node (unfold_test true).
// - Inside: the test stays true until the eye leaves the sphere: m >= (r - d) / rho;
//   rotation plays no part (w = infinity).
// - Outside (visible and above the threshold), the dual of the above:
//   t_m: the threshold fails only when |c - e_k| > R, m > (R - d) / rho;
//   t_r: from e_k the direction to c is within asin(s / d) of D (s < d) and
//   the sphere's angular radius is at least asin(r / (d + s)), so it can leave
//   the view only if alpha + w omega + asin(s / d) > beta + asin(r / (d + s)).
//   For m <= K with K rho <= d / 2: asin(m rho / d) <= (pi / 3) m rho / d (the
//   chord of the convex asin up to 1/2) and asin(r / (d + s)) >= phi -
//   s r / (d sqrt(d^2 - r^2)) (its tangent at s = 0, it is convex in s); so
//   leaving needs w omega + m b >= G = beta - (alpha - phi) with
//   b = (pi/3) rho / d + rho r / (d sqrt(d^2 - r^2)) (G replaced by its sine,
//   gap_into_view), or m > K.
//   Fold needs either: with M = min(t_m, K, G / (b + k)) the node keeps its
//   test while m < M and w < (G - b M) / omega; rotation alone can always
//   turn it out of view, so w is always finite.
EventTime potential_fold_event(const CriterionCamera& cam, const glm::vec4& cr,
                               const EventRates& q) {
  return fold_event(cam, look(cam, cr), q);
}

// Both clocks in step, one frame of each: the frames before which nothing
// can change are those before either clock's bound.
std::uint32_t potential_unfold_time(const CriterionCamera& cam, const glm::vec4& cr, double rho,
                                    double omega, std::uint32_t cap) {
  const EventTime e =
      potential_unfold_event(cam, cr, EventRates(cam, rho, omega, double(cap), double(cap)));
  return frames(std::min(e.m, e.w), cap);
}

std::uint32_t potential_fold_time(const CriterionCamera& cam, const glm::vec4& cr, double rho,
                                  double omega, std::uint32_t cap) {
  const EventTime e =
      potential_fold_event(cam, cr, EventRates(cam, rho, omega, double(cap), double(cap)));
  return frames(std::min(e.m, e.w), cap);
}

}  // namespace treecut::strategies
