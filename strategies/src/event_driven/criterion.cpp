// Event times of the fold/unfold criterion (Zach & Karner 2003, section 3):
// lower bounds of how far the eye must move (in units of rho) or the view
// direction turn (in units of omega) before unfold_test can change. Each
// bound is derived below from the geometry; the velocities carry a relative
// margin of 1e-6 and every result an absolute one of 1e-6 units, so rounding
// errors (of the order of 1e-15 in double) can only make an event earlier,
// never later. The event_queue strategy's exactness against topdown
// (tests/strategies/event_queue_gl_test.cpp) rests on these bounds.
#include <algorithm>
#include <cmath>
#include <glm/mat4x4.hpp>
#include <limits>

#include "event_time.hpp"
#include "treecut/strategies/refinement_criterion.hpp"

namespace treecut::strategies {

using event_time::fold_event;
using event_time::unfold_event;
namespace {

constexpr double kVelocityMargin = 1.0 + 1e-6;

// Frames from a real lower bound x: floored, 0 for negative or NaN, at most
// cap. The true first frame k* of a change is an integer >= x, so any
// computed x' < x + 1 still gives floor(x') <= k*: errors below one frame
// are harmless.
std::uint32_t frames(double x, std::uint32_t cap) {
  if (!(x > 0.0)) return 0;
  if (x >= double(cap)) return cap;
  return static_cast<std::uint32_t>(x);
}

}  // namespace

CriterionConstants CriterionConstants::from_view(const ViewSnapshot& view, double theta) {
  CriterionConstants c;
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

bool unfold_test(const CriterionConstants& cam, const ViewSnapshot& view, const glm::vec4& cr) {
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
// The lens (issue 31): a zoom by e^z scales the threshold distance R = r S /
// theta by e^z, and a new aspect or field of view moves the cone's half-angle
// beta. The event queue charges |d beta| to the rotation clock (in each bound
// below beta enters exactly as a turn of the view direction would) and a zoom
// by e^z, z = |ln(S' / S)|, to the translation clock as a translation of
// z D (D = rates.reach, the model's diameter). The threshold then needs
// d - s <= R e^z with s + z D < m rho. d - s - R e^z is concave in (s, z), so
// its minimum over that triangle is at a corner: the threshold cannot pass
// before min(d - R, D ln(d / R)) / rho >= t_m min(1, D / d) (ln x >= 1 - 1/x).
// Inside and visibility are unchanged (s still <= m rho).
// Unfold needs inside, or visible and the threshold: m >= min(t_i, max(t_r, t_m)).
// When M <= t_m the threshold alone keeps the node folded until t_m and
// rotation cannot change that (w = infinity); else the node waits for
// min(t_i, M) on the translation clock or W on the rotation clock.

EventRates::EventRates(const CriterionConstants& cam, double rho_, double omega_, double cap_,
                       double cap_w_, double turn_per_move, double reach_)
    : rho(rho_ * kVelocityMargin),
      inv_rho(1.0 / (rho_ * kVelocityMargin)),
      omega(omega_ * kVelocityMargin),
      inv_omega(1.0 / (omega_ * kVelocityMargin)),
      size_scale(cam.pixel_scale / cam.theta),
      cap(cap_),
      cap_w(cap_w_),
      split(omega_ * turn_per_move),
      reach(reach_) {}

EventTime potential_unfold_event(const CriterionConstants& cam, const glm::vec4& cr,
                                 const EventRates& q) {
  return unfold_event(cam, look(cam, cr), q);
}

Decision decide(const CriterionConstants& cam, const glm::vec4& cr, const EventRates& q) {
  return event_time::decide(cam, cr, q);
}

// An unfolded node (unfold_test true).
// - Inside: the test stays true until the eye leaves the sphere: m >= (r - d) / rho;
//   rotation plays no part (w = infinity).
// - Outside (visible and above the threshold), the dual of the above:
//   t_m: the threshold fails only when |c - e_k| > R, m > (R - d) / rho;
//   with the lens charged as above it needs d + s > R e^-z >= R (1 - z),
//   linear in (s, z): t_m min(1, D / R) at the corners;
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
EventTime potential_fold_event(const CriterionConstants& cam, const glm::vec4& cr,
                               const EventRates& q) {
  return fold_event(cam, look(cam, cr), q);
}

// Both clocks in step, one frame of each: the frames before which nothing
// can change are those before either clock's bound.
std::uint32_t potential_unfold_time(const CriterionConstants& cam, const glm::vec4& cr, double rho,
                                    double omega, std::uint32_t cap) {
  const EventTime e =
      potential_unfold_event(cam, cr, EventRates(cam, rho, omega, double(cap), double(cap)));
  return frames(std::min(e.m, e.w), cap);
}

std::uint32_t potential_fold_time(const CriterionConstants& cam, const glm::vec4& cr, double rho,
                                  double omega, std::uint32_t cap) {
  const EventTime e =
      potential_fold_event(cam, cr, EventRates(cam, rho, omega, double(cap), double(cap)));
  return frames(std::min(e.m, e.w), cap);
}

}  // namespace treecut::strategies
