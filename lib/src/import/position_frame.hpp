// Positions a reader has in double (LAS, text, PLY and PCD doubles) made
// the PointSet's floats relative to an origin (point_set.hpp), with one rule
// for every reader (issue 43, items 6 and 7):
//
//  - Only coordinates that need an origin get one: within 32,768 units of
//    zero a float's spacing is at most 2^-9 (rounding under 1 mm), so a
//    scan in local coordinates keeps zero as its origin and exports as it
//    was read. Beyond, the origin is the centre of the points' bounds in
//    whole units: a model up to 65 km across keeps millimetres.
//  - One far point does not decide for the others: the bounds are those of
//    the points within kMaxCoordinate of the median, and a point beyond
//    kMaxCoordinate of the origin (or of zero: the coordinate limit) is
//    dropped and named (a first point at 1e20 used to become the origin,
//    and the real points were dropped).
#pragma once

#include <cstddef>
#include <glm/ext/vector_double3.hpp>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "treecut/point_set.hpp"

namespace treecut::detail {

/// Coordinates within this of zero need no origin.
inline constexpr double kNoOriginReach = 32768.0;

/// The origin for POINTS (finite), by the rule above.
glm::dvec3 choose_origin(std::span<const glm::dvec3> points);

/// Whether BOUNDS [LO, HI] lie within kNoOriginReach of zero.
bool near_zero(const glm::dvec3& lo, const glm::dvec3& hi);

/// What place_points() dropped.
struct Dropped {
  std::size_t nonfinite = 0;  ///< without a finite position (an organized cloud's holes)
  std::size_t far = 0;        ///< beyond kMaxCoordinate of the origin or of zero
  std::size_t first_far = 0;  ///< the first far one's index among the points given
  glm::dvec3 first_far_at{0.0};
  /// "dropped 1 point beyond the coordinate limit, 1e18 from the others or
  /// from zero (the first: point 1 at 1e+20 0 0)", FIRST_NUMBER the first
  /// far point's number.
  [[nodiscard]] std::string far_message(std::size_t first_number) const;
  /// Adds what a later batch dropped, BEFORE points after the first batch's
  /// first (its first_far counts from there).
  void add(const Dropped& batch, std::size_t before) {
    if (batch.far > 0 && far == 0)
      first_far = before + batch.first_far, first_far_at = batch.first_far_at;
    far += batch.far, nonfinite += batch.nonfinite;
  }
};

/// Sets POINTS.frame.origin by choose_origin (over the finite DOUBLES) and
/// POINTS.positions to DOUBLES relative to it, and keeps DOUBLES as
/// POINTS.exact_positions where the floats do not give every one back;
/// drops (PointSet::keep_if) the points without a finite position or beyond
/// kMaxCoordinate of it. The other per-point arrays of POINTS must be in
/// step with DOUBLES. With ORIGIN, that origin instead (a file's later
/// batches keep the one its first chose).
Dropped place_points(std::vector<glm::dvec3>&& doubles, PointSet& points,
                     const std::optional<glm::dvec3>& origin = std::nullopt);

/// Whether the float P, relative to ORIGIN, gives the file's coordinates
/// EXACT back.
inline bool float_exact(const glm::vec3& p, const glm::dvec3& origin, const glm::dvec3& exact) {
  return origin + glm::dvec3(p) == exact;
}

}  // namespace treecut::detail
